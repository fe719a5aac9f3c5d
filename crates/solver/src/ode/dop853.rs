//! Hairer's DOP853 (Hairer, Norsett & Wanner, *Solving ODEs I*, 2nd ed., section II.10, code
//! DOP853): the explicit Runge-Kutta pair of order 8 of Prince & Dormand (J. Comput. Appl. Math.
//! 7:67-75, 1981) with Hairer's error estimate built from embedded solutions of orders 5 and 3,
//! and an order-7 continuous extension. Adaptive. 12 evaluations per step (the 13th stage, f at
//! the new state, is the next step's first), plus 3 in a step whose continuous extension is
//! needed (a sample inside it, or a step observer). Those 3 stages are evaluated after
//! [`OdeSystem::step_accepted`], so in a step where a system's discrete history changes (a
//! contact begins) they see the new history and the other 12 the old: the interpolant inside
//! that one step is then of lower order. At tight tolerances it takes several times fewer
//! evaluations than DOPRI5 (4.4x on the harmonic oscillator at rtol 1e-10).
//!
//! The coefficients (the submodule `coefficients`) are generated from SciPy's
//! `dop853_coefficients.py` by `scripts/dop853_coefficients.py`.

use super::{Adaptive, Integrator, OdeSystem, Stats, Stepper, Work};
use crate::error::Result;

mod coefficients;

use coefficients::{A, B, C, D, E3, E5, FSAL, STAGES};

/// DOP853: adaptive only.
pub static DOP853: Integrator = Integrator {
    name: "dop853",
    order: 8,
    adaptive: Some(Adaptive {
        // The 5th-order estimate, corrected by the 3rd-order one, is treated as O(h^8), as in
        // Hairer's DOP853 and SciPy.
        control_order: 8.0,
        default_decades: (4, 11),
    }),
    fixed: None,
    stability,
    stages: STAGES,
    dense_len: 7,
    fsal: FSAL,
    jacobian: false,
    stepper: &Dop853,
};

/// R(z) = 1 + z b^T (I - z A)^-1 1 from the tableau: the stages of one step on y' = lambda y
/// from y = 1, in complex arithmetic (z = re + i im).
fn stability(re: f64, im: f64) -> (f64, f64) {
    let mul = |(a, b): (f64, f64), (c, d): (f64, f64)| (a * c - b * d, a * d + b * c);
    let combine = |row: &[(usize, f64)], g: &[(f64, f64)]| {
        let (mut sr, mut si) = (0.0, 0.0);
        for &(j, a) in row {
            sr += a * g[j].0;
            si += a * g[j].1;
        }
        let (pr, pi) = mul((re, im), (sr, si));
        (1.0 + pr, pi)
    };
    let mut g = [(0.0, 0.0); FSAL];
    g[0] = (1.0, 0.0);
    for s in 1..FSAL {
        g[s] = combine(A[s], &g[..s]);
    }
    combine(B, &g)
}

/// `out = y + h * sum_j a_j k[j]` over the nonzero coefficients `row` = [(j, a_j)].
#[inline]
fn rk_stage(out: &mut [f64], y: &[f64], h: f64, row: &[(usize, f64)], k: &[Vec<f64>]) {
    combine(out, row, k);
    for (o, &yi) in out.iter_mut().zip(y) {
        *o = yi + h * *o;
    }
}

/// `out = sum_j a_j k[j]` over `row` = [(j, a_j)], summed in the order of `row` from 0 for every
/// component, one stage at a time: each pass is a loop over slices the compiler vectorises,
/// where a sum over the row for each component in turn (the same sums, bit for bit) was not,
/// and took a tenth of a DOP853 run of the mixed 4-UPS/RPU (`perf`).
fn combine(out: &mut [f64], row: &[(usize, f64)], k: &[Vec<f64>]) {
    let n = out.len();
    out.fill(0.0);
    for &(j, a) in row {
        for (o, &v) in out.iter_mut().zip(&k[j][..n]) {
            *o += a * v;
        }
    }
}

struct Dop853;

impl Stepper for Dop853 {
    /// One DOP853 step with k1 = f(t, y) in `w.k[0]`: stages 1..11, the 8th-order result in
    /// `w.y_new` and f(t + h, y_new) in `w.k[12]`.
    fn step(
        &self,
        sys: &mut dyn OdeSystem,
        t: f64,
        y: &[f64],
        h: f64,
        w: &mut Work,
        stats: &mut Stats,
        _retry: bool,
    ) -> Result<()> {
        for s in 1..FSAL {
            let (done, rest) = w.k.split_at_mut(s);
            rk_stage(&mut w.tmp, y, h, A[s], done);
            sys.rhs(t + C[s] * h, &w.tmp, &mut rest[0]);
        }
        let (done, rest) = w.k.split_at_mut(FSAL);
        rk_stage(&mut w.y_new, y, h, B, done);
        sys.rhs(t + h, &w.y_new, &mut rest[0]);
        stats.rhs_evals += FSAL as u64;
        Ok(())
    }

    /// DOP853's error norm (Hairer's code, SciPy's `DOP853._estimate_error_norm`): with the 5th-
    /// and 3rd-order estimates e5, e3 scaled per component by `atol + rtol * max(|y_old|,
    /// |y_new|)`, `|h| * |e5|^2 / sqrt((|e5|^2 + 0.01 |e3|^2) n)`. The 3rd-order estimate keeps
    /// the 5th-order one honest at large steps, where the latter can be accidentally small.
    fn error_norm(&self, w: &Work, y: &[f64], h: f64, rtol: f64, atol: f64) -> f64 {
        let (mut s5, mut s3) = (0.0, 0.0);
        let n = w.n_err;
        for i in 0..n {
            let sc = atol + rtol * y[i].abs().max(w.y_new[i].abs());
            let (mut e5, mut e3) = (0.0, 0.0);
            for &(j, e) in E5 {
                e5 += e * w.k[j][i];
            }
            for &(j, e) in E3 {
                e3 += e * w.k[j][i];
            }
            s5 += (e5 / sc) * (e5 / sc);
            s3 += (e3 / sc) * (e3 / sc);
        }
        if s5 == 0.0 && s3 == 0.0 {
            return 0.0;
        }
        h.abs() * s5 / ((s5 + 0.01 * s3) * n as f64).sqrt()
    }

    /// DOP853's order-7 continuous extension of the step from (t, y): the three extra stages
    /// 13..15 (three right-hand-side evaluations) and the seven coefficient vectors of Hairer's
    /// CONTD8.
    fn dense(
        &self,
        sys: &mut dyn OdeSystem,
        t: f64,
        y: &[f64],
        h: f64,
        w: &mut Work,
        stats: &mut Stats,
    ) {
        for s in FSAL + 1..STAGES {
            let (done, rest) = w.k.split_at_mut(s);
            rk_stage(&mut w.tmp, y, h, A[s], done);
            sys.rhs(t + C[s] * h, &w.tmp, &mut rest[0]);
        }
        let (f_old, f_new) = (&w.k[0], &w.k[FSAL]);
        let (first, rest) = w.cont.split_at_mut(3);
        for i in 0..y.len() {
            let dy = w.y_new[i] - y[i];
            first[0][i] = dy;
            first[1][i] = h * f_old[i] - dy;
            first[2][i] = 2.0 * dy - h * (f_new[i] + f_old[i]);
        }
        for (c, row) in rest.iter_mut().zip(D) {
            let c = &mut c[..y.len()];
            combine(c, row, &w.k);
            for v in c {
                *v *= h;
            }
        }
        stats.rhs_evals += (STAGES - FSAL - 1) as u64;
    }

    /// y(t + theta h) = y0 + x (F0 + (1-x) (F1 + x (F2 + (1-x) (F3 + x (F4 + (1-x) (F5 +
    /// x F6)))))) with x = theta (SciPy's `Dop853DenseOutput`).
    #[inline]
    fn eval_component(&self, y0: &[f64], w: &Work, _h: f64, theta: f64, i: usize) -> f64 {
        let (x, x1) = (theta, 1.0 - theta);
        let f = &w.cont;
        let mut v = f[6][i] * x;
        v = (v + f[5][i]) * x1;
        v = (v + f[4][i]) * x;
        v = (v + f[3][i]) * x1;
        v = (v + f[2][i]) * x;
        v = (v + f[1][i]) * x1;
        v = (v + f[0][i]) * x;
        y0[i] + v
    }
}
