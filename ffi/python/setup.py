"""Builds the wheel: `cargo build -p depthor-ffi --release` in the repository this directory
belongs to, and ships `libdepthor_ffi.so` inside the `depthor` package (a platform wheel).

`pip install ./ffi/python` needs cargo (the repository's toolchain) and network access for
numpy. Environment: `DEPTHOR_FFI_LIB=/path/libdepthor_ffi.so` ships that library instead of
building one; `CARGO`, `CARGO_TARGET_DIR` are honoured.
"""

import os
import shutil
import subprocess
from pathlib import Path

from setuptools import setup
from setuptools.command.build_py import build_py
from setuptools.dist import Distribution

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent.parent


class BuildWithLibrary(build_py):
    """build_py, then the Rust shared library copied into the package."""

    def run(self):
        super().run()
        lib = os.environ.get("DEPTHOR_FFI_LIB")
        if lib:
            src = Path(lib)
        else:
            cargo = os.environ.get("CARGO", "cargo")
            manifest = ROOT / "Cargo.toml"
            subprocess.check_call(
                [cargo, "build", "-p", "depthor-ffi", "--release", "--manifest-path", str(manifest)]
            )
            target = Path(os.environ.get("CARGO_TARGET_DIR", ROOT / "target"))
            src = target / "release" / "libdepthor_ffi.so"
        dst = Path(self.build_lib) / "depthor" / "libdepthor_ffi.so"
        dst.parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(src, dst)


class BinaryDistribution(Distribution):
    """A wheel with a native library: tagged for this platform, not py3-none-any."""

    def has_ext_modules(self):
        return True


setup(cmdclass={"build_py": BuildWithLibrary}, distclass=BinaryDistribution)
