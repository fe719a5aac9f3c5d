"""Forced Duffing oscillator x'' + delta x' + alpha x + beta x^3 = gamma cos(omega t), the
equation of jointplay's built-in system `duffing` (crates/analysis/src/flow/systems.rs), integrated with
`scipy.integrate.solve_ivp`. Defaults as jointplay's: delta = 0.3, alpha = -1, beta = 1,
omega = 1.2; the benchmark starts at (x, x') = (1, 0) and sets gamma.
"""
import math

import numpy as np
from scipy.integrate import solve_ivp

DELTA, ALPHA, BETA, OMEGA = 0.3, -1.0, 1.0, 1.2
PERIOD = 2.0 * math.pi / OMEGA


def rhs(t, y, gamma):
    x, v = y
    return [v, gamma * math.cos(OMEGA * t) - DELTA * v - ALPHA * x - BETA * x**3]


def simulate(method, rtol, atol, gamma, periods):
    """States (x, v) at the strobe times k T, k = 1..periods, and the evaluation count."""
    strobe = np.arange(1, periods + 1) * PERIOD
    sol = solve_ivp(rhs, (0.0, periods * PERIOD), [1.0, 0.0], method=method, rtol=rtol,
                    atol=atol, t_eval=strobe, args=(gamma,))
    if sol.status != 0:
        raise RuntimeError(f"{method} rtol {rtol}: {sol.message}")
    return sol.y.T, {"nfev": sol.nfev}
