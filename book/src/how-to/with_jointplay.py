#!/usr/bin/env python3
"""The jointplay Python package: a scene edited, run and read; a sweep run; any file loaded.

    python3 with_jointplay.py [OUT]     # from the repository's root; OUT defaults to out

About 20 s on 2 cores: two drive periods of the 4-UPS/RPU and the 601 values of the Duffing
cascade. All quantities are SI.
"""
import sys

import jointplay

out = sys.argv[1] if len(sys.argv) > 1 else "out"

scene = jointplay.load_scene("data/scenes/4ups-rpu-mixed.toml")
scene["joints.S2.clearance.radial_clearance"] = 4e-4   # m: the paths of studies, checked at once
scene["joints.*.clearance.normal.onset_velocity_floor"] = 1e-4   # m/s, in every clearance joint
print("degrees of freedom:", scene.check()["dof"])     # the compiled summary, as a dict

run = scene.run()                                       # GIL released, progress bar after 1 s
t = run.time                                            # s, shape (n,)
p = run["bodies/platform/position"]                     # shape (n, 3), a view, no copy
print(f"{len(t)} samples; platform position in {run.units['bodies/platform/position']}")
fn = run.observable("joints.S2.normal_force.radial")    # one column by its path (N)
print(f"S2 normal force up to {fn.max():.1f} N; columns of S2's force:",
      run.columns["joints/S2/force_on_journal"])
print("stats:", run.stats, "| complete:", run.complete)
print("wrote", run.write(out))                          # OUT/4ups-rpu-mixed.h5, as `jointplay run`

res = jointplay.run_study("analyses/duffing/cascade.toml", out=f"{out}/duffing", threads=2)
gamma, x = res["sweep/parameter"], res["sweep/x"]       # one row per value of gamma
print(res.file, res.kind, res.complete, x.shape, res.data.units["sweep/x"])

f = jointplay.load(res.file)                            # any file jointplay writes
print(len(f.datasets), "datasets; study:", f.attrs["study_name"])
