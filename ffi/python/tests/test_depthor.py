"""The depthor Python package against the Rust engine, bit for bit.

Driven by ``ffi/tests/python.rs``, which installs the package into a fresh venv and writes
into ``$DEPTHOR_TEST_DIR``: ``model.dblob``, ``rgb.bin`` (H·W·3 uint8), ``sparse.bin`` and
``depth.bin`` (H·W float32 little endian: the input and the Rust ``Engine::run`` output) and
``shape.txt`` ("H W"). Run by hand: ``DEPTHOR_TEST_DIR=… python -m unittest discover -s
ffi/python/tests``.
"""

import os
import unittest
from pathlib import Path

import numpy as np

import depthor


def _dir() -> Path:
    d = os.environ.get("DEPTHOR_TEST_DIR")
    if not d:
        raise unittest.SkipTest("DEPTHOR_TEST_DIR not set (ffi/tests/python.rs sets it)")
    return Path(d)


class EngineTest(unittest.TestCase):
    def setUp(self):
        d = _dir()
        self.blob = (d / "model.dblob").read_bytes()
        self.h, self.w = map(int, (d / "shape.txt").read_text().split())
        self.rgb = np.fromfile(d / "rgb.bin", dtype=np.uint8).reshape(self.h, self.w, 3)
        self.sparse = np.fromfile(d / "sparse.bin", dtype="<f4").reshape(self.h, self.w)
        self.want = np.fromfile(d / "depth.bin", dtype="<f4").reshape(self.h, self.w)

    def test_output_is_the_rust_engines_bit_for_bit(self):
        engine = depthor.Engine(self.blob, self.h, self.w)
        self.assertEqual(engine.shape, (self.h, self.w))
        got = engine.run(self.rgb, self.sparse)
        self.assertEqual(got.dtype, np.float32)
        self.assertTrue(np.array_equal(got.view(np.uint32), self.want.view(np.uint32)))
        self.assertTrue((got > 0).any())
        # A second run on the same engine gives the same bits.
        self.assertTrue(np.array_equal(engine.run(self.rgb, self.sparse).view(np.uint32), got.view(np.uint32)))

    def test_arena_and_native_size(self):
        self.assertEqual(depthor.arena_bytes(self.blob, self.h, self.w), depthor.Engine(self.blob, self.h, self.w).arena_bytes)
        native = depthor.Engine(self.blob)
        self.assertGreater(native.shape[0], 0)
        self.assertEqual(native.arena_bytes, depthor.arena_bytes(self.blob))

    def test_errors_raise_with_their_codes(self):
        cases = []
        bad = bytearray(self.blob)
        bad[-1] ^= 0x5A
        cases.append((bytes(bad), "DEPTHOR_E_BLOB_CHECKSUM"))
        bad = bytearray(self.blob)
        bad[4] ^= 1
        cases.append((bytes(bad), "DEPTHOR_E_BLOB_VERSION"))
        cases.append((self.blob[:20], "DEPTHOR_E_BLOB"))
        for blob, name in cases:
            with self.assertRaises(depthor.DepthorError) as e:
                depthor.Engine(blob, self.h, self.w)
            self.assertEqual(e.exception.code, depthor.STATUS[name])
            self.assertEqual(e.exception.name, name)
        with self.assertRaises(depthor.DepthorError) as e:
            depthor.Engine(self.blob, 0, self.w)
        self.assertEqual(e.exception.name, "DEPTHOR_E_SIZE")
        engine = depthor.Engine(self.blob, self.h, self.w)
        with self.assertRaises(ValueError):
            engine.run(self.rgb[:, :-1], self.sparse)
        with self.assertRaises(ValueError):
            engine.run(self.rgb, self.sparse.T)

    def test_status_messages(self):
        msgs = {depthor.status_message(c) for c in depthor.STATUS.values()}
        self.assertEqual(len(msgs), len(depthor.STATUS))
        self.assertEqual(depthor.status_message(99), "unknown status code")


if __name__ == "__main__":
    unittest.main()
