//! What a continuation finds, as data: branches of periodic orbits ([`Point`]: the parameter,
//! the orbit, its multipliers and stability), their special points (folds, period doublings,
//! Neimark-Sacker points, grazings), and where an interrupted continuation stands. Written and
//! read back by [`crate::storage::continuation_file`]; found by `crate::study::continuation`.

use nalgebra::Complex;

use crate::measures::periodic::Orbit;

/// The kinds of special points.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    Fold = 1,
    PeriodDoubling = 2,
    NeimarkSacker = 3,
    Grazing = 4,
}

impl Kind {
    pub fn name(self) -> &'static str {
        match self {
            Kind::Fold => "fold",
            Kind::PeriodDoubling => "period-doubling",
            Kind::NeimarkSacker => "neimark-sacker",
            Kind::Grazing => "grazing",
        }
    }
    pub(crate) const ALL: [Kind; 4] = [
        Kind::Fold,
        Kind::PeriodDoubling,
        Kind::NeimarkSacker,
        Kind::Grazing,
    ];
}

/// One point of a branch.
#[derive(Debug, Clone)]
pub struct Point {
    pub parameter: f64,
    pub orbit: Orbit,
    /// Corrector iterations.
    pub iterations: usize,
    /// The observables at the orbit's `k` strobe points (`[k][observables]`).
    pub strobe: Vec<Vec<f64>>,
    /// The smallest gap along the orbit, when grazing is followed.
    pub gap: Option<f64>,
    /// Unit tangent: state part and scaled-parameter part.
    pub(crate) tangent_y: Vec<f64>,
    pub(crate) tangent_s: f64,
    pub(crate) s: f64,
}

/// A located special point.
#[derive(Debug, Clone)]
pub struct Special {
    pub kind: Kind,
    pub branch: usize,
    /// Index of the branch point before it.
    pub after: usize,
    pub parameter: f64,
    /// The arclength bracket reached (parameter units): the error bound of `parameter`.
    pub bracket: f64,
    /// The strobe point and the multipliers there (of the nearest corrected orbit).
    pub state: Vec<f64>,
    pub multipliers: Vec<Complex<f64>>,
    /// The observables at its strobe points.
    pub strobe: Vec<Vec<f64>>,
}

/// One branch.
#[derive(Debug, Clone)]
pub struct Branch {
    pub k: usize,
    /// Where it starts: "start" or the special point it was switched from.
    pub origin: String,
    pub points: Vec<Point>,
    /// Why it ended.
    pub end: String,
    /// It ended because a step failed (the last good point is kept).
    pub failed: bool,
}

/// A continuation's result.
#[derive(Debug, Clone, Default)]
pub struct Continuation {
    pub branches: Vec<Branch>,
    pub specials: Vec<Special>,
    /// Seconds of wall time.
    pub wall: f64,
    /// Units of the observables (set by [`run_study`](crate::study::continuation::run::run_study)).
    pub units: Vec<String>,
    /// Set when the continuation stopped before its end (a progress report returned `false`):
    /// what [`resume`](crate::study::continuation::follow::resume) needs to go on. The last branch is then the one being followed.
    pub unfinished: Option<Unfinished>,
}

/// Where an interrupted continuation stands: the step of the branch being followed (its last
/// branch, whose last point is the next step's anchor), the branches still to follow, and the
/// points done (for the progress fraction).
#[derive(Debug, Clone)]
pub struct Unfinished {
    pub step: f64,
    pub(crate) queue: Vec<Pending>,
    pub points_done: usize,
}

/// A branch waiting to be followed: its first point, its periods per orbit, where it comes from,
/// and the first step's tangent when it is not the point's own (branch switching).
#[derive(Debug, Clone)]
pub(crate) struct Pending {
    pub(crate) start: Point,
    pub(crate) k: usize,
    pub(crate) origin: String,
    pub(crate) switch: Option<(Vec<f64>, f64)>,
}
