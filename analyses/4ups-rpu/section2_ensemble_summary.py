#!/usr/bin/env python3
"""Mean and spread of each section-2 quantity over an ensemble of perturbed starts.

  python3 analyses/4ups-rpu/section2_ensemble_summary.py out/4ups-rpu/section2-ensemble.md

Reads the comparison tables the program writes next to the study's HDF5 file (one column per
case) and, for every quantity, prints over the cases whose label starts with "d" (the perturbed
starts of `analyses/4ups-rpu/section2-ensemble.toml`): the number of cases with a value, the mean,
the sample standard deviation, the smallest and the largest value, and the unperturbed case's own
value ("d0_000") for comparison with one realisation.
"""
import math
import sys


def rows(path):
    header = None
    with open(path) as f:
        for line in f:
            line = line.strip()
            if not line.startswith("|"):
                header = None
                continue
            cells = [c.strip() for c in line.strip("|").split("|")]
            if cells[0] == "quantity":
                header = cells
                continue
            if header is None or set(cells[0]) <= {"-"}:
                continue
            yield header, cells


def number(text):
    try:
        v = float(text)
    except ValueError:
        return None
    return v if math.isfinite(v) else None


def main():
    print("| quantity | unit | cases | mean | standard deviation | min | max | unperturbed start |")
    print("|---|---|---|---|---|---|---|---|")
    seen = set()
    for header, cells in rows(sys.argv[1]):
        key = cells[0]
        if key in seen:
            continue
        seen.add(key)
        vals = [number(v) for h, v in zip(header[2:], cells[2:]) if h.startswith("d")]
        base = [v for h, v in zip(header[2:], cells[2:]) if h == "dp0_000"]
        got = [v for v in vals if v is not None]
        if len(got) < 2:
            continue
        mean = sum(got) / len(got)
        sd = math.sqrt(sum((v - mean) ** 2 for v in got) / (len(got) - 1))
        print(f"| {key} | {cells[1]} | {len(got)} of {len(vals)} | {mean:.4g} | {sd:.3g} | {min(got):.4g} "
              f"| {max(got):.4g} | {base[0] if base else '-'} |")


if __name__ == "__main__":
    main()
