#!/usr/bin/env bash
# Regenerates the numbers of book/src/results/hard-cases.md: the two runs that diverge (the
# clearance slider-crank with RK4 at h = 1e-4 s; the square-layout 4-UPS/RPU with U1 at -0.059 m
# standing on its base, with the paper's RK4) and the bundled hanging variant of the latter, which
# completes; the compile-time warning of Lankarani-Nikravesh at c_e = 0.3; then the hard-case
# suite with its long case, the diverging-run test of tests/cli.rs, and the fuzzing test with its
# counts printed.
#
#   bench/results-hard-cases.sh
#
# About 5 minutes on 2 cores once built. JOINTPLAY=path/to/jointplay uses that binary for the runs
# instead of building the release one.
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
cd "$root"
. bench/lib.sh
program
# solver SCENE LINES...: SCENE with its [solver] table replaced by LINES (one key each)
solver() {
  local scene=$1; shift
  awk -v lines="$(printf '%s\n' "$@")" '
    /^\[solver\]/ { print; printf "%s\n", lines; skip = 1; next }
    /^\[/ { skip = 0 }
    !skip { print }' "$scene"
}
echo "## the clearance slider-crank with RK4 at h = 1e-4 s (expected to stop)"
solver data/scenes/slider-crank-clearance.toml 'integrator = "rk4"' 'step = 1e-4' 'periods = 2' \
  >"$work/slider-crank-rk4.toml"
(cd "$work" && "$bin" run slider-crank-rk4.toml --out out --no-plots) || true
echo "## the square-layout 4-UPS/RPU, U1 at -0.059 m, standing, RK4 at h = 1e-4 s (expected to stop)"
python3 data/scenes/tools/gen_4ups_rpu.py --layout square --u1-sign -1 --clearance mixed \
  --gravity standing >"$work/square-u1neg-standing.toml"
(cd "$work" && "$bin" run square-u1neg-standing.toml --out out --no-plots) || true
echo "## the bundled variant, hanging from its base, with the same integrator (completes)"
"$bin" run data/scenes/variants/4ups-rpu-mixed-square-u1neg.toml --out "$work/out" --no-plots -q
echo "## Lankarani-Nikravesh at c_e = 0.3"
sed 's/restitution = 0.9/restitution = 0.3/' data/scenes/slider-crank-clearance.toml >"$work/ln03.toml"
(cd "$work" && "$bin" check ln03.toml 2>&1 | grep '^warning') || true
echo "## the hard-case suite, with its long case"
cargo test --release -p jointplay-analysis --test hard_cases -- --include-ignored
echo "## the diverging run of tests/cli.rs"
cargo test --release --test cli a_diverging_run_keeps_its_samples_in_a_file_marked_incomplete
echo "## bad input: the fuzzing test's counts"
cargo test --release -p jointplay-analysis --test fuzz_inputs -- --nocapture
