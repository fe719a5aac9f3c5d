//! The onset memory: the approach velocity delta'(t_c) that a contact's law reads (its damping
//! scales with it), stored when the penetration crosses zero inside an accepted step and
//! forgotten when the contact separates. The crossing is located on the cubic Hermite
//! interpolant of delta through the step's ends,
//!
//! ```text
//!   p(s) = h00(s) delta_0 + h10(s) h delta'_0 + h01(s) delta_1 + h11(s) h delta'_1,   p(s*) = 0,
//!   delta'(t_c) = p'(s*) / h
//! ```
//!
//! (a linear fallback where that interpolant is not to be trusted), and [`onset_rate_tangent`]
//! is its derivative for the tangent dynamics.

use crate::kin::GROUND;
use crate::model::Model;
use crate::workspace::Workspace;

impl Model {
    /// Updates the contact-onset history after an accepted step from (t0, y0) to (t1, y1).
    ///
    /// A contact whose penetration crosses zero inside the step gets the approach velocity at
    /// the crossing, located on the cubic Hermite interpolant of delta built from delta and
    /// delta_dot at both ends (not the value at the step end). A contact that is already
    /// penetrating at the start of the run takes its current rate. A contact that has separated
    /// forgets its onset. Returns true when a new onset was stored (the right-hand side at y1
    /// then changes, since it used the provisional value delta_dot(t1)).
    pub fn update_onsets(
        &self,
        t0: f64,
        y0: &[f64],
        t1: f64,
        y1: &[f64],
        ws: &mut Workspace,
    ) -> bool {
        if !self.effects.clearance {
            return false;
        }
        let nb = self.nb();
        let idx = |b: usize| if b == GROUND { nb } else { b };
        let mut changed = false;
        self.kinematics(y0, ws);
        for c in &self.clearances {
            let slots = c.first..c.first + c.geometry.n_contacts();
            c.geometry(
                &ws.kin[idx(c.housing)],
                &ws.kin[idx(c.journal)],
                &mut ws.contacts0[slots],
            );
        }
        self.kinematics(y1, ws);
        let h = t1 - t0;
        for c in &self.clearances {
            let n = c.geometry.n_contacts();
            let slots = c.first..c.first + n;
            c.geometry(
                &ws.kin[idx(c.housing)],
                &ws.kin[idx(c.journal)],
                &mut ws.contacts[slots],
            );
            if !c.law.needs_onset() {
                continue;
            }
            for s in c.first..c.first + n {
                let (a, b) = (ws.contacts0[s], ws.contacts[s]);
                if b.delta <= 0.0 {
                    ws.onset[s] = f64::NAN;
                    continue;
                }
                if !ws.onset[s].is_nan() {
                    continue;
                }
                ws.onset[s] = if a.delta > 0.0 {
                    a.delta_dot
                } else {
                    onset_rate(a.delta, a.delta_dot, b.delta, b.delta_dot, h)
                };
                changed = true;
            }
        }
        changed
    }
}

/// The derivative of `onset_rate` (the approach velocity read from the cubic through the step's
/// end points) along a perturbation `(dd0, dr0, dd1, dr1)` of its data: the
/// first-order change of the approach velocity stored at an onset when the trajectory is
/// perturbed. The crossing moves with the perturbation (implicit differentiation of
/// `p(s*) = 0`), which is the saltation rule of the onset-velocity reset (Mueller, Chaos Solitons
/// Fractals 5, 1995) applied to the same Hermite interpolant that locates the onset.
#[allow(clippy::too_many_arguments)]
pub fn onset_rate_tangent(
    (d0, r0, d1, r1): (f64, f64, f64, f64),
    h: f64,
    (dd0, dr0, dd1, dr1): (f64, f64, f64, f64),
) -> f64 {
    let basis = |s: f64| {
        [
            2.0 * s * s * s - 3.0 * s * s + 1.0,
            (s * s * s - 2.0 * s * s + s) * h,
            -2.0 * s * s * s + 3.0 * s * s,
            (s * s * s - s * s) * h,
        ]
    };
    let dbasis = |s: f64| {
        [
            6.0 * s * s - 6.0 * s,
            (3.0 * s * s - 4.0 * s + 1.0) * h,
            -6.0 * s * s + 6.0 * s,
            (3.0 * s * s - 2.0 * s) * h,
        ]
    };
    let ddbasis = |s: f64| {
        [
            12.0 * s - 6.0,
            (6.0 * s - 4.0) * h,
            -12.0 * s + 6.0,
            (6.0 * s - 2.0) * h,
        ]
    };
    if !hermite_trusted(d0, r0, d1, r1, h) {
        // The derivative of the linear fallback of `onset_rate`.
        let span = d1 - d0;
        let s = if span != 0.0 { -d0 / span } else { 0.5 };
        let ds = if span != 0.0 && (0.0..=1.0).contains(&s) {
            (-dd0 * span + d0 * (dd1 - dd0)) / (span * span)
        } else {
            0.0
        };
        let s = s.clamp(0.0, 1.0);
        return dr0 + (dr1 - dr0) * s + (r1 - r0) * ds;
    }
    let dot = |b: [f64; 4], x: [f64; 4]| b.iter().zip(x).map(|(b, x)| b * x).sum::<f64>();
    let data = [d0, r0, d1, r1];
    let pert = [dd0, dr0, dd1, dr1];
    let (mut lo, mut hi) = (0.0, 1.0);
    for _ in 0..50 {
        let mid = 0.5 * (lo + hi);
        if dot(basis(mid), data) > 0.0 {
            hi = mid
        } else {
            lo = mid
        }
    }
    let s = 0.5 * (lo + hi);
    let slope = dot(dbasis(s), data);
    // p(s*, data) = 0: ds*/d(data) = -p_data / p_s; the stored rate is p_s(s*) / h.
    let ds = if slope != 0.0 {
        -dot(basis(s), pert) / slope
    } else {
        0.0
    };
    (dot(dbasis(s), pert) + dot(ddbasis(s), data) * ds) / h
}

/// Whether the cubic Hermite interpolant of a step's penetration can be trusted: its secant
/// slope `(d1 - d0) / h`, the mean rate over the step, must lie within the range of the end
/// rates widened by that range and by half the larger rate. A step much shorter than
/// the penetration's round-off (the steps around a located onset event can be 1e-20 s long,
/// with penetrations of 1e-17 m that are round-off) fails it: there the secant is noise.
fn hermite_trusted(d0: f64, r0: f64, d1: f64, r1: f64, h: f64) -> bool {
    let secant = (d1 - d0) / h;
    let (lo, hi) = (r0.min(r1), r0.max(r1));
    let margin = (hi - lo) + 0.5 * r0.abs().max(r1.abs());
    secant >= lo - margin && secant <= hi + margin
}

/// Approach velocity where delta crosses zero inside a step of length h, from delta and its rate
/// at both ends, on the cubic Hermite interpolant (bisection on the sign change); where that
/// interpolant is not to be trusted ([`hermite_trusted`]), the rate interpolated linearly at the
/// linear crossing.
fn onset_rate(d0: f64, r0: f64, d1: f64, r1: f64, h: f64) -> f64 {
    if !hermite_trusted(d0, r0, d1, r1, h) {
        let span = d1 - d0;
        let s = if span != 0.0 {
            (-d0 / span).clamp(0.0, 1.0)
        } else {
            0.5
        };
        return r0 + (r1 - r0) * s;
    }
    let p = |s: f64| {
        (2.0 * s * s * s - 3.0 * s * s + 1.0) * d0
            + (s * s * s - 2.0 * s * s + s) * h * r0
            + (-2.0 * s * s * s + 3.0 * s * s) * d1
            + (s * s * s - s * s) * h * r1
    };
    let dp = |s: f64| {
        (6.0 * s * s - 6.0 * s) * d0
            + (3.0 * s * s - 4.0 * s + 1.0) * h * r0
            + (-6.0 * s * s + 6.0 * s) * d1
            + (3.0 * s * s - 2.0 * s) * h * r1
    };
    let (mut lo, mut hi) = (0.0, 1.0);
    for _ in 0..50 {
        let mid = 0.5 * (lo + hi);
        if p(mid) > 0.0 { hi = mid } else { lo = mid }
    }
    dp(0.5 * (lo + hi)) / h
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A step of 2.7e-20 s around a located onset, whose penetrations (1e-17 m) are round-off
    /// (measured on the clearance slider-crank with onset events): the Hermite interpolant would
    /// give 1500 m/s; the rate is the ends' 4.3858 m/s.
    #[test]
    fn onset_rate_of_a_round_off_step_is_the_rate_at_its_ends() {
        let (d0, r0, d1, r1, h) = (
            -1.1058862159352145e-17,
            4.385826513509208,
            1.6588293239028218e-17,
            4.38582651350921,
            2.710505431213761e-20,
        );
        let v = onset_rate(d0, r0, d1, r1, h);
        assert!((v - r0).abs() < 1e-12 * r0, "{v}");
        // Its tangent is the tangent of the same formula (finite differences of it).
        let pert = (1e-18, 1e-3, -2e-18, 2e-3);
        let e = 1e-3;
        let fd = (onset_rate(
            d0 + e * pert.0,
            r0 + e * pert.1,
            d1 + e * pert.2,
            r1 + e * pert.3,
            h,
        ) - onset_rate(
            d0 - e * pert.0,
            r0 - e * pert.1,
            d1 - e * pert.2,
            r1 - e * pert.3,
            h,
        )) / (2.0 * e);
        let tan = onset_rate_tangent((d0, r0, d1, r1), h, pert);
        assert!((fd - tan).abs() < 1e-8, "{fd} vs {tan}");
    }

    #[test]
    fn onset_rate_tangent_matches_finite_differences() {
        // A crossing inside the step: delta from -1e-6 m (approaching at 0.3 m/s) to 2e-6 m.
        let data = (-1e-6, 0.3, 2e-6, 0.25);
        let h = 1e-5;
        let pert = (3e-7, -0.05, 1e-7, 0.02);
        let at = |e: f64| {
            onset_rate(
                data.0 + e * pert.0,
                data.1 + e * pert.1,
                data.2 + e * pert.2,
                data.3 + e * pert.3,
                h,
            )
        };
        // Central differences with e = 1e-3: the rate is smooth in the data (a simple root of a
        // cubic), truncation O(e^2) ~ 1e-6 relative, far above the bisection's 2^-50 resolution.
        let fd = (at(1e-3) - at(-1e-3)) / 2e-3;
        let an = onset_rate_tangent(data, h, pert);
        assert!((an - fd).abs() < 1e-5 * fd.abs().max(1e-3), "{an} vs {fd}");
    }
}
