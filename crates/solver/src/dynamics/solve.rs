//! Stage 4, the reduced solve: with `b = G M^-1 Q - rhs`, the multipliers from
//! `S lambda = b`, `S = G M^-1 G^T` (minimum-norm `S^+ b` when constraints are redundant), and the
//! accelerations `a = M^-1 Q - M^-1 G^T lambda`.
//!
//! Every row acts on at most two bodies, so `S_ij = sum_k G_i^k M_k^-1 G_j^k^T` over the bodies k
//! (the ground aside) that rows i and j share, and S_ij = 0 when they share none. That pattern is
//! fixed by the scene ([`Coupling`](crate::coupling::Coupling), built when the model is
//! compiled). Each evaluation gathers the blocks G_i^k and M_k^-1 G_i^k^T body by body, writes
//! every stored entry of S from its one or two terms (three products instead of six for rows that
//! constrain rotation only), and factors S in place with
//! [`SparsePsd`](crate::linalg::SparsePsd), in an elimination order computed once from the
//! pattern (for the legs of a parallel mechanism, leg rows before platform rows, without fill).
//! The cost grows with the rows per body rather than with the cube of the rows. The dense solve
//! by [`PsdSolver`](crate::linalg::PsdSolver) remains as the reference
//! ([`Model::accelerations_dense`](crate::model::Model::accelerations_dense)) and as the fallback
//! for the rare evaluation where a small pivot is not clearly a redundant direction.

use nalgebra::Vector3;

use super::blocks::{dot3w, dot6};
use crate::kin::GROUND;
use crate::model::Model;
use crate::workspace::{Workspace, minv_block};

/// Relative pivot tolerance of the reduced-matrix factorisation: pivots below it count as
/// redundant constraint directions.
pub const RANK_TOL: f64 = 1e-10;

impl Model {
    /// The reduced system on the sparse path: S assembled entry by entry and factored by
    /// [`SparsePsd`](crate::linalg::SparsePsd); then `a -= M^-1 G^T lambda`. Returns false, with
    /// the multipliers and accelerations untouched, when the factorisation defers to the dense
    /// path.
    pub(super) fn solve_sparse(&self, ws: &mut Workspace) -> bool {
        let c = &self.coupling;
        let nb = self.nb();
        for k in 0..nb {
            let (mi, inv_j) = (1.0 / self.bodies[k].mass, ws.inv_j[k]);
            let (u0, u1) = (c.inc_ptr[k], c.inc_ptr[k + 1]);
            let incs = c.inc[u0..u1].iter();
            for ((&(i, side), gj), gw) in incs.zip(&mut ws.inc_j[u0..u1]).zip(&mut ws.inc_w[u0..u1])
            {
                let r = &ws.rows[i];
                let j = if side == 0 { &r.ja } else { &r.jb };
                *gj = *j;
                let t = inv_j * Vector3::new(j[3], j[4], j[5]);
                *gw = [j[0] * mi, j[1] * mi, j[2] * mi, t.x, t.y, t.z];
            }
        }
        // S_ij = sum over the bodies k that rows i and j share of G_i^k M_k^-1 G_j^k^T.
        let s = ws.sparse.values_mut();
        let (gj, gw) = (&ws.inc_j, &ws.inc_w);
        for &[slot, u, v] in &c.first[0] {
            s[slot as usize] = dot3w(&gj[u as usize], &gw[v as usize]);
        }
        for &[slot, u, v] in &c.first[1] {
            s[slot as usize] = dot6(&gj[u as usize], &gw[v as usize]);
        }
        for &[slot, u, v] in &c.extra[0] {
            s[slot as usize] += dot3w(&gj[u as usize], &gw[v as usize]);
        }
        for &[slot, u, v] in &c.extra[1] {
            s[slot as usize] += dot6(&gj[u as usize], &gw[v as usize]);
        }
        if !ws.sparse.factor(RANK_TOL) {
            return false;
        }
        ws.rank = ws.sparse.rank();
        ws.sparse.solve(&mut ws.lambda);
        for k in 0..nb {
            // In a local copy, which the compiler keeps in registers.
            let mut acc = ws.acc[k];
            let (u0, u1) = (c.inc_ptr[k], c.inc_ptr[k + 1]);
            for (&(i, _), w) in c.inc[u0..u1].iter().zip(&ws.inc_w[u0..u1]) {
                let l = ws.lambda[i];
                for c in 0..6 {
                    acc[c] -= l * w[c];
                }
            }
            ws.acc[k] = acc;
        }
        true
    }

    /// The reduced system on the dense path: S = G M^-1 G^T row pair by row pair, factored by
    /// [`PsdSolver`](crate::linalg::PsdSolver); then `a -= M^-1 G^T lambda`.
    pub(super) fn solve_dense(&self, ws: &mut Workspace) {
        let nr = self.n_rows;
        ws.s.resize(nr * nr, 0.0);
        // W = M^-1 G^T, row by row.
        for i in 0..nr {
            let r = &ws.rows[i];
            ws.wrows[i] = (
                minv_block(self, ws, r.a, &r.ja),
                minv_block(self, ws, r.b, &r.jb),
            );
        }
        // S = G M^-1 G^T (only bodies shared by two rows contribute).
        for i in 0..nr {
            let ri = ws.rows[i];
            for j in i..nr {
                let rj = &ws.rows[j];
                let wj = &ws.wrows[j];
                let mut s = 0.0;
                if ri.a != GROUND {
                    if ri.a == rj.a {
                        s += dot6(&ri.ja, &wj.0);
                    }
                    if ri.a == rj.b {
                        s += dot6(&ri.ja, &wj.1);
                    }
                }
                if ri.b != GROUND {
                    if ri.b == rj.a {
                        s += dot6(&ri.jb, &wj.0);
                    }
                    if ri.b == rj.b {
                        s += dot6(&ri.jb, &wj.1);
                    }
                }
                ws.s[i * nr + j] = s;
                ws.s[j * nr + i] = s;
            }
        }
        ws.solver.factor(&ws.s, nr, RANK_TOL);
        ws.rank = ws.solver.rank();
        ws.solver.solve(&mut ws.lambda);
        for i in 0..nr {
            let l = ws.lambda[i];
            let r = &ws.rows[i];
            let (wa, wb) = &ws.wrows[i];
            if r.a != GROUND {
                for c in 0..6 {
                    ws.acc[r.a][c] -= l * wa[c];
                }
            }
            if r.b != GROUND {
                for c in 0..6 {
                    ws.acc[r.b][c] -= l * wb[c];
                }
            }
        }
    }
}
