"""The Python package against the program: the same numbers, the same files, the same errors,
and its own paths (progress, Ctrl-C)."""

import _thread
import pathlib
import signal
import sys
import threading
import time

import numpy as np
import pytest

import jointplay
from conftest import ROOT, SCENES

sys.path.insert(0, str(ROOT / "analyses"))
import pendulum_period  # noqa: E402

SWEEP = """
[study]
name = "duffing-small"
system = { kind = "duffing", gamma = 0.2, initial = [1.0, 0.0], solver = { integrator = "dopri5", rtol = 1e-9, atol = 1e-11 } }

[analysis]
periods = 30
transient = 20
samples_per_period = 20

[[sections]]
name = "v0"
terms = { v = 1.0 }
direction = "down"

[sweep]
parameter = "gamma"
from = 0.2
to = 0.3
count = 5
"""


def same_file(a, b, skip=("wall_time", "wall_time_s")):
    """Every dataset and root attribute of two jointplay files equal bit for bit (but `skip`)."""
    fa, fb = jointplay.load(a), jointplay.load(b)
    # Groups written as jobs finish may come in another order.
    assert sorted(fa.datasets) == sorted(fb.datasets)
    for d in fa.datasets:
        if d.rsplit("/", 1)[-1] in skip:
            continue
        x, y = fa[d], fb[d]
        if isinstance(x, list):  # text
            assert x == y, d
            continue
        assert x.shape == y.shape, d
        assert np.array_equal(x.view(np.uint64), y.view(np.uint64)), d
    aa, ab = fa.attrs, fb.attrs
    assert {k: v for k, v in aa.items() if k not in skip} == \
        {k: v for k, v in ab.items() if k not in skip}
    return fa


def test_the_pendulum_period_equals_the_programs_to_the_last_digit(program, tmp_path):
    program("run", SCENES / "pendulum.toml", "--out", tmp_path, "--no-plots", "-q")
    f = jointplay.load(tmp_path / "pendulum.h5")
    cli = pendulum_period.measure(f["time"], f["bodies/bob/position"][:, 0],
                                  f["bodies/bob/velocity"][:, 0])
    run = jointplay.load_scene(SCENES / "pendulum.toml").run(progress=False)
    assert run.complete and run.units["bodies/bob/position"] == "m"
    py = pendulum_period.measure(run.time, run.observable("bodies.bob.position.x"),
                                 run["bodies/bob/velocity"][:, 0])
    assert repr(py) == repr(cli)
    assert abs(py - pendulum_period.exact_period()) < 1e-9
    # The run's file is the program's file.
    out = tmp_path / "py"
    same_file(run.write(out), tmp_path / "pendulum.h5",
              skip=("wall_time", "wall_time_s", "scene_file"))


def test_an_edit_in_python_runs_as_the_same_edit_in_a_study(tmp_path):
    scene = jointplay.load_scene(SCENES / "slider-crank-clearance.toml")
    scene["solver.periods"] = 0.4
    scene["joints.piston_pin.clearance.bushing_radius"] = 0.00975
    scene["joints.*.clearance.normal.onset_velocity_floor"] = 1e-4
    assert scene["joints.piston_pin.clearance.bushing_radius"] == 0.00975
    run = scene.run(progress=False)
    study = tmp_path / "edit.toml"
    study.write_text(f"""
[study]
name = "edit"
scene = "{SCENES / 'slider-crank-clearance.toml'}"
set = {{ "solver.periods" = 0.4, "joints.piston_pin.clearance.bushing_radius" = 0.00975,
         "joints.*.clearance.normal.onset_velocity_floor" = 1e-4 }}

[[cases]]
label = "edited"
""")
    res = jointplay.run_study(study, out=tmp_path / "out", progress=False)
    assert res.kind == "comparison" and res.complete and "edited" in res.table
    for d in run.datasets:
        assert np.array_equal(run[d], res[f"cases/edited/{d}"]), d
    assert np.array_equal(run.time, res["cases/edited/time"])


def test_a_run_written_with_fewer_significant_bits_keeps_its_exact_values_in_memory(tmp_path):
    """`output.significant_bits` rounds the values of the file only: the run in memory keeps
    them as computed, the file holds each one within 2^-(bits+1) of it, the times exact."""
    scene = jointplay.load_scene(SCENES / "pendulum.toml")
    scene["solver.end_time"] = 1.0
    scene["output.significant_bits"] = 20
    assert scene.check()["output"]["significant_bits"] == 20
    run = scene.run(progress=False)
    f = jointplay.load(run.write(tmp_path))
    assert f.attrs["significant_bits"] == 20
    assert np.array_equal(f["time"], run.time)
    exact, stored = run["bodies/bob/position"], f["bodies/bob/position"]
    nonzero = exact != 0
    rel = np.abs(stored[nonzero] - exact[nonzero]) / np.abs(exact[nonzero])
    assert 0 < rel.max() <= 2.0 ** -21
    # The 32 dropped bits are zero in the file.
    assert np.all(stored.view(np.uint64) & np.uint64(2**32 - 1) == 0)


def test_significant_bits_by_quantity_round_each_dataset_to_its_own_bits(tmp_path):
    """`output.significant_bits` as a table: each quantity keeps its own bits, `default` the
    others; the file's attribute is the fewest."""
    scene = jointplay.load_scene(SCENES / "pendulum.toml")
    scene["solver.end_time"] = 1.0
    scene["output.significant_bits"] = {"default": 30, "reaction_force": 16, "position": 52}
    assert scene.check()["output"]["significant_bits"] == {
        "default": 30, "position": None, "reaction_force": 16}
    run = scene.run(progress=False)
    f = jointplay.load(run.write(tmp_path))
    assert f.attrs["significant_bits"] == 16
    assert "significant_bits" not in f.attributes("bodies/bob/position")
    assert np.array_equal(f["bodies/bob/position"], run["bodies/bob/position"])
    for name, bits in [("bodies/bob/velocity", 30), ("joints/pivot/reaction_force", 16)]:
        assert f.attributes(name)["significant_bits"] == bits
        exact, stored = run[name], f[name]
        nonzero = exact != 0
        rel = np.abs(stored[nonzero] - exact[nonzero]) / np.abs(exact[nonzero])
        assert 0 < rel.max() <= 2.0 ** -(bits + 1), name


def test_files_are_written_in_the_hdf5_format_asked_for(tmp_path):
    """`set_hdf5_format`: the superblock's version (the byte after the signature) is 3 in the
    1.10 format, 0 in the oldest; the values are the same."""
    scene = jointplay.load_scene(SCENES / "pendulum.toml")
    scene["solver.end_time"] = 1.0
    run = scene.run(progress=False)
    try:
        jointplay.set_hdf5_format("1.8")
        old = run.write(tmp_path / "old")
    finally:
        jointplay.set_hdf5_format("1.10")
    new = run.write(tmp_path / "new")
    assert (pathlib.Path(new).read_bytes()[8], pathlib.Path(old).read_bytes()[8]) == (3, 0)
    assert np.array_equal(jointplay.load(old)["bodies/bob/position"],
                          jointplay.load(new)["bodies/bob/position"])
    with pytest.raises(jointplay.JointplayError, match="1.6"):
        jointplay.set_hdf5_format("1.6")


def test_errors_name_the_path():
    scene = jointplay.load_scene(SCENES / "pendulum.toml")
    with pytest.raises(KeyError, match="joints.nope.kind: no element 'nope'"):
        scene["joints.nope.kind"]
    with pytest.raises(jointplay.JointplayError, match=r"bodies.bob.mass: .*bodies\[0\].mass"):
        scene["bodies.bob.mass"] = "heavy"
    with pytest.raises(jointplay.JointplayError,
                       match="gravity.3: index 3 is out of range: 'gravity' has 3 components"):
        scene["gravity.3"] = 1.0
    with pytest.raises(jointplay.JointplayError, match="(?s)solver.integratr: .*unknown field `integratr`"):
        scene["solver.integratr"] = "rk4"
    # A refused edit leaves the scene as it was.
    assert scene["bodies.bob.mass"] == 1.0 and "solver.integratr" not in scene
    # A value out of range is refused where the program refuses it: when the scene compiles.
    scene["bodies.bob.mass"] = -1.0
    with pytest.raises(jointplay.JointplayError, match=r"bodies\[0\].mass: .*-1"):
        scene.check()
    with pytest.raises(jointplay.JointplayError, match=r"bodies\[0\].mass: .*-1"):
        scene.run(progress=False)
    with pytest.raises(jointplay.JointplayError, match="pendulum.toml: cannot read"):
        jointplay.load_scene(SCENES / "no" / "pendulum.toml")
    with pytest.raises(jointplay.JointplayError, match=r"<study text>: analysis.transient"):
        jointplay.run_study(SWEEP.replace("transient = 20", "transient = 40"), progress=False)


def test_a_sweep_from_python_writes_the_programs_file(program, tmp_path):
    study = tmp_path / "duffing-small.toml"
    study.write_text(SWEEP)
    program("run", study, "--out", tmp_path / "cli", "--no-plots", "-q")
    res = jointplay.run_study(study, out=tmp_path / "py", threads=2, progress=False)
    assert res.kind == "analysis" and res.complete and res.failed == []
    f = same_file(res.file, tmp_path / "cli" / "duffing-small.h5")
    assert f["sweep/x"].shape == (5, 10) and f.units["sweep/x"] == "1"
    assert res.data.attrs["complete"] == 1
    # The built-in system observes its state by default.
    assert "sweep/v" in f.datasets


def test_a_sweep_with_chaos_measures_from_python(tmp_path):
    """The chaos measures come back as arrays: each value's Lyapunov exponents (summing to the
    Duffing oscillator's -delta = -0.3), K and class."""
    text = SWEEP.replace("periods = 30", "periods = 520").replace(
        "[sweep]",
        "[lyapunov]\nexponents = 2\nperiods = 40\nper_period = 2\n[zero_one]\nobservable = \"x\"\n[sweep]",
    ).replace("to = 0.3", "to = 0.5")
    res = jointplay.run_study(text, out=tmp_path, progress=False)
    ex = res["sweep/chaos/exponents"]
    assert ex.shape == (5, 2)
    assert np.allclose(ex.sum(axis=1), -0.3, atol=1e-6)
    assert res["sweep/chaos/class"][0] == 1  # gamma = 0.2: periodic
    assert res["sweep/chaos/k"][-1] > 0.8  # gamma = 0.5: chaotic by the 0-1 test


PRECISION = """
[study]
name = "wp"
system = { kind = "duffing", gamma = 0.2, initial = [1.0, 0.0], solver = { integrator = "dopri5", rtol = 1e-8, atol = 1e-10 } }

[analysis]
periods = 4
samples_per_period = 50

[precision]
restarts = 4
min_time = 0.0

[[precision.methods]]
integrator = "rk4"
settings = [0.05235987755982988, 0.02617993877991494, 0.01308996938995747]
"""


def test_work_precision_writes_the_programs_table_and_file(program, tmp_path):
    study = tmp_path / "wp.toml"
    study.write_text(PRECISION)
    program("precision", study, "--out", tmp_path / "cli", "--no-plots", "-q")
    res = jointplay.run_study(study, out=tmp_path / "py", precision=True, progress=False)
    assert res.kind == "precision" and res.table.count("| rk4 |") == 3
    f = jointplay.load(res.file)
    g = jointplay.load(tmp_path / "cli" / "wp.h5")
    # RK4's one-period error falls by 2^4 per halving of the step, in both.
    for h in (f, g):
        e = h["runs/restart_error"]
        assert np.all((12 < e[:-1] / e[1:]) & (e[:-1] / e[1:] < 20)), e
    assert np.array_equal(f["runs/restart_error"], g["runs/restart_error"])
    names = f["runs/integrator"]
    assert names == g["runs/integrator"] and len(names) == 3
    assert all(n.startswith("rk4, fixed step ") for n in names), names
    # Without precision=True, the study runs as an analysis, as `jointplay run` runs it.
    assert jointplay.run_study(study, out=tmp_path / "a", progress=False).kind == "analysis"


def test_progress_is_drawn_with_tqdm_and_without(tmp_path, capfd, monkeypatch):
    pytest.importorskip("tqdm")
    # Long enough (about a second) for the bar to be drawn.
    sweep = SWEEP.replace("periods = 30", "periods = 3000").replace("transient = 20",
                                                                   "transient = 2990")
    jointplay.run_study(sweep, out=tmp_path / "a", progress=True, threads=1)
    err = capfd.readouterr().err
    assert "duffing-small: 5 of 5 values done" in err and "%|" in err
    # Without tqdm: one line on standard error.
    monkeypatch.setitem(sys.modules, "tqdm.auto", None)
    jointplay.run_study(sweep, out=tmp_path / "b", progress=True, threads=1)
    err = capfd.readouterr().err
    assert "values done" in err and "%" in err
    # No bar when asked.
    jointplay.run_study(SWEEP, out=tmp_path / "c", progress=False)
    assert capfd.readouterr().err == ""


def interrupt_after(seconds):
    # A shell starts background jobs with SIGINT ignored, and interrupt_main then does nothing:
    # restore Python's own handler so that the simulated Ctrl-C arrives wherever the tests run.
    signal.signal(signal.SIGINT, signal.default_int_handler)
    timer = threading.Timer(seconds, _thread.interrupt_main)
    timer.start()
    return timer


def test_ctrl_c_stops_a_run_and_keeps_its_samples(tmp_path):
    scene = jointplay.load_scene(SCENES / "pendulum.toml")
    scene["solver.end_time"] = 1e5  # tens of seconds of computing: the interrupt comes first
    scene["output.interval"] = 1.0
    timer = interrupt_after(0.5)
    with pytest.raises(jointplay.Interrupted) as e:
        scene.run(progress=False)
    timer.join()
    assert isinstance(e.value, KeyboardInterrupt)
    run = e.value.partial
    assert not run.complete and run.stopped["interrupted"]
    n = len(run.time)
    assert 0 < n < 1e8 and np.all(np.isfinite(run["bodies/bob/position"]))
    f = jointplay.load(run.write(tmp_path))
    assert f.attrs["complete"] == 0 and len(f["time"]) == n


def test_ctrl_c_stops_a_sweep_and_resume_finishes_it(tmp_path):
    long = (SWEEP.replace("periods = 30", "periods = 100000").replace("count = 5", "count = 4")
            .replace("samples_per_period = 20", "samples_per_period = 0"))
    timer = interrupt_after(0.5)
    with pytest.raises(jointplay.Interrupted, match="resume=True runs the rest") as e:
        jointplay.run_study(long, out=tmp_path, threads=2, progress=False)
    timer.join()
    part = e.value.partial
    assert not part.complete and part.data.attrs["complete"] == 0
    done = part["sweep/done"]
    assert np.all(done != 2) and np.any(done == 0)
    res = jointplay.run_study(long, out=tmp_path, threads=2, progress=False, resume=True)
    assert res.complete and np.all(res["sweep/done"] == 1)
    assert pathlib.Path(res.file) == pathlib.Path(part.file)


def test_ctrl_c_stops_a_lyapunov_run(tmp_path):
    """The interrupt reaches the Lyapunov run after the analysis run: it stops at its next
    re-orthonormalisation, the samples are kept and the file is marked incomplete."""
    text = SWEEP.split("[sweep]")[0] + "[lyapunov]\nexponents = 2\nperiods = 10000000\nper_period = 2\n"
    timer = interrupt_after(1.0)
    with pytest.raises(jointplay.Interrupted) as e:
        jointplay.run_study(text, out=tmp_path, progress=False)
    timer.join()
    part = e.value.partial
    assert not part.complete and part.data.attrs["complete"] == 0
    assert "chaos/lyapunov/exponents" not in part.data.datasets




def test_a_continuation_from_python_stops_and_resumes_to_the_programs_branches(program, tmp_path):
    """The bundled continuation study runs from Python into the program's file; stopped after 3
    points it is marked unfinished and resumable, and resume=True ends on the program's
    branches."""
    study = ROOT / "analyses" / "duffing" / "continuation.toml"
    program("run", study, "--out", tmp_path / "cli", "--no-plots", "-q")
    part = jointplay.run_study(study, out=tmp_path / "py", progress=False, max_jobs=3)
    assert not part.complete
    assert part.data.attrs["complete"] == 1  # the analysis itself is complete
    rest = jointplay.run_study(study, out=tmp_path / "py", progress=False, resume=True)
    assert rest.complete
    a = jointplay.load(tmp_path / "cli" / "duffing-continuation.h5")
    b = jointplay.load(rest.file)
    for name in ["continuation/branch_0/parameter", "continuation/branch_0/state",
                 "continuation/branch_1/state", "continuation/special/parameter"]:
        assert np.array_equal(a[name].view(np.uint64), b[name].view(np.uint64)), name


def test_a_huge_thread_count_is_a_value_error_naming_the_argument(tmp_path):
    # threads=10**6 started threads until the machine stalled.
    with pytest.raises(ValueError, match="threads: 1000000 is more than"):
        jointplay.run_study(SWEEP, out=tmp_path, threads=10**6, progress=False)
    with pytest.raises(ValueError, match="threads: 1000000 is more than"):
        jointplay.run_study(tmp_path / "missing.toml", threads=10**6, progress=False)


def test_a_scene_is_used_from_another_thread_while_it_runs():
    # The run held a borrow of the scene while it ran with the GIL released: an edit from
    # another thread (or from a progress callback) raised "RuntimeError: Already borrowed".
    scene = jointplay.load_scene(SCENES / "pendulum.toml")
    scene["solver.end_time"] = 300.0
    scene["output.interval"] = 1.0
    errors = []

    def use():
        for k in range(40):
            try:
                scene["bodies.bob.mass"] = 1.0 + k
                scene.check()
                scene.to_toml()
                del scene["output.interval"]
                scene["output.interval"] = 1.0
            except Exception as e:  # noqa: BLE001 - every failure is the finding
                errors.append(e)
            time.sleep(0.005)

    t = threading.Thread(target=use)
    t.start()
    run = scene.run(progress=False)
    t.join()
    assert errors == []
    assert run.complete
    assert scene["bodies.bob.mass"] == 40.0


def test_a_study_runs_on_a_scene_edited_in_memory(tmp_path):
    """`run_study(..., scene=Scene)` runs the study on the edited scene, written beside the
    results: the same values as the same edit made by the study's `set`."""
    scene = jointplay.load_scene(SCENES / "slider-crank-clearance.toml")
    scene["solver.periods"] = 0.4
    scene["joints.piston_pin.clearance.bushing_radius"] = 0.00975
    study = tmp_path / "base.toml"
    study.write_text(f"""
[study]
name = "in-memory"
scene = "{SCENES / 'slider-crank-clearance.toml'}"

[[cases]]
label = "edited"
""")
    res = jointplay.run_study(study, out=tmp_path / "mem", progress=False, scene=scene)
    written = tmp_path / "mem" / "in-memory.scene.toml"
    assert written.exists() and res.complete
    edited = tmp_path / "set.toml"
    edited.write_text(study.read_text().replace(
        "\n\n[[cases]]",
        '\nset = { "solver.periods" = 0.4, '
        '"joints.piston_pin.clearance.bushing_radius" = 0.00975 }\n\n[[cases]]'))
    ref = jointplay.run_study(edited, out=tmp_path / "set", progress=False)
    for d in ("time", "joints/piston_pin/normal_force", "bodies/slider/position"):
        assert np.array_equal(res[f"cases/edited/{d}"], ref[f"cases/edited/{d}"]), d
    # A study of a built-in system has no scene to replace.
    with pytest.raises(jointplay.JointplayError, match="study.scene"):
        jointplay.run_study(SWEEP, out=tmp_path / "sys", progress=False, scene=scene)


def test_a_run_strobes_its_journal_orbit_without_losing_the_last_period():
    """A run records the journal's radial eccentricity and its rate, so its phase plane and
    Poincare section need no rerun; ``Run.strobe`` keeps every drive period up to the run's end
    and refuses a sampling that misses the strobe times."""
    scene = jointplay.load_scene(SCENES / "slider-crank-clearance.toml")
    scene["solver.periods"] = 3
    period = 2 * np.pi / 523.5987755982989  # s, 5000 rpm
    scene["output.interval"] = period / 50
    run = scene.run(progress=False)
    assert run.units["joints/piston_pin/radial_eccentricity_rate"] == "m/s"
    times, ecc = run.strobe("joints/piston_pin/radial_eccentricity")
    # Four strobe points over three periods: t = 0 and the end of each, the last the last sample.
    assert times.shape == (4,) and ecc.shape == (4, 2)
    assert times[-1] == run.time[-1]
    assert np.allclose(times, np.arange(4) * period, rtol=0, atol=1e-12)
    rows = [int(np.argmin(abs(run.time - t))) for t in times]
    assert np.array_equal(ecc, run["joints/piston_pin/radial_eccentricity"][rows])
    _, rate = run.strobe("joints.piston_pin.radial_eccentricity_rate.u", phase=period / 2)
    assert rate.shape == (3,)
    assert np.array_equal(rate, run.observable("joints.piston_pin.radial_eccentricity_rate.u")[25::50])
    with pytest.raises(ValueError, match=r"output.interval = "):
        run.strobe("joints/piston_pin/radial_eccentricity", period=period * 1.01)


def png_size(path):
    b = pathlib.Path(path).read_bytes()
    return int.from_bytes(b[16:20], "big"), int.from_bytes(b[20:24], "big")


def test_figure_style_sizes_the_figures_and_refuses_values_out_of_range(tmp_path):
    for kwargs, named in [({"scale": 20}, "figure scale"), ({"font_scale": 0.1}, "font scale"),
                          ({"size": (10, 10)}, "figure size")]:
        with pytest.raises(ValueError, match=named):
            jointplay.set_figure_style(**kwargs)
    sizes = {}
    try:
        for scale in (1, 2):
            jointplay.set_figure_style(scale=scale)
            out = tmp_path / f"x{scale}"
            jointplay.run_study(SWEEP, out=out, progress=False, plots=True)
            sizes[scale] = png_size(sorted(out.glob("*.png"))[0])
    finally:
        jointplay.set_figure_style()
    (w, h), (w2, h2) = sizes[1], sizes[2]
    assert (w2, h2) == (2 * w, 2 * h) and w % 560 == 0 and h % 380 == 0


def test_check_says_which_clearance_joints_the_start_closed():
    scene = jointplay.load_scene(SCENES / "slider-crank-clearance.toml")
    closed = scene.check()["closed_start"]
    assert closed["joints"] == {"piston_pin": [0.0, 0.0, 0.0]} and closed["moved"] is False
    scene["joints.piston_pin.clearance.initial_eccentricity"] = [2e-4, 0.0, 0.0]
    closed = scene.check()["closed_start"]
    assert closed["joints"]["piston_pin"] == [2e-4, 0.0, 0.0] and closed["moved"] is True
    assert closed["position_gap"] > 1e-4
    scene["joints.piston_pin.clearance.start"] = "free"
    with pytest.raises(jointplay.JointplayError, match="initial_eccentricity"):
        scene.check()
    del scene["joints.piston_pin.clearance.initial_eccentricity"]
    assert scene.check()["closed_start"] is None


def test_a_lubricated_bearing_from_python_carries_its_weight_on_the_film():
    scene = jointplay.load_scene(SCENES / "journal-bearing.toml")
    scene["solver.end_time"] = 0.2
    run = scene.run(progress=False)
    film = run["joints/bearing/film_force"]
    assert run.units["joints/bearing/film_force"] == "N"
    # Settled well before 0.2 s (the orbit decays by e every 8 ms): the film carries the 20 kg
    # rotor's weight, and the resultant on the journal is the film alone (no asperity contact).
    assert abs(film[-1, 1] - 20.0 * 9.81) < 1e-6 and abs(film[-1, 0]) < 1e-6
    assert np.array_equal(film, run["joints/bearing/force_on_journal"])
    # The same scene without its film: the rotor falls onto the wall.
    scene["disable"] = ["bearing.lubrication"]
    dry = scene.run(progress=False)
    assert "joints/bearing/film_force" not in dry.datasets
    assert dry["joints/bearing/penetration"].max() > 0.0


def test_lugre_bristles_are_states_of_the_run_from_python():
    scene = jointplay.load_scene(SCENES / "lugre-stick-slip.toml")
    assert scene.check()["bristle_states"] == 12
    scene["solver.end_time"] = 1.0
    run = scene.run(progress=False)
    # Presliding after 1 s: the spring pulls with k v t = 0.2 N, which the bristles hold
    # (sigma0 z m g = 0.2 N), while the block has crept a few micrometres.
    friction = run["joints/floor/friction_force"][-1].sum()
    assert abs(abs(friction) - 0.2) < 1e-3
    assert abs(run["bodies/block/position"][-1, 0]) < 5e-5
    # The bristles are recorded (three columns per contact, housing axes): the lower corners'
    # hold the spring between them, z = 0.2 N / (sigma0 m g) = 2.0 um (the damping terms are
    # below 1 % at this creep).
    z = run["joints/floor/bristle"]
    assert z.shape[1] == 12 and run.units["joints/floor/bristle"] == "m"
    assert abs(z[-1, 3] / (0.2 / (10193.68 * 9.81)) - 1.0) < 0.02
    # Without friction there are no bristles.
    scene["disable"] = ["friction"]
    assert scene.check()["bristle_states"] == 0


def test_export_writes_csv_and_mat_files_that_read_back_to_the_run(program, tmp_path):
    # scipy.io.loadmat reads MAT level 5 on its own: it checks the file against MATLAB's
    # format, not against the writer's idea of it.
    import csv

    import h5py

    import scipy.io

    program("run", SCENES / "slider-in-guide.toml", "--out", tmp_path, "--no-plots", "-q")
    run = tmp_path / "slider-in-guide.h5"
    program("export", run, "--format", "csv", "--out", tmp_path)
    program("export", run, "--format", "mat", "--out", tmp_path)
    with h5py.File(run) as f:
        m = scipy.io.loadmat(tmp_path / "slider-in-guide.mat")
        assert np.array_equal(m["time"][:, 0], f["time"][:])
        sampled = ("bodies/slider/position", "joints/guide/normal_force",
                   "joints/guide/contact_state", "diagnostics/energy")
        for d in sampled:
            ref = f[d][:].astype(float)
            ref = ref[:, None] if ref.ndim == 1 else ref
            assert np.array_equal(m[d.replace("/", "_")], ref), d
        assert m["units"][0, 0]["joints_guide_normal_force"][0] == "N"
        names = [s.strip() for s in m["columns"][0, 0]["joints_guide_normal_force"]]
        assert names == [f"joints.guide.normal_force.{c}" for c in
                         ("front_upper", "front_lower", "rear_upper", "rear_lower")]
        with open(tmp_path / "slider-in-guide.csv", newline="") as fh:
            rows = list(csv.reader(fh))
        header = rows[0]
        assert header[0] == "time [s]"
        k = header.index("joints.guide.penetration.rear_lower [m]")
        column = np.array([float(r[k]) for r in rows[1:]])
        # Every digit kept: the values read back to the same doubles.
        assert np.array_equal(column, f["joints/guide/penetration"][:, 3])
    # A study's file needs a case, and names its cases.
    bad = program("export", SCENES / "slider-in-guide.toml", "--format", "csv", check=False)
    assert bad.returncode == 1 and "reads the HDF5 file a run wrote" in bad.stderr
