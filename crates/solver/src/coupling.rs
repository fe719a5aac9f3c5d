//! The sparsity of the reduced matrix `S = G M^-1 G^T` of a mechanism's constraints: which rows
//! act on which body, the terms each stored entry of S is written from, and the symbolic
//! factorisation that follows from that pattern. Built once when a model is compiled; knows
//! constraint rows only by the bodies they act on.

use crate::kin::GROUND;
use crate::linalg::SparsePsd;

/// A block of consecutive constraint rows `first..first + n` acting on bodies `a` and `b`
/// ([`GROUND`] for the ground).
#[derive(Debug, Clone, Copy)]
pub struct RowBlock {
    pub a: usize,
    pub b: usize,
    pub first: usize,
    pub n: usize,
    /// The rows constrain rotation only (zero translational Jacobian): a perpendicularity or an
    /// angle.
    pub rotation_only: bool,
}

/// Which constraint rows act on which body: fixed by the scene, it fixes the sparsity of the
/// reduced matrix `S = G M^-1 G^T`, whose entry (i, j) is nonzero only when rows i and j act on a
/// common body (the ground aside). Built once when the model is compiled.
#[derive(Debug, Clone, Default)]
pub struct Coupling {
    /// Rows acting on body k: `inc[inc_ptr[k]..inc_ptr[k + 1]]`, ascending, each as (row, side)
    /// with side 0 when k is the row's body a and 1 when it is its body b.
    pub(crate) inc_ptr: Vec<usize>,
    pub(crate) inc: Vec<(usize, u8)>,
    /// The terms G_u^k M_k^-1 G_v^k^T of S as (storage index in the sparse solver, incidence u,
    /// incidence v), one per pair u <= v of rows on a body: `first` holds the first term of each
    /// entry, in storage order, and `extra` the second one of the entries whose rows share both
    /// bodies. Writing the first terms and adding the others fills S without clearing it. Each
    /// list comes in two parts: [0] terms with a row that constrains rotation only (a
    /// perpendicularity or an angle: zero translational Jacobian, so only the rotational halves
    /// contribute, with the same value), [1] the others.
    pub(crate) first: [Vec<[u32; 3]>; 2],
    pub(crate) extra: [Vec<[u32; 3]>; 2],
    /// The symbolic factorisation (elimination order and pattern of the factor).
    pub(crate) solver: SparsePsd,
}

impl Coupling {
    /// The coupling of the rows of `blocks` (n_rows in all) among nb bodies.
    pub fn new(nb: usize, blocks: &[RowBlock], n_rows: usize) -> Self {
        let mut on_body: Vec<Vec<(usize, u8)>> = vec![Vec::new(); nb];
        let mut rot_only = vec![false; n_rows];
        for &RowBlock {
            a,
            b,
            first,
            n,
            rotation_only,
        } in blocks
        {
            for i in first..first + n {
                rot_only[i] = rotation_only;
                for (k, side) in [(a, 0), (b, 1)] {
                    if k != GROUND {
                        on_body[k].push((i, side));
                    }
                }
            }
        }
        for rows in &mut on_body {
            rows.sort_unstable();
        }
        let cliques: Vec<Vec<usize>> = on_body
            .iter()
            .map(|rows| rows.iter().map(|r| r.0).collect())
            .collect();
        let solver = SparsePsd::new(n_rows, &cliques);
        let mut inc_ptr = vec![0];
        let mut inc = Vec::new();
        let mut terms = Vec::new();
        for rows in &on_body {
            let u0 = inc.len();
            for (u, ru) in rows.iter().enumerate() {
                for (v, rv) in rows.iter().enumerate().skip(u) {
                    let slot = solver.index(ru.0, rv.0);
                    let full = !(rot_only[ru.0] || rot_only[rv.0]);
                    terms.push((
                        [slot, u0 + u, u0 + v].map(|x| u32::try_from(x).unwrap()),
                        full,
                    ));
                }
            }
            inc.extend_from_slice(rows);
            inc_ptr.push(inc.len());
        }
        terms.sort_unstable();
        let (mut first, mut extra) = ([Vec::new(), Vec::new()], [Vec::new(), Vec::new()]);
        for (i, (tm, full)) in terms.iter().enumerate() {
            if i > 0 && terms[i - 1].0[0] == tm[0] {
                extra[*full as usize].push(*tm);
            } else {
                first[*full as usize].push(*tm);
            }
        }
        Coupling {
            inc_ptr,
            inc,
            first,
            extra,
            solver,
        }
    }
}
