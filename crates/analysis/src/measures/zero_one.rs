//! The 0-1 test for chaos on a scalar series (Gottwald & Melbourne, Proc. R. Soc. A 460, 2004;
//! the implementation of SIAM J. Appl. Dyn. Syst. 8, 2009, arXiv 0906.1418).
//!
//! For a series `phi_j`, j = 1..N, and a frequency c, the translation variables
//! `p_c(n) = sum_{j<=n} phi_j cos(j c)`, `q_c(n) = sum_{j<=n} phi_j sin(j c)` are bounded for a
//! regular series and behave like a Brownian motion for a chaotic one. Their mean-square
//! displacement `M_c(n) = 1/(N - n) sum_{j<=N-n} (p_c(j+n) - p_c(j))^2 + (q_c(j+n) - q_c(j))^2`,
//! n <= N/10, less its oscillatory term `(E phi)^2 (1 - cos n c) / (1 - cos c)` (the modified
//! `D_c(n)`), grows linearly in n for chaos and stays bounded otherwise. `K_c` is the correlation
//! of `D_c(n)` with n; K is the median of `K_c` over 100 frequencies in (pi/5, 4pi/5) (the
//! median discards the few c resonant with the series). K is near 1 for chaos, near 0 for
//! periodic and quasi-periodic motion.
//!
//! Guards, from the same papers' notes on validity (arXiv 0906.1415):
//! - a constant series (a period-1 stroboscopic series, whose spread is round-off) has no
//!   meaningful K: it is reported as constant, with no K;
//! - an oversampled series (a flow sampled much faster than its time scale) gives K near 0 for
//!   chaos: sample on a section. A lag-1 autocorrelation above 0.95 is reported as
//!   oversampling (K is still given, flagged);
//! - fewer than [`MIN_SAMPLES`] samples is an error.

use crate::measures::indicator::{Indicator, Number, Reading, Row, Verdict};

/// The least number of samples the test is run on: `n <= N/10` must leave enough lags for the
/// correlation (G&M use N = 1e4; 500 gives 50 lags).
pub const MIN_SAMPLES: usize = 500;

/// Frequencies the median is taken over.
const N_C: usize = 100;

/// The outcome of the 0-1 test.
#[derive(Debug, Clone, PartialEq)]
pub struct ZeroOne {
    /// The median K, None for a constant series.
    pub k: Option<f64>,
    /// The series is constant to round-off (relative spread below 1e-9).
    pub constant: bool,
    /// The series is oversampled (lag-1 autocorrelation above 0.95).
    pub oversampled: bool,
    /// Samples used.
    pub samples: usize,
}

/// Runs the test on `series`. An error (a sentence) when the series is too short or not finite.
pub fn zero_one(series: &[f64]) -> Result<ZeroOne, String> {
    let n = series.len();
    if n < MIN_SAMPLES {
        return Err(format!(
            "the 0-1 test needs at least {MIN_SAMPLES} samples, got {n}: run more periods after the transient"
        ));
    }
    if let Some(i) = series.iter().position(|x| !x.is_finite()) {
        return Err(format!("sample {i} is not finite"));
    }
    let mean = series.iter().sum::<f64>() / n as f64;
    let var = series.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / n as f64;
    let scale = series.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    if var.sqrt() <= 1e-9 * scale.max(f64::MIN_POSITIVE) {
        return Ok(ZeroOne {
            k: None,
            constant: true,
            oversampled: false,
            samples: n,
        });
    }
    let lag1 = series
        .windows(2)
        .map(|w| (w[0] - mean) * (w[1] - mean))
        .sum::<f64>()
        / (n as f64 * var);
    let n_cut = n / 10;
    let lags: Vec<f64> = (1..=n_cut).map(|l| l as f64).collect();
    let (mut p, mut q) = (vec![0.0; n + 1], vec![0.0; n + 1]);
    let mut ks = Vec::with_capacity(N_C);
    for i in 0..N_C {
        // Evenly spread over (pi/5, 4pi/5), offset from the ends.
        let c = std::f64::consts::PI * (0.2 + 0.6 * (i as f64 + 0.5) / N_C as f64);
        for j in 0..n {
            let jc = (j + 1) as f64 * c;
            p[j + 1] = p[j] + series[j] * jc.cos();
            q[j + 1] = q[j] + series[j] * jc.sin();
        }
        let d: Vec<f64> = (1..=n_cut)
            .map(|lag| {
                let m = (1..=n - lag)
                    .map(|j| (p[j + lag] - p[j]).powi(2) + (q[j + lag] - q[j]).powi(2))
                    .sum::<f64>()
                    / (n - lag) as f64;
                m - mean * mean * (1.0 - (lag as f64 * c).cos()) / (1.0 - c.cos())
            })
            .collect();
        ks.push(correlation(&lags, &d));
    }
    ks.retain(|k| k.is_finite());
    ks.sort_by(f64::total_cmp);
    let k = if ks.is_empty() {
        None
    } else if ks.len() % 2 == 1 {
        Some(ks[ks.len() / 2])
    } else {
        Some(0.5 * (ks[ks.len() / 2 - 1] + ks[ks.len() / 2]))
    };
    Ok(ZeroOne {
        k,
        constant: false,
        oversampled: lag1 > 0.95,
        samples: n,
    })
}

/// Pearson correlation of two series of equal length.
fn correlation(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len() as f64;
    let (ma, mb) = (a.iter().sum::<f64>() / n, b.iter().sum::<f64>() / n);
    let (mut sab, mut saa, mut sbb) = (0.0, 0.0, 0.0);
    for (x, y) in a.iter().zip(b) {
        sab += (x - ma) * (y - mb);
        saa += (x - ma).powi(2);
        sbb += (y - mb).powi(2);
    }
    sab / (saa * sbb).sqrt()
}

/// The 0-1 test as a chaos indicator ([`crate::measures::indicator`]): its number is K, chaotic
/// above 0.8 and regular below 0.2 (the thresholds of book/src/explanation/lyapunov.md), a
/// constant series regular with no K.
pub struct ZeroOneTest;

impl Indicator for ZeroOneTest {
    fn key(&self) -> &'static str {
        "zero_one"
    }

    fn title(&self) -> &'static str {
        "0-1 test"
    }

    fn least_samples(&self) -> usize {
        MIN_SAMPLES
    }

    fn row(&self) -> Row {
        Row {
            name: "k",
            unit: "1",
            description: "0-1 test K per value (NaN: constant series)",
            column: "K",
            digits: 3,
            title: "0-1 test for chaos",
            range: Some((-0.1, 1.1)),
        }
    }

    fn compute(&self, series: &[f64]) -> Result<Reading, String> {
        let z = zero_one(series)?;
        let verdict = match z.k {
            _ if z.constant => Verdict::Constant,
            Some(k) if k > 0.8 => Verdict::Chaotic,
            Some(k) if k < 0.2 => Verdict::Regular,
            _ => Verdict::Unsure,
        };
        let value = z.k.unwrap_or(f64::NAN);
        Ok(Reading {
            key: self.key(),
            value,
            verdict,
            attributes: vec![
                ("k", Number::Real(value)),
                ("constant", Number::Flag(z.constant)),
                ("oversampled", Number::Flag(z.oversampled)),
                ("samples", Number::Count(z.samples as u64)),
            ],
        })
    }

    fn line(&self, k: f64) -> String {
        if k.is_nan() {
            "0-1 test     constant series (no K)".to_string()
        } else {
            format!("0-1 test     K = {k:.3}")
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn logistic(r: f64, n: usize) -> Vec<f64> {
        let mut x = 0.3;
        for _ in 0..1000 {
            x = r * x * (1.0 - x);
        }
        (0..n)
            .map(|_| {
                x = r * x * (1.0 - x);
                x
            })
            .collect()
    }

    // Thresholds: Gottwald & Melbourne (2009, fig. 2) report K within about 0.05 of 0 or 1 at
    // N = 5000 for these cases; 0.1 leaves room for the finite N and the fixed set of c.

    #[test]
    fn logistic_map_at_3_97_is_chaotic() {
        let r = zero_one(&logistic(3.97, 5000)).unwrap();
        assert!(r.k.unwrap() > 0.9, "{r:?}");
        assert!(!r.oversampled);
    }

    #[test]
    fn logistic_map_at_3_5_is_periodic() {
        // Period 4.
        let r = zero_one(&logistic(3.5, 5000)).unwrap();
        assert!(r.k.unwrap().abs() < 0.1, "{r:?}");
    }

    #[test]
    fn a_quasi_periodic_signal_is_regular() {
        let s: Vec<f64> = (0..5000)
            .map(|j| {
                let t = j as f64;
                t.cos() + (2f64.sqrt() * t).cos()
            })
            .collect();
        let r = zero_one(&s).unwrap();
        assert!(r.k.unwrap().abs() < 0.1, "{r:?}");
    }

    #[test]
    fn a_constant_series_has_no_k_and_a_short_one_is_refused() {
        let s: Vec<f64> = (0..1000).map(|j| 0.25 + 1e-14 * (j % 3) as f64).collect();
        let r = zero_one(&s).unwrap();
        assert!(r.constant && r.k.is_none());
        let e = zero_one(&s[..100]).unwrap_err();
        assert!(e.contains("at least 500 samples, got 100"), "{e}");
    }

    #[test]
    fn an_oversampled_flow_is_flagged() {
        let s: Vec<f64> = (0..2000).map(|j| (j as f64 * 1e-3).sin()).collect();
        assert!(zero_one(&s).unwrap().oversampled);
    }
}
