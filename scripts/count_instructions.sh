#!/usr/bin/env bash
# Instructions per frame on aarch64 of the core int8 engine (each kernel set) and of tract f32 on
# the same graph, side by side in one run, counted under qemu-aarch64 user mode with a TCG plugin
# (scripts/qemu-insns/insns.c). Per frame = (count at 3 frames − count at 1 frame) / 2, so
# loading, parsing, planning (and tract's model optimisation) drop out.
#   core:  core/examples/frames.rs, N frames of the blob with one kernel set; every set must
#          print the same output hash (same bits);
#   tract: `depthor bench engine --runtime tract --runs R` (one warm-up + R frames: R = 1 and 3)
#          on the model's NNEF export, the same graph in f32 at the same size.
# Then the ratio tract / core (best set) and MACs per instruction (MACs from the blob's plan).
#
#   bash scripts/count_instructions.sh [model dir, default models/mcu_lite] [QEMU CPU, default max]
#
# DEPTHOR_COUNT_TRACT=0 skips tract (its cross-build is the whole host crate).
# Needs: rustup target aarch64-unknown-linux-gnu, qemu-user, gcc-aarch64-linux-gnu, gcc
# (.ci/run installs them).
set -euo pipefail
cd "$(dirname "$0")/.."
model="${1:-models/mcu_lite}"
cpu="${2:-max}"
count_tract="${DEPTHOR_COUNT_TRACT:-1}"
target_dir="${CARGO_TARGET_DIR:-target}"
plugin="$target_dir/qemu-insns/libinsns.so"
mkdir -p "$(dirname "$plugin")"
gcc -O2 -shared -fPIC -o "$plugin" scripts/qemu-insns/insns.c
export CARGO_TARGET_AARCH64_UNKNOWN_LINUX_GNU_LINKER=aarch64-linux-gnu-gcc
cargo build --release -q -p depthor-core --example frames --target aarch64-unknown-linux-gnu
if [ "$count_tract" != 0 ]; then
  cargo build --release -q -p depthor-host --bin depthor --target aarch64-unknown-linux-gnu
fi
bin="$target_dir/aarch64-unknown-linux-gnu/release"
qemu() { qemu-aarch64 -cpu "$cpu" -L /usr/aarch64-linux-gnu -plugin "$plugin" "$@"; }
run() { # set frames -> "instructions hash macs"
  local out
  out=$(qemu "$bin/examples/frames" "$model/depthor.dblob" "$1" "$2" 2>&1)
  local insns hash macs
  insns=$(sed -n 's/^insns: //p' <<<"$out")
  hash=$(sed -n 's/.*output hash //p' <<<"$out")
  macs=$(sed -n 's/.*macs per frame \([0-9]*\).*/\1/p' <<<"$out")
  [ -n "$insns" ] && [ -n "$hash" ] || return 1 # the set is not on this CPU model
  echo "$insns $hash $macs"
}
echo "aarch64 (qemu-aarch64 -cpu $cpu), $model, instructions per frame:"
base="" best="" best_set="" macs=""
for set in portable neon neon-dot; do
  if ! one=$(run "$set" 1); then
    echo "  core $set: not on this CPU model"; continue
  fi
  three=$(run "$set" 3)
  read -r i1 _ _ <<<"$one"
  read -r i3 hash macs <<<"$three"
  per=$(( (i3 - i1) / 2 ))
  [ -z "$base" ] && base=$per
  if [ -z "$best" ] || [ "$per" -lt "$best" ]; then best=$per best_set=$set; fi
  awk -v s="$set" -v p="$per" -v b="$base" -v h="$hash" -v m="$macs" \
    'BEGIN { printf "  core %-9s %8.2f M  (%.2fx portable, %.3f MACs/instruction)  3-frame output hash %s\n", s, p / 1e6, b / p, m / p, h }'
done
if [ "$count_tract" != 0 ]; then
  tract() { # runs -> instructions
    local out
    out=$(qemu "$bin/depthor" bench engine --model "$model" --runtime tract --runs "$1" 2>&1)
    sed -n 's/^insns: //p' <<<"$out"
  }
  t1=$(tract 1)
  t3=$(tract 3)
  tper=$(( (t3 - t1) / 2 ))
  awk -v p="$tper" -v m="$macs" -v b="$best" -v s="$best_set" \
    'BEGIN { printf "  tract f32      %8.2f M  (%.3f MACs/instruction)\n  tract / core %s: %.2f\n", p / 1e6, m / p, s, p / b }'
fi
awk -v m="$macs" 'BEGIN { printf "  MACs per frame: %.2f M (the blob'"'"'s plan)\n", m / 1e6 }'
