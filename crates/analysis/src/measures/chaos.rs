//! Is it chaos? The chaos measures of an analysis study: the Lyapunov spectrum
//! ([`crate::measures::lyapunov`]) and the 0-1 test ([`crate::measures::zero_one`]) of a run or of every sweep value,
//! and a classification (their HDF5 layout: [`crate::storage::chaos`]).
//!
//! A study asks for them with a `[lyapunov]` table (its fields: [`LyapunovSpec`]) and a
//! `[zero_one]` table (`observable`, the name of one of the study's observables, and `section`,
//! `"strobe"` by default or a hyperplane section's name). The Lyapunov run starts from the
//! analysis run's final hybrid state, so the analysis's periods serve as its transient.
//!
//! **Classification** (thresholds chosen here, documented in book/src/explanation/lyapunov.md). The strobe series of
//! the first observable (of the 0-1 test's observable when it runs) is first searched for a
//! period p <= 64: over its last half, `|x_(j+p) - x_j| <= 1e-6` of its spread plus 1e-9 of its
//! size.
//! - *chaotic*: `lambda_1 > 3 s` and `lambda_1 > 1e-3 / T` (s its standard error, T the period),
//!   K > 0.8 when the 0-1 test ran, and no period found;
//! - *periodic*: a period found and `lambda_1` not chaotic by the rule above; or
//!   `lambda_1 < -3 s` and `lambda_1 < -1e-3 / T` (every direction contracts: for a forced flow
//!   the time direction is not a state, so a periodic orbit has no zero exponent) with K < 0.2
//!   when the test ran; or, with no Lyapunov run, K < 0.2;
//! - *quasi-periodic*: no period found, `|lambda_1| <= 3 s + 1e-3 / T` and K < 0.2 (the 0-1 test
//!   must have run);
//! - *undetermined* otherwise (the measures disagree, or the run is too short to tell), and
//!   whenever lambda_1's batch estimates changed while it averaged
//!   ([`crate::measures::lyapunov::drift`]: a transient that settles, the mean of two motions)
//!   and no period was found: say so rather than guess.

use crate::measures::indicator::{Asked, Reading, Verdict};
use crate::measures::lyapunov::{LyapunovSpec, Spectrum};

/// What the measures say.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Class {
    Undetermined = 0,
    Periodic = 1,
    QuasiPeriodic = 2,
    Chaotic = 3,
}

/// The class names in the order of their codes (the HDF5 `class` attribute `names`).
pub const CLASS_NAMES: [&str; 4] = ["undetermined", "periodic", "quasi-periodic", "chaotic"];

impl Class {
    pub fn name(self) -> &'static str {
        CLASS_NAMES[self as usize]
    }
}

/// The chaos measures of one run.
#[derive(Debug, Clone)]
pub struct Chaos {
    pub spectrum: Option<Spectrum>,
    /// What each indicator the study asked for read ([`crate::measures::registry`]).
    pub readings: Vec<Reading>,
    pub class: Class,
}

/// The least period p <= 64 of a strobe series over its last half (the rule of the module
/// overview), None when it has none (or fewer than 2 p samples).
pub fn strobe_period(series: &[f64]) -> Option<usize> {
    let tail = &series[series.len() / 2..];
    if tail.is_empty() || tail.iter().any(|x| !x.is_finite()) {
        return None;
    }
    let (lo, hi) = tail
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), x| {
            (a.min(*x), b.max(*x))
        });
    let size = lo.abs().max(hi.abs());
    let tol = 1e-6 * (hi - lo) + 1e-9 * size;
    (1..=64)
        .filter(|p| tail.len() >= 2 * p)
        .find(|&p| tail.windows(p + 1).all(|w| (w[p] - w[0]).abs() <= tol))
}

/// Classifies by the rules of the module overview; `period` is the strobe series' period found
/// by [`strobe_period`]; the indicators' verdicts count as the 0-1 test's K does there (chaotic:
/// K > 0.8, regular: K < 0.2), every indicator that ran having to agree.
pub fn classify(spectrum: Option<&Spectrum>, readings: &[Reading], period: Option<usize>) -> Class {
    let all = |ok: &dyn Fn(Verdict) -> bool| readings.iter().all(|r| ok(r.verdict));
    let ran = !readings.is_empty();
    // An estimate that changed while it averaged is the mean of two motions: no class, unless
    // the strobe series repeats (the motion had settled before: a change of the batch estimates
    // is then that of the tangent vectors on the orbit, as the rotation of a complex pair of
    // multipliers gives).
    if period.is_none() && spectrum.is_some_and(|s| s.drift.is_some()) {
        return Class::Undetermined;
    }
    if let Some(s) = spectrum {
        let (l, e) = (s.exponents[0], s.stderr[0]);
        let e = if e.is_finite() { e } else { f64::INFINITY };
        if period.is_some() && !(l > 3.0 * e && l > 1e-3 / s.period) {
            return Class::Periodic;
        }
    } else if period.is_some() {
        return Class::Periodic;
    }
    match spectrum {
        Some(s) => {
            let (l, e) = (s.exponents[0], s.stderr[0]);
            let e = if e.is_finite() { e } else { f64::INFINITY };
            let floor = 1e-3 / s.period;
            if l > 3.0 * e && l > floor {
                if all(&|v| v == Verdict::Chaotic) && period.is_none() {
                    Class::Chaotic
                } else {
                    Class::Undetermined
                }
            } else if l < -3.0 * e && l < -floor {
                if all(&|v| matches!(v, Verdict::Regular | Verdict::Constant)) {
                    Class::Periodic
                } else {
                    Class::Undetermined
                }
            } else if l.abs() <= 3.0 * e + floor && ran && all(&|v| v == Verdict::Regular) {
                Class::QuasiPeriodic
            } else {
                Class::Undetermined
            }
        }
        None => {
            if ran && all(&|v| matches!(v, Verdict::Regular | Verdict::Constant)) {
                Class::Periodic
            } else if ran && all(&|v| v == Verdict::Chaotic) {
                Class::Chaotic
            } else {
                Class::Undetermined
            }
        }
    }
}

/// The settings of both measures, as a study gives them.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ChaosSpec {
    pub lyapunov: Option<LyapunovSpec>,
    /// The indicators asked for, in the order of [`crate::measures::registry::INDICATORS`].
    pub indicators: Vec<Asked>,
}

impl ChaosSpec {
    pub fn any(&self) -> bool {
        self.lyapunov.is_some() || !self.indicators.is_empty()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use jointplay_solver::state::HybridState;

    fn spectrum(l: f64, e: f64) -> Spectrum {
        Spectrum {
            exponents: vec![l],
            stderr: vec![e],
            period: 1.0,
            time: 1.0,
            phase_dim: 2,
            history_t: vec![],
            history: vec![],
            two_trajectory: None,
            mean_divergence: None,
            jvp: "analytic",
            rhs_evals: 0,
            stopped_early: false,
            events: 0,
            end: HybridState::new(0.0, vec![]),
            drift: None,
        }
    }
    /// The 0-1 test's reading of K = `v` (the thresholds of [`crate::measures::zero_one`]).
    fn k(v: f64) -> Reading {
        let verdict = if v > 0.8 {
            Verdict::Chaotic
        } else if v < 0.2 {
            Verdict::Regular
        } else {
            Verdict::Unsure
        };
        Reading {
            key: "zero_one",
            value: v,
            verdict,
            attributes: vec![],
        }
    }

    #[test]
    fn the_classes_follow_the_documented_thresholds() {
        let c = |l: f64, e: f64, z: &[Reading]| classify(Some(&spectrum(l, e)), z, None);
        assert_eq!(c(0.15, 0.002, &[k(0.98)]), Class::Chaotic);
        assert_eq!(c(0.15, 0.002, &[k(0.1)]), Class::Undetermined);
        assert_eq!(c(-0.3, 0.01, &[k(0.01)]), Class::Periodic);
        assert_eq!(c(1e-4, 0.01, &[k(0.05)]), Class::QuasiPeriodic);
        assert_eq!(c(1e-4, 0.01, &[]), Class::Undetermined);
        // A strobe series that repeats makes it periodic unless lambda_1 is clearly positive.
        let p = classify(Some(&spectrum(1e-4, 0.01)), &[k(0.05)], Some(2));
        assert_eq!(p, Class::Periodic);
        let series: Vec<f64> = (0..100).map(|j| [0.3, -0.7, 0.1][j % 3]).collect();
        assert_eq!(strobe_period(&series), Some(3));
        let drifting: Vec<f64> = (0..100).map(|j| (j as f64).sin()).collect();
        assert_eq!(strobe_period(&drifting), None);
        let constant = Reading {
            verdict: Verdict::Constant,
            value: f64::NAN,
            ..k(0.5)
        };
        assert_eq!(classify(None, &[constant], None), Class::Periodic);
        // An estimate that changed while it averaged has no class, whatever its mean says.
        let mut moved = spectrum(0.15, 0.002);
        moved.drift = Some(crate::measures::lyapunov::Drift {
            time: 100.0,
            before: 0.3,
            after: -0.05,
            statistic: 4.0,
            critical: 2.0,
        });
        assert_eq!(
            classify(Some(&moved), &[k(0.98)], None),
            Class::Undetermined
        );
    }

    /// Maps with known dynamics, iterated here: a series of `n` iterates after 1000 of
    /// transient, each map's largest exponent (per iterate) with its batch-means standard error
    /// (20 batches), and the 0-1 test's reading of the series.
    fn map_case(
        n: usize,
        mut step: impl FnMut() -> (f64, f64),
    ) -> (Vec<f64>, Spectrum, Vec<Reading>) {
        use crate::measures::indicator::Indicator;
        for _ in 0..1000 {
            step();
        }
        let (series, logs): (Vec<f64>, Vec<f64>) = (0..n).map(|_| step()).unzip();
        let batch = n / 20;
        let means: Vec<f64> = logs
            .chunks_exact(batch)
            .map(|c| c.iter().sum::<f64>() / batch as f64)
            .collect();
        let l = means.iter().sum::<f64>() / means.len() as f64;
        let var = means.iter().map(|m| (m - l).powi(2)).sum::<f64>() / (means.len() - 1) as f64;
        let e = (var / means.len() as f64).sqrt();
        let reading = crate::measures::zero_one::ZeroOneTest
            .compute(&series)
            .unwrap();
        (series, spectrum(l, e), vec![reading])
    }

    /// The logistic map x -> r x (1 - x) with its exponent ln |r (1 - 2 x)| per iterate.
    fn logistic(r: f64, n: usize) -> (Vec<f64>, Spectrum, Vec<Reading>) {
        let mut x = 0.3;
        map_case(n, move || {
            let d = (r * (1.0 - 2.0 * x)).abs().ln();
            x = r * x * (1.0 - x);
            (x, d)
        })
    }

    /// The classifier on maps whose dynamics are known: the logistic map's period-doubling
    /// cascade (periods 2, 4 and 8 at r = 3.2, 3.5, 3.55) and its period-3 window (r = 3.83,
    /// inside 1 + sqrt(8) = 3.8284 .. 3.8415), fully developed chaos at r = 4 (lambda_1 = ln 2
    /// exactly: the map is conjugate to the tent map), the Henon map at a = 1.4, b = 0.3
    /// (lambda_1 = 0.419, Sprott, *Chaos and Time-Series Analysis*, 2003, table A.1), and a
    /// rotation by the golden mean (quasi-periodic, lambda_1 = 0).
    #[test]
    fn the_classifier_knows_the_windows_of_the_logistic_and_henon_maps() {
        for (r, p) in [(3.2, 2), (3.5, 4), (3.55, 8), (3.83, 3)] {
            let (series, spec, readings) = logistic(r, 4000);
            let period = strobe_period(&series);
            assert_eq!(period, Some(p), "logistic r = {r}");
            assert!(spec.exponents[0] < 0.0, "r = {r}: {}", spec.exponents[0]);
            assert_eq!(classify(Some(&spec), &readings, period), Class::Periodic);
        }
        // Chaos: no period, lambda_1 = ln 2 within its standard error (4 of them: the batch
        // means of a chaotic series scatter), K near 1.
        let (series, spec, readings) = logistic(4.0, 10000);
        let (l, e) = (spec.exponents[0], spec.stderr[0]);
        assert!(
            (l - std::f64::consts::LN_2).abs() < 4.0 * e && e < 0.01,
            "{l} +- {e}"
        );
        let period = strobe_period(&series);
        assert_eq!(period, None);
        assert_eq!(classify(Some(&spec), &readings, period), Class::Chaotic);

        // Henon: the exponent from the tangent map, re-orthonormalised each iterate (in 2D the
        // growth of one vector is lambda_1).
        let (mut x, mut y, mut v) = (0.1, 0.1, (1.0f64, 0.0f64));
        let (series, spec, readings) = map_case(10000, move || {
            let w = (-2.8 * x * v.0 + v.1, 0.3 * v.0);
            let norm = (w.0 * w.0 + w.1 * w.1).sqrt();
            v = (w.0 / norm, w.1 / norm);
            (x, y) = (1.0 - 1.4 * x * x + y, 0.3 * x);
            (x, norm.ln())
        });
        let (l, e) = (spec.exponents[0], spec.stderr[0]);
        assert!((l - 0.419).abs() < 0.01 && e < 0.01, "Henon {l} +- {e}");
        let period = strobe_period(&series);
        assert_eq!(period, None);
        assert_eq!(classify(Some(&spec), &readings, period), Class::Chaotic);

        // A rotation by the golden mean, observed through sin(2 pi x): never repeats, every
        // exponent zero, K near 0.
        let omega = (5f64.sqrt() - 1.0) / 2.0;
        let mut x = 0.0f64;
        let (series, spec, readings) = map_case(4000, move || {
            x = (x + omega).fract();
            ((std::f64::consts::TAU * x).sin(), 0.0)
        });
        let period = strobe_period(&series);
        assert_eq!(period, None);
        assert_eq!(
            classify(Some(&spec), &readings, period),
            Class::QuasiPeriodic,
            "{:?}",
            readings[0]
        );
    }
}
