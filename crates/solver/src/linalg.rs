//! Dense symmetric positive semi-definite solves that cope with rank deficiency.
//!
//! The reduced constraint matrix `S = G M^-1 G^T` is singular when constraints are redundant (a
//! planar mechanism built from 3D revolute joints, or five drives on the 4-DOF 4-UPS/RPU). We
//! factor it by Cholesky with diagonal pivoting, `P^T S P = L L^T` with `L` of size m x r, stopping
//! when the largest remaining pivot falls below `tol` times the largest diagonal entry (Higham,
//! *Accuracy and Stability of Numerical Algorithms*, 2nd ed., section 10.3). The minimum-norm
//! least-squares solution is then `x = S^+ b = P L (L^T L)^-2 L^T P^T b`, since
//! `S^+ = L (L^T L)^-2 L^T` for a full-column-rank `L`. For a consistent right-hand side this is the
//! unique set of multipliers of least Euclidean norm: redundant actuators share their load instead of
//! one of them carrying none of it. nalgebra offers no pivoted Cholesky, so it is written here.

/// Reusable factorisation workspace for matrices up to size `m`.
#[derive(Debug, Clone, Default)]
pub struct PsdSolver {
    m: usize,
    /// Working copy of S, overwritten by the factor (row-major m x m; column k of L in column k).
    a: Vec<f64>,
    perm: Vec<usize>,
    rank: usize,
    full_rank: bool,
    /// Cholesky factor of L^T L (r x r, lower, row-major) when rank deficient.
    g: Vec<f64>,
    tmp: Vec<f64>,
    tmp2: Vec<f64>,
}

impl PsdSolver {
    pub fn new() -> Self {
        Self::default()
    }

    /// Numerical rank found by the last [`PsdSolver::factor`].
    pub fn rank(&self) -> usize {
        self.rank
    }

    /// Factors the symmetric PSD matrix `s` (row-major m x m).
    pub fn factor(&mut self, s: &[f64], m: usize, tol: f64) {
        self.m = m;
        self.a.clear();
        self.a.extend_from_slice(s);
        self.perm.clear();
        self.perm.extend(0..m);
        let a = &mut self.a;
        let dmax = (0..m).map(|i| a[i * m + i]).fold(0.0f64, f64::max);
        let thresh = tol * dmax.max(f64::MIN_POSITIVE);
        let mut r = 0;
        for k in 0..m {
            // Pivot: largest remaining diagonal.
            let (mut p, mut best) = (k, a[k * m + k]);
            for i in k + 1..m {
                if a[i * m + i] > best {
                    best = a[i * m + i];
                    p = i;
                }
            }
            if best.is_nan() || best <= thresh {
                break;
            }
            if p != k {
                // Symmetric swap of rows/columns k and p.
                for j in 0..m {
                    a.swap(k * m + j, p * m + j);
                }
                for i in 0..m {
                    a.swap(i * m + k, i * m + p);
                }
                self.perm.swap(k, p);
            }
            let lkk = a[k * m + k].sqrt();
            a[k * m + k] = lkk;
            for i in k + 1..m {
                a[i * m + k] /= lkk;
            }
            // Update the whole trailing block (both triangles) so that later symmetric swaps of
            // rows and columns stay valid.
            for j in k + 1..m {
                let ljk = a[j * m + k];
                if ljk != 0.0 {
                    for i in k + 1..m {
                        a[i * m + j] -= a[i * m + k] * ljk;
                    }
                }
            }
            r += 1;
        }
        self.rank = r;
        self.full_rank = r == m;
        if !self.full_rank && r > 0 {
            // G = chol(L^T L), r x r.
            self.g.clear();
            self.g.resize(r * r, 0.0);
            for i in 0..r {
                for j in 0..=i {
                    let mut s = 0.0;
                    for k in i.max(j)..m {
                        s += a[k * m + i] * a[k * m + j];
                    }
                    self.g[i * r + j] = s;
                }
            }
            let g = &mut self.g;
            for j in 0..r {
                let mut d = g[j * r + j];
                for k in 0..j {
                    d -= g[j * r + k] * g[j * r + k];
                }
                let d = d.max(f64::MIN_POSITIVE).sqrt();
                g[j * r + j] = d;
                for i in j + 1..r {
                    let mut s = g[i * r + j];
                    for k in 0..j {
                        s -= g[i * r + k] * g[j * r + k];
                    }
                    g[i * r + j] = s / d;
                }
            }
        }
    }

    /// Solves `S x = b` in place (minimum-norm least squares when S is singular).
    pub fn solve(&mut self, b: &mut [f64]) {
        let m = self.m;
        let r = self.rank;
        let a = &self.a;
        self.tmp.clear();
        self.tmp.extend(self.perm.iter().map(|&p| b[p]));
        let x = &mut self.tmp;
        if self.full_rank {
            // L y = Pb, L^T x = y.
            for i in 0..m {
                let mut s = x[i];
                for k in 0..i {
                    s -= a[i * m + k] * x[k];
                }
                x[i] = s / a[i * m + i];
            }
            for i in (0..m).rev() {
                let mut s = x[i];
                for k in i + 1..m {
                    s -= a[k * m + i] * x[k];
                }
                x[i] = s / a[i * m + i];
            }
        } else {
            // c = L^T Pb (r), z = (L^T L)^-1 c twice, x = L z.
            self.tmp2.clear();
            self.tmp2.resize(r, 0.0);
            let c = &mut self.tmp2;
            for j in 0..r {
                let mut s = 0.0;
                for k in j..m {
                    s += a[k * m + j] * x[k];
                }
                c[j] = s;
            }
            let g = &self.g;
            for _ in 0..2 {
                for i in 0..r {
                    let mut s = c[i];
                    for k in 0..i {
                        s -= g[i * r + k] * c[k];
                    }
                    c[i] = s / g[i * r + i];
                }
                for i in (0..r).rev() {
                    let mut s = c[i];
                    for k in i + 1..r {
                        s -= g[k * r + i] * c[k];
                    }
                    c[i] = s / g[i * r + i];
                }
            }
            for i in 0..m {
                let mut s = 0.0;
                for k in 0..r.min(i + 1) {
                    s += a[i * m + k] * c[k];
                }
                x[i] = s;
            }
        }
        for (i, &p) in self.perm.iter().enumerate() {
            b[p] = x[i];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::DMatrix;

    fn gram(rows: &[&[f64]]) -> (Vec<f64>, usize) {
        let m = rows.len();
        let mut s = vec![0.0; m * m];
        for i in 0..m {
            for j in 0..m {
                s[i * m + j] = rows[i].iter().zip(rows[j]).map(|(a, b)| a * b).sum();
            }
        }
        (s, m)
    }

    #[test]
    fn full_rank_solve_matches_direct() {
        let (s, m) = gram(&[&[2.0, 1.0, 0.0], &[0.0, 1.0, 3.0], &[1.0, 0.0, 1.0]]);
        let mut b = vec![1.0, -2.0, 0.5];
        let x_ref = DMatrix::from_row_slice(m, m, &s)
            .lu()
            .solve(&nalgebra::DVector::from_vec(b.clone()))
            .unwrap();
        let mut f = PsdSolver::new();
        f.factor(&s, m, 1e-12);
        assert_eq!(f.rank(), 3);
        f.solve(&mut b);
        for i in 0..m {
            assert!((b[i] - x_ref[i]).abs() < 1e-12);
        }
    }

    #[test]
    fn redundant_rows_give_the_pseudo_inverse_solution() {
        // Four rows in 3D, one of them the sum of two others: S is 4x4 of rank 3.
        let r3 = [1.0, 1.0, 0.5];
        let (s, m) = gram(&[&[1.0, 0.0, 0.5], &[0.0, 1.0, 0.0], &r3, &[0.3, -1.0, 2.0]]);
        let b0 = vec![0.7, -0.2, 0.5, 1.1];
        let pinv = DMatrix::from_row_slice(m, m, &s)
            .pseudo_inverse(1e-12)
            .unwrap();
        let x_ref = &pinv * nalgebra::DVector::from_vec(b0.clone());
        let mut f = PsdSolver::new();
        f.factor(&s, m, 1e-12);
        assert_eq!(f.rank(), 3);
        let mut b = b0;
        f.solve(&mut b);
        for i in 0..m {
            // Agreement to rounding of a well-conditioned 4x4 problem.
            assert!((b[i] - x_ref[i]).abs() < 1e-10, "{b:?} vs {x_ref}");
        }
    }
}
