//! Where an adaptive run's steps and right-hand sides go, and what bounds its steps.
//!
//! Runs a scene with an adaptive integrator, as a work-precision study runs it (atol = rtol
//! 1e-3, no step bound; `jointplay precision`), and sorts every accepted step by its contacts:
//! *free* (no contact penetrates at either end), *closed* (some contact penetrates at both ends),
//! *onset* and *end* (a contact begins, or ends, inside the step). Each class gets its steps,
//! its right-hand sides (rejected attempts counted with the step accepted after them), the
//! simulated time it covers and its mean step.
//!
//! A closed step's length h is then set beside h_s, the largest step at which the integrator is
//! stable (|R(h lambda)| <= 1, R its stability function) on the fastest linearised normal mode
//! lambda of the contacts at the step's end ([`Model::contact_modes`]: the step-size guard's
//! mode, m x'' + c x' + k x = 0 with the constrained effective mass). Steps near h_s (h/h_s of
//! 0.5 or more) are held by stability: a method with a larger stability region per right-hand
//! side would take fewer. Steps far below it are held by accuracy.
//!
//! ```text
//! cargo run --release -p jointplay-solver --example step_census -- SCENE INTEGRATOR RTOL [--events] [--until T]
//! ```
//!
//! `--events` sets `solver.onset_events`; `--until` ends the run at T s (default: the scene's
//! span).

use jointplay_solver::dynamics::Mechanism;
use jointplay_solver::model::Model;
use jointplay_solver::ode::{self, Flow, Method, OdeSystem, Step};
use jointplay_solver::scene::SceneSpec;
use jointplay_solver::workspace::Workspace;
use std::path::Path;
use std::process::ExitCode;

/// The mechanism, counting its right-hand sides.
struct Counting<'m> {
    mech: Mechanism<'m>,
    evaluations: u64,
}

impl OdeSystem for Counting<'_> {
    fn dim(&self) -> usize {
        self.mech.dim()
    }
    fn rhs(&mut self, t: f64, y: &[f64], dydt: &mut [f64]) {
        self.evaluations += 1;
        self.mech.rhs(t, y, dydt)
    }
    fn step_accepted(&mut self, t0: f64, y0: &[f64], t1: f64, y1: &[f64]) -> bool {
        self.mech.step_accepted(t0, y0, t1, y1)
    }
    fn check_step(&mut self, t: f64, y: &[f64]) -> Option<String> {
        self.mech.check_step(t, y)
    }
    fn explain_non_finite(&mut self, t: f64, y: &[f64], component: usize) -> String {
        self.mech.explain_non_finite(t, y, component)
    }
    fn events(&self) -> usize {
        self.mech.events()
    }
    fn event_values(&mut self, t: f64, y: &[f64], g: &mut [f64]) {
        self.mech.event_values(t, y, g)
    }
    fn event_restarts_step(&self, i: usize) -> bool {
        self.mech.event_restarts_step(i)
    }
}

/// The largest step h at which `stability` (R at h lambda, as real and imaginary part) keeps
/// |R| <= 1 on the mode `lambda` (1/s), by bisection from a step where it does not.
fn stable_step(stability: fn(f64, f64) -> (f64, f64), lambda: (f64, f64)) -> f64 {
    let stable = |h: f64| {
        let (re, im) = stability(h * lambda.0, h * lambda.1);
        re.hypot(im) <= 1.0
    };
    let mut hi = 1.0 / lambda.0.hypot(lambda.1);
    while stable(hi) {
        hi *= 2.0;
    }
    let mut lo = 0.0;
    for _ in 0..60 {
        let mid = 0.5 * (lo + hi);
        if stable(mid) { lo = mid } else { hi = mid }
    }
    lo
}

const CLASSES: [&str; 4] = ["free", "closed", "onset", "end"];
const BINS: [f64; 4] = [0.25, 0.5, 0.75, 1.0];

fn main() -> ExitCode {
    match census() {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("step_census: {e}");
            ExitCode::FAILURE
        }
    }
}

fn census() -> Result<(), String> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let usage = "usage: step_census SCENE INTEGRATOR RTOL [--events] [--until T]";
    let [scene, integrator, rtol, rest @ ..] = &args[..] else {
        return Err(usage.into());
    };
    let rtol: f64 = rtol
        .parse()
        .map_err(|_| format!("RTOL '{rtol}' is not a number"))?;
    let (mut events, mut until) = (false, None);
    let mut rest = rest.iter();
    while let Some(a) = rest.next() {
        match a.as_str() {
            "--events" => events = true,
            "--until" => {
                let t = rest.next().ok_or(usage)?;
                until = Some(
                    t.parse::<f64>()
                        .map_err(|_| format!("--until '{t}' is not a number"))?,
                );
            }
            _ => return Err(usage.into()),
        }
    }
    let file = SceneSpec::load(Path::new(scene)).map_err(|e| e.to_string())?;
    let (mut model, mut state) = Model::compile(&file).map_err(|e| e.to_string())?;
    model.assemble(&mut state).map_err(|e| e.to_string())?;
    let method = Method::of_family(integrator, rtol, rtol * 1e-3)
        .filter(|m| m.fixed_step().is_none())
        .ok_or_else(|| format!("'{integrator}' is not an adaptive integrator"))?;
    model.settings.method = method;
    model.settings.onset_events = events;
    let t_end = until.unwrap_or(model.settings.end_time);
    let stability = method.integrator().stability;

    let model = &model;
    let mut ws = Workspace::new(model);
    let (mut rates, mut modes) = (Vec::new(), Vec::new());
    let (mut steps, mut evaluations, mut time) = ([0u64; 4], [0u64; 4], [0.0f64; 4]);
    let mut bins = [0u64; BINS.len() + 1];
    let mut counted = 0;
    let mut observe = |sys: &mut Counting, step: &Step| {
        let mut touching = |y: &[f64]| {
            model.contact_rates(y, &mut ws, &mut rates);
            rates.iter().any(|r| r.0 > 0.0)
        };
        let class = match (touching(step.y0), touching(step.y1)) {
            (false, false) => 0,
            (true, true) => 1,
            (false, true) => 2,
            (true, false) => 3,
        };
        steps[class] += 1;
        evaluations[class] += sys.evaluations - counted;
        counted = sys.evaluations;
        let h = step.t1 - step.t0;
        time[class] += h;
        if class == 1 {
            // The workspace holds the evaluation at the step's end (its last stage).
            model.contact_modes(&mut sys.mech.ws, &mut modes);
            let h_s = modes
                .iter()
                .flatten()
                .map(|&lambda| stable_step(stability, lambda))
                .fold(f64::INFINITY, f64::min);
            let ratio = h / h_s;
            bins[BINS.iter().position(|&b| ratio < b).unwrap_or(BINS.len())] += 1;
        }
        Flow::Continue
    };
    let mut sys = Counting {
        mech: Mechanism::new(model),
        evaluations: 0,
    };
    let stats = ode::integrate_steps(
        &mut sys,
        method,
        state.t,
        &mut state.y,
        t_end,
        &[],
        |_, _, _| Flow::Continue,
        Some(&mut observe),
    )
    .map_err(|e| e.to_string())?;

    println!(
        "{scene}: {} from {} s to {t_end} s{}: {} steps ({} rejected), {} right-hand sides",
        method.describe(),
        model.settings.start_time,
        if events { ", onset events" } else { "" },
        stats.accepted,
        stats.rejected,
        stats.rhs_evals
    );
    println!(
        "| steps | count | right-hand sides | share | simulated time (s) | share | mean step (s) |"
    );
    println!("|---|---|---|---|---|---|---|");
    let (all_evaluations, span) = (sys.evaluations as f64, t_end - model.settings.start_time);
    for (k, name) in CLASSES.iter().enumerate() {
        println!(
            "| {name} | {} | {} | {:.1} % | {:.4e} | {:.1} % | {:.3e} |",
            steps[k],
            evaluations[k],
            100.0 * evaluations[k] as f64 / all_evaluations,
            time[k],
            100.0 * time[k] / span,
            time[k] / steps[k].max(1) as f64
        );
    }
    let closed = steps[1].max(1) as f64;
    print!("closed steps by h/h_s:");
    let mut lower = 0.0;
    for (k, count) in bins.iter().enumerate() {
        let label = match BINS.get(k) {
            Some(b) => format!("{lower}-{b}"),
            None => format!(">= {lower}"),
        };
        print!(" {label}: {:.1} %", 100.0 * *count as f64 / closed);
        lower = BINS.get(k).copied().unwrap_or(lower);
    }
    println!();
    Ok(())
}
