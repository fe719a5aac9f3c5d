//! Symmetric positive semi-definite solves that cope with rank deficiency.
//!
//! The reduced constraint matrix `S = G M^-1 G^T` is singular when constraints are redundant (a
//! planar mechanism built from 3D revolute joints, or five drives on the 4-DOF 4-UPS/RPU). Both
//! solvers here return the minimum-norm least-squares solution `x = S^+ b`. For a consistent
//! right-hand side this is the unique set of multipliers of least Euclidean norm: redundant
//! actuators share their load instead of one of them carrying none of it.
//!
//! * [`PsdSolver`], dense: Cholesky with diagonal pivoting, `P^T S P = L L^T` with `L` of size
//!   m x r, stopping when the largest remaining pivot falls below `tol` times the largest diagonal
//!   entry (Higham, *Accuracy and Stability of Numerical Algorithms*, 2nd ed., section 10.3). Then
//!   `x = S^+ b = P L (L^T L)^-2 L^T P^T b`, since `S^+ = L (L^T L)^-2 L^T` for a
//!   full-column-rank `L`. O(m^3) per factorisation. nalgebra offers no pivoted Cholesky, so it is
//!   written here.
//! * [`SparsePsd`]: LDL^T in an elimination order fixed once from the sparsity pattern, touching
//!   only the entries of the factor, with rank deficiency handled by dropping rounding-level pivots
//!   and projecting on the null space they span (the details are on the type). It defers to
//!   [`PsdSolver`] when a small pivot is not clearly a rounding-level zero. Written here rather
//!   than taken from a sparse crate: nalgebra-sparse's Cholesky needs a positive definite matrix,
//!   and neither it nor faer's sparse factorisations give the minimum-norm solution of a singular
//!   S; the kernel here is small, specialised to a pattern fixed in advance (a few hundred
//!   nonzeros for the 4-UPS/RPU), and adds no dependency to build.

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

/// Sparse LDL^T of a symmetric positive semi-definite matrix with a fixed sparsity pattern,
/// giving the same minimum-norm solution `x = S^+ b` as [`PsdSolver`].
///
/// The pattern is analysed once ([`SparsePsd::new`]): a minimum-degree elimination order is found
/// on the graph of the matrix (George & Liu, *Computer Solution of Large Sparse Positive Definite
/// Systems*, 1981, chapter 5), and the elimination graph gives the pattern of the factor, fill
/// included. For the reduced matrix of a mechanism whose bodies (the ground left out) form a tree,
/// such as the legs of a parallel platform, that order eliminates leg rows before platform rows
/// and creates no fill at all. The columns are then taken level by level up the elimination tree,
/// which leaves the factor unchanged. Each [`SparsePsd::factor`] touches only the stored entries.
///
/// Rank deficiency. The pivots come in the fixed order, so the diagonal pivoting of [`PsdSolver`]
/// is not available. A pivot `d_k <= tol * max_i S_ii` is taken as zero: column k of the unit
/// lower factor is set to `e_k` and `d_k = 0`, which drops the rest of row k of the current Schur
/// complement. For a positive semi-definite matrix every entry of that row is bounded by
/// `sqrt(d_k d_j)`; when a dropped row holds an entry above `tol * max_i S_ii` (a pivot that is
/// small but not a rounding-level zero, near a singular configuration), dropping it would perturb S
/// more than the pivoted factorisation ever does, and [`SparsePsd::factor`] reports failure so
/// that the caller can use [`PsdSolver`] instead. Otherwise the factorisation is exact for a matrix
/// `S~ = L D L^T` within that bound of S, and `null(S~)` is spanned by `n_k = L^-T e_k` for the
/// dropped k (`S~ n_k = L D e_k = 0`). With N an orthonormal basis of those vectors (modified
/// Gram-Schmidt, twice) and `P = I - N N^T` the orthogonal projector on `range(S~)`, the solve
/// computes `x = P L^-T D^+ L^-1 P b`: the first projection makes the right-hand side consistent
/// (least squares), the triangular solves give one solution, and the second projection removes its
/// null-space part, leaving the minimum-norm one, i.e. `S~^+ b`. For a full-rank matrix both
/// projections are the identity and this is the plain LDL^T solve.
#[derive(Debug, Clone, Default)]
pub struct SparsePsd {
    n: usize,
    /// perm[k]: original index of the k-th pivot; iperm its inverse.
    perm: Vec<usize>,
    iperm: Vec<usize>,
    /// Column k (pivot order) is stored at colptr[k]..colptr[k+1]: its diagonal, then its
    /// below-diagonal entries at rows rowidx[..] (pivot order, ascending).
    colptr: Vec<usize>,
    rowidx: Vec<usize>,
    /// For column k, upd[upd_ptr[k]..upd_ptr[k+1]] lists the storage index, counted from
    /// colptr[k + 1], that receives the Schur update of each pair (p <= q) of its below-diagonal
    /// rows, p outer, q inner.
    upd_ptr: Vec<usize>,
    upd: Vec<u32>,
    /// For column k and each of its below-diagonal rows p (index a, at runs[colptr[k] - k + a]):
    /// where the targets of the pairs (p, q >= p) start, counted from colptr[k + 1], when they lie
    /// one after another in storage (the diagonal of p, then its rows q in order), as they do
    /// along a chain of the elimination tree; u32::MAX when they do not. Contiguous targets need
    /// no index loads or bounds checks per update.
    runs: Vec<u32>,
    /// The assembled matrix (lower triangle, in the storage above), overwritten by the factor:
    /// 1/d_k (0 for a dropped pivot) in the diagonal slots, L below.
    s: Vec<f64>,
    /// Slots outside the pattern of the matrix (fill of the factor, and the diagonal of an index
    /// in no group), which the assembly leaves alone and the factorisation clears first.
    fill: Vec<usize>,
    /// Dropped pivots, and an orthonormal basis of the null space of the factored matrix, one
    /// vector of length n after another (pivot order).
    dropped: Vec<usize>,
    null: Vec<f64>,
    x: Vec<f64>,
    t: Vec<f64>,
    rank: usize,
}

impl SparsePsd {
    /// Symbolic analysis of the n x n symmetric pattern in which every pair of indices that share
    /// a group of `cliques` may be nonzero (plus the diagonal).
    pub fn new(n: usize, cliques: &[Vec<usize>]) -> Self {
        use std::collections::BTreeSet;
        let mut adj: Vec<BTreeSet<usize>> = vec![BTreeSet::new(); n];
        let mut grouped = vec![false; n];
        for c in cliques {
            for &i in c {
                grouped[i] = true;
                for &j in c {
                    if i != j {
                        adj[i].insert(j);
                    }
                }
            }
        }
        let pattern = adj.clone();
        // Minimum degree on the elimination graph, ties to the lowest index. Eliminating v makes
        // its remaining neighbours a clique; they are the pattern of its column of L.
        let mut alive = vec![true; n];
        let mut order = Vec::with_capacity(n);
        let mut cols: Vec<Vec<usize>> = Vec::with_capacity(n);
        for _ in 0..n {
            let Some(v) = (0..n)
                .filter(|&v| alive[v])
                .min_by_key(|&v| (adj[v].len(), v))
            else {
                break;
            };
            let nb: Vec<usize> = adj[v].iter().copied().collect();
            for &u in &nb {
                adj[u].remove(&v);
                adj[u].extend(nb.iter().copied().filter(|&w| w != u));
            }
            adj[v].clear();
            alive[v] = false;
            order.push(v);
            cols.push(nb);
        }
        let mut iperm = vec![0; n];
        for (k, &v) in order.iter().enumerate() {
            iperm[v] = k;
        }
        // Any order in which every column comes after its children in the elimination tree (the
        // parent of a column is its first row below the diagonal) gives the same factor (Liu,
        // SIAM J. Matrix Anal. Appl. 11:134-172, 1990). Taking the columns level by level from
        // the leaves interleaves independent subtrees, such as the legs of a parallel mechanism,
        // so that the processor can overlap their dependency chains (measured: the triangular
        // solves about 10% faster; the factorisation unchanged).
        let parent: Vec<Option<usize>> = cols
            .iter()
            .map(|c| c.iter().map(|&v| iperm[v]).min())
            .collect();
        let mut children = vec![0usize; n];
        for p in parent.iter().flatten() {
            children[*p] += 1;
        }
        let mut queue: std::collections::VecDeque<usize> =
            (0..n).filter(|&k| children[k] == 0).collect();
        let mut level_order = Vec::with_capacity(n);
        while let Some(k) = queue.pop_front() {
            level_order.push(k);
            if let Some(p) = parent[k] {
                children[p] -= 1;
                if children[p] == 0 {
                    queue.push_back(p);
                }
            }
        }
        debug_assert_eq!(level_order.len(), n);
        let cols: Vec<Vec<usize>> = level_order.iter().map(|&k| cols[k].clone()).collect();
        let order: Vec<usize> = level_order.iter().map(|&k| order[k]).collect();
        for (k, &v) in order.iter().enumerate() {
            iperm[v] = k;
        }
        let mut colptr = Vec::with_capacity(n + 1);
        let mut rowidx = Vec::new();
        for (k, c) in cols.iter().enumerate() {
            colptr.push(rowidx.len());
            rowidx.push(k);
            let mut c: Vec<usize> = c.iter().map(|&v| iperm[v]).collect();
            c.sort_unstable();
            assert!(
                c.iter().all(|&i| i > k),
                "pivot order breaks the elimination tree"
            );
            rowidx.extend(c);
        }
        colptr.push(rowidx.len());
        let mut me = SparsePsd {
            n,
            perm: order,
            iperm,
            colptr,
            rowidx,
            ..Default::default()
        };
        let mut upd_ptr = Vec::with_capacity(n + 1);
        let mut upd = Vec::new();
        let mut runs = Vec::new();
        for k in 0..n {
            upd_ptr.push(upd.len());
            let pat = &me.rowidx[me.colptr[k] + 1..me.colptr[k + 1]];
            let base = me.colptr[k + 1];
            for (a, &p) in pat.iter().enumerate() {
                let start = me.slot(p, p) - base;
                let mut contiguous = true;
                for (b, &q) in pat[a..].iter().enumerate() {
                    let s = me.slot(q, p) - base;
                    contiguous &= s == start + b;
                    upd.push(u32::try_from(s).expect("factor too large"));
                }
                runs.push(if contiguous {
                    u32::try_from(start).expect("factor too large")
                } else {
                    u32::MAX
                });
            }
        }
        upd_ptr.push(upd.len());
        me.upd_ptr = upd_ptr;
        me.upd = upd;
        me.runs = runs;
        let nnz = me.rowidx.len();
        me.s = vec![0.0; nnz];
        for k in 0..n {
            let j = me.perm[k];
            if !grouped[j] {
                me.fill.push(me.colptr[k]);
            }
            for idx in me.colptr[k] + 1..me.colptr[k + 1] {
                if !pattern[j].contains(&me.perm[me.rowidx[idx]]) {
                    me.fill.push(idx);
                }
            }
        }
        me.x = vec![0.0; n];
        me.t = vec![0.0; n];
        me
    }

    /// Storage index of entry (i, j), i >= j, in pivot order.
    fn slot(&self, i: usize, j: usize) -> usize {
        let c0 = self.colptr[j];
        let pat = &self.rowidx[c0..self.colptr[j + 1]];
        c0 + pat
            .binary_search(&i)
            .expect("entry outside the symbolic pattern")
    }

    /// Order of the matrix.
    pub fn dim(&self) -> usize {
        self.n
    }

    /// Storage index of entry (i, j) (original indices, either triangle) in
    /// [`SparsePsd::values_mut`].
    /// Panics when the pair shares no group of the pattern.
    pub fn index(&self, i: usize, j: usize) -> usize {
        let (pi, pj) = (self.iperm[i], self.iperm[j]);
        self.slot(pi.max(pj), pi.min(pj))
    }

    /// Number of stored entries (diagonal included) of the factor.
    pub fn nnz(&self) -> usize {
        self.rowidx.len()
    }

    /// The matrix entries to assemble, indexed by [`SparsePsd::index`]. Every entry of the
    /// pattern (diagonal included) must be written before each [`SparsePsd::factor`], which
    /// overwrites them with the factor.
    pub fn values_mut(&mut self) -> &mut [f64] {
        &mut self.s
    }

    /// Numerical rank found by the last successful [`SparsePsd::factor`].
    pub fn rank(&self) -> usize {
        self.rank
    }

    /// The assembled matrix as a dense row-major n x n matrix (original order); before
    /// [`SparsePsd::factor`] only.
    pub fn to_dense(&self, out: &mut [f64]) {
        let n = self.n;
        out[..n * n].fill(0.0);
        for k in 0..n {
            let j = self.perm[k];
            for idx in self.colptr[k]..self.colptr[k + 1] {
                let i = self.perm[self.rowidx[idx]];
                out[i * n + j] = self.s[idx];
                out[j * n + i] = self.s[idx];
            }
        }
    }

    /// Factors the assembled matrix, pivots below `tol` times the largest diagonal entry taken as
    /// zero. Returns false, leaving no usable factor, when a dropped pivot's row is not negligible
    /// in that sense or the matrix holds NaN (see the type's documentation).
    pub fn factor(&mut self, tol: f64) -> bool {
        for &f in &self.fill {
            self.s[f] = 0.0;
        }
        let n = self.n;
        let cp = &self.colptr;
        // Largest diagonal entry (NaN ignored, as by f64::max), in four independent chains.
        let mut mx = [0.0f64; 4];
        for (i, &c) in cp[..n].iter().enumerate() {
            let v = self.s[c];
            if v > mx[i % 4] {
                mx[i % 4] = v;
            }
        }
        let dmax = mx[0].max(mx[1]).max(mx[2].max(mx[3]));
        let thresh = tol * dmax.max(f64::MIN_POSITIVE);
        let l = &mut self.s;
        let mut rank = 0;
        self.dropped.clear();
        for k in 0..n {
            let (c0, c1) = (cp[k], cp[k + 1]);
            let d = l[c0];
            if d.is_nan() {
                return false;
            }
            if d <= thresh {
                if !l[c0 + 1..c1].iter().all(|v| v.abs() <= thresh) {
                    return false;
                }
                l[c0..c1].fill(0.0);
                self.dropped.push(k);
                continue;
            }
            let m = c1 - c0 - 1;
            // Entries of later columns only: the trailing part of the storage.
            let (done, trail) = l.split_at_mut(c1);
            let t = &mut self.t[..m];
            let dinv = 1.0 / d;
            done[c0] = dinv;
            let lk = &mut done[c0 + 1..c1];
            // Keep the unscaled column (L_pk d_k) while scaling it, in one pass.
            for (v, ti) in lk.iter_mut().zip(t.iter_mut()) {
                *ti = *v;
                *v *= dinv;
            }
            // Schur update of the trailing entries that column k reaches:
            // S_qp -= L_qk d_k L_pk for every pair p <= q of its rows.
            let mut upd = &self.upd[self.upd_ptr[k]..self.upd_ptr[k + 1]];
            let runs = &self.runs[c0 - k..c0 - k + m];
            for (a, (&ta, &run)) in t.iter().zip(runs).enumerate() {
                let (now, rest) = upd.split_at(m - a);
                if run != u32::MAX {
                    let dst = &mut trail[run as usize..run as usize + (m - a)];
                    for (x, &lq) in dst.iter_mut().zip(&lk[a..]) {
                        *x -= lq * ta;
                    }
                } else {
                    for (&tg, &lq) in now.iter().zip(&lk[a..]) {
                        trail[tg as usize] -= lq * ta;
                    }
                }
                upd = rest;
            }
            rank += 1;
        }
        self.rank = rank;
        self.null_basis();
        true
    }

    /// Orthonormal basis of span{L^-T e_k} over the dropped pivots k.
    fn null_basis(&mut self) {
        let n = self.n;
        self.null.clear();
        self.null.resize(self.dropped.len() * n, 0.0);
        for (v, &k) in self.dropped.iter().enumerate() {
            let (done, rest) = self.null.split_at_mut(v * n);
            let x = &mut rest[..n];
            // Back substitution L^T x = e_k; x_j = 0 for j > k.
            x[k] = 1.0;
            for j in (0..k).rev() {
                let mut s = 0.0;
                for idx in self.colptr[j] + 1..self.colptr[j + 1] {
                    s -= self.s[idx] * x[self.rowidx[idx]];
                }
                x[j] = s;
            }
            for _ in 0..2 {
                for w in done.chunks_exact(n) {
                    let c: f64 = w.iter().zip(x.iter()).map(|(a, b)| a * b).sum();
                    for (xi, wi) in x.iter_mut().zip(w) {
                        *xi -= c * wi;
                    }
                }
            }
            let norm = x.iter().map(|a| a * a).sum::<f64>().sqrt();
            for xi in x.iter_mut() {
                *xi /= norm;
            }
        }
    }

    fn project(null: &[f64], x: &mut [f64]) {
        for w in null.chunks_exact(x.len()) {
            let c: f64 = w.iter().zip(x.iter()).map(|(a, b)| a * b).sum();
            for (xi, wi) in x.iter_mut().zip(w) {
                *xi -= c * wi;
            }
        }
    }

    /// Solves `S x = b` in place with the last factorisation (minimum-norm least squares when S
    /// is singular).
    pub fn solve(&mut self, b: &mut [f64]) {
        let n = self.n;
        let (cp, ri, l) = (&self.colptr, &self.rowidx, &self.s);
        let x = &mut self.x;
        for k in 0..n {
            x[k] = b[self.perm[k]];
        }
        Self::project(&self.null, x);
        for k in 0..n {
            let (c0, c1) = (cp[k] + 1, cp[k + 1]);
            let xk = x[k];
            for (&i, &v) in ri[c0..c1].iter().zip(&l[c0..c1]) {
                x[i] -= v * xk;
            }
        }
        for k in 0..n {
            x[k] *= l[cp[k]];
        }
        for k in (0..n).rev() {
            // Two partial sums halve the chain of dependent subtractions.
            let (c0, c1) = (cp[k] + 1, cp[k + 1]);
            let (rows, vals) = (&ri[c0..c1], &l[c0..c1]);
            let mut s = [x[k], 0.0];
            for (i2, v2) in rows.chunks(2).zip(vals.chunks(2)) {
                for j in 0..i2.len() {
                    s[j] -= v2[j] * x[i2[j]];
                }
            }
            x[k] = s[0] + s[1];
        }
        Self::project(&self.null, x);
        for k in 0..n {
            b[self.perm[k]] = x[k];
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

    /// Rows of a chain of `nbody` bodies of 3 coordinates each, every row acting on two
    /// neighbours (row i on bodies i/2 and i/2 + 1), plus `extra` rows that combine earlier ones:
    /// a Gram matrix with the pattern of a tree and a known rank.
    fn chain(nbody: usize, extra: usize) -> (Vec<f64>, usize, Vec<Vec<usize>>, usize) {
        let mut seed = 12345u64;
        let mut rnd = || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        let nc = 3 * nbody;
        let mut rows: Vec<(usize, Vec<f64>)> = Vec::new();
        for i in 0..2 * (nbody - 1) {
            let b = i / 2;
            let mut g = vec![0.0; nc];
            for c in 0..6 {
                g[3 * b + c] = rnd();
            }
            rows.push((b, g));
        }
        for e in 0..extra {
            // Twice a row plus its neighbour on the same body pair: redundant.
            let (b, g0) = rows[2 * e].clone();
            let g1 = &rows[2 * e + 1].1;
            let g = g0.iter().zip(g1).map(|(x, y)| 2.0 * x - y).collect();
            rows.push((b, g));
        }
        let m = rows.len();
        let mut s = vec![0.0; m * m];
        for i in 0..m {
            for j in 0..m {
                s[i * m + j] = rows[i].1.iter().zip(&rows[j].1).map(|(a, b)| a * b).sum();
            }
        }
        let mut cliques = vec![Vec::new(); nbody];
        for (i, (b, _)) in rows.iter().enumerate() {
            cliques[*b].push(i);
            cliques[b + 1].push(i);
        }
        (s, m, cliques, 2 * (nbody - 1))
    }

    fn sparse_from(s: &[f64], m: usize, cliques: &[Vec<usize>]) -> SparsePsd {
        let mut f = SparsePsd::new(m, cliques);
        for i in 0..m {
            for j in 0..=i {
                if s[i * m + j] != 0.0 {
                    let k = f.index(i, j);
                    f.values_mut()[k] = s[i * m + j];
                }
            }
        }
        f
    }

    #[test]
    fn sparse_solve_is_the_pseudo_inverse_with_and_without_redundancy() {
        for extra in [0, 1, 3] {
            let (s, m, cliques, rank) = chain(6, extra);
            let mut f = sparse_from(&s, m, &cliques);
            assert!(f.factor(1e-10));
            assert_eq!(f.rank(), rank);
            // An inconsistent right-hand side: S^+ b is the minimum-norm least-squares solution.
            let b0: Vec<f64> = (0..m).map(|i| (i as f64 * 0.7).sin()).collect();
            let pinv = DMatrix::from_row_slice(m, m, &s)
                .pseudo_inverse(1e-10)
                .unwrap();
            let x_ref = &pinv * nalgebra::DVector::from_vec(b0.clone());
            let mut b = b0;
            f.solve(&mut b);
            let scale = x_ref.amax();
            for i in 0..m {
                // Rounding of well-conditioned problems of size 10..13.
                assert!(
                    (b[i] - x_ref[i]).abs() < 1e-9 * scale,
                    "extra {extra}: {b:?} vs {x_ref}"
                );
            }
        }
    }

    #[test]
    fn sparse_factor_defers_a_small_pivot_with_a_sizeable_coupling() {
        // [[e, sqrt(e)], [sqrt(e), 2]] is positive definite; its first pivot e is below the
        // threshold, but dropping it would discard the coupling sqrt(e) >> 1e-10 * 2.
        let e: f64 = 1e-12;
        let s = [e, e.sqrt(), e.sqrt(), 2.0];
        let mut f = sparse_from(&s, 2, &[vec![0, 1]]);
        let mut d = [0.0; 4];
        f.to_dense(&mut d);
        assert_eq!(d, s);
        assert!(!f.factor(1e-10));
    }

    #[test]
    fn sparse_fill_is_cleared_between_factorisations() {
        // Rows on a ring of bodies (row i on bodies i and i + 1 mod 5, 3 coordinates each): the
        // row graph is a cycle, whose elimination creates fill.
        let nbody = 5;
        let rows: Vec<Vec<f64>> = (0..nbody)
            .map(|i| {
                let mut g = vec![0.0; 3 * nbody];
                for c in 0..3 {
                    g[3 * i + c] = 1.0 + 0.1 * (i + c) as f64;
                    g[3 * ((i + 1) % nbody) + c] = 0.5 - 0.2 * c as f64;
                }
                g
            })
            .collect();
        let m = rows.len();
        let s: Vec<f64> = (0..m * m)
            .map(|k| {
                rows[k / m]
                    .iter()
                    .zip(&rows[k % m])
                    .map(|(a, b)| a * b)
                    .sum()
            })
            .collect();
        let cliques: Vec<Vec<usize>> = (0..nbody)
            .map(|b| vec![(b + nbody - 1) % nbody, b])
            .collect();
        let mut f = sparse_from(&s, m, &cliques);
        assert!(f.nnz() > m + m, "the ring should fill in");
        let x_ref = DMatrix::from_row_slice(m, m, &s)
            .lu()
            .solve(&nalgebra::DVector::from_element(m, 1.0))
            .unwrap();
        for _ in 0..2 {
            // Assemble again over the previous factor, as every evaluation does.
            for i in 0..m {
                for j in 0..=i {
                    if s[i * m + j] != 0.0 {
                        let k = f.index(i, j);
                        f.values_mut()[k] = s[i * m + j];
                    }
                }
            }
            assert!(f.factor(1e-10));
            let mut b = vec![1.0; m];
            f.solve(&mut b);
            for i in 0..m {
                assert!(
                    (b[i] - x_ref[i]).abs() < 1e-10 * x_ref.amax(),
                    "{b:?} vs {x_ref}"
                );
            }
        }
    }
}
