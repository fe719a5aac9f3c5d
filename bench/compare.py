#!/usr/bin/env python3
"""Work-precision comparison of jointplay with straightforward SciPy (solve_ivp) peers.

    python3 bench/compare.py [--jointplay PATH] [--out DIR] [--only duffing|slider-crank]

For each problem: a reference solution at very tight tolerance (checked against a second
tolerance and against jointplay at tight tolerance); SciPy RK45, DOP853 and LSODA over a range of
rtol and jointplay's dopri5 (on the slider-crank also with onset events) and rk4 over a range of
settings; for every run the error against the reference and the wall time; a markdown table of the runs and the ratio of SciPy time to jointplay
time at equal error (log-log interpolation along each method's work-precision front).
The report goes to stdout and DIR/results.md, the raw numbers to DIR/results.json, the
work-precision figures to DIR/<problem>.png (when matplotlib is installed).

Timing. SciPy: wall time of the integration call inside this Python process (the model's Python
right-hand side and solve_ivp; interpreter start and imports not included). jointplay: the whole
process `jointplay run FILE --out DIR --no-plots -q` (start, parsing, assembly, integration,
recording, HDF5 writing), and separately the integration-and-recording time it stores in its HDF5
file (`wall_time_s` of a scene run, `wall_time` of an analysis study). A run shorter than one
second is repeated (--repeats, default 3) and the shortest time is kept.
"""
import argparse
import json
import math
import os
import platform
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import h5py
import numpy as np
import scipy

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
import duffing  # noqa: E402
import slider_crank  # noqa: E402

REPO = HERE.parent
SCENE = REPO / "data" / "scenes" / "slider-crank-clearance.toml"
ATOL_FACTOR = 1e-3  # atol = rtol * ATOL_FACTOR for every adaptive run of both programs


# ---------------------------------------------------------------------------------------------
# Timing and jointplay invocation


def timed(fn, repeats):
    """Runs fn(); repeats it while the runs are shorter than a second; returns (result, min time)."""
    best = math.inf
    result = None
    for i in range(repeats):
        t0 = time.perf_counter()
        result = fn()
        dt = time.perf_counter() - t0
        best = min(best, dt)
        if dt > 1.0:
            break
    return result, best


def find_jointplay(arg):
    cands = [arg, os.environ.get("JOINTPLAY")]
    if os.environ.get("CARGO_TARGET_DIR"):
        cands.append(str(Path(os.environ["CARGO_TARGET_DIR"]) / "release" / "jointplay"))
    cands += [str(REPO / "target" / "release" / "jointplay"), shutil.which("jointplay")]
    for c in cands:
        if c and Path(c).is_file() and os.access(c, os.X_OK):
            return c
    sys.exit("jointplay binary not found: build it (cargo build --release) and pass --jointplay "
             "PATH or set JOINTPLAY")


class Jointplay:
    def __init__(self, exe, tmp, repeats):
        self.exe, self.tmp, self.repeats = exe, Path(tmp), repeats
        self.n = 0

    def run(self, text, stem, h5name, time_attr):
        """Writes `text` to a temporary file and runs it. Returns the output directory, the
        shortest process time and the shortest integration time recorded in the HDF5 file
        (attribute `time_attr`) over the repeats."""
        self.n += 1
        src = self.tmp / f"{stem}-{self.n}.toml"
        src.write_text(text)
        out = self.tmp / f"out-{self.n}"
        recorded = []

        def go():
            r = subprocess.run([self.exe, "run", str(src), "--out", str(out), "--no-plots", "-q"],
                               capture_output=True, text=True)
            if r.returncode != 0:
                raise RuntimeError(f"jointplay failed on {src}:\n{r.stdout}\n{r.stderr}")

        def go_and_read():
            t0 = time.perf_counter()
            go()
            dt = time.perf_counter() - t0
            with h5py.File(out / h5name, "r") as f:
                recorded.append(float(f.attrs[time_attr]))
            return dt

        best = math.inf
        for _ in range(self.repeats):
            dt = go_and_read()
            best = min(best, dt)
            if dt > 1.0:
                break
        return out, best, min(recorded)


# ---------------------------------------------------------------------------------------------
# Problems


def duffing_study(name, gamma, periods, solver):
    return f"""[study]
name = "{name}"
description = "work-precision run"
system = {{ kind = "duffing", delta = {duffing.DELTA}, alpha = {duffing.ALPHA}, beta = {duffing.BETA}, gamma = {gamma}, omega = {duffing.OMEGA}, initial = [1.0, 0.0], solver = {{ {solver} }} }}

[analysis]
periods = {periods}
transient = 0
samples_per_period = 0

[[observables]]
name = "x"
path = "x"

[[observables]]
name = "v"
path = "v"
"""


class DuffingProblem:
    unit = "1"
    measure = ("max over the strobe times t_k = k 2pi/1.2 of the state error "
               "sqrt(dx^2 + dv^2) (dimensionless)")

    def __init__(self, key, gamma, periods):
        self.key, self.gamma, self.periods = key, gamma, periods
        self.title = (f"Duffing oscillator, gamma = {gamma}, x(0) = 1, x'(0) = 0, "
                      f"{periods} forcing periods")

    # SciPy
    def scipy_run(self, method, rtol, atol):
        y, info = duffing.simulate(method, rtol, atol, self.gamma, self.periods)
        return y, info["nfev"]

    # jointplay
    def jp_run(self, jp, integrator, value):
        if integrator == "dopri5":
            solver = f'integrator = "dopri5", rtol = {value:.1e}, atol = {value * ATOL_FACTOR:.1e}'
        else:
            solver = f'integrator = "rk4", step = {value!r}'
        out, t, t_int = jp.run(duffing_study("duffing-bench", self.gamma, self.periods, solver),
                               self.key, "duffing-bench.h5", "wall_time")
        with h5py.File(out / "duffing-bench.h5", "r") as f:
            y = np.stack([f["sections/strobe/x"][:], f["sections/strobe/v"][:]], axis=1)
            return y, t, t_int, int(f.attrs["rhs_evals"])

    def error(self, y, ref):
        return float(np.max(np.hypot(y[:, 0] - ref[:, 0], y[:, 1] - ref[:, 1])))

    def settings(self, quick):
        rk4 = [duffing.PERIOD / n for n in (25, 50, 100, 200, 400, 800, 1600)]
        if self.gamma > 0.3:  # chaotic: the error of loose runs saturates at the attractor size
            sp = {"RK45": [1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10, 1e-11],
                  "DOP853": [1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10, 1e-11, 1e-12],
                  "LSODA": [1e-6, 1e-7, 1e-8, 1e-9, 1e-10, 1e-11]}
            jd = [1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10, 1e-11, 1e-12]
            rk4 = [duffing.PERIOD / n for n in (100, 200, 400, 800, 1600, 3200)]
        else:
            sp = {"RK45": [1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10, 1e-11],
                  "DOP853": [1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10, 1e-11, 1e-12],
                  "LSODA": [1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10, 1e-11]}
            jd = [1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10, 1e-11, 1e-12]
        if quick:
            sp = {k: v[::2] for k, v in sp.items()}
            jd, rk4 = jd[::2], rk4[::2]
        return sp, {"dopri5": jd, "rk4": rk4}

    def reference(self, jp, repeats):
        ref, _ = self.scipy_run("DOP853", 3e-14, 3e-17)
        chk, _ = self.scipy_run("DOP853", 1e-12, 1e-15)
        jy = self.jp_run(jp, "dopri5", 1e-13)[0]
        return ref, [
            ("SciPy DOP853 rtol 3e-14 (the reference) vs SciPy DOP853 rtol 1e-12",
             self.error(chk, ref)),
            ("SciPy DOP853 rtol 3e-14 vs jointplay dopri5 rtol 1e-13", self.error(jy, ref)),
        ]


def slider_scene(solver_lines):
    text = SCENE.read_text()
    text, n = re.subn(r"\n\[solver\]\n.*?(?=\n\[output\])",
                      "\n[solver]\n" + solver_lines + "\nperiods = 2\n", text, flags=re.S)
    assert n == 1, "unexpected scene layout: [solver] before [output]"
    text, n = re.subn(r"\n\[output\]\n.*", "\n[output]\ninterval = 1e-5\naccelerations = false\n"
                      "diagnostics = false\n", text, flags=re.S)
    assert n == 1
    return text


class SliderCrankProblem:
    key = "slider-crank"
    unit = "m"
    measure = ("max over the samples t_k = k 1e-5 s, 0 <= t_k <= 0.024 s, of the error of the "
               "slider position |dx_slider| (m)")
    title = ("Slider-crank with a 0.5 mm revolute clearance (data/scenes/"
             "slider-crank-clearance.toml), two crank turns at 5000 rpm")
    samples = np.arange(2401) * 1e-5

    def scipy_run(self, method, rtol, atol):
        y, info = slider_crank.simulate(method, rtol, atol, self.samples)
        return y, info["nfev"]

    def jp_run(self, jp, integrator, value):
        if integrator.startswith("dopri5"):
            solver = f'integrator = "dopri5"\nrtol = {value:.1e}\natol = {value * ATOL_FACTOR:.1e}'
            if integrator == "dopri5-events":
                # Contact onsets located on the dense output and the step restarted there.
                solver += "\nonset_events = true"
        else:
            solver = f'integrator = "rk4"\nstep = {value!r}'
        out, t, t_int = jp.run(slider_scene(solver), self.key, "slider-crank-clearance.h5",
                               "wall_time_s")
        with h5py.File(out / "slider-crank-clearance.h5", "r") as f:
            y = np.full((len(self.samples), 18), np.nan)
            y[:, 6] = f["bodies/slider/position"][:, 0]
            y[:, 15] = f["bodies/slider/velocity"][:, 0]
            self._last_ecc = f["joints/piston_pin/eccentricity_global"][:, :2]
            return y, t, t_int, int(f.attrs["rhs_evaluations"])

    def error(self, y, ref):
        return float(np.max(np.abs(y[:, 6] - ref[:, 6])))

    def settings(self, quick):
        sp = {"RK45": [1e-6, 1e-7, 1e-8, 1e-9, 1e-10],
              "DOP853": [1e-7, 1e-8, 1e-9, 1e-10, 1e-11, 1e-12],
              "LSODA": [1e-6, 1e-7, 1e-8, 1e-9, 1e-10]}
        jp = {"dopri5": [1e-8, 1e-9, 1e-10, 1e-11, 1e-12, 1e-13],
              "dopri5-events": [1e-8, 1e-9, 1e-10, 1e-11, 1e-12, 1e-13],
              "rk4": [1e-5, 5e-6, 2e-6, 1e-6, 5e-7, 2e-7]}
        if quick:
            sp = {k: v[::2] for k, v in sp.items()}
            jp = {k: v[::2] for k, v in jp.items()}
        return sp, jp

    def agreement(self, a, ecc_a, b, ecc_b):
        return (float(np.max(np.abs(a[:, 6] - b[:, 6]))),
                float(np.max(np.abs(a[:, 15] - b[:, 15]))),
                float(np.max(np.hypot(*(ecc_a - ecc_b).T))))

    def reference(self, jp, repeats):
        ref, _ = self.scipy_run("DOP853", 3e-14, 3e-17)
        chk, _ = self.scipy_run("DOP853", 1e-13, 1e-16)
        ecc_ref = slider_crank.eccentricity(ref)
        rows = [("SciPy DOP853 rtol 1e-13", self.agreement(chk, slider_crank.eccentricity(chk),
                                                           ref, ecc_ref))]
        for rtol in (1e-12, 1e-13, 1e-14):
            y = self.jp_run(jp, "dopri5", rtol)[0]
            rows.append((f"jointplay dopri5 rtol {rtol:.0e}",
                         self.agreement(y, self._last_ecc, ref, ecc_ref)))
        self.agreement_rows = rows
        return ref, [(f"SciPy DOP853 rtol 3e-14 (the reference) vs {name}", d[0])
                     for name, d in rows]


# ---------------------------------------------------------------------------------------------
# Equal-error interpolation


def front(runs, key):
    """Work-precision front: the runs no other run beats in both error and time, by error."""
    pts = sorted((r["error"], r[key]) for r in runs if r["error"] > 0 and math.isfinite(r["error"]))
    out = []
    for e, t in pts:
        if not out or t < out[-1][1]:
            out.append((e, t))
    return out


def time_at(runs, key, err):
    """Time to reach `err`, interpolated log-log on the front; None outside its error range."""
    f = front(runs, key)
    for (e0, t0), (e1, t1) in zip(f, f[1:]):
        if e0 <= err <= e1:
            if e1 == e0:
                return t0
            s = (math.log(err) - math.log(e0)) / (math.log(e1) - math.log(e0))
            return math.exp(math.log(t0) + s * (math.log(t1) - math.log(t0)))
    if len(f) == 1 and f[0][0] == err:
        return f[0][1]
    return None


def fmt(x, spec=".3g"):
    return "n/a" if x is None else format(x, spec)


# ---------------------------------------------------------------------------------------------
# Driver


def run_problem(p, jp, repeats, quick, log):
    t_start = time.perf_counter()
    log(f"## {p.title}\n")
    log(f"Error measure: {p.measure}.\n")
    ref, checks = p.reference(jp, repeats)
    log("Reference: SciPy DOP853 at rtol 3e-14, atol 3e-17. Its checks (same error measure):\n")
    for name, d in checks:
        log(f"- {name}: {d:.2e}")
    log("")
    if hasattr(p, "agreement_rows"):
        log("Agreement with the reference (max over all samples; slider position, slider "
            "velocity, journal eccentricity vector):\n")
        log("| solution | slider x (m) | slider v (m/s) | eccentricity (m) |")
        log("|---|---|---|---|")
        for name, (dx, dv, de) in p.agreement_rows:
            log(f"| {name} | {dx:.2e} | {dv:.2e} | {de:.2e} |")
        log("")

    sp_settings, jp_settings = p.settings(quick)
    runs = []
    for method, rtols in sp_settings.items():
        for rtol in rtols:
            try:
                (y, nfev), t = timed(lambda: p.scipy_run(method, rtol, rtol * ATOL_FACTOR),
                                     repeats)
            except RuntimeError as e:
                print(f"  skipped: {e}", file=sys.stderr)
                continue
            runs.append({"program": "SciPy", "method": method, "setting": f"rtol {rtol:.0e}",
                         "error": p.error(y, ref), "time": t, "nfev": int(nfev)})
            print(f"  SciPy {method} rtol {rtol:.0e}: {runs[-1]['error']:.2e} {t:.3f} s",
                  file=sys.stderr)
    for integ, values in jp_settings.items():
        for v in values:
            y, t, t_int, nfev = p.jp_run(jp, integ, v)
            setting = f"rtol {v:.0e}" if integ.startswith("dopri5") else f"step {v:.3g}"
            runs.append({"program": "jointplay", "method": integ, "setting": setting,
                         "error": p.error(y, ref), "time": t, "time_int": t_int, "nfev": nfev})
            print(f"  jointplay {integ} {setting}: {runs[-1]['error']:.2e} {t:.3f} s "
                  f"({t_int:.4f} s integration)", file=sys.stderr)

    log(f"Runs (atol = {ATOL_FACTOR:g} rtol; error in {p.unit}; SciPy time: the solve in-process; "
        "jointplay: the whole process, and in brackets the integration time it records):\n")
    log("| program | method | setting | error | wall time (s) | RHS evaluations |")
    log("|---|---|---|---|---|---|")
    for r in runs:
        tt = f"{r['time']:.3f}"
        if "time_int" in r:
            tt += f" ({r['time_int']:.4f})"
        log(f"| {r['program']} | {r['method']} | {r['setting']} | {r['error']:.2e} | {tt} | "
            f"{r['nfev']} |")
    log("")

    # Ratios at equal error against jointplay's best method at that error.
    jpr = [r for r in runs if r["program"] == "jointplay"]
    errs = [r["error"] for r in runs if r["error"] > 0]
    levels = [10.0**k for k in range(math.floor(math.log10(min(errs))),
                                      math.ceil(math.log10(max(errs))) + 1)]
    methods = list(sp_settings)
    log("Time at equal error (log-log interpolation along each method's work-precision front; "
        "jointplay: the fastest of its methods at that error; ratio = SciPy time / jointplay "
        "time, process time first, integration time in brackets):\n")
    head = "| error | " + " | ".join(f"{m} (s)" for m in methods) + \
        " | jointplay process (s) | jointplay integration (s) | " + \
        " | ".join(f"{m} / jointplay" for m in methods) + " |"
    log(head)
    log("|" + "---|" * (head.count("|") - 1))
    ratios = []
    for lev in levels:
        jt = [time_at([r for r in jpr if r["method"] == m], "time", lev) for m in jp_settings]
        ji = [time_at([r for r in jpr if r["method"] == m], "time_int", lev) for m in jp_settings]
        jt = min([x for x in jt if x is not None], default=None)
        ji = min([x for x in ji if x is not None], default=None)
        st = [time_at([r for r in runs if r["method"] == m and r["program"] == "SciPy"], "time",
                      lev) for m in methods]
        if jt is None and all(s is None for s in st):
            continue
        cells = []
        for s in st:
            if s is None or jt is None:
                cells.append("n/a")
            else:
                cells.append(f"{s / jt:.1f} ({s / ji:.0f})")
                ratios.append({"error": lev, "ratio_process": s / jt, "ratio_integration": s / ji})
        log(f"| {lev:.0e} | " + " | ".join(fmt(s) for s in st) + f" | {fmt(jt)} | {fmt(ji)} | "
            + " | ".join(cells) + " |")
    log("")
    elapsed = time.perf_counter() - t_start
    log(f"({p.key}: {elapsed:.0f} s for this problem, references and repeats included)\n")
    return {"problem": p.key, "title": p.title, "measure": p.measure, "checks": checks,
            "runs": runs, "seconds": elapsed,
            "agreement": getattr(p, "agreement_rows", None)}


def plot(result, path):
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return
    fig, ax = plt.subplots(figsize=(7, 5))
    groups = {}
    for r in result["runs"]:
        groups.setdefault((r["program"], r["method"]), []).append(r)
    for (prog, meth), rs in groups.items():
        rs = sorted(rs, key=lambda r: r["error"])
        ax.loglog([r["time"] for r in rs], [r["error"] for r in rs], "o-",
                  label=f"{prog} {meth}" + (" (process)" if prog == "jointplay" else ""))
        if prog == "jointplay":
            ax.loglog([r["time_int"] for r in rs], [r["error"] for r in rs], "x--",
                      label=f"{prog} {meth} (integration)")
    ax.set_xlabel("wall time (s)")
    ax.set_ylabel(f"error ({result['problem']})")
    ax.set_title(result["title"], fontsize=8)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--jointplay", help="path of the jointplay binary")
    ap.add_argument("--out", default=str(HERE / "out"), help="output directory (bench/out)")
    ap.add_argument("--only", choices=["duffing", "slider-crank"], help="run one problem")
    ap.add_argument("--repeats", type=int, default=3, help="repeats of runs shorter than 1 s")
    ap.add_argument("--quick", action="store_true", help="every other setting only")
    args = ap.parse_args()
    exe = find_jointplay(args.jointplay)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    lines = []

    def log(s):
        print(s)
        lines.append(s)

    t0 = time.perf_counter()
    ver = subprocess.run([exe, "--version"], capture_output=True, text=True).stdout.strip()
    cpu = next((ln.split(":", 1)[1].strip() for ln in open("/proc/cpuinfo")
                if ln.startswith("model name")), platform.processor()) \
        if Path("/proc/cpuinfo").exists() else platform.processor()
    log(f"# jointplay vs SciPy solve_ivp\n\n{ver or exe}; Python {platform.python_version()}, "
        f"NumPy {np.__version__}, SciPy {scipy.__version__}; {cpu}, {os.cpu_count()} cores\n")
    problems = []
    if args.only in (None, "duffing"):
        problems += [DuffingProblem("duffing-periodic", 0.2, 200),
                     DuffingProblem("duffing-chaotic", 0.5, 10)]
    if args.only in (None, "slider-crank"):
        problems.append(SliderCrankProblem())
    results = []
    with tempfile.TemporaryDirectory(prefix="jointplay-bench-") as tmp:
        jp = Jointplay(exe, tmp, args.repeats)
        for p in problems:
            res = run_problem(p, jp, args.repeats, args.quick, log)
            results.append(res)
            plot(res, out / f"{p.key}.png")
    log(f"Total: {time.perf_counter() - t0:.0f} s.")
    (out / "results.md").write_text("\n".join(lines) + "\n")
    (out / "results.json").write_text(json.dumps(results, indent=1, default=float))


if __name__ == "__main__":
    main()
