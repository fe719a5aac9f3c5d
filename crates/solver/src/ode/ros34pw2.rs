//! ROS34PW2, the Rosenbrock-W method of Rang & Angermann (BIT Numer. Math. 45:761-787, 2005):
//! 4 stages, order 3 with an embedded order-2 solution, L-stable and stiffly accurate, and a
//! W-method: both orders hold for *any* matrix A standing in for the Jacobian df/dy (and without
//! df/dt), so A may be approximate, of low rank, and kept over several steps. Each stage solves
//!
//! ```text
//!   (I - h gamma A) k_i = h f(t + alpha_i h, y + sum_{j<i} alpha_ij k_j) + h A sum_{j<i} gamma_ij k_j,
//!   y_new = y + sum b_i k_i,   error estimate sum (b_i - b^_i) k_i   (O(h^3) for any A),
//! ```
//!
//! with gamma = 0.4358665215. Dense output: the cubic Hermite interpolant through the step's end
//! points and slopes (order 3, the method's own). 4 right-hand sides a step: stages 2 to 4 and f
//! at the new state (the next step's first stage).
//!
//! # The Jacobian it uses
//!
//! * A system that knows where its stiffness lies ([`Stiffness::directions`](super::Stiffness::directions): a mechanism's
//!   closed contacts) gives a few directions; with Q their orthonormal basis (n x r) the method
//!   takes `A = Z Q^T` with `Z = J Q`, the Jacobian restricted to them. Z comes from the system
//!   when it can form it ([`Stiffness::jacobian`](super::Stiffness::jacobian): a mechanism differences its contact
//!   forces alone and solves for the constrained response with the factorisation at the step
//!   start, counted as one evaluation), else from r forward differences of f. Then `I - c A` is
//!   inverted by the Woodbury identity,
//!   `(I - c Z Q^T)^-1 b = b + c Z (I_r - c Q^T Z)^-1 Q^T b`: an r x r factorisation and O(n r)
//!   work per stage, instead of n + 1 evaluations and an O(n^3) factorisation for the full
//!   Jacobian. The rest of df/dy (the smooth dynamics) is left to the explicit part of the
//!   stages, which the W-method's order conditions allow. The same A serves later steps while
//!   the set of stiff directions' sources is unchanged, for at most [`MAX_AGE`] step attempts; a
//!   step rejected with an A formed before its own start forms it afresh. (Measured on the
//!   4-UPS/RPU's work-precision windows, with every retry forming A again: A kept for up to 1,
//!   2, 5 and 20 steps took 9 678, 9 575, 9 628 and 10 960
//!   evaluations at rtol 1e-3 for restart errors of 3.5, 4.5, 4.2 and 3.3e-7 m; 5 keeps the
//!   evaluations of the smaller ages at a fraction of their time per step.)
//! * A mechanism without a closed contact has no stiff direction: A = 0 and the stages are
//!   explicit (its other stiffness, a stiff spring or the Baumgarte terms, is not treated).
//! * Any other system: the full Jacobian by forward differences at each step start (n
//!   evaluations, kept for the retries after a rejection) and an LU factorisation of
//!   `I - h gamma J`.
//!
//! [`Stats::rhs_evals`] counts the differencing evaluations, [`Stats::jacobians`] the matrices.

use nalgebra::{DMatrix, Dyn, LU};

use super::{
    Adaptive, DenseJacobian, Integrator, OdeSystem, Stats, Stepper, Work, hermite, lu_solve,
};
use crate::error::{Error, Result};

/// ROS34PW2: adaptive only.
pub static ROS34PW2: Integrator = Integrator {
    name: "ros34pw2",
    order: 3,
    adaptive: Some(Adaptive {
        // The difference of the order-3 and order-2 solutions: O(h^3).
        control_order: 3.0,
        default_decades: (3, 8),
    }),
    fixed: None,
    stability,
    stages: 7,
    dense_len: 0,
    fsal: F1,
    jacobian: true,
    stepper: &Ros34pw2,
};

/// Stage vectors: F0 = f(t, y) (FSAL), k1..k4, a scratch for f at a stage, F1 = f(t + h, y_new).
const F1: usize = 6;
const SCRATCH: usize = 5;

const GAMMA: f64 = 4.358_665_215_084_59e-1;
/// alpha_ij (strictly lower), row by row.
const ALPHA: [[f64; 3]; 4] = [
    [0.0, 0.0, 0.0],
    [8.717_330_430_169_18e-1, 0.0, 0.0],
    [8.445_706_001_536_942e-1, -1.129_906_423_648_418_5e-1, 0.0],
    [0.0, 0.0, 1.0],
];
/// gamma_ij (strictly lower), row by row.
const GAMMAS: [[f64; 3]; 4] = [
    [0.0, 0.0, 0.0],
    [-8.717_330_430_169_18e-1, 0.0, 0.0],
    [-9.033_805_701_304_408e-1, 5.418_067_238_809_533e-2, 0.0],
    [
        2.421_238_070_609_534_6e-1,
        -1.223_250_583_904_514_7,
        5.452_602_553_351_021e-1,
    ],
];
const B: [f64; 4] = [
    2.421_238_070_609_534_6e-1,
    -1.223_250_583_904_514_7,
    1.545_260_255_335_102,
    4.358_665_215_084_59e-1,
];
const B_HAT: [f64; 4] = [
    3.781_090_314_581_937e-1,
    -9.604_229_221_242_318e-2,
    0.5,
    2.179_332_607_542_295e-1,
];

/// How many step attempts a low-rank Jacobian serves at most while its directions' sources stay
/// the same.
pub const MAX_AGE: u32 = 5;

/// The stability function R(z) at z = h lambda: one step on y' = lambda y with A = lambda.
fn stability(re: f64, im: f64) -> (f64, f64) {
    let mul = |a: (f64, f64), b: (f64, f64)| (a.0 * b.0 - a.1 * b.1, a.0 * b.1 + a.1 * b.0);
    let div = |a: (f64, f64), b: (f64, f64)| {
        let d = b.0 * b.0 + b.1 * b.1;
        ((a.0 * b.0 + a.1 * b.1) / d, (a.1 * b.0 - a.0 * b.1) / d)
    };
    let z = (re, im);
    let w = (1.0 - GAMMA * re, -GAMMA * im);
    let mut k = [(0.0, 0.0); 4];
    for i in 0..4 {
        let (mut ya, mut ug) = ((1.0, 0.0), (0.0, 0.0));
        for j in 0..i {
            ya = (ya.0 + ALPHA[i][j] * k[j].0, ya.1 + ALPHA[i][j] * k[j].1);
            ug = (ug.0 + GAMMAS[i][j] * k[j].0, ug.1 + GAMMAS[i][j] * k[j].1);
        }
        let r = mul(z, (ya.0 + ug.0, ya.1 + ug.1));
        k[i] = div(r, w);
    }
    let mut y = (1.0, 0.0);
    for i in 0..4 {
        y = (y.0 + B[i] * k[i].0, y.1 + B[i] * k[i].1);
    }
    y
}

/// The low-rank Jacobian `A = Z Q^T` and its bookkeeping.
#[derive(Default)]
pub(super) struct LowRank {
    /// Orthonormal basis Q (n x r, column-major) and Z = J Q (n x r).
    basis: Vec<f64>,
    image: Vec<f64>,
    rank: usize,
    /// The sources of the directions A was formed from, and the step attempts it has served.
    pattern: Vec<u32>,
    age: u32,
    valid: bool,
    /// Whether the last attempt formed A (low rank) or the full Jacobian (`dense_here`) at its
    /// own (t, y): a retry from there keeps it.
    formed_here: bool,
    dense_here: bool,
    /// The system's directions and sources at this step start.
    dirs: Vec<f64>,
    new_pattern: Vec<u32>,
    /// LU factors of S = I_r - h gamma Q^T Z.
    small: Option<LU<f64, Dyn, Dyn>>,
    /// Q^T v.
    proj: Vec<f64>,
    /// Q^T Z (r x r, row-major), formed with Z.
    qz: Vec<f64>,
    /// Q^T k_j of the stages (4 x r) and a stage's coefficients of Z (r).
    stage_proj: Vec<f64>,
    x: Vec<f64>,
    sol: Vec<f64>,
}

impl LowRank {
    /// Orthonormalises the system's directions into `basis` (modified Gram-Schmidt, twice, a
    /// direction dropped when less than 1e-8 of it is new).
    fn orthonormalise(&mut self, n: usize) {
        self.basis.clear();
        self.rank = 0;
        for d in self.dirs.chunks_exact(n) {
            let norm0 = d.iter().map(|v| v * v).sum::<f64>().sqrt();
            if !(norm0 > 0.0 && norm0.is_finite()) {
                continue;
            }
            let mut v: Vec<f64> = d.iter().map(|x| x / norm0).collect();
            for _ in 0..2 {
                for q in self.basis.chunks_exact(n) {
                    let p: f64 = q.iter().zip(&v).map(|(a, b)| a * b).sum();
                    for (vi, qi) in v.iter_mut().zip(q) {
                        *vi -= p * qi;
                    }
                }
            }
            let norm = v.iter().map(|x| x * x).sum::<f64>().sqrt();
            if norm > 1e-8 {
                self.basis.extend(v.iter().map(|x| x / norm));
                self.rank += 1;
            }
        }
    }

    /// Makes A for a step of `h` from `(t, y)` with f0 = f(t, y), the system's directions and
    /// their sources in `dirs` and `new_pattern`: formed afresh (orthonormal basis, `Z = J Q` from
    /// the system or by differences, `Q^T Z`) unless the one kept still serves, then `S = I_r -
    /// h gamma Q^T Z` factorised. `tmp` and `scratch` are vectors of the state's length.
    fn prepare(
        &mut self,
        sys: &mut dyn OdeSystem,
        (t, y, f0): (f64, &[f64], &[f64]),
        (h, retry): (f64, bool),
        (tmp, scratch): (&mut [f64], &mut [f64]),
        stats: &mut Stats,
    ) -> Result<()> {
        let n = y.len();
        let fresh = !self.valid
            || self.pattern != self.new_pattern
            || self.age >= MAX_AGE
            || (retry && !self.formed_here);
        self.formed_here = fresh;
        self.dense_here = false;
        if fresh {
            self.orthonormalise(n);
            self.image.clear();
            self.image.resize(n * self.rank, 0.0);
            let analytic = self.rank > 0
                && sys
                    .stiffness()
                    .is_some_and(|s| s.jacobian(t, y, &self.basis, &mut self.image));
            if analytic {
                stats.rhs_evals += 1;
            } else {
                let sqrt_eps = f64::EPSILON.sqrt();
                for (q, z) in self
                    .basis
                    .chunks_exact(n)
                    .zip(self.image.chunks_exact_mut(n))
                {
                    let scale = q
                        .iter()
                        .zip(y)
                        .filter(|(qi, _)| **qi != 0.0)
                        .fold(1e-2_f64, |m, (_, yi)| m.max(yi.abs()));
                    let eps = sqrt_eps * scale;
                    for i in 0..n {
                        tmp[i] = y[i] + eps * q[i];
                    }
                    sys.rhs(t, tmp, scratch);
                    for i in 0..n {
                        z[i] = (scratch[i] - f0[i]) / eps;
                    }
                }
                stats.rhs_evals += self.rank as u64;
            }
            if self.rank > 0 {
                stats.jacobians += 1;
            }
            if self.image.iter().any(|v| !v.is_finite()) {
                self.valid = false;
                return Err(Error::Diverged {
                    time: t,
                    message: "the Jacobian along the stiff directions is not finite".into(),
                });
            }
            let r = self.rank;
            self.qz.clear();
            for q in self.basis.chunks_exact(n) {
                for z in self.image.chunks_exact(n) {
                    self.qz
                        .push(q.iter().zip(z).map(|(x, y)| x * y).sum::<f64>());
                }
            }
            debug_assert_eq!(self.qz.len(), r * r);
            std::mem::swap(&mut self.pattern, &mut self.new_pattern);
            self.valid = true;
            self.age = 0;
        }
        self.age += 1;
        // S = I_r - c Q^T Z.
        let (r, c) = (self.rank, h * GAMMA);
        self.small = None;
        if r > 0 {
            let s = DMatrix::<f64>::from_fn(r, r, |a, b| {
                (if a == b { 1.0 } else { 0.0 }) - c * self.qz[a * r + b]
            });
            let lu = LU::new(s);
            if !lu.is_invertible() {
                return Err(singular(t, h));
            }
            self.small = Some(lu);
        }
        Ok(())
    }

    /// Stage `i` with A = Z Q^T: with f at the stage in `f`, `ki` = the stage's k. With
    /// M = Q^T Z, P_j = Q^T k_j and p_u = sum_j gamma_ij P_j: Q^T b = h Q^T f + h M p_u,
    /// x = S^-1 Q^T b, k_i = h f + Z (h p_u + c x) and P_i = Q^T b + c M x: one projection and
    /// one product with Z a stage.
    fn stage(&mut self, i: usize, (h, c): (f64, f64), f: &[f64], ki: &mut [f64]) {
        let n = f.len();
        let r = self.rank;
        self.project(n, f);
        let LowRank {
            qz,
            proj,
            stage_proj,
            small,
            image,
            x,
            sol,
            ..
        } = self;
        stage_proj.resize(4 * r, 0.0);
        x.clear();
        for a in 0..r {
            let mut pu = 0.0;
            for j in 0..i {
                pu += GAMMAS[i][j] * stage_proj[j * r + a];
            }
            x.push(pu);
        }
        // x holds p_u; proj becomes Q^T b.
        for a in 0..r {
            let mp: f64 = (0..r).map(|b| qz[a * r + b] * x[b]).sum();
            proj[a] = h * (proj[a] + mp);
        }
        sol.clear();
        sol.extend_from_slice(proj);
        if let Some(lu) = small.as_ref() {
            lu_solve(lu, sol);
        }
        // x becomes h p_u + c S^-1 Q^T b.
        for a in 0..r {
            x[a] = h * x[a] + c * sol[a];
        }
        for m in 0..n {
            ki[m] = h * f[m];
        }
        for (z, &xa) in image.chunks_exact(n).zip(x.iter()) {
            for (o, zi) in ki.iter_mut().zip(z) {
                *o += xa * zi;
            }
        }
        for a in 0..r {
            let ms: f64 = (0..r).map(|b| qz[a * r + b] * sol[b]).sum();
            stage_proj[i * r + a] = proj[a] + c * ms;
        }
    }

    /// Q^T v into `proj`.
    fn project(&mut self, n: usize, v: &[f64]) {
        self.proj.clear();
        for q in self.basis.chunks_exact(n) {
            self.proj.push(q.iter().zip(v).map(|(a, b)| a * b).sum());
        }
    }
}

impl DenseJacobian {
    /// Stage `i` with the full Jacobian: b = h f + h J u with u = sum_j gamma_ij k_j (the
    /// earlier stages' k in `ks`, u formed in `u`), then `ki` = (I - c J)^-1 b with the
    /// factorisation of the step.
    fn stage(
        &self,
        i: usize,
        h: f64,
        (ks, f): (&[Vec<f64>], &[f64]),
        u: &mut [f64],
        ki: &mut [f64],
    ) {
        let n = f.len();
        for m in 0..n {
            let mut v = 0.0;
            for j in 0..i {
                v += GAMMAS[i][j] * ks[j][m];
            }
            u[m] = v;
        }
        for m in 0..n {
            ki[m] = h * f[m];
        }
        for col in 0..n {
            let uc = u[col];
            if uc != 0.0 {
                for m in 0..n {
                    ki[m] += h * self.jac[(m, col)] * uc;
                }
            }
        }
        if let Some(lu) = self.lu.as_ref() {
            lu_solve(lu, ki);
        }
    }
}

fn singular(t: f64, h: f64) -> Error {
    Error::Diverged {
        time: t,
        message: format!("the W-method's matrix I - h gamma A is singular at step {h:e} s"),
    }
}

struct Ros34pw2;

impl Stepper for Ros34pw2 {
    /// One step with F0 = f(t, y) in `w.k[0]`: the stages in `w.k[1..5]`, the new state in
    /// `w.y_new`, f there in `w.k[6]` and the error estimate in `w.tmp`.
    fn step(
        &self,
        sys: &mut dyn OdeSystem,
        t: f64,
        y: &[f64],
        h: f64,
        w: &mut Work,
        stats: &mut Stats,
        retry: bool,
    ) -> Result<()> {
        let n = y.len();
        let lin = w.lin.as_mut().expect("ROS34PW2 work space");
        let lr = &mut lin.low;
        let c = h * GAMMA;

        // The matrix A: low rank along the system's stiff directions, or the full Jacobian.
        let mut dirs = std::mem::take(&mut lr.dirs);
        let mut pattern = std::mem::take(&mut lr.new_pattern);
        dirs.clear();
        pattern.clear();
        let low = match sys.stiffness() {
            Some(s) => {
                s.directions(t, y, h, &mut dirs, &mut pattern);
                true
            }
            None => false,
        };
        lr.dirs = dirs;
        lr.new_pattern = pattern;
        let (k, rest) = w.k.split_at_mut(SCRATCH);
        let (scratch, f1) = rest.split_at_mut(1);
        let (scratch, f1) = (&mut scratch[0], &mut f1[0]);
        if low {
            lr.prepare(sys, (t, y, &k[0]), (h, retry), (&mut w.tmp, scratch), stats)?;
        } else {
            lr.valid = false;
            if !retry || !lr.dense_here {
                lin.dense
                    .difference_jacobian(sys, (t, y, &k[0]), &mut w.tmp, scratch);
                stats.rhs_evals += n as u64;
                stats.jacobians += 1;
                lr.dense_here = true;
            }
            if lin.dense.factor(c).is_none() {
                return Err(singular(t, h));
            }
        }

        // The stages.
        for i in 0..4 {
            let alpha_i: f64 = ALPHA[i].iter().sum();
            // Stage argument and f there (F0 for the first stage).
            if i > 0 {
                for m in 0..n {
                    let mut v = y[m];
                    for j in 0..i {
                        v += ALPHA[i][j] * k[1 + j][m];
                    }
                    w.tmp[m] = v;
                }
                sys.rhs(t + alpha_i * h, &w.tmp, scratch);
            } else {
                scratch.copy_from_slice(&k[0]);
            }
            let (head, tail) = k.split_at_mut(1 + i);
            let ki = &mut tail[0];
            if low {
                lin.low.stage(i, (h, c), scratch, ki);
            } else {
                lin.dense
                    .stage(i, h, (&head[1..], scratch), &mut w.y_new, ki);
            }
        }
        for m in 0..n {
            let (mut yn, mut e) = (y[m], 0.0);
            for j in 0..4 {
                yn += B[j] * k[1 + j][m];
                e += (B[j] - B_HAT[j]) * k[1 + j][m];
            }
            w.y_new[m] = yn;
            w.tmp[m] = e;
        }
        sys.rhs(t + h, &w.y_new, f1);
        stats.rhs_evals += 4;
        Ok(())
    }

    /// Cubic Hermite interpolation on [t, t+h] from y0, f0 (k[0]) and y1, f1 (k[6]).
    #[inline]
    fn eval_component(&self, y0: &[f64], w: &Work, h: f64, theta: f64, i: usize) -> f64 {
        hermite(y0, &w.y_new, &w.k[0], &w.k[F1], h, theta, i)
    }
}
