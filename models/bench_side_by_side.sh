#!/usr/bin/env bash
# Side by side in one run, one thread each: the core's int8 engine and tract f32
# (`depthor bench engine`) against ONNX Runtime f32 and int8 (QDQ, per-channel) on the same
# network, weights and size (`depthor_models.bench_onnx`), and LiteRT with XNNPACK f32 and int8
# (`depthor_models.bench_litert`, when models/.venv-litert exists: requirements-litert.txt),
# twice in turn so that a load change on a shared machine shows as a difference between the
# two rounds. The LiteRT conversion (onnx2tf) runs in round 1 and is reused in round 2.
# Usage: bash models/bench_side_by_side.sh [mcu|mcu_lite|phone|phone_lite] [runs]
# The depthor binary is built in $CARGO_TARGET_DIR (default target/).
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
variant="${1:-mcu}"
runs="${2:-20}"
cd "$here/.."
cargo build --release -q -p depthor-host
target="${CARGO_TARGET_DIR:-target}"
export DEPTHOR_CLI="${DEPTHOR_CLI:-$(cd "$target" && pwd)/release/depthor}"
litert=1
if [ ! -x models/.venv-litert/bin/python ]; then
  litert=0
  echo "== LiteRT skipped: no models/.venv-litert (python3.11 -m venv models/.venv-litert &&" \
    "models/.venv-litert/bin/pip install -r models/requirements-litert.txt)"
fi
for round in 1 2; do
  echo "== round $round: depthor bench engine --model $variant --runs $runs"
  "$DEPTHOR_CLI" bench engine --model "$variant" --runs "$runs"
  echo "== round $round: bench_onnx --variant $variant --runs $runs"
  (cd models && PYTHONPATH=. .venv/bin/python -m depthor_models.bench_onnx --variant "$variant" --runs "$runs")
  if [ "$litert" = 1 ]; then
    echo "== round $round: bench_litert --variant $variant --runs $runs"
    (cd models && PYTHONPATH=. .venv/bin/python -m depthor_models.bench_litert --variant "$variant" --runs "$runs")
  fi
done
