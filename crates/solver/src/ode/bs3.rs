//! The Bogacki-Shampine 3(2) pair (Bogacki & Shampine, Appl. Math. Lett. 2(4):321-325, 1989;
//! MATLAB's `ode23`, SciPy's `RK23`) with local extrapolation (the order-3 solution is
//! propagated), first-same-as-last stage reuse and a cubic Hermite dense output from the end
//! points' values and slopes (of order 3, the method's own). Adaptive, and also run at a fixed
//! step (the family `bs3_fixed`, for convergence studies). 3 right-hand-side evaluations per
//! step.
//!
//! Why a third-order pair beside DOPRI5: when the step is bounded by stability rather than
//! accuracy (a stiff contact that stays closed, an oscillatory mode `lambda` with
//! `|h lambda|` near the stability boundary), what a step costs is its evaluations and what it
//! gains is the largest stable `h`. The propagated solution's stability function is
//! `R(z) = 1 + z + z^2/2 + z^3/6`, stable to `|z| = sqrt(3)` on the imaginary axis, where
//! DOPRI5's is stable only to about `|z| = 1`; for the closed S2 contact of the 4-UPS/RPU
//! (`lambda = -219 +- 6604i 1/s`) this pair is stable to h = 2.9e-4 s with 3 evaluations a step,
//! DOPRI5 to 3.4e-4 s with 6: 0.59 times the evaluations per simulated second at the bound.
//! (RK4, stable to 4.4e-4 s with 4, covers a little more per evaluation but has no error
//! estimate to follow the impacts.) Where accuracy bounds the step (tight tolerances, smooth
//! flows) the low order costs many more steps than DOPRI5.

use super::{
    Adaptive, Fixed, Integrator, OdeSystem, Stats, Stepper, Work, axpy, hermite, polynomial,
};
use crate::error::Result;

/// BS3: adaptive (`bs3`) or at a fixed step (`bs3_fixed`).
pub static BS3: Integrator = Integrator {
    name: "bs3",
    order: 3,
    adaptive: Some(Adaptive {
        control_order: 3.0,
        default_decades: (3, 8),
    }),
    // The fixed-step family is for convergence studies, not among the default work-precision
    // runs.
    fixed: Some(Fixed {
        family: "bs3_fixed",
        default_steps: &[],
    }),
    stability,
    stages: 4,
    dense_len: 0,
    fsal: 3,
    jacobian: false,
    stepper: &Bs3,
};

/// The propagated 3rd-order solution of a three-stage method: R(z) = sum_{k<=3} z^k / k!.
fn stability(re: f64, im: f64) -> (f64, f64) {
    polynomial(&[1.0, 1.0, 0.5, 1.0 / 6.0], re, im)
}

// Bogacki-Shampine tableau: c = (0, 1/2, 3/4, 1); the 4th stage is f at the new state.
const C2: f64 = 1.0 / 2.0;
const C3: f64 = 3.0 / 4.0;
const A21: f64 = 1.0 / 2.0;
const A32: f64 = 3.0 / 4.0;
const B1: f64 = 2.0 / 9.0;
const B2: f64 = 1.0 / 3.0;
const B3: f64 = 4.0 / 9.0;
// Error coefficients b - b_hat, b_hat = (7/24, 1/4, 1/3, 1/8) the 2nd-order solution.
const E1: f64 = 2.0 / 9.0 - 7.0 / 24.0;
const E2: f64 = 1.0 / 3.0 - 1.0 / 4.0;
const E3: f64 = 4.0 / 9.0 - 1.0 / 3.0;
const E4: f64 = -1.0 / 8.0;

struct Bs3;

impl Stepper for Bs3 {
    /// One BS3 step with k1 = f(t, y) in `w.k[0]`; 3rd-order result in `w.y_new`,
    /// f(t+h, y_new) in `w.k[3]`, and the error estimate in `w.tmp`.
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
        let [k1, k2, k3, k4] = &mut w.k[..] else {
            unreachable!("BS3 has four stage vectors")
        };
        // Each loop over slices cut to one length (see `axpy`).
        axpy(&mut w.tmp[..n], y, h * A21, k1);
        sys.rhs(t + C2 * h, &w.tmp, k2);
        axpy(&mut w.tmp[..n], y, h * A32, k2);
        sys.rhs(t + C3 * h, &w.tmp, k3);
        {
            let (out, k1, k2, k3) = (&mut w.y_new[..n], &k1[..n], &k2[..n], &k3[..n]);
            for i in 0..n {
                out[i] = y[i] + h * (B1 * k1[i] + B2 * k2[i] + B3 * k3[i]);
            }
        }
        sys.rhs(t + h, &w.y_new, k4);
        let (err, k1, k2, k3, k4) = (&mut w.tmp[..n], &k1[..n], &k2[..n], &k3[..n], &k4[..n]);
        for i in 0..n {
            err[i] = h * (E1 * k1[i] + E2 * k2[i] + E3 * k3[i] + E4 * k4[i]);
        }
        stats.rhs_evals += 3;
        Ok(())
    }

    /// Cubic Hermite interpolation on [t, t+h] from y0, f0 (k[0]) and y1, f1 (k[3]).
    #[inline]
    fn eval_component(&self, y0: &[f64], w: &Work, h: f64, theta: f64, i: usize) -> f64 {
        hermite(y0, &w.y_new, &w.k[0], &w.k[3], h, theta, i)
    }
}
