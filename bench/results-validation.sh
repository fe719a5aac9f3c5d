#!/usr/bin/env bash
# Regenerates the numbers of book/src/results/validation.md: the test suite, which checks every
# bound of the page's table against its closed-form oracle (the measured values in the table were
# read when the tests were written; the tests assert the bounds), then the ideal and the clearance
# slider-crank of analyses/slider-crank-clearance/run.sh, whose first impact, approach speed and
# later impacts are printed from the clearance run's file.
#
#   bench/results-validation.sh [OUT_DIR]      (default out/slider-crank-clearance)
#
# About 2 minutes on 2 cores once built (the dev profile, optimised, as run.sh uses). Reading the
# file needs Python 3 with h5py (bench/requirements.txt) or the jointplay Python package.
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
cd "$root"
out=${1:-out/slider-crank-clearance}
echo "## cargo test --workspace"
cargo test --workspace
echo "## analyses/slider-crank-clearance/run.sh $out"
analyses/slider-crank-clearance/run.sh "$out"
python3 - "$out/slider-crank-clearance.h5" <<'PY'
import sys
import numpy as np
try:
    import h5py
    f = h5py.File(sys.argv[1], "r")
    get = lambda k: np.asarray(f[k][...], dtype=float)
except ImportError:
    import jointplay
    f = jointplay.load(sys.argv[1])
    get = lambda k: np.asarray(f[k], dtype=float)
t = get("time")
force = get("joints/piston_pin/normal_force").reshape(len(t), -1)[:, 0]
rate = get("joints/piston_pin/penetration_rate").reshape(len(t), -1)[:, 0]
touching = force > 0
starts = np.flatnonzero(np.diff(touching.astype(int)) == 1) + 1
ends = np.flatnonzero(np.diff(touching.astype(int)) == -1) + 1
peaks = [force[s:next((e for e in ends if e > s), len(t))].max() for s in starts]
i = int(np.argmax(force))
s0 = starts[0]
print(f"peak contact force {force[i]:.3e} N at t = {t[i] * 1e3:.2f} ms")
print(f"approach speed at the first impact {rate[s0 - 1:s0 + 1].max():.2f} m/s (t = {t[s0] * 1e3:.2f} ms)")
print(f"impacts {len(starts)}; largest force after the first {max(peaks[1:]):.3e} N")
PY
