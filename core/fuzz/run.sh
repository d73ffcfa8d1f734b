#!/usr/bin/env bash
# Runs each cargo-fuzz target for SECONDS on its committed seeds (core/fuzz/seeds/<target>) plus
# the local, uncommitted corpus core/fuzz/corpus/<target> (new inputs go there).
#   core/fuzz/run.sh SECONDS [TARGET...]      (all targets when none is named)
# Needs the nightly toolchain and cargo-fuzz (`cargo install cargo-fuzz`). Builds once, then
# runs the targets one after another, niced; stops at the first crash (libFuzzer writes the
# input to core/fuzz/artifacts/<target>/) and exits non-zero. Each run's final statistics
# (executions, exec/s, cov/ft) are in core/fuzz/logs/<target>.log.
set -euo pipefail
cd "$(dirname "$0")/.."
secs=${1:?usage: run.sh SECONDS [TARGET...]}
shift
targets=("$@")
if [ ${#targets[@]} -eq 0 ]; then
  targets=(parse_blob engine_run projection zone_bridge replay_image vl53l5cx_results vl53l5cx_driver zone_gate)
fi
mkdir -p fuzz/logs
# AddressSanitizer's checks as calls, not inline shadow compares: the coverage build traces
# every comparison, ASan's included, which made the byte loops (dot kernels, CRC, firmware
# upload) several times slower. The same checks; `cov` counts fewer edges (ASan's own branches
# are gone).
export RUSTFLAGS="${RUSTFLAGS:-} -Cllvm-args=-asan-instrumentation-with-call-threshold=0"
nice -n 10 cargo +nightly fuzz build
for t in "${targets[@]}"; do
  mkdir -p "fuzz/corpus/$t"
  dict=()
  if [ "$t" = parse_blob ]; then dict=(-dict="$PWD/fuzz/blob.dict"); fi
  echo "== fuzz $t for ${secs}s"
  if ! nice -n 10 cargo +nightly fuzz run "$t" "$PWD/fuzz/corpus/$t" "$PWD/fuzz/seeds/$t" -- \
    -max_total_time="$secs" -timeout=10 -rss_limit_mb=2048 -print_final_stats=1 "${dict[@]}" \
    >"fuzz/logs/$t.log" 2>&1; then
    tail -n 40 "fuzz/logs/$t.log"
    echo "fuzz target $t failed (log: core/fuzz/logs/$t.log)"
    exit 1
  fi
  grep -E '^#[0-9]+ +DONE|stat::number_of_executed_units|stat::average_exec_per_sec' "fuzz/logs/$t.log"
done
