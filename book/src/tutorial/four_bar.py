"""The tutorial's four-bar from Python (book/src/tutorial/python.md).

    python book/src/tutorial/four_bar.py OUTDIR

Reads the scene, checks it, runs two crank turns at two clearances and compares the peak
contact force, then runs a small clearance sweep as a study and counts the distinct strobe
points of each value. Writes its HDF5 files into OUTDIR. With matplotlib installed it also
draws OUTDIR/four-bar-python.png.
"""

import os
import sys

import numpy as np

import jointplay

HERE = os.path.dirname(os.path.abspath(__file__))
SCENE = os.path.join(HERE, "four-bar.toml")


def distinct(values, tol):
    """How many values differ from each other by more than tol."""
    v = np.sort(np.asarray(values))
    return 1 + int(np.sum(np.diff(v) > tol))


def main(out):
    os.makedirs(out, exist_ok=True)

    # The scene, edited by the same paths a study uses.
    scene = jointplay.load_scene(SCENE)
    scene["solver.periods"] = 2                      # two crank turns: 0.05 s
    summary = scene.check()
    print(
        f"degrees of freedom {summary['dof']}, {summary['remaining_dof']} left free by the drive; "
        f"drive period {summary['period']:.4f} s"
    )

    runs = {}
    for clearance in (5e-5, 2.5e-4):                 # m
        scene["joints.coupler_pin.clearance.radial_clearance"] = clearance
        run = scene.run(progress=False)
        force = run.observable("joints.coupler_pin.normal_force.radial")   # N
        late = run.time > 0.025                       # the second crank turn
        print(
            f"clearance {clearance * 1e3:.2f} mm: peak contact force {force.max():.0f} N, "
            f"{force[late].max():.0f} N in the second turn; "
            f"{run.stats['rhs_evaluations']:.0f} right-hand sides"
        )
        runs[clearance] = run
    # The journal's orbit once per crank turn (a Poincare section of the run): the radial
    # eccentricity (m) and its rate (m/s) at t = 0, T, 2T, the last one at the run's end.
    times, ecc = runs[2.5e-4].strobe("joints/coupler_pin/radial_eccentricity")
    _, rate = runs[2.5e-4].strobe("joints/coupler_pin/radial_eccentricity_rate")
    for t, e, r in zip(times, ecc, rate):
        print(
            f"t = {t:.3f} s: journal {np.hypot(*e) * 1e3:.3f} mm off centre, "
            f"moving at {np.hypot(*r):.3f} m/s"
        )
    path = runs[2.5e-4].write(out)                   # OUT/four-bar.h5, as `jointplay run`
    print(f"wrote {path}")

    # A study from a string: three clearances, 30 crank turns each, the last 10 kept.
    study = f"""
[study]
name = "four-bar-python"
scene = "{SCENE}"

[analysis]
periods = 30
transient = 20
samples_per_period = 0

[[observables]]
name = "rocker_w"
path = "bodies.rocker.angular_velocity.z"

[sweep]
parameter = "joints.coupler_pin.clearance.radial_clearance"
unit = "m"
values = [5e-5, 1.5e-4, 2.5e-4]
"""
    res = jointplay.run_study(study, out=out, progress=False)
    clearances = res["sweep/parameter"]             # m
    strobe = res["sweep/rocker_w"]                  # rad/s, one row per clearance
    for c, w in zip(clearances, strobe):
        print(
            f"clearance {c * 1e3:.2f} mm: rocker at the strobe {w.min():.3f} to {w.max():.3f} rad/s, "
            f"{distinct(w, 0.05)} distinct points of {len(w)}"
        )
    print(f"wrote {res.file}")

    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return
    fig, ax = plt.subplots(figsize=(6, 4))
    for c, w in zip(clearances, strobe):
        ax.plot(np.full(len(w), c * 1e3), w, ".", color="C3")
    ax.set_xlabel("radial clearance (mm)")
    ax.set_ylabel("rocker angular velocity at the strobe (rad/s)")
    fig.tight_layout()
    fig.savefig(os.path.join(out, "four-bar-python.png"), dpi=120)
    print(f"wrote {os.path.join(out, 'four-bar-python.png')}")


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit("usage: python four_bar.py OUTDIR")
    main(sys.argv[1])
