#!/usr/bin/env bash
# Installs what depthor's tests need beyond rustup/cargo and python3, each only when missing:
# the toolchain, target and components named in rust-toolchain.toml, and the Debian package
# qemu-system-arm (the Cortex-M firmware tests run under QEMU's mps2-an386), and
# gcc-arm-none-eabi + libnewlib-arm-none-eabi (depthor-ffi's C firmware, firmware-sim/c).
# Usage: bash scripts/setup.sh            (idempotent; prints one line per thing it checks)
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."

toml=rust-toolchain.toml
channel="$(sed -n 's/^channel *= *"\(.*\)"/\1/p' "$toml")"
targets="$(sed -n 's/^targets *= *\[\(.*\)\]/\1/p' "$toml" | tr ',' '\n' | tr -d '" ')"
components="$(sed -n 's/^components *= *\[\(.*\)\]/\1/p' "$toml" | tr ',' '\n' | tr -d '" ')"

command -v rustup >/dev/null || { echo "setup: rustup is not on PATH (install it first)"; exit 1; }
echo "setup: Rust toolchain $channel (from $toml)"
rustup toolchain install "$channel" --profile minimal --no-self-update >/dev/null 2>&1 \
  || rustup toolchain install "$channel" --profile minimal
for t in $targets; do
  if rustup target list --installed --toolchain "$channel" | grep -qx "$t"; then
    echo "setup: target $t: installed"
  else
    echo "setup: target $t: missing, installing"
    rustup target add --toolchain "$channel" "$t"
  fi
done
for c in $components; do
  if rustup component list --installed --toolchain "$channel" | grep -q "^$c"; then
    echo "setup: component $c: installed"
  else
    echo "setup: component $c: missing, installing"
    rustup component add --toolchain "$channel" "$c"
  fi
done

# Debian packages: the command that must exist -> the package that provides it.
apt_install() {
  if [ "$(id -u)" = 0 ]; then sudo=""; else sudo="sudo"; fi
  command -v apt-get >/dev/null || { echo "setup: no apt-get here; install $* by hand"; exit 1; }
  $sudo apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends "$@"
}
missing=()
command -v qemu-system-arm >/dev/null || missing+=(qemu-system-arm)
# The C firmware of depthor-ffi (firmware-sim/c): arm-none-eabi-gcc and newlib; make.
command -v arm-none-eabi-gcc >/dev/null || missing+=(gcc-arm-none-eabi)
[ -e /usr/lib/arm-none-eabi/newlib/librdimon.a ] || missing+=(libnewlib-arm-none-eabi)
command -v make >/dev/null || missing+=(make)
if [ ${#missing[@]} -gt 0 ]; then
  echo "setup: Debian packages missing: ${missing[*]}, installing"
  apt_install "${missing[@]}"
fi
echo "setup: qemu-system-arm: $(qemu-system-arm --version | head -1)"
echo "setup: arm-none-eabi-gcc: $(arm-none-eabi-gcc --version | head -1)"
if command -v python3 >/dev/null; then
  echo "setup: python3: $(python3 --version) (models/smoke.sh makes models/.venv on first run)"
else
  echo "setup: python3 is not on PATH (the Python tests need it)"; exit 1
fi
echo "setup: done"
