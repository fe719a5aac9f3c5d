#!/usr/bin/env python3
"""The measures of the paper's section 3 from the short section-3 analysis.

  python3 analyses/4ups-rpu/section3_quick_summary.py out/section3-quick.h5

For each clearance of `analyses/4ups-rpu/section3-quick.toml`: the spread (max - min) of the
stroboscopic points of the velocities the paper's bifurcation diagrams plot (S2 and R1
eccentricity rates along Y, the platform's Y velocity; for the platform also over the last 10
points, which shows whether the points still converge), and the range of the S2 and R1 Y
eccentricities over the kept history (the last drive periods), which the paper gives for 0.3 and
0.7 mm (S2 0.016 and 0.036 mm, R1 0.053 and 0.124 mm). When the study computed the chaos
measures (`section3-fine.toml`), three more columns: the largest Lyapunov exponent with its
standard error, the two-trajectory estimate, and the class.
"""
import sys

import h5py
import numpy as np

# /sweep/chaos/class (book/src/explanation/lyapunov.md).
CLASSES = ["undetermined", "periodic", "quasi-periodic", "chaotic"]


def main():
    with h5py.File(sys.argv[1], "r") as f:
        g = f["sweep"]
        params = g["parameter"][:]
        done = g["done"][:]
        h = g["history"]
        chaos = g["chaos"] if "chaos" in g else None
        head = ("| clearance (mm) | S2 e_y range (mm) | R1 e_y range (mm) | strobe spread S2 v_y (m/s) "
                "| strobe spread R1 v_y (m/s) | strobe spread platform v_y (m/s) | last-10 spread platform v_y (m/s) |")
        rule = "|---|---|---|---|---|---|---|"
        if chaos is not None:
            head += " lambda_1 (1/s) | two trajectories (1/s) | class |"
            rule += "---|---|---|"
        print(head)
        print(rule)
        for j, c in enumerate(params):
            if done[j] != 1:
                continue
            rng = lambda ds: np.ptp(h[ds][j]) * 1e3
            spread = lambda ds: np.ptp(g[ds][j])
            last = np.ptp(g["platform_vy"][j][-10:])
            row = (f"| {c * 1e3:.2f} | {rng('S2_ey'):.4f} | {rng('R1_ey'):.4f} | {spread('S2_vy'):.2e} "
                   f"| {spread('R1_vy'):.2e} | {spread('platform_vy'):.2e} | {last:.2e} |")
            if chaos is not None:
                lam, err = chaos["exponents"][j][0], chaos["stderr"][j][0]
                two = chaos["two_trajectory"][j]
                row += f" {lam:.3f} ± {err:.3f} | {two[0]:.3f} ± {two[1]:.3f} | {CLASSES[chaos['class'][j]]} |"
            print(row)


if __name__ == "__main__":
    main()
