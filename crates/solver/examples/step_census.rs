//! Where an adaptive run's steps and right-hand sides go, and what bounds its steps.
//!
//! Runs a scene with an adaptive integrator, as a work-precision study runs it (atol = rtol
//! 1e-3, no step bound; `jointplay precision`), and sorts every accepted step by its contacts:
//! *free* (no contact penetrates at either end), *closed* (some contact penetrates at both ends),
//! *onset* and *end* (a contact begins, or ends, inside the step). Each class gets its steps,
//! its right-hand sides (rejected attempts counted with the step accepted after them, an
//! evaluation at a step's end state after it, such as the first stage after an onset changed
//! the history, with that step), the simulated time it covers and its mean step.
//!
//! A closed step's length h is then set beside h_s, the largest step at which the integrator is
//! stable (|R(h lambda)| <= 1, R its stability function) on the fastest linearised normal mode
//! lambda of the contacts at the step's end ([`Model::contact_modes`]: the step-size guard's
//! mode, m x'' + c x' + k x = 0 with the constrained effective mass; the friction's modes are
//! left out). Steps near h_s (h/h_s of 0.5 or more) are held by stability: a method with a
//! larger stability region per right-hand side would take fewer. Steps far below it are held by
//! accuracy. A linearly implicit method is stable on these modes at any step (h_s infinite).
//! The census also gives the spread of |lambda| of the modes that set h_s, and the method's
//! stability floor over the closed time: the sum of h/h_s over the closed steps, the number of
//! steps the closed time would take if every step were as long as h_s (the integral of dt/h_s
//! over it), times the fewest right-hand sides a step took. An explicit method whose contacts
//! stay closed for as long cannot cover that time with fewer, whatever it does where contacts
//! begin and end: a step longer than h_s amplifies the mode, so a run exceeds h_s only briefly
//! (the bin `>= 1`), and the floor is an estimate, not a strict bound.
//!
//! ```text
//! cargo run --release -p jointplay-solver --example step_census -- SCENE INTEGRATOR RTOL [--events] [--ends] [--friction] [--until T]
//! ```
//!
//! `--events` sets `solver.onset_events`, `--ends` `solver.end_events`, `--friction`
//! `solver.friction_events`; `--until` ends the run at T s (default: the scene's span).

use jointplay_solver::dynamics::Mechanism;
use jointplay_solver::error::{Error, Result};
use jointplay_solver::model::Model;
use jointplay_solver::ode::{self, Events, Flow, Method, OdeSystem, Stiffness};
use jointplay_solver::scene::SceneSpec;
use jointplay_solver::workspace::Workspace;
use std::path::Path;
use std::process::ExitCode;

/// The mechanism, counting its right-hand sides and sorting its accepted steps.
struct Census<'m> {
    mech: Mechanism<'m>,
    /// Scratch of the contact geometry at the step's ends, and the contact modes.
    ws: Workspace,
    rates: Vec<(f64, f64, bool)>,
    modes: Vec<Option<(f64, f64)>>,
    stability: fn(f64, f64) -> (f64, f64),
    evaluations: u64,
    /// Right-hand sides up to the last accepted step.
    counted: u64,
    /// The last accepted step's class and end `(t1, y1)` (t1 NaN before the first): an
    /// evaluation there (the first stage of the next step after an onset changed the history,
    /// or after an event) belongs to it.
    last: (usize, f64, Vec<f64>),
    /// Per class of [`CLASSES`]: steps, right-hand sides, simulated time (s).
    steps: [u64; 4],
    class_evaluations: [u64; 4],
    time: [f64; 4],
    /// Closed steps by h/h_s, in the bins of [`BINS`].
    bins: [u64; BINS.len() + 1],
    /// Per closed step, |lambda| (1/s) of the mode that sets h_s.
    fastest: Vec<f64>,
    /// The sum of h/h_s over the closed steps: the steps the closed time would take at h_s.
    steps_at_h_s: f64,
    /// The fewest right-hand sides an accepted step took (the method's cost of a step that is
    /// not rejected and not cut at an event).
    fewest: u64,
}

impl Census<'_> {
    fn touching(&mut self, y: &[f64]) -> bool {
        self.mech
            .model
            .contact_rates(y, &mut self.ws, &mut self.rates);
        self.rates.iter().any(|r| r.0 > 0.0)
    }

    /// Sorts the step from `(t0, y0)` to `(t1, y1)`, just accepted.
    fn count(&mut self, (t0, y0): (f64, &[f64]), (t1, y1): (f64, &[f64])) {
        let class = match (self.touching(y0), self.touching(y1)) {
            (false, false) => 0,
            (true, true) => 1,
            (false, true) => 2,
            (true, false) => 3,
        };
        self.steps[class] += 1;
        let taken = self.evaluations - self.counted;
        if taken > 0 {
            self.fewest = self.fewest.min(taken);
        }
        self.class_evaluations[class] += taken;
        self.counted = self.evaluations;
        self.last.0 = class;
        self.last.1 = t1;
        self.last.2.clear();
        self.last.2.extend_from_slice(y1);
        let h = t1 - t0;
        self.time[class] += h;
        if class == 1 {
            // The mechanism's workspace holds the evaluation at the step's end (the method's
            // last stage, its contact geometry refreshed by `step_accepted`).
            let model = self.mech.model;
            model.contact_modes(&mut self.mech.ws, &mut self.modes);
            // The smallest h_s; among modes stable at any step, the fastest.
            let (h_s, speed) = self
                .modes
                .iter()
                .flatten()
                .map(|&l| (stable_step(self.stability, l), l.0.hypot(l.1)))
                .min_by(|a, b| a.0.total_cmp(&b.0).then(b.1.total_cmp(&a.1)))
                .unwrap_or((f64::INFINITY, 0.0));
            self.fastest.push(speed);
            let ratio = h / h_s;
            self.steps_at_h_s += ratio;
            self.bins[BINS.iter().position(|&b| ratio < b).unwrap_or(BINS.len())] += 1;
        }
    }
}

/// The mechanism's own system, with the census taken at every accepted step. Every method the
/// integrators call on a mechanism is forwarded, so the run takes the mechanism's steps.
impl OdeSystem for Census<'_> {
    fn dim(&self) -> usize {
        self.mech.dim()
    }
    fn error_dim(&self) -> usize {
        self.mech.error_dim()
    }
    fn rhs(&mut self, t: f64, y: &[f64], dydt: &mut [f64]) {
        self.evaluations += 1;
        if t == self.last.1 && y == &self.last.2[..] {
            self.class_evaluations[self.last.0] += 1;
            self.counted += 1;
        }
        self.mech.rhs(t, y, dydt)
    }
    fn step_accepted(&mut self, t0: f64, y0: &[f64], t1: f64, y1: &[f64]) -> bool {
        let changed = self.mech.step_accepted(t0, y0, t1, y1);
        self.count((t0, y0), (t1, y1));
        changed
    }
    fn check_step(&mut self, t: f64, y: &[f64]) -> Option<String> {
        self.mech.check_step(t, y)
    }
    fn explain_non_finite(&mut self, t: f64, y: &[f64], component: usize) -> String {
        self.mech.explain_non_finite(t, y, component)
    }
    fn events(&mut self) -> Option<&mut dyn Events> {
        self.mech.events()
    }
    fn stiffness(&mut self) -> Option<&mut dyn Stiffness> {
        Some(self)
    }
}

/// The mechanism's stiff directions, with the contact Jacobian counted as an evaluation.
impl Stiffness for Census<'_> {
    fn directions(
        &mut self,
        t: f64,
        y: &[f64],
        h: f64,
        dirs: &mut Vec<f64>,
        pattern: &mut Vec<u32>,
    ) {
        if let Some(s) = self.mech.stiffness() {
            s.directions(t, y, h, dirs, pattern)
        }
    }
    fn jacobian(&mut self, t: f64, y: &[f64], basis: &[f64], image: &mut [f64]) -> bool {
        self.evaluations += 1;
        self.mech
            .stiffness()
            .is_some_and(|s| s.jacobian(t, y, basis, image))
    }
}

/// The largest step h at which `stability` (R at h lambda, as real and imaginary part) keeps
/// |R| <= 1 on the mode `lambda` (1/s), by bisection from a step where it does not; infinite
/// when it is stable up to |h lambda| = 1e6 (a linearly implicit method on a damped mode).
fn stable_step(stability: fn(f64, f64) -> (f64, f64), lambda: (f64, f64)) -> f64 {
    let stable = |h: f64| {
        let (re, im) = stability(h * lambda.0, h * lambda.1);
        re.hypot(im) <= 1.0
    };
    let speed = lambda.0.hypot(lambda.1);
    if speed == 0.0 {
        return f64::INFINITY;
    }
    let mut hi = 1.0 / speed;
    while stable(hi) {
        if hi * speed > 1e6 {
            return f64::INFINITY;
        }
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

fn census() -> Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let usage =
        "usage: step_census SCENE INTEGRATOR RTOL [--events] [--ends] [--friction] [--until T]";
    let [scene, integrator, rtol, rest @ ..] = &args[..] else {
        return Err(Error::Usage { usage });
    };
    let rtol: f64 = rtol.parse().map_err(|_| Error::NotANumber {
        argument: "RTOL".into(),
        value: rtol.clone(),
    })?;
    if !(rtol.is_finite() && rtol > 0.0) {
        return Err(Error::NotPositive {
            argument: "RTOL".into(),
            value: rtol,
        });
    }
    let (mut events, mut ends, mut friction, mut until) = (false, false, false, None);
    let mut rest = rest.iter();
    while let Some(a) = rest.next() {
        match a.as_str() {
            "--events" => events = true,
            "--ends" => ends = true,
            "--friction" => friction = true,
            "--until" => {
                let t = rest.next().ok_or(Error::Usage { usage })?;
                until = Some(t.parse::<f64>().map_err(|_| Error::NotANumber {
                    argument: "--until".into(),
                    value: t.clone(),
                })?);
            }
            _ => return Err(Error::Usage { usage }),
        }
    }
    let file = SceneSpec::load(Path::new(scene))?;
    let (mut model, mut state) = Model::compile(&file)?;
    model.assemble(&mut state)?;
    let method = Method::of_family(integrator, rtol, rtol * 1e-3)
        .filter(|m| m.fixed_step().is_none())
        .ok_or_else(|| Error::NotAdaptive {
            family: integrator.clone(),
        })?;
    model.settings.method = method;
    model.settings.onset_events = events;
    model.settings.end_events = ends;
    model.settings.friction_events = friction;
    let t_end = until.unwrap_or(model.settings.end_time);

    let model = &model;
    let mut census = Census {
        mech: Mechanism::new(model),
        ws: Workspace::new(model),
        rates: Vec::new(),
        modes: Vec::new(),
        stability: method.integrator().stability,
        evaluations: 0,
        counted: 0,
        last: (0, f64::NAN, Vec::new()),
        steps: [0; 4],
        class_evaluations: [0; 4],
        time: [0.0; 4],
        bins: [0; BINS.len() + 1],
        fastest: Vec::new(),
        steps_at_h_s: 0.0,
        fewest: u64::MAX,
    };
    let stats = ode::integrate(
        &mut census,
        method,
        state.t,
        &mut state.y,
        t_end,
        &[],
        |_, _, _| Flow::Continue,
    )?;
    // Evaluations after the last accepted step (rejected attempts at the end) go to its class.
    census.class_evaluations[census.last.0] += census.evaluations - census.counted;
    let Census {
        steps,
        class_evaluations: evaluations,
        time,
        bins,
        evaluations: all_evaluations,
        mut fastest,
        steps_at_h_s,
        fewest,
        ..
    } = census;

    println!(
        "{scene}: {} from {} s to {t_end} s{}: {} steps ({} rejected), {} right-hand sides",
        method.describe(),
        model.settings.start_time,
        events_named(events, ends, friction),
        stats.accepted,
        stats.rejected,
        stats.rhs_evals
    );
    println!(
        "| steps | count | right-hand sides | share | simulated time (s) | share | mean step (s) |"
    );
    println!("|---|---|---|---|---|---|---|");
    let (all_evaluations, span) = (all_evaluations as f64, t_end - model.settings.start_time);
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
    if steps_at_h_s > 0.0 && fewest < u64::MAX {
        // The closed time covered in steps of h_s each: this method's fewest right-hand sides
        // for it, if the contacts close for as long as in this run, held only by stability.
        println!(
            "stability floor of the closed time: {steps_at_h_s:.0} steps of h_s, {:.0} right-hand sides at {fewest} a step",
            steps_at_h_s * fewest as f64
        );
    }
    fastest.sort_by(f64::total_cmp);
    if !fastest.is_empty() {
        let at = |q: f64| fastest[((fastest.len() - 1) as f64 * q).round() as usize];
        println!(
            "|lambda| of the mode that sets h_s in closed steps (1/s): 10 % {:.3e}, median {:.3e}, 90 % {:.3e}",
            at(0.1),
            at(0.5),
            at(0.9)
        );
    }
    Ok(())
}

/// The events a census runs with, as its heading names them ("" for none).
fn events_named(onsets: bool, ends: bool, friction: bool) -> String {
    let named: Vec<&str> = [
        (onsets, "onset"),
        (ends, "end"),
        (friction, "friction-kink"),
    ]
    .into_iter()
    .filter_map(|(on, name)| on.then_some(name))
    .collect();
    if named.is_empty() {
        String::new()
    } else {
        format!(", {} events", named.join(", "))
    }
}
