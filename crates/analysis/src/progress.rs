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
//! a plain `f64` ([`crate::run::simulate`]).

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
    use crate::nonlinear::{Loaded, Options, execute};

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
}
