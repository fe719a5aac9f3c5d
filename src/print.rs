//! What `jointplay run STUDY` and `jointplay precision` show: progress bars and lines while a
//! study runs ([`Reporter`]), and what it wrote and did once it ends ([`outcome`]), from the data
//! [`jointplay_analysis::execute`] returns.

use std::io::IsTerminal;
use std::path::Path;
use std::sync::Mutex;
use std::time::Instant;

use anyhow::Result;
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use jointplay_analysis::execute::{Analysed, Followed, Kind, Outcome, Report};
use jointplay_analysis::progress::{Progress, Tally};

/// A hidden progress bar of `len` steps drawn with `template` (shown by the caller on stderr).
pub fn progress_bar(len: u64, template: &str) -> ProgressBar {
    let bar = ProgressBar::with_draw_target(Some(len), ProgressDrawTarget::hidden());
    // The templates are literals of this file; a bad one falls back to the default style.
    if let Ok(style) = ProgressStyle::with_template(template) {
        bar.set_style(style);
    }
    bar
}

/// The progress of a study on standard error (cases, values, continuation points, lines of a
/// work-precision study), and the analysis's summary printed once it is written, before its
/// continuation runs.
pub struct Reporter {
    path: std::path::PathBuf,
    quiet: bool,
    precision: bool,
    comparison: bool,
    start: Instant,
    tally: Mutex<Tally>,
    /// Cases or values.
    jobs: ProgressBar,
    /// Continuation points.
    points: ProgressBar,
}

impl Reporter {
    pub fn new(path: &Path, quiet: bool, precision: bool, comparison: bool) -> Reporter {
        let jobs = if comparison {
            let bar = progress_bar(
                0,
                "[{elapsed_precise}] {bar:40} {pos}/{len} cases (eta {eta})",
            );
            if !quiet {
                bar.set_draw_target(ProgressDrawTarget::stderr());
            }
            bar
        } else {
            progress_bar(
                1000,
                "{spinner} [{elapsed_precise}] {bar:40} {msg} (eta {eta})",
            )
        };
        let points = progress_bar(
            1000,
            "{spinner} [{elapsed_precise}] {bar:40} continuation (eta {eta})",
        );
        if !quiet && std::io::stderr().is_terminal() {
            points.set_draw_target(ProgressDrawTarget::stderr());
        }
        Reporter {
            path: path.to_path_buf(),
            quiet,
            precision,
            comparison,
            start: Instant::now(),
            tally: Mutex::new(Tally::default()),
            jobs,
            points,
        }
    }

    pub fn report(&self, r: Report) {
        match r {
            Report::Progress(p) if self.precision => self.precision_line(p),
            Report::Progress(p) => self.progress(p),
            Report::Analysed(a) => {
                self.jobs.finish_and_clear();
                analysed(a);
            }
            Report::Resuming {
                name,
                branches,
                specials,
            } => {
                println!("study        {name} ({})", self.path.display());
                println!("resume       {branches} branches and {specials} special points kept");
            }
            Report::Point { fraction, line } => {
                self.points.set_position((fraction * 1000.0) as u64);
                if !self.quiet && self.points.is_hidden() {
                    println!("point        {line}");
                }
            }
        }
    }

    /// Clears the bars (the study ended).
    pub fn finish(&self) {
        self.jobs.finish_and_clear();
        self.points.finish_and_clear();
    }

    fn progress(&self, p: Progress) {
        if self.comparison {
            // One step per case.
            match p {
                Progress::Start { total, .. } => self.jobs.set_length(total as u64),
                Progress::Done { ok: true, .. } => self.jobs.inc(1),
                _ => {}
            }
            return;
        }
        let mut t = self.tally.lock().unwrap_or_else(|e| e.into_inner());
        t.update(p);
        let (done, total) = t.jobs();
        self.jobs.set_position((t.fraction() * 1000.0) as u64);
        self.jobs
            .set_message(format!("{done} of {total} values done"));
        if !self.quiet && self.start.elapsed().as_secs_f64() > 1.0 && self.jobs.is_hidden() {
            self.jobs.set_draw_target(ProgressDrawTarget::stderr());
        }
    }

    fn precision_line(&self, p: Progress) {
        if self.quiet {
            return;
        }
        let el = self.start.elapsed().as_secs_f64();
        match p {
            Progress::Reference => eprintln!("[{el:7.1} s] reference"),
            Progress::Check => eprintln!("[{el:7.1} s] check of the reference"),
            Progress::Run { done, total, what } => {
                eprintln!("[{el:7.1} s] run {}/{total}: {what}", done + 1)
            }
            Progress::Start { .. } | Progress::Fraction { .. } | Progress::Done { .. } => {}
        }
    }
}

fn wrote(files: &[std::path::PathBuf]) {
    for f in files {
        println!("wrote        {}", f.display());
    }
}

/// An analysis just written: its warnings, what ran, its cost and its chaos classification.
fn analysed(a: &Analysed) {
    let o = &a.run;
    for w in &o.warnings {
        eprintln!("warning: {w}");
    }
    println!("study        {} ({})", a.name, a.path.display());
    if let Some((parameter, continuation)) = &a.sweep {
        println!(
            "sweep        {parameter} over {} values{}; {} run now",
            o.jobs,
            if *continuation {
                " (continuation, up and back down)"
            } else {
                ""
            },
            o.ran
        );
    }
    if let Some(sh) = a.shard {
        println!(
            "shard        {sh}: {} of the {} values (index j with j mod {} = {})",
            o.jobs, a.values, sh.count, sh.index
        );
    }
    println!(
        "periods      {} ({} transient), {} samples per period",
        a.periods, a.transient, a.samples_per_period
    );
    // A single run's Lyapunov run evaluates the right-hand side too, within the same wall time.
    match a.lyapunov_rhs {
        Some(ly) => println!(
            "RHS          {} evaluations in the analysis run and {ly} in the Lyapunov run, {:.0} \
             per second of wall time",
            o.rhs_evals,
            (o.rhs_evals + ly) as f64 / o.wall.max(1e-9)
        ),
        None => println!(
            "RHS          {} evaluations, {:.0} per second of wall time",
            o.rhs_evals,
            o.rhs_evals as f64 / o.wall.max(1e-9)
        ),
    }
    println!("wall time    {:.3} s", o.wall);
    if o.threads > 1 {
        println!(
            "parallel     efficiency {:.0} % on {} threads (jobs {:.1} s of {} x {:.1} s)",
            100.0 * o.efficiency(),
            o.threads,
            o.busy,
            o.threads,
            o.wall
        );
    }
    for line in &a.chaos {
        println!("{line}");
    }
}

/// A continuation's summary and, when it stopped early, how to go on.
fn followed(f: &Followed) {
    for line in &f.lines {
        println!("{line}");
    }
    if let Some(hint) = &f.incomplete {
        println!("incomplete   {hint}");
    }
}

/// What a study wrote and did; its failure as the error.
pub fn outcome(o: &Outcome) -> Result<()> {
    match o.kind {
        Kind::Comparison => {
            for w in &o.warnings {
                eprintln!("warning: {w}");
            }
            for line in &o.lines {
                println!("{line}");
            }
            wrote(std::slice::from_ref(&o.file));
            wrote(&o.tables);
            wrote(&o.figures);
        }
        Kind::Precision => {
            print!("{}", o.table.as_deref().unwrap_or_default());
            println!();
            println!("wrote        {}", o.file.display());
            for f in o.tables.iter().chain(&o.figures) {
                println!("             {}", f.display());
            }
            println!("wall time    {:.1} s", o.wall);
        }
        Kind::Analysis if o.already_finished => println!(
            "finished     the continuation in {} is finished: nothing to resume",
            o.file.display()
        ),
        Kind::Analysis => {
            if let Some(f) = &o.continuation {
                followed(f);
            }
            wrote(std::slice::from_ref(&o.file));
            wrote(&o.tables);
            if o.figures_at_merge {
                println!("figures      drawn by `jointplay merge` from the merged file");
            }
            wrote(&o.figures);
            if let Some(hint) = &o.incomplete {
                println!("incomplete   {hint}");
            }
            if o.analysed.as_ref().is_some_and(|a| a.sweep.is_some()) {
                for f in &o.failed {
                    eprintln!("failed       value {}: {}", f.label, f.message);
                }
            }
        }
    }
    match &o.failure {
        Some(f) => anyhow::bail!("{f}"),
        None => Ok(()),
    }
}
