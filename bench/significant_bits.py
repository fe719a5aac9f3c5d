#!/usr/bin/env python3
"""What `output.significant_bits` saves: file sizes of the same runs with every bit kept and with
the recorded values rounded to fewer mantissa bits.

  python3 bench/significant_bits.py [--jointplay PATH] [--bits 40,36,...]

Runs, with the jointplay binary, for every bit count and once with every bit kept:

- `clearance-size`: the bundled study `analyses/4ups-rpu/clearance-size.toml` (4 cases of the
  mixed 4-UPS/RPU, RK4 at 1e-4 s, 2 drive periods, 1 ms output), its `set` given
  `output.significant_bits`;
- `mixed-dopri5`: `data/scenes/4ups-rpu-mixed.toml` over 6 drive periods (12 s) with DOPRI5 at
  rtol 1e-6, 1 ms output.

It prints, per run and bit count, the file's size, the size of its samples as the program wrote
them before any compression (`raw`: every dataset's element count times its element size), the
ratios of the exact file and of `raw` to it, the bound 2^-(bits+1) and the largest relative error
found against the exact file (over every nonzero recorded value). Scenes and studies with the
edits are written to a temporary directory; the committed files are not touched. It stops with an
error when a value exceeds its bound or a dataset not marked `significant_bits` differs from the
exact file's. One to two minutes on 2 cores.
"""
import argparse
import os
import re
import subprocess
import sys
import tempfile

import h5py
import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def raw_size(path):
    total = 0

    def visit(_name, obj):
        nonlocal total
        if isinstance(obj, h5py.Dataset) and obj.shape is not None:
            total += obj.size * obj.dtype.itemsize

    with h5py.File(path, "r") as f:
        f.visititems(visit)
    return total


def worst_error(exact, rounded):
    """The largest |rounded - exact| / |exact| over the datasets marked `significant_bits`, and
    the names of the other datasets (of any type and shape) that differ from the exact file's."""
    worst = 0.0
    differ = []
    with h5py.File(exact, "r") as a, h5py.File(rounded, "r") as b:

        def visit(name, obj):
            nonlocal worst
            if not isinstance(obj, h5py.Dataset):
                return
            x, y = a[name][()], obj[()]
            if "significant_bits" not in obj.attrs:
                same = (np.array_equal(x, y, equal_nan=True) if obj.dtype.kind == "f"
                        else np.array_equal(x, y))
                if not same:
                    differ.append(name)
                return
            m = x != 0
            if m.any():
                worst = max(worst, float(np.max(np.abs(y[m] - x[m]) / np.abs(x[m]))))

        b.visititems(visit)
    return worst, differ


def run(jp, target, out):
    subprocess.run([jp, "run", target, "--out", out, "--no-plots", "-q"], check=True,
                   stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--jointplay", default=os.path.join(ROOT, "target/release/jointplay"))
    ap.add_argument("--bits", default="44,36,30,28,26,23,20,18,16")
    args = ap.parse_args()
    bits = [None] + [int(b) for b in args.bits.split(",")]
    scene = os.path.join(ROOT, "data/scenes/4ups-rpu-mixed.toml")
    study = os.path.join(ROOT, "analyses/4ups-rpu/clearance-size.toml")
    with open(scene) as f:
        scene_text = f.read()
    with open(study) as f:
        study_text = f.read()
    with tempfile.TemporaryDirectory() as tmp:
        print("| run | significant_bits | file (bytes) | exact file / file | raw / file "
              "| bound 2^-(bits+1) | largest relative error |")
        print("|---|---|---|---|---|---|---|")
        for name in ["clearance-size", "mixed-dopri5"]:
            exact = None
            for b in bits:
                tag = "all" if b is None else str(b)
                d = os.path.join(tmp, f"{name}-{tag}")
                os.makedirs(d)
                if name == "clearance-size":
                    text = study_text.replace(
                        'scene = "../../data/scenes/4ups-rpu-mixed.toml"', f'scene = "{scene}"')
                    if b is not None:
                        text = text.replace(
                            f'scene = "{scene}"',
                            f'scene = "{scene}"\nset = {{ "output.significant_bits" = {b} }}')
                    target = os.path.join(d, "clearance-size.toml")
                    h5 = os.path.join(d, "clearance-size.h5")
                else:
                    text = re.sub(r'(?m)^integrator = "rk4"\nstep = 1e-4',
                                  'integrator = "dopri5"\nrtol = 1e-6', scene_text)
                    text = re.sub(r"(?m)^periods = 2.0", "periods = 6.0", text)
                    if b is not None:
                        text = re.sub(r"(?m)^\[output\]", f"[output]\nsignificant_bits = {b}",
                                      text)
                    target = os.path.join(d, "scene.toml")
                    h5 = os.path.join(d, "4ups-rpu-mixed.h5")
                with open(target, "w") as f:
                    f.write(text)
                run(args.jointplay, target, d)
                size = os.path.getsize(h5)
                if b is None:
                    exact, exact_size = h5, size
                    print(f"| {name} | all | {size} | 1.00 | {raw_size(h5) / size:.2f} | | |")
                    continue
                worst, differ = worst_error(exact, h5)
                if differ:
                    sys.exit(f"{h5}: datasets not marked rounded differ from the exact file: "
                             f"{differ}")
                if worst > 2.0 ** -(b + 1):
                    sys.exit(f"{h5}: relative error {worst:e} above the bound 2^-{b + 1}")
                print(f"| {name} | {b} | {size} | {exact_size / size:.2f} | "
                      f"{raw_size(h5) / size:.2f} | {2.0 ** -(b + 1):.1e} | {worst:.1e} |")


if __name__ == "__main__":
    main()
