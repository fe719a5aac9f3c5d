//! Assembly: bringing a state onto the constraints at its time, positions by Newton iterations
//! with minimum-norm corrections `dx = -G^T (G G^T)^+ Phi`, then velocities by the mass-weighted
//! projection `v = v0 - M^-1 G^T S^+ (G v0 - s')`.

use nalgebra::{Quaternion, UnitQuaternion, Vector3};

use super::blocks::dot6;
use super::solve::RANK_TOL;
use crate::error::{Error, Result};
use crate::kin::GROUND;
use crate::linalg::PsdSolver;
use crate::model::{Model, State};
use crate::workspace::{Row, Workspace, minv_block};

impl Model {
    /// Brings the state onto the position and velocity constraints at its time: Newton iterations
    /// with minimum-norm corrections for positions, then the mass-weighted projection of the
    /// velocities, `v = v0 - M^-1 G^T S^+ (G v0 - s')`.
    pub fn assemble(&self, state: &mut State) -> Result<AssemblyReport> {
        self.assemble_within(state, 0.0)
    }

    /// [`Model::assemble`] that leaves the velocities alone when their residual max |Phi'| is
    /// already below `velocity_tol` (m/s or rad/s), so that a state already on the constraints
    /// comes back bit for bit (the positions are left alone below 1e-12 in any case).
    pub fn assemble_within(&self, state: &mut State, velocity_tol: f64) -> Result<AssemblyReport> {
        let nb = self.nb();
        let np = 7 * nb;
        let nr = self.n_rows;
        let mut report = AssemblyReport::default();
        if nr == 0 {
            return Ok(report);
        }
        let mut ws = Workspace::new(self);
        let mut solver = PsdSolver::new();
        let mut s = vec![0.0; nr * nr];
        let tol = 1e-12;
        let t = state.t;
        self.kinematics(&state.y, &mut ws);
        self.constraints(t, &mut ws);
        report.initial_residual = max_abs(&ws.phi);
        for it in 0..60 {
            let res = max_abs(&ws.phi);
            report.iterations = it;
            if res < tol {
                break;
            }
            // S = G G^T (unweighted), mu = S^+ phi, dx = -G^T mu.
            for i in 0..nr {
                for j in i..nr {
                    let v = row_dot(&ws.rows[i], &ws.rows[j]);
                    s[i * nr + j] = v;
                    s[j * nr + i] = v;
                }
            }
            solver.factor(&s, nr, RANK_TOL);
            let mut mu = ws.phi.clone();
            solver.solve(&mut mu);
            let mut dx = vec![[0.0; 6]; nb];
            for (i, r) in ws.rows.iter().enumerate() {
                for (b, j) in [(r.a, &r.ja), (r.b, &r.jb)] {
                    if b != GROUND {
                        for c in 0..6 {
                            dx[b][c] -= mu[i] * j[c];
                        }
                    }
                }
            }
            for (k, d) in dx.iter().enumerate() {
                for c in 0..3 {
                    state.y[7 * k + c] += d[c];
                }
                let q = &state.y[7 * k + 3..7 * k + 7];
                let q = UnitQuaternion::from_quaternion(Quaternion::new(q[0], q[1], q[2], q[3]));
                let dq = UnitQuaternion::from_scaled_axis(Vector3::new(d[3], d[4], d[5]));
                let qn = (dq * q).into_inner();
                state.y[7 * k + 3..7 * k + 7].copy_from_slice(&[qn.w, qn.i, qn.j, qn.k]);
            }
            self.kinematics(&state.y, &mut ws);
            self.constraints(t, &mut ws);
        }
        let res = max_abs(&ws.phi);
        report.final_residual = res;
        // A position so far off that the corrections overflowed leaves NaN in the state: refused
        // here, before anything (the rank analysis, a run) works on it.
        if !res.is_finite() || res >= 1e-9 || state.y[..np].iter().any(|v| !v.is_finite()) {
            let worst = ws
                .phi
                .iter()
                .enumerate()
                .max_by(|a, b| a.1.abs().total_cmp(&b.1.abs()))
                .map(|(i, _)| i)
                .unwrap_or(0);
            return Err(Error::Assembly {
                file: self.file.clone(),
                time: t,
                message: format!(
                    "position constraints not met after {} Newton iterations: residual {:.3e} (m or rad) in {}; \
                     check that the initial poses, joint points and drive values are compatible",
                    report.iterations,
                    res,
                    self.row_owner(worst)
                ),
            });
        }
        // Velocities: mass-weighted projection.
        self.accelerations(t, &state.y, &mut ws);
        report.initial_velocity_residual = max_abs(&ws.phi_dot);
        if report.initial_velocity_residual < velocity_tol {
            report.final_velocity_residual = report.initial_velocity_residual;
            return Ok(report);
        }
        let mut mu = ws.phi_dot.clone();
        // The acceleration evaluation left G M^-1 G^T factored.
        ws.solve_reduced(&mut mu);
        for (i, r) in ws.rows.iter().enumerate() {
            for (b, j) in [(r.a, &r.ja), (r.b, &r.jb)] {
                let w = minv_block(self, &ws, b, j);
                if b != GROUND {
                    for c in 0..6 {
                        state.y[np + 6 * b + c] -= mu[i] * w[c];
                    }
                }
            }
        }
        self.kinematics(&state.y, &mut ws);
        self.constraints(t, &mut ws);
        report.final_velocity_residual = max_abs(&ws.phi_dot);
        if state.y.iter().any(|v| !v.is_finite()) {
            return Err(Error::Assembly {
                file: self.file.clone(),
                time: t,
                message: "the velocities projected onto the constraints are not finite; check \
                          the initial velocities and the masses"
                    .into(),
            });
        }
        Ok(report)
    }
}

/// Residuals before and after assembly.
#[derive(Debug, Clone, Copy, Default)]
pub struct AssemblyReport {
    pub iterations: usize,
    /// max |Phi| (m or rad).
    pub initial_residual: f64,
    pub final_residual: f64,
    /// max |Phi'| (m/s or rad/s).
    pub initial_velocity_residual: f64,
    pub final_velocity_residual: f64,
}

/// The largest magnitude in `v`; NaN when any entry is NaN (`f64::max` would skip it, and a
/// residual that became NaN would pass for a small one).
fn max_abs(v: &[f64]) -> f64 {
    v.iter().fold(
        0.0,
        |m: f64, x| {
            if x.is_nan() { f64::NAN } else { m.max(x.abs()) }
        },
    )
}

/// G_i . G_j over the bodies the two rows share.
fn row_dot(ri: &Row, rj: &Row) -> f64 {
    let mut s = 0.0;
    for (bi, ji) in [(ri.a, &ri.ja), (ri.b, &ri.jb)] {
        if bi == GROUND {
            continue;
        }
        for (bj, jj) in [(rj.a, &rj.ja), (rj.b, &rj.jb)] {
            if bi == bj {
                s += dot6(ji, jj);
            }
        }
    }
    s
}
