#!/usr/bin/env python3
"""Reads the files of `jointplay run` with h5py: a run, a comparison study and a sweep.

    jointplay run data/scenes/pendulum.toml --out out
    jointplay run analyses/4ups-rpu/ablation.toml --out out/4ups-rpu
    jointplay run analyses/duffing/cascade.toml --out out/duffing
    python3 read_with_h5py.py [OUT]          # OUT defaults to out

Every dataset carries its SI unit in the attribute `unit`; the layouts are in the book's
"HDF5 layouts" reference page.
"""
import sys
from pathlib import Path

import h5py
import numpy as np

out = Path(sys.argv[1] if len(sys.argv) > 1 else "out")

# A run: /time (s) and one dataset per recorded quantity, one column per component.
with h5py.File(out / "pendulum.h5", "r") as f:
    t = f["time"][:]                                # s, shape (n,)
    position = f["bodies/bob/position"][:]          # m, shape (n, 3): x, y, z
    unit = f["bodies/bob/position"].attrs["unit"]
    print(f"pendulum: {len(t)} samples from {t[0]} to {t[-1]} s, "
          f"x between {position[:, 0].min():.4f} and {position[:, 0].max():.4f} {unit}")
    print("  integrator:", f.attrs["integrator"], "| complete:", bool(f.attrs["complete"]))

# A comparison study: each case under /cases/<label>, in the order of the root attribute `cases`.
with h5py.File(out / "4ups-rpu" / "ablation.h5", "r") as f:
    for label in f.attrs["cases"].split(","):
        case = f["cases"][label]
        y = case["bodies/platform/position"][:, 1]  # m
        force = case["joints/S2/force_on_journal"][:]   # N, on the ball of S2
        print(f"ablation {label}: platform y {y[-1]:.6f} m at the end, "
              f"S2 force up to {np.linalg.norm(force, axis=1).max():.1f} N")

# A sweep: one row per value of /sweep/parameter, one column per kept drive period.
with h5py.File(out / "duffing" / "duffing-cascade.h5", "r") as f:
    gamma = f["sweep/parameter"][:]
    x = f["sweep/x"][:]                             # the strobe points of observable x
    done = f["sweep/done"][:] == 1                  # rows not done hold NaN
    print(f"cascade: {done.sum()} of {len(done)} values done, complete = {f.attrs['complete']}")
    for g0 in (0.2, 0.28, 0.29):
        row = x[np.argmin(abs(gamma - g0))]
        print(f"  gamma = {g0}: {len(np.unique(row[-16:].round(6)))} distinct strobe points")
