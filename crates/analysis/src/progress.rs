//! Progress reports of the library's long computations, one type for all of them.
//!
//! A computation made of jobs (the cases of a comparison study, the values of an analysis sweep)
//! reports [`Progress::Start`] once, then [`Progress::Fraction`] while a job runs and
//! [`Progress::Done`] when it ends; jobs are numbered from 0 in the order of the input (cases,
//! sweep values), so the caller can name them. A work-precision measurement reports its stages:
//! [`Progress::Reference`], [`Progress::Check`], then one [`Progress::Run`] per tested method.
//!
//! Computations that run jobs in parallel take `&(dyn Fn(Progress) + Sync)`; sequential ones take
//! `&mut dyn FnMut(Progress)`. A single integration reports only the fraction of its span done, as
//! a plain `f64` ([`crate::study::run::simulate`]). [`Tally`] turns the reports of a computation made of
//! jobs into the fraction done and the jobs finished, for a progress bar.
//!
//! A [`Stop`] asks a running computation to end early (an interrupt from the keyboard, seen by
//! another thread): each integration checks it at every accepted step or sample and ends as a
//! failure would, keeping what it computed, with [`crate::Error::Interrupted`]. A run is then
//! marked incomplete, a sweep keeps its finished values and leaves the interrupted ones to
//! `--resume`, and a work-precision measurement stops between its runs.

use std::collections::BTreeMap;
use std::sync::atomic::{AtomicBool, Ordering};

/// A request to stop a computation early, shared between the computation and whoever asks.
#[derive(Debug, Default)]
pub struct Stop(AtomicBool);

impl Stop {
    /// A request not yet made.
    pub fn new() -> Stop {
        Stop::default()
    }

    /// Asks the computation to stop as soon as it next checks.
    pub fn request(&self) {
        self.0.store(true, Ordering::SeqCst);
    }

    /// True once [`Stop::request`] was called, or [`request_process_stop`].
    pub fn requested(&self) -> bool {
        self.0.load(Ordering::SeqCst) || PROCESS_STOP.load(Ordering::SeqCst)
    }
}

/// A stop asked of every computation of the process (see [`request_process_stop`]).
static PROCESS_STOP: AtomicBool = AtomicBool::new(false);

/// Asks every computation of this process to stop as if its own [`Stop`] were requested: what
/// the program does on SIGINT and SIGTERM, so that a sweep keeps its finished values, a run is
/// written incomplete and a continuation keeps its points, each in a file that resumes.
pub fn request_process_stop() {
    PROCESS_STOP.store(true, Ordering::SeqCst);
}

/// True once [`request_process_stop`] was called.
pub fn process_stop_requested() -> bool {
    PROCESS_STOP.load(Ordering::SeqCst)
}

/// The state of a computation made of jobs, from its [`Progress`] reports: the fraction of each
/// running job, the jobs finished now, and those finished before it started (a resumed sweep).
#[derive(Debug, Clone, Default)]
pub struct Tally {
    running: BTreeMap<usize, f64>,
    finished: usize,
    pending: usize,
    before: usize,
}

impl Tally {
    /// Takes one report into account.
    pub fn update(&mut self, p: Progress) {
        match p {
            Progress::Start { total, pending } => {
                self.pending = pending;
                self.before = total - pending;
            }
            Progress::Fraction { job, fraction } => {
                self.running.insert(job, fraction);
            }
            Progress::Done { job, .. } => {
                self.running.remove(&job);
                self.finished += 1;
            }
            Progress::Reference | Progress::Check | Progress::Run { .. } => {}
        }
    }

    /// The fraction (0 to 1) of the work of this computation done: finished jobs count whole,
    /// running ones by their fraction.
    pub fn fraction(&self) -> f64 {
        let running: f64 = self.running.values().sum();
        ((self.finished as f64 + running) / self.pending.max(1) as f64).min(1.0)
    }

    /// Jobs done (including those done before a resumed computation started) and all jobs.
    pub fn jobs(&self) -> (usize, usize) {
        (self.finished + self.before, self.pending + self.before)
    }
}

/// One progress report.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Progress<'a> {
    /// `total` jobs, of which `pending` will run now (the others were done before).
    Start { total: usize, pending: usize },
    /// Job `job` has done `fraction` (0 to 1) of its span.
    Fraction { job: usize, fraction: f64 },
    /// Job `job` finished (`ok` false: failed).
    Done { job: usize, ok: bool },
    /// Work-precision: the reference run starts.
    Reference,
    /// Work-precision: the check run of the reference starts.
    Check,
    /// Work-precision: run `done + 1` of `total` starts, with the method `what`.
    Run {
        done: usize,
        total: usize,
        what: &'a str,
    },
}

#[cfg(test)]
mod tests {
    use std::path::Path;
    use std::sync::Mutex;

    use super::*;
    use crate::study::analysis::load::Loaded;
    use crate::study::analysis::sweep::{Options, execute, execute_until};

    const SWEEP: &str = r#"
[study]
name = "progress-sweep"
system = { kind = "duffing", delta = 0.3, alpha = -1.0, beta = 1.0, gamma = 0.2, omega = 1.2, initial = [1.0, 0.0], solver = { integrator = "rk4", step = 0.05 } }

[analysis]
periods = 4
transient = 2
samples_per_period = 0

[[observables]]
name = "x"
path = "x"

[sweep]
parameter = "gamma"
values = [0.2, 0.3, 0.4]
"#;

    /// A resumed computation of 4 jobs, 1 done before: finished jobs count whole, running ones
    /// by their fraction, over the jobs that run now.
    #[test]
    fn a_tally_counts_jobs_done_before_and_the_fractions_of_running_ones() {
        let mut t = Tally::default();
        t.update(Progress::Start {
            total: 4,
            pending: 3,
        });
        t.update(Progress::Fraction {
            job: 1,
            fraction: 0.5,
        });
        t.update(Progress::Fraction {
            job: 2,
            fraction: 0.25,
        });
        t.update(Progress::Done { job: 2, ok: true });
        assert_eq!(t.jobs(), (2, 4));
        assert_eq!(t.fraction(), 0.5);
    }

    /// A sweep says how many values it runs, then reports each value's fraction and its end,
    /// naming the value by its index.
    #[test]
    fn a_sweep_reports_its_start_the_fractions_and_every_value_done() {
        let st = Loaded::parse(SWEEP, Path::new("progress.toml")).unwrap();
        let dir = std::env::temp_dir().join(format!("jointplay-progress-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        // Start and Done as text (the reports borrow), fractions as numbers.
        let events = Mutex::new(Vec::new());
        let fractions = Mutex::new(Vec::new());
        let record = |p: Progress| match p {
            Progress::Fraction { fraction, .. } => fractions.lock().unwrap().push(fraction),
            other => events.lock().unwrap().push(format!("{other:?}")),
        };
        let out = execute(&st, &dir, Options::default(), "test", &record).unwrap();
        let _ = std::fs::remove_dir_all(&dir);
        assert!(out.complete && out.failed.is_empty());
        let mut events = events.into_inner().unwrap();
        assert_eq!(events[0], "Start { total: 3, pending: 3 }");
        events[1..].sort();
        assert_eq!(
            events[1..],
            [
                "Done { job: 0, ok: true }",
                "Done { job: 1, ok: true }",
                "Done { job: 2, ok: true }"
            ]
        );
        let fractions = fractions.into_inner().unwrap();
        assert!(!fractions.is_empty());
        assert!(
            fractions.iter().all(|f| (0.0..=1.0).contains(f)),
            "{fractions:?}"
        );
    }

    /// A stop requested while the first value runs ends the sweep: the values finished are
    /// kept, the interrupted one and those not started stay to run (`done` 0), and a resumed
    /// sweep then writes the same datasets as one never interrupted.
    #[test]
    fn a_stopped_sweep_keeps_its_finished_values_and_resumes_to_the_same_file() {
        let text = SWEEP.replace("[study]", "[study]\ndescription = \"stop\"");
        let st = Loaded::parse(&text, Path::new("progress-stop.toml")).unwrap();
        let base = std::env::temp_dir().join(format!("jointplay-stop-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&base);
        let (a, b) = (base.join("a"), base.join("b"));
        let stop = Stop::new();
        // One value at a time, so that the stop falls inside the second value.
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .unwrap();
        // The first job to report runs alone to its end; the stop falls inside the next one.
        let first = Mutex::new(None);
        let out = pool
            .install(|| {
                execute_until(
                    &st,
                    &a,
                    Options::default(),
                    "test",
                    &|p| {
                        if let Progress::Fraction { job, fraction } = p {
                            let first = *first.lock().unwrap().get_or_insert(job);
                            if job != first && fraction > 0.4 {
                                stop.request();
                            }
                        }
                    },
                    &stop,
                )
            })
            .unwrap();
        assert!(
            out.interrupted && !out.complete && out.failed.is_empty(),
            "{out:?}"
        );
        let done = |f: &Path| -> Vec<u8> {
            hdf5::File::open(f)
                .unwrap()
                .dataset("sweep/done")
                .unwrap()
                .read_raw()
                .unwrap()
        };
        assert_eq!(done(&out.file).iter().filter(|&&d| d == 1).count(), 1);
        assert_eq!(done(&out.file).iter().filter(|&&d| d == 0).count(), 2);
        let resumed = execute(
            &st,
            &a,
            Options {
                resume: true,
                ..Options::default()
            },
            "test",
            &|_| {},
        )
        .unwrap();
        assert!(resumed.complete && !resumed.interrupted);
        let whole = execute(&st, &b, Options::default(), "test", &|_| {}).unwrap();
        let x = |f: &Path| -> Vec<f64> {
            hdf5::File::open(f)
                .unwrap()
                .dataset("sweep/x")
                .unwrap()
                .read_raw()
                .unwrap()
        };
        let (xa, xb) = (x(&resumed.file), x(&whole.file));
        let _ = std::fs::remove_dir_all(&base);
        assert_eq!(xa.len(), 6);
        assert!(xa.iter().zip(&xb).all(|(p, q)| p.to_bits() == q.to_bits()));
    }
}
