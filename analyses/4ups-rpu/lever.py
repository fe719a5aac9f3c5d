#!/usr/bin/env python3
"""The platform motion that clearance in S2 and S5 frees, and the load its ball contacts carry.

With S2 and S5 ideal the five legs fix the platform's in-plane pose (X, Y, rotation about Z).
Clearance in S2 and S5 frees one combination of the three: the one that keeps limb 1 (R1-P1-U1)
and legs 3 and 4 at their driven lengths. Legs 2 and 5 restrain it only through their ball
contacts. Every moving body moves in that mode: the platform, and the swing and telescopic rods
of all five limbs, which turn about their base joints as the platform moves.

For each reconstructed geometry this script prints, per metre of leg-2 length (a ball moves at
most its clearance along the leg), how far the mode takes the platform in X and Y and how much
it turns; then the load that each of the two balls (S2, S5) carries along its leg
when the mode is held still, by virtual work: P = Q / 2, Q = sum over bodies of
m (g - a) . dr/dl - I (u x u'') . (u x du/dl) (a rod's turning inertia; the platform does not
turn in the driven motion). Q is the generalised force of weight and inertia on the mode per
metre of leg-2 length, so P is in newtons along the leg; P > 0 pulls leg 2 (and 5) longer, and
the ball then rests against the side of its socket that stops the leg from lengthening.

  * the weight share: P from gravity alone, for gravity along -X ("standing", the scene's first
    reading) and +X ("hanging"), counting the platform alone (the first version of this script)
    and every body;
  * the inertial load over a drive period of trajectory (69) at 1.57, 3.14 and 4.71 rad/s, and
    the total load's range over the period. A range that keeps one sign means the balls stay on
    one side of their clearance (the contact can settle); a range that crosses zero means the
    load reverses and the balls cross their clearance twice a period (rattling).
  * the drift: the side the balls sit on gives the sign of the platform's settled Y offset,
    sign(P) sign(dY/dl) (the mode moves the way the load pulls it, until the balls touch).

Rod masses and inertias are the paper's Table 1; centres of mass at mid-length (swing rod 0.38 m
from the base joint, telescopic rod 0.42 m from the platform joint), as in the scene generator.

  python3 analyses/4ups-rpu/lever.py
"""
import math

import numpy as np

R_P, R_11, L_R1 = 0.645, 0.202, 0.710
U1X, U1Y = 0.059, 0.229
M_PLATFORM = 18.64
M_SWING, I_SWING, L_SWING = 10.54, 0.643, 0.760
M_TELE, I_TELE, L_TELE = 8.57, 0.550, 0.840
G = 9.81


def geometry(layout, u1_sign):
    angles = [45, 135, 225, 315] if layout == "square" else [72, 144, 216, 288]
    bases = [np.array([0.0, L_R1, 0.0])]
    tops = [np.array([u1_sign * U1X, U1Y, 0.0])]
    for a in angles:
        r = math.radians(a)
        bases.append(np.array([0.0, R_P * math.cos(r), R_P * math.sin(r)]))
        tops.append(np.array([0.0, R_11 * math.cos(r), R_11 * math.sin(r)]))
    return bases, tops


def centre(t, omega):
    return np.array([1.21 - 0.03 * math.cos(omega * t), 0.03 * math.sin(omega * t), 0.0])


def pose(geo, c, q):
    """Platform-joint points of the five limbs for platform centre c moved by q = (x, y, theta)."""
    bases, tops = geo
    x, y, th = q
    rz = np.array([[math.cos(th), -math.sin(th), 0], [math.sin(th), math.cos(th), 0], [0, 0, 1]])
    p = c + np.array([x, y, 0.0])
    return p, [p + rz @ s for s in tops]


def bodies(geo, c, q):
    """(mass, inertia, centre of mass, leg direction or None) of every moving body."""
    bases, _ = geo
    p, tops = pose(geo, c, q)
    out = [(M_PLATFORM, 0.0, p, None)]
    for b, s in zip(bases, tops):
        u = (s - b) / np.linalg.norm(s - b)
        out.append((M_SWING, I_SWING, b + u * L_SWING / 2, u))
        out.append((M_TELE, I_TELE, s - u * L_TELE / 2, u))
    return out


def mode(geo, c):
    """The freed in-plane motion (dx, dy, dtheta) per metre of leg-2 length."""
    bases, _ = geo

    def lengths(q):
        _, tops = pose(geo, c, q)
        return np.array([np.linalg.norm(s - b) for b, s in zip(bases, tops)])

    h = 1e-7
    jac = np.zeros((5, 3))
    for k in range(3):
        e = np.zeros(3)
        e[k] = h
        jac[:, k] = (lengths(e) - lengths(-e)) / (2 * h)
    # Rows: limb 1, legs 2 (S2), 3, 4, 5 (S5). Legs 3 and 4 are mirror images (so are 2 and 5),
    # so in-plane motion keeps limb 1 and leg 3 fixed: the null space of those two rows.
    n = np.linalg.svd(jac[[0, 2], :])[2][-1]
    return n / (jac[1] @ n)


def ball_load(geo, t, omega, gx, inertia=True, platform_only=False):
    """Load on each ball along its leg (N) at time t: P = Q / 2."""
    c = centre(t, omega)
    m = mode(geo, c)
    h = 1e-6
    g = np.array([gx, 0.0, 0.0])
    b0 = bodies(geo, c, np.zeros(3))
    bp, bm = bodies(geo, c, h * m), bodies(geo, c, -h * m)
    dt = 1e-4
    later, earlier = bodies(geo, centre(t + dt, omega), np.zeros(3)), bodies(geo, centre(t - dt, omega), np.zeros(3))
    q = 0.0
    for k, (mass, inert, r, u) in enumerate(b0):
        if platform_only and k > 0:
            continue
        dr = (bp[k][2] - bm[k][2]) / (2 * h)
        a = (later[k][2] - 2 * r + earlier[k][2]) / dt**2 if inertia else np.zeros(3)
        q += mass * (g - a) @ dr
        if u is not None and inertia:
            du = (bp[k][3] - bm[k][3]) / (2 * h)
            udd = (later[k][3] - 2 * u + earlier[k][3]) / dt**2
            q -= inert * np.cross(u, udd) @ np.cross(u, du)
    return q / 2


def main():
    geos = [(lay, s) for lay in ("square", "pentagon") for s in (1, -1)]
    print("Freed mode per metre of leg-2 length (at t = 0):")
    print("geometry          dX/dl    dY/dl   dtheta/dl (rad/m)")
    for lay, s in geos:
        dx, dy, dth = mode(geometry(lay, s), centre(0.0, 3.14))
        print(f"{lay:8s} U1 {s:+d}   {dx:7.3f}  {dy:7.2f}  {dth:10.2f}")
    print()
    print("Weight share per ball along its leg (N, > 0 pulls the leg longer), t = 0:")
    print("geometry        gravity   platform only   every body")
    for lay, s in geos:
        geo = geometry(lay, s)
        for name, gx in (("-X", -G), ("+X", G)):
            p1 = ball_load(geo, 0.0, 3.14, gx, inertia=False, platform_only=True)
            p2 = ball_load(geo, 0.0, 3.14, gx, inertia=False)
            print(f"{lay:8s} U1 {s:+d}   {name}      {p1:8.1f}        {p2:8.1f}")
    print()
    print("Ball load over one drive period, every body (N): inertia alone, and weight + inertia;")
    print("'closed' when the total keeps one sign (the balls stay on one side), 'reverses' otherwise;")
    print("drift: the sign of the settled Y offset, sign(P) x sign(dY/dl).")
    print("geometry        omega  inertia range       gravity  total range          contact   drift")
    for lay, s in geos:
        geo = geometry(lay, s)
        for omega in (1.57, 3.14, 4.71):
            ts = np.linspace(0.0, 2 * math.pi / omega, 101)
            ine = [ball_load(geo, t, omega, 0.0) for t in ts]
            for name, gx in (("-X", -G), ("+X", G)):
                tot = [ball_load(geo, t, omega, gx) for t in ts]
                lo, hi = min(tot), max(tot)
                closed = lo > 0 or hi < 0
                dy = mode(geo, centre(0.0, omega))[1]
                drift = "+Y" if (np.mean(tot) * dy) > 0 else "-Y"
                print(f"{lay:8s} U1 {s:+d}  {omega:4.2f}  {min(ine):7.1f}..{max(ine):6.1f}    {name}    "
                      f"{lo:7.1f}..{hi:7.1f}      {'closed' if closed else 'reverses':8s}  {drift}")


if __name__ == "__main__":
    main()
