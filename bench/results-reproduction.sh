#!/usr/bin/env bash
# Regenerates the numbers of book/src/results/reproduction.md (Chen et al. 2023, sections 2 and 3,
# reproduced): the statics behind the direction of gravity (lever.py), every study run-all.sh
# runs (it rewrites the page's generated tables and copies its figures), then the long section-3
# studies and the continuations of the period-1 orbit, each followed by the summary script whose
# output the page's hand-kept tables quote.
#
#   bench/results-reproduction.sh [OUT_DIR]      (default out/4ups-rpu)
#
# About 5 hours on 2 cores: run-all.sh about 10 min, section3-fine 25 min, section3-chaos 24 min,
# section3-zero-one 53 min, periodic 2.5 h (its continuation alone), the rest minutes each.
# JOINTPLAY=path/to/jointplay uses that binary instead of building the release one. The summary
# scripts need Python 3 with h5py and numpy (bench/requirements.txt).
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
cd "$root"
out=${1:-out/4ups-rpu}
if [[ -z "${JOINTPLAY:-}" ]]; then
  cargo build --release --quiet
  JOINTPLAY=target/release/jointplay
fi
export JOINTPLAY
run() { # run STUDY: one study of analyses/4ups-rpu, with its wall time
  local start=$SECONDS
  "$JOINTPLAY" run "analyses/4ups-rpu/$1.toml" --out "$out" -q
  echo "$1: $((SECONDS - start)) s wall"
}
echo "## Which way is down? (lever.py)"
python3 analyses/4ups-rpu/lever.py
echo "## run-all.sh: sections 2.2-2.6, geometries, screen, short section 3, ramp, ensembles"
analyses/4ups-rpu/run-all.sh "$out"
python3 analyses/4ups-rpu/section3_quick_summary.py "$out/section3-quick.h5"
echo "## section 3 on the paper's grid, classified"
run section3-fine
python3 analyses/4ups-rpu/section3_quick_summary.py "$out/section3-fine.h5"
run section3-ideal
run section3-diagram
python3 analyses/4ups-rpu/section3_tolerance.py
echo "## the former default (gravity along -X), 50 periods"
run section3-portraits
run section3-bifurcation
python3 analyses/4ups-rpu/section3_summary.py "$out"
echo "## chaos measures"
run section3-chaos-hanging
run section3-chaos
run section3-zero-one
echo "## the period-1 orbit by shooting and its continuation"
run periodic-hanging
run periodic
echo "## the chaos and continuation tables, read from the files"
python3 - "$out" <<'PY'
import sys, math
import h5py
import numpy as np
out = sys.argv[1]
names = ["undetermined", "periodic", "quasi-periodic", "chaotic"]
for s in ["section3-chaos-hanging", "section3-chaos", "section3-zero-one"]:
    with h5py.File(f"{out}/{s}.h5", "r") as f:
        g = f["sweep"]
        c = g["chaos"]
        print(f"### {s}: clearance (mm), lambda_1 (1/s) +- stderr, two trajectories (1/s), class, 0-1 K")
        ex, se, tt = c["exponents"][:], c["stderr"][:], c["two_trajectory"][:]
        k = c["k"][:] if "k" in c else np.full(len(g["parameter"]), np.nan)
        for j, p in enumerate(g["parameter"][:]):
            print(f"| {p * 1e3:.2f} | {ex[j, 0]:+.3f} +- {se[j, 0]:.3f} | {tt[j, 0]:+.3f} +- {tt[j, 1]:.3f}"
                  f" | {names[int(c['class'][j])]} | {k[j]:.2f} |")
for s in ["periodic-hanging", "periodic"]:
    with h5py.File(f"{out}/{s}.h5", "r") as f:
        T = float(f.attrs["period"])
        b = f["continuation/branch_0"]
        print(f"### {s}: clearance (mm), mu_1, |mu_1|, ln|mu_1|/T (1/s), iterations, residual")
        for j, p in enumerate(b["parameter"][:]):
            mu = complex(b["multipliers_re"][j, 0], b["multipliers_im"][j, 0])
            print(f"| {p * 1e3:.3f} | {mu:.4f} | {abs(mu):.3f} | {math.log(abs(mu)) / T:+.3f}"
                  f" | {int(b['iterations'][j])} | {b['residual'][j]:.1e} |")
PY
