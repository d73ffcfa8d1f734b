"""`photo_recording`: a recording copy whose RGB frames carry the training's photometric
changes, everything else byte-identical, and loadable like the source."""

from __future__ import annotations

import numpy as np
import pytest

from depthor_models import data, photo_recording
from test_train import write_recording


def test_copy_changes_only_rgb(tmp_path):
    src = write_recording(tmp_path / "src", n=3)
    out = tmp_path / "photo"
    assert photo_recording.write(src, out, seed=5) == 3
    assert (out / "recording.json").read_bytes() == (src / "recording.json").read_bytes()
    a, b = data.load_recording(src, cache=False), data.load_recording(out, cache=False)
    assert np.array_equal(a.depth_mm, b.depth_mm) and np.array_equal(a.zone_m, b.zone_m)
    assert a.rgb.shape == b.rgb.shape and not np.array_equal(a.rgb, b.rgb)
    for fid in ("000000", "000002"):
        assert ((out / "frames" / fid / "dtof.json").read_bytes()
                == (src / "frames" / fid / "dtof.json").read_bytes())
    # the same seed draws the same changes; another seed others
    again = tmp_path / "again"
    photo_recording.write(src, again, seed=5)
    assert np.array_equal(data.load_recording(again, cache=False).rgb, b.rgb)
    with pytest.raises(FileExistsError):
        photo_recording.write(src, again, seed=6)
    photo_recording.write(src, again, seed=6, overwrite=True)
    assert not np.array_equal(data.load_recording(again, cache=False).rgb, b.rgb)
