//! The classical Runge-Kutta method of order 4 (Kutta, Z. Math. Phys. 46:435-453, 1901), at a
//! fixed step, with a cubic Hermite dense output built from the end-point values and slopes
//! (local interpolation error O(h^4), the order of the method itself). 4 right-hand-side
//! evaluations per step (the 5th, f at the new state, is the next step's first).

use super::{Fixed, Integrator, OdeSystem, Stats, Stepper, Work, axpy, hermite, polynomial};
use crate::error::Result;

/// RK4: fixed step only; the family `rk4` in studies.
pub static RK4: Integrator = Integrator {
    name: "rk4",
    order: 4,
    adaptive: None,
    fixed: Some(Fixed {
        family: "rk4",
        default_steps: &[4.0, 2.0, 1.0, 0.5, 0.25, 0.125],
    }),
    stability,
    stages: 5,
    dense_len: 0,
    fsal: 4,
    jacobian: false,
    stepper: &Rk4,
};

/// R(z) = sum_{k<=4} z^k / k!.
fn stability(re: f64, im: f64) -> (f64, f64) {
    polynomial(&[1.0, 1.0, 0.5, 1.0 / 6.0, 1.0 / 24.0], re, im)
}

struct Rk4;

impl Stepper for Rk4 {
    /// One RK4 step from (t, y) with k1 = f(t, y) already in `w.k[0]`; result in `w.y_new`,
    /// and `w.k[4]` = f(t + h, y_new) (the next step's first stage, used by the dense output).
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
        let n = y.len();
        let y = &y[..n];
        let [k1, k2, k3, k4, k5] = &mut w.k[..] else {
            unreachable!("RK4 has five stage vectors")
        };
        // Each loop over slices cut to one length (see `axpy`).
        axpy(&mut w.tmp[..n], y, 0.5 * h, k1);
        sys.rhs(t + 0.5 * h, &w.tmp, k2);
        axpy(&mut w.tmp[..n], y, 0.5 * h, k2);
        sys.rhs(t + 0.5 * h, &w.tmp, k3);
        axpy(&mut w.tmp[..n], y, h, k3);
        sys.rhs(t + h, &w.tmp, k4);
        {
            let (out, k1, k2, k3, k4) = (&mut w.y_new[..n], &k1[..n], &k2[..n], &k3[..n], &k4[..n]);
            for i in 0..n {
                out[i] = y[i] + h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
            }
        }
        sys.rhs(t + h, &w.y_new, k5);
        stats.rhs_evals += 4;
        Ok(())
    }

    /// Cubic Hermite interpolation on [t, t+h] from y0, f0 (k[0]) and y1, f1 (k[4]).
    #[inline]
    fn eval_component(&self, y0: &[f64], w: &Work, h: f64, theta: f64, i: usize) -> f64 {
        hermite(y0, &w.y_new, &w.k[0], &w.k[4], h, theta, i)
    }
}
