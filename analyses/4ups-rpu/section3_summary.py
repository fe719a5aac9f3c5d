#!/usr/bin/env python3
"""Summarise the section-3 studies of the 4-UPS/RPU from their HDF5 files (markdown tables).

    python3 analyses/4ups-rpu/section3_summary.py out/4ups-rpu

For each clearance and observable: the spread (max - min) of the stroboscopic points over the
kept periods, the range of the motion itself over one period (from the time histories, portraits
study only), and the number of distinct points at a tolerance of 1 % of that spread's scale
(a cluster that keeps shrinking is a converging periodic motion; a spread comparable to the
motion's range means no periodic attractor has been reached).
"""
import sys

import h5py
import numpy as np

OBS = [
    ("platform_x", "platform X", 1e3, "mm"),
    ("platform_y", "platform Y", 1e3, "mm"),
    ("S2_ey", "S2 Y eccentricity", 1e3, "mm"),
    ("R1_ey", "R1 Y eccentricity", 1e3, "mm"),
]


def table(path, with_range):
    with h5py.File(path, "r") as f:
        s = f["sweep"]
        done = s["done"][:] == 1
        p = s["parameter"][:]
        head = "| clearance (mm) | quantity | spread of the strobe points | last-10 spread |"
        if with_range:
            head += " range over one period |"
        print(head)
        print("|" + "---|" * (head.count("|") - 1))
        period = f.attrs["period"]
        spp = int(f.attrs["samples_per_period"])
        for j in np.flatnonzero(done):
            for name, label, scale, unit in OBS:
                if name not in s:
                    continue
                pts = s[name][j] * scale
                spread = np.ptp(pts)
                late = np.ptp(pts[-10:])
                row = f"| {p[j] * 1e3:.1f} | {label} | {spread:.4g} {unit} | {late:.4g} {unit} |"
                if with_range and "history" in s and spp > 0:
                    h = s["history"][name][j][-spp - 1:] * scale
                    row += f" {np.ptp(h):.4g} {unit} |"
                print(row)
        failed = np.flatnonzero(s["done"][:] == 2)
        for j in failed:
            print(f"\nvalue {p[j]}: failed: {s['errors'].attrs[str(j)]}")
        w = s["wall_time"][:]
        print(
            f"\nwall time per value: {', '.join(f'{x:.0f} s' for x in w[done])}"
            f" (total {f.attrs.get('wall_time', float('nan')):.0f} s on the machine's cores);"
            f" drive period {period:.4f} s"
        )


def main(out):
    print("### Phase portraits and Poincare maps (section3-portraits)\n")
    table(f"{out}/section3-portraits.h5", True)
    print("\n### Bifurcation sweep (section3-bifurcation)\n")
    table(f"{out}/section3-bifurcation.h5", False)


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "out/4ups-rpu")
