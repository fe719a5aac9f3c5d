"""Planar slider-crank with a revolute clearance joint between connecting rod and slider, written
the classic way (Nikravesh, *Computer-Aided Analysis of Mechanical Systems*, 1988; Flores &
Ambrosio, Comput. Struct. 82:1359-1369, 2004): Cartesian coordinates (x, y, phi) of the centre of
mass of each body, ideal joints as constraints with Lagrange multipliers and Baumgarte
stabilisation, the clearance joint as a pair of contact forces, integrated with
`scipy.integrate.solve_ivp`.

The model is that of `data/scenes/slider-crank-clearance.toml`:

* crank (body 1): 0.30 kg, J = 1e-4 kg m^2, length 0.05 m, centre of mass at its middle, pivoted
  on the ground at the origin and driven at a constant 5000 rpm (phi_1 = omega t);
* connecting rod (body 2): 0.21 kg, J = 2.5e-4 kg m^2, length 0.12 m, centre of mass at its
  middle, pinned to the crank tip (ideal revolute joint);
* slider (body 3): 0.14 kg, J = 1e-4 kg m^2, on a frictionless guide along the x axis through the
  origin (y_3 = 0, phi_3 = 0);
* clearance joint between rod end (journal, radius 9.5 mm) and slider (bearing, radius 10.0 mm,
  radial clearance c = 0.5 mm): e = r_journal - r_bearing, penetration delta = |e| - c, normal
  n = e/|e|, penetration rate delta' = (v_journal - v_bearing) . n;
  Lankarani-Nikravesh law F = K delta^1.5 (1 + D delta'/delta'_0), D = 3 (1 - c_e^2)/4,
  c_e = 0.9, K = 4/(3 (eta_i + eta_j)) sqrt(R_i R_j/(R_j - R_i)), eta = (1 - nu^2)/E,
  E = 207 GPa, nu = 0.3 (K = 6.6102e10 N/m^1.5); F is never negative; no friction. delta'_0 is
  the approach velocity at the onset of the contact, floored at 1e-3 m/s, as jointplay does;
* gravity 9.81 m/s^2 along -y;
* start at top dead centre (phi_1 = phi_2 = 0) on the ideal mechanism's velocities (crank at
  omega, rod at -r omega / l, slider at rest), journal centred in the bearing; two crank turns
  (0.024 s).

The onset velocity is history: it is located exactly by a terminal `solve_ivp` event where the
penetration crosses zero upwards, and the integration is restarted there with the new value (and
again where the contact ends). Between events the right-hand side is smooth.
"""
import math

import numpy as np
from scipy.integrate import solve_ivp

# Geometry and inertia (SI).
R_CRANK = 0.05
L_ROD = 0.12
M = np.array([0.30, 0.30, 1.0e-4, 0.21, 0.21, 2.5e-4, 0.14, 0.14, 1.0e-4])
OMEGA = 5000.0 * 2.0 * math.pi / 60.0  # rad/s
GRAVITY = 9.81
T_END = 2 * 60.0 / 5000.0  # two crank turns (s)

# Points relative to each body's centre of mass, in body axes (only x components are non-zero).
S1_O = -0.5 * R_CRANK  # crank: ground pivot
S1_B = 0.5 * R_CRANK  # crank: crank pin
S2_B = -0.5 * L_ROD  # rod: crank pin
S2_C = 0.5 * L_ROD  # rod: journal centre (piston pin)

# Clearance joint and contact law.
R_JOURNAL = 0.0095
R_BEARING = 0.0100
CLEARANCE = R_BEARING - R_JOURNAL
E_MOD, NU = 207e9, 0.3
ETA = (1.0 - NU**2) / E_MOD
K_CONTACT = 4.0 / (3.0 * 2.0 * ETA) * math.sqrt(R_JOURNAL * R_BEARING / (R_BEARING - R_JOURNAL))
C_E = 0.9
D_LN = 0.75 * (1.0 - C_E**2)
V_FLOOR = 1e-3  # m/s
N_EXP = 1.5

# Baumgarte parameters (jointplay's defaults).
ALPHA = 5.0
BETA = 5.0


def initial_state():
    """y = [x1, y1, phi1, x2, y2, phi2, x3, y3, phi3, and their rates]."""
    w2 = -R_CRANK * OMEGA / L_ROD
    q = [0.5 * R_CRANK, 0.0, 0.0, R_CRANK + 0.5 * L_ROD, 0.0, 0.0, R_CRANK + L_ROD, 0.0, 0.0]
    qd = [0.0, 0.5 * R_CRANK * OMEGA, OMEGA, 0.0, 0.5 * R_CRANK * OMEGA, w2, 0.0, 0.0, 0.0]
    return np.array(q + qd)


def contact(y):
    """Penetration (m), its rate (m/s, approach positive), normal n and the eccentricity e."""
    x2, y2, f2 = y[3], y[4], y[5]
    x2d, y2d, f2d = y[12], y[13], y[14]
    c2, s2 = math.cos(f2), math.sin(f2)
    ex = x2 + S2_C * c2 - y[6]
    ey = y2 + S2_C * s2 - y[7]
    d = np.float64(math.hypot(ex, ey))  # numpy scalar: a trial step far into the wall gives
    delta = d - CLEARANCE  # inf (a rejected step), not an OverflowError
    if d == 0.0:
        return delta, 0.0, (0.0, 0.0), (ex, ey)
    nx, ny = ex / d, ey / d
    vx = x2d - S2_C * s2 * f2d - y[15]
    vy = y2d + S2_C * c2 * f2d - y[16]
    return delta, vx * nx + vy * ny, (nx, ny), (ex, ey)


def normal_force(delta, delta_dot, v_on, damping=D_LN):
    if delta <= 0.0:
        return 0.0
    if math.isnan(v_on):  # onset not yet located (see onset_diagnostic.py): jointplay's rule
        v_on = delta_dot
    f = K_CONTACT * delta**N_EXP * (1.0 + damping * delta_dot / max(abs(v_on), V_FLOOR))
    return max(f, 0.0)


def rhs(t, y, v_on, damping=D_LN):
    """Equations of motion [M Phi_q^T; Phi_q 0] [q''; lambda] = [Q; gamma - 2a Phi' - b^2 Phi]."""
    q, qd = y[:9], y[9:]
    f1, f2 = q[2], q[5]
    if not (math.isfinite(f1) and math.isfinite(f2)):
        # A trial stage that overflowed: NaN makes solve_ivp reject the step and shrink it
        # (math.cos would raise instead).
        return np.full(len(y), np.nan)
    c1, s1, c2, s2 = math.cos(f1), math.sin(f1), math.cos(f2), math.sin(f2)
    w1, w2 = qd[2], qd[5]

    # Constraints: crank pivot (2), crank pin (2), guide (y3 = 0, phi3 = 0), driver (phi1 = w t).
    phi = np.array([
        q[0] + S1_O * c1,
        q[1] + S1_O * s1,
        q[0] + S1_B * c1 - q[3] - S2_B * c2,
        q[1] + S1_B * s1 - q[4] - S2_B * s2,
        q[7],
        q[8],
        q[2] - OMEGA * t,
    ])
    jac = np.zeros((7, 9))
    jac[0, 0] = jac[1, 1] = 1.0
    jac[0, 2], jac[1, 2] = -S1_O * s1, S1_O * c1
    jac[2, 0] = jac[3, 1] = 1.0
    jac[2, 2], jac[3, 2] = -S1_B * s1, S1_B * c1
    jac[2, 3] = jac[3, 4] = -1.0
    jac[2, 5], jac[3, 5] = S2_B * s2, -S2_B * c2
    jac[4, 7] = 1.0
    jac[5, 8] = 1.0
    jac[6, 2] = 1.0
    phi_t = np.array([0, 0, 0, 0, 0, 0, -OMEGA])
    phi_dot = jac @ qd + phi_t
    gamma = np.array([
        S1_O * c1 * w1**2,
        S1_O * s1 * w1**2,
        S1_B * c1 * w1**2 - S2_B * c2 * w2**2,
        S1_B * s1 * w1**2 - S2_B * s2 * w2**2,
        0.0,
        0.0,
        0.0,
    ])

    # Applied forces: gravity and the contact force on journal (rod) and bearing (slider).
    force = np.array([0.0, -M[0] * GRAVITY, 0.0, 0.0, -M[3] * GRAVITY, 0.0,
                      0.0, -M[6] * GRAVITY, 0.0])
    delta, delta_dot, (nx, ny), _ = contact(y)
    if delta > 0.0:
        fn = normal_force(delta, delta_dot, v_on, damping)
        fx, fy = -fn * nx, -fn * ny  # on the journal
        force[3] += fx
        force[4] += fy
        # Moment about the rod's centre of mass; the contact point lies on the line of n
        # through the journal centre, so the lever arm is the rod's half-length.
        force[5] += S2_C * c2 * fy - S2_C * s2 * fx
        force[6] -= fx
        force[7] -= fy

    a = np.zeros((16, 16))
    a[:9, :9] = np.diag(M)
    a[:9, 9:] = jac.T
    a[9:, :9] = jac
    b = np.concatenate([force, gamma - 2.0 * ALPHA * phi_dot - BETA**2 * phi])
    x = np.linalg.solve(a, b)
    return np.concatenate([qd, x[:9]])


def _start(t, y, *args):
    return contact(y)[0]


_start.terminal = True
_start.direction = 1.0


def _end(t, y, *args):
    return contact(y)[0]


_end.terminal = True
_end.direction = -1.0


def simulate(method, rtol, atol, samples, t_end=T_END, max_step=np.inf, damping=D_LN,
             events=True):
    """Integrates over [0, t_end]; returns the states at `samples` (shape (len(samples), 18)) and
    counters. Each contact onset and end is an event that restarts the integration. With
    `damping = 0` (Hertz law, no history) `events = False` integrates in one go, stepping across
    the contact onsets and ends."""
    if not events:
        if damping != 0.0:
            raise ValueError("the onset velocity of a damped law needs the events")
        with np.errstate(all="ignore"):
            sol = solve_ivp(rhs, (0.0, t_end), initial_state(), method=method, rtol=rtol,
                            atol=atol, t_eval=samples, args=(1.0, 0.0), max_step=max_step)
        if sol.status != 0:
            raise RuntimeError(f"{method} rtol {rtol}: {sol.message}")
        return sol.y.T, {"nfev": sol.nfev, "segments": 1, "impacts": []}
    samples = np.asarray(samples, dtype=float)
    y = initial_state()
    t = 0.0
    v_on = None  # None: free flight; else the onset velocity of the current contact
    out = np.full((len(samples), 18), np.nan)
    nfev = 0
    nseg = 0
    impacts = []
    with np.errstate(all="ignore"):
        while t < t_end:
            sel = (samples > t) | ((samples == t) & (t == 0.0))
            idx = np.nonzero(sel)[0]
            sol = solve_ivp(rhs, (t, t_end), y, method=method, rtol=rtol, atol=atol,
                            t_eval=samples[idx], events=_end if v_on is not None else _start,
                            args=(v_on if v_on is not None else 0.0, damping),
                            max_step=max_step)
            nseg += 1
            nfev += sol.nfev
            if sol.status < 0:
                raise RuntimeError(f"{method} rtol {rtol}: {sol.message} at t = {t}")
            n = np.size(sol.t)
            if n:
                out[idx[:n]] = np.asarray(sol.y).T
            if sol.status == 1:
                t = float(sol.t_events[0][0])
                y = sol.y_events[0][0].copy()
                if v_on is None:
                    delta, delta_dot, _, _ = contact(y)
                    v_on = delta_dot
                    impacts.append((t, delta_dot))
                else:
                    v_on = None
            else:
                t = t_end
    return out, {"nfev": nfev, "segments": nseg, "impacts": impacts}


def eccentricity(states):
    """Journal centre relative to the bearing centre (m), global axes, per row of `states`."""
    f2 = states[:, 5]
    ex = states[:, 3] + S2_C * np.cos(f2) - states[:, 6]
    ey = states[:, 4] + S2_C * np.sin(f2) - states[:, 7]
    return np.stack([ex, ey], axis=1)


if __name__ == "__main__":
    import time

    ts = np.arange(241) * 1e-4
    for method, rtol in [("RK45", 1e-6), ("DOP853", 1e-9)]:
        t0 = time.perf_counter()
        ys, info = simulate(method, rtol, rtol * 1e-6, ts)
        print(method, rtol, f"{time.perf_counter() - t0:.2f} s", info["nfev"], "evaluations,",
              len(info["impacts"]), "impacts; slider x at end", ys[-1, 6])
