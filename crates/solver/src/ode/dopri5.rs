//! The embedded Dormand-Prince 5(4) pair (Dormand & Prince, J. Comput. Appl. Math. 6:19-26,
//! 1980) with local extrapolation (the order-5 solution is propagated), first-same-as-last stage
//! reuse and Hairer's order-4 continuous extension (Hairer, Norsett & Wanner, *Solving ODEs I*,
//! 2nd ed., section II.6, code DOPRI5). Adaptive, and also run at a fixed step (the family
//! `dopri5_fixed`, for convergence studies). 6 right-hand-side evaluations per step.

use super::{Adaptive, Fixed, Integrator, OdeSystem, Stats, Stepper, Work, polynomial};
use crate::error::Result;

/// DOPRI5: adaptive (`dopri5`, the scene's choice) or at a fixed step (`dopri5_fixed`).
pub static DOPRI5: Integrator = Integrator {
    name: "dopri5",
    order: 5,
    adaptive: Some(Adaptive {
        control_order: 5.0,
        default_decades: (3, 10),
    }),
    // The fixed-step family is for convergence studies, not among the default work-precision
    // runs.
    fixed: Some(Fixed {
        family: "dopri5_fixed",
        default_steps: &[],
    }),
    stability,
    stages: 7,
    dense_len: 5,
    fsal: 6,
    jacobian: false,
    stepper: &Dopri5,
};

/// The propagated 5th-order solution: R(z) = sum_{k<=5} z^k / k! + z^6 / 600 (the last
/// coefficient is b^T A^5 1 of the tableau).
fn stability(re: f64, im: f64) -> (f64, f64) {
    polynomial(
        &[
            1.0,
            1.0,
            0.5,
            1.0 / 6.0,
            1.0 / 24.0,
            1.0 / 120.0,
            1.0 / 600.0,
        ],
        re,
        im,
    )
}

// Dormand-Prince 5(4) tableau.
const C2: f64 = 1.0 / 5.0;
const C3: f64 = 3.0 / 10.0;
const C4: f64 = 4.0 / 5.0;
const C5: f64 = 8.0 / 9.0;
const A21: f64 = 1.0 / 5.0;
const A31: f64 = 3.0 / 40.0;
const A32: f64 = 9.0 / 40.0;
const A41: f64 = 44.0 / 45.0;
const A42: f64 = -56.0 / 15.0;
const A43: f64 = 32.0 / 9.0;
const A51: f64 = 19372.0 / 6561.0;
const A52: f64 = -25360.0 / 2187.0;
const A53: f64 = 64448.0 / 6561.0;
const A54: f64 = -212.0 / 729.0;
const A61: f64 = 9017.0 / 3168.0;
const A62: f64 = -355.0 / 33.0;
const A63: f64 = 46732.0 / 5247.0;
const A64: f64 = 49.0 / 176.0;
const A65: f64 = -5103.0 / 18656.0;
const A71: f64 = 35.0 / 384.0;
const A73: f64 = 500.0 / 1113.0;
const A74: f64 = 125.0 / 192.0;
const A75: f64 = -2187.0 / 6784.0;
const A76: f64 = 11.0 / 84.0;
// Error coefficients b - b_hat.
const E1: f64 = 71.0 / 57600.0;
const E3: f64 = -71.0 / 16695.0;
const E4: f64 = 71.0 / 1920.0;
const E5: f64 = -17253.0 / 339200.0;
const E6: f64 = 22.0 / 525.0;
const E7: f64 = -1.0 / 40.0;
// Dense output coefficients (Hairer's DOPRI5, CONTD5).
const D1: f64 = -12715105075.0 / 11282082432.0;
const D3: f64 = 87487479700.0 / 32700410799.0;
const D4: f64 = -10690763975.0 / 1880347072.0;
const D5: f64 = 701980252875.0 / 199316789632.0;
const D6: f64 = -1453857185.0 / 822651844.0;
const D7: f64 = 69997945.0 / 29380423.0;

#[inline]
fn axpy_stage(out: &mut [f64], y: &[f64], h: f64, terms: &[(f64, &[f64])]) {
    for i in 0..out.len() {
        let mut s = 0.0;
        for (c, k) in terms {
            s += c * k[i];
        }
        out[i] = y[i] + h * s;
    }
}

struct Dopri5;

impl Stepper for Dopri5 {
    /// One DOPRI5 step with k1 = f(t, y) in `w.k[0]`; 5th-order result in `w.y_new`,
    /// f(t+h, y_new) in `w.k[6]`, and the error estimate in `w.tmp`.
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
        let [k1, k2, k3, k4, k5, k6, k7] = &mut w.k[..] else {
            unreachable!("DOPRI5 has seven stage vectors")
        };
        axpy_stage(&mut w.tmp, y, h, &[(A21, k1)]);
        sys.rhs(t + C2 * h, &w.tmp, k2);
        axpy_stage(&mut w.tmp, y, h, &[(A31, k1), (A32, k2)]);
        sys.rhs(t + C3 * h, &w.tmp, k3);
        axpy_stage(&mut w.tmp, y, h, &[(A41, k1), (A42, k2), (A43, k3)]);
        sys.rhs(t + C4 * h, &w.tmp, k4);
        axpy_stage(
            &mut w.tmp,
            y,
            h,
            &[(A51, k1), (A52, k2), (A53, k3), (A54, k4)],
        );
        sys.rhs(t + C5 * h, &w.tmp, k5);
        axpy_stage(
            &mut w.tmp,
            y,
            h,
            &[(A61, k1), (A62, k2), (A63, k3), (A64, k4), (A65, k5)],
        );
        sys.rhs(t + h, &w.tmp, k6);
        axpy_stage(
            &mut w.y_new,
            y,
            h,
            &[(A71, k1), (A73, k3), (A74, k4), (A75, k5), (A76, k6)],
        );
        sys.rhs(t + h, &w.y_new, k7);
        // Slices cut to one length, not the vectors: stores through `err` cannot then be taken
        // to change where the stages' data lie, so their addresses are not reloaded for every
        // component (this loop was a third of the stepper's own time, by `perf annotate`).
        let n = y.len();
        let err = &mut w.tmp[..n];
        let (k1, k3, k4, k5, k6, k7) = (&k1[..n], &k3[..n], &k4[..n], &k5[..n], &k6[..n], &k7[..n]);
        for i in 0..n {
            err[i] =
                h * (E1 * k1[i] + E3 * k3[i] + E4 * k4[i] + E5 * k5[i] + E6 * k6[i] + E7 * k7[i]);
        }
        stats.rhs_evals += 6;
        Ok(())
    }

    /// Stores the DOPRI5 continuous extension of the step just taken.
    fn dense(
        &self,
        _sys: &mut dyn OdeSystem,
        _t: f64,
        y: &[f64],
        h: f64,
        w: &mut Work,
        _stats: &mut Stats,
    ) {
        let [k1, _, k3, k4, k5, k6, k7] = &w.k[..] else {
            unreachable!("DOPRI5 has seven stage vectors")
        };
        let [c0, c1, c2, c3, c4] = &mut w.cont[..] else {
            unreachable!("DOPRI5 has five dense-output vectors")
        };
        // Slices of one length, as in `step`.
        let n = y.len();
        let (c0, c1, c2, c3, c4) = (
            &mut c0[..n],
            &mut c1[..n],
            &mut c2[..n],
            &mut c3[..n],
            &mut c4[..n],
        );
        let (k1, k3, k4, k5, k6, k7) = (&k1[..n], &k3[..n], &k4[..n], &k5[..n], &k6[..n], &k7[..n]);
        let y_new = &w.y_new[..n];
        for i in 0..n {
            let ydiff = y_new[i] - y[i];
            let bspl = h * k1[i] - ydiff;
            c0[i] = y[i];
            c1[i] = ydiff;
            c2[i] = bspl;
            c3[i] = ydiff - h * k7[i] - bspl;
            c4[i] =
                h * (D1 * k1[i] + D3 * k3[i] + D4 * k4[i] + D5 * k5[i] + D6 * k6[i] + D7 * k7[i]);
        }
    }

    #[inline]
    fn eval_component(&self, _y0: &[f64], w: &Work, _h: f64, theta: f64, i: usize) -> f64 {
        let th1 = 1.0 - theta;
        let [c0, c1, c2, c3, c4] = &w.cont[..] else {
            unreachable!("DOPRI5 has five dense-output vectors")
        };
        c0[i] + theta * (c1[i] + th1 * (c2[i] + theta * (c3[i] + th1 * c4[i])))
    }
}
