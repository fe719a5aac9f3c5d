//! Lubricated journal bearings: the hydrodynamic force of the oil film between a journal and its
//! bearing, from the eccentricity, its rate and the two bodies' spins, in the short-bearing
//! (Ocvirk) and the long-bearing (Sommerfeld) solutions of Reynolds' equation.
//!
//! # The short bearing (Ocvirk)
//!
//! For a bearing of length `L`, journal radius `R` and radial clearance `c` filled with oil of
//! dynamic viscosity `mu` (Pa s), the film thickness at the angle `theta` measured from the
//! thickest point, in the sense of the bearing axis `a`, is `h = c (1 + eps cos theta)` with the
//! eccentricity ratio `eps = |e| / c`. Dropping the circumferential pressure flow beside the axial
//! one (valid for `L/D` below about 0.5; Ocvirk 1952), Reynolds' equation in the frame turning
//! with the line of centres at the rate `gamma'` integrates in the axial coordinate `z` to
//!
//! ```text
//! p(theta, z) = 3 mu / c^2 (L^2/4 - z^2) (eps w sin theta - 2 eps' cos theta) / (1 + eps cos theta)^3
//! ```
//!
//! with the effective wedge speed `w = omega_journal + omega_bearing - 2 gamma'` (the spins about
//! `a`, rad/s) and the squeeze rate `eps'` (Hamrock, Schmid, Jacobson, *Fundamentals of Fluid
//! Film Lubrication*, 2nd ed., ch. 18; Flores, Ambrosio, Claro, Lankarani, Mech. Mach. Theory 41
//! (2006) 247-261). The oil cannot hold a tension: the film cavitates where `p < 0` (the
//! half-Sommerfeld or Gumbel condition). Where it does is found here, not assumed: the bracket
//! is `A sin(theta - theta0)` with `A cos theta0 = eps w`, `A sin theta0 = 2 eps'`, so the film
//! carries pressure on exactly the half circle `theta0 < theta < theta0 + pi`, which turns with
//! the squeeze as Daniel, Machado and Cavalca (Mech. Mach. Theory 99 (2016) 19-36) show it must.
//! The fixed "pi-film" of the classical formulas (`0 < theta < pi`) is the case `eps' = 0`.
//!
//! The force on the journal, `F = R int int p (cos theta n + sin theta t) dtheta dz` with `n`
//! the unit eccentricity and `t = a x n`, is then
//!
//! ```text
//! F = mu R L^3 / (2 c^2) [ (eps w I_sc - 2 eps' I_cc) n + (eps w I_ss - 2 eps' I_sc) t ]
//! ```
//!
//! where `I_xy` are the integrals of `cos^2`, `sin cos` and `sin^2` over `(1 + eps cos theta)^3`
//! across the pressure zone. Sommerfeld's substitution `cos psi = (eps + cos theta) / (1 + eps
//! cos theta)` makes them polynomials in `psi` (with `b = sqrt(1 - eps^2)`):
//! `I_ss = [psi/2 - sin 2psi / 4] / b^3`, `I_sc = [sin^2 psi / 2 + eps cos psi] / b^4`,
//! `I_cc = [psi (1/2 + eps^2) + sin 2psi / 4 - 2 eps sin psi] / b^5`. The force acts at the
//! journal centre, and the bearing takes the opposite force on the same line. For a steadily loaded
//! journal (`eps' = gamma' = 0`, bearing at rest) they give the classical load components
//! `mu U L^3 / c^2 eps^2 / (1 - eps^2)^2` along the line of centres and
//! `mu U L^3 / c^2 pi eps / (4 (1 - eps^2)^(3/2))` across it (`U = omega R`) and the attitude
//! angle `tan phi = pi sqrt(1 - eps^2) / (4 eps)`.
//!
//! Written in the vectors `e`, `e'` (the eccentricity and its rate in the bearing plane) the
//! bracket's coefficients are `eps w = eps (omega_j + omega_b) - 2 (e' . t) / c` and
//! `2 eps' = 2 (e' . n) / c`, which stay finite at `e = 0`; there the force is
//! `-pi mu R L^3 / (2 c^3) e'` whatever direction `n` is given, so the force is continuous
//! through the concentric position. With the spins at rest the film only dissipates:
//! `F . e' = -mu R L^3 / c^3 int (e'_n cos theta + e'_t sin theta)^2 / (1 + eps cos theta)^3 <= 0`
//! over the pressure zone.
//!
//! # The long bearing (Sommerfeld)
//!
//! For a long bearing (`L/D` above about 4) the axial flow is the one dropped: Reynolds'
//! equation in the same frame, `(1/R^2) d/dtheta (h^3 dp/dtheta) = -6 mu c (eps w sin theta -
//! 2 eps' cos theta)`, integrates in `theta`. A periodic pressure fixes the constant of the
//! first integration, and the pressure referred to the ambient at the thickest film (`p = 0` at
//! `theta = 0`, Sommerfeld's reference; Pinkus and Sternlicht, *Theory of Hydrodynamic
//! Lubrication*, 1961, ch. 3 and 14) is
//!
//! ```text
//! p = 6 mu R^2 / c^2 [ eps w sin theta (2 + eps cos theta) / ((2 + eps^2) D^2)
//!                      + eps' (1 - cos theta)(2 + eps + eps cos theta) / ((1 + eps)^2 D^2) ]
//! ```
//!
//! with `D = 1 + eps cos theta` (the squeeze term is `(eps'/eps) (1/D^2 - 1/(1 + eps)^2)`
//! written without the cancellation at small `eps`). As for the short bearing the film
//! cavitates where `p < 0`, and where that is is found from the pressure's sign: besides the
//! reference it vanishes at exactly one angle more ([`long_integrals`]), so the film is an arc
//! from the reference to that angle, on the side the wedge drives oil into; pure squeeze fills
//! the whole film (approach) or none of it (separation). The force on the journal is
//! `6 mu R^3 L / c^2 (J_n n + J_t t)` with the arc's integrals in closed form. A steadily loaded
//! journal carries the classical half-Sommerfeld load, `12 mu omega R^3 L eps^2 / (c^2 (2 +
//! eps^2)(1 - eps^2))` along the line of centres and `6 pi mu omega R^3 L eps / (c^2 (2 +
//! eps^2) sqrt(1 - eps^2))` across it, attitude `tan phi = pi sqrt(1 - eps^2) / (2 eps)`; a
//! journal squeezed without spin meets the full film's `12 pi mu R^3 L eps' / (c^2 (1 -
//! eps^2)^(3/2))` (Hamrock, Schmid, Jacobson, ch. 10 and 17); without spin the film only
//! dissipates, as the tests check.
//!
//! The reference makes the long film depend on where the thickest point is, which is not
//! defined at the concentric position: there the force of a journal moving at `e'` is the full
//! squeeze film's `-12 pi mu R^3 L / c^3 e'` (the unit eccentricity taken along `e'`), while a
//! journal passing close by the centre on a line feels no film on its way in and the full one
//! on its way out. The short film, whose pressure needs no reference, is continuous there.
//! Multibody papers that use the long bearing (Flores et al. 2006, 2009) integrate its
//! pressure over the fixed arc `0 < theta < pi` instead, wedge and squeeze alike; that arc is
//! the one found here only for `eps' = 0`.
//!
//! # Towards the wall
//!
//! The film force grows without bound as `eps -> 1`: a real film breaks down into asperity
//! contact first. Above `eccentricity_limit` (default 0.95) the film force is evaluated at the
//! limit (its coefficients frozen, still in the current direction and rates), and when the journal
//! reaches the wall the joint's dry normal and friction laws act on the penetration as in a dry
//! joint: film and asperity contact add, as Flores et al. (Nonlinear Dyn. 56 (2009) 277-295) do,
//! and the force stays continuous so the integrators need no event at the transition.
//!
//! What is left out: the viscous shear torque on the journal (Petroff's term), the tilting
//! moments of a misaligned journal in a spatial bearing (its film acts on the eccentricity of the
//! journal centre in the plane normal to the bearing axis), inertia of the oil, thermal effects.

use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

/// The film models.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum FilmModel {
    /// Ocvirk's short bearing with the half-Sommerfeld (Gumbel) cavitation zone found from the
    /// pressure's sign.
    #[default]
    Short,
    /// Sommerfeld's infinitely long bearing, the pressure referred to the ambient at the
    /// thickest film and cut where it is negative (half-Sommerfeld).
    Long,
}

impl FilmModel {
    pub fn name(self) -> &'static str {
        match self {
            FilmModel::Short => "short",
            FilmModel::Long => "long",
        }
    }
}

/// The default of the scene's `eccentricity_limit` (`crate::scene::LubricationSpec`).
pub const DEFAULT_ECCENTRICITY_LIMIT: f64 = 0.95;

/// A compiled oil film.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Film {
    pub model: FilmModel,
    /// Pa s.
    pub viscosity: f64,
    /// Bearing length, journal radius, radial clearance (m).
    pub length: f64,
    pub radius: f64,
    pub clearance: f64,
    pub eccentricity_limit: f64,
}

impl Film {
    /// The force of the film on the journal (N, global), from the eccentricity `e` of the
    /// journal centre from the bearing centre and its rate `e_dot` (both normal to the unit
    /// bearing axis `a`; m, m/s) and the sum of the journal's and the bearing's spins about `a`
    /// (rad/s). The bearing feels the opposite force.
    pub fn force(
        &self,
        e: &Vector3<f64>,
        e_dot: &Vector3<f64>,
        a: &Vector3<f64>,
        spin: f64,
    ) -> Vector3<f64> {
        let c = self.clearance;
        let d = e.norm();
        // The unit eccentricity; at the concentric position any direction in the plane gives
        // the same force (module docs), the rate's if it has one.
        let n = if d > 1e-12 * c {
            e / d
        } else {
            let v = e_dot - a * e_dot.dot(a);
            if v.norm() > 0.0 {
                v.normalize()
            } else {
                return Vector3::zeros();
            }
        };
        let t = a.cross(&n);
        let eps = (d / c).min(self.eccentricity_limit);
        let wedge = eps * spin - 2.0 * e_dot.dot(&t) / c;
        let squeeze = 2.0 * e_dot.dot(&n) / c;
        let (fn_, ft) = match self.model {
            FilmModel::Short => {
                let [i_cc, i_sc, i_ss] = zone_integrals(eps, squeeze.atan2(wedge));
                let k = self.viscosity * self.radius * self.length.powi(3) / (2.0 * c * c);
                (
                    k * (wedge * i_sc - squeeze * i_cc),
                    k * (wedge * i_ss - squeeze * i_sc),
                )
            }
            FilmModel::Long => {
                let [jn, jt] = long_integrals(eps, wedge, 0.5 * squeeze);
                let k = 6.0 * self.viscosity * self.radius.powi(3) * self.length / (c * c);
                (k * jn, k * jt)
            }
        };
        n * fn_ + t * ft
    }

    /// The film's stiffness `k = -dF_n/de_n` (N/m) and damping `c = -dF_n/de'_n` (N s/m)
    /// along the unit eccentricity `n` (returned with them; any normal to `a` at the centre),
    /// by central differences of [`Film::force`] (steps of 1e-6 of the clearance and of the
    /// rate's scale): what the step-size guard linearises a film with. The force is smooth in
    /// both below the eccentricity limit, so the differences are accurate to about 1e-10
    /// relative there.
    pub fn linearised(
        &self,
        e: &Vector3<f64>,
        e_dot: &Vector3<f64>,
        a: &Vector3<f64>,
        spin: f64,
    ) -> (f64, f64, Vector3<f64>) {
        let c = self.clearance;
        let d = e.norm();
        let n = if d > 1e-12 * c {
            e / d
        } else {
            crate::kin::any_normal(a)
        };
        let along = |f: Vector3<f64>| f.dot(&n);
        let h = 1e-6 * c;
        let k = -(along(self.force(&(e + n * h), e_dot, a, spin))
            - along(self.force(&(e - n * h), e_dot, a, spin)))
            / (2.0 * h);
        let hv = 1e-6 * (e_dot.norm() + c * spin.abs()).max(1e-3 * c);
        let damping = -(along(self.force(e, &(e_dot + n * hv), a, spin))
            - along(self.force(e, &(e_dot - n * hv), a, spin)))
            / (2.0 * hv);
        (k, damping, n)
    }

    /// `check`'s line for the film.
    pub fn describe(&self) -> String {
        format!(
            "lubricated, {} bearing: viscosity {} Pa s, length {} m (L/D = {:.3}), film held above eccentricity ratio {}",
            self.model.name(),
            self.viscosity,
            self.length,
            self.length / (2.0 * self.radius),
            self.eccentricity_limit
        )
    }
}

/// Sommerfeld's angle psi of the film angle `theta`, `cos psi = (eps + cos theta) / (1 + eps cos
/// theta)`, continued through every turn: `psi = theta - 2 atan(beta sin theta / (1 + beta cos
/// theta))` with `beta = eps / (1 + b)`. The denominator stays above `1 - beta > 0`, so there is
/// no branch to choose and psi(k pi) = k pi exactly (a form through `atan2` and a count of
/// turns jumps by 2 pi one rounding away from an odd multiple of pi).
fn sommerfeld(eps: f64, b: f64, theta: f64) -> f64 {
    let beta = eps / (1.0 + b);
    theta - 2.0 * (beta * theta.sin() / (1.0 + beta * theta.cos())).atan()
}

/// `[I_cc, I_sc, I_ss]`: the integrals of `cos^2`, `sin cos`, `sin^2` over
/// `(1 + eps cos theta)^3` for `theta0 < theta < theta0 + pi` (module docs).
pub fn zone_integrals(eps: f64, theta0: f64) -> [f64; 3] {
    let b = (1.0 - eps * eps).sqrt();
    let p0 = sommerfeld(eps, b, theta0);
    let p1 = sommerfeld(eps, b, theta0 + std::f64::consts::PI);
    let cc = |p: f64| p * (0.5 + eps * eps) + 0.25 * (2.0 * p).sin() - 2.0 * eps * p.sin();
    let sc = |p: f64| 0.5 * p.sin().powi(2) + eps * p.cos();
    let ss = |p: f64| 0.5 * p - 0.25 * (2.0 * p).sin();
    let (b3, b4, b5) = (b * b * b, b * b * b * b, b * b * b * b * b);
    [
        (cc(p1) - cc(p0)) / b5,
        (sc(p1) - sc(p0)) / b4,
        (ss(p1) - ss(p0)) / b3,
    ]
}

/// `[J_n, J_t]`: the long bearing's pressure shape `P` (module docs) times `cos theta` and
/// `sin theta`, integrated over the zone where it is positive, for the eccentricity ratio `eps`,
/// the wedge `W = eps w` and the squeeze rate `S = eps'`.
///
/// `P D^2` (with `D = 1 + eps cos theta`) is `Q = A sin theta (2 + eps cos theta) + B (1 - cos
/// theta)(2 + eps + eps cos theta)`, `A = W / (2 + eps^2)`, `B = S / (1 + eps)^2`. In the half
/// angle `phi = theta / 2`, `Q = 2 sin phi (1 + eps cos^2 phi) sin phi (A f(phi) + 2 B)` with
/// `f = cot phi (2 - eps + 2 eps cos^2 phi) / (1 + eps cos^2 phi)`, which falls strictly from
/// `+inf` to `-inf` on `(0, pi)` (its derivative is `-g / sin^2 phi - 2 eps^2 cos^2 phi / (1 +
/// eps cos^2 phi)^2` with `g > 0`). So `Q` vanishes at `theta = 0` (the reference) and at one
/// `theta* = 2 phi*` more, and the zone is `(0, theta*)` for `A > 0`, `(theta*, 2 pi)` for
/// `A < 0`, the whole film for `A = 0 < B` and none for `A = 0 >= B`. In `u = cot phi`, `f(u) =
/// u (2 - eps + (2 + eps) u^2) / (1 + (1 + eps) u^2)`, whose ratio to `u` lies between 1 and 2,
/// so the root of `f(u) = -2B/A` is bracketed by `[y/2, y]` and found by Newton's method kept
/// inside its bracket.
///
/// The integrals have closed antiderivatives, in the continued Sommerfeld angle `psi` (`dpsi /
/// dtheta = b / D`, `b = sqrt(1 - eps^2)`) and rational functions that stay finite as `eps -> 0`:
///
/// ```text
/// int sin cos (2 + eps cos) / D^2          = -cos^2 / D
/// int sin^2 (2 + eps cos) / D^2            = psi / b - sin cos / D
/// int cos (1 - cos)(2 + eps + eps cos) / D^2 = -(1 + eps)/(1 - eps) psi / b + 2/(1 - eps) sin / D - sin cos / D
/// int sin (1 - cos)(2 + eps + eps cos) / D^2 = (1 - cos)^2 / D
/// ```
///
/// (each checked by differentiation, and in the tests against the pressure integrated by
/// brute force).
pub fn long_integrals(eps: f64, wedge: f64, squeeze_rate: f64) -> [f64; 2] {
    use std::f64::consts::TAU;
    let a = wedge / (2.0 + eps * eps);
    let bq = squeeze_rate / ((1.0 + eps) * (1.0 + eps));
    let (from, to) = if a == 0.0 {
        if bq > 0.0 {
            (0.0, TAU)
        } else {
            return [0.0, 0.0];
        }
    } else {
        let y = -2.0 * bq / a;
        let f = |u: f64| u * (2.0 - eps + (2.0 + eps) * u * u) / (1.0 + (1.0 + eps) * u * u);
        let (mut lo, mut hi) = if y >= 0.0 { (0.5 * y, y) } else { (y, 0.5 * y) };
        let mut u = 0.5 * (lo + hi);
        for _ in 0..100 {
            let r = f(u) - y;
            if r == 0.0 {
                break;
            }
            if r > 0.0 {
                hi = u;
            } else {
                lo = u;
            }
            // f' from the quotient rule; Newton's step, or bisection when it leaves the bracket.
            let (num, den) = (
                u * (2.0 - eps + (2.0 + eps) * u * u),
                1.0 + (1.0 + eps) * u * u,
            );
            let dnum = 2.0 - eps + 3.0 * (2.0 + eps) * u * u;
            let dden = 2.0 * (1.0 + eps) * u;
            let slope = (dnum * den - num * dden) / (den * den);
            let next = u - r / slope;
            let next = if next > lo && next < hi && slope > 0.0 {
                next
            } else {
                0.5 * (lo + hi)
            };
            if (next - u).abs() <= 1e-15 * u.abs().max(f64::MIN_POSITIVE) {
                u = next;
                break;
            }
            u = next;
        }
        let theta = 2.0 * 1.0f64.atan2(u);
        if a > 0.0 { (0.0, theta) } else { (theta, TAU) }
    };
    let b = (1.0 - eps * eps).sqrt();
    let at = |th: f64| {
        let (s, c) = th.sin_cos();
        let d = 1.0 + eps * c;
        let psi_b = sommerfeld(eps, b, th) / b;
        [
            -c * c / d,
            psi_b - s * c / d,
            -(1.0 + eps) / (1.0 - eps) * psi_b + 2.0 / (1.0 - eps) * s / d - s * c / d,
            (1.0 - c) * (1.0 - c) / d,
        ]
    };
    let (p, q) = (at(from), at(to));
    let d = |k: usize| q[k] - p[k];
    [a * d(0) + bq * d(2), a * d(1) + bq * d(3)]
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    fn film() -> Film {
        Film {
            model: FilmModel::Short,
            viscosity: 0.04,
            length: 0.02,
            radius: 0.02,
            clearance: 1e-4,
            eccentricity_limit: 0.99,
        }
    }

    /// The pressure integrated by brute force: the film's force on the journal from `p` on a
    /// fine grid in theta (its positive part), against the closed form. The grid sum is
    /// Simpson's rule on 20 000 panels of a smooth integrand except at the two zero crossings of
    /// `p`, where `max(p, 0)` has a kink: the error there is O(h^2 p') ~ 1e-8 relative, so 1e-6
    /// checks the closed form (the substitution, the zone, the signs) to far below any physical
    /// tolerance.
    fn by_quadrature(f: &Film, e: Vector3<f64>, ed: Vector3<f64>, spin: f64) -> Vector3<f64> {
        let a = Vector3::z();
        let c = f.clearance;
        let d = e.norm();
        let n = e / d;
        let t = a.cross(&n);
        let eps = d / c;
        // gamma' from the rate across the line of centres.
        let gamma_dot = ed.dot(&t) / d;
        let w = spin - 2.0 * gamma_dot;
        let eps_dot = ed.dot(&n) / c;
        let m = 20_000;
        let h = 2.0 * PI / m as f64;
        let mut s = Vector3::zeros();
        for i in 0..=m {
            let th = i as f64 * h;
            let g =
                (eps * w * th.sin() - 2.0 * eps_dot * th.cos()) / (1.0 + eps * th.cos()).powi(3);
            // z-integrated pressure: mu L^3 / (2 c^2) g.
            let p = (f.viscosity * f.length.powi(3) / (2.0 * c * c) * g).max(0.0);
            let wgt = if i == 0 || i == m {
                1.0
            } else if i % 2 == 1 {
                4.0
            } else {
                2.0
            };
            s += (n * th.cos() + t * th.sin()) * (wgt * p);
        }
        s * (f.radius * h / 3.0)
    }

    #[test]
    fn the_closed_form_is_the_pressure_integrated() {
        let f = film();
        let cases = [
            // steady, squeezing in, squeezing out, whirling against the spin, spin reversed,
            // squeeze-dominated.
            ([0.6e-4, 0.2e-4, 0.0], [0.0, 0.0, 0.0], 100.0),
            ([0.3e-4, -0.5e-4, 0.0], [1e-3, -2e-3, 0.0], 50.0),
            ([-0.7e-4, 0.1e-4, 0.0], [3e-3, 1e-3, 0.0], 20.0),
            ([0.2e-4, 0.2e-4, 0.0], [-4e-3, 4e-3, 0.0], 80.0),
            ([0.5e-4, 0.0, 0.0], [0.0, 1e-3, 0.0], -60.0),
            ([0.1e-4, 0.85e-4, 0.0], [-0.05, 0.01, 0.0], 1.0),
        ];
        for (e, ed, spin) in cases {
            let (e, ed) = (Vector3::from(e), Vector3::from(ed));
            let got = f.force(&e, &ed, &Vector3::z(), spin);
            let want = by_quadrature(&f, e, ed, spin);
            assert!(
                (got - want).norm() <= 1e-6 * want.norm(),
                "e {e:?} e' {ed:?} spin {spin}: {got:?} against {want:?}"
            );
        }
    }

    /// Hamrock's steady short-bearing load and attitude angle (module docs), to rounding.
    #[test]
    fn a_steady_journal_carries_ocvirks_load() {
        let f = film();
        let (omega, c) = (100.0, f.clearance);
        for eps in [0.1, 0.5, 0.8, 0.95] {
            let e = Vector3::new(eps * c, 0.0, 0.0);
            let force = f.force(&e, &Vector3::zeros(), &Vector3::z(), omega);
            let k = f.viscosity * omega * f.radius * f.length.powi(3) / (c * c);
            let wr = k * eps * eps / (1.0 - eps * eps).powi(2);
            let wt = k * PI * eps / (4.0 * (1.0 - eps * eps).powf(1.5));
            assert!((force.x + wr).abs() <= 1e-12 * wr, "{eps}: {force:?}");
            assert!((force.y - wt).abs() <= 1e-12 * wt, "{eps}: {force:?}");
            let phi = (force.y / -force.x).atan();
            let want = (PI * (1.0 - eps * eps).sqrt() / (4.0 * eps)).atan();
            assert!((phi - want).abs() < 1e-12, "{eps}: {phi} against {want}");
        }
    }

    /// Without spin the film takes energy out: F . e' <= 0 (module docs), over a spread of
    /// positions and rates, whirling ones included, in both models.
    #[test]
    fn without_spin_the_film_only_dissipates() {
        for f in [film(), long_film()] {
            dissipates(&f);
        }
    }

    fn dissipates(f: &Film) {
        let c = f.clearance;
        for i in 0..400 {
            let x = i as f64;
            let eps = 0.97 * ((x * 0.37).sin() * 0.5 + 0.5);
            let ang = x * 1.3;
            let e = Vector3::new(ang.cos(), ang.sin(), 0.0) * (eps * c);
            let ed = Vector3::new((x * 0.71).cos(), (x * 0.53).sin(), 0.0) * 1e-2;
            let p = f.force(&e, &ed, &Vector3::z(), 0.0).dot(&ed);
            assert!(p <= 1e-15, "{:?}, case {i}: power {p}", f.model);
        }
    }

    /// At the concentric position the film resists the approach isotropically, and the force
    /// tends to that value as the journal leaves the centre in any direction.
    #[test]
    fn the_force_is_continuous_through_the_centre() {
        let f = film();
        let ed = Vector3::new(2e-3, -1e-3, 0.0);
        let k = PI * f.viscosity * f.radius * f.length.powi(3) / (2.0 * f.clearance.powi(3));
        let at = f.force(&Vector3::zeros(), &ed, &Vector3::z(), 0.0);
        assert!((at + ed * k).norm() <= 1e-12 * (ed * k).norm(), "{at:?}");
        for ang in [0.0, 1.0, 2.5, 4.0] {
            let e = Vector3::new(f64::cos(ang), f64::sin(ang), 0.0) * 1e-11;
            let near = f.force(&e, &ed, &Vector3::z(), 0.0);
            assert!(
                (near - at).norm() <= 1e-6 * at.norm(),
                "{ang}: {near:?} against {at:?}"
            );
        }
    }

    /// At the centre the linearisation is the pure squeeze damper of the module docs, and
    /// without spin no stiffness; in steady running the stiffness is positive and rises with
    /// the eccentricity.
    #[test]
    fn the_linearised_film_is_the_squeeze_damper_at_the_centre() {
        let f = film();
        let (k, c, _) = f.linearised(&Vector3::zeros(), &Vector3::zeros(), &Vector3::z(), 0.0);
        let want = PI * f.viscosity * f.radius * f.length.powi(3) / (2.0 * f.clearance.powi(3));
        assert!(
            k.abs() <= 1e-9 * want && (c - want).abs() <= 1e-6 * want,
            "{k} {c} {want}"
        );
        let stiff = |eps: f64| {
            let e = Vector3::new(eps * f.clearance, 0.0, 0.0);
            f.linearised(&e, &Vector3::zeros(), &Vector3::z(), 100.0).0
        };
        assert!(0.0 < stiff(0.3) && stiff(0.3) < stiff(0.6) && stiff(0.6) < stiff(0.9));
    }

    /// The zone's ends at and next to odd multiples of pi (steady running with a squeeze of
    /// either sign at rounding level, or a reversed spin): the integrals are continuous there.
    #[test]
    fn the_zone_integrals_are_continuous_at_the_half_turns() {
        for eps in [0.0, 0.5, 0.9] {
            for theta0 in [0.0, PI, -PI] {
                let at = zone_integrals(eps, theta0);
                for near in [
                    theta0 - 4e-16,
                    theta0 + 4e-16,
                    theta0.next_down(),
                    theta0.next_up(),
                ] {
                    let got = zone_integrals(eps, near);
                    for k in 0..3 {
                        assert!(
                            (got[k] - at[k]).abs() <= 1e-12 * (1.0 + at[k].abs()),
                            "eps {eps}, theta0 {near:e}: {got:?} against {at:?}"
                        );
                    }
                }
            }
        }
    }

    fn long_film() -> Film {
        Film {
            model: FilmModel::Long,
            ..film()
        }
    }

    /// The long bearing's pressure (module docs) integrated by brute force, as
    /// [`by_quadrature`] does the short one's (the same rule, grid and tolerance argument).
    fn long_by_quadrature(f: &Film, e: Vector3<f64>, ed: Vector3<f64>, spin: f64) -> Vector3<f64> {
        let a = Vector3::z();
        let c = f.clearance;
        let d = e.norm();
        let n = e / d;
        let t = a.cross(&n);
        let eps = d / c;
        let w = spin - 2.0 * ed.dot(&t) / d;
        let eps_dot = ed.dot(&n) / c;
        let m = 20_000;
        let h = 2.0 * PI / m as f64;
        let mut s = Vector3::zeros();
        for i in 0..=m {
            let th = i as f64 * h;
            let dd = 1.0 + eps * th.cos();
            let shape = eps * w * th.sin() * (2.0 + eps * th.cos()) / ((2.0 + eps * eps) * dd * dd)
                + eps_dot / eps * (1.0 / (dd * dd) - 1.0 / ((1.0 + eps) * (1.0 + eps)));
            let p = (6.0 * f.viscosity * f.radius * f.radius / (c * c) * shape).max(0.0);
            let wgt = if i == 0 || i == m {
                1.0
            } else if i % 2 == 1 {
                4.0
            } else {
                2.0
            };
            s += (n * th.cos() + t * th.sin()) * (wgt * p);
        }
        s * (f.radius * f.length * h / 3.0)
    }

    #[test]
    fn the_long_bearings_closed_form_is_its_pressure_integrated() {
        let f = long_film();
        let cases = [
            ([0.6e-4, 0.2e-4, 0.0], [0.0, 0.0, 0.0], 100.0),
            ([0.3e-4, -0.5e-4, 0.0], [1e-3, -2e-3, 0.0], 50.0),
            ([-0.7e-4, 0.1e-4, 0.0], [3e-3, 1e-3, 0.0], 20.0),
            ([0.2e-4, 0.2e-4, 0.0], [-4e-3, 4e-3, 0.0], 80.0),
            ([0.5e-4, 0.0, 0.0], [0.0, 1e-3, 0.0], -60.0),
            ([0.1e-4, 0.85e-4, 0.0], [-0.05, 0.01, 0.0], 1.0),
            // squeezing in with no spin (the whole film), squeezing out (none but the wedge).
            ([0.4e-4, 0.3e-4, 0.0], [4e-3, 3e-3, 0.0], 0.0),
            ([0.4e-4, 0.3e-4, 0.0], [-4e-3, -2e-3, 0.0], 0.0),
            ([0.02e-4, 0.0, 0.0], [1e-4, 3e-3, 0.0], 10.0),
        ];
        for (e, ed, spin) in cases {
            let (e, ed) = (Vector3::from(e), Vector3::from(ed));
            let got = f.force(&e, &ed, &Vector3::z(), spin);
            let want = long_by_quadrature(&f, e, ed, spin);
            assert!(
                (got - want).norm() <= 1e-6 * want.norm().max(1e-9),
                "e {e:?} e' {ed:?} spin {spin}: {got:?} against {want:?}"
            );
        }
    }

    /// The half-Sommerfeld long bearing's steady load and attitude (Hamrock, Schmid, Jacobson,
    /// *Fundamentals of Fluid Film Lubrication*, 2nd ed., ch. 10: `W_r = 12 mu omega R^3 L eps^2 /
    /// (c^2 (2 + eps^2)(1 - eps^2))`, `W_t = 6 pi mu omega R^3 L eps / (c^2 (2 + eps^2)
    /// sqrt(1 - eps^2))`, `tan phi = pi sqrt(1 - eps^2) / (2 eps)`), to rounding; and the full
    /// film's pure-squeeze load `12 pi mu R^3 L eps' / (c^2 (1 - eps^2)^(3/2))`, along the line
    /// of centres, against the approach.
    #[test]
    fn a_long_bearing_carries_sommerfelds_load_and_squeeze() {
        let f = long_film();
        let (omega, c) = (100.0, f.clearance);
        let k = f.viscosity * f.radius.powi(3) * f.length / (c * c);
        for eps in [0.01, 0.1, 0.5, 0.8, 0.95] {
            let e = Vector3::new(eps * c, 0.0, 0.0);
            let force = f.force(&e, &Vector3::zeros(), &Vector3::z(), omega);
            let wr = k * omega * 12.0 * eps * eps / ((2.0 + eps * eps) * (1.0 - eps * eps));
            let wt = k * omega * 6.0 * PI * eps / ((2.0 + eps * eps) * (1.0 - eps * eps).sqrt());
            assert!((force.x + wr).abs() <= 1e-12 * wr, "{eps}: {force:?} {wr}");
            assert!((force.y - wt).abs() <= 1e-12 * wt, "{eps}: {force:?} {wt}");
            let phi = (force.y / -force.x).atan();
            let want = (PI * (1.0 - eps * eps).sqrt() / (2.0 * eps)).atan();
            assert!((phi - want).abs() < 1e-12, "{eps}: {phi} against {want}");
            let rate = 2e-3;
            let sq = f.force(&e, &Vector3::new(rate, 0.0, 0.0), &Vector3::z(), 0.0);
            let w = 12.0 * PI * k * rate / c / (1.0 - eps * eps).powf(1.5);
            assert!(
                (sq.x + w).abs() <= 1e-12 * w && sq.y.abs() <= 1e-12 * w,
                "{eps}: {sq:?} {w}"
            );
        }
    }

    /// Above the limit the force is the limit's, continuous across it.
    #[test]
    fn above_the_limit_the_film_is_held() {
        let mut f = film();
        f.eccentricity_limit = 0.9;
        let c = f.clearance;
        let ed = Vector3::new(1e-3, 2e-3, 0.0);
        let at = |eps: f64| f.force(&Vector3::new(eps * c, 0.0, 0.0), &ed, &Vector3::z(), 30.0);
        assert_eq!(at(0.95), at(0.9));
        assert_eq!(at(1.2), at(0.9));
        assert!((at(0.9 - 1e-9) - at(0.9)).norm() <= 1e-6 * at(0.9).norm());
    }
}
