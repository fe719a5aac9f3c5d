#!/usr/bin/env python3
"""Load a jointplay sweep file with h5py and draw its bifurcation diagram with matplotlib.

    python3 -m pip install h5py matplotlib
    python3 analyses/plot_sweep.py out/duffing/duffing-cascade.h5 x   # writes duffing-cascade-x.png

Layout (book/src/reference/hdf5.md): /sweep/parameter holds one value per job,
/sweep/<observable> the stroboscopic points (jobs x kept periods), /sweep/done which jobs are
finished (rows of unfinished jobs hold NaN), and every dataset its unit as an attribute.
"""
import sys

import h5py
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def main(path, observable):
    with h5py.File(path, "r") as f:
        sweep = f["sweep"]
        p = sweep["parameter"][:]
        points = sweep[observable][:]
        done = sweep["done"][:] == 1
        down = sweep["direction"][:] < 0
        unit = sweep[observable].attrs["unit"]
        pname = sweep["parameter"].attrs["path"]
        punit = sweep["parameter"].attrs["unit"]
        if not f.attrs["complete"]:
            print(f"{path}: incomplete sweep, {done.sum()} of {len(done)} values done")
    fig, ax = plt.subplots(figsize=(8, 5))
    for sel, colour, label in [(done & ~down, "tab:red", "up"), (done & down, "tab:blue", "down")]:
        if sel.any():
            n = points.shape[1]
            ax.plot(
                p[sel].repeat(n), points[sel].ravel(), ",", color=colour, label=label
            )
    ax.set_xlabel(f"{pname} ({punit})" if punit else pname)
    ax.set_ylabel(f"{observable} ({unit})" if unit not in ("", "1") else observable)
    ax.set_title(f"Bifurcation diagram of {observable}")
    out = path.rsplit(".h5", 1)[0] + f"-{observable}.png"
    fig.savefig(out, dpi=150)
    print("wrote", out)


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    main(sys.argv[1], sys.argv[2])
