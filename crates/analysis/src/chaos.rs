//! Is it chaos? The chaos measures of an analysis study: the Lyapunov spectrum
//! ([`crate::lyapunov`]) and the 0-1 test ([`crate::zero_one`]) of a run or of every sweep value,
//! a classification, and their HDF5 layout.
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
//! - *undetermined* otherwise (the measures disagree, or the run is too short to tell): say so
//!   rather than guess.

use serde::Deserialize;

use crate::h5::{create_nan, f64_attr, str_attr, u8_attr_set, u64_attr, write_table, write1};
use crate::lyapunov::{LyapunovSpec, Spectrum};
use crate::zero_one::ZeroOne;

/// The `[zero_one]` table.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ZeroOneSpec {
    /// Name of the observable the test runs on.
    pub observable: String,
    /// The section whose samples it uses: "strobe" (default) or a hyperplane's name.
    #[serde(default = "strobe")]
    pub section: String,
}

fn strobe() -> String {
    "strobe".into()
}

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
    pub zero_one: Option<ZeroOne>,
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
/// by [`strobe_period`].
pub fn classify(
    spectrum: Option<&Spectrum>,
    zero_one: Option<&ZeroOne>,
    period: Option<usize>,
) -> Class {
    let k = zero_one.and_then(|z| z.k);
    let constant = zero_one.is_some_and(|z| z.constant);
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
                if k.is_none_or(|k| k > 0.8) && !constant && period.is_none() {
                    Class::Chaotic
                } else {
                    Class::Undetermined
                }
            } else if l < -3.0 * e && l < -floor {
                if k.is_none_or(|k| k < 0.2) {
                    Class::Periodic
                } else {
                    Class::Undetermined
                }
            } else if l.abs() <= 3.0 * e + floor && k.is_some_and(|k| k < 0.2) && !constant {
                Class::QuasiPeriodic
            } else {
                Class::Undetermined
            }
        }
        None => {
            if constant || k.is_some_and(|k| k < 0.2) {
                Class::Periodic
            } else if k.is_some_and(|k| k > 0.8) {
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
    pub zero_one: Option<ZeroOneSpec>,
}

impl ChaosSpec {
    pub fn any(&self) -> bool {
        self.lyapunov.is_some() || self.zero_one.is_some()
    }
}

/// Writes the measures of a single run into the group `/chaos` (layout in book/src/reference/hdf5.md).
pub(crate) fn write_single(file: &hdf5::File, c: &Chaos) -> hdf5::Result<()> {
    let g = file.create_group("chaos")?;
    write_class(&g, c.class)?;
    if let Some(s) = &c.spectrum {
        let l = g.create_group("lyapunov")?;
        write1(
            &l,
            "exponents",
            &s.exponents,
            "1/s",
            "Lyapunov exponents of the flow, largest first",
        )?;
        write1(
            &l,
            "stderr",
            &s.stderr,
            "1/s",
            "batch-means standard errors of the exponents",
        )?;
        write1(
            &l,
            "map_exponents",
            &s.map_exponents(),
            "1",
            "exponents of the stroboscopic map, per iteration: the flow's times the period",
        )?;
        write1(
            &l,
            "history_time",
            &s.history_t,
            "s",
            "times of the re-orthonormalisations",
        )?;
        let flat: Vec<f64> = s.history.iter().flatten().copied().collect();
        write_table(
            &l,
            "history",
            &flat,
            s.exponents.len(),
            "1/s",
            "running estimate of every exponent at each re-orthonormalisation",
        )?;
        f64_attr(&l, "averaging_time", s.time)?;
        f64_attr(&l, "period", s.period)?;
        u64_attr(&l, "phase_dim", s.phase_dim as u64)?;
        u64_attr(&l, "rhs_evals", s.rhs_evals)?;
        str_attr(&l, "jvp", s.jvp)?;
        if let Some(d) = s.mean_divergence {
            f64_attr(&l, "mean_divergence", d)?;
        }
        if let Some((v, e, h)) = &s.two_trajectory {
            f64_attr(&l, "two_trajectory", *v)?;
            f64_attr(&l, "two_trajectory_stderr", *e)?;
            write1(
                &l,
                "two_trajectory_history",
                h,
                "1/s",
                "running two-trajectory estimate of lambda_1",
            )?;
        }
    }
    if let Some(z) = &c.zero_one {
        let g0 = g.create_group("zero_one")?;
        f64_attr(&g0, "k", z.k.unwrap_or(f64::NAN))?;
        u8_attr_set(&g0, "constant", u8::from(z.constant))?;
        u8_attr_set(&g0, "oversampled", u8::from(z.oversampled))?;
        u64_attr(&g0, "samples", z.samples as u64)?;
    }
    Ok(())
}

fn write_class(g: &hdf5::Group, class: Class) -> hdf5::Result<()> {
    str_attr(g, "class", class.name())
}

/// Creates the per-value datasets of a sweep's measures in `/sweep/chaos` (`n` values, `k`
/// exponents), NaN until a value is written.
pub(crate) fn create_rows(g: &hdf5::Group, n: usize, spec: &ChaosSpec) -> hdf5::Result<()> {
    let c = g.create_group("chaos")?;
    c.new_dataset::<u8>().shape(n).create("class")?;
    let names: Vec<String> = CLASS_NAMES.iter().map(|s| s.to_string()).collect();
    let ds = c.dataset("class")?;
    str_attr(&ds, "names", &names.join(","))?;
    str_attr(
        &ds,
        "description",
        "class code per value: 0 undetermined, 1 periodic, 2 quasi-periodic, 3 chaotic",
    )?;
    if let Some(l) = &spec.lyapunov {
        let k = l.exponents;
        create_nan(
            &c,
            "exponents",
            &[n, k],
            "1/s",
            "Lyapunov exponents per value, largest first",
        )?;
        create_nan(
            &c,
            "stderr",
            &[n, k],
            "1/s",
            "their batch-means standard errors",
        )?;
        create_nan(
            &c,
            "map_exponents",
            &[n, k],
            "1",
            "exponents of the stroboscopic map (per iteration)",
        )?;
        if l.two_trajectory {
            create_nan(
                &c,
                "two_trajectory",
                &[n, 2],
                "1/s",
                "two-trajectory lambda_1 and its standard error",
            )?;
        }
    }
    if spec.zero_one.is_some() {
        create_nan(
            &c,
            "k",
            &[n],
            "1",
            "0-1 test K per value (NaN: constant series)",
        )?;
    }
    Ok(())
}

/// The right-hand-side evaluations of a single run's Lyapunov run in the analysis file `path`
/// (None when it has none): the analysis run's own are the file's `rhs_evals`.
pub fn lyapunov_rhs_evals(path: &std::path::Path) -> crate::Result<Option<u64>> {
    let file = hdf5::File::open(path).map_err(crate::h5::h5err(path))?;
    Ok(file
        .group("chaos/lyapunov")
        .ok()
        .and_then(|l| crate::h5::read_attr::<u64>(&l, "rhs_evals").ok()))
}

/// Lines for the program's summary of the chaos measures in the analysis file `path` (none when
/// it has none).
pub fn summary(path: &std::path::Path) -> crate::Result<Vec<String>> {
    let e = crate::h5::h5err(path);
    let file = hdf5::File::open(path).map_err(&e)?;
    let mut out = Vec::new();
    let list = |v: &[f64], digits: usize| {
        v.iter()
            .map(|x| format!("{x:.digits$}"))
            .collect::<Vec<_>>()
            .join(", ")
    };
    if let Ok(c) = file.group("chaos") {
        if let Ok(l) = c.group("lyapunov") {
            let ex = l
                .dataset("exponents")
                .and_then(|d| d.read_raw::<f64>())
                .map_err(&e)?;
            let se = l
                .dataset("stderr")
                .and_then(|d| d.read_raw::<f64>())
                .map_err(&e)?;
            let mu = l
                .dataset("map_exponents")
                .and_then(|d| d.read_raw::<f64>())
                .map_err(&e)?;
            out.push(format!(
                "lyapunov     {} 1/s (+- {})",
                list(&ex, 4),
                list(&se, 4)
            ));
            out.push(format!("map          {} per period", list(&mu, 4)));
            // How long the estimate averaged: the whole `periods`, or less when `until_stderr`
            // stopped it.
            if let (Ok(t), Ok(p)) = (
                crate::h5::read_attr::<f64>(&l, "averaging_time"),
                crate::h5::read_attr::<f64>(&l, "period"),
            ) {
                out.push(format!("averaged     {t:.6} s ({:.1} periods)", t / p));
            }
            if let (Ok(v), Ok(s)) = (
                crate::h5::read_attr::<f64>(&l, "two_trajectory"),
                crate::h5::read_attr::<f64>(&l, "two_trajectory_stderr"),
            ) {
                out.push(format!("two traj.    {v:.4} +- {s:.4} 1/s"));
            }
        }
        if let Ok(z) = c.group("zero_one") {
            let k = crate::h5::read_attr::<f64>(&z, "k").map_err(&e)?;
            out.push(if k.is_nan() {
                "0-1 test     constant series (no K)".to_string()
            } else {
                format!("0-1 test     K = {k:.3}")
            });
        }
        out.push(format!(
            "class        {}",
            crate::h5::read_str(&c, "class").map_err(&e)?
        ));
    } else if let Ok(c) = file.group("sweep/chaos") {
        let class = c
            .dataset("class")
            .and_then(|d| d.read_raw::<u8>())
            .map_err(&e)?;
        let done = file
            .dataset("sweep/done")
            .and_then(|d| d.read_raw::<u8>())
            .map_err(&e)?;
        let mut counts = [0usize; 4];
        for (c, d) in class.iter().zip(&done) {
            if *d == 1 {
                counts[(*c as usize).min(3)] += 1;
            }
        }
        out.push(format!(
            "classes      {} periodic, {} quasi-periodic, {} chaotic, {} undetermined",
            counts[1], counts[2], counts[3], counts[0]
        ));
    }
    Ok(out)
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
        }
    }
    fn k(v: f64) -> ZeroOne {
        ZeroOne {
            k: Some(v),
            constant: false,
            oversampled: false,
            samples: 1000,
        }
    }

    #[test]
    fn the_classes_follow_the_documented_thresholds() {
        let c = |l: f64, e: f64, z: Option<&ZeroOne>| classify(Some(&spectrum(l, e)), z, None);
        assert_eq!(c(0.15, 0.002, Some(&k(0.98))), Class::Chaotic);
        assert_eq!(c(0.15, 0.002, Some(&k(0.1))), Class::Undetermined);
        assert_eq!(c(-0.3, 0.01, Some(&k(0.01))), Class::Periodic);
        assert_eq!(c(1e-4, 0.01, Some(&k(0.05))), Class::QuasiPeriodic);
        assert_eq!(c(1e-4, 0.01, None), Class::Undetermined);
        // A strobe series that repeats makes it periodic unless lambda_1 is clearly positive.
        let p = classify(Some(&spectrum(1e-4, 0.01)), Some(&k(0.05)), Some(2));
        assert_eq!(p, Class::Periodic);
        let series: Vec<f64> = (0..100).map(|j| [0.3, -0.7, 0.1][j % 3]).collect();
        assert_eq!(strobe_period(&series), Some(3));
        let drifting: Vec<f64> = (0..100).map(|j| (j as f64).sin()).collect();
        assert_eq!(strobe_period(&drifting), None);
        let constant = ZeroOne {
            k: None,
            constant: true,
            oversampled: false,
            samples: 1000,
        };
        assert_eq!(classify(None, Some(&constant), None), Class::Periodic);
    }
}
