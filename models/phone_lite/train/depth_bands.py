"""phone_lite (float) vs bilinear zones on a recording, by reference depth band: pixel share, Rel
and signed relative error (pooled)."""
# Run from models/: PYTHONPATH=. .venv/bin/python phone_lite/train/depth_bands.py REC [REC…] (recordings at
# 320×240, e.g. rec/real_phone/nyu rec/real_phone/middlebury … rec/phone_val48); its output is quoted in
# ../MODEL_CARD.md (Discussion) and docs/results/models_phone_lite.md.

import sys
import numpy as np, torch
from depthor_models import data
from depthor_models.train import make_model, load_weights, zone_baselines
torch.set_num_threads(2)
net = make_model("phone_lite", 0); net.load_state_dict(load_weights("phone_lite/train/model_final.pt")); net.eval()
for path in sys.argv[1:]:
    rec = data.load_recording(path, size=(320, 240), cache=False)
    idx = np.arange(len(rec)); rgb, sp, gt = data.batch(rec, idx); g = gt[:, 0].numpy()
    with torch.no_grad(): p = net(rgb, sp)[:, 0].numpy()
    b = zone_baselines(rec, idx)["bilinear"]
    m = (g > 0) & (g <= 10)
    print(path.split('/')[-1], "valid px", int(m.sum()), "zones with a return:", [int((rec.status[i] == 5).sum()) for i in idx])
    for lo, hi in ((0, 1.5), (1.5, 2.5), (2.5, 4), (4, 10)):
        k = m & (g > lo) & (g <= hi)
        if k.sum() == 0: continue
        rm = np.abs(p[k] - g[k]) / g[k]; rb = np.abs(b[k] - g[k]) / g[k]
        print(f"  {lo}-{hi} m: share {k.sum()/m.sum():.2f}  Rel model {rm.mean():.3f} bilinear {rb.mean():.3f}  "
              f"signed model {np.mean((p[k]-g[k])/g[k]):+.3f} bilinear {np.mean((b[k]-g[k])/g[k]):+.3f}")
