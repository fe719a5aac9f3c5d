//! The sweep executor of an analysis study ([`execute_until`]): the file set up or resumed, the
//! jobs run (in parallel, or in order for a continuation sweep) and their results written
//! through the sweep's journal ([`crate::storage::sweep`]); a single run written while it goes.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc;
use std::time::Instant;

use jointplay_solver::state::HybridState;
use rayon::prelude::*;

use crate::flow::Flow;
use crate::measures::sections::HistorySink;
use crate::progress::{Progress, Stop};
use crate::storage::analysis_file::{JobResult, Root, SingleHistory, SweepLayout, write_single};
use crate::storage::h5::{PartialFile, h5err};
use crate::storage::hybrid;
use crate::storage::rows::Outcome as Kept;
use crate::storage::sweep as storage;
use crate::study::spec::invalid;
use crate::{Error, Result};
use jointplay_solver::ode::OdeSystem;

use crate::storage::analysis_file::Shard;
use crate::study::analysis::job::throttled;
use crate::study::analysis::load::{Base, Loaded};
use crate::study::analysis::spec::*;

/// Summary of an executed study.
#[derive(Debug, Clone)]
pub struct Outcome {
    pub file: PathBuf,
    /// Jobs in the file: every value of the sweep, or a shard's values.
    pub jobs: usize,
    pub ran: usize,
    /// Every job of the file done (or failed); false when stopped by `max_jobs` or on request.
    pub complete: bool,
    /// Stopped on request ([`execute_until`]): a single run written incomplete, or a sweep with
    /// values left to run.
    pub interrupted: bool,
    /// Failed jobs: their index in the whole sweep and the message.
    pub failed: Vec<(usize, String)>,
    /// Warnings of a single run (the scene's and the step-size guard's).
    pub warnings: Vec<String>,
    pub wall: f64,
    pub rhs_evals: u64,
    /// Wall time the jobs of this call took, summed over the threads that ran them (s).
    pub busy: f64,
    /// Threads of the pool the jobs ran on (1 for a single run or a continuation).
    pub threads: usize,
    /// The sweep's table beside its file, `<stem>.md` and `<stem>.csv` ([`crate::storage::table`];
    /// none for a single run or a shard).
    pub tables: Vec<PathBuf>,
}

impl Outcome {
    /// Parallel efficiency: the jobs' summed wall time over the threads' wall time,
    /// `busy / (threads * wall)`; 1 when every thread ran a job from start to end. What it misses
    /// is the time threads waited (the last jobs of a sweep running alone) and the time outside
    /// the jobs (reading the study, writing the file).
    pub fn efficiency(&self) -> f64 {
        self.busy / (self.threads.max(1) as f64 * self.wall.max(1e-9))
    }
}

/// How [`execute`] treats an existing file and how much it runs.
#[derive(Debug, Clone, Copy, Default)]
pub struct Options {
    /// Keep the finished jobs of an existing file and run only the rest.
    pub resume: bool,
    /// Stop after this many jobs have finished (the file stays incomplete; resume later).
    pub max_jobs: Option<usize>,
    /// Run only this shard of the sweep's values, into its shard file (see [`crate::study::shards`]).
    pub shard: Option<Shard>,
}

/// Runs the study and writes `dir/<name>.h5`: for a single run under `<name>.h5.partial`, renamed
/// once complete; for a sweep job by job (with `resume`, only the jobs the existing file lacks).
/// Time histories go to the file block by block while each run goes. With a shard, only the
/// shard's values, into `dir/<name>.shard-I-of-N.h5`. A history block that cannot be written
/// ends the study with that error, as any other write does.
pub fn execute(
    st: &Loaded,
    dir: &Path,
    opts: Options,
    version: &str,
    progress: &(dyn Fn(Progress) + Sync),
) -> Result<Outcome> {
    execute_until(st, dir, opts, version, progress, &Stop::new())
}

/// [`execute`] that ends early when `stop` is requested. A single run is then written with what
/// it recorded, marked incomplete with the time it stopped (`stopped_at`); a sweep keeps the
/// values finished before, leaves the interrupted ones not run (`/sweep/done` 0, for `resume`)
/// and starts no other. [`Outcome::interrupted`] says so.
pub fn execute_until(
    st: &Loaded,
    dir: &Path,
    opts: Options,
    version: &str,
    progress: &(dyn Fn(Progress) + Sync),
    user_stop: &Stop,
) -> Result<Outcome> {
    let start = Instant::now();
    let Some(sw) = &st.spec.sweep else {
        if let Some(sh) = opts.shard {
            return Err(invalid(
                &st.path,
                "sweep",
                format!("--shard {sh}: shards split a sweep's values; this study has no [sweep]"),
            ));
        }
        return single_run(st, dir, version, progress, user_stop, start);
    };
    let mut sweep = Sweep::set_up(st, sw, dir, opts, progress)?;
    let stop = AtomicBool::new(sweep.limit == 0);
    if sw.continuation {
        sweep.run_in_order(progress, user_stop, &stop)?;
    } else {
        sweep.run_in_parallel(progress, user_stop, &stop)?;
    }
    sweep.write(version, user_stop, start)
}

/// A study without a sweep: one run, its histories appended to `<name>.h5.partial` while it
/// goes, the file finished (or marked incomplete with the error) once it ends.
fn single_run(
    st: &Loaded,
    dir: &Path,
    version: &str,
    progress: &(dyn Fn(Progress) + Sync),
    user_stop: &Stop,
    start: Instant,
) -> Result<Outcome> {
    let name = &st.spec.study.name;
    progress(Progress::Start {
        total: 1,
        pending: 1,
    });
    // A run that fails keeps what it recorded, in a file marked incomplete. The time
    // histories are appended to the file while the run goes.
    let mut out = PartialFile::create(dir, name, version)?;
    let partial = out.partial().to_path_buf();
    let e = h5err(&partial);
    let history = if st.spec.analysis.samples_per_period > 0 {
        if let Err(err) = SingleHistory::create(&out.file, &st.spec.observables) {
            return Err(out.fail(err));
        }
        // On disk whole (h5::create_streamed), then the histories opened there.
        if let Err(err) = out.materialize() {
            out.discard();
            return Err(err);
        }
        match SingleHistory::open(
            &out.file,
            &st.spec.observables,
            st.spec.analysis.history_bits(),
        ) {
            Ok(h) => Some(h),
            Err(err) => return Err(out.fail(err)),
        }
    } else {
        None
    };
    // A block that cannot be written stops the run and, below, the study: it is the file
    // that failed, not the run.
    let mut write_failure = None;
    let mut append = |from: usize, time: &[f64], values: &[Vec<f64>]| -> Result<()> {
        match &history {
            Some(h) => h.append(from, time, values).map_err(|err| {
                write_failure = Some(e(err));
                Error::Interrupted { time: None }
            }),
            None => Ok(()),
        }
    };
    let job_start = Instant::now();
    let ran = st.run_job_partial(
        None,
        None,
        &mut throttled(0, progress),
        user_stop,
        history.is_some().then_some(&mut append as HistorySink),
    );
    let (r, failure) = match (ran, write_failure) {
        (Ok(x), None) => x,
        (_, Some(err)) | (Err(err), None) => {
            drop(history);
            out.discard();
            return Err(err);
        }
    };
    progress(Progress::Done {
        job: 0,
        ok: failure.is_none(),
    });
    let planes: Vec<&str> = st.planes.iter().map(|p| p.name.as_str()).collect();
    let a = &st.spec.analysis;
    let written = write_single(
        &out.file,
        &Root::of(st, &r.integrator, r.start, r.period),
        &st.spec.observables,
        &planes,
        (a.samples_per_period > 0).then_some(a.history_bits()),
        &r,
        failure.as_ref(),
    );
    drop(history);
    if let Err(err) = written {
        return Err(out.fail(err));
    }
    let file = out.finish()?;
    let interrupted = matches!(failure, Some(Error::Interrupted { .. }));
    Ok(Outcome {
        file,
        jobs: 1,
        ran: 1,
        complete: !interrupted,
        interrupted,
        failed: failure.map(|e| (0, e.to_string())).into_iter().collect(),
        warnings: r.warnings,
        wall: start.elapsed().as_secs_f64(),
        rhs_evals: r.trace.stats.rhs_evals,
        busy: job_start.elapsed().as_secs_f64(),
        threads: 1,
        tables: Vec::new(),
    })
}

/// A sweep being run: the rows of its file, its lock, its layout and the values kept so far
/// (from its journal, when resumed), and the tally of this call's jobs.
struct Sweep<'s> {
    st: &'s Loaded,
    opts: Options,
    /// The job (index in the whole sweep) of each row of the file: the identity without a shard.
    rows: Vec<usize>,
    path: PathBuf,
    /// Held until the file is written (crate::storage::lock).
    _lock: crate::storage::lock::Lock,
    layout: SweepLayout,
    store: storage::Store,
    journal: PathBuf,
    warnings: Vec<String>,
    /// At most this many values finish in this call (`max_jobs`).
    limit: usize,
    tally: Tally,
    /// Nanoseconds the jobs took, summed over the threads.
    busy: AtomicU64,
    threads: usize,
}

/// What this call's jobs did: values finished (done or failed), the failures, the
/// right-hand-side evaluations of the values done.
#[derive(Default)]
struct Tally {
    finished: usize,
    failed: Vec<(usize, String)>,
    rhs: u64,
}

impl<'s> Sweep<'s> {
    /// The rows of the file (a shard's or every value), its lock taken before anything under its
    /// name is touched, and the values kept from an earlier run when resuming.
    fn set_up(
        st: &'s Loaded,
        sw: &SweepSpec,
        dir: &Path,
        opts: Options,
        progress: &(dyn Fn(Progress) + Sync),
    ) -> Result<Sweep<'s>> {
        let name = &st.spec.study.name;
        let rows: Vec<usize> = match opts.shard {
            Some(sh) => {
                crate::study::shards::check(st, sh)?;
                sh.jobs(st.jobs.len())
            }
            None => (0..st.jobs.len()).collect(),
        };
        crate::storage::durable::create_dir(dir)?;
        let path = match opts.shard {
            Some(sh) => dir.join(sh.file_name(name)),
            None => dir.join(format!("{name}.h5")),
        };
        let lock = crate::storage::lock::Lock::acquire(&path)?;
        let n = rows.len();
        let layout = st.layout(sw)?;
        let mut warnings = Vec::new();
        let store = storage::open(
            &path,
            &st.text,
            opts.shard,
            &layout,
            n,
            opts.resume,
            &mut |w| warnings.push(w),
        )?;
        let journal = store.journal.path().to_path_buf();
        let pending = store.values.iter().filter(|v| v.is_none()).count();
        progress(Progress::Start { total: n, pending });
        Ok(Sweep {
            st,
            opts,
            rows,
            path,
            _lock: lock,
            layout,
            store,
            journal,
            warnings,
            limit: opts.max_jobs.unwrap_or(usize::MAX),
            tally: Tally::default(),
            busy: AtomicU64::new(0),
            threads: 1,
        })
    }

    /// A continuation sweep: the values in order, each from the previous value's final state
    /// (read back from the values kept when resuming, so a resumed run continues from exactly
    /// the same state). Never sharded: rows are jobs.
    fn run_in_order(
        &mut self,
        progress: &(dyn Fn(Progress) + Sync),
        user_stop: &Stop,
        stop: &AtomicBool,
    ) -> Result<()> {
        let st = self.st;
        let mut prev: Option<HybridState> = None;
        for j in 0..self.rows.len() {
            if stop.load(Ordering::SeqCst) || user_stop.requested() {
                break;
            }
            if let Some(v) = &self.store.values[j] {
                prev = match &v.outcome {
                    Kept::Done(row) => Some(storage::row_state(row).map_err(|m| Error::Io {
                        file: self.journal.clone(),
                        message: format!("value {j}: {m}"),
                    })?),
                    Kept::Failed(_) => None,
                };
                continue;
            }
            let job_start = Instant::now();
            let res = st.run_job(
                Some(st.jobs[j].0),
                prev.as_ref(),
                &mut throttled(j, progress),
                user_stop,
                None,
            );
            self.busy
                .fetch_add(job_start.elapsed().as_nanos() as u64, Ordering::Relaxed);
            prev = res.as_ref().ok().map(|r| r.trace.final_state.clone());
            keep(
                &mut self.tally,
                &mut self.store,
                Keeping {
                    rows: &self.rows,
                    layout: &self.layout,
                    limit: self.limit,
                    stop,
                    progress,
                },
                vec![(j, res)],
            )?;
        }
        Ok(())
    }

    /// Independent values on the caller's rayon pool (the global one, or one it installed), the
    /// costliest first (crate::study::schedule); a thread of its own keeps each result as it
    /// comes, several at once when they come together.
    fn run_in_parallel(
        &mut self,
        progress: &(dyn Fn(Progress) + Sync),
        user_stop: &Stop,
        stop: &AtomicBool,
    ) -> Result<()> {
        let st = self.st;
        let threads = rayon::current_num_threads();
        self.threads = threads;
        // Bounded, so that finished jobs wait for the writer instead of piling up in memory.
        let (tx, rx) = mpsc::sync_channel::<(usize, Box<Result<JobResult>>)>(2 * threads);
        // The costs of the values kept already seed the estimate.
        let known: Vec<Option<f64>> = self
            .store
            .values
            .iter()
            .map(|v| match v.as_ref().map(|v| &v.outcome) {
                Some(Kept::Done(row)) => row.f64s("wall_time").first().copied(),
                _ => None,
            })
            .collect();
        let todo: Vec<bool> = self.store.values.iter().map(|v| v.is_none()).collect();
        let queue = std::sync::Mutex::new(crate::study::schedule::Queue::new(
            self.rows.iter().map(|&j| st.jobs[j].0).collect(),
            &todo,
            &known,
        ));
        let (rows, layout, limit, busy) = (&self.rows, &self.layout, self.limit, &self.busy);
        let (tally, store) = (&mut self.tally, &mut self.store);
        let write_err = std::thread::scope(|scope| {
            let writer = scope.spawn(move || {
                let mut write_err = None;
                while let Ok(first) = rx.recv() {
                    // The results that came meanwhile are kept together: one commit for all.
                    let mut batch = vec![(first.0, *first.1)];
                    while let Ok((r, res)) = rx.try_recv() {
                        batch.push((r, *res));
                    }
                    if write_err.is_some() || stop.load(Ordering::SeqCst) {
                        continue;
                    }
                    let how = Keeping {
                        rows,
                        layout,
                        limit,
                        stop,
                        progress,
                    };
                    if let Err(err) = keep(tally, store, how, batch) {
                        // Stop the other jobs: their results could not be kept.
                        stop.store(true, Ordering::SeqCst);
                        write_err = Some(err);
                    }
                }
                write_err
            });
            let queue = &queue;
            (0..threads).into_par_iter().for_each_with(tx, |tx, _| {
                loop {
                    if stop.load(Ordering::SeqCst) || user_stop.requested() {
                        return;
                    }
                    let next = queue.lock().map(|mut q| q.take_next()).unwrap_or(None);
                    let Some(r) = next else { return };
                    let j = rows[r];
                    let job_start = Instant::now();
                    let res = st.run_job(
                        Some(st.jobs[j].0),
                        None,
                        &mut throttled(j, progress),
                        user_stop,
                        None,
                    );
                    let took = job_start.elapsed();
                    busy.fetch_add(took.as_nanos() as u64, Ordering::Relaxed);
                    // A failed or interrupted run's time says little about the value's cost.
                    if res.is_ok()
                        && let Ok(mut q) = queue.lock()
                    {
                        q.finished(r, took.as_secs_f64());
                    }
                    // The writer lives until every sender is gone.
                    let _ = tx.send((r, Box::new(res)));
                }
            });
            writer.join()
        });
        match write_err {
            Ok(None) => Ok(()),
            Ok(Some(err)) => Err(err),
            Err(_) => Err(Error::Io {
                file: self.journal.clone(),
                message: "the thread keeping the sweep's results stopped unexpectedly".into(),
            }),
        }
    }

    /// The file, written from the values kept; a complete one ends the journal. The sweep's
    /// table beside it (a shard's rows are part of a sweep: its table comes with the merge).
    fn write(self, version: &str, user_stop: &Stop, start: Instant) -> Result<Outcome> {
        let st = self.st;
        let wall = start.elapsed().as_secs_f64();
        let jobs: Vec<(f64, i8)> = self.rows.iter().map(|&j| st.jobs[j]).collect();
        let shard = self.opts.shard.map(|sh| (sh, self.rows.as_slice()));
        let complete = storage::write_file(
            &self.path,
            &self.layout,
            version,
            &jobs,
            shard,
            &self.store.values,
            wall,
        )?;
        if complete {
            drop(self.store);
            crate::storage::durable::remove(&self.journal)?;
        }
        let tables = if self.opts.shard.is_none() {
            crate::storage::table::write_beside(&self.path)?
        } else {
            Vec::new()
        };
        Ok(Outcome {
            file: self.path.clone(),
            jobs: self.rows.len(),
            ran: self.tally.finished,
            complete,
            interrupted: user_stop.requested() && !complete,
            failed: self.tally.failed,
            warnings: self.warnings,
            wall,
            rhs_evals: self.tally.rhs,
            busy: self.busy.load(Ordering::Relaxed) as f64 * 1e-9,
            threads: self.threads,
            tables,
        })
    }
}

/// What [`keep`] needs of the sweep besides its tally and its store.
struct Keeping<'k> {
    rows: &'k [usize],
    layout: &'k SweepLayout,
    limit: usize,
    stop: &'k AtomicBool,
    progress: &'k (dyn Fn(Progress) + Sync),
}

/// Keeps the results of the jobs in rows `batch`: appended to the journal, forced to disk once
/// for all of them, and only then counted. An interrupted value is left to run again; values
/// past `max_jobs` are dropped.
fn keep(
    tally: &mut Tally,
    store: &mut storage::Store,
    how: Keeping,
    batch: Vec<(usize, Result<JobResult>)>,
) -> Result<()> {
    let mut counted = Vec::new();
    for (r, res) in batch {
        if tally.finished + counted.len() >= how.limit {
            break;
        }
        let j = how.rows[r];
        let outcome = match res {
            Err(Error::Interrupted { .. }) => continue,
            Ok(res) => {
                tally.rhs += res.trace.stats.rhs_evals;
                counted.push((j, true));
                Kept::Done(storage::job_row(how.layout, &res))
            }
            Err(err) => {
                let msg = err.to_string();
                tally.failed.push((j, msg.clone()));
                counted.push((j, false));
                Kept::Failed(msg)
            }
        };
        store.add(crate::storage::rows::Value { row: r, outcome })?;
    }
    store.commit()?;
    for (job, ok) in counted {
        (how.progress)(Progress::Done { job, ok });
        tally.finished += 1;
    }
    if tally.finished >= how.limit {
        how.stop.store(true, Ordering::SeqCst);
    }
    Ok(())
}

impl Loaded {
    /// The layout of this study's sweep file, from a probe of job 0 (its flow is built, not run).
    fn layout(&self, sw: &SweepSpec) -> Result<SweepLayout> {
        let target = self.target(Some(self.jobs[0].0))?;
        let flow = target.flow();
        // The memory of a new run has the sizes of the flow's memory (contacts, clearance joints).
        let mut memory = HybridState::default();
        flow.save_memory(&mut memory);
        let (method, period, start) = (flow.method(), flow.period(), flow.start_time());
        let plan = self.plan(method, start, period);
        Ok(SweepLayout {
            root: Root::of(self, &method.describe(), start, period),
            observables: self.spec.observables.clone(),
            units: flow.observable_units(),
            sections: self.planes.iter().map(|p| p.name.clone()).collect(),
            parameter: sw.parameter.clone(),
            unit: sw.unit.clone(),
            continuation: sw.continuation,
            kept: plan.kept(),
            history: plan.history_len(),
            shape: hybrid::StateShape {
                dim: flow.dim(),
                contacts: memory.onset.len(),
                clearances: memory.warned.len(),
            },
            chaos: self.chaos_spec(),
            bits: self.spec.analysis.history_bits(),
        })
    }
}

impl Root {
    /// The root attributes of `st`'s file.
    pub(crate) fn of(st: &Loaded, integrator: &str, start: f64, period: f64) -> Root {
        let a = &st.spec.analysis;
        let flow = match &st.base {
            Base::Scene { path, .. } => format!("scene {}", path.display()),
            Base::System(_) => "system".to_string(),
        };
        Root {
            study_name: st.spec.study.name.clone(),
            study_file: st.path.display().to_string(),
            study: st.text.clone(),
            description: st.spec.study.description.clone(),
            flow,
            flow_text: st.base_text(),
            integrator: integrator.to_string(),
            start_time: start,
            period,
            phase: a.phase,
            periods: a.periods as u64,
            transient: a.transient as u64,
            samples_per_period: a.samples_per_period as u64,
            history_periods: a.history_periods.unwrap_or(a.periods - a.transient) as u64,
        }
    }
}
