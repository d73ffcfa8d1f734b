#!/usr/bin/env bash
# Builds depthor-ffi's static libraries for the targets of issue 43 and prints their sizes:
#   x86_64-unknown-linux-gnu, aarch64-unknown-linux-gnu   (std: panics caught at the boundary)
#   thumbv7em-none-eabihf, thumbv7em-none-eabihf + arm-dsp (no_std, no alloc)
# Each lands in target/ffi-libs/<name>/libdepthor_ffi.a (name: the target, "-dsp" for arm-dsp).
# Profiles: `release` for Linux, `ffi-mcu` (release + fat LTO, root Cargo.toml) for Cortex-M.
# Sizes: the archive as built (debug = 1 from `release`), the archive with debug info
# stripped (llvm-strip --strip-debug, when present), and text/data summed over its members.
# Usage: bash ffi/build-libs.sh [name…]     (idempotent; needs the rustup targets, see
#        scripts/setup.sh; no C toolchain: a staticlib needs no linker)
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
out=target/ffi-libs
all=(x86_64-unknown-linux-gnu aarch64-unknown-linux-gnu thumbv7em-none-eabihf thumbv7em-none-eabihf-dsp)
names=("${@:-${all[@]}}")

build() {
  local name=$1 target=${1%-dsp} profile=release flags=()
  case $name in
    thumbv7em-*-dsp) profile=ffi-mcu flags=(--no-default-features --features arm-dsp) ;;
    thumbv7em-*) profile=ffi-mcu flags=(--no-default-features) ;;
  esac
  nice cargo rustc -q -p depthor-ffi --profile "$profile" --target "$target" --crate-type staticlib \
    "${flags[@]}"
  mkdir -p "$out/$name"
  cp "${CARGO_TARGET_DIR:-target}/$target/$profile/libdepthor_ffi.a" "$out/$name/libdepthor_ffi.a"
}

# text+data of every member (GNU size reads any little-endian ELF through elf32/64-little).
text_data() {
  local lib=$1 size=size
  case $lib in *thumbv7em*) command -v arm-none-eabi-size >/dev/null && size=arm-none-eabi-size ;; esac
  case $lib in *aarch64*) size="size --target=elf64-little" ;; esac
  $size -t "$lib" 2>/dev/null | awk '/\(TOTALS\)/ {print "text " $1 " B, data " $2 " B"}'
}

printf '%-28s %12s %14s  %s\n' library "archive B" "stripped B" "members' text/data"
for name in "${names[@]}"; do
  build "$name"
  lib="$out/$name/libdepthor_ffi.a"
  stripped=-
  if command -v llvm-strip >/dev/null; then
    llvm-strip --strip-debug -o "$lib.stripped" "$lib"
    stripped=$(stat -c %s "$lib.stripped")
  fi
  printf '%-28s %12s %14s  %s\n' "$name" "$(stat -c %s "$lib")" "$stripped" "$(text_data "$lib")"
done
