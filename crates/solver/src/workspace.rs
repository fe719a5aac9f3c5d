//! The workspace of a model: scratch memory of the right-hand side, allocated once per run so
//! that no step allocates, and the results of the last evaluation (multipliers, accelerations,
//! constraint residuals, contact points) that recorders and guards read. The model itself
//! ([`crate::model::Model`]) is immutable; everything a run writes while it evaluates lives here.
//! The contact-onset history is not scratch: it is part of the run's state
//! ([`crate::state::HybridState`]) and is kept here only while the run is stepping.

use nalgebra::{Matrix3, Vector3};

use crate::clearance::{ContactEval, Resultant};
use crate::kin::{GROUND, Kin};
use crate::linalg::{PsdSolver, SparsePsd};
use crate::model::Model;

/// One constraint row: Jacobian blocks (v, w) of its two bodies.
#[derive(Debug, Clone, Copy)]
pub struct Row {
    pub a: usize,
    pub b: usize,
    pub ja: [f64; 6],
    pub jb: [f64; 6],
}

/// Scratch memory of the right-hand side; also holds the last evaluation's results
/// (multipliers, accelerations, constraint residuals) for the recorders.
#[derive(Debug, Clone)]
pub struct Workspace {
    /// Per body, with the ground appended at index nb.
    pub kin: Vec<Kin>,
    /// Inverse global inertia per body.
    pub inv_j: Vec<Matrix3<f64>>,
    /// Applied generalized forces per body: force (N) and torque about the COM (N m).
    pub q: Vec<[f64; 6]>,
    /// M^-1 Q per body.
    pub minv_q: Vec<[f64; 6]>,
    pub rows: Vec<Row>,
    /// Phi, Phi' (= G v - s') and the Baumgarte right-hand side per row.
    pub phi: Vec<f64>,
    pub phi_dot: Vec<f64>,
    pub rhs: Vec<f64>,
    /// Jacobian blocks G_i^k and W_i^k = M_k^-1 G_i^k^T of the rows acting on each body, in the
    /// order of [`Coupling`]'s incidence list.
    pub(crate) inc_j: Vec<[f64; 6]>,
    pub(crate) inc_w: Vec<[f64; 6]>,
    /// The sparse factorisation of the reduced matrix.
    pub(crate) sparse: SparsePsd,
    /// The dense path (reference, and fallback near singular configurations): M^-1 G^T per row
    /// (blocks for a and b), the dense reduced matrix (allocated on first use) and its solver.
    pub(crate) wrows: Vec<([f64; 6], [f64; 6])>,
    pub(crate) s: Vec<f64>,
    pub(crate) solver: PsdSolver,
    /// Whether the last evaluation solved on the dense path.
    pub(crate) dense_used: bool,
    /// Multipliers of the last evaluation.
    pub lambda: Vec<f64>,
    /// Accelerations of the last evaluation per body: a (m/s^2), alpha (rad/s^2).
    pub acc: Vec<[f64; 6]>,
    /// Numerical rank of the reduced matrix at the last evaluation.
    pub rank: usize,
    /// Contact points of the clearance joints at the last evaluation.
    pub contacts: Vec<ContactEval>,
    /// Resultant contact wrench per clearance joint at the last evaluation.
    pub resultants: Vec<Resultant>,
    /// Approach velocity at the onset of each contact (m/s); NaN while out of contact. This is
    /// history, updated only on accepted steps ([`Model::update_onsets`]).
    pub onset: Vec<f64>,
    /// Contact geometry at the start of the last accepted step (scratch for onset location).
    pub(crate) contacts0: Vec<ContactEval>,
    /// The LuGre contacts' bristle deflections (m) read from the state by the kinematics, and
    /// their rates (m/s) from the last evaluation of the contact forces.
    pub bristle: Vec<f64>,
    pub bristle_rate: Vec<f64>,
}

impl Workspace {
    /// Solves `S x = b` in place with the reduced matrix S = G M^-1 G^T factored by the last
    /// evaluation of the accelerations (minimum-norm when constraints are redundant).
    pub(crate) fn solve_reduced(&mut self, b: &mut [f64]) {
        if self.dense_used {
            self.solver.solve(b);
        } else {
            self.sparse.solve(b);
        }
    }

    pub fn new(m: &Model) -> Self {
        let nb = m.nb();
        let nr = m.n_rows;
        let zero_row = Row {
            a: GROUND,
            b: GROUND,
            ja: [0.0; 6],
            jb: [0.0; 6],
        };
        Workspace {
            kin: vec![Kin::default(); nb + 1],
            inv_j: vec![Matrix3::zeros(); nb],
            q: vec![[0.0; 6]; nb],
            minv_q: vec![[0.0; 6]; nb],
            rows: vec![zero_row; nr],
            phi: vec![0.0; nr],
            phi_dot: vec![0.0; nr],
            rhs: vec![0.0; nr],
            inc_j: vec![[0.0; 6]; m.coupling.inc.len()],
            inc_w: vec![[0.0; 6]; m.coupling.inc.len()],
            sparse: m.coupling.solver.clone(),
            wrows: vec![([0.0; 6], [0.0; 6]); nr],
            s: Vec::new(),
            solver: PsdSolver::new(),
            dense_used: false,
            lambda: vec![0.0; nr],
            acc: vec![[0.0; 6]; nb],
            rank: 0,
            contacts: vec![ContactEval::default(); m.n_contacts],
            resultants: vec![Resultant::default(); m.clearances.len()],
            onset: vec![f64::NAN; m.n_contacts],
            contacts0: vec![ContactEval::default(); m.n_contacts],
            bristle: vec![0.0; m.n_bristle],
            bristle_rate: vec![0.0; m.n_bristle],
        }
    }
}

impl Workspace {
    /// Whether the last evaluation solved the reduced system on the dense path (see
    /// [`SparsePsd::factor`](SparsePsd::factor) for when the sparse one defers to
    /// it).
    pub fn solved_densely(&self) -> bool {
        self.dense_used
    }
}

/// `M_b^-1 j` for a Jacobian block `j` of body `b` (zero for the ground).
pub(crate) fn minv_block(m: &Model, ws: &Workspace, b: usize, j: &[f64; 6]) -> [f64; 6] {
    if b == GROUND {
        return [0.0; 6];
    }
    let mi = 1.0 / m.bodies[b].mass;
    let t = ws.inv_j[b] * Vector3::new(j[3], j[4], j[5]);
    [j[0] * mi, j[1] * mi, j[2] * mi, t.x, t.y, t.z]
}
