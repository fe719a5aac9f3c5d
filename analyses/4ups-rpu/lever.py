#!/usr/bin/env python3
"""The platform motion that clearance in S2 and S5 frees, for each reconstructed geometry.

With S2 and S5 ideal the five legs fix the platform's in-plane pose (X, Y, rotation about Z).
Clearance in S2 and S5 frees one combination of the three: the one that keeps limb 1 (R1-P1-U1)
and legs 3 and 4 at their driven lengths. Legs 2 and 5 restrain it only through their ball
contacts. This script prints, per 1 mm change of the leg-2 length (the most the ball can move
along the leg is the clearance), how far that motion takes the platform in X and Y and how much it
turns; and the share of the platform's weight that legs 2 and 5 carry in that motion,
m g dX/dl / 2 (virtual work, platform weight only). A large Y lever means a large Y offset per
unit of clearance. A small weight share means the ball contacts are lightly loaded, so the
platform's inertia can reverse them during a drive period.

  python3 analyses/4ups-rpu/lever.py
"""
import math

import numpy as np

R_P, R_11, L_R1 = 0.645, 0.202, 0.710
U1X, U1Y = 0.059, 0.229
M_PLATFORM, G = 18.64, 9.81


def lever(layout, u1_sign, t=0.0, omega=3.14):
    angles = [45, 135, 225, 315] if layout == "square" else [72, 144, 216, 288]
    centre = np.array([1.21 - 0.03 * math.cos(omega * t), 0.03 * math.sin(omega * t), 0.0])
    b1 = np.array([0.0, L_R1, 0.0])
    u1 = np.array([u1_sign * U1X, U1Y, 0.0])
    legs = []
    for a in angles:
        r = math.radians(a)
        legs.append((np.array([0.0, R_P * math.cos(r), R_P * math.sin(r)]),
                     np.array([0.0, R_11 * math.cos(r), R_11 * math.sin(r)])))

    def lengths(q):
        x, y, th = q
        rz = np.array([[math.cos(th), -math.sin(th), 0], [math.sin(th), math.cos(th), 0], [0, 0, 1]])
        p = centre + np.array([x, y, 0.0])
        return np.array([np.linalg.norm(p + rz @ u1 - b1)]
                        + [np.linalg.norm(p + rz @ s - b) for b, s in legs])

    h = 1e-7
    jac = np.zeros((5, 3))
    for k in range(3):
        e = np.zeros(3)
        e[k] = h
        jac[:, k] = (lengths(e) - lengths(-e)) / (2 * h)
    # Rows: limb 1, legs 2 (S2), 3, 4, 5 (S5). Legs 3 and 4 are mirror images (so are 2 and 5),
    # so in-plane motion keeps limb 1 and leg 3 fixed: the null space of those two rows.
    n = np.linalg.svd(jac[[0, 2], :])[2][-1]
    mode = n / (jac[1] @ n)  # per metre of leg-2 length
    return mode


def main():
    print("geometry          dX/dl    dY/dl   dtheta/dl (rad/m)  weight share per leg (N)")
    for layout in ("square", "pentagon"):
        for s in (1, -1):
            dx, dy, dth = lever(layout, s)
            print(f"{layout:8s} U1 {s:+d}   {dx:7.3f}  {dy:7.2f}  {dth:10.2f}          "
                  f"{abs(M_PLATFORM * G * dx) / 2:6.1f}")


if __name__ == "__main__":
    main()
