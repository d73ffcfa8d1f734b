"""Where phone_lite loses on nyu: global scale, or the RGB guidance? (float PyTorch, pooled pixels)"""
# Run from models/: PYTHONPATH=. .venv/bin/python phone_lite/train/rgb_and_scale.py REC [REC…] (recordings at
# 320×240, e.g. rec/real_phone/nyu rec/real_phone/middlebury … rec/phone_val48); its output is quoted in
# ../MODEL_CARD.md (Discussion) and docs/results/models_phone_lite.md.

import sys
import numpy as np, torch
from depthor_models import data
from depthor_models.train import make_model, load_weights, zone_baselines, predict

torch.set_num_threads(2)
net = make_model("phone_lite", 0)
net.load_state_dict(load_weights("phone_lite/train/model_final.pt"))
net.eval()

def rmse(p, g):
    m = (g > 0) & (g <= 10)
    return float(np.sqrt(np.mean((p[m] - g[m]) ** 2)))

def rel(p, g):
    m = (g > 0) & (g <= 10)
    return float(np.mean(np.abs(p[m] - g[m]) / g[m]))

def aligned(p, g):
    """RMSE after one least-squares scale per frame."""
    out = []
    for pi, gi in zip(p, g):
        m = (gi > 0) & (gi <= 10)
        s = float((pi[m] * gi[m]).sum() / (pi[m] ** 2).sum())
        out.append((s * pi - gi)[m])
    e = np.concatenate(out)
    return float(np.sqrt(np.mean(e ** 2)))

print("set frames | model RMSE Rel | grey-RGB model RMSE Rel | bilinear RMSE Rel | scale-aligned model / bilinear | median pred/gt")
for path in sys.argv[1:]:
    rec = data.load_recording(path, size=(320, 240), cache=False)
    idx = np.arange(len(rec))
    rgb, sp, gt = data.batch(rec, idx)
    g = gt[:, 0].numpy()
    with torch.no_grad():
        p = net(rgb, sp)[:, 0].numpy()
        pg = net(torch.full_like(rgb, 0.5), sp)[:, 0].numpy()
    b = zone_baselines(rec, idx)["bilinear"]
    m = (g > 0) & (g <= 10)
    ratio = float(np.median(p[m] / g[m]))
    print(f"{path.split('/')[-1]} {len(rec)} | {rmse(p,g):.3f} {rel(p,g):.3f} | {rmse(pg,g):.3f} {rel(pg,g):.3f} | "
          f"{rmse(b,g):.3f} {rel(b,g):.3f} | {aligned(p,g):.3f} / {aligned(b,g):.3f} | {ratio:.3f}")
