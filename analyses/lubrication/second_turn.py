"""The dry and lubricated slider-crank over its second crank turn, from the study's file.

    jointplay run analyses/lubrication/slider-crank.toml --out out/lubrication
    python analyses/lubrication/second_turn.py out/lubrication/slider-crank-lubricated.h5

Per case: the share of the turn the journal spends in asperity contact (penetration > 0), the
largest asperity (normal) force, the largest film force, the largest slider acceleration and the
deepest penetration (negative: the thinnest film). SI units.
"""

import sys

import h5py
import numpy as np

PERIOD = 60.0 / 5000.0  # s: one crank turn at 5000 rpm


def main(path):
    with h5py.File(path, "r") as f:
        for label, case in f["cases"].items():
            t = case["time"][:]
            pin = case["joints/piston_pin"]
            turn = t >= PERIOD
            pen = pin["penetration"][:, 0][turn]
            normal = pin["normal_force"][:, 0][turn]
            film = (
                np.linalg.norm(pin["film_force"][:][turn], axis=1).max()
                if "film_force" in pin
                else 0.0
            )
            acc = np.abs(case["bodies/slider/acceleration"][:, 0][turn]).max()
            print(
                f"{label:20s} contact {100 * np.mean(pen > 0):5.1f} %  "
                f"asperity {normal.max():8.0f} N  film {film:7.0f} N  "
                f"|a| {acc:8.0f} m/s^2  deepest {1e6 * pen.max():6.1f} um"
            )


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "out/lubrication/slider-crank-lubricated.h5")
