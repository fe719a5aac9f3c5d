//! Normal-contact and friction laws: pure functions of the penetration `delta` (m, > 0 in
//! contact), its rate `delta_dot` (m/s, > 0 while approaching), the approach velocity at contact
//! onset `v_on` (m/s) and the tangential sliding speed. No law sees the time step.
//!
//! # Normal laws
//! All return `F_N >= 0` (N); a law that would pull the bodies together returns zero.
//!
//! * Hertz (Hertz 1882; Johnson, *Contact Mechanics*, 1985, ch. 4): `F = K delta^n`.
//! * Hysteresis-damped laws of the Hunt-Crossley family, `F = K delta^n (1 + D delta_dot / v_on)`,
//!   with the damping factor D set by the restitution coefficient c_e:
//!   - Hunt & Crossley, J. Appl. Mech. 42:440-445 (1975): D = 3 (1 - c_e) / 2;
//!   - Lankarani & Nikravesh, J. Mech. Des. 112:369-376 (1990): D = 3 (1 - c_e^2) / 4
//!     (the law of the 4-UPS/RPU paper, its eq. 48);
//!   - Flores, Machado, Silva & Martins, Multibody Syst. Dyn. 25:357-375 (2011):
//!     D = 8 (1 - c_e) / (5 c_e);
//!   - Gonthier, McPhee, Lange & Piedboeuf, Multibody Syst. Dyn. 11:209-233 (2004):
//!     D = (1 - c_e^2) / c_e;
//!   - Carvalho & Martins, Mech. Mach. Theory 139:174-194 (2019), "Exact restitution and
//!     generalizations for the Hunt-Crossley contact model": D = 3 (1 - c_e)(11 - c_e) /
//!     (2 (1 + 9 c_e)) for c_e > 1/3 (their approximation of the exact inverse; below 1/3 they
//!     fall back to Gonthier's factor, as here).
//!
//!   For an isolated two-body impact every law of this family restores the restitution `e` that
//!   solves `(1 + D) = (1 - e D) exp(D (1 + e))`, whatever K, n and the masses
//!   ([`hunt_crossley_restitution`]): separate m v dv/(1 + D v / v0) = -K delta^n d delta and
//!   integrate over approach and rebound. At c_e = 0.9 this gives 0.913 for Lankarani-Nikravesh,
//!   0.909 for Hunt-Crossley, 0.894 for Flores, 0.876 for Gonthier and 0.900 for Carvalho-Martins.
//! * IMPACT (MSC ADAMS function reference, IMPACT and STEP): ADAMS writes
//!   `max(0, k (x1 - x)^e - STEP(x, x1 - d, c_max, x1, 0) x')` for a distance x; with
//!   delta = x1 - x and the approach rate delta_dot = -x' that is `F = max(0, K delta^n +
//!   STEP(delta, 0, 0, d_max, c_max) delta_dot)`, the cubic STEP rising from 0 at first touch
//!   to the maximum damping c_max (N s/m) at the penetration d_max (m), so the damping force never
//!   jumps at contact onset. Use it to compare with ADAMS models.
//!
//! The onset velocity v_on that the damped laws divide by is floored at `v_floor` (m/s): a grazing
//! contact starting at a tiny approach speed would otherwise produce an unbounded damping term.
//!
//! # Stiffness from materials
//! Point contact of two spheres (or, as the paper does for its revolute joint, of a journal in a
//! bushing treated as spheres), paper eqs. 49-50 after Goldsmith (*Impact*, 1960):
//! `K = 4 / (3 (eta_i + eta_j)) sqrt(R_i R_j / |R_i - R_j|)`, `eta = (1 - nu^2) / E` (N/m^1.5).
//!
//! # Friction laws
//! Friction opposes the sliding velocity: `F_T = -c(|v_t|) F_N v_t / |v_t|`, with
//! * none: c = 0;
//! * Coulomb regularised linearly below `v_reg` (as in Exudyn's contact elements): c = mu
//!   min(|v_t| / v_reg, 1);
//! * Ambrosio's modified Coulomb (Ambrosio, "Impact of rigid and flexible multibody systems:
//!   deformation description and contact models", NATO Sci. Ser. II 103, 2003; the paper's eqs.
//!   51-52): c = mu c_d, c_d = 0 below v0, (|v_t| - v0)/(v1 - v0) between v0 and v1, 1 above v1;
//! * Threlfall (Mech. Mach. Theory 13:475-483, 1978), as quoted in the friction survey of
//!   Marques, Flores, Claro & Lankarani, Nonlinear Dyn. 86:1407-1443 (2016):
//!   c = mu (1 - exp(-3 |v_t| / v0));
//! * LuGre (Canudas de Wit, Olsson, Astrom & Lischinsky, "A new model for control of systems with
//!   friction", IEEE Trans. Autom. Control 40(3):419-425, 1995), in the form normalised by the
//!   normal force that multibody contact uses (Do, Ferri & Bauchau, "Efficient simulation of a
//!   dynamic system with LuGre friction", J. Comput. Nonlinear Dyn. 2(4):281-289, 2007; in
//!   clearance joints, Muvengei, Kihiu & Ikua, Multibody Syst. Dyn. 28:369-393, 2012). A bristle
//!   deflection z (m, a vector per contact, held in the housing's axes so that bristles stuck
//!   to a turning housing turn with it) is part of the continuous state and obeys
//!
//!   ```text
//!   z' = v_t - sigma0 |v_t| z / g(|v_t|),     g(v) = mu_c + (mu_s - mu_c) exp(-(v / v_s)^2),
//!   F_T = -(sigma0 z_t + sigma1 z'_t + sigma2 v_t) F_N,
//!   ```
//!
//!   with z_t, z'_t their parts in the contact's tangent plane, sigma0 (1/m) the bristle
//!   stiffness, sigma1 (s/m) its damping and sigma2 (s/m) the viscous friction, all per newton of
//!   normal force. Sliding steadily at v_t, z = g(v) v_t / (sigma0 |v_t|) and
//!   |F_T| = (g(v) + sigma2 v) F_N: the Stribeck curve. At small displacements the bristles act
//!   as a spring of stiffness sigma0 F_N (presliding). From |z| <= mu_s / sigma0, z stays there.
//!
//! The memoryless laws keep |F_T| <= mu F_N; LuGre's force can exceed mu_s F_N for an instant by
//! its damping and viscous terms.

use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

/// Kinds of hysteresis damping factor D(c_e).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Damping {
    HuntCrossley,
    LankaraniNikravesh,
    Flores,
    Gonthier,
    CarvalhoMartins,
}

impl Damping {
    /// The dimensionless damping factor D for restitution `ce` in (0, 1].
    pub fn factor(self, ce: f64) -> f64 {
        match self {
            Damping::HuntCrossley => 1.5 * (1.0 - ce),
            Damping::LankaraniNikravesh => 0.75 * (1.0 - ce * ce),
            Damping::Flores => 8.0 * (1.0 - ce) / (5.0 * ce),
            Damping::Gonthier => (1.0 - ce * ce) / ce,
            Damping::CarvalhoMartins => {
                if ce > 1.0 / 3.0 {
                    1.5 * (1.0 - ce) * (11.0 - ce) / (1.0 + 9.0 * ce)
                } else {
                    (1.0 - ce * ce) / ce
                }
            }
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            Damping::HuntCrossley => "Hunt-Crossley",
            Damping::LankaraniNikravesh => "Lankarani-Nikravesh",
            Damping::Flores => "Flores et al.",
            Damping::Gonthier => "Gonthier et al.",
            Damping::CarvalhoMartins => "Carvalho-Martins",
        }
    }
}

/// The elastic part of a normal law: the force-penetration relation without damping.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Elastic {
    /// F = K delta^n (point contact, paper eq. 48 without damping).
    Power { k: f64, n: f64 },
    /// Johnson's line contact of a cylinder of length L in a cylindrical hole with radial
    /// clearance dR (Johnson, *Contact Mechanics*, 1985; compared in Pereira, Ramalho & Ambrosio,
    /// Nonlinear Dyn. 63:681-697, 2011): delta = (F / (pi L E*)) (ln(4 pi L E* dR / F) - 1),
    /// 1/E* = (1 - nu_i^2)/E_i + (1 - nu_j^2)/E_j. With x = F / (pi L E*) (a length) this is
    /// delta = x (ln(4 dR / x) - 1), solved for x by Newton's method. The relation holds while
    /// x < 4 dR / e^2 (delta < 0.54 dR, far beyond any elastic penetration); past 90 % of that the
    /// force continues along its tangent so that it stays monotone.
    CylinderLine {
        /// pi L E* (N/m).
        c: f64,
        /// Radial clearance dR (m).
        dr: f64,
    },
}

impl Elastic {
    /// Elastic force (N) at penetration delta > 0.
    #[inline]
    pub fn force(&self, delta: f64) -> f64 {
        match *self {
            Elastic::Power { k, n } => k * delta.powf(n),
            Elastic::CylinderLine { c, dr } => c * line_x(delta, dr),
        }
    }

    /// Elastic energy stored at penetration delta > 0 (J): the integral of the force.
    pub fn energy(&self, delta: f64) -> f64 {
        match *self {
            Elastic::Power { k, n } => k * delta.powf(n + 1.0) / (n + 1.0),
            Elastic::CylinderLine { c, dr } => {
                // With x(delta): integral of c x d(delta) = c x^2 (ln(4 dR / x) / 2 - 3/4)
                // (integration by parts of delta(x) = x (ln(4 dR / x) - 1)); linear extension
                // beyond the validity limit adds its trapezoid.
                let a = 4.0 * dr;
                let x_lim = 0.9 * a / std::f64::consts::E.powi(2);
                let d_lim = x_lim * ((a / x_lim).ln() - 1.0);
                let v = |x: f64| c * x * x * (0.5 * (a / x).ln() - 0.75);
                if delta <= d_lim {
                    v(line_x(delta, dr))
                } else {
                    let f_lim = c * x_lim;
                    let f = self.force(delta);
                    v(x_lim) + 0.5 * (f_lim + f) * (delta - d_lim)
                }
            }
        }
    }

    /// Tangent stiffness dF/d(delta) (N/m) at penetration delta > 0.
    pub fn stiffness(&self, delta: f64) -> f64 {
        match *self {
            Elastic::Power { k, n } => n * k * delta.powf(n - 1.0),
            Elastic::CylinderLine { c, dr } => {
                // d(delta)/dx = ln(4 dR / x) - 2 (see `line_x`), so dF/d(delta) = c / that.
                let a = 4.0 * dr;
                let x_lim = 0.9 * a / std::f64::consts::E.powi(2);
                let x = line_x(delta, dr).min(x_lim);
                c / ((a / x).ln() - 2.0)
            }
        }
    }

    pub fn describe(&self) -> String {
        match *self {
            Elastic::Power { k, n } => format!("K = {k:.4e} N/m^{n}"),
            Elastic::CylinderLine { c, dr } => {
                format!("Johnson line contact, pi L E* = {c:.4e} N/m, radial clearance {dr:.4e} m")
            }
        }
    }
}

/// x = F / (pi L E*) of Johnson's line contact at penetration delta (> 0).
fn line_x(delta: f64, dr: f64) -> f64 {
    let a = 4.0 * dr;
    let x_lim = 0.9 * a / std::f64::consts::E.powi(2);
    let d_lim = x_lim * ((a / x_lim).ln() - 1.0);
    if delta >= d_lim {
        // Tangent continuation: d(delta)/dx = ln(a / x) - 2 at x_lim.
        return x_lim + (delta - d_lim) / ((a / x_lim).ln() - 2.0);
    }
    // Fixed-point start, then Newton on g(x) = x (ln(a/x) - 1) - delta, g' = ln(a/x) - 2 > 0.
    let mut x = delta / ((a / delta).ln() - 1.0).max(1.0);
    for _ in 0..50 {
        let l = (a / x).ln();
        let step = (x * (l - 1.0) - delta) / (l - 2.0);
        let xn = (x - step).clamp(0.5 * x, (2.0 * x).min(x_lim));
        if (xn - x).abs() <= 1e-15 * x {
            return xn;
        }
        x = xn;
    }
    x
}

/// A compiled normal-contact law.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum NormalLaw {
    /// F = elastic(delta).
    Hertz { el: Elastic },
    /// F = elastic(delta) (1 + D delta_dot / max(v_on, v_floor)).
    Hysteresis {
        el: Elastic,
        kind: Damping,
        restitution: f64,
        /// D, precomputed from the restitution.
        d: f64,
        /// m/s.
        v_floor: f64,
    },
    /// ADAMS IMPACT: F = K delta^n + STEP(delta, 0, 0, d_max, c_max) delta_dot.
    Impact {
        k: f64,
        n: f64,
        c_max: f64,
        d_max: f64,
    },
}

/// ADAMS' cubic STEP(x, x0, h0, x1, h1).
pub fn step(x: f64, x0: f64, h0: f64, x1: f64, h1: f64) -> f64 {
    if x <= x0 {
        h0
    } else if x >= x1 {
        h1
    } else {
        let d = (x - x0) / (x1 - x0);
        h0 + (h1 - h0) * d * d * (3.0 - 2.0 * d)
    }
}

impl NormalLaw {
    /// Whether the law needs the onset velocity.
    pub fn needs_onset(&self) -> bool {
        matches!(self, NormalLaw::Hysteresis { .. })
    }

    /// Normal force (N) at penetration `delta`, rate `delta_dot` and onset velocity `v_on`.
    #[inline]
    pub fn force(&self, delta: f64, delta_dot: f64, v_on: f64) -> f64 {
        if delta <= 0.0 {
            return 0.0;
        }
        let f = match *self {
            NormalLaw::Hertz { el } => el.force(delta),
            NormalLaw::Hysteresis { el, d, v_floor, .. } => {
                el.force(delta) * (1.0 + d * delta_dot / v_on.abs().max(v_floor))
            }
            NormalLaw::Impact { k, n, c_max, d_max } => {
                k * delta.powf(n) + step(delta, 0.0, 0.0, d_max, c_max) * delta_dot
            }
        };
        f.max(0.0)
    }

    /// The law linearised about a contact state: the stiffness dF/d(delta) (N/m) and the damping
    /// dF/d(delta_dot) (N s/m) at penetration `delta` > 0, rate `delta_dot` and onset velocity
    /// `v_on`. Zero when the law gives no force there.
    pub fn linearised(&self, delta: f64, delta_dot: f64, v_on: f64) -> (f64, f64) {
        if self.force(delta, delta_dot, v_on) <= 0.0 {
            return (0.0, 0.0);
        }
        match *self {
            NormalLaw::Hertz { el } => (el.stiffness(delta), 0.0),
            NormalLaw::Hysteresis { el, d, v_floor, .. } => {
                let v = v_on.abs().max(v_floor);
                (
                    el.stiffness(delta) * (1.0 + d * delta_dot / v).max(0.0),
                    el.force(delta) * d / v,
                )
            }
            NormalLaw::Impact { k, n, c_max, d_max } => (
                Elastic::Power { k, n }.stiffness(delta),
                step(delta, 0.0, 0.0, d_max, c_max),
            ),
        }
    }

    /// Elastic energy stored at penetration delta (J); zero out of contact.
    pub fn elastic_energy(&self, delta: f64) -> f64 {
        if delta <= 0.0 {
            return 0.0;
        }
        match *self {
            NormalLaw::Hertz { el } | NormalLaw::Hysteresis { el, .. } => el.energy(delta),
            NormalLaw::Impact { k, n, .. } => Elastic::Power { k, n }.energy(delta),
        }
    }

    /// One-line description for `jointplay check`.
    pub fn describe(&self) -> String {
        match *self {
            NormalLaw::Hertz { el } => format!("Hertz, {}", el.describe()),
            NormalLaw::Hysteresis {
                el,
                kind,
                restitution,
                d,
                v_floor,
            } => format!(
                "{}, {}, c_e = {restitution}, D = {d:.5}, onset-velocity floor {v_floor:e} m/s",
                kind.name(),
                el.describe()
            ),
            NormalLaw::Impact { k, n, c_max, d_max } => format!(
                "IMPACT (ADAMS), K = {k:.4e} N/m^{n}, c_max = {c_max} N s/m, d_max = {d_max:e} m"
            ),
        }
    }
}

/// Point-contact stiffness (paper eq. 49): radii in m, moduli in Pa.
pub fn point_contact_stiffness(
    r_i: f64,
    r_j: f64,
    e_i: f64,
    nu_i: f64,
    e_j: f64,
    nu_j: f64,
) -> f64 {
    let eta = |e: f64, nu: f64| (1.0 - nu * nu) / e;
    4.0 / (3.0 * (eta(e_i, nu_i) + eta(e_j, nu_j))) * (r_i * r_j / (r_i - r_j).abs()).sqrt()
}

/// The restitution an isolated impact obtains from a Hunt-Crossley-type law with damping factor
/// D: the root e in (0, 1) of (1 + D) = (1 - e D) exp(D (1 + e)) (bisection; exact to 1e-14).
pub fn hunt_crossley_restitution(d: f64) -> f64 {
    if d <= 0.0 {
        return 1.0;
    }
    let g = |e: f64| (1.0 - e * d) * (d * (1.0 + e)).exp() - (1.0 + d);
    // g(0) = e^D - 1 - D > 0 and g(min(1, 1/D)) < 0 for D > 0.
    let (mut lo, mut hi) = (0.0, (1.0f64).min(1.0 / d));
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if g(mid) > 0.0 { lo = mid } else { hi = mid }
    }
    0.5 * (lo + hi)
}

/// A compiled friction law.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum FrictionLaw {
    None,
    Coulomb {
        mu: f64,
        v_reg: f64,
    },
    Ambrosio {
        mu: f64,
        v0: f64,
        v1: f64,
    },
    Threlfall {
        mu: f64,
        v0: f64,
    },
    /// LuGre, normalised by the normal force: Coulomb and static coefficients, Stribeck velocity
    /// (m/s), bristle stiffness sigma0 (1/m), bristle damping sigma1 (s/m), viscous sigma2 (s/m).
    LuGre {
        mu_c: f64,
        mu_s: f64,
        v_s: f64,
        sigma0: f64,
        sigma1: f64,
        sigma2: f64,
    },
}

impl FrictionLaw {
    /// Whether the law carries a bristle state (LuGre): three state components per contact.
    pub fn has_bristles(&self) -> bool {
        matches!(self, FrictionLaw::LuGre { .. })
    }

    /// LuGre's bristle rate `z' = v_t - sigma0 |v_t| z / g(|v_t|)` (m/s) for deflection
    /// `z` (m) and tangential sliding velocity `vt` (m/s); zero for the other laws.
    #[inline]
    pub fn bristle_rate(&self, z: &Vector3<f64>, vt: &Vector3<f64>) -> Vector3<f64> {
        match *self {
            FrictionLaw::LuGre { sigma0, .. } => {
                let v = vt.norm();
                vt - z * (sigma0 * v / self.stribeck(v))
            }
            FrictionLaw::None
            | FrictionLaw::Coulomb { .. }
            | FrictionLaw::Ambrosio { .. }
            | FrictionLaw::Threlfall { .. } => Vector3::zeros(),
        }
    }

    /// LuGre's friction force on the journal (N, global) from the tangential parts of the
    /// deflection, its rate and the sliding velocity, for normal force `fn_` (N).
    #[inline]
    pub fn bristle_force(
        &self,
        zt: &Vector3<f64>,
        zt_dot: &Vector3<f64>,
        vt: &Vector3<f64>,
        fn_: f64,
    ) -> Vector3<f64> {
        match *self {
            FrictionLaw::LuGre {
                sigma0,
                sigma1,
                sigma2,
                ..
            } => -(zt * sigma0 + zt_dot * sigma1 + vt * sigma2) * fn_,
            FrictionLaw::None
            | FrictionLaw::Coulomb { .. }
            | FrictionLaw::Ambrosio { .. }
            | FrictionLaw::Threlfall { .. } => Vector3::zeros(),
        }
    }

    /// LuGre's g(v) = mu_c + (mu_s - mu_c) exp(-(v / v_s)^2), the coefficient of steady sliding
    /// without the viscous term (0 for the other laws).
    #[inline]
    pub fn stribeck(&self, v: f64) -> f64 {
        match *self {
            FrictionLaw::LuGre {
                mu_c, mu_s, v_s, ..
            } => mu_c + (mu_s - mu_c) * (-(v / v_s) * (v / v_s)).exp(),
            FrictionLaw::None
            | FrictionLaw::Coulomb { .. }
            | FrictionLaw::Ambrosio { .. }
            | FrictionLaw::Threlfall { .. } => 0.0,
        }
    }

    /// The friction coefficient in effect at sliding speed `v` (m/s, >= 0).
    #[inline]
    pub fn coefficient(&self, v: f64) -> f64 {
        match *self {
            FrictionLaw::None => 0.0,
            FrictionLaw::Coulomb { mu, v_reg } => mu * (v / v_reg).min(1.0),
            FrictionLaw::Ambrosio { mu, v0, v1 } => {
                if v <= v0 {
                    0.0
                } else if v >= v1 {
                    mu
                } else {
                    mu * (v - v0) / (v1 - v0)
                }
            }
            FrictionLaw::Threlfall { mu, v0 } => mu * (1.0 - (-3.0 * v / v0).exp()),
            // LuGre's coefficient in steady sliding (its Stribeck curve).
            FrictionLaw::LuGre { sigma2, .. } => self.stribeck(v) + sigma2 * v,
        }
    }

    pub fn is_none(&self) -> bool {
        matches!(self, FrictionLaw::None)
    }

    /// The sliding speeds (m/s) at which the coefficient is continuous but its slope jumps, in
    /// increasing order, and how many there are: Ambrosio's v0 and v1, the regularised Coulomb's
    /// v_reg; none for Threlfall's law (smooth) and without friction.
    pub fn kinks(&self) -> ([f64; 2], usize) {
        match *self {
            FrictionLaw::Coulomb { v_reg, .. } => ([v_reg, f64::NAN], 1),
            FrictionLaw::Ambrosio { v0, v1, .. } => ([v0, v1], 2),
            FrictionLaw::None | FrictionLaw::Threlfall { .. } | FrictionLaw::LuGre { .. } => {
                ([f64::NAN; 2], 0)
            }
        }
    }

    /// d(coefficient)/d(speed) at sliding speed `v` (s/m): the friction force `c(v) F_N` acts as
    /// a viscous damper of coefficient `F_N` times this in the tangent plane.
    pub fn slope(&self, v: f64) -> f64 {
        match *self {
            FrictionLaw::None => 0.0,
            FrictionLaw::Coulomb { mu, v_reg } => {
                if v < v_reg {
                    mu / v_reg
                } else {
                    0.0
                }
            }
            FrictionLaw::Ambrosio { mu, v0, v1 } => {
                if v > v0 && v < v1 {
                    mu / (v1 - v0)
                } else {
                    0.0
                }
            }
            FrictionLaw::Threlfall { mu, v0 } => mu * 3.0 / v0 * (-3.0 * v / v0).exp(),
            // The bristles' damping and the viscous term act as a damper of F_N (sigma1 +
            // sigma2) while presliding; the steady curve's own slope adds to the latter.
            FrictionLaw::LuGre {
                mu_c,
                mu_s,
                v_s,
                sigma1,
                sigma2,
                ..
            } => {
                let x = v / v_s;
                sigma1 + sigma2 + ((mu_s - mu_c) * 2.0 * x / v_s * (-x * x).exp()).abs()
            }
        }
    }

    pub fn describe(&self) -> String {
        match *self {
            FrictionLaw::None => "no friction".into(),
            FrictionLaw::Coulomb { mu, v_reg } => {
                format!("Coulomb, mu = {mu}, regularised below {v_reg:e} m/s")
            }
            FrictionLaw::Ambrosio { mu, v0, v1 } => {
                format!("modified Coulomb (Ambrosio), mu = {mu}, v0 = {v0:e} m/s, v1 = {v1:e} m/s")
            }
            FrictionLaw::Threlfall { mu, v0 } => format!("Threlfall, mu = {mu}, v0 = {v0:e} m/s"),
            FrictionLaw::LuGre {
                mu_c,
                mu_s,
                v_s,
                sigma0,
                sigma1,
                sigma2,
            } => format!(
                "LuGre, mu_c = {mu_c}, mu_s = {mu_s}, v_s = {v_s:e} m/s, sigma0 = {sigma0:e} 1/m, \
                 sigma1 = {sigma1:e} s/m, sigma2 = {sigma2:e} s/m (3 bristle states per contact)"
            ),
        }
    }
}

// ---------------------------------------------------------------------------------------------
// The laws' fields in the scene file (`normal = { law = "...", ... }`, `friction = { ... }`):
// each law takes exactly its own fields; compile/laws.rs validates them and builds the law.

/// Elastic contact model.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ContactModel {
    /// F = K delta^exponent, K given or from the point-contact formula (paper eq. 49).
    #[default]
    Point,
    /// Johnson's line contact of a journal in a bearing over `contact_length` (planar revolute
    /// joints; needs youngs_modulus and poisson_ratio).
    Line,
}

/// Normal-contact law of a clearance joint: `law` names it, the other fields are its own (a
/// field the law does not take is rejected). The laws and their sources are in
/// [`crate::contact`].
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(tag = "law", rename_all = "snake_case", deny_unknown_fields)]
pub enum NormalSpec {
    /// Hertz (Hertz 1882; Johnson, *Contact Mechanics*, 1985, ch. 4): the elastic force alone.
    Hertz(ElasticSpec),
    /// Lankarani & Nikravesh, J. Mech. Des. 112:369-376 (1990).
    LankaraniNikravesh(DampedSpec),
    /// Hunt & Crossley, J. Appl. Mech. 42:440-445 (1975).
    HuntCrossley(DampedSpec),
    /// Flores, Machado, Silva & Martins, Multibody Syst. Dyn. 25:357-375 (2011).
    Flores(DampedSpec),
    /// Gonthier, McPhee, Lange & Piedboeuf, Multibody Syst. Dyn. 11:209-233 (2004).
    Gonthier(DampedSpec),
    /// Carvalho & Martins, Mech. Mach. Theory 139:174-194 (2019).
    CarvalhoMartins(DampedSpec),
    /// MSC ADAMS IMPACT function: K delta^n with damping ramped up to `max_damping` over
    /// `full_damping_penetration`.
    Impact(ImpactSpec),
}

impl NormalSpec {
    /// The elastic part of the law (the whole of Hertz).
    pub fn elastic(&self) -> ElasticSpec {
        match self {
            NormalSpec::Hertz(e) => e.clone(),
            NormalSpec::LankaraniNikravesh(d)
            | NormalSpec::HuntCrossley(d)
            | NormalSpec::Flores(d)
            | NormalSpec::Gonthier(d)
            | NormalSpec::CarvalhoMartins(d) => d.elastic(),
            NormalSpec::Impact(i) => i.elastic(),
        }
    }
}

/// The elastic force of a normal law: point contact K delta^n (K given, or from youngs_modulus
/// and poisson_ratio) or line contact. The fields of `law = "hertz"`.
#[derive(Debug, Clone, Default, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct ElasticSpec {
    /// Elastic model: point (default) or line.
    #[serde(default)]
    pub contact: ContactModel,
    /// Line contact: axial length of the journal-bearing contact (m).
    #[serde(default)]
    pub contact_length: Option<f64>,
    /// Generalised stiffness K (N/m^exponent); or give youngs_modulus and poisson_ratio.
    #[serde(default)]
    pub stiffness: Option<f64>,
    /// Young's modulus of both bodies (Pa), for K from the point-contact formula.
    #[serde(default)]
    pub youngs_modulus: Option<f64>,
    /// Poisson's ratio of both bodies.
    #[serde(default)]
    pub poisson_ratio: Option<f64>,
    /// Exponent n (default 1.5, Hertz point contact).
    #[serde(default)]
    pub exponent: Option<f64>,
}

/// The fields of a hysteresis-damped law of the Hunt-Crossley family: the elastic fields of
/// [`ElasticSpec`], the coefficient of restitution and the onset-velocity floor.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct DampedSpec {
    #[serde(default)]
    pub contact: ContactModel,
    #[serde(default)]
    pub contact_length: Option<f64>,
    #[serde(default)]
    pub stiffness: Option<f64>,
    #[serde(default)]
    pub youngs_modulus: Option<f64>,
    #[serde(default)]
    pub poisson_ratio: Option<f64>,
    #[serde(default)]
    pub exponent: Option<f64>,
    /// Coefficient of restitution c_e, in (0, 1].
    #[serde(default)]
    pub restitution: Option<f64>,
    /// Floor of the onset approach velocity (m/s); default 1e-3.
    #[serde(default)]
    pub onset_velocity_floor: Option<f64>,
}

impl DampedSpec {
    /// The elastic fields.
    pub fn elastic(&self) -> ElasticSpec {
        ElasticSpec {
            contact: self.contact,
            contact_length: self.contact_length,
            stiffness: self.stiffness,
            youngs_modulus: self.youngs_modulus,
            poisson_ratio: self.poisson_ratio,
            exponent: self.exponent,
        }
    }
}

/// The fields of the IMPACT law: the elastic fields of [`ElasticSpec`] and the damping ramp.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct ImpactSpec {
    #[serde(default)]
    pub contact: ContactModel,
    #[serde(default)]
    pub contact_length: Option<f64>,
    #[serde(default)]
    pub stiffness: Option<f64>,
    #[serde(default)]
    pub youngs_modulus: Option<f64>,
    #[serde(default)]
    pub poisson_ratio: Option<f64>,
    #[serde(default)]
    pub exponent: Option<f64>,
    /// Maximum damping coefficient (N s/m).
    #[serde(default)]
    pub max_damping: Option<f64>,
    /// Penetration at which the damping reaches max_damping (m).
    #[serde(default)]
    pub full_damping_penetration: Option<f64>,
}

impl ImpactSpec {
    /// The elastic fields.
    pub fn elastic(&self) -> ElasticSpec {
        ElasticSpec {
            contact: self.contact,
            contact_length: self.contact_length,
            stiffness: self.stiffness,
            youngs_modulus: self.youngs_modulus,
            poisson_ratio: self.poisson_ratio,
            exponent: self.exponent,
        }
    }
}

/// Friction law of a clearance joint.
#[derive(Debug, Clone, Default, Deserialize, Serialize)]
#[serde(tag = "law", rename_all = "snake_case", deny_unknown_fields)]
pub enum FrictionSpec {
    #[default]
    None,
    /// Coulomb, regularised linearly below `regularisation_velocity` (m/s).
    Coulomb {
        coefficient: f64,
        regularisation_velocity: f64,
    },
    /// Ambrosio's modified Coulomb: no friction below v0, full above v1 (m/s).
    Ambrosio { coefficient: f64, v0: f64, v1: f64 },
    /// Threlfall: mu (1 - exp(-3 |v| / v0)).
    Threlfall { coefficient: f64, v0: f64 },
    /// LuGre normalised by the normal force: Coulomb `coefficient`, `static_coefficient`,
    /// `stribeck_velocity` (m/s), `bristle_stiffness` sigma0 (1/m), `bristle_damping` sigma1
    /// (s/m), `viscous` sigma2 (s/m).
    #[serde(rename = "lugre")]
    LuGre {
        coefficient: f64,
        static_coefficient: f64,
        stribeck_velocity: f64,
        bristle_stiffness: f64,
        #[serde(default)]
        bristle_damping: f64,
        #[serde(default)]
        viscous: f64,
    },
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn paper_stiffness_values() {
        // clearance-geometry notes: K = 1.326e11 (sphere, Rb = 15 mm, c = 0.3 mm) and 8.62e10
        // N/m^1.5 (revolute, R_B1 = 10 mm, C_r = 0.3 mm), E = 207 GPa, nu = 0.3; 4 digits quoted.
        let k = point_contact_stiffness(0.015, 0.0153, 207e9, 0.3, 207e9, 0.3);
        assert!((k / 1.326e11 - 1.0).abs() < 5e-4, "{k:e}");
        let k = point_contact_stiffness(0.0097, 0.010, 207e9, 0.3, 207e9, 0.3);
        assert!((k / 8.62e10 - 1.0).abs() < 1e-3, "{k:e}");
    }

    #[test]
    fn restitution_relation_matches_known_values() {
        // ce = 0.9 with Lankarani-Nikravesh restores about 0.913 (the value usually quoted).
        let e = hunt_crossley_restitution(Damping::LankaraniNikravesh.factor(0.9));
        assert!((e - 0.913).abs() < 5e-4, "{e}");
        // Small damping: e = 1 - 2D/3 + O(D^2), which is Hunt & Crossley's own derivation.
        let e = hunt_crossley_restitution(1e-4);
        assert!((e - (1.0 - 2e-4 / 3.0)).abs() < 1e-8);
        // Carvalho-Martins' approximation reproduces c_e to 2e-4 for c_e >= 0.5.
        for ce in [0.5, 0.7, 0.9, 0.95] {
            let e = hunt_crossley_restitution(Damping::CarvalhoMartins.factor(ce));
            assert!((e - ce).abs() < 2e-4, "ce {ce}: {e}");
        }
    }

    #[test]
    fn normal_force_is_never_negative() {
        let law = NormalLaw::Hysteresis {
            el: Elastic::Power { k: 1e10, n: 1.5 },
            kind: Damping::LankaraniNikravesh,
            restitution: 0.5,
            d: Damping::LankaraniNikravesh.factor(0.5),
            v_floor: 1e-4,
        };
        // Fast separation at small penetration would make the damped law pull.
        assert_eq!(law.force(1e-7, -10.0, 0.01), 0.0);
        assert!(law.force(1e-7, 0.01, 0.01) > 0.0);
        let imp = NormalLaw::Impact {
            k: 1e10,
            n: 1.5,
            c_max: 1e5,
            d_max: 1e-6,
        };
        assert_eq!(imp.force(2e-6, -10.0, 0.0), 0.0);
        assert_eq!(imp.force(-1e-6, 1.0, 0.0), 0.0);
        // No damping at first touch: STEP(0) = 0.
        assert_eq!(step(0.0, 0.0, 0.0, 1e-6, 1e5), 0.0);
        assert_eq!(step(1e-6, 0.0, 0.0, 1e-6, 1e5), 1e5);
    }

    #[test]
    fn johnson_line_contact_inverts_its_own_relation() {
        let dr = 3e-4;
        let el = Elastic::CylinderLine {
            c: std::f64::consts::PI * 0.02 * 1.137e11,
            dr,
        };
        for f in [1.0, 1e2, 1e4, 1e6] {
            // delta from the explicit relation, then the force back from the inversion.
            let x = f / (std::f64::consts::PI * 0.02 * 1.137e11);
            let delta = x * ((4.0 * dr / x).ln() - 1.0);
            let back = el.force(delta);
            assert!(((back - f) / f).abs() < 1e-12, "F = {f}: {back}");
            // Energy is the integral of the force (midpoint rule, 1e4 intervals).
            let n = 10000;
            let num: f64 = (0..n)
                .map(|i| el.force((i as f64 + 0.5) * delta / n as f64) * delta / n as f64)
                .sum();
            assert!(
                ((el.energy(delta) - num) / num).abs() < 1e-6,
                "{} vs {num}",
                el.energy(delta)
            );
        }
        // Monotone through the validity limit.
        let mut last = 0.0;
        for k in 1..400 {
            let f = el.force(k as f64 * 1e-6);
            assert!(f > last);
            last = f;
        }
    }

    #[test]
    fn friction_is_bounded_and_vanishes_below_v0() {
        let laws = [
            FrictionLaw::Coulomb {
                mu: 0.05,
                v_reg: 1e-3,
            },
            FrictionLaw::Ambrosio {
                mu: 0.05,
                v0: 1e-4,
                v1: 1e-2,
            },
            FrictionLaw::Threlfall { mu: 0.05, v0: 1e-3 },
        ];
        for law in laws {
            for k in 0..200 {
                let v = 1e-7 * 1.1f64.powi(k);
                let c = law.coefficient(v);
                assert!((0.0..=0.05).contains(&c), "{law:?} at {v}: {c}");
            }
        }
        assert_eq!(laws[1].coefficient(0.9e-4), 0.0);
        assert_eq!(laws[1].coefficient(0.02), 0.05);
        assert!((laws[1].coefficient(5.05e-3) - 0.025).abs() < 1e-12);
    }
}
