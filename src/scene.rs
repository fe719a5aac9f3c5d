//! Scenes: `jointplay check` (a scene's compiled summary, or a study checked as `run` checks it)
//! and `jointplay run SCENE` (a simulation written to its run file, optionally continued from
//! another run file).

use std::path::Path;
use std::time::Instant;

use anyhow::{Context, Result};
use indicatif::ProgressDrawTarget;
use jointplay_analysis::figures::run_figures;
use jointplay_analysis::flow::summary::Summary;
use jointplay_analysis::storage::hybrid::read_run_file;
use jointplay_analysis::storage::inputs::Input;
use jointplay_analysis::storage::run_file::Meta;
use jointplay_analysis::study::analysis::Loaded;
use jointplay_analysis::study::precision;
use jointplay_analysis::study::run::{resume_to_file, simulate_to_file};
use jointplay_analysis::study::spec::Study;
use jointplay_solver::model::Model;
use jointplay_solver::scene::SceneSpec;

use crate::VERSION;
use crate::print::progress_bar;

pub fn check(path: &Path) -> Result<()> {
    match Input::read(path)?.0 {
        Input::Scene => check_scene(path),
        Input::Comparison => {
            // Everything `run` checks before the first case starts: the study, every case's
            // edited scene compiled and assembled.
            let study = Study::load(path)?;
            println!(
                "study        {} ({}), comparison of {} cases",
                study.spec.study.name,
                path.display(),
                study.cases.len()
            );
            for c in &study.cases {
                let (model, mut state) = Model::compile(&c.scene)?;
                for w in &model.warnings {
                    eprintln!("warning: {w}");
                }
                let s = Summary::new(&c.scene.path, &model, &mut state)?;
                println!(
                    "case         {}: {} bodies, {} joints, {} s to {} s",
                    c.label,
                    s.bodies.len(),
                    s.joints.len(),
                    s.start_time,
                    s.end_time
                );
            }
            Ok(())
        }
        kind => {
            // The study and the flow of its first value, as `run` builds them before running.
            let st = Loaded::load(path)?;
            let what = if kind == Input::Precision {
                let p = precision::Precision::new(st)?;
                println!(
                    "study        {} ({}), work-precision, {} runs",
                    p.study().spec.study.name,
                    path.display(),
                    p.total_runs()
                );
                return Ok(());
            } else if st.spec.sweep.is_some() {
                format!("analysis sweep of {} values", st.jobs.len())
            } else {
                "analysis".to_string()
            };
            println!(
                "study        {} ({}), {what}",
                st.spec.study.name,
                path.display()
            );
            Ok(())
        }
    }
}

fn check_scene(path: &Path) -> Result<()> {
    let scene = SceneSpec::load(path)?;
    let (model, mut state) = Model::compile(&scene)?;
    for w in &model.warnings {
        eprintln!("warning: {w}");
    }
    for line in Summary::new(path, &model, &mut state)?.lines() {
        println!("{line}");
    }
    Ok(())
}

/// Simulates a scene into DIR/<name>.h5 (from the final state of the run file `from`, when
/// given) and draws its figures.
pub fn run_scene(
    path: &Path,
    out: &Path,
    plots: bool,
    quiet: bool,
    from: Option<&Path>,
) -> Result<()> {
    let scene = SceneSpec::load(path)?;
    let (model, state) = Model::compile(&scene)?;
    for w in &model.warnings {
        eprintln!("warning: {w}");
    }
    let target = out.join(format!("{}.h5", model.name));
    if let Some(f) = from
        && let (Ok(a), Ok(b)) = (f.canonicalize(), target.canonicalize())
        && a == b
    {
        // The continuation holds the samples after the file's final state only: written over
        // the file it continues, it would replace the only copy of the run's first part.
        anyhow::bail!(
            "{}: --from {} would be replaced by the run continued from it: write the \
             continuation to another --out directory",
            path.display(),
            f.display()
        );
    }
    let start = Instant::now();
    let bar = progress_bar(
        1000,
        "{spinner} [{elapsed_precise}] {bar:40} {percent:>3}% (eta {eta})",
    );
    let mut shown = false;
    let mut progress = |f: f64| {
        if !quiet && !shown && start.elapsed().as_secs_f64() > 1.0 {
            bar.set_draw_target(ProgressDrawTarget::stderr());
            shown = true;
        }
        bar.set_position((f * 1000.0) as u64);
    };
    // The run goes to its file as it is recorded: memory does not grow with its length.
    let meta = Meta::of(&model, path, &scene.text, VERSION);
    let mut begin = model.settings.start_time;
    let (result, written) = match from {
        None => {
            simulate_to_file(&model, state, &mut progress, out, &meta).map_err(anyhow::Error::new)
        }
        Some(f) => {
            let from_state = read_run_file(f)?;
            begin = from_state.t;
            resume_to_file(&model, from_state, &mut progress, out, &meta).map_err(|e| {
                anyhow::Error::new(e).context(format!("continuing from {}", f.display()))
            })
        }
    }
    .with_context(|| format!("simulating {}", path.display()))?;
    bar.finish_and_clear();
    for w in &result.warnings {
        eprintln!("warning: {}: {}", path.display(), w.message);
    }
    let file = &written.path;
    if result.interrupted() {
        eprintln!(
            "stopped      {}\nwrote        {} with the {} samples recorded before the stop, marked \
             incomplete (attributes complete = 0, interrupted = 1); continue it with\n             \
             jointplay run {} --out OTHER_DIR --from {}",
            result
                .stopped
                .as_ref()
                .map_or(String::new(), |s| s.to_string()),
            file.display(),
            written.samples,
            path.display(),
            file.display()
        );
        return Ok(());
    }
    if let Some(s) = &result.stopped {
        anyhow::bail!(
            "simulating {}: {}\nwrote {} with the {} samples recorded before the failure, marked incomplete (attribute complete = 0)",
            path.display(),
            s,
            file.display(),
            written.samples
        );
    }
    let st = &result.stats;
    let wall = st.wall.as_secs_f64();
    println!("scene        {} ({})", model.name, path.display());
    println!(
        "span         {} s to {} s, {} samples",
        begin, model.settings.end_time, written.samples
    );
    println!("integrator   {}", model.settings.method.describe());
    println!(
        "steps        {} accepted, {} rejected, {} ended at an event",
        st.accepted, st.rejected, st.events
    );
    println!(
        "RHS          {} evaluations, {:.0} per second of integration",
        st.rhs_evals,
        st.rhs_evals as f64 / wall.max(1e-9)
    );
    // The recording is evaluated and written beside the integration, by the file's own thread;
    // the whole run also holds its last block and closing the file.
    println!(
        "wall time    {wall:.3} s integrating, {:.3} s with the file written",
        start.elapsed().as_secs_f64()
    );
    if let Some((p, v)) = written.max_drift {
        println!("drift        max |Phi| {p:.3e} (m, rad), max |Phi'| {v:.3e} (m/s, rad/s)");
    }
    println!("wrote        {}", file.display());
    if plots {
        if written.bucket > 1 {
            println!(
                "figures      drawn from the first sample and the farthest excursion of every {} \
                 (the file holds them all)",
                written.bucket
            );
        }
        for f in run_figures(out, &model.name, &result)? {
            println!("wrote        {}", f.display());
        }
    }
    Ok(())
}
