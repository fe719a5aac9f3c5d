//! jointplay for Python: the `jointplay._jointplay` extension module, built by maturin
//! (`pip install ./crates/python`) and re-exported by the `jointplay` package.
//!
//! It calls the Rust crates directly: a `Scene` is a scene's TOML tree, read and edited by the
//! study paths of [`jointplay_analysis::study::spec`] and checked against the scene format on every
//! edit; `Scene::run` compiles and simulates it (`jointplay_analysis::study::run::simulate_until`)
//! and hands its recording over as numpy arrays that view the run's own memory (no copy);
//! `run_study` runs a comparison, analysis (sweep) or work-precision study through the program's
//! own entry point ([`jointplay_analysis::execute`]), so it writes the same files, and loads the
//! result (`H5`, read by [`jointplay_analysis::storage::read`]). This crate only converts.
//!
//! Long computations run on a thread of their own with the GIL released, while the calling
//! thread draws the progress bar (`jointplay._progress`, tqdm when installed) and checks for
//! signals every 50 ms: Ctrl-C requests a [`Stop`], the computation ends as it does on any
//! interruption (a run keeps its samples, a sweep its finished values), and
//! `jointplay.Interrupted`, a `KeyboardInterrupt`, is raised carrying what was kept.
//!
//! Every error of the program comes back as `jointplay.JointplayError` with the program's own
//! message (file, field or path, value, time).

use std::path::PathBuf;
use std::sync::Mutex;
use std::time::{Duration, Instant};

use jointplay_analysis::execute::{Caller, ExecOptions, Outcome, Report, Source, execute};
use jointplay_analysis::flow::summary::Summary;
use jointplay_analysis::progress::{Progress, Stop, Tally};
use jointplay_analysis::storage::inputs::Input;
use jointplay_analysis::storage::read::{Attr, Data, Reader};
use jointplay_analysis::storage::run::RunResult;
use jointplay_analysis::storage::run_file::{Meta, write_run};
use jointplay_analysis::study::run::simulate_until;
use jointplay_analysis::study::spec::{edit, lookup};
use jointplay_solver::model::Model;
use jointplay_solver::scene::{SceneFile, SceneSpec};
use numpy::ndarray::{ArrayD, ArrayView1, ArrayView2, IxDyn};
use numpy::{PyArray, PyArray1, PyArray2};
use pyo3::create_exception;
use pyo3::exceptions::{
    PyException, PyKeyError, PyKeyboardInterrupt, PyRuntimeError, PyTypeError, PyValueError,
};
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyDict, PyFloat, PyInt, PyList, PyString};
use toml::{Table, Value};

/// The program version written into every output file.
const VERSION: &str = env!("CARGO_PKG_VERSION");

create_exception!(
    _jointplay,
    JointplayError,
    PyException,
    "An error of jointplay: the message names the file, the field or path, the value and the time."
);
create_exception!(
    _jointplay,
    Interrupted,
    PyKeyboardInterrupt,
    "Ctrl-C stopped a computation cleanly. `partial` holds what was kept (a Run, or a StudyResult \
     whose file is marked incomplete), or None."
);

fn err(e: impl std::fmt::Display) -> PyErr {
    // A huge value in a file or an edit is echoed at most in part.
    JointplayError::new_err(
        jointplay_analysis::clip_lines(&e.to_string(), jointplay_analysis::MESSAGE_LIMIT)
            .into_owned(),
    )
}

// ---------------------------------------------------------------------------------------------
// TOML values <-> Python objects

fn to_py<'py>(py: Python<'py>, v: &Value) -> PyResult<Bound<'py, PyAny>> {
    Ok(match v {
        Value::String(s) => PyString::new(py, s).into_any(),
        Value::Integer(i) => i.into_pyobject(py)?.into_any(),
        Value::Float(f) => PyFloat::new(py, *f).into_any(),
        Value::Boolean(b) => PyBool::new(py, *b).to_owned().into_any(),
        Value::Datetime(d) => PyString::new(py, &d.to_string()).into_any(),
        Value::Array(a) => {
            let items = a
                .iter()
                .map(|x| to_py(py, x))
                .collect::<PyResult<Vec<_>>>()?;
            PyList::new(py, items)?.into_any()
        }
        Value::Table(t) => table_to_py(py, t)?.into_any(),
    })
}

fn table_to_py<'py>(py: Python<'py>, t: &Table) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    for (k, v) in t {
        d.set_item(k, to_py(py, v)?)?;
    }
    Ok(d)
}

/// A Python value as TOML: numbers (numpy scalars too), booleans, strings, sequences and dicts.
fn from_py(v: &Bound<'_, PyAny>, at: &str) -> PyResult<Value> {
    if v.is_instance_of::<PyBool>() {
        return Ok(Value::Boolean(v.extract()?));
    }
    if v.is_instance_of::<PyInt>() {
        return Ok(Value::Integer(v.extract::<i64>().map_err(|_| {
            err(format!("{at}: the integer {v} does not fit in 64 bits"))
        })?));
    }
    if let Ok(s) = v.cast::<PyString>() {
        return Ok(Value::String(s.extract::<String>()?));
    }
    if let Ok(d) = v.cast::<PyDict>() {
        let mut t = Table::new();
        for (k, x) in d.iter() {
            let k: String = k
                .extract()
                .map_err(|_| PyTypeError::new_err(format!("{at}: table keys must be strings")))?;
            let field = format!("{at}.{k}");
            t.insert(k, from_py(&x, &field)?);
        }
        return Ok(Value::Table(t));
    }
    if let Ok(f) = v.extract::<f64>() {
        return Ok(Value::Float(f));
    }
    if let Ok(items) = v.try_iter() {
        let mut a = Vec::new();
        for (i, x) in items.enumerate() {
            a.push(from_py(&x?, &format!("{at}.{i}"))?);
        }
        return Ok(Value::Array(a));
    }
    Err(PyTypeError::new_err(format!(
        "{at}: cannot store a {} in a scene (use a number, a string, a bool, a list or a dict)",
        v.get_type().name()?
    )))
}

// ---------------------------------------------------------------------------------------------
// Long computations: a worker thread without the GIL, a progress bar and Ctrl-C

/// What a computation reports to its progress bar: the fraction done and a short message.
#[derive(Default)]
struct Shown {
    fraction: f64,
    message: String,
}

/// Runs `work` on a thread of its own with the GIL released, drawing a progress bar from
/// `shown` (after `delay`, when `show`) and checking for signals every 50 ms. A signal requests
/// the stop; the work ends as it does on any interruption and its result is returned with the
/// signal's exception.
fn drive<T: Send>(
    py: Python<'_>,
    mut show: bool,
    label: &str,
    delay: Duration,
    shown: &Mutex<Shown>,
    work: impl FnOnce(&Stop) -> T + Send,
) -> PyResult<(T, Option<PyErr>)> {
    let stop = Stop::new();
    let start = Instant::now();
    let mut bar: Option<Bound<'_, PyAny>> = None;
    let mut signal = None;
    let result = std::thread::scope(|scope| -> PyResult<T> {
        let handle = scope.spawn(|| work(&stop));
        loop {
            py.detach(|| std::thread::sleep(Duration::from_millis(50)));
            let finished = handle.is_finished();
            if signal.is_none()
                && let Err(e) = py.check_signals()
            {
                stop.request();
                signal = Some(e);
            }
            // A bar that cannot be drawn is given up (its error printed once); the
            // computation goes on.
            let mut draw = || -> PyResult<()> {
                if show && bar.is_none() && start.elapsed() >= delay && !finished {
                    let module = py.import("jointplay._progress")?;
                    bar = Some(module.getattr("Bar")?.call1((label,))?);
                }
                if let Some(b) = &bar {
                    let s = shown.lock().unwrap_or_else(|e| e.into_inner());
                    b.call_method1("update", (s.fraction, s.message.as_str()))?;
                }
                Ok(())
            };
            if let Err(e) = draw() {
                e.display(py);
                show = false;
                bar = None;
            }
            if finished {
                break;
            }
        }
        if let Some(b) = &bar
            && let Err(e) = b.call_method0("close")
        {
            e.display(py);
        }
        py.detach(|| handle.join())
            .map_err(|_| PyRuntimeError::new_err("jointplay: the computation thread panicked"))
    })?;
    Ok((result, signal))
}

/// The exception of a signal that stopped a computation: `jointplay.Interrupted` carrying
/// `partial` for Ctrl-C, the signal handler's own exception otherwise.
fn interrupted(py: Python<'_>, signal: PyErr, message: &str, partial: Py<PyAny>) -> PyErr {
    if !signal.is_instance_of::<PyKeyboardInterrupt>(py) {
        return signal;
    }
    let e = Interrupted::new_err(message.to_string());
    if let Err(x) = e.value(py).setattr("partial", partial) {
        return x;
    }
    e
}

fn pool(threads: Option<usize>) -> PyResult<Option<rayon::ThreadPool>> {
    let max = jointplay_analysis::max_threads();
    match threads {
        None => Ok(None),
        Some(0) => Err(err("threads: must be at least 1")),
        Some(n) if n > max => Err(PyValueError::new_err(format!(
            "threads: {n} is more than the {max} allowed (1024, or 64 per core on a larger machine)"
        ))),
        Some(n) => rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build()
            .map(Some)
            .map_err(|e| err(format!("threads: {e}"))),
    }
}

// ---------------------------------------------------------------------------------------------
// Scene

/// A mechanism scene: the TOML tree of a scene file, read and edited by the paths of studies.
///
/// ``scene["joints.S2.clearance.radial_clearance"] = 4e-4`` edits it as a study's ``set`` does
/// (every quantity in SI units: m, kg, s, rad, N, N m); the edited scene is checked against the
/// scene format at once, and a bad path or value raises ``JointplayError`` naming the path.
/// ``del scene[path]`` removes a key as a study's ``remove`` does (removing a joint's
/// ``clearance`` makes it ideal).
///
/// A scene may be used from several threads, and read or edited from a progress callback while
/// it runs: a run simulates the scene as it was when the run started.
#[pyclass(module = "jointplay", frozen)]
struct Scene {
    data: Mutex<SceneData>,
}

#[derive(Clone)]
struct SceneData {
    /// The file the scene was read from (or the path that names it); names it in messages.
    path: PathBuf,
    /// The text as read, and whether the tree was edited since.
    text: String,
    edited: bool,
    tree: Table,
}

impl Scene {
    fn new(text: String, path: PathBuf) -> PyResult<Scene> {
        SceneSpec::parse(&text, &path).map_err(err)?;
        let tree: Table = text.parse().map_err(|e: toml::de::Error| {
            err(format!("{}: {}", path.display(), e.to_string().trim_end()))
        })?;
        Ok(Scene {
            data: Mutex::new(SceneData {
                path,
                text,
                edited: false,
                tree,
            }),
        })
    }

    /// The scene's data; a lock poisoned by a panic elsewhere still holds a valid tree (every
    /// edit is applied to a copy and swapped in whole).
    fn data(&self) -> std::sync::MutexGuard<'_, SceneData> {
        self.data.lock().unwrap_or_else(|e| e.into_inner())
    }
}

impl SceneData {
    fn current_text(&self) -> PyResult<String> {
        if self.edited {
            toml::to_string(&self.tree).map_err(|e| err(format!("{}: {e}", self.path.display())))
        } else {
            Ok(self.text.clone())
        }
    }

    fn file(&self) -> PyResult<SceneFile> {
        let text = self.current_text()?;
        let spec = SceneSpec::parse(&text, &self.path).map_err(err)?;
        Ok(SceneFile {
            path: self.path.clone(),
            text,
            spec,
        })
    }

    /// Applies `value` at `path` (None: remove) to a copy of the tree and keeps it only when the
    /// edited scene is still valid.
    fn apply(&mut self, path: &str, value: Option<&Value>) -> PyResult<()> {
        let mut tree = self.tree.clone();
        edit(&mut tree, path, value)
            .map_err(|m| err(format!("{path}: {m} in {}", self.path.display())))?;
        let text = toml::to_string(&tree)
            .map_err(|e| err(format!("{path}: {e} in {}", self.path.display())))?;
        SceneSpec::parse(&text, &self.path).map_err(|e| err(format!("{path}: {e}")))?;
        self.tree = tree;
        self.edited = true;
        Ok(())
    }
}

#[pymethods]
impl Scene {
    /// A scene from TOML text. ``path`` names it in messages and gives its default name (the
    /// file stem); no file is read.
    #[staticmethod]
    #[pyo3(signature = (text, path = "scene.toml"))]
    fn from_toml(text: String, path: &str) -> PyResult<Scene> {
        Scene::new(text, PathBuf::from(path))
    }

    /// The value at a study path (a list for a path with ``*``); ``KeyError`` naming the path
    /// when nothing is there (a field left at its default is not in the scene).
    fn __getitem__<'py>(&self, py: Python<'py>, path: &str) -> PyResult<Bound<'py, PyAny>> {
        let d = self.data();
        let found = lookup(&d.tree, path)
            .map_err(|m| PyKeyError::new_err(format!("{path}: {m} in {}", d.path.display())))?;
        if path.split('.').any(|s| s == "*") {
            let items = found
                .iter()
                .map(|v| to_py(py, v))
                .collect::<PyResult<Vec<_>>>()?;
            Ok(PyList::new(py, items)?.into_any())
        } else {
            to_py(py, found[0])
        }
    }

    fn __setitem__(&self, path: &str, value: &Bound<'_, PyAny>) -> PyResult<()> {
        // The value is converted (which may run Python code) before the scene is locked.
        let v = from_py(value, path)?;
        self.data().apply(path, Some(&v))
    }

    fn __delitem__(&self, path: &str) -> PyResult<()> {
        self.data().apply(path, None)
    }

    fn __contains__(&self, path: &str) -> bool {
        lookup(&self.data().tree, path).is_ok()
    }

    /// The scene's name (its ``name`` field, or the file stem): names its output file.
    #[getter]
    fn name(&self) -> PyResult<String> {
        Ok(self.data().file()?.name())
    }

    /// The file the scene was read from, or the path given to ``from_toml``.
    #[getter]
    fn path(&self) -> String {
        self.data().path.display().to_string()
    }

    /// The scene as TOML text: the file as read until it is edited, the edited tree after.
    fn to_toml(&self) -> PyResult<String> {
        self.data().current_text()
    }

    /// The scene as a dict (a copy: edit the scene by path).
    fn to_dict<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let tree = self.data().tree.clone();
        table_to_py(py, &tree)
    }

    fn copy(&self) -> Scene {
        Scene {
            data: Mutex::new(self.data().clone()),
        }
    }

    fn __repr__(&self) -> String {
        format!("<jointplay.Scene {}>", self.data().path.display())
    }

    /// Compiles the scene and assembles its initial state: what ``jointplay check`` prints, as a
    /// dict (degrees of freedom, ranks and redundancy, effects, solver, span in s, outputs,
    /// warnings; ``lines`` holds the printed text).
    fn check<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let file = self.data().file()?;
        let (model, mut state) = Model::compile(&file).map_err(err)?;
        let s = Summary::new(&file.path, &model, &mut state).map_err(err)?;
        let d = PyDict::new(py);
        d.set_item("name", &s.name)?;
        d.set_item("file", s.file.display().to_string())?;
        d.set_item("description", &s.description)?;
        let bodies = PyList::empty(py);
        for b in &s.bodies {
            let x = PyDict::new(py);
            x.set_item("name", &b.name)?;
            x.set_item("mass", b.mass)?;
            x.set_item("inertia_diagonal", b.inertia_diagonal.to_vec())?;
            x.set_item("shapes", b.shapes)?;
            bodies.append(x)?;
        }
        d.set_item("bodies", bodies)?;
        let joints = PyList::empty(py);
        for j in &s.joints {
            let x = PyDict::new(py);
            x.set_item("name", &j.name)?;
            x.set_item("kind", j.kind)?;
            x.set_item("body_a", &j.body_a)?;
            x.set_item("body_b", &j.body_b)?;
            x.set_item("rows", j.rows)?;
            joints.append(x)?;
        }
        d.set_item("joints", joints)?;
        let drives = PyList::empty(py);
        for dr in &s.drives {
            let x = PyDict::new(py);
            x.set_item("name", &dr.name)?;
            x.set_item("joint", &dr.joint)?;
            x.set_item("coordinate", format!("{:?}", dr.coordinate).to_lowercase())?;
            x.set_item("profile", &dr.profile)?;
            x.set_item("period", dr.period)?;
            drives.append(x)?;
        }
        d.set_item("drives", drives)?;
        let st = &s.structure;
        d.set_item("coordinates", st.n_coords)?;
        d.set_item("bristle_states", s.bristle_states)?;
        d.set_item("joint_rows", st.joint_rows)?;
        d.set_item("drive_rows", st.drive_rows)?;
        d.set_item("joint_rank", st.joint_rank)?;
        d.set_item("rank", st.rank)?;
        d.set_item("dof", st.dof)?;
        d.set_item("redundant_joint_rows", st.redundant_joint_rows)?;
        d.set_item("redundant_drives", st.redundant_drives)?;
        d.set_item("remaining_dof", st.remaining_dof)?;
        let a = PyDict::new(py);
        a.set_item("iterations", s.assembly.iterations)?;
        a.set_item("initial_residual", s.assembly.initial_residual)?;
        a.set_item("final_residual", s.assembly.final_residual)?;
        a.set_item(
            "initial_velocity_residual",
            s.assembly.initial_velocity_residual,
        )?;
        a.set_item(
            "final_velocity_residual",
            s.assembly.final_velocity_residual,
        )?;
        d.set_item("assembly", a)?;
        // The clearance joints the start closed as ideal joints (compile/start.rs), or None.
        let closed = match &s.closed_start {
            Some(c) => {
                let cd = PyDict::new(py);
                let joints = PyDict::new(py);
                for (name, e) in &c.joints {
                    joints.set_item(name, [e.x, e.y, e.z])?;
                }
                cd.set_item("joints", joints)?;
                cd.set_item("moved", c.moved)?;
                cd.set_item("position_gap", c.gap.map(|g| g.0))?;
                cd.set_item("velocity_gap", c.gap.map(|g| g.1))?;
                cd.into_any()
            }
            None => py.None().into_bound(py),
        };
        d.set_item("closed_start", closed)?;
        d.set_item("effects", &s.effects)?;
        d.set_item("disabled", &s.disabled)?;
        d.set_item("solver", &s.solver)?;
        d.set_item("baumgarte_alpha", s.alpha)?;
        d.set_item("baumgarte_beta", s.beta)?;
        d.set_item("start_time", s.start_time)?;
        d.set_item("end_time", s.end_time)?;
        d.set_item("period", s.period)?;
        let o = PyDict::new(py);
        o.set_item("interval", s.output.interval)?;
        o.set_item("bodies", s.output.bodies)?;
        o.set_item("joints", s.output.joints)?;
        o.set_item("drives", s.output.drives)?;
        o.set_item("accelerations", s.output.accelerations)?;
        o.set_item("diagnostics", s.output.diagnostics)?;
        // An int (or None) when every value keeps the same bits, else a dict by quantity with
        // "default" (None: every bit kept), as the scene gives it.
        let bits = &s.output.significant_bits;
        if bits.by_quantity.is_empty() {
            o.set_item("significant_bits", bits.default)?;
        } else {
            let by = PyDict::new(py);
            by.set_item("default", bits.default)?;
            for (q, b) in &bits.by_quantity {
                by.set_item(q, *b)?;
            }
            o.set_item("significant_bits", by)?;
        }
        d.set_item("output", o)?;
        d.set_item("warnings", &model.warnings)?;
        d.set_item("lines", s.lines())?;
        Ok(d)
    }

    /// Compiles and simulates the scene from its start to its end time (s) and returns the
    /// ``Run``. The GIL is released while it runs; ``progress`` shows a bar after a second.
    /// A run that diverges comes back with ``complete`` False and ``stopped`` set, keeping every
    /// sample before the failure (as the program's file does). Ctrl-C raises
    /// ``jointplay.Interrupted`` whose ``partial`` is the run up to the interruption.
    #[pyo3(signature = (progress = true))]
    fn run(&self, py: Python<'_>, progress: bool) -> PyResult<Run> {
        // The scene as it is now; it stays free for other calls (from the progress callback or
        // other threads) while it runs.
        let file = self.data().file()?;
        let (model, state) = Model::compile(&file).map_err(err)?;
        let shown = Mutex::new(Shown::default());
        let (res, signal) = drive(
            py,
            progress,
            &model.name,
            Duration::from_secs(1),
            &shown,
            |stop| {
                simulate_until(
                    &model,
                    state,
                    &mut |f| {
                        if let Ok(mut s) = shown.lock() {
                            s.fraction = f;
                        }
                    },
                    stop,
                )
            },
        )?;
        let result = res.map_err(|e| err(format!("simulating {}: {e}", file.path.display())))?;
        let run = Run {
            model,
            path: file.path,
            text: file.text,
            result,
        };
        match signal {
            None => Ok(run),
            Some(s) => {
                let t = run
                    .result
                    .stopped
                    .as_ref()
                    .map(|s| s.time)
                    .unwrap_or(f64::NAN);
                let message = format!(
                    "{}: interrupted at t = {t} s; the run up to then is in the exception's `partial`",
                    run.path.display()
                );
                let partial = Py::new(py, run)?.into_any();
                Err(interrupted(py, s, &message, partial))
            }
        }
    }
}

/// Reads a scene file (TOML); errors name the file and the field.
#[pyfunction]
fn load_scene(path: PathBuf) -> PyResult<Scene> {
    let text = std::fs::read_to_string(&path)
        .map_err(|e| err(format!("{}: cannot read: {e}", path.display())))?;
    Scene::new(text, path)
}

// ---------------------------------------------------------------------------------------------
// Run

/// One simulated run: its recorded quantities as numpy arrays that view the run's memory
/// (read-only, no copy), with their units.
///
/// ``run["bodies/bob/position"]`` is a dataset of the run file: one row per sample, one column
/// per component (``run.columns[...]`` names them); ``run.observable("bodies.bob.position.x")``
/// is one column by its study path. ``run.time`` is in s; ``run.units`` gives every dataset's
/// SI unit. ``run.write(out)`` writes the file ``jointplay run`` writes.
#[pyclass(module = "jointplay", frozen)]
struct Run {
    model: Model,
    path: PathBuf,
    text: String,
    result: RunResult,
}

impl Run {
    /// The channel that records observable `path`, and its column there.
    fn column(&self, path: &str) -> PyResult<(&jointplay_analysis::storage::run::Channel, usize)> {
        self.result
            .recording
            .channels
            .iter()
            .find_map(|ch| {
                ch.columns
                    .iter()
                    .position(|o| o.path == path)
                    .map(|k| (ch, k))
            })
            .ok_or_else(|| {
                PyKeyError::new_err(format!(
                    "{path}: not recorded in this run (see Run.columns)"
                ))
            })
    }

    fn channel(&self, dataset: &str) -> PyResult<&jointplay_analysis::storage::run::Channel> {
        self.result.recording.channel(dataset).ok_or_else(|| {
            PyKeyError::new_err(format!(
                "{dataset}: not a dataset of this run (see Run.datasets)"
            ))
        })
    }
}

/// A read-only numpy array viewing `view`, whose memory `owner` (a frozen `Run`) keeps alive.
fn borrowed<'py, D: numpy::ndarray::Dimension>(
    view: numpy::ndarray::ArrayView<'_, f64, D>,
    owner: Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyAny>> {
    // SAFETY: the view points into a `Run`, which is frozen (never mutated) and kept alive by the
    // array's base object; the array is made read-only before it is handed out.
    let a = unsafe { PyArray::borrow_from_array(&view, owner) }.into_any();
    let kw = PyDict::new(a.py());
    kw.set_item("write", false)?;
    a.call_method("setflags", (), Some(&kw))?;
    Ok(a)
}

#[pymethods]
impl Run {
    /// Sample times (s).
    #[getter]
    fn time<'py>(slf: Bound<'py, Self>) -> PyResult<Bound<'py, PyAny>> {
        let r = slf.get();
        let view = ArrayView1::from(&r.result.recording.time[..]);
        borrowed(view, slf.clone().into_any())
    }

    /// A dataset of the run file by its path (``bodies/bob/position``): samples x components,
    /// or one value per sample for a scalar (``drives/motor/force``).
    fn __getitem__<'py>(slf: Bound<'py, Self>, dataset: &str) -> PyResult<Bound<'py, PyAny>> {
        let r = slf.get();
        let ch = r.channel(dataset)?;
        let n = r.result.recording.time.len();
        if ch.scalar {
            borrowed(ArrayView1::from(&ch.values[..]), slf.clone().into_any())
        } else {
            let view = ArrayView2::from_shape((n, ch.width()), &ch.values[..]).map_err(err)?;
            borrowed(view, slf.clone().into_any())
        }
    }

    /// One recorded column by its observable path (``bodies.bob.position.x``), one value per
    /// sample, in the unit ``run.units`` gives its dataset.
    fn observable<'py>(slf: Bound<'py, Self>, path: &str) -> PyResult<Bound<'py, PyAny>> {
        let r = slf.get();
        let n = r.result.recording.time.len();
        let (ch, k) = r.column(path)?;
        let all = ArrayView2::from_shape((n, ch.width()), &ch.values[..]).map_err(err)?;
        borrowed(all.column(k), slf.clone().into_any())
    }

    /// A stroboscopic (Poincare) section of the run: the samples of ``path`` at
    /// ``t0 + phase + k * period`` (s) for k = 0, 1, ... up to the run's last sample, and those
    /// times. ``path`` is a dataset (``joints/pin/radial_eccentricity``, rows x components) or an
    /// observable path (``joints.pin.radial_eccentricity_rate.u``, one value per row).
    /// ``period`` defaults to the drives' common period. Returns ``(times, values)``.
    ///
    /// The strobe times are counted with a tolerance of 1e-9 periods, so the last one, at the
    /// run's end, is kept where rounding would drop it; each must be a sample time (to 1e-6 of
    /// ``output.interval``), else the call says which interval would make it one: the values are
    /// the ones the run took, not interpolated.
    #[pyo3(signature = (path, phase = 0.0, period = None))]
    fn strobe<'py>(
        slf: Bound<'py, Self>,
        path: &str,
        phase: f64,
        period: Option<f64>,
    ) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyAny>)> {
        let py = slf.py();
        let r = slf.get();
        let period = period.or(r.model.settings.period).ok_or_else(|| {
            PyValueError::new_err(
                "the scene's drives have no common period: give period= (s)".to_string(),
            )
        })?;
        let rec = &r.result.recording;
        let rows = rec
            .strobe_rows(r.model.outputs.interval, phase, period)
            .map_err(PyValueError::new_err)?;
        let times: Vec<f64> = rows.iter().map(|&i| rec.time[i]).collect();
        let n = rec.time.len();
        let values = if path.contains('/') {
            let ch = r.channel(path)?;
            let w = ch.width();
            let v: Vec<f64> = rows
                .iter()
                .flat_map(|&i| ch.values[i * w..(i + 1) * w].iter().copied())
                .collect();
            if ch.scalar {
                PyArray1::from_vec(py, v).into_any()
            } else {
                let a = numpy::ndarray::Array2::from_shape_vec((rows.len(), w), v).map_err(err)?;
                PyArray2::from_owned_array(py, a).into_any()
            }
        } else {
            let (ch, k) = r.column(path)?;
            let w = ch.width();
            debug_assert_eq!(ch.values.len(), n * w);
            PyArray1::from_vec(py, rows.iter().map(|&i| ch.values[i * w + k]).collect()).into_any()
        };
        Ok((PyArray1::from_vec(py, times).into_any(), values))
    }

    /// The recorded datasets, in the order of the run file.
    #[getter]
    fn datasets(&self) -> Vec<String> {
        self.result
            .recording
            .channels
            .iter()
            .map(|c| c.dataset.clone())
            .collect()
    }

    /// The SI unit of every dataset (``"m"``, ``"m/s"``, ``"N"``, ...; ``"s"`` for ``time``).
    #[getter]
    fn units<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let d = PyDict::new(py);
        d.set_item("time", "s")?;
        for c in &self.result.recording.channels {
            d.set_item(&c.dataset, &c.unit)?;
        }
        Ok(d)
    }

    /// The observable path of each column of every dataset.
    #[getter]
    fn columns<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let d = PyDict::new(py);
        for c in &self.result.recording.channels {
            let paths: Vec<&str> = c.columns.iter().map(|o| o.path.as_str()).collect();
            d.set_item(&c.dataset, paths)?;
        }
        Ok(d)
    }

    /// The scene's name.
    #[getter]
    fn name(&self) -> String {
        self.model.name.clone()
    }

    /// True when the run reached its end time.
    #[getter]
    fn complete(&self) -> bool {
        self.result.stopped.is_none()
    }

    /// Where and why the run stopped early (``{"time": s, "message": ...}``), or None.
    #[getter]
    fn stopped<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyDict>>> {
        let Some(s) = &self.result.stopped else {
            return Ok(None);
        };
        let d = PyDict::new(py);
        d.set_item("time", s.time)?;
        d.set_item("message", &s.message)?;
        d.set_item("interrupted", self.result.interrupted())?;
        Ok(Some(d))
    }

    /// Steps and right-hand-side evaluations, and the wall time of the integration (s).
    #[getter]
    fn stats<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let s = &self.result.stats;
        let d = PyDict::new(py);
        d.set_item("accepted_steps", s.accepted)?;
        d.set_item("rejected_steps", s.rejected)?;
        d.set_item("rhs_evaluations", s.rhs_evals)?;
        d.set_item("wall_time", s.wall.as_secs_f64())?;
        Ok(d)
    }

    /// Warnings of the scene and of the step-size guard, one line each.
    #[getter]
    fn warnings(&self) -> Vec<String> {
        let mut w = self.model.warnings.clone();
        w.extend(self.result.warnings.iter().map(|x| x.message.clone()));
        w
    }

    /// Writes the run file ``jointplay run`` writes, ``OUT/<scene name>.h5`` (marked incomplete
    /// when the run stopped early), and returns its path. The file appears only once complete.
    #[pyo3(signature = (out = PathBuf::from("out")))]
    fn write(&self, py: Python<'_>, out: PathBuf) -> PyResult<String> {
        py.detach(|| {
            let meta = Meta::of(&self.model, &self.path, &self.text, VERSION);
            write_run(&out, &meta, &self.result)
        })
        .map(|p| p.display().to_string())
        .map_err(err)
    }

    fn __repr__(&self) -> String {
        format!(
            "<jointplay.Run {}: {} samples, {}>",
            self.model.name,
            self.result.recording.time.len(),
            if self.result.stopped.is_none() {
                "complete"
            } else {
                "stopped early"
            }
        )
    }
}

// ---------------------------------------------------------------------------------------------
// HDF5 files

/// An HDF5 file written by jointplay, read on demand: ``f["sweep/x"]`` is a numpy array (every
/// number as float64), ``f.datasets`` lists the datasets, ``f.attrs`` the root attributes and
/// ``f.units`` each dataset's SI unit.
#[pyclass(module = "jointplay", frozen)]
struct H5 {
    reader: Reader,
}

fn attrs_to_py<'py>(py: Python<'py>, attrs: Vec<(String, Attr)>) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    for (name, a) in attrs {
        match a {
            Attr::Text(s) => d.set_item(name, s)?,
            Attr::Float(x) => d.set_item(name, x)?,
            Attr::Integer(i) => d.set_item(name, i)?,
        }
    }
    Ok(d)
}

#[pymethods]
impl H5 {
    #[new]
    fn py_new(path: PathBuf) -> PyResult<H5> {
        Ok(H5 {
            reader: Reader::open(&path).map_err(err)?,
        })
    }

    /// The file's path.
    #[getter]
    fn path(&self) -> String {
        self.reader.path().display().to_string()
    }

    /// Every dataset's path, groups first to last (``cases/ideal/bodies/platform/position``).
    #[getter]
    fn datasets(&self) -> PyResult<Vec<String>> {
        self.reader.datasets().map_err(err)
    }

    /// The root attributes (program, units, study, complete, ...).
    #[getter]
    fn attrs<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let a = self
            .reader
            .attributes(None)
            .map_err(err)?
            .unwrap_or_default();
        attrs_to_py(py, a)
    }

    /// The attributes of a group or dataset by its path.
    fn attributes<'py>(&self, py: Python<'py>, path: &str) -> PyResult<Bound<'py, PyDict>> {
        match self.reader.attributes(Some(path)).map_err(err)? {
            Some(a) => attrs_to_py(py, a),
            None => Err(PyKeyError::new_err(format!(
                "{path}: no group or dataset in {}",
                self.reader.path().display()
            ))),
        }
    }

    /// The SI unit of every dataset that states one.
    #[getter]
    fn units<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let d = PyDict::new(py);
        for (p, u) in self.reader.units().map_err(err)? {
            d.set_item(p, u)?;
        }
        Ok(d)
    }

    /// A dataset: numbers as a numpy float64 array of its shape, text as a list of str.
    fn __getitem__<'py>(&self, py: Python<'py>, path: &str) -> PyResult<Bound<'py, PyAny>> {
        match self.reader.dataset(path).map_err(err)? {
            None => Err(PyKeyError::new_err(format!(
                "{path}: no dataset in {} (see .datasets)",
                self.reader.path().display()
            ))),
            Some(Data::Text(items)) => Ok(PyList::new(py, items)?.into_any()),
            Some(Data::Numbers { shape, values }) => {
                let a = ArrayD::from_shape_vec(IxDyn(&shape), values).map_err(err)?;
                Ok(PyArray::from_owned_array(py, a).into_any())
            }
        }
    }

    fn __contains__(&self, path: &str) -> PyResult<bool> {
        self.reader.contains(path).map_err(err)
    }

    fn __repr__(&self) -> String {
        format!("<jointplay.H5 {}>", self.reader.path().display())
    }
}

/// Opens an HDF5 file written by jointplay (a run, a study, an analysis or a work-precision
/// file).
#[pyfunction]
fn load(path: PathBuf) -> PyResult<H5> {
    H5::py_new(path)
}

// ---------------------------------------------------------------------------------------------
// Studies

/// What ``run_study`` wrote: the HDF5 file, loaded (``result.data``), with the study's kind,
/// whether it is complete, the failures, the table and the figures.
#[pyclass(module = "jointplay", frozen, get_all)]
struct StudyResult {
    /// ``comparison``, ``analysis`` or ``precision``.
    kind: String,
    /// The HDF5 file's path.
    file: String,
    /// The file, loaded on demand.
    data: Py<H5>,
    /// Every case or sweep value done (False: a sweep stopped early; ``resume=True`` runs the
    /// rest).
    complete: bool,
    /// The failed cases or sweep values: (label or value index, message).
    failed: Vec<(String, String)>,
    /// The comparison or work-precision table (markdown), and its file.
    table: Option<String>,
    table_file: Option<String>,
    /// The figures written (PNG and SVG).
    figures: Vec<String>,
    /// Warnings, one line each.
    warnings: Vec<String>,
}

#[pymethods]
impl StudyResult {
    fn __getitem__<'py>(&self, py: Python<'py>, path: &str) -> PyResult<Bound<'py, PyAny>> {
        self.data.get().__getitem__(py, path)
    }

    fn __repr__(&self) -> String {
        format!(
            "<jointplay.StudyResult {} {} ({})>",
            self.kind,
            self.file,
            if self.complete {
                "complete"
            } else {
                "incomplete"
            }
        )
    }
}

fn study_result(py: Python<'_>, o: &Outcome) -> PyResult<StudyResult> {
    Ok(StudyResult {
        kind: o.kind.name().to_string(),
        file: o.file.display().to_string(),
        data: Py::new(
            py,
            H5 {
                reader: Reader::new(&o.file),
            },
        )?,
        complete: o.complete,
        failed: o
            .failed
            .iter()
            .map(|f| (f.label.clone(), f.message.clone()))
            .collect(),
        table: o.table.clone(),
        table_file: o
            .table
            .as_ref()
            .and(o.tables.first())
            .map(|t| t.display().to_string()),
        figures: o.figures.iter().map(|p| p.display().to_string()).collect(),
        warnings: o.warnings.clone(),
    })
}

/// The error of a study that wrote its files but failed in part: the failure and, for a
/// sweep, every failed value.
fn failure(o: &Outcome, f: &str) -> PyErr {
    let mut m = f.to_string();
    if o.analysed.as_ref().is_some_and(|a| a.sweep.is_some()) {
        for x in &o.failed {
            m.push_str(&format!("\n  value {}: {}", x.label, x.message));
        }
    }
    err(m)
}

/// The study `text` (read from `path`) with its `study.scene` replaced by `scene`, written to
/// `out/<study name>.scene.toml` (whole, or not at all) and named by its absolute path.
fn with_scene(
    text: &str,
    path: &std::path::Path,
    scene: &Scene,
    out: &std::path::Path,
) -> PyResult<String> {
    let mut table: Table = text.parse().map_err(|e: toml::de::Error| {
        err(format!("{}: {}", path.display(), e.to_string().trim_end()))
    })?;
    let study = table
        .get_mut("study")
        .and_then(Value::as_table_mut)
        .ok_or_else(|| err(format!("{}: study: no [study] table", path.display())))?;
    if !study.contains_key("scene") {
        return Err(err(format!(
            "{}: study.scene: the study names no scene for `scene` to replace (a study of a \
             built-in system, or a work-precision scene run)",
            path.display()
        )));
    }
    let name = study
        .get("name")
        .and_then(Value::as_str)
        .unwrap_or("study")
        .to_string();
    let scene_text = scene.data().current_text()?;
    std::fs::create_dir_all(out).map_err(|e| err(format!("{}: {e}", out.display())))?;
    let file = out.join(format!("{name}.scene.toml"));
    jointplay_analysis::storage::durable::write_new(&file, scene_text.as_bytes()).map_err(err)?;
    let file = file
        .canonicalize()
        .map_err(|e| err(format!("{}: {e}", file.display())))?;
    study.insert("scene".into(), Value::String(file.display().to_string()));
    toml::to_string(&table).map_err(|e| err(format!("{}: {e}", path.display())))
}

/// Runs a study as ``jointplay run STUDY --out OUT`` does (as ``jointplay precision`` with
/// ``precision=True``: an analysis study with or without a ``[precision]`` table, or a scene)
/// and returns a ``StudyResult`` with the HDF5 file loaded. The program and this function call
/// the same code: they write the same files.
///
/// ``source`` is a study file or its TOML text (scene paths in text are relative to the current
/// directory). ``threads`` sets the cases or sweep values run at once (default: every core).
/// ``resume`` keeps a sweep's finished values in an existing file and ``max_jobs`` stops after
/// that many; for a ``[continuation]`` without a sweep they go on from where its branches
/// stopped and stop after that many points (a continuation already finished is returned as it
/// is, complete, with nothing run; they do not apply with ``precision=True``). A study's ``[continuation]`` is followed after its sweep
/// even when values failed or are left to run, as the program does (the failed values are then
/// raised as ``JointplayError`` after the file is written). ``plots`` draws the figures as the
/// program does. Ctrl-C stops cleanly: a sweep keeps its finished values (``resume=True`` later
/// runs the rest), a continuation its points, and a single run is written with what it
/// computed, marked incomplete; ``jointplay.Interrupted`` then carries the result.
///
/// ``scene`` (a ``Scene``, edited in memory or not) takes the place of the scene the study names
/// (``study.scene``): it is written to ``OUT/<study name>.scene.toml`` and the study runs on that
/// file, so that the study text the result keeps names a scene that exists.
#[pyfunction]
#[pyo3(signature = (source, out = PathBuf::from("out"), threads = None, progress = true, resume = false, max_jobs = None, plots = false, precision = false, scene = None))]
#[allow(clippy::too_many_arguments)]
fn run_study(
    py: Python<'_>,
    source: PathBuf,
    out: PathBuf,
    threads: Option<usize>,
    progress: bool,
    resume: bool,
    max_jobs: Option<usize>,
    plots: bool,
    precision: bool,
    scene: Option<Py<Scene>>,
) -> PyResult<StudyResult> {
    // The arguments first: a bad thread count is refused whatever the source.
    let pool = pool(threads)?;
    let as_text = source.to_string_lossy().to_string();
    let (path, kind, text) = if source.is_file() {
        let (kind, text) = Input::read(&source).map_err(err)?;
        (source.clone(), kind, text)
    } else if as_text.contains('\n') || as_text.contains('[') {
        (
            PathBuf::from("<study text>"),
            Input::of_text(&as_text),
            as_text.clone(),
        )
    } else {
        return Err(err(format!(
            "{}: cannot read: no such file",
            source.display()
        )));
    };
    let text = match &scene {
        Some(sc) => with_scene(&text, &path, sc.get(), &out)?,
        None => text,
    };
    let tally = Mutex::new(Tally::default());
    let shown = Mutex::new(Shown::default());
    let report = |r: Report| {
        let mut s = shown.lock().unwrap_or_else(|e| e.into_inner());
        let p = match r {
            Report::Progress(p) => p,
            Report::Point { fraction, line } => {
                s.fraction = fraction;
                s.message = line.to_string();
                return;
            }
            Report::Analysed(_) | Report::Resuming { .. } => return,
        };
        let mut t = tally.lock().unwrap_or_else(|e| e.into_inner());
        t.update(p);
        match p {
            Progress::Reference => s.message = "reference".into(),
            Progress::Check => s.message = "check of the reference".into(),
            Progress::Run { done, total, what } => {
                s.fraction = done as f64 / total.max(1) as f64;
                s.message = format!("run {}/{total}: {what}", done + 1);
            }
            _ => {
                let (done, total) = t.jobs();
                s.fraction = t.fraction();
                let what = if kind == Input::Comparison {
                    "cases"
                } else {
                    "values"
                };
                // A single run shows its fraction alone.
                if total > 1 {
                    s.message = format!("{done} of {total} {what} done");
                }
            }
        }
    };
    // The bar is labelled with the study's name.
    let label = text
        .parse::<Table>()
        .ok()
        .and_then(|t| t.get("study")?.get("name")?.as_str().map(str::to_string))
        .or_else(|| path.file_stem().map(|s| s.to_string_lossy().to_string()))
        .unwrap_or_default();
    let options = ExecOptions {
        out,
        plots,
        precision,
        resume,
        max_jobs,
        shard: None,
        env: None,
        version: VERSION,
        caller: Caller::Python,
    };
    let source = Source::Text {
        text,
        path: path.clone(),
    };
    let (res, signal) = drive(py, progress, &label, Duration::ZERO, &shown, |stop| {
        let work = || execute(&source, &options, &report, stop);
        match &pool {
            Some(p) => p.install(work),
            None => work(),
        }
    })?;
    match (res, signal) {
        (Ok(o), None) => match &o.failure {
            Some(f) => Err(failure(&o, f)),
            None => study_result(py, &o),
        },
        (Ok(o), Some(s)) => {
            let message = format!(
                "{}: interrupted; {} keeps what was computed{}",
                path.display(),
                o.file.display(),
                if o.resumable {
                    " (resume=True runs the rest)"
                } else {
                    ""
                }
            );
            let partial = Py::new(py, study_result(py, &o)?)?.into_any();
            Err(interrupted(py, s, &message, partial))
        }
        (Err(m), Some(s)) => Err(interrupted(
            py,
            s,
            &format!("{}: interrupted: {m}", path.display()),
            py.None(),
        )),
        (Err(m), None) => Err(err(m)),
    }
}

/// Sets the HDF5 format of every file written from now on in this process: ``"1.10"`` (the
/// default; smaller files, read by HDF5 1.10 and later) or ``"1.8"`` (the oldest format, for
/// readers built on HDF5 1.8), as the program's ``--hdf5-format``. The values are the same.
#[pyfunction]
fn set_hdf5_format(version: &str) -> PyResult<()> {
    jointplay_analysis::storage::h5::set_format(version.parse().map_err(err)?);
    Ok(())
}

/// Sets how every figure drawn from now on in this process is sized, as the program's
/// ``--figure-size``, ``--figure-scale`` and ``--font-scale``: ``size`` is one panel's
/// ``(width, height)`` in px at scale 1 (default ``(560, 380)``), ``scale`` multiplies every pixel
/// dimension (0.25 to 8; 2 for print), ``font_scale`` the fonts alone (0.5 to 4). A value out of
/// range is a ValueError naming it.
#[pyfunction]
#[pyo3(signature = (size = (560, 380), scale = 1.0, font_scale = 1.0))]
fn set_figure_style(size: (u32, u32), scale: f64, font_scale: f64) -> PyResult<()> {
    use jointplay_analysis::figures::plot::{Style, set_style};
    set_style(Style::new(size, scale, font_scale).map_err(PyValueError::new_err)?);
    Ok(())
}

/// jointplay: nonlinear dynamics of mechanisms whose joints have clearance.
#[pymodule]
fn _jointplay(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("__version__", VERSION)?;
    m.add("JointplayError", m.py().get_type::<JointplayError>())?;
    m.add("Interrupted", m.py().get_type::<Interrupted>())?;
    m.add_class::<Scene>()?;
    m.add_class::<Run>()?;
    m.add_class::<H5>()?;
    m.add_class::<StudyResult>()?;
    m.add_function(wrap_pyfunction!(load_scene, m)?)?;
    m.add_function(wrap_pyfunction!(load, m)?)?;
    m.add_function(wrap_pyfunction!(run_study, m)?)?;
    m.add_function(wrap_pyfunction!(set_hdf5_format, m)?)?;
    m.add_function(wrap_pyfunction!(set_figure_style, m)?)?;
    Ok(())
}
