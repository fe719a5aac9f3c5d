#!/usr/bin/env bash
# Regenerates the numbers of book/src/results/effects.md (what each effect costs): the effects and
# run_rate benches (the latter also in its paired mode), whole runs of the mixed 4-UPS/RPU as
# `jointplay run` reports them (the paper's 2-period RK4 run, 10 s and 50 periods with DOPRI5 at
# rtol 1e-6, 50 periods with bs3 at rtol 1e-3), the instructions of a 10 s run per thread
# (valgrind, when installed) and the SciPy comparison (bench/compare.py).
#
#   bench/results-effects.sh [OLD]     # OLD: an earlier jointplay binary, set beside this one
#                                      # by bench/writer.sh OLD NEW (about 3 min more)
#
# About 15 minutes on 2 cores once built. Wall times drift with the machine's speed: compare the
# numbers of one invocation. The `perf` shares quoted on the page are profiles taken by hand
# (`perf record` on `jointplay run`), not rerun here. JOINTPLAY=path/to/jointplay uses that binary
# instead of building the release one; bench/compare.py needs bench/requirements.txt.
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
cd "$root"
. bench/lib.sh
program
scene 5 "$work/p5.toml"    # 10 s, DOPRI5 rtol 1e-6, atol 1e-9, 1 ms output
scene 50 "$work/p50.toml"  # 100 s
sed -e 's/^integrator = "dopri5"/integrator = "bs3"/' -e 's/^rtol = 1e-6/rtol = 1e-3/' \
  -e 's/^atol = 1e-9/atol = 1e-6/' "$work/p50.toml" >"$work/bs3-p50.toml"
# lines RUN_OUTPUT: the summary lines of `jointplay run` that the page quotes
lines() { grep -E '^(steps|RHS|wall time)'; }
run() { "$bin" run "$@" --out "$work/out" --no-plots -q; }

echo "## effects bench (one right-hand side per variant)"
cargo bench -p jointplay-analysis --bench effects
echo "## run_rate bench"
cargo bench -p jointplay-analysis --bench run_rate
echo "## run_rate bench, paired mode"
RUN_RATE_PAIRED=12 RUN_RATE_PAIRED_50=3 cargo bench -p jointplay-analysis --bench run_rate

echo "## 4ups-rpu-mixed.toml as bundled (RK4, h = 1e-4 s, 2 periods), three runs"
for _ in 1 2 3; do run data/scenes/4ups-rpu-mixed.toml | lines; done
echo "## 10 s, DOPRI5 rtol 1e-6: time besides the integration over 20 runs (ms: median, min, max)"
for _ in $(seq 20); do
  run "$work/p5.toml" | awk '/^wall time/ { printf "%.0f\n", 1000 * ($6 - $3) }'
done | sort -g | awk '{ v[NR] = $1 } END { print v[int((NR + 1) / 2)], v[1], v[NR] }'
echo "## 50 periods, DOPRI5 rtol 1e-6, three runs (evaluations per second of integration)"
for _ in 1 2 3; do run "$work/p50.toml" | lines; done
echo "## 50 periods, bs3 rtol 1e-3, two runs (whole process, s)"
for _ in 1 2; do
  t0=$(date +%s.%N); run "$work/bs3-p50.toml" >/dev/null; t1=$(date +%s.%N)
  awk -v a="$t0" -v b="$t1" 'BEGIN { printf "%.2f\n", b - a }'
done
if command -v valgrind >/dev/null; then
  echo "## 10 s run: instructions per thread (valgrind --tool=callgrind --separate-threads=yes)"
  (cd "$work" && valgrind --tool=callgrind --separate-threads=yes --callgrind-out-file=cg.out \
    "$bin" run p5.toml --out out --no-plots -q >/dev/null 2>&1)
  for f in "$work"/cg.out-*; do # one file per thread
    awk -v t="${f##*-}" '/^summary:/ { printf "thread %s: %.2f G\n", t, $2 / 1e9; exit }' "$f"
  done
fi
if [[ $# -ge 1 ]]; then
  echo "## bench/writer.sh $1 $bin"
  bench/writer.sh "$1" "$bin"
fi
echo "## against SciPy (bench/compare.py)"
python3 bench/compare.py --jointplay "$bin"
