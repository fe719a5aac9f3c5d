"""The program and the Python package run a study through the same code: the same study run by
`jointplay run` and by `jointplay.run_study` writes equal files, dataset by dataset and
attribute by attribute (wall-clock quantities aside)."""

import h5py
import numpy as np
import pytest

import jointplay

# A small sweep with a section, and a continuation followed after it into the same file.
STUDY = """
[study]
name = "parity"
system = { kind = "duffing", delta = 0.3, alpha = -1.0, beta = 1.0, gamma = 0.2, omega = 1.2, initial = [1.0, 0.0], solver = { integrator = "dopri5", rtol = 1e-9, atol = 1e-11 } }

[analysis]
periods = 8
transient = 4
samples_per_period = 8

[[observables]]
name = "x"
path = "x"

[[observables]]
name = "v"
path = "v"

[[sections]]
name = "v0"
terms = { v = 1.0 }
direction = "down"

[sweep]
parameter = "gamma"
from = 0.2
to = 0.3
count = 3

[continuation]
parameter = "gamma"
from = 0.2
to = 0.24
step = 0.01
tolerance = 1e-9
max_points = 4
"""

COMPARISON = """
[study]
name = "parity-cases"
scene = "{scene}"


[[cases]]
label = "short"
set = { "solver.end_time" = 0.2 }

[[cases]]
label = "heavier"
set = { "solver.end_time" = 0.2, "bodies.bob.mass" = 2.0 }
"""


def wall_clock(name):
    return "wall" in name or "per_second" in name


def attrs(obj):
    return {k: v for k, v in obj.attrs.items() if not wall_clock(k)}


def same(a, b, where):
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        a, b = np.asarray(a), np.asarray(b)
        assert a.shape == b.shape and a.dtype == b.dtype, where
        if a.dtype.kind == "f":
            assert np.array_equal(a.view(np.uint8), b.view(np.uint8)), where
        else:
            assert np.array_equal(a, b), where
    else:
        assert a == b, where


def equal_files(a, b):
    """Every group, dataset and attribute of two HDF5 files equal (wall-clock ones aside)."""
    with h5py.File(a, "r") as fa, h5py.File(b, "r") as fb:
        names_a, names_b = [], []
        fa.visit(names_a.append)
        fb.visit(names_b.append)
        assert names_a == names_b
        for k, v in attrs(fa).items():
            same(v, attrs(fb)[k], f"/@{k}")
        assert attrs(fa).keys() == attrs(fb).keys()
        for name in names_a:
            x, y = fa[name], fb[name]
            assert type(x) is type(y), name
            assert attrs(x).keys() == attrs(y).keys(), name
            for k, v in attrs(x).items():
                same(v, attrs(y)[k], f"{name}@{k}")
            if isinstance(x, h5py.Dataset) and not wall_clock(name):
                same(x[()], y[()], name)


@pytest.mark.parametrize("kind", ["analysis", "comparison"])
def test_the_program_and_python_write_the_same_files(program, tmp_path, kind):
    from conftest import SCENES

    if kind == "analysis":
        study = tmp_path / "parity.toml"
        study.write_text(STUDY)
        name = "parity"
    else:
        study = tmp_path / "parity-cases.toml"
        study.write_text(COMPARISON.replace("{scene}", str(SCENES / "pendulum.toml")))
        name = "parity-cases"
    program("run", study, "--out", tmp_path / "cli", "--no-plots", "-q")
    res = jointplay.run_study(study, out=tmp_path / "py", progress=False)
    assert res.complete
    equal_files(tmp_path / "cli" / f"{name}.h5", res.file)
    if kind == "analysis":
        assert "continuation/branch_0/parameter" in res.data.datasets


def test_resuming_a_finished_continuation_returns_it_as_the_program_does(program, tmp_path):
    # Python raised "nothing to resume" where the program says the continuation is finished.
    text = STUDY.split("[[sections]]")[0] + "[continuation]" + STUDY.split("[continuation]")[1]
    study = tmp_path / "finished.toml"
    study.write_text(text)
    first = jointplay.run_study(study, out=tmp_path, progress=False)
    assert first.complete
    again = jointplay.run_study(study, out=tmp_path, progress=False, resume=True)
    assert again.complete and again.file == first.file
    out = program("run", study, "--out", tmp_path, "--resume", "-q").stdout
    assert "finished     the continuation in" in out
