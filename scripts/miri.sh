#!/usr/bin/env bash
# Miri (nightly) on a subset of depthor-core's unit tests: the parsers (blob, CRC), the planner,
# the engine's safe API at 4×4 on the committed test-network blob, and the portable kernels
# (issue 45; what Miri cannot run and why: docs/reliability.md, "Miri").
#   bash scripts/miri.sh [FILTER...]     (default: the subset below)
# Under Miri `Isa::best()` is the portable set (no cpuid/xgetbv, see kernels/isa.rs), so the AVX
# and Arm `asm!` paths are skipped by the tests' own `available()` checks. Proptests run
# PROPTEST_CASES (default 4) cases; isolation is off so proptest can read its regression files.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
filters=("$@")
if [ ${#filters[@]} -eq 0 ]; then
  # The parsers and the planner's placement, the engine at 4×4, then the portable kernels whose
  # tests finish under Miri in minutes (the exhaustive ones, e.g. every int8 code pair, do not).
  filters=(
    blob:: engine::
    kernels::requant:: kernels::pool:: kernels::float:: kernels::bins::
    kernels::elementwise::tests::add_suite kernels::elementwise::tests::mul_suite
    kernels::elementwise::tests::concat_ kernels::elementwise::tests::minmax_norm_by_hand
    kernels::elementwise::tests::mul_fast_equals_ref_bits
    kernels::elementwise::tests::narrow_doubling_high_mul_is_gemmlowps
    kernels::elementwise::tests::pixel_shuffle_matches_pytorch_order
    kernels::wide::tests::any_geometry_matches_the_reference
  )
fi
export MIRIFLAGS="-Zmiri-disable-isolation ${MIRIFLAGS:-}"
export PROPTEST_CASES="${PROPTEST_CASES:-4}"
cargo +nightly miri test -p depthor-core --lib -- "${filters[@]}"
