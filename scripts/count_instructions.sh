#!/usr/bin/env bash
# Instructions per frame of the core int8 engine on aarch64, each kernel set side by side in one
# run, counted under qemu-aarch64 user mode with a TCG plugin (scripts/qemu-insns/insns.c).
# Per frame = (count at 3 frames − count at 1 frame) / 2, so parsing and planning drop out.
# Every set must print the same output hash (same bits).
#
#   bash scripts/count_instructions.sh [model dir, default models/mcu_lite] [QEMU CPU, default max]
#
# Needs: rustup target aarch64-unknown-linux-gnu, qemu-user, gcc-aarch64-linux-gnu, gcc
# (.ci/run installs them). tract f32 on the same graph is not counted yet (issue 40, item 3).
set -euo pipefail
cd "$(dirname "$0")/.."
model="${1:-models/mcu_lite}"
cpu="${2:-max}"
target_dir="${CARGO_TARGET_DIR:-target}"
plugin="$target_dir/qemu-insns/libinsns.so"
mkdir -p "$(dirname "$plugin")"
gcc -O2 -shared -fPIC -o "$plugin" scripts/qemu-insns/insns.c
CARGO_TARGET_AARCH64_UNKNOWN_LINUX_GNU_LINKER=aarch64-linux-gnu-gcc \
  cargo build --release -q -p depthor-core --example frames --target aarch64-unknown-linux-gnu
exe="$target_dir/aarch64-unknown-linux-gnu/release/examples/frames"
run() { # set frames -> "instructions hash"
  local out
  out=$(qemu-aarch64 -cpu "$cpu" -L /usr/aarch64-linux-gnu -plugin "$plugin" \
    "$exe" "$model/depthor.dblob" "$1" "$2" 2>&1)
  local insns hash
  insns=$(sed -n 's/^insns: //p' <<<"$out")
  hash=$(sed -n 's/.*output hash //p' <<<"$out")
  [ -n "$insns" ] && [ -n "$hash" ] || return 1 # the set is not on this CPU model
  echo "$insns $hash"
}
echo "core int8 on aarch64 (qemu-aarch64 -cpu $cpu), $model, instructions per frame:"
base=""
for set in portable neon neon-dot; do
  if ! one=$(run "$set" 1); then
    echo "  $set: not on this CPU model"; continue
  fi
  three=$(run "$set" 3)
  per=$(( (${three%% *} - ${one%% *}) / 2 ))
  [ -z "$base" ] && base=$per
  awk -v s="$set" -v p="$per" -v b="$base" -v h="${three##* }" \
    'BEGIN { printf "  %-9s %8.2f M  (%.2fx portable)  3-frame output hash %s\n", s, p / 1e6, b / p, h }'
done
