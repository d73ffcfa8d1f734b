#!/usr/bin/env bash
# Side by side in one run, one thread each: the core's int8 engine and tract f32
# (`depthor bench engine`) against ONNX Runtime f32 and int8 (QDQ, per-channel) on the same
# network, weights and size (`depthor_models.bench_onnx`), twice in turn so that a load change
# on a shared machine shows as a difference between the two rounds.
# Usage: bash models/bench_side_by_side.sh [mcu|mcu_lite|phone|phone_lite] [runs]
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
variant="${1:-mcu}"
runs="${2:-20}"
cd "$here/.."
cargo build --release -q -p depthor-host
for round in 1 2; do
  echo "== round $round: depthor bench engine --model $variant --runs $runs"
  ./target/release/depthor bench engine --model "$variant" --runs "$runs"
  echo "== round $round: bench_onnx --variant $variant --runs $runs"
  (cd models && PYTHONPATH=. .venv/bin/python -m depthor_models.bench_onnx --variant "$variant" --runs "$runs")
done
