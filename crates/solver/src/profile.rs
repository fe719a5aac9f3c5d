//! Prescribed motions s(t) for drives, with exact first and second derivatives.
//!
//! * constant rate: s = s0 + r t;
//! * harmonic: s = m + A sin(w t + phi);
//! * tabulated: natural cubic spline through the table (C2, so the drive's acceleration, and with it
//!   the actuator force, is continuous); held constant before the first and after the last point;
//! * leg length: s = |p(t) - a| + s_off with p(t) = c + u cos(w t) + v sin(w t), the inverse
//!   kinematics of a leg whose platform end translates on an ellipse; with d = p - a, L = |d|:
//!   s' = d.p'/L, s'' = (p'.p' + d.p'' - s'^2)/L.
//!
//! **Ramped start** (`ramp_time` T_r > 0, constant-rate, harmonic and leg-length profiles): the
//! phase `theta = omega t` (for a constant rate `s - s0 = r t`, with omega = r) is replaced by one whose rate rises from rest to omega with the C1
//! smoothstep r(u) = 3u^2 - 2u^3, u = t / T_r:
//!
//! ```text
//! theta' = omega r(u),  theta = omega T_r u^3 (1 - u/2),  theta'' = 6 omega u (1 - u) / T_r   (t < T_r)
//! theta  = omega (t - T_r / 2),  theta' = omega,  theta'' = 0                                  (t >= T_r)
//! ```
//!
//! so the drive starts at rest where the unramped one starts, with a continuous acceleration
//! (no start-up jerk of the actuators' velocity), and runs after the ramp T_r / 2 behind the
//! unramped motion. The chain rule gives p' = p_theta theta' and
//! p'' = p_thetatheta theta'^2 + p_theta theta''.

use nalgebra::Vector3;

/// A compiled profile.
#[derive(Debug, Clone)]
pub enum Profile {
    ConstantRate {
        initial: f64,
        rate: f64,
        /// Ramp time (s; 0: none).
        ramp: f64,
    },
    Harmonic {
        mean: f64,
        amplitude: f64,
        omega: f64,
        phase: f64,
        /// Ramp time (s; 0: none).
        ramp: f64,
    },
    Spline(Spline),
    LegLength {
        anchor: Vector3<f64>,
        center: Vector3<f64>,
        cos_amp: Vector3<f64>,
        sin_amp: Vector3<f64>,
        omega: f64,
        offset: f64,
        /// Ramp time (s; 0: none).
        ramp: f64,
    },
}

/// The phase (theta, theta', theta'') at time t: omega t without a ramp (`ramp` 0), else the
/// ramped phase of the module overview, at rest before t = 0.
fn drive_phase(omega: f64, ramp: f64, t: f64) -> (f64, f64, f64) {
    if ramp <= 0.0 {
        return (omega * t, omega, 0.0);
    }
    if t >= ramp {
        return (omega * (t - 0.5 * ramp), omega, 0.0);
    }
    if t <= 0.0 {
        return (0.0, 0.0, 0.0);
    }
    let u = t / ramp;
    (
        omega * ramp * u * u * u * (1.0 - 0.5 * u),
        omega * u * u * (3.0 - 2.0 * u),
        6.0 * omega * u * (1.0 - u) / ramp,
    )
}

impl Profile {
    /// (s, s', s'') at time t.
    pub fn eval(&self, t: f64) -> (f64, f64, f64) {
        self.eval_memo(t, &mut SinCos::default())
    }

    /// [`Profile::eval`], taking the sine and cosine from `memo` when its last argument was the
    /// same: the drives of a mechanism usually share one frequency, and then one `sin_cos` per
    /// time serves them all. The results are those of [`Profile::eval`], bit for bit.
    pub fn eval_memo(&self, t: f64, memo: &mut SinCos) -> (f64, f64, f64) {
        match self {
            Profile::ConstantRate {
                initial,
                rate,
                ramp,
            } => {
                // The rate is the phase rate: unramped this is initial + rate t, rate, 0 to the
                // bit.
                let (th, thd, thdd) = drive_phase(*rate, *ramp, t);
                (initial + th, thd, thdd)
            }
            Profile::Harmonic {
                mean,
                amplitude,
                omega,
                phase,
                ramp,
            } => {
                // Unramped, theta'' is 0 and this is amplitude omega cos, -amplitude omega^2 sin
                // to the bit.
                let (th, thd, thdd) = drive_phase(*omega, *ramp, t);
                let (s, c) = memo.sin_cos(th + phase);
                (
                    mean + amplitude * s,
                    amplitude * thd * c,
                    -amplitude * thd * thd * s + amplitude * thdd * c,
                )
            }
            Profile::Spline(sp) => sp.eval(t),
            Profile::LegLength {
                anchor,
                center,
                cos_amp,
                sin_amp,
                omega,
                offset,
                ramp,
            } => {
                let (th, thd, thdd) = drive_phase(*omega, *ramp, t);
                let (s, c) = memo.sin_cos(th);
                let p_th = -cos_amp * s + sin_amp * c;
                let p = center + cos_amp * c + sin_amp * s;
                let pd = p_th * thd;
                let pdd = -(cos_amp * c + sin_amp * s) * (thd * thd) + p_th * thdd;
                let d = p - anchor;
                let l = d.norm();
                let ld = d.dot(&pd) / l;
                let ldd = (pd.dot(&pd) + d.dot(&pdd) - ld * ld) / l;
                (l + offset, ld, ldd)
            }
        }
    }

    /// One line for people: the kind of motion and its parameters, e.g.
    /// "harmonic 0 + 0.1 sin(2 t + 0)".
    pub fn describe(&self) -> String {
        match self {
            Profile::ConstantRate {
                initial,
                rate,
                ramp,
            } => {
                format!("constant rate {rate} from {initial}{}", ramp_words(*ramp))
            }
            Profile::Harmonic {
                mean,
                amplitude,
                omega,
                phase,
                ramp,
            } => {
                format!(
                    "harmonic {mean} + {amplitude} sin({omega} t + {phase}){}",
                    ramp_words(*ramp)
                )
            }
            Profile::Spline(_) => "tabulated (natural cubic spline)".into(),
            Profile::LegLength { omega, ramp, .. } => {
                format!(
                    "leg length of a harmonic path, omega {omega} rad/s{}",
                    ramp_words(*ramp)
                )
            }
        }
    }

    /// The period of the motion (s) when it has one.
    pub fn period(&self) -> Option<f64> {
        match self {
            Profile::ConstantRate { rate, .. } if *rate != 0.0 => {
                Some(2.0 * std::f64::consts::PI / rate.abs())
            }
            Profile::Harmonic { omega, .. } | Profile::LegLength { omega, .. } if *omega != 0.0 => {
                Some(2.0 * std::f64::consts::PI / omega.abs())
            }
            // At rest (a zero rate or frequency), or not periodic.
            Profile::ConstantRate { .. }
            | Profile::Harmonic { .. }
            | Profile::LegLength { .. }
            | Profile::Spline(_) => None,
        }
    }
}

fn ramp_words(ramp: f64) -> String {
    if ramp > 0.0 {
        format!(", ramped up from rest over {ramp} s")
    } else {
        String::new()
    }
}

/// The last argument given to [`SinCos::sin_cos`] and its sine and cosine.
#[derive(Debug, Clone, Copy)]
pub struct SinCos {
    x: f64,
    sin: f64,
    cos: f64,
}

impl Default for SinCos {
    fn default() -> Self {
        // NaN's own sine and cosine, so that even a NaN argument gets the right answer.
        SinCos {
            x: f64::NAN,
            sin: f64::NAN,
            cos: f64::NAN,
        }
    }
}

impl SinCos {
    /// `x.sin_cos()`, computed only when x differs (bitwise) from the last argument.
    pub fn sin_cos(&mut self, x: f64) -> (f64, f64) {
        if x.to_bits() != self.x.to_bits() {
            (self.sin, self.cos) = x.sin_cos();
            self.x = x;
        }
        (self.sin, self.cos)
    }
}

/// Natural cubic spline (second derivative zero at both ends).
#[derive(Debug, Clone)]
pub struct Spline {
    t: Vec<f64>,
    y: Vec<f64>,
    /// Second derivatives at the knots.
    m: Vec<f64>,
}

impl Spline {
    /// Builds the spline; `t` strictly increasing, at least two points (checked by the caller).
    pub fn new(t: Vec<f64>, y: Vec<f64>) -> Spline {
        let n = t.len();
        let mut m = vec![0.0; n];
        if n > 2 {
            // Tridiagonal system for the interior second derivatives (Thomas algorithm).
            let mut c = vec![0.0; n];
            let mut d = vec![0.0; n];
            for i in 1..n - 1 {
                let h0 = t[i] - t[i - 1];
                let h1 = t[i + 1] - t[i];
                let a = h0 / 6.0;
                let b = (h0 + h1) / 3.0;
                let cc = h1 / 6.0;
                let r = (y[i + 1] - y[i]) / h1 - (y[i] - y[i - 1]) / h0;
                let denom = b - a * c[i - 1];
                c[i] = cc / denom;
                d[i] = (r - a * d[i - 1]) / denom;
            }
            for i in (1..n - 1).rev() {
                m[i] = d[i] - c[i] * m[i + 1];
            }
        }
        Spline { t, y, m }
    }

    pub fn eval(&self, x: f64) -> (f64, f64, f64) {
        let n = self.t.len();
        if x <= self.t[0] {
            return (self.y[0], 0.0, 0.0);
        }
        if x >= self.t[n - 1] {
            return (self.y[n - 1], 0.0, 0.0);
        }
        let i = match self.t.binary_search_by(|v| v.total_cmp(&x)) {
            Ok(i) => i.min(n - 2),
            Err(i) => i - 1,
        };
        let h = self.t[i + 1] - self.t[i];
        let a = (self.t[i + 1] - x) / h;
        let b = (x - self.t[i]) / h;
        let (m0, m1) = (self.m[i], self.m[i + 1]);
        let (y0, y1) = (self.y[i], self.y[i + 1]);
        let s = a * y0 + b * y1 + ((a * a * a - a) * m0 + (b * b * b - b) * m1) * h * h / 6.0;
        let sd =
            (y1 - y0) / h - (3.0 * a * a - 1.0) / 6.0 * h * m0 + (3.0 * b * b - 1.0) / 6.0 * h * m1;
        let sdd = a * m0 + b * m1;
        (s, sd, sdd)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn check_derivatives(p: &Profile, t: f64) {
        let h = 1e-5;
        let (_, d, dd) = p.eval(t);
        let fd = (p.eval(t + h).0 - p.eval(t - h).0) / (2.0 * h);
        let fdd = (p.eval(t + h).1 - p.eval(t - h).1) / (2.0 * h);
        // Central differences at h = 1e-5 are accurate to ~1e-9 for these smooth functions.
        assert!(
            (d - fd).abs() < 1e-7 * (1.0 + d.abs()),
            "{p:?} s' {d} vs {fd}"
        );
        assert!(
            (dd - fdd).abs() < 1e-6 * (1.0 + dd.abs()),
            "{p:?} s'' {dd} vs {fdd}"
        );
    }

    #[test]
    fn derivatives_match_finite_differences() {
        let leg = Profile::LegLength {
            anchor: Vector3::new(0.0, 0.456, 0.456),
            center: Vector3::new(1.21, 0.143, 0.143),
            cos_amp: Vector3::new(-0.03, 0.0, 0.0),
            sin_amp: Vector3::new(0.0, 0.03, 0.0),
            omega: 2.5,
            offset: 0.0,
            ramp: 0.0,
        };
        let harm = Profile::Harmonic {
            mean: 1.0,
            amplitude: 0.2,
            omega: 2.0,
            phase: 0.3,
            ramp: 0.0,
        };
        let sp = Profile::Spline(Spline::new(
            vec![0.0, 0.5, 1.0, 2.0, 3.0],
            vec![0.0, 0.3, 0.2, 0.9, 1.0],
        ));
        for t in [0.1, 0.7, 1.3, 2.2] {
            check_derivatives(&leg, t);
            check_derivatives(&harm, t);
            check_derivatives(&sp, t);
        }
    }

    /// A ramped drive starts at rest where the unramped one starts, its derivatives are exact
    /// (finite differences inside and after the ramp), its speed and acceleration are
    /// continuous at the ramp's end, and after it the motion is the unramped one T_r / 2 later.
    #[test]
    fn a_ramped_drive_starts_at_rest_and_runs_half_the_ramp_behind() {
        let leg = |ramp| Profile::LegLength {
            anchor: Vector3::new(0.0, 0.456, 0.456),
            center: Vector3::new(1.21, 0.143, 0.143),
            cos_amp: Vector3::new(-0.03, 0.0, 0.0),
            sin_amp: Vector3::new(0.0, 0.03, 0.0),
            omega: 3.0,
            offset: 0.0,
            ramp,
        };
        let harm = |ramp| Profile::Harmonic {
            mean: 1.0,
            amplitude: 0.2,
            omega: 2.0,
            phase: 0.3,
            ramp,
        };
        let tr = 0.8;
        for (ramped, plain) in [(leg(tr), leg(0.0)), (harm(tr), harm(0.0))] {
            let (s0, v0, _) = ramped.eval(0.0);
            assert_eq!(s0, plain.eval(0.0).0);
            assert_eq!(v0, 0.0);
            for t in [0.05, 0.3, 0.61, 1.1, 2.7] {
                check_derivatives(&ramped, t);
            }
            // Continuity at the ramp's end (the cubic's value, slope and curvature there).
            let (a, b) = (ramped.eval(tr - 1e-9), ramped.eval(tr + 1e-9));
            assert!((a.0 - b.0).abs() < 1e-8 && (a.1 - b.1).abs() < 1e-7);
            assert!((a.2 - b.2).abs() < 1e-6, "{a:?} {b:?}");
            // Half the ramp behind: the same state as the plain drive at t - T_r / 2 (to
            // round-off in the phase, ~1e-15 rad).
            for t in [tr, 1.7, 5.0] {
                let (r, p) = (ramped.eval(t), plain.eval(t - 0.5 * tr));
                assert!((r.0 - p.0).abs() < 1e-12 && (r.1 - p.1).abs() < 1e-12);
                assert!((r.2 - p.2).abs() < 1e-11, "{r:?} {p:?}");
            }
            assert_eq!(ramped.period(), plain.period());
        }
        assert!(
            leg(tr)
                .describe()
                .ends_with("ramped up from rest over 0.8 s")
        );
    }

    /// A crank ramped up at a constant rate r over T_r: the closed forms of the module overview,
    /// s - s0 = r T_r u^3 (1 - u/2), s' = r (3u^2 - 2u^3), s'' = 6 r u (1 - u) / T_r before T_r,
    /// and s0 + r (t - T_r/2) after; at rest at t = 0; unramped, the plain line to the bit.
    #[test]
    fn a_ramped_constant_rate_starts_at_rest_and_runs_half_the_ramp_behind() {
        let (s0, r, tr) = (0.3, 251.327_412_287_183_45, 0.2); // 2400 rpm in rad/s
        let ramped = Profile::ConstantRate {
            initial: s0,
            rate: r,
            ramp: tr,
        };
        let plain = Profile::ConstantRate {
            initial: s0,
            rate: r,
            ramp: 0.0,
        };
        assert_eq!(ramped.eval(0.0), (s0, 0.0, 0.0));
        for t in [0.0, 0.013, 1.7] {
            assert_eq!(plain.eval(t), (s0 + r * t, r, 0.0));
        }
        // Closed forms before the ramp's end; the tolerance is round-off on values of ~50 rad.
        for t in [0.02, 0.1, 0.19] {
            let u = t / tr;
            let (a, b, c) = ramped.eval(t);
            assert!((a - (s0 + r * tr * u.powi(3) * (1.0 - 0.5 * u))).abs() < 1e-12);
            assert!((b - r * u * u * (3.0 - 2.0 * u)).abs() < 1e-11);
            assert!((c - 6.0 * r * u * (1.0 - u) / tr).abs() < 1e-9);
            check_derivatives(&ramped, t);
        }
        for t in [tr, 0.5, 3.0] {
            let (a, b, c) = ramped.eval(t);
            assert!((a - (s0 + r * (t - 0.5 * tr))).abs() < 1e-12 && b == r && c == 0.0);
        }
        assert_eq!(ramped.period(), plain.period());
        assert_eq!(
            ramped.describe(),
            format!("constant rate {r} from {s0}, ramped up from rest over 0.2 s")
        );
    }

    #[test]
    fn describe_names_the_motion_and_its_parameters() {
        let rate = Profile::ConstantRate {
            initial: 0.5,
            rate: 2.0,
            ramp: 0.0,
        };
        assert_eq!(rate.describe(), "constant rate 2 from 0.5");
        let harm = Profile::Harmonic {
            mean: 1.0,
            amplitude: 0.2,
            omega: 2.5,
            phase: 0.0,
            ramp: 0.0,
        };
        assert_eq!(harm.describe(), "harmonic 1 + 0.2 sin(2.5 t + 0)");
        let sp = Profile::Spline(Spline::new(vec![0.0, 1.0], vec![0.0, 1.0]));
        assert_eq!(sp.describe(), "tabulated (natural cubic spline)");
        let leg = Profile::LegLength {
            anchor: Vector3::zeros(),
            center: Vector3::x(),
            cos_amp: Vector3::zeros(),
            sin_amp: Vector3::zeros(),
            omega: 3.0,
            offset: 0.0,
            ramp: 0.0,
        };
        assert_eq!(
            leg.describe(),
            "leg length of a harmonic path, omega 3 rad/s"
        );
    }

    #[test]
    fn spline_interpolates_and_reproduces_cubics_in_the_interior() {
        let t: Vec<f64> = (0..=40).map(|i| i as f64 * 0.05).collect();
        let y: Vec<f64> = t.iter().map(|x| x.sin()).collect();
        let sp = Spline::new(t.clone(), y.clone());
        for (ti, yi) in t.iter().zip(&y) {
            assert!((sp.eval(*ti).0 - yi).abs() < 1e-15);
        }
        // Interior accuracy of a natural spline on sin with h = 0.05 is O(h^4) ~ 1e-6.
        let (s, _, _) = sp.eval(1.0123);
        assert!((s - 1.0123f64.sin()).abs() < 1e-6);
    }
}
