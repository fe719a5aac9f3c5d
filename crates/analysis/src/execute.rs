//! The one entry point of the program (`jointplay run STUDY`, `jointplay precision`) and of the
//! Python package (`run_study`): [`execute`] runs a comparison, analysis or work-precision study
//! and returns what it wrote and what the caller reports as data ([`Outcome`]); nothing here
//! prints.
//!
//! What lives here once: which options apply to which study kind (and the message when one does
//! not), an analysis study's sequence (the analysis or sweep, then its `[continuation]` into the
//! same file), the resume of a continuation without a sweep, the shard of a Slurm job array, the
//! lock of the output, the failure summary (failed values, a continuation that could not start)
//! and what to say about resuming an incomplete study.

use std::path::{Path, PathBuf};

use crate::figures::plot::Format;
use crate::figures::redraw;
use crate::progress::{Progress, Stop};
use crate::storage::analysis_file::Shard;
use crate::storage::inputs::Input;
use crate::study::analysis::load::Loaded;
use crate::study::analysis::sweep::{Options, execute_until};
use crate::study::comparison::Comparison;
use crate::study::continuation::run::{Begin, run_into};
use crate::study::precision::measure::{Precision, scene_study};
use crate::study::spec::Study;
use crate::{Error, Result};

/// What a study is read from.
#[derive(Debug, Clone)]
pub enum Source {
    /// A study file (or a scene, for work-precision).
    File(PathBuf),
    /// Study text; `path` names it in messages (scene paths are relative to its directory).
    Text { text: String, path: PathBuf },
}

/// Who calls: the options are named as the caller spells them in messages and hints.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Caller {
    /// `jointplay run` and `jointplay precision` (`--resume`, `--max-jobs`, `--shard`).
    Program,
    /// The Python package's `run_study` (`resume=True`, `max_jobs`).
    Python,
}

/// An environment variable's value by its name.
pub type Env = dyn Fn(&str) -> Option<String> + Sync;

/// How a study is run.
pub struct ExecOptions<'a> {
    /// The output directory (created if missing).
    pub out: PathBuf,
    /// Draw the figures (PNG and SVG).
    pub plots: bool,
    /// Work-precision of an analysis study or a scene instead of running it.
    pub precision: bool,
    /// A sweep: keep the finished values of the existing file. A continuation without a sweep:
    /// go on from where it stopped.
    pub resume: bool,
    /// Stop after this many sweep values (or continuation points, without a sweep).
    pub max_jobs: Option<usize>,
    /// Compute only this shard of a sweep's values.
    pub shard: Option<Shard>,
    /// The environment, for the shard of a Slurm job array (`SLURM_ARRAY_*`); None: none.
    pub env: Option<&'a Env>,
    /// The program version written into the files.
    pub version: &'a str,
    pub caller: Caller,
}

/// What [`execute`] reports while it runs.
#[derive(Debug, Clone, Copy)]
pub enum Report<'a> {
    /// Cases or values started and done, work-precision runs.
    Progress(Progress<'a>),
    /// The analysis (or sweep) is written; its continuation follows when it has one.
    Analysed(&'a Analysed),
    /// An unfinished continuation goes on: the branches and special points it keeps.
    Resuming {
        name: &'a str,
        branches: usize,
        specials: usize,
    },
    /// A continuation point is done: the fraction of the continuation and a line about it.
    Point { fraction: f64, line: &'a str },
}

/// The kind of a study run.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    Comparison,
    Analysis,
    Precision,
}

impl Kind {
    pub fn name(self) -> &'static str {
        match self {
            Kind::Comparison => "comparison",
            Kind::Analysis => "analysis",
            Kind::Precision => "precision",
        }
    }
}

/// A failed case or sweep value.
#[derive(Debug, Clone)]
pub struct Failed {
    /// The case's label, or the value's index (with its parameter value in a sweep).
    pub label: String,
    pub message: String,
}

/// What an analysis (a single run or a sweep) did, before its continuation.
#[derive(Debug, Clone)]
pub struct Analysed {
    pub name: String,
    pub path: PathBuf,
    /// The sweep: its parameter, whether it is a continuation sweep, and the values in the study.
    pub sweep: Option<(String, bool)>,
    pub values: usize,
    /// The shard run, and whether it came from the Slurm environment.
    pub shard: Option<Shard>,
    pub shard_from_env: bool,
    pub periods: usize,
    pub transient: usize,
    pub samples_per_period: usize,
    /// The outcome of the sweep executor (file, jobs, ran, failures, timings, tables).
    pub run: crate::study::analysis::sweep::Outcome,
    /// Right-hand-side evaluations of the Lyapunov run of a single run, beside `run.rhs_evals`.
    pub lyapunov_rhs: Option<u64>,
    /// The chaos classification, one line each.
    pub chaos: Vec<String>,
}

/// What a continuation did.
#[derive(Debug, Clone, Default)]
pub struct Followed {
    /// Its summary, one line each (branches, special points, wall time).
    pub lines: Vec<String>,
    /// Points computed now.
    pub points: usize,
    /// Stopped before its end (on request or after `max_jobs` points): `resume` goes on; the
    /// hint, as the caller spells it.
    pub unfinished: bool,
    pub incomplete: Option<String>,
    /// Why it could not start (or go on), written into the file too.
    pub error: Option<String>,
}

/// What a study wrote and what the caller reports: files, tables, failures, hints.
#[derive(Debug, Clone)]
pub struct Outcome {
    pub kind: Kind,
    /// The study's name and what it was read from.
    pub name: String,
    pub path: PathBuf,
    /// The HDF5 file written.
    pub file: PathBuf,
    /// A comparison's or work-precision's table (markdown) and the table files written (a
    /// sweep's `.md` and `.csv`).
    pub table: Option<String>,
    pub tables: Vec<PathBuf>,
    /// The figures written (with `plots`).
    pub figures: Vec<PathBuf>,
    /// A shard asked for figures: they are drawn from the merged file.
    pub figures_at_merge: bool,
    pub warnings: Vec<String>,
    /// A comparison's summary, one line each.
    pub lines: Vec<String>,
    /// An analysis study: its analysis (none when only its continuation was resumed).
    pub analysed: Option<Analysed>,
    /// A resumed continuation: the branches and special points kept.
    pub resumed: Option<(usize, usize)>,
    /// The continuation run now, if any.
    pub continuation: Option<Followed>,
    /// A continuation without a sweep asked to resume is finished already: nothing ran.
    pub already_finished: bool,
    pub failed: Vec<Failed>,
    /// Why the study counts as failed, after its files were written (failed cases or values, a
    /// single run that failed, a continuation that could not start); the caller's error.
    pub failure: Option<String>,
    /// Every case, value and continuation point done.
    pub complete: bool,
    /// Stopped on request.
    pub interrupted: bool,
    /// The incomplete study's hint, as the caller spells it ("stopped after 3 values: rerun with
    /// --resume to compute the rest").
    pub incomplete: Option<String>,
    /// What goes on with `resume` ("resume=True runs the rest"), when anything does.
    pub resumable: bool,
    /// Wall time of the whole call (s).
    pub wall: f64,
}

impl Outcome {
    fn new(kind: Kind, name: String, path: PathBuf, file: PathBuf) -> Outcome {
        Outcome {
            kind,
            name,
            path,
            file,
            table: None,
            tables: Vec::new(),
            figures: Vec::new(),
            figures_at_merge: false,
            warnings: Vec::new(),
            lines: Vec::new(),
            analysed: None,
            resumed: None,
            continuation: None,
            already_finished: false,
            failed: Vec::new(),
            failure: None,
            complete: true,
            interrupted: false,
            incomplete: None,
            resumable: false,
            wall: 0.0,
        }
    }
}

/// Runs the study of `source` as `options` ask, reporting through `report`, and stopping early
/// when `stop` is requested (a sweep keeps its finished values, a continuation its points, a
/// single run is written incomplete). Errors are those before anything is written, or of
/// writing; a study that wrote its files but failed in part returns them with
/// [`Outcome::failure`] set.
pub fn execute(
    source: &Source,
    options: &ExecOptions,
    report: &(dyn Fn(Report) + Sync),
    stop: &Stop,
) -> Result<Outcome> {
    let start = std::time::Instant::now();
    let (path, kind, text) = match source {
        Source::File(p) => {
            let (kind, text) = Input::read(p)?;
            (p.clone(), kind, text)
        }
        Source::Text { text, path } => (path.clone(), Input::of_text(text), text.clone()),
    };
    check_options(&path, kind, options)?;
    let progress = |p: Progress| report(Report::Progress(p));
    let mut o = if options.precision {
        work_precision(&path, kind, &text, options, &progress, stop)?
    } else if kind == Input::Comparison {
        comparison(&path, &text, options, &progress, stop)?
    } else {
        analysis(&path, &text, options, report, stop)?
    };
    o.wall = start.elapsed().as_secs_f64();
    Ok(o)
}

/// The options `options` sets that do not apply to a study of `kind` from `path`, as an error
/// naming them as the caller spells them. A scene is refused unless for work-precision (the
/// program simulates scenes itself, and calls this first with the options it was given).
pub fn check_options(path: &Path, kind: Input, options: &ExecOptions) -> Result<()> {
    let refuse = |message: &str| {
        Err(Error::Io {
            file: path.to_path_buf(),
            message: message.to_string(),
        })
    };
    let program = options.caller == Caller::Program;
    let sweep_options = options.resume || options.max_jobs.is_some() || options.shard.is_some();
    if options.precision {
        return match kind {
            Input::Comparison => {
                refuse("a comparison study has several cases; give one scene or an analysis study")
            }
            _ if sweep_options => refuse(if program {
                "--resume, --max-jobs and --shard do not apply to work-precision"
            } else {
                "resume and max_jobs do not apply to work-precision (precision=True)"
            }),
            _ => Ok(()),
        };
    }
    match kind {
        Input::Scene if !program => {
            refuse("a scene, not a study: use jointplay.load_scene(...).run(), or precision=True")
        }
        Input::Scene | Input::Comparison if sweep_options => refuse(if program {
            "--resume, --max-jobs and --shard apply to analysis studies with a [sweep]"
        } else {
            "resume and max_jobs apply to analysis studies with a [sweep] or a [continuation]"
        }),
        _ => Ok(()),
    }
}

/// The options of an analysis study `st` that do not apply to it (no sweep, or no continuation).
fn check_analysis_options(st: &Loaded, options: &ExecOptions) -> Result<()> {
    let continuation_only = st.spec.sweep.is_none() && st.spec.continuation.is_some();
    let resume = options.resume || options.max_jobs.is_some();
    if st.spec.sweep.is_none() && (options.shard.is_some() || (!continuation_only && resume)) {
        return Err(Error::Io {
            file: st.path.clone(),
            message: match options.caller {
                Caller::Program => {
                    "--resume and --max-jobs apply to studies with a [sweep] or \
                                    a [continuation], --shard to studies with a [sweep]"
                }
                Caller::Python => {
                    "resume and max_jobs apply to studies with a [sweep] or a [continuation]"
                }
            }
            .into(),
        });
    }
    Ok(())
}

fn figures(file: &Path, options: &ExecOptions) -> Result<Vec<PathBuf>> {
    if !options.plots {
        return Ok(Vec::new());
    }
    redraw(file, &options.out, &[Format::Png, Format::Svg])
}

fn create_dir(dir: &Path) -> Result<()> {
    std::fs::create_dir_all(dir).map_err(|e| Error::Write {
        file: dir.to_path_buf(),
        message: e.to_string(),
    })
}

/// A comparison study: every case run, the file, the table and the figures written; failed
/// cases are recorded in the file and make [`Outcome::failure`].
fn comparison(
    path: &Path,
    text: &str,
    options: &ExecOptions,
    progress: &(dyn Fn(Progress) + Sync),
    stop: &Stop,
) -> Result<Outcome> {
    let study = Study::parse(text, path)?;
    let cases = Comparison::run_until(&study, progress, stop)?;
    let file = cases.write(&options.out, options.version)?;
    let mut o = Outcome::new(
        Kind::Comparison,
        study.spec.study.name.clone(),
        path.to_path_buf(),
        file.clone(),
    );
    o.warnings = cases.warnings();
    o.lines = cases.lines();
    let table = cases.write_table(&file, &options.out)?;
    o.table = Some(std::fs::read_to_string(&table).map_err(|e| Error::Read {
        file: table.clone(),
        message: e.to_string(),
    })?);
    o.tables.push(table);
    o.figures = if options.plots {
        cases.figures(&options.out)?
    } else {
        Vec::new()
    };
    o.failed = cases
        .failed
        .iter()
        .map(|(label, message)| Failed {
            label: label.clone(),
            message: message.clone(),
        })
        .collect();
    o.complete = o.failed.is_empty();
    o.interrupted = stop.requested();
    o.failure = cases.finish().err().map(|e| e.to_string());
    Ok(o)
}

/// Work-precision of an analysis study or a scene: the file, the table and the figure.
fn work_precision(
    path: &Path,
    kind: Input,
    text: &str,
    options: &ExecOptions,
    progress: &(dyn Fn(Progress) + Sync),
    stop: &Stop,
) -> Result<Outcome> {
    let study = match kind {
        Input::Scene => scene_study(path)?,
        _ => Loaded::parse(text, path)?,
    };
    let mut p = Precision::new(study)?;
    let r = p
        .execute_until(&mut |pr| progress(pr), stop)
        .map_err(|e| Error::Context {
            what: format!("work-precision of {}", path.display()),
            inner: Box::new(e),
        })?;
    create_dir(&options.out)?;
    let file = r.write(&options.out, &p.study().text, &p.study().path)?;
    let md = options.out.join(format!("{}.md", r.name));
    let table = r.markdown();
    std::fs::write(&md, &table).map_err(|e| Error::Write {
        file: md.clone(),
        message: e.to_string(),
    })?;
    let mut o = Outcome::new(Kind::Precision, r.name.clone(), path.to_path_buf(), file);
    o.figures = figures(&o.file, options)?;
    o.table = Some(table);
    o.tables.push(md);
    Ok(o)
}

/// An analysis study: a continuation without a sweep resumed, or the analysis (a single run or
/// a sweep, or a shard of it) then its continuation.
fn analysis(
    path: &Path,
    text: &str,
    options: &ExecOptions,
    report: &(dyn Fn(Report) + Sync),
    stop: &Stop,
) -> Result<Outcome> {
    let st = Loaded::parse(text, path)?;
    check_analysis_options(&st, options)?;
    let continuation_only = st.spec.sweep.is_none() && st.spec.continuation.is_some();
    // A continuation's start state, read before the analysis rewrites the output file (it may
    // be the file named by `continuation.start`).
    let start_state = st.continuation_start()?;
    // A continuation goes on from its file; with none begun (stopped before its first point),
    // it starts afresh, as a sweep with nothing kept does.
    let file = options.out.join(format!("{}.h5", st.spec.study.name));
    if continuation_only && options.resume && crate::storage::continuation_file::begun(&file) {
        return resume_continuation(&st, file, options, report, stop);
    }
    // In a Slurm job array, a sweep is sharded by the task's id unless the shard is given.
    let mut shard = options.shard;
    let mut from_env = false;
    if let Some(env) = options.env
        && shard.is_none()
        && st.spec.sweep.is_some()
    {
        shard = Shard::from_slurm(env).map_err(|m| Error::Io {
            file: path.to_path_buf(),
            message: m,
        })?;
        from_env = shard.is_some();
    }
    // One writer of the study's file from the sweep or run to the end of its continuation (a
    // shard's file is locked by the shard's run).
    create_dir(&options.out)?;
    let _lock = match shard {
        None => Some(crate::storage::lock::Lock::acquire(&file)?),
        Some(_) => None,
    };
    let opts = Options {
        resume: options.resume,
        max_jobs: options.max_jobs,
        shard,
    };
    let progress = |p: Progress| report(Report::Progress(p));
    let run = execute_until(&st, &options.out, opts, options.version, &progress, stop).map_err(
        |e| Error::Context {
            what: match (from_env, shard) {
                (true, Some(sh)) => format!(
                    "running {} as shard {sh} (from SLURM_ARRAY_TASK_ID, SLURM_ARRAY_TASK_COUNT \
                     and SLURM_ARRAY_TASK_MIN)",
                    path.display()
                ),
                _ => format!("running {}", path.display()),
            },
            inner: Box::new(e),
        },
    )?;
    let analysed = Analysed {
        name: st.spec.study.name.clone(),
        path: path.to_path_buf(),
        sweep: st
            .spec
            .sweep
            .as_ref()
            .map(|sw| (sw.parameter.clone(), sw.continuation)),
        values: st.jobs.len(),
        shard,
        shard_from_env: from_env,
        periods: st.spec.analysis.periods,
        transient: st.spec.analysis.transient,
        samples_per_period: st.spec.analysis.samples_per_period,
        lyapunov_rhs: crate::storage::chaos::lyapunov_rhs_evals(&run.file)?,
        chaos: crate::storage::chaos::summary(&run.file)?,
        run,
    };
    report(Report::Analysed(&analysed));
    let run = &analysed.run;
    let mut o = Outcome::new(
        Kind::Analysis,
        st.spec.study.name.clone(),
        path.to_path_buf(),
        run.file.clone(),
    );
    o.warnings.clone_from(&run.warnings);
    o.tables.clone_from(&run.tables);
    o.interrupted = run.interrupted;
    o.complete = run.complete && run.failed.is_empty();
    // Periodic orbits: followed once the analysis file is written, into the same file (not by
    // a shard, which holds only part of a sweep), whatever values failed or are left.
    if st.spec.continuation.is_some() && shard.is_none() && !stop.requested() {
        let limit = options.max_jobs.filter(|_| continuation_only);
        let begin = Begin::Fresh(start_state);
        let f = follow(&st, &run.file, begin, limit, options.caller, report, stop)?;
        o.complete &= !f.unfinished && f.error.is_none();
        o.interrupted |= stop.requested();
        o.resumable |= f.unfinished;
        o.continuation = Some(f);
    }
    if shard.is_some() {
        // Shards may run side by side into one directory: the figures come from the merge.
        o.figures_at_merge = options.plots;
    } else {
        o.figures = figures(&run.file, options)?;
    }
    explain(&mut o, &st, run, shard, path, options.caller);
    o.analysed = Some(analysed);
    Ok(o)
}

/// What an analysis's outcome says of itself: how to finish an incomplete run or sweep, which
/// values failed, and the failure message (a single run's, the failed values', or the
/// continuation's that could not start).
fn explain(
    o: &mut Outcome,
    st: &Loaded,
    run: &crate::study::analysis::sweep::Outcome,
    shard: Option<Shard>,
    path: &Path,
    caller: Caller,
) {
    let program = caller == Caller::Program;
    if !run.complete && st.spec.sweep.is_none() {
        // One run has no finished values to keep: it runs again from its start.
        o.incomplete = Some(if program {
            "stopped before its end: run the same command again to redo it".into()
        } else {
            "stopped before its end: run it again to redo it".into()
        });
    } else if !run.complete {
        o.resumable = true;
        o.incomplete = Some(format!(
            "stopped after {} values: rerun with {}{} to compute the rest",
            run.ran,
            if program { "--resume" } else { "resume=True" },
            shard.map(|s| format!(" --shard {s}")).unwrap_or_default()
        ));
    }
    o.failed = run
        .failed
        .iter()
        .map(|(j, m)| Failed {
            label: match st.jobs.get(*j) {
                Some(v) if st.spec.sweep.is_some() => format!("{j} ({})", v.0),
                _ => j.to_string(),
            },
            message: m.clone(),
        })
        .collect();
    o.failure = if let Some((_, m)) = run.failed.first()
        && st.jobs.is_empty()
    {
        Some(format!(
            "{}: {m}\nwrote {} with what was computed before the failure, marked incomplete \
             (attribute complete = 0)",
            path.display(),
            run.file.display()
        ))
    } else if !run.failed.is_empty() {
        Some(format!(
            "{} of {} values failed; the others are in {}",
            run.failed.len(),
            run.jobs,
            run.file.display()
        ))
    } else {
        o.continuation
            .as_ref()
            .and_then(|f| f.error.as_ref())
            .map(|e| {
                format!(
                    "{}: the continuation could not start: {e}\n(the analysis is in {}; \
                 /continuation holds the error)",
                    path.display(),
                    run.file.display()
                )
            })
    };
}

/// A continuation without a sweep that goes on from its file `file` (or is finished already).
fn resume_continuation(
    st: &Loaded,
    file: PathBuf,
    options: &ExecOptions,
    report: &(dyn Fn(Report) + Sync),
    stop: &Stop,
) -> Result<Outcome> {
    let path = &st.path;
    let nothing = |what: &str| Error::Io {
        file: path.clone(),
        message: format!(
            "nothing to resume: {} {what} (run without {})",
            file.display(),
            match options.caller {
                Caller::Program => "--resume",
                Caller::Python => "resume=True",
            }
        ),
    };
    if !file.exists() {
        return Err(nothing("does not exist"));
    }
    let mut o = Outcome::new(
        Kind::Analysis,
        st.spec.study.name.clone(),
        path.clone(),
        file.clone(),
    );
    let Some(prior) = crate::storage::continuation_file::read_unfinished(
        &file,
        &crate::study::continuation::run::layout(st)?,
    )?
    else {
        if crate::storage::continuation_file::is_finished(&file)? {
            o.already_finished = true;
            return Ok(o);
        }
        return Err(nothing("has no continuation"));
    };
    let kept = (prior.branches.len(), prior.specials.len());
    report(Report::Resuming {
        name: &st.spec.study.name,
        branches: kept.0,
        specials: kept.1,
    });
    o.resumed = Some(kept);
    let f = follow(
        st,
        &file,
        Begin::Resume(prior),
        options.max_jobs,
        options.caller,
        report,
        stop,
    )?;
    if let Some(e) = &f.error {
        return Err(Error::Io {
            file: path.clone(),
            message: format!("the continuation could not go on: {e}"),
        });
    }
    o.complete = !f.unfinished;
    o.resumable = f.unfinished;
    o.interrupted = stop.requested();
    o.continuation = Some(f);
    o.figures = figures(&file, options)?;
    Ok(o)
}

/// Follows the periodic orbits of `st`'s `[continuation]` into its analysis file `file`, written
/// after every point (a stop keeps what was computed), at most `limit` points now.
fn follow(
    st: &Loaded,
    file: &Path,
    begin: Begin,
    limit: Option<usize>,
    caller: Caller,
    report: &(dyn Fn(Report) + Sync),
    stop: &Stop,
) -> Result<Followed> {
    let mut points = 0usize;
    let res = run_into(st, file, begin, limit, &mut |r| {
        report(Report::Point {
            fraction: r.fraction,
            line: &r.line,
        });
        points += 1;
        !stop.requested()
    })
    .map_err(|e| Error::Context {
        what: "writing the continuation into the analysis file".into(),
        inner: Box::new(e),
    })?;
    Ok(match res {
        Ok(c) => Followed {
            lines: crate::study::continuation::branch::summary(&c),
            points,
            unfinished: c.unfinished.is_some(),
            incomplete: c.unfinished.as_ref().map(|_| {
                format!(
                    "stopped after {points} points: rerun with {} to go on",
                    match caller {
                        Caller::Program => "--resume",
                        Caller::Python => "resume=True",
                    }
                )
            }),
            error: None,
        },
        Err(e) => Followed {
            points,
            error: Some(e.to_string()),
            ..Followed::default()
        },
    })
}
