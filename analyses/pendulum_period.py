#!/usr/bin/env python3
"""Reads a pendulum run written by `jointplay run` and compares its period with the exact one.

    cargo run -- run data/scenes/pendulum.toml --out out
    python3 analyses/pendulum_period.py out/pendulum.h5

Needs h5py and numpy (pip install h5py); `measure` takes arrays from anywhere (the Python
package's tests give it a run's arrays). The period is measured between upward zero crossings of
the bob's x coordinate, each located on the cubic Hermite interpolant of the recorded position and
velocity, and compared with T = 4 sqrt(I_O / (m g L)) K(sin(theta0 / 2)) for the scene's values.
"""
import math
import sys


def ellip_k(k):
    """Complete elliptic integral of the first kind by the arithmetic-geometric mean."""
    a, b = 1.0, math.sqrt(1.0 - k * k)
    for _ in range(40):
        a, b = 0.5 * (a + b), math.sqrt(a * b)
    return math.pi / (2.0 * a)


def measure(t, x, vx):
    """The mean period (s) between upward zero crossings of x, located on the cubic Hermite
    interpolant of the samples of x (m) and its rate vx (m/s) at times t (s)."""
    crossings = []
    for i in range(len(t) - 1):
        if x[i] < 0.0 <= x[i + 1]:
            h = t[i + 1] - t[i]

            def p(s):
                return ((2 * s**3 - 3 * s * s + 1) * x[i] + (s**3 - 2 * s * s + s) * h * vx[i]
                        + (-2 * s**3 + 3 * s * s) * x[i + 1] + (s**3 - s * s) * h * vx[i + 1])

            lo, hi = 0.0, 1.0
            for _ in range(60):
                mid = 0.5 * (lo + hi)
                lo, hi = (mid, hi) if p(mid) < 0.0 else (lo, mid)
            crossings.append(t[i] + 0.5 * (lo + hi) * h)
    return (crossings[-1] - crossings[0]) / (len(crossings) - 1)


def exact_period():
    """T = 4 sqrt(I_O / (m g L)) K(sin(theta0 / 2)) for the scene's values (s)."""
    # Scene values: L = 1 m, m = 1 kg, I_c = 1e-3 kg m^2, g = 9.81 m/s^2, theta0 = 60 degrees.
    i_o, m, g, l, theta0 = 1.0e-3 + 1.0, 1.0, 9.81, 1.0, math.pi / 3.0
    return 4.0 * math.sqrt(i_o / (m * g * l)) * ellip_k(math.sin(theta0 / 2.0))


def main(path):
    import h5py

    with h5py.File(path, "r") as f:
        t = f["time"][:]
        x = f["bodies/bob/position"][:, 0]
        vx = f["bodies/bob/velocity"][:, 0]
        print(f"{path}: {len(t)} samples, integrator: {f.attrs['integrator']}")
    measured, exact = measure(t, x, vx), exact_period()
    print(f"period measured {measured:.15f} s, exact {exact:.15f} s, "
          f"relative error {abs(measured - exact) / exact:.2e}")


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "out/pendulum.h5")
