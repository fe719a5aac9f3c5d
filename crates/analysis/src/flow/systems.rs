//! Built-in reference systems: plain ODEs with well-known nonlinear behaviour, usable from a study
//! file in place of a mechanism scene, so that the analysis pipeline (sections, sweeps, figures)
//! can be checked against published results.
//!
//! * `duffing`: the forced Duffing oscillator
//!   `x'' + delta x' + alpha x + beta x^3 = gamma cos(omega t)`, state `(x, v)`
//!   (Guckenheimer & Holmes, *Nonlinear Oscillations, Dynamical Systems, and Bifurcations of
//!   Vector Fields*, Springer 1983, section 2.2). Its stroboscopic map contracts areas by
//!   `exp(-delta T)`, `T = 2 pi / omega`.
//! * `pendulum`: the forced damped pendulum
//!   `theta'' + damping theta' + omega0^2 sin(theta) = forcing cos(omega t)`, state
//!   `(theta, theta_dot)` (Baker & Gollub, *Chaotic Dynamics: An Introduction*, 2nd ed.,
//!   Cambridge 1996, chapter 3). The observable `theta_wrapped` is the angle in `(-pi, pi]`.
//! * `lorenz`: `x' = sigma (y - x)`, `y' = x (rho - z) - y`, `z' = x y - beta z`
//!   (Lorenz, J. Atmos. Sci. 20:130-141, 1963); autonomous, so it has no drive period and its
//!   sections are hyperplanes.
//!
//! * `impact`: the Newton impact oscillator
//!   `x'' + damping x' + stiffness x = forcing cos(omega t)` with a rigid stop at `x = stop`: when
//!   the mass reaches the stop the velocity is reset, `v -> -restitution v` (Newton's law of
//!   restitution), at the impact time located on the integrator's dense output; state `(x, v)`
//!   (the `impact` demo of COCO: Dankowicz & Schilder, *Recipes for Continuation*, SIAM 2013; its
//!   parameters are the defaults here: stiffness 1, damping 0.1, omega 1, stop 1,
//!   restitution 0.8). It grazes the stop at `forcing = stop sqrt((k - omega^2)^2 + (c omega)^2)`.
//!   Each impact contracts phase-space areas by `restitution^2` (the determinant of its saltation
//!   matrix), so its Lyapunov exponents sum to `-damping + 2 ln(restitution)` times the impacts
//!   per unit time. An impact slower than 1e-9 (the mass chattering toward rest on the stop, which
//!   this law does not model) stops the run with an error.
//!
//! * `van_der_pol`: the forced van der Pol oscillator
//!   `x'' - mu (1 - x^2) x' + x = forcing cos(omega t)`, state `(x, v)` (van der Pol & van der
//!   Mark, Nature 120, 1927; Guckenheimer & Holmes 1983, section 2.1). Its vector field has
//!   divergence `mu (1 - x^2)`, so the stroboscopic map multiplies areas by
//!   `exp(mu T (1 - <x^2>))` with `<x^2>` the mean of `x^2` over the period: where a complex pair
//!   of multipliers of a periodic orbit crosses the unit circle (a Neimark-Sacker bifurcation:
//!   the forced response gives way to a torus), `<x^2> = 1` along that orbit exactly. With the
//!   defaults (mu 0.4, omega 1.15) the period-1 response loses stability that way as the forcing
//!   falls from 0.6 to 0.55.
//!
//! All are dimensionless (the pendulum's angle in rad, its time in units of `1/omega0`).

use std::f64::consts::PI;

use jointplay_solver::ode::dopri5::DOPRI5;
use jointplay_solver::ode::{Events, Method, OdeSystem};
use jointplay_solver::scene::IntegratorKind;
use serde::Deserialize;
use toml::Table;

/// Which reference system, with its parameters.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Builtin {
    Duffing {
        delta: f64,
        alpha: f64,
        beta: f64,
        gamma: f64,
        omega: f64,
    },
    Pendulum {
        damping: f64,
        omega0: f64,
        forcing: f64,
        omega: f64,
    },
    Lorenz {
        sigma: f64,
        rho: f64,
        beta: f64,
    },
    Impact {
        damping: f64,
        stiffness: f64,
        forcing: f64,
        omega: f64,
        stop: f64,
        restitution: f64,
    },
    VanDerPol {
        mu: f64,
        forcing: f64,
        omega: f64,
    },
}

/// The approach velocity below which an impact is taken for chattering (see the module overview).
pub const CHATTER_VELOCITY: f64 = 1e-9;

/// Integrator settings of a reference system (the same keys as a scene's `[solver]`).
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OdeSolverSpec {
    #[serde(default = "dopri5")]
    pub integrator: IntegratorKind,
    #[serde(default)]
    pub step: Option<f64>,
    #[serde(default = "default_rtol")]
    pub rtol: f64,
    #[serde(default = "default_atol")]
    pub atol: f64,
    #[serde(default)]
    pub max_step: Option<f64>,
}

fn dopri5() -> IntegratorKind {
    IntegratorKind(&DOPRI5)
}
fn default_rtol() -> f64 {
    1e-10
}
fn default_atol() -> f64 {
    1e-12
}

impl Default for OdeSolverSpec {
    fn default() -> Self {
        OdeSolverSpec {
            integrator: dopri5(),
            step: None,
            rtol: default_rtol(),
            atol: default_atol(),
            max_step: None,
        }
    }
}

/// The `system` table of a study: `kind`, the parameters, `initial` and `solver`.
#[derive(Debug, Clone)]
pub struct SystemSpec {
    pub builtin: Builtin,
    pub initial: Vec<f64>,
    pub method: Method,
    /// Start time.
    pub start_time: f64,
}

fn param(t: &Table, key: &str, default: f64) -> Result<f64, (String, String)> {
    match t.get(key) {
        None => Ok(default),
        Some(v) => {
            let x = v
                .as_float()
                .or_else(|| v.as_integer().map(|i| i as f64))
                .ok_or_else(|| (key.to_string(), "must be a number".to_string()))?;
            if x.is_finite() {
                Ok(x)
            } else {
                Err((key.to_string(), "must be finite".to_string()))
            }
        }
    }
}

impl SystemSpec {
    /// Parses a `system` table; errors name the key (relative to the table) and the problem.
    pub fn parse(t: &Table) -> Result<SystemSpec, (String, String)> {
        let kind = t.get("kind").and_then(|v| v.as_str()).ok_or_else(|| {
            (
                "kind".to_string(),
                "missing: use \"duffing\", \"pendulum\", \"lorenz\", \"impact\" or \"van_der_pol\""
                    .to_string(),
            )
        })?;
        let (builtin, allowed, dim) = builtin_of(kind, t)?;
        check_keys(t, kind, allowed)?;
        check_parameters(&builtin)?;
        let initial = initial_state(t, kind, dim, &builtin)?;
        let method = solver_method(t)?;
        Ok(SystemSpec {
            builtin,
            initial,
            method,
            start_time: param(t, "start_time", 0.0)?,
        })
    }
}

type Field = (String, String);

/// The system of `kind` with its parameters from `t` (defaults where absent), the keys it
/// takes and the size of its state.
fn builtin_of(kind: &str, t: &Table) -> Result<(Builtin, &'static [&'static str], usize), Field> {
    let (builtin, allowed, dim): (Builtin, &'static [&'static str], usize) = match kind {
        "duffing" => (
            Builtin::Duffing {
                delta: param(t, "delta", 0.3)?,
                alpha: param(t, "alpha", -1.0)?,
                beta: param(t, "beta", 1.0)?,
                gamma: param(t, "gamma", 0.3)?,
                omega: param(t, "omega", 1.2)?,
            },
            &["delta", "alpha", "beta", "gamma", "omega"],
            2,
        ),
        "pendulum" => (
            Builtin::Pendulum {
                damping: param(t, "damping", 0.5)?,
                omega0: param(t, "omega0", 1.0)?,
                forcing: param(t, "forcing", 1.5)?,
                omega: param(t, "omega", 2.0 / 3.0)?,
            },
            &["damping", "omega0", "forcing", "omega"],
            2,
        ),
        "lorenz" => (
            Builtin::Lorenz {
                sigma: param(t, "sigma", 10.0)?,
                rho: param(t, "rho", 28.0)?,
                beta: param(t, "beta", 8.0 / 3.0)?,
            },
            &["sigma", "rho", "beta"],
            3,
        ),
        "impact" => (
            Builtin::Impact {
                damping: param(t, "damping", 0.1)?,
                stiffness: param(t, "stiffness", 1.0)?,
                forcing: param(t, "forcing", 0.2)?,
                omega: param(t, "omega", 1.0)?,
                stop: param(t, "stop", 1.0)?,
                restitution: param(t, "restitution", 0.8)?,
            },
            &[
                "damping",
                "stiffness",
                "forcing",
                "omega",
                "stop",
                "restitution",
            ],
            2,
        ),
        "van_der_pol" => (
            Builtin::VanDerPol {
                mu: param(t, "mu", 0.4)?,
                forcing: param(t, "forcing", 0.6)?,
                omega: param(t, "omega", 1.15)?,
            },
            &["mu", "forcing", "omega"],
            2,
        ),
        other => {
            return Err((
                "kind".into(),
                format!(
                    "unknown system '{other}': use \"duffing\", \"pendulum\", \"lorenz\", \"impact\" or \"van_der_pol\""
                ),
            ));
        }
    };
    Ok((builtin, allowed, dim))
}

/// Refuses a key that is neither a parameter of the system nor a key every system takes.
fn check_keys(t: &Table, kind: &str, allowed: &[&str]) -> Result<(), Field> {
    for key in t.keys() {
        if !allowed.contains(&key.as_str())
            && !["kind", "initial", "solver", "start_time"].contains(&key.as_str())
        {
            return Err((
                key.clone(),
                format!(
                    "unknown key for the {kind} system (its parameters: {})",
                    allowed.join(", ")
                ),
            ));
        }
    }
    Ok(())
}

/// Refuses parameters out of their range: a drive frequency that is not positive, a coefficient
/// of restitution outside [0, 1].
fn check_parameters(builtin: &Builtin) -> Result<(), Field> {
    if let Builtin::Duffing { omega, .. }
    | Builtin::Pendulum { omega, .. }
    | Builtin::Impact { omega, .. }
    | Builtin::VanDerPol { omega, .. } = *builtin
        && omega <= 0.0
    {
        return Err(("omega".into(), "must be positive".into()));
    }
    if let Builtin::Impact { restitution, .. } = *builtin
        && !(0.0..=1.0).contains(&restitution)
    {
        return Err((
            "restitution".into(),
            "must be between 0 and 1 (Newton's coefficient of restitution)".into(),
        ));
    }
    Ok(())
}

/// The initial state: `initial`, checked against the system's size (and the impact
/// oscillator's stop), or the system's default.
fn initial_state(t: &Table, kind: &str, dim: usize, builtin: &Builtin) -> Result<Vec<f64>, Field> {
    let initial = match t.get("initial") {
        None => vec![if dim == 3 { 1.0 } else { 0.0 }; dim],
        Some(v) => {
            let a = v
                .as_array()
                .ok_or(("initial".to_string(), "must be an array".to_string()))?;
            let x: Option<Vec<f64>> = a
                .iter()
                .map(|v| v.as_float().or_else(|| v.as_integer().map(|i| i as f64)))
                .collect();
            let x = x.ok_or(("initial".to_string(), "must hold numbers".to_string()))?;
            if x.len() != dim || x.iter().any(|v| !v.is_finite()) {
                return Err((
                    "initial".into(),
                    format!(
                        "must hold {dim} finite numbers ({})",
                        state_names(kind).join(", ")
                    ),
                ));
            }
            x
        }
    };
    if let Builtin::Impact { stop, .. } = *builtin
        && initial[0] > stop
    {
        return Err((
            "initial".into(),
            format!("x = {} starts beyond the stop at {stop}", initial[0]),
        ));
    }
    Ok(initial)
}

/// The integrator and its settings from the `solver` table: a fixed-step integrator needs its
/// step; the adaptive ones share their settings and checks.
fn solver_method(t: &Table) -> Result<Method, Field> {
    let solver: OdeSolverSpec = match t.get("solver") {
        None => OdeSolverSpec::default(),
        Some(v) => v
            .clone()
            .try_into()
            .map_err(|e: toml::de::Error| ("solver".to_string(), e.message().to_string()))?,
    };
    // A fixed-step integrator needs its step; the adaptive ones share their settings and
    // checks.
    let max_step = solver.max_step.unwrap_or(f64::INFINITY);
    let integrator = solver.integrator.0;
    let step = if integrator.adaptive.is_none() {
        let step = solver.step.ok_or((
            "solver.step".to_string(),
            format!("{} needs a step", integrator.name),
        ))?;
        if !(step > 0.0 && step.is_finite()) {
            return Err(("solver.step".into(), "must be positive".into()));
        }
        step
    } else {
        // An infinite tolerance was taken: every step accepted, whatever its error.
        for (field, v) in [("solver.rtol", solver.rtol), ("solver.atol", solver.atol)] {
            if !(v > 0.0 && v.is_finite()) {
                return Err((
                    field.to_string(),
                    format!("{v}: tolerances must be positive and finite"),
                ));
            }
        }
        if max_step <= 0.0 || max_step.is_nan() {
            return Err((
                "solver.max_step".to_string(),
                "must be positive".to_string(),
            ));
        }
        f64::NAN
    };
    Ok(solver
        .integrator
        .method(step, solver.rtol, solver.atol, max_step))
}

fn state_names(kind: &str) -> &'static [&'static str] {
    match kind {
        "duffing" => &["x", "v"],
        "pendulum" => &["theta", "theta_dot"],
        "impact" | "van_der_pol" => &["x", "v"],
        _ => &["x", "y", "z"],
    }
}

impl Builtin {
    /// Name of the system kind.
    pub fn kind(&self) -> &'static str {
        match self {
            Builtin::Duffing { .. } => "duffing",
            Builtin::Pendulum { .. } => "pendulum",
            Builtin::Lorenz { .. } => "lorenz",
            Builtin::Impact { .. } => "impact",
            Builtin::VanDerPol { .. } => "van_der_pol",
        }
    }

    /// Names of the state components.
    pub fn state_names(&self) -> &'static [&'static str] {
        state_names(self.kind())
    }

    /// The forcing period `2 pi / omega`, if forced.
    pub fn period(&self) -> Option<f64> {
        match self {
            Builtin::Duffing { omega, .. }
            | Builtin::Pendulum { omega, .. }
            | Builtin::Impact { omega, .. }
            | Builtin::VanDerPol { omega, .. } => Some(2.0 * PI / omega),
            Builtin::Lorenz { .. } => None,
        }
    }

    /// Observable `name` at state `y` with its unit, or `None` for an unknown name.
    pub fn observable(&self, name: &str) -> Option<(usize, &'static str)> {
        let unit = match self {
            Builtin::Pendulum { .. } => ["rad", "rad/s", "rad"],
            _ => ["1", "1", "1"],
        };
        if let Some(i) = self.state_names().iter().position(|s| *s == name) {
            return Some((i, unit[i]));
        }
        match (self, name) {
            (Builtin::Pendulum { .. }, "theta_wrapped") => Some((WRAPPED, "rad")),
            _ => None,
        }
    }

    /// Every observable name.
    pub fn observable_names(&self) -> Vec<&'static str> {
        let mut v = self.state_names().to_vec();
        if matches!(self, Builtin::Pendulum { .. }) {
            v.push("theta_wrapped");
        }
        v
    }
}

/// Index code of the wrapped pendulum angle among [`Builtin::observable`]'s results.
pub const WRAPPED: usize = usize::MAX;

/// Value of observable `index` (from [`Builtin::observable`]) at state `y`.
pub fn observe(index: usize, y: &[f64]) -> f64 {
    if index == WRAPPED {
        // Into (-pi, pi].
        let r = y[0].rem_euclid(2.0 * PI);
        if r > PI { r - 2.0 * PI } else { r }
    } else {
        y[index]
    }
}

impl OdeSystem for Builtin {
    fn dim(&self) -> usize {
        match self {
            Builtin::Lorenz { .. } => 3,
            _ => 2,
        }
    }

    fn rhs(&mut self, t: f64, y: &[f64], d: &mut [f64]) {
        match *self {
            Builtin::Duffing {
                delta,
                alpha,
                beta,
                gamma,
                omega,
            } => {
                d[0] = y[1];
                d[1] =
                    gamma * (omega * t).cos() - delta * y[1] - alpha * y[0] - beta * y[0].powi(3);
            }
            Builtin::Pendulum {
                damping,
                omega0,
                forcing,
                omega,
            } => {
                d[0] = y[1];
                d[1] = forcing * (omega * t).cos() - damping * y[1] - omega0 * omega0 * y[0].sin();
            }
            Builtin::Lorenz { sigma, rho, beta } => {
                d[0] = sigma * (y[1] - y[0]);
                d[1] = y[0] * (rho - y[2]) - y[1];
                d[2] = y[0] * y[1] - beta * y[2];
            }
            Builtin::Impact {
                damping,
                stiffness,
                forcing,
                omega,
                ..
            } => {
                d[0] = y[1];
                d[1] = forcing * (omega * t).cos() - damping * y[1] - stiffness * y[0];
            }
            Builtin::VanDerPol { mu, forcing, omega } => {
                d[0] = y[1];
                d[1] = forcing * (omega * t).cos() + mu * (1.0 - y[0] * y[0]) * y[1] - y[0];
            }
        }
    }

    fn events(&mut self) -> Option<&mut dyn Events> {
        if matches!(self, Builtin::Impact { .. }) {
            Some(self)
        } else {
            None
        }
    }
}

impl Events for Builtin {
    fn count(&mut self) -> usize {
        usize::from(matches!(self, Builtin::Impact { .. }))
    }

    fn values(&mut self, _t: f64, y: &[f64], g: &mut [f64]) {
        if let Builtin::Impact { stop, .. } = *self {
            g[0] = stop - y[0];
        }
    }

    fn apply(&mut self, _i: usize, t: f64, y: &mut [f64]) -> jointplay_solver::Result<()> {
        if let Builtin::Impact {
            stop, restitution, ..
        } = *self
        {
            if y[1] < CHATTER_VELOCITY {
                return Err(jointplay_solver::Error::Diverged {
                    time: t,
                    message: format!(
                        "impact at t = {t} with approach velocity {:e} (below {CHATTER_VELOCITY:e}): the mass chatters toward rest on the stop, which the Newton impact law does not model",
                        y[1]
                    ),
                });
            }
            // On the stop exactly (the located crossing is within round-off of it).
            y[0] = stop;
            y[1] *= -restitution;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use jointplay_solver::ode::INTEGRATORS;

    fn solver(text: &str) -> Result<Method, (String, String)> {
        let t: Table = format!("kind = \"duffing\"\nsolver = {{ {text} }}")
            .parse()
            .unwrap();
        SystemSpec::parse(&t).map(|s| s.method)
    }

    #[test]
    fn every_fixed_step_integrator_needs_its_step() {
        let fixed = INTEGRATORS.iter().filter(|i| i.adaptive.is_none());
        for name in fixed.map(|i| i.name) {
            let e = solver(&format!("integrator = \"{name}\"")).unwrap_err();
            assert_eq!(e, ("solver.step".into(), format!("{name} needs a step")));
            let m = solver(&format!("integrator = \"{name}\", step = 0.01")).unwrap();
            assert_eq!((m.family(), m.fixed_step()), (name, Some(0.01)));
        }
    }

    #[test]
    fn every_adaptive_integrator_is_selectable_with_its_tolerances() {
        let adaptive = INTEGRATORS.iter().filter(|i| i.adaptive.is_some());
        for family in adaptive.map(|i| i.name) {
            let m = solver(&format!(
                "integrator = \"{family}\", rtol = 1e-7, atol = 1e-9, max_step = 0.1"
            ))
            .unwrap();
            assert_eq!(m.family(), family);
            assert_eq!(
                Method::of_family(family, 1e-7, 1e-9).unwrap().setting(),
                1e-7
            );
            assert_eq!(
                m.describe(),
                format!("{family}, rtol 1e-7, atol 1e-9, max step 1e-1 s")
            );
            let e = solver(&format!("integrator = \"{family}\", rtol = 0.0")).unwrap_err();
            assert_eq!(e.0, "solver.rtol");
        }
    }
}
