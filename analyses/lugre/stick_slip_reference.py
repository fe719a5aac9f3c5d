"""The stick-slip block of data/scenes/lugre-stick-slip.toml against an independent computation.

The one-degree-of-freedom model of the same experiment (Canudas de Wit, Olsson, Astrom &
Lischinsky, IEEE Trans. Autom. Control 40(3):419-425, 1995: a 1 kg block, a 2 N/m spring whose
far end moves at 0.1 m/s, LuGre friction with normal force m g) is integrated with SciPy's Radau
method and compared with the block's motion in the program's run file.

    jointplay run data/scenes/lugre-stick-slip.toml --out out/lugre
    python analyses/lugre/stick_slip_reference.py out/lugre/lugre-stick-slip.h5

Needs h5py, numpy and scipy.
"""

import sys

import h5py
import numpy as np
from scipy.integrate import solve_ivp

# The scene's parameters (SI): the law per newton of normal force.
M, G, K, PULL = 1.0, 9.81, 2.0, 0.1
MU_C, MU_S, V_S = 0.101937, 0.152905, 1e-3
S0, S1, S2 = 10193.68, 32.2353, 0.0407747


def rhs(t, y):
    x, v, z = y
    g = MU_C + (MU_S - MU_C) * np.exp(-((v / V_S) ** 2))
    zd = v - S0 * abs(v) * z / g
    friction = (S0 * z + S1 * zd + S2 * v) * M * G
    return [v, (K * (PULL * t - x) - friction) / M, zd]


def rises(t, v, level=0.05):
    up = (v[:-1] < level) & (v[1:] >= level)
    return t[1:][up]


def main(path):
    with h5py.File(path, "r") as f:
        t = f["time"][:]
        x = f["bodies/block/position"][:, 0]
        v = f["bodies/block/velocity"][:, 0]
    ref = solve_ivp(rhs, (t[0], t[-1]), [0.0, 0.0, 0.0], method="Radau",
                    rtol=1e-10, atol=1e-13, t_eval=t, max_step=1e-3)
    if not ref.success:
        sys.exit(f"the reference integration failed: {ref.message}")
    xr, vr = ref.y[0], ref.y[1]
    print(f"samples                {len(t)} from {t[0]} to {t[-1]} s")
    print(f"max |x - x_ref|        {np.abs(x - xr).max():.3e} m (travel {np.abs(xr).max():.4f} m)")
    print(f"max |v - v_ref|        {np.abs(v - vr).max():.3e} m/s (peak {vr.max():.5f} m/s)")
    print(f"slips begin (v > 0.05) here {np.round(rises(t, v), 4)} s, reference {np.round(rises(t, vr), 4)} s")
    print(f"peak slip speed        here {v.max():.6f} m/s, reference {vr.max():.6f} m/s")


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    main(sys.argv[1])
