//! The `[continuation]` table of an analysis study (format in book/src/reference/analysis.md),
//! checked field by field, and the numerical [`Settings`] it gives the algorithm.

use crate::measures::periodic::Newton;

/// What a continuation needs besides the flow.
#[derive(Debug, Clone)]
pub struct Settings {
    /// Start and end of the parameter range.
    pub from: f64,
    pub to: f64,
    /// First, smallest and largest step (parameter units, see the module overview).
    pub step: f64,
    pub min_step: f64,
    pub max_step: f64,
    /// Points per branch at most.
    pub max_points: usize,
    /// Drive periods per orbit of the first branch.
    pub k: usize,
    pub newton: Newton,
    /// Bracket (parameter units) special points are located to.
    pub locate: f64,
    /// Follow the period-2k branch from every period doubling.
    pub switch_period_doubling: bool,
    /// Branches at most (the first one and those switched to).
    pub max_branches: usize,
    /// Grazing: the index of the contact observable and the level at which contact begins (the
    /// gap is `level - max` of the observable over the orbit).
    pub grazing: Option<(usize, f64)>,
    /// Samples per drive period for the gap.
    pub samples: usize,
}

/// The `[continuation]` table of an analysis study (format in book/src/reference/analysis.md, "Periodic orbits and
/// continuation").
#[derive(Debug, Clone, PartialEq, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ContinuationSpec {
    /// A scene path or a system parameter, as `sweep.parameter`.
    pub parameter: String,
    /// Further scene paths set to the same value.
    #[serde(default)]
    pub also: Vec<String>,
    /// Unit of the parameter, for labels.
    #[serde(default)]
    pub unit: String,
    /// The parameter's start value (the orbit the run settles on there) and end value.
    pub from: f64,
    pub to: f64,
    /// First step (parameter units; see [`crate::study::continuation`]); smallest and largest step
    /// (default a ten-thousandth of it and ten times it).
    pub step: f64,
    #[serde(default)]
    pub min_step: Option<f64>,
    #[serde(default)]
    pub max_step: Option<f64>,
    /// Points per branch at most.
    #[serde(default = "default_points")]
    pub max_points: usize,
    /// Drive periods per orbit of the first branch (1: period-1 orbits).
    #[serde(default = "one")]
    pub orbit_periods: usize,
    /// Newton tolerance: the largest component of `P^k(y) - y` (SI units of the state).
    #[serde(default = "default_tolerance")]
    pub tolerance: f64,
    #[serde(default = "default_iterations")]
    pub max_iterations: usize,
    /// Bracket special points are located to (parameter units; default 1e-6 of the range).
    #[serde(default)]
    pub locate: Option<f64>,
    /// Follow the period-2k branch from every period doubling.
    #[serde(default = "yes")]
    pub switch_period_doubling: bool,
    /// Branches at most, the first one included.
    #[serde(default = "default_branches")]
    pub max_branches: usize,
    /// Grazing: the contact observable and the level where contact begins.
    #[serde(default)]
    pub grazing: Option<GrazingSpec>,
    /// Samples per drive period for the gap and the observables along the orbit.
    #[serde(default = "default_samples")]
    pub samples: usize,
    /// Periods run at `from` before shooting (default `analysis.transient`, or none from a
    /// `start` state).
    #[serde(default)]
    pub transient: Option<usize>,
    /// The state to shoot from instead of the study's start after its transient.
    #[serde(default)]
    pub start: Option<StartSpec>,
}

/// `[continuation] start`: a state from a file of the program. Without `branch`, the file's
/// final state (a run file of `jointplay run SCENE`, or an analysis file of a single run); with
/// it, a point of a branch of its `/continuation` (`point` counts from 0, negative from the end;
/// default the last), whose parameter must be `from`.
#[derive(Debug, Clone, PartialEq, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StartSpec {
    /// The HDF5 file, relative to the study file.
    pub file: String,
    #[serde(default)]
    pub branch: Option<usize>,
    #[serde(default)]
    pub point: Option<i64>,
}

/// Largest constraint residuals a `start` state may have (position m, velocity m/s, Euler norm):
/// a state written by a run keeps them near its integration tolerance (Baumgarte stabilisation),
/// so more than this is a state of another scene or an edited one, which the assembly would move
/// by an amount nobody asked for.
pub(crate) const START_OFF_MANIFOLD: [f64; 3] = [1e-6, 1e-6, 1e-6];

/// The contact observable of grazing detection: contact begins when its largest value along the
/// orbit reaches `level` (the gap is `level - max`).
#[derive(Debug, Clone, PartialEq, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GrazingSpec {
    pub observable: String,
    #[serde(default)]
    pub level: f64,
}

fn one() -> usize {
    1
}

fn yes() -> bool {
    true
}

fn default_points() -> usize {
    200
}

fn default_tolerance() -> f64 {
    1e-8
}

fn default_iterations() -> usize {
    10
}

fn default_branches() -> usize {
    4
}

fn default_samples() -> usize {
    100
}

impl ContinuationSpec {
    /// Checks the numbers; errors name the field of the `[continuation]` table.
    pub fn check(&self) -> std::result::Result<(), (String, String)> {
        let bad = |f: &str, m: &str| Err((format!("continuation.{f}"), m.to_string()));
        for (f, v) in [("from", self.from), ("to", self.to)] {
            if !v.is_finite() {
                return bad(f, "must be finite");
            }
        }
        if self.from == self.to {
            return bad("to", "must differ from continuation.from");
        }
        let range = (self.to - self.from).abs();
        for (f, v) in [
            ("step", Some(self.step)),
            ("min_step", self.min_step),
            ("max_step", self.max_step),
            ("locate", self.locate),
            ("tolerance", Some(self.tolerance)),
        ] {
            if let Some(v) = v
                && !(v.is_finite() && v > 0.0)
            {
                return bad(f, "must be positive and finite");
            }
        }
        if self.step > range {
            return bad(
                "step",
                "is larger than the range from continuation.from to .to",
            );
        }
        if self.min_step() > self.step || self.max_step() < self.step {
            return bad(
                "min_step",
                "min_step <= step <= max_step must hold (defaults: step / 1e4 and 10 step)",
            );
        }
        if self.max_points < 2 {
            return bad("max_points", "must be at least 2");
        }
        if self.orbit_periods == 0 {
            return bad("orbit_periods", "must be at least 1");
        }
        if self.max_iterations == 0 {
            return bad("max_iterations", "must be at least 1");
        }
        if self.max_branches == 0 {
            return bad("max_branches", "must be at least 1");
        }
        if self.samples < 8 {
            return bad("samples", "must be at least 8 per period");
        }
        if let Some(g) = &self.grazing
            && !g.level.is_finite()
        {
            return bad("grazing.level", "must be finite");
        }
        Ok(())
    }
    pub fn min_step(&self) -> f64 {
        self.min_step.unwrap_or(self.step * 1e-4)
    }
    pub fn max_step(&self) -> f64 {
        self.max_step.unwrap_or(self.step * 10.0)
    }
    /// The settings of [`continuation`](crate::study::continuation::follow::continuation), with the grazing observable's index.
    pub fn settings(&self, grazing: Option<usize>) -> Settings {
        Settings {
            from: self.from,
            to: self.to,
            step: self.step,
            min_step: self.min_step(),
            max_step: self.max_step(),
            max_points: self.max_points,
            k: self.orbit_periods,
            newton: Newton {
                tolerance: self.tolerance,
                max_iterations: self.max_iterations,
            },
            locate: self.locate.unwrap_or(1e-6 * (self.to - self.from).abs()),
            switch_period_doubling: self.switch_period_doubling,
            max_branches: self.max_branches,
            grazing: grazing.zip(self.grazing.as_ref().map(|g| g.level)),
            samples: self.samples,
        }
    }
}
