"""Writes a variant's model card, models/<variant>/MODEL_CARD.md, from measured files only.

    python3 models/card.py mcu --synthetic eval/mcu_test500/summary.json \
        --real eval/mcu_real/summary.json [--run models/mcu/train] [--regression eval/reg/summary.json]

Inputs: models/<variant>/summary.json (export: parameters, MACs), card.json (the regression
entry host/tests/model_card.rs checks), `depthor eval` summaries (synthetic held-out set, real
sets with their union), and the training run folder (args.json, train.csv, eval.csv,
data_generation.txt). With --regression the card.json figures are replaced by that summary's
int8 RMSE and δ1. Standard library only (no torch needed).
"""

from __future__ import annotations

import argparse
import csv
import json
from pathlib import Path

HERE = Path(__file__).resolve().parent
ARCHITECTURE = ("RGB encoder (BasicBlock stages 1/2…1/32), monocular prior (D_inv, F_mde), depth encoder over "
                "cat(D_inv, D_rel, S) (5×5 dilation-2 stem, CBAM on the deepest stage), fusing decoder, 128-bin adaptive "
                "depth head at 1/2 resolution, mixed-affinity refinement (3/5/7 kernels, fixed iterations, t ∈ {0, T/2, T}).")
ORDER = ["int8", "float", "nearest", "bilinear", "joint_bilateral", "prior_fit"]
METRICS = [("delta1", "δ1"), ("delta2", "δ2"), ("delta3", "δ3"), ("abs_rel", "Rel"),
           ("rmse", "RMSE"), ("log10", "log10"), ("ewmae", "EWMAE")]


def table(methods: dict) -> list[str]:
    """Markdown rows of a summary's methods (int8, float, then baselines)."""
    head = "| method | " + " | ".join(label for _, label in METRICS) + " | ms/frame |"
    rows = [head, "|---" * (len(METRICS) + 2) + "|"]
    for key in sorted(methods, key=lambda k: ORDER.index(k) if k in ORDER else len(ORDER)):
        m = methods[key]
        cells = " | ".join(f"{m[k]:.3f}" for k, _ in METRICS)
        rows.append(f"| {m['label']} | {cells} | {m['ms_per_frame']:.1f} |")
    return rows


def aggregate(s: dict) -> str:
    """How the summary combined its frames (docs/eval.md); summaries written before `depthor
    eval --aggregate` existed pooled pixels."""
    return {"image": "per-image mean", "pixel": "pooled pixels"}.get(s.get("aggregate", "pixel"), s.get("aggregate"))


def verdict(s: dict) -> list[str]:
    """The comparisons the issue's acceptance asks for, as measured."""
    out = []
    c = s.get("int8_vs_best_baseline")
    b = s.get("best_baseline")
    if c and b:
        out.append(f"- int8 RMSE / best baseline's ({b['rmse']['method']}, {b['rmse']['value']:.3f} m): "
                   f"**{c['rmse_ratio']:.3f}** (target ≤ 0.8 on synthetic)")
        out.append(f"- int8 δ1 − best baseline's ({b['delta1']['method']}, {b['delta1']['value']:.3f}): "
                   f"**{c['delta1_gain']:+.3f}** (target ≥ +0.03 on synthetic)")
    f = s.get("int8_vs_float")
    if f:
        out.append(f"- int8 vs float: RMSE {100 * f['rmse_rel_diff']:+.2f} % (target within ±1 %), "
                   f"δ1 {f['delta1_diff']:+.4f} (target within ±0.005)")
    return out


def losses(name: str, m: dict) -> list[str]:
    """The sentence naming the baselines that beat int8 on RMSE or Rel (empty if none)."""
    beaten_by = [k for k in m if k not in ("int8", "float")
                 and (m[k]["rmse"] < m["int8"]["rmse"] or m[k]["abs_rel"] < m["int8"]["abs_rel"])]
    if not beaten_by:
        return []
    return [f"On {name} the int8 model does not beat: {', '.join(beaten_by)} (RMSE or Rel).", ""]


def real_section(s: dict, discussion: str = "") -> list[str]:
    lines = []
    for r in s.get("recordings", []):
        name = Path(r["recording"]).name
        lines += [f"**{name}** ({r['frames']} frames)", ""] + table(r["methods"]) + [""] + verdict(r) + [""]
        lines += losses(name, r["methods"])
    lines += [f"**Union of the real sets** ({s['frames']} frames)", ""] + table(s["methods"]) + [""] + verdict(s)
    lines += [""] + losses("the union", s["methods"])
    if discussion:
        lines += [discussion, ""]
    return lines


def training_section(run: Path) -> list[str]:
    lines = []
    args = json.loads((run / "args.json").read_text())
    steps = list(csv.DictReader((run / "train.csv").open()))
    evals = list(csv.DictReader((run / "eval.csv").open())) if (run / "eval.csv").exists() else []
    n = int(args.get("threads", 2))
    threads = f"{n} thread" + ("s" if n != 1 else "")
    lines.append(f"Run folder `{run.relative_to(HERE.parent) if run.is_relative_to(HERE.parent) else run}`: "
                 f"{len(steps)} steps of batch {args['batch']} on CPU ({threads}), "
                 + (f"quantisation-aware ({float(args.get('qat_float_p', 0)):.0%} of the steps on the "
                    f"float network), " if args.get("qat") else "") +
                 f"{float(steps[-1]['wall_s']) / 60:.0f} min wall; initialised from `{args.get('init')}`; "
                 f"train set `{args['train']}`, in-run check set `{args['test']}`; AdamW (weight decay "
                 f"{args['weight_decay']}), clip {args['clip']}, OneCycle max lr {args['max_lr']}, SILog α 10 λ 0.85.")
    if evals:
        e = evals[-1]
        how = "int8 rounding simulated, PyTorch" if args.get("qat") else "float PyTorch"
        lines.append(f"Last in-run check ({e['frames']} frames of the check set, {how}): RMSE "
                     f"{float(e['model_rmse']):.3f} m vs bilinear {float(e['bilinear_rmse']):.3f}, δ1 "
                     f"{float(e['model_delta1']):.3f} vs {float(e['bilinear_delta1']):.3f}.")
    gen = run / "data_generation.txt"
    if gen.exists():
        lines += ["", "Data generation (from the run folder):", "", "```", gen.read_text().rstrip(), "```"]
    if (run / "loss.png").exists():
        lines += ["", f"Loss curves: `{(run / 'loss.png').name}` in the run folder."]
    return lines


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("variant")
    ap.add_argument("--synthetic", type=Path, help="depthor eval summary.json on the held-out synthetic set")
    ap.add_argument("--synthetic-command", default="", help="the command that made --synthetic")
    ap.add_argument("--extra-synthetic", nargs=3, action="append", default=[],
                    metavar=("TITLE", "SUMMARY", "COMMAND"),
                    help="another held-out synthetic set (e.g. other scene ranges): its title, "
                         "depthor eval summary.json and the command that made it; repeatable")
    ap.add_argument("--real", type=Path, help="depthor eval summary.json over the real sets")
    ap.add_argument("--real-command", default="", help="the command that made --real")
    ap.add_argument("--run", type=Path, help="training run folder")
    ap.add_argument("--regression", type=Path, help="depthor eval summary.json on the card's regression set")
    ap.add_argument("--discussion", default="",
                    help="a paragraph after the real sets: why the model loses where it does")
    ap.add_argument("--architecture", default=ARCHITECTURE, help="the Model section's architecture line (default: the mcu/phone network)")
    ap.add_argument("--note", default="", help="a paragraph placed under the status line (e.g. where trained weights are)")
    a = ap.parse_args()

    d = HERE / a.variant
    summary = json.loads((d / "summary.json").read_text())
    card = json.loads((d / "card.json").read_text())
    if a.regression:
        s = json.loads(a.regression.read_text())
        card["regression"]["int8_rmse"] = round(s["methods"]["int8"]["rmse"], 4)
        card["regression"]["int8_delta1"] = round(s["methods"]["int8"]["delta1"], 4)
        card["regression"].pop("int8_vs_float_rmse_rel", None)
        card["regression"].pop("int8_vs_float_delta1", None)
    card["weights"] = summary.get("weights")
    (d / "card.json").write_text(json.dumps(card, indent=1, ensure_ascii=False) + "\n")

    blob = (d / "depthor.dblob").stat().st_size
    L = [f"# Model card: DEPTHOR `{a.variant}`", "",
         "Written by `models/card.py` from measured files; every figure below comes from a command shown here.", "",
         *(["**Status: these weights are untrained** (seeded random initialisation), so the model loses to every "
            "baseline below; the tables are the pipeline's check, not a result.", ""]
           if "untrained" in str(summary.get("weights")) else []),
         *([a.note, ""] if a.note else []),
         "## Model", "",
         f"- Input {summary['height']}×{summary['width']} (H×W) RGB + projected dToF; output dense depth in metres.",
         f"- Parameters: {summary['params_deployed']:,} deployed (prior {summary['params_prior']:,}); "
         f"MACs per frame {summary['macs'] / 1e9:.3f} G (prior {summary['macs_prior'] / 1e9:.3f} G).",
         f"- Weights: {summary.get('weights')}" + (f" (`{summary['weights_path']}`)" if summary.get("weights_path") else ""),
         f"- Files: `depthor.nnef.tgz` (float, tract), `prior.nnef.tgz`, `graph.json` + `weights.bin`, "
         f"`depthor.dblob` (int8, {blob:,} B, the core's).",
         f"- Architecture: {a.architecture}",
         ""]
    if a.run:
        L += ["## Training", ""] + training_section(a.run) + [""]
    if a.synthetic:
        s = json.loads(a.synthetic.read_text())
        L += ["## Held-out synthetic test set", "",
              f"{s['frames']} frames ({aggregate(s)}); command: `{a.synthetic_command}`", ""] + table(s["methods"]) + [""] + verdict(s) + [""]
    for title, path, command in a.extra_synthetic:
        s = json.loads(Path(path).read_text())
        L += [f"## Held-out synthetic test set: {title}", "",
              f"{s['frames']} frames ({aggregate(s)}); command: `{command}`", ""] + table(s["methods"]) + [""] + verdict(s) + [""]
    if a.real:
        s = json.loads(a.real.read_text())
        L += ["## Real RGB-D sets (dToF simulated on their reference depth with this variant's preset)", "",
              f"Command: `{a.real_command}` ({aggregate(s)})", ""] + real_section(s, a.discussion) + [""]
    r = card["regression"]
    L += ["## Regression check", "",
          f"`host/tests/model_card.rs` rebuilds {r['scenes']} scenes (preset {r['preset']}, seed {r['seed']}) and fails "
          f"if the int8 RMSE exceeds 1.05 × {r['int8_rmse']} m (δ1 here {r['int8_delta1']})"
          + ", or if int8 falls behind float by more than 1 % in RMSE or 0.005 in δ1"
          + f". Command: `{r['command']}`.", ""]
    (d / "MODEL_CARD.md").write_text("\n".join(L))
    print(f"wrote {d / 'MODEL_CARD.md'} and {d / 'card.json'}")


if __name__ == "__main__":
    main()
