//! Tangent (variational) dynamics of a flow, through contact memory, on a mechanism's constraint
//! manifold.
//!
//! A flow `y' = f(t, y; m)` whose right-hand side also reads a discrete memory `m` (a mechanism's
//! contact-onset velocities, [`jointplay_solver::workspace::Workspace::onset`]) has tangent
//! vectors `(v, w)`: `v` is a perturbation of the continuous state and `w` the perturbation it
//! causes in the memory. Between events they evolve by
//!
//! ```text
//! v' = J(t, y) v + (df/dm) w,        w' = 0,
//! ```
//!
//! and at a contact onset the memory is reset to the approach velocity `m_s = delta_dot(t*)`
//! at the crossing time `t*` of `delta = 0`. The crossing moves with the perturbation, so the
//! reset is differentiated with the event time (the saltation rule of a state reset, Mueller,
//! Chaos Solitons Fractals 5, 1995; tutorial arXiv 2306.06862):
//!
//! ```text
//! w_s = grad(delta_dot) . v - delta_ddot (grad(delta) . v) / delta_dot ,
//! ```
//!
//! evaluated on the same Hermite interpolant the solver locates the onset on
//! ([`jointplay_solver::dynamics::onset_rate_tangent`]). The continuous state does not jump at an
//! onset (the compliant force is zero at zero penetration), so `v` has no saltation term; a slot
//! out of contact forgets its memory and its `w_s` is zero.
//!
//! **Jacobian-vector products.** The built-in systems give `J v` analytically. A mechanism's is a
//! directional central difference `(f(y + e v, m + e w) - f(y - e v, m - e w)) / 2e` with
//! `e = sqrt(eps) / |v|` (about 1.5e-8 in the SI state's units), evaluated in a second workspace
//! so that the guards and the onset history of the run are untouched. The increment is absolute,
//! not scaled by |y| as usual for smooth problems (Knoll & Keyes, J. Comput. Phys. 193, 2004),
//! because a mechanism's state norm is set by its velocities while the stiff contact's
//! nonlinearity lives at the scale of the penetration (micrometres). A forward difference, whose
//! error is about e f''/f' ~ e / delta, was measured 6e-3 off the derivative of the flow map
//! through an onset on the clearance slider-crank; the central one, (e / delta)^2, agrees within
//! the finite-difference check's own resolution. It costs two right-hand sides per vector. The
//! forward quotient `(f(y + e v, m + e w) - f(y, m)) / e` costs one and is the default of
//! `[lyapunov] difference` (the central one is `difference = "central"`); where each is enough,
//! with the measurements: book/src/explanation/lyapunov.md.
//!
//! **The constraint manifold.** A mechanism's state `(positions with Euler parameters,
//! velocities)` lives on the manifold `C(y) = 0` of its position constraints `Phi(q, t)`, its
//! velocity constraints `Phi' = G v - s'` and the unit norm of each body's Euler parameters.
//! Baumgarte stabilisation makes the manifold attracting, so perturbations off it decay with rates
//! set by the stabilisation, not by the mechanics (spurious exponents), and the Euler-parameter
//! norm is neutral. [`Tangent::manifold_basis`] gives an orthonormal basis of the null space of
//! the Jacobian `dC/dy` (central differences, then an SVD), of dimension twice the free degrees of
//! freedom; the tangent vectors start in it and are projected onto it before every
//! re-orthonormalisation, so only the motion on the manifold is measured. Redundant constraint
//! rows do not change the null space.

use jointplay_solver::dynamics::onset_rate_tangent;
use jointplay_solver::ode::OdeSystem;
use nalgebra::DMatrix;

pub use crate::flow::scratch::{Difference, MechTangent};
use crate::flow::systems::Builtin;
use crate::flow::{AnyFlow, Flow, MechFlow, SysFlow, either};

/// What the Lyapunov analysis needs of a flow beyond [`Flow`].
pub trait Tangent: Flow {
    /// The offsets in the state of each body's four Euler parameters (none for a built-in
    /// system). A unit quaternion and its negative are one orientation, and a body that turns a
    /// whole turn comes back with its parameters negated: a map whose images are compared with
    /// its arguments (shooting) compares these up to their sign.
    fn euler_parameters(&self) -> Vec<usize> {
        Vec::new()
    }

    /// Length of the memory the tangent carries (contact slots), 0 for a smooth flow.
    fn memory_len(&self) -> usize {
        0
    }
    /// The current memory values (NaN: inactive).
    fn memory(&self) -> Vec<f64> {
        Vec::new()
    }
    /// Replaces the memory values (the two-trajectory estimate pulls its second trajectory's
    /// onset velocities back with its state).
    fn set_memory(&mut self, _memory: &[f64]) {}
    /// `out = J(t, y) v + (df/dm) w`, with `f0 = f(t, y)` already evaluated.
    fn jvp(&mut self, t: f64, y: &[f64], f0: &[f64], v: &[f64], w: &[f64], out: &mut [f64]);
    /// Called before the flow's own [`OdeSystem::step_accepted`] of the step from `(t0, y0)` to
    /// `(t1, y1)`, with the memory as it was; prepares what the memory update needs.
    fn before_accept(&mut self, _t0: f64, _y0: &[f64], _t1: f64, _y1: &[f64]) {}
    /// After the flow's [`OdeSystem::step_accepted`]: updates the memory tangent `w` of one
    /// tangent vector whose values at the step ends are `v0`, `v1` (`before` is the memory before
    /// the step).
    #[allow(clippy::too_many_arguments)]
    fn memory_tangent(
        &mut self,
        _t0: f64,
        _y0: &[f64],
        _v0: &[f64],
        _t1: f64,
        _y1: &[f64],
        _v1: &[f64],
        _before: &[f64],
        _w: &mut [f64],
    ) {
    }
    /// Orthonormal basis (columns) of the tangent space of the phase space at `(t, y)`; None when
    /// it is the whole state space.
    fn manifold_basis(&mut self, _t: f64, _y: &[f64]) -> crate::Result<Option<DMatrix<f64>>> {
        Ok(None)
    }
    /// `out = DR v`: the Jacobian of event `i`'s reset at the pre-event state `y`, applied to
    /// `v`. Identity by default.
    fn reset_jvp(&self, _i: usize, _t: f64, _y: &[f64], v: &[f64], out: &mut [f64]) {
        out.copy_from_slice(v);
    }
    /// The gradient of event function `i` at `(t, y)` (see
    /// [`Events::values`](jointplay_solver::ode::Events::values)); zeros by default (no events).
    fn event_gradient(&self, _i: usize, _t: f64, _y: &[f64], out: &mut [f64]) {
        out.fill(0.0);
    }
    /// Dimension of the phase space (the number of exponents of the full spectrum).
    fn phase_dim(&self) -> usize {
        self.dim()
    }
    /// Divergence of the vector field at `(t, y)` when known in closed form (a check of the
    /// spectrum's sum).
    fn divergence(&self, _t: f64, _y: &[f64]) -> Option<f64> {
        None
    }
    /// Chooses the difference quotient of a finite-difference [`Tangent::jvp`]; flows with an
    /// analytic one ignore it.
    fn set_difference(&mut self, _difference: Difference) {}
    /// How [`Tangent::jvp`] is computed: "analytic" or the difference quotient's name.
    fn jvp_kind(&self) -> &'static str {
        "analytic"
    }
    /// Moves `y` at time `t` back onto the phase space (a mechanism assembles it onto its
    /// constraint manifold: positions, velocities, Euler-parameter norms); nothing by default.
    fn onto_manifold(&mut self, _t: f64, _y: &mut [f64]) -> crate::Result<()> {
        Ok(())
    }
    /// How far `(t, y)` is off the phase space: the largest position constraint residual, the
    /// largest velocity constraint residual (for a mechanism's joints in m and m/s) and the
    /// largest `|e.e - 1|` of the Euler parameters; zeros for a flow without constraints.
    fn off_manifold(&mut self, _t: f64, _y: &[f64]) -> [f64; 3] {
        [0.0; 3]
    }
}

impl Tangent for SysFlow<'_> {
    fn jvp(&mut self, t: f64, y: &[f64], _f0: &[f64], v: &[f64], _w: &[f64], out: &mut [f64]) {
        self.sys.jvp(t, y, v, out);
    }
    fn divergence(&self, _t: f64, y: &[f64]) -> Option<f64> {
        Some(self.sys.divergence(y))
    }
    fn reset_jvp(&self, _i: usize, _t: f64, _y: &[f64], v: &[f64], out: &mut [f64]) {
        out.copy_from_slice(v);
        if let Builtin::Impact { restitution, .. } = self.sys {
            out[1] = -restitution * v[1];
        }
    }
    fn event_gradient(&self, _i: usize, _t: f64, _y: &[f64], out: &mut [f64]) {
        out.fill(0.0);
        if let Builtin::Impact { .. } = self.sys {
            // g = stop - x.
            out[0] = -1.0;
        }
    }
}

impl Builtin {
    /// The Jacobian-vector product `J(t, y) v`, analytic.
    pub fn jvp(&self, _t: f64, y: &[f64], v: &[f64], out: &mut [f64]) {
        match *self {
            Builtin::Duffing {
                delta, alpha, beta, ..
            } => {
                out[0] = v[1];
                out[1] = -(alpha + 3.0 * beta * y[0] * y[0]) * v[0] - delta * v[1];
            }
            Builtin::Pendulum {
                damping, omega0, ..
            } => {
                out[0] = v[1];
                out[1] = -omega0 * omega0 * y[0].cos() * v[0] - damping * v[1];
            }
            Builtin::Lorenz { sigma, rho, beta } => {
                out[0] = sigma * (v[1] - v[0]);
                out[1] = (rho - y[2]) * v[0] - v[1] - y[0] * v[2];
                out[2] = y[1] * v[0] + y[0] * v[1] - beta * v[2];
            }
            Builtin::Impact {
                damping, stiffness, ..
            } => {
                out[0] = v[1];
                out[1] = -stiffness * v[0] - damping * v[1];
            }
            Builtin::VanDerPol { mu, .. } => {
                out[0] = v[1];
                out[1] = -(2.0 * mu * y[0] * y[1] + 1.0) * v[0] + mu * (1.0 - y[0] * y[0]) * v[1];
            }
        }
    }

    /// The divergence (trace of the Jacobian) of the vector field.
    pub fn divergence(&self, y: &[f64]) -> f64 {
        match *self {
            Builtin::Duffing { delta, .. } => -delta,
            Builtin::Pendulum { damping, .. } => -damping,
            Builtin::Lorenz { sigma, beta, .. } => -(sigma + 1.0 + beta),
            Builtin::Impact { damping, .. } => -damping,
            Builtin::VanDerPol { mu, .. } => mu * (1.0 - y[0] * y[0]),
        }
    }
}

/// `sqrt(eps) / |v|`: the central-difference increment along `v` (see the module overview).
fn increment(_y: &[f64], v: &[f64]) -> f64 {
    let nv = v.iter().map(|x| x * x).sum::<f64>().sqrt();
    if nv == 0.0 {
        return 0.0;
    }
    f64::EPSILON.sqrt() / nv
}

impl MechFlow<'_> {
    fn tangent_scratch(&mut self) -> &mut MechTangent {
        if self.tangent.is_none() {
            self.tangent = Some(Box::new(MechTangent::new(&self.mech.ws, self.dim())));
        }
        self.tangent.as_mut().expect("just set")
    }

    /// Position constraints, velocity constraints and Euler-parameter norms at `(t, y)`.
    fn manifold_residual(&mut self, t: f64, y: &[f64], out: &mut Vec<f64>) {
        let m = self.mech.model;
        let tg = self.tangent_scratch();
        m.kinematics(y, &mut tg.ws);
        out.clear();
        if m.n_rows > 0 {
            m.constraints(t, &mut tg.ws);
            out.extend_from_slice(&tg.ws.phi);
            out.extend_from_slice(&tg.ws.phi_dot);
        }
        for b in 0..m.nb() {
            let q = &y[7 * b + 3..7 * b + 7];
            out.push(q.iter().map(|x| x * x).sum::<f64>() - 1.0);
        }
    }
}

impl Tangent for MechFlow<'_> {
    fn euler_parameters(&self) -> Vec<usize> {
        // Per body its centre of mass (3) and Euler parameters (4).
        (0..self.mech.model.nb()).map(|k| 7 * k + 3).collect()
    }
    fn memory_len(&self) -> usize {
        self.mech.ws.onset.len()
    }
    fn memory(&self) -> Vec<f64> {
        self.mech.ws.onset.clone()
    }
    fn set_memory(&mut self, memory: &[f64]) {
        self.mech.ws.onset.copy_from_slice(memory);
    }
    fn jvp(&mut self, t: f64, y: &[f64], f0: &[f64], v: &[f64], w: &[f64], out: &mut [f64]) {
        let e = increment(y, v);
        if e == 0.0 {
            out.fill(0.0);
            return;
        }
        let model = self.mech.model;
        self.tangent_scratch();
        // Disjoint fields: the run's onset history is read, the scratch workspace written (no
        // copy of the history per evaluation).
        let onset = &self.mech.ws.onset;
        let tg = self.tangent.as_mut().expect("made above");
        let mut yp = std::mem::take(&mut tg.y);
        let mut minus = std::mem::take(&mut tg.minus);
        let signs: &[f64] = match tg.difference {
            Difference::Central => &[1.0, -1.0],
            Difference::Forward => &[1.0],
        };
        for &sign in signs {
            for (i, x) in yp.iter_mut().enumerate() {
                *x = y[i] + sign * e * v[i];
            }
            for (s, o) in tg.ws.onset.iter_mut().enumerate() {
                *o = onset[s] + sign * e * w.get(s).copied().unwrap_or(0.0);
            }
            let dest = if sign > 0.0 {
                &mut *out
            } else {
                &mut minus[..]
            };
            model.rhs(t, &yp, &mut tg.ws, dest);
        }
        match tg.difference {
            Difference::Central => {
                for (o, m) in out.iter_mut().zip(&minus) {
                    *o = (*o - m) / (2.0 * e);
                }
            }
            Difference::Forward => {
                for (o, b) in out.iter_mut().zip(f0) {
                    *o = (*o - b) / e;
                }
            }
        }
        tg.y = yp;
        tg.minus = minus;
    }
    fn set_difference(&mut self, difference: Difference) {
        self.tangent_scratch().difference = difference;
    }
    fn jvp_kind(&self) -> &'static str {
        self.tangent
            .as_ref()
            .map_or(Difference::Central, |t| t.difference)
            .name()
    }
    fn before_accept(&mut self, _t0: f64, y0: &[f64], _t1: f64, y1: &[f64]) {
        let model = self.mech.model;
        let tg = self.tangent_scratch();
        let mut r = std::mem::take(&mut tg.rates0);
        model.contact_rates(y0, &mut tg.ws, &mut r);
        tg.rates0 = r;
        let mut r = std::mem::take(&mut tg.rates1);
        model.contact_rates(y1, &mut tg.ws, &mut r);
        tg.rates1 = r;
    }
    fn memory_tangent(
        &mut self,
        t0: f64,
        y0: &[f64],
        v0: &[f64],
        t1: f64,
        y1: &[f64],
        v1: &[f64],
        before: &[f64],
        w: &mut [f64],
    ) {
        let model = self.mech.model;
        let after = self.mech.ws.onset.clone();

        if after
            .iter()
            .zip(before)
            .all(|(a, b)| a.is_nan() == b.is_nan())
        {
            // No onset began or ended in this step: nothing to update (the common case, checked
            // before any difference quotient is taken).
            return;
        }
        let tg = self.tangent_scratch();
        // Directional derivatives of (delta, delta_dot) at both ends along v0 and v1.
        let mut deriv = |y: &[f64], v: &[f64], base: &[(f64, f64, bool)]| -> Vec<(f64, f64)> {
            let e = increment(y, v);
            let yp: Vec<f64> = y.iter().zip(v).map(|(a, b)| a + e * b).collect();
            let mut r = std::mem::take(&mut tg.scratch);
            model.contact_rates(&yp, &mut tg.ws, &mut r);
            let d = r
                .iter()
                .zip(base)
                .map(|(p, b)| {
                    if e == 0.0 {
                        (0.0, 0.0)
                    } else {
                        ((p.0 - b.0) / e, (p.1 - b.1) / e)
                    }
                })
                .collect();
            tg.scratch = r;
            d
        };
        let (r0, r1) = (tg.rates0.clone(), tg.rates1.clone());
        let d0 = deriv(y0, v0, &r0);
        let d1 = deriv(y1, v1, &r1);
        let h = t1 - t0;
        for s in 0..w.len() {
            if after[s].is_nan() {
                w[s] = 0.0;
            } else if before[s].is_nan() {
                let (a, b) = (r0[s], r1[s]);
                w[s] = if a.0 > 0.0 {
                    d0[s].1
                } else {
                    onset_rate_tangent(
                        (a.0, a.1, b.0, b.1),
                        h,
                        (d0[s].0, d0[s].1, d1[s].0, d1[s].1),
                    )
                };
            }
        }
    }
    fn manifold_basis(&mut self, t: f64, y: &[f64]) -> crate::Result<Option<DMatrix<f64>>> {
        let n = y.len();
        let mut c0 = Vec::new();
        self.manifold_residual(t, y, &mut c0);
        let m = c0.len();
        // dC/dy by central differences: C is smooth (polynomial in the Euler parameters and
        // velocities), so with a step of 1e-6 (1 + |y_i|) the truncation error, O(h^2), and the
        // rounding error, O(eps / h), are both about 1e-11 of the entries.
        let rows = m.max(n);
        let mut jac = DMatrix::<f64>::zeros(rows, n);
        let mut yp = y.to_vec();
        let (mut cp, mut cm) = (Vec::new(), Vec::new());
        for i in 0..n {
            let h = 1e-6 * (1.0 + y[i].abs());
            yp[i] = y[i] + h;
            self.manifold_residual(t, &yp, &mut cp);
            yp[i] = y[i] - h;
            self.manifold_residual(t, &yp, &mut cm);
            yp[i] = y[i];
            for r in 0..m {
                jac[(r, i)] = (cp[r] - cm[r]) / (2.0 * h);
            }
        }
        let dim = self.phase_dim();
        // The null space: the right singular vectors of the `dim` smallest singular values (the
        // matrix is padded with zero rows to be square, so that the SVD gives all of them).
        let svd = jac.svd(false, true);
        let vt = svd.v_t.expect("requested");
        let mut order: Vec<usize> = (0..svd.singular_values.len()).collect();
        order.sort_by(|&a, &b| svd.singular_values[a].total_cmp(&svd.singular_values[b]));
        let mut basis = DMatrix::zeros(n, dim);
        for (c, &k) in order.iter().take(dim).enumerate() {
            for r in 0..n {
                basis[(r, c)] = vt[(k, r)];
            }
        }
        Ok(Some(basis))
    }
    fn off_manifold(&mut self, t: f64, y: &[f64]) -> [f64; 3] {
        let mut r = Vec::new();
        self.manifold_residual(t, y, &mut r);
        let rows = self.mech.model.n_rows;
        let max = |v: &[f64]| v.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        [
            max(&r[..rows]),
            max(&r[rows..2 * rows]),
            max(&r[2 * rows..]),
        ]
    }
    fn onto_manifold(&mut self, t: f64, y: &mut [f64]) -> crate::Result<()> {
        let mut state = jointplay_solver::model::State { t, y: y.to_vec() };
        self.mech.model.assemble(&mut state)?;
        y.copy_from_slice(&state.y);
        Ok(())
    }
    fn phase_dim(&self) -> usize {
        let m = self.mech.model;
        // LuGre's bristle deflections are free coordinates of their own.
        if m.n_rows == 0 {
            return 12 * m.nb() + m.n_bristle;
        }
        2 * self.remaining_dof() + m.n_bristle
    }
}

impl Tangent for AnyFlow<'_> {
    fn memory_len(&self) -> usize {
        either!(self, f => f.memory_len())
    }
    fn memory(&self) -> Vec<f64> {
        either!(self, f => f.memory())
    }
    fn set_memory(&mut self, memory: &[f64]) {
        either!(self, f => f.set_memory(memory))
    }
    fn jvp(&mut self, t: f64, y: &[f64], f0: &[f64], v: &[f64], w: &[f64], out: &mut [f64]) {
        either!(self, f => f.jvp(t, y, f0, v, w, out))
    }
    fn before_accept(&mut self, t0: f64, y0: &[f64], t1: f64, y1: &[f64]) {
        either!(self, f => f.before_accept(t0, y0, t1, y1))
    }
    fn memory_tangent(
        &mut self,
        t0: f64,
        y0: &[f64],
        v0: &[f64],
        t1: f64,
        y1: &[f64],
        v1: &[f64],
        before: &[f64],
        w: &mut [f64],
    ) {
        either!(self, f => f.memory_tangent(t0, y0, v0, t1, y1, v1, before, w))
    }
    fn manifold_basis(&mut self, t: f64, y: &[f64]) -> crate::Result<Option<DMatrix<f64>>> {
        either!(self, f => f.manifold_basis(t, y))
    }
    fn euler_parameters(&self) -> Vec<usize> {
        either!(self, f => f.euler_parameters())
    }
    fn phase_dim(&self) -> usize {
        either!(self, f => f.phase_dim())
    }
    fn divergence(&self, t: f64, y: &[f64]) -> Option<f64> {
        either!(self, f => f.divergence(t, y))
    }
    fn reset_jvp(&self, i: usize, t: f64, y: &[f64], v: &[f64], out: &mut [f64]) {
        either!(self, f => f.reset_jvp(i, t, y, v, out))
    }
    fn onto_manifold(&mut self, t: f64, y: &mut [f64]) -> crate::Result<()> {
        either!(self, f => f.onto_manifold(t, y))
    }
    fn off_manifold(&mut self, t: f64, y: &[f64]) -> [f64; 3] {
        either!(self, f => f.off_manifold(t, y))
    }
    fn event_gradient(&self, i: usize, t: f64, y: &[f64], out: &mut [f64]) {
        either!(self, f => f.event_gradient(i, t, y, out))
    }
    fn set_difference(&mut self, difference: Difference) {
        either!(self, f => f.set_difference(difference))
    }
    fn jvp_kind(&self) -> &'static str {
        either!(self, f => f.jvp_kind())
    }
}
