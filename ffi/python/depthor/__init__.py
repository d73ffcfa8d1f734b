"""depthor-core's int8 engine from Python: ctypes over ``libdepthor_ffi.so`` (``depthor.h``).

    import numpy as np, depthor
    engine = depthor.Engine(open("models/mcu_lite/depthor.dblob", "rb").read())
    depth = engine.run(rgb, sparse)   # (H, W, 3) uint8, (H, W) float32 metres -> (H, W) float32

Bit for bit the Rust engine's output (``ffi/tests/python.rs``). Errors of the library raise
:class:`DepthorError` (``.code`` is the ``DEPTHOR_E_*`` value, ``.name`` its name); shapes that
do not match the engine raise ``ValueError``. One :class:`Engine` serves one thread at a time.
The library is the one inside the package, or ``$DEPTHOR_FFI_LIB``.
"""

import ctypes
import os
from pathlib import Path

import numpy as np

__all__ = ["Engine", "DepthorError", "arena_bytes", "status_message", "STATUS"]

#: Status codes of depthor.h, by name.
STATUS = {
    "DEPTHOR_OK": 0,
    "DEPTHOR_E_NULL": -1,
    "DEPTHOR_E_ALIGN": -2,
    "DEPTHOR_E_BLOB": -3,
    "DEPTHOR_E_BLOB_CHECKSUM": -4,
    "DEPTHOR_E_BLOB_VERSION": -5,
    "DEPTHOR_E_SIZE": -6,
    "DEPTHOR_E_ARENA": -7,
    "DEPTHOR_E_LENGTH": -8,
    "DEPTHOR_E_OVERLAP": -9,
    "DEPTHOR_E_NOT_INIT": -10,
    "DEPTHOR_E_CALIBRATION": -11,
    "DEPTHOR_E_INTERNAL": -12,
}
_NAMES = {v: k for k, v in STATUS.items()}

_u8p = ctypes.POINTER(ctypes.c_uint8)
_f32p = ctypes.POINTER(ctypes.c_float)
_u32p = ctypes.POINTER(ctypes.c_uint32)


def _load():
    path = os.environ.get("DEPTHOR_FFI_LIB") or str(Path(__file__).with_name("libdepthor_ffi.so"))
    lib = ctypes.CDLL(path)
    sig = {
        "depthor_engine_size": (ctypes.c_size_t, []),
        "depthor_engine_align": (ctypes.c_size_t, []),
        "depthor_arena_bytes": (
            ctypes.c_int32,
            [_u8p, ctypes.c_size_t, ctypes.c_uint32, ctypes.c_uint32, ctypes.POINTER(ctypes.c_size_t)],
        ),
        "depthor_engine_init": (
            ctypes.c_int32,
            [ctypes.c_void_p, _u8p, ctypes.c_size_t, _u8p, ctypes.c_size_t, ctypes.c_uint32, ctypes.c_uint32],
        ),
        "depthor_engine_input_size": (ctypes.c_int32, [ctypes.c_void_p, _u32p, _u32p]),
        "depthor_engine_run": (
            ctypes.c_int32,
            [ctypes.c_void_p, _u8p, ctypes.c_size_t, _f32p, ctypes.c_size_t, _f32p, ctypes.c_size_t],
        ),
        "depthor_status_message": (ctypes.c_char_p, [ctypes.c_int32]),
    }
    for name, (res, args) in sig.items():
        f = getattr(lib, name)
        f.restype, f.argtypes = res, args
    return lib


_lib = _load()


def status_message(code: int) -> str:
    """The library's description of a status code."""
    return _lib.depthor_status_message(code).decode()


class DepthorError(Exception):
    """A negative status of the library."""

    def __init__(self, code: int):
        self.code = code
        self.name = _NAMES.get(code, "unknown")
        super().__init__(f"{self.name} ({code}): {status_message(code)}")


def _check(code: int) -> None:
    if code != 0:
        raise DepthorError(code)


def _bytes_ptr(a: np.ndarray):
    return a.ctypes.data_as(_u8p)


def arena_bytes(blob: bytes, height: int = 0, width: int = 0) -> int:
    """Arena bytes ``blob`` needs at ``height × width`` (0, 0: its native size)."""
    b = np.frombuffer(bytes(blob), dtype=np.uint8)
    n = ctypes.c_size_t(0)
    _check(_lib.depthor_arena_bytes(_bytes_ptr(b), b.size, height, width, ctypes.byref(n)))
    return n.value


class Engine:
    """A prepared engine: owns its memory, its arena and a copy of the blob."""

    def __init__(self, blob: bytes, height: int = 0, width: int = 0):
        self._blob = np.frombuffer(bytes(blob), dtype=np.uint8)
        self.arena_bytes = arena_bytes(blob, height, width)
        self._arena = np.zeros(self.arena_bytes, dtype=np.uint8)
        size, align = _lib.depthor_engine_size(), _lib.depthor_engine_align()
        self._raw = np.zeros(size + align, dtype=np.uint8)
        off = (-self._raw.ctypes.data) % align
        self._mem = self._raw[off : off + size]
        _check(
            _lib.depthor_engine_init(
                self._mem.ctypes.data,
                _bytes_ptr(self._blob),
                self._blob.size,
                _bytes_ptr(self._arena),
                self._arena.size,
                height,
                width,
            )
        )
        h, w = ctypes.c_uint32(0), ctypes.c_uint32(0)
        _check(_lib.depthor_engine_input_size(self._mem.ctypes.data, ctypes.byref(h), ctypes.byref(w)))
        self.shape = (h.value, w.value)

    def run(self, rgb: np.ndarray, sparse_m: np.ndarray) -> np.ndarray:
        """One frame: ``rgb`` (H, W, 3) uint8, ``sparse_m`` (H, W) metres (0 = no point) ->
        dense depth (H, W) float32 metres."""
        h, w = self.shape
        rgb = np.ascontiguousarray(rgb, dtype=np.uint8)
        sparse = np.ascontiguousarray(sparse_m, dtype=np.float32)
        if rgb.shape != (h, w, 3) or sparse.shape != (h, w):
            raise ValueError(
                f"engine runs at {h}x{w}: rgb must be ({h}, {w}, 3), sparse ({h}, {w}); "
                f"got {rgb.shape} and {sparse.shape}"
            )
        out = np.empty((h, w), dtype=np.float32)
        _check(
            _lib.depthor_engine_run(
                self._mem.ctypes.data,
                _bytes_ptr(rgb),
                rgb.size,
                sparse.ctypes.data_as(_f32p),
                sparse.size,
                out.ctypes.data_as(_f32p),
                out.size,
            )
        )
        return out
