#!/usr/bin/env bash
# Smoke check of models/: creates models/.venv from requirements.txt if missing (or stale),
# installs the `depthor` package (ffi/python: ctypes over libdepthor_ffi.so, built by cargo) into
# it when ffi/, core/ or the lock file changed since the last install, then runs the pytest
# subset without the `slow` marker (both variants built and traced, graph.json re-run by the
# numpy interpreter, mcu NNEF exported offline and checked in tract, the int8 engine beside
# PyTorch frame by frame).
# Usage: bash models/smoke.sh [extra pytest args]
# Environment: DEPTHOR_REQUIRE_FFI=0 skips the package (no cargo needed; the engine tests then
# skip); otherwise (default 1) they fail without it. CARGO_TARGET_DIR is honoured by the build.
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
venv="$here/.venv"
stamp="$venv/.requirements.sha256"
want="$(sha256sum "$here/requirements.txt" | cut -d' ' -f1)"
if [[ ! -x "$venv/bin/python" || ! -f "$stamp" || "$(cat "$stamp")" != "$want" ]]; then
  echo "models/smoke.sh: installing $venv (torch wheel is large; a few minutes)"
  python3 -m venv "$venv"
  "$venv/bin/pip" install --quiet --no-cache-dir -r "$here/requirements.txt"
  echo "$want" > "$stamp"
fi
# The depthor package: `pip install ffi/python` runs `cargo build -p depthor-ffi --release`
# (≈ 10 s after an ffi/ change, ≈ 1 min when core/ rebuilds too, several cold) and ships the
# library inside the package. Skipped when the sources it is built from are unchanged since the
# last install (stamp: their hash).
export DEPTHOR_REQUIRE_FFI="${DEPTHOR_REQUIRE_FFI:-1}"
if [[ "$DEPTHOR_REQUIRE_FFI" == 1 ]]; then
  root="$(cd "$here/.." && pwd)"
  ffi_stamp="$venv/.depthor-ffi.sha256"
  ffi_want="$(cd "$root" && find Cargo.toml Cargo.lock rust-toolchain.toml core/Cargo.toml \
    core/src ffi/Cargo.toml ffi/build.rs ffi/cbindgen.toml ffi/src ffi/python/setup.py \
    ffi/python/pyproject.toml ffi/python/depthor -type f ! -name '*.pyc' -print0 | sort -z \
    | xargs -0 sha256sum | sha256sum | cut -d' ' -f1)"
  if [[ ! -f "$ffi_stamp" || "$(cat "$ffi_stamp")" != "$ffi_want" ]] \
    || ! "$venv/bin/python" -c "import depthor" 2>/dev/null; then
    echo "models/smoke.sh: installing the depthor package (ffi/python; cargo build --release)"
    # A venv that can build wheels itself (setuptools ≥ 70.1, or wheel) builds without an
    # isolated environment (nothing downloaded); otherwise pip fetches setuptools for the build.
    isolation=()
    if "$venv/bin/python" -c "import setuptools.command.bdist_wheel" 2>/dev/null \
      || "$venv/bin/python" -c "import setuptools, wheel" 2>/dev/null; then
      isolation=(--no-build-isolation)
    fi
    "$venv/bin/pip" install --quiet --no-deps "${isolation[@]}" --force-reinstall "$root/ffi/python"
    echo "$ffi_want" > "$ffi_stamp"
  fi
fi
cd "$here"
exec "$venv/bin/python" -m pytest -q -m "not slow" "$@"
