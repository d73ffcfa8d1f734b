"""Distributed training (issue 21): `torchrun --nproc-per-node 2` on CPU (gloo) trains what one
process trains on the same global batch, and a run checkpointed by 2 processes resumes in 1 and
ends where the single-process run ends; the streaming loader gives the in-memory batches."""

from __future__ import annotations

import csv
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch

from depthor_models import data
from depthor_models import train as T
from test_train import write_recording

MODELS = Path(__file__).resolve().parents[1]


def _args(rec, out, *extra):
    return ["--train", str(rec), "--test", str(rec), "--out", str(out), "--steps", "3",
            "--batch", "4", "--max-lr", "1e-3", "--eval-frames", "1", "--ckpt-every-s", "1e9",
            "--threads", "1", "--device", "cpu", "--dtype", "float64", *extra]


def _rows(run: Path) -> list[dict]:
    with (run / "train.csv").open() as f:
        return list(csv.DictReader(f))


def _same_rows(a: list[dict], b: list[dict]) -> None:
    assert [r["step"] for r in a] == [r["step"] for r in b]
    for ra, rb in zip(a, b):
        assert ra["lr"] == rb["lr"], (ra, rb)  # the schedule is a function of the global step
        for k in ("loss", "silog", "prior", "grad_norm"):
            assert float(ra[k]) == pytest.approx(float(rb[k]), rel=1e-5, abs=1e-5), (k, ra, rb)


def test_stream_dataset_matches_memory_batches(tmp_path):
    rec_dir = write_recording(tmp_path / "rec", n=4)
    size = (40, 64)  # resampled, as training resamples to the model's input
    rec = data.load_recording(rec_dir, cache=False, size=size)
    ds = data.FrameDataset(data.FrameReader(str(rec_dir), size=size))
    keys = [(2, True), (0, False), (3, True)]
    got = torch.utils.data.DataLoader(ds, batch_sampler=[keys], num_workers=1)
    want = data.batch(rec, np.array([k[0] for k in keys]), np.array([k[1] for k in keys]))
    for g, w in zip(next(iter(got)), want):
        assert torch.equal(g, w)
    assert data.FrameReader(str(rec_dir), size=size).ids == rec.ids


def test_torchrun_two_processes_equal_one_and_resume_with_another_count(tmp_path):
    rec_dir = write_recording(tmp_path / "rec", n=6)
    T.main(_args(rec_dir, tmp_path / "one"))
    env = {**os.environ, "PYTHONPATH": str(MODELS) + os.pathsep + os.environ.get("PYTHONPATH", ""),
           "OMP_NUM_THREADS": "1"}
    cmd = [sys.executable, "-m", "torch.distributed.run", "--standalone", "--nproc-per-node", "2",
           "-m", "depthor_models.train",
           *_args(rec_dir, tmp_path / "two", "--stop-after", "2", "--data", "stream",
                  "--workers", "1")]
    run = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stdout[-3000:] + run.stderr[-3000:]
    assert "distributed: 2 processes (cpu), 2 of the global batch 4 each" in run.stdout
    ck = torch.load(tmp_path / "two" / "ckpt.pt", weights_only=False)
    assert ck["step"] == 2 and ck["world"] == 2 and ck["scheduler"]["last_epoch"] == 2
    one = _rows(tmp_path / "one")
    _same_rows(_rows(tmp_path / "two"), one[:2])  # 2 processes, steps 1-2
    # The 2-process checkpoint resumed by 1 process: step 3 and the weights as in the 1-process run.
    T.main(_args(rec_dir, tmp_path / "two", "--resume"))
    _same_rows(_rows(tmp_path / "two"), one)
    a = torch.load(tmp_path / "one" / "model_final.pt")
    b = torch.load(tmp_path / "two" / "model_final.pt")
    start = T.make_model("mcu", 0).double().state_dict()
    moved = 0
    for k, v in a.items():
        if v.dtype.is_floating_point:
            assert torch.allclose(v, b[k], rtol=1e-7, atol=1e-9), (k, (v - b[k]).abs().max())
            moved += int(not torch.equal(v, start[k]))
        else:
            assert torch.equal(v, b[k]), k
    assert moved > 10  # the runs did train
