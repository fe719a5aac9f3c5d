#!/usr/bin/env python3
"""How much of the slider-crank's cost comes from the way the contact onset is handled?

The peer in slider_crank.py stops the integration at every contact onset and end (terminal
solve_ivp events) and restarts it, so that no step straddles the onset and the onset velocity is
exact. jointplay instead steps across: during the step in which the penetration becomes positive the
damped law uses the current penetration rate as the onset velocity, and once the step is accepted the
onset velocity is located on the cubic Hermite interpolant of the penetration and the first stage of
the next step is re-evaluated (crates/solver/src/dynamics/onset.rs, update_onsets; ode/step_loop.rs). This script
integrates the same SciPy model with the same RK45 (Dormand-Prince 5(4)) both ways, driving
scipy.integrate.RK45 step by step for the second, and prints error and right-hand-side evaluations.

    python3 bench/onset_diagnostic.py
"""
import math
import sys
import time
from pathlib import Path

import numpy as np
from scipy.integrate import RK45

sys.path.insert(0, str(Path(__file__).resolve().parent))
import slider_crank as sc  # noqa: E402


def hermite_onset(d0, r0, d1, r1, h):
    """Rate where the cubic Hermite interpolant of delta crosses zero (bisection), as jointplay."""
    def p(s):
        return ((2 * s**3 - 3 * s**2 + 1) * d0 + (s**3 - 2 * s**2 + s) * h * r0
                + (-2 * s**3 + 3 * s**2) * d1 + (s**3 - s**2) * h * r1)

    def dp(s):
        return ((6 * s**2 - 6 * s) * d0 + (3 * s**2 - 4 * s + 1) * h * r0
                + (-6 * s**2 + 6 * s) * d1 + (3 * s**2 - 2 * s) * h * r1)

    lo, hi = 0.0, 1.0
    for _ in range(50):
        mid = 0.5 * (lo + hi)
        if p(mid) > 0.0:
            hi = mid
        else:
            lo = mid
    return dp(0.5 * (lo + hi)) / h


def simulate_stepping_across(rtol, atol, samples):
    """RK45 without restarts, with jointplay's provisional and then located onset velocity."""
    hist = {"v_on": math.nan}
    nfev = [0]

    def f(t, y):
        nfev[0] += 1
        return sc.rhs(t, y, hist["v_on"])

    solver = RK45(f, 0.0, sc.initial_state(), sc.T_END, rtol=rtol, atol=atol)
    out = np.full((len(samples), 18), np.nan)
    out[0] = sc.initial_state()
    k = 1
    with np.errstate(all="ignore"):
        while solver.status == "running":
            t0, y0 = solver.t, solver.y.copy()
            solver.step()
            t1, y1 = solver.t, solver.y
            dense = solver.dense_output()
            while k < len(samples) and samples[k] <= t1:
                out[k] = dense(samples[k])
                k += 1
            a, b = sc.contact(y0), sc.contact(y1)
            if b[0] <= 0.0:
                hist["v_on"] = math.nan
            elif math.isnan(hist["v_on"]):
                hist["v_on"] = a[1] if a[0] > 0.0 else hermite_onset(a[0], a[1], b[0], b[1],
                                                                       t1 - t0)
                solver.f = f(t1, y1)  # the history changed the right-hand side at y1
    return out, nfev[0]


def main():
    ts = np.arange(2401) * 1e-5
    ref, _ = sc.simulate("DOP853", 3e-14, 3e-17, ts)
    print("| rtol | events and restarts: error (m) | RHS | stepping across: error (m) | RHS |")
    print("|---|---|---|---|---|")
    for rtol in (1e-6, 1e-7, 1e-8, 1e-9, 1e-10):
        y1, info = sc.simulate("RK45", rtol, rtol * 1e-3, ts)
        t = time.perf_counter()
        y2, n2 = simulate_stepping_across(rtol, rtol * 1e-3, ts)
        e1 = np.max(np.abs(y1[:, 6] - ref[:, 6]))
        e2 = np.max(np.abs(y2[:, 6] - ref[:, 6]))
        print(f"| {rtol:.0e} | {e1:.2e} | {info['nfev']} | {e2:.2e} | {n2} |")


if __name__ == "__main__":
    main()
