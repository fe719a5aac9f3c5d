"""The slider-crank with a translational clearance against Siconos's impulsive result.

    jointplay run data/scenes/slider-crank-translational.toml --out out/slider-crank-translational
    python analyses/slider-crank-translational/compare_siconos.py \
        out/slider-crank-translational/slider-crank-translational.h5

Prints, at a few times, the crank's turns and rate in this run and in Siconos's
(data/reference/siconos-slider-crank-translational.csv), and the mechanical energy of both (J):
for Siconos's run it is computed here from its angles and rates with the mass matrix and gravity
of its plugin (SliderCrankPlugin.cpp), for this run it is the file's diagnostics/energy.
SI units.
"""

import sys
from pathlib import Path

import h5py
import numpy as np

L1, L2, M1, M2, M3 = 0.153, 0.306, 0.038, 0.038, 0.076
J1, J2, J3, G = 7.4e-5, 5.9e-4, 2.7e-6, 9.81
REFERENCE = Path(__file__).resolve().parents[2] / "data/reference/siconos-slider-crank-translational.csv"


def siconos_energy(q0, q1, q2, v0, v1, v2):
    """Kinetic plus gravitational energy of Siconos's three-coordinate model (J)."""
    m11 = J1 + (0.25 * M1 + M2 + M3) * L1 * L1
    m12 = (0.5 * M2 + M3) * L1 * L2 * np.cos(q1 - q0)
    m22 = J2 + (0.25 * M2 + M3) * L2 * L2
    kinetic = 0.5 * (m11 * v0 * v0 + 2 * m12 * v0 * v1 + m22 * v1 * v1 + J3 * v2 * v2)
    potential = (0.5 * M1 + M2 + M3) * G * L1 * np.sin(q0) + (0.5 * M2 + M3) * G * L2 * np.sin(q1)
    return kinetic + potential


def main(path):
    ref = np.loadtxt(REFERENCE, delimiter=",", comments="#", skiprows=9)
    with h5py.File(path, "r") as f:
        t = f["time"][:]
        q = f["bodies/crank/orientation"][:]
        crank = np.unwrap(2 * np.arctan2(q[:, 3], q[:, 0]))
        rate = f["bodies/crank/angular_velocity"][:, 2]
        energy = f["diagnostics/energy"][:]
    print("t (s)   turns here / Siconos   rate here / Siconos (rad/s)   energy here / Siconos (J)")
    for at in [0.0, 0.01, 0.025, 0.05, 0.1, 0.15, 0.2]:
        k, r = np.argmin(abs(t - at)), ref[np.argmin(abs(ref[:, 0] - at))]
        e_ref = siconos_energy(r[1], r[2], r[3], r[4], r[5], r[6])
        print(
            f"{at:5.3f}   {crank[k] / (2 * np.pi):6.4f} / {r[1] / (2 * np.pi):6.4f}"
            f"        {rate[k]:7.2f} / {r[4]:7.2f}              {energy[k]:6.4f} / {e_ref:6.4f}"
        )


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "out/slider-crank-translational/slider-crank-translational.h5")
