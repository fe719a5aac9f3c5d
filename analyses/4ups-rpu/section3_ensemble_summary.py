#!/usr/bin/env python3
"""Does every perturbed start reach the same motion? The summary of a section-3 ensemble.

  python3 analyses/4ups-rpu/section3_ensemble_summary.py out/4ups-rpu/section3-ensemble-0.3.h5

For each member of `analyses/4ups-rpu/section3-ensemble-*.toml` (the platform's initial Y
velocity perturbed by delta): its last strobe point of the S2, R1 and platform Y velocities,
how much its own last 10 strobe points still spread (convergence to a period-1 orbit), and the
ranges of the S2 and R1 Y eccentricities over the kept history (the orbit ranges the paper gives
at 0.3 and 0.7 mm). Then, over the ensemble: the spread of the members' last strobe points (one
attractor when it is as small as each member's own last-10 spread) and the mean and spread of
the orbit ranges.
"""
import sys

import h5py
import numpy as np


def main():
    with h5py.File(sys.argv[1], "r") as f:
        g = f["sweep"]
        delta = g["parameter"][:]
        done = g["done"][:] == 1
        h = g["history"]
        print("| delta (m/s) | S2 v_y (m/s) | R1 v_y (m/s) | platform v_y (m/s) | own last-10 spread, platform v_y (m/s) "
              "| S2 e_y range (mm) | R1 e_y range (mm) |")
        print("|---|---|---|---|---|---|---|")
        rows = []
        for j, d in enumerate(delta):
            if not done[j]:
                print(f"| {d:+.3f} | not done | | | | | |")
                continue
            last = {k: g[k][j][-1] for k in ("S2_vy", "R1_vy", "platform_vy")}
            own = np.ptp(g["platform_vy"][j][-10:])
            s2 = np.ptp(h["S2_ey"][j]) * 1e3
            r1 = np.ptp(h["R1_ey"][j]) * 1e3
            rows.append((last["S2_vy"], last["R1_vy"], last["platform_vy"], own, s2, r1))
            print(f"| {d:+.3f} | {last['S2_vy']:.9e} | {last['R1_vy']:.9e} | {last['platform_vy']:.9e} "
                  f"| {own:.1e} | {s2:.4f} | {r1:.4f} |")
        a = np.array(rows)
        print()
        print(f"members done: {len(rows)} of {len(delta)}")
        for i, name in enumerate(("S2 v_y", "R1 v_y", "platform v_y")):
            print(f"spread of the last strobe points over the ensemble, {name}: {np.ptp(a[:, i]):.2e} m/s")
        print(f"largest own last-10 spread, platform v_y: {a[:, 3].max():.2e} m/s")
        for i, name in ((4, "S2"), (5, "R1")):
            print(f"{name} e_y range: mean {a[:, i].mean():.4f} mm, spread (max - min) {np.ptp(a[:, i]):.4f} mm, "
                  f"sample standard deviation {a[:, i].std(ddof=1):.4f} mm")


if __name__ == "__main__":
    main()
