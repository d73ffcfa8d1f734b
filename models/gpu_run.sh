#!/bin/bash
# One GPU lease (a machine with CUDA PyTorch and many cores, reached with a copy of this tree):
# training data with the release simulator, then mcu_lite float fine-tuning (a) and
# quantisation-aware fine-tuning (b), each on a time-based OneCycle; results into $OUT
# (a_model_final.pt, a_run.tgz, b_model_final.pt, b_run.tgz). Run from the repository root:
#   strip -o d target/release/depthor && gzip -9c d > .devcarry/depthor.gz   # here
#   BATCH=64 TOTAL=530 bash models/gpu_run.sh                                   # there
# The run of 2026-12-04 (models/mcu_lite/train/gpu_a, gpu_b) is this script with those values,
# before --prefetch and the variant settings were added.
# Other variants: VARIANT=phone_lite PRESET=phone TEACHER_VARIANT=phone INIT= CLOSE= (INIT empty:
# from the seeded random network; CLOSE empty: no close-range half of the data).
set -u -o pipefail
export PYTHONUNBUFFERED=1 PYTHONPATH=$PWD/models
T0=$(date +%s)
el() { echo "[$(( $(date +%s) - T0 )) s] $*"; }
TOTAL=${TOTAL:-560}          # seconds this script may use in all
N=${N:-20000}                # frames per training seed
NS=${NS:-8}                  # shards per seed
DEV=${DEV:-cuda}
VARIANT=${VARIANT:-mcu_lite}
PRESET=${PRESET:-mcu}
TEACHER_VARIANT=${TEACHER_VARIANT:-mcu}
INIT0=${INIT-models/mcu_lite/train/model_final.pt}
CLOSE=${CLOSE-models/scenes/close_range.json}
BATCH=${BATCH:-32}
THREADS=${THREADS:-8}
OUT=${OUT:-/tmp/out}
W=${W:-/tmp/w}; D=$W/data; R=$W/runs
rm -rf "$W"; mkdir -p "$D" "$R" "$OUT"
gunzip -c "${DEPTHOR_BIN_GZ:-.devcarry/depthor.gz}" > "$W/depthor" && chmod +x "$W/depthor"
B=$W/depthor
nproc; nvidia-smi -L 2>/dev/null
python3 -c "import torch; print('torch', torch.__version__, 'cuda', torch.cuda.is_available())"

el "simulating $N + $N training frames in $NS + $NS shards, and the 48 + 48 check frames"
export RAYON_NUM_THREADS=2
TRAIN=""
TEST="$D/v"
for k in $(seq 0 $((NS - 1))); do
  "$B" sim --preset "$PRESET" --scenes "$N" --seed 1000 --shard "$k/$NS" --out "$D/tr$k" >/dev/null &
  TRAIN="$TRAIN,$D/tr$k"
  if [ -n "$CLOSE" ]; then
    "$B" sim --preset "$PRESET" --scenes "$N" --seed 3000000 --shard "$k/$NS" \
      --scene-config "$CLOSE" --out "$D/cl$k" >/dev/null &
    TRAIN="$TRAIN,$D/cl$k"
  fi
done
"$B" sim --preset "$PRESET" --scenes 48 --seed 800000 --out "$D/v" >/dev/null &
if [ -n "$CLOSE" ]; then
  "$B" sim --preset "$PRESET" --scenes 48 --seed 3800000 --scene-config "$CLOSE" \
    --out "$D/cv" >/dev/null &
  TEST="$D/cv,$D/v"
fi
wait
TRAIN=${TRAIN#,}
unset RAYON_NUM_THREADS
el "decoding frames into the training caches"
python3 - "$TRAIN,$TEST" <<'EOF'
import sys
from multiprocessing import Pool
from depthor_models import data
def load(p):
    return len(data.load_recording(p))
with Pool(16) as pool:
    print("frames:", sum(pool.map(load, sys.argv[1].split(","))))
EOF
el "data ready"
du -sh "$D"

left() { echo $(( TOTAL - ($(date +%s) - T0) )); }
COMMON=(--variant "$VARIANT" --stage depthor --teacher "models/$TEACHER_VARIANT/train/model_final.pt"
        --teacher-variant "$TEACHER_VARIANT" --kd-weight 1 --train "$TRAIN" --test "$TEST"
        --batch "$BATCH" --threads "$THREADS" --steps 1000000 --augment --prefetch --ckpt-every-s 90
        --device "$DEV")
# a: float; b: QAT. Overheads (start, data, final eval, cache save) ≈ 45 s per phase.
SA=$(( ($(left) - 90) * 55 / 100 ))
el "phase a: float, $SA s of steps"
INIT_ARGS=(); [ -n "$INIT0" ] && INIT_ARGS=(--init "$INIT0")
python3 -m depthor_models.train "${COMMON[@]}" "${INIT_ARGS[@]}" \
  --out "$R/a" --max-lr 3e-4 --seed 21 --schedule-s "$SA" --time-limit-s $((SA + 20)) \
  2>&1 | tee "$R/a.log" | awk '!/^step [0-9]+ loss/ || $2 % 500 == 0' 
cp "$R/a/model_final.pt" "$OUT/a_model_final.pt"
(cd "$R" && tar czf "$OUT/a_run.tgz" a.log a/train.csv a/eval.csv a/args.json a/loss.png)
el "phase a done"
INIT=$R/a/model_final.pt; [ -f "$INIT" ] || INIT=$INIT0
mkdir -p "$R/b"
for f in teacher_cache.npy teacher_cache.done.npy; do
  [ -f "$R/a/$f" ] && ln -s "$R/a/$f" "$R/b/$f"
done
SB=$(( $(left) - 50 ))
el "phase b: quantisation-aware from $INIT, $SB s of steps"
python3 -m depthor_models.train "${COMMON[@]}" --qat --init "$INIT" \
  --out "$R/b" --max-lr 5e-5 --seed 22 --schedule-s "$SB" --time-limit-s $((SB + 15)) \
  2>&1 | tee "$R/b.log" | awk '!/^step [0-9]+ loss/ || $2 % 500 == 0' 
cp "$R/b/model_final.pt" "$OUT/b_model_final.pt"
(cd "$R" && tar czf "$OUT/b_run.tgz" b.log b/train.csv b/eval.csv b/args.json b/loss.png b/ckpt.pt)
el "phase b done"
ls -la "$OUT"
