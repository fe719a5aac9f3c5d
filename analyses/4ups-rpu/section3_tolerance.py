#!/usr/bin/env python3
"""Which tolerance converges the section-3 bifurcation diagram?

Runs the study section3-diagram.toml at four clearances (0.1, 0.3, 0.5, 0.7 mm; the paper's 50
periods, the first 10 transient) with DOPRI5 (or, with --integrator bs3, the Bogacki-Shampine
3(2) pair) at rtol 1e-5, 1e-6 and 1e-7 (atol = rtol x 1e-3 m), and a reference (DOPRI5 at rtol
1e-8 with contact onsets as events), then prints, for the velocities the
paper's diagrams plot, how far each run's strobe points lie from the reference's, as a fraction
of the diagram's height (the reference's range over its four clearances and all strobe points):

- "settled": the last 10 strobe points of each clearance, what the diagram shows as the orbit;
- "all": every strobe point after the transient, the approach to the orbit included;
- "spread": the largest range of the last 10 strobe points of one clearance (m/s), which the
  classification reads as one point per period when it is small.

A fraction of 1e-3 is one pixel of a 1000-pixel-high figure. The runs are written to DIR
(default out/section3-tolerance); a complete file already there from the same study text is
reused.

    python3 analyses/4ups-rpu/section3_tolerance.py [--integrator bs3] [--out DIR] [--jointplay BIN]

BIN defaults to $JOINTPLAY, then target/release/jointplay (build it with cargo build --release).
"""

import argparse
import os
import re
import subprocess
import sys
import time
from pathlib import Path

import h5py
import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent.parent
OBSERVABLES = ["platform_vx", "platform_vy", "S2_vx", "S2_vy", "R1_vx", "R1_vy"]
# (integrator, rtol, onset events); the last is the reference.
TOLERANCES = ["1e-5", "1e-6", "1e-7"]
REFERENCE = ("dopri5", "1e-8", True)


def replace_once(text, old, new):
    """`text` with its only occurrence of `old` replaced; an error if there is not exactly one."""
    if text.count(old) != 1:
        sys.exit(f"section3-diagram.toml: expected one '{old}', found {text.count(old)}")
    return text.replace(old, new)


def study(integrator, rtol, events):
    """The text of section3-diagram.toml at four clearances, with `integrator` at tolerance rtol."""
    text = (HERE / "section3-diagram.toml").read_text()
    scene = (HERE / "../../data/scenes/4ups-rpu-mixed.toml").resolve()
    text = replace_once(text, '"../../data/scenes/4ups-rpu-mixed.toml"', f'"{scene}"')
    solver = f'"solver.integrator" = "{integrator}", "solver.rtol" = {rtol}, "solver.atol" = {float(rtol) * 1e-3:.0e}'
    if events:
        solver += ', "solver.onset_events" = true'
    text = replace_once(text, '"solver.integrator" = "dopri5", "solver.rtol" = 1e-6, "solver.atol" = 1e-9', solver)
    text = replace_once(text, 'name = "section3-diagram"', f'name = "{name(integrator, rtol, events)}"')
    text = replace_once(text, "from = 2e-5\nto = 8e-4\ncount = 40", "from = 1e-4\nto = 7e-4\ncount = 4")
    # The figures are not needed to compare the numbers.
    return re.split(r"^\[\[figures\]\]", text, flags=re.M)[0]


def name(integrator, rtol, events):
    # The DOPRI5 files keep their first names, so that earlier runs are reused.
    prefix = "tolerance-" if integrator == "dopri5" else f"tolerance-{integrator}-"
    return f"{prefix}{rtol}" + ("-events" if events else "")


def reusable(path, text):
    """Whether `path` is a complete run of the study `text`."""
    try:
        with h5py.File(path, "r") as f:
            study = f.attrs["study"]
            study = study.decode() if isinstance(study, bytes) else str(study)
            return int(f.attrs["complete"]) == 1 and study == text
    except (OSError, KeyError):
        return False


def sweep(path):
    """The strobe-point datasets and evaluation counts of a sweep file, read into memory."""
    with h5py.File(path, "r") as f:
        s = f["sweep"]
        return {k: s[k][()] for k in OBSERVABLES + ["rhs_evals"]}


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--integrator", default="dopri5", choices=["dopri5", "bs3"])
    ap.add_argument("--out", default=str(ROOT / "out" / "section3-tolerance"))
    ap.add_argument("--jointplay", default=os.environ.get("JOINTPLAY", str(ROOT / "target/release/jointplay")))
    args = ap.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    runs = [(args.integrator, rtol, False) for rtol in TOLERANCES] + [REFERENCE]
    files = []
    for integrator, rtol, events in runs:
        n = name(integrator, rtol, events)
        h5 = out / f"{n}.h5"
        text = study(integrator, rtol, events)
        if not reusable(h5, text):
            toml = out / f"{n}.toml"
            toml.write_text(text)
            t0 = time.monotonic()
            r = subprocess.run([args.jointplay, "run", str(toml), "--out", str(out), "-q", "--no-plots"])
            if r.returncode != 0:
                sys.exit(f"{toml}: jointplay run failed (exit {r.returncode})")
            print(f"ran {n} in {time.monotonic() - t0:.1f} s", file=sys.stderr)
        files.append(h5)
    ref = sweep(files[-1])
    height = {k: np.ptp(ref[k]) for k in OBSERVABLES}
    print("| run | RHS evaluations | " + " | ".join(f"{k} settled / all" for k in OBSERVABLES) + " |")
    print("|---|---|" + "---|" * len(OBSERVABLES))
    for (integrator, rtol, events), h5 in zip(runs, files):
        s = sweep(h5)
        cells = []
        for k in OBSERVABLES:
            a, r = s[k], ref[k]
            settled = np.max(np.abs(a[:, -10:] - r[:, -10:])) / height[k]
            every = np.max(np.abs(a - r)) / height[k]
            cells.append(f"{settled:.1e} / {every:.1e}")
        label = f"{integrator} rtol {rtol}" + (" + onset events (reference)" if events else "")
        print(f"| {label} | {int(s['rhs_evals'].sum()):,} | " + " | ".join(cells) + " |")
    print()
    print("diagram height (m/s): " + ", ".join(f"{k} {height[k]:.3e}" for k in OBSERVABLES))
    for (integrator, rtol, events), h5 in zip(runs, files):
        s = sweep(h5)
        spread = [np.max(np.ptp(s[k][:, -10:], axis=1)) for k in OBSERVABLES]
        print(f"spread of the last 10 strobe points, {integrator} rtol {rtol}: " + ", ".join(f"{v:.1e}" for v in spread))


if __name__ == "__main__":
    main()
