//! The constrained Newton-Euler equations and everything evaluated on them, in stages.
//!
//! For body k with mass m_k, global inertia J_k = A_k J'_k A_k^T, centre-of-mass velocity v_k and
//! angular velocity w_k (global):
//!
//! ```text
//!   m_k a_k = f_k - (G^T lambda)_k,          J_k alpha_k = n_k - w_k x J_k w_k - (G^T lambda)_k
//!   G a = gamma - 2 alpha_B Phi' - beta_B^2 Phi                      (Baumgarte, 1972)
//! ```
//!
//! where G is the constraint Jacobian with respect to the velocities (6 columns per body),
//! gamma = -(dG/dt) v + s''(t) the velocity-quadratic terms, and alpha_B, beta_B the Baumgarte
//! parameters. With the block-diagonal mass matrix the multipliers follow from the reduced system
//! `S lambda = G M^-1 Q - rhs` with `S = G M^-1 G^T`, and then `a = M^-1 (Q - G^T lambda)`; when
//! constraints are redundant S is singular and lambda is its minimum-norm solution `S^+ b`.
//!
//! One evaluation runs the stages in order, each reading what the earlier ones left in the
//! [`Workspace`] (as MuJoCo's `mj_forward` runs its own), composed in `forward`:
//!
//! | stage | file | fills |
//! |---|---|---|
//! | kinematics | `kinematics.rs` | r, A, v, w per body (`ws.kin`) |
//! | applied forces | `forces.rs` | Q = (f, n - w x J w) and J^-1 per body (`ws.q`, `ws.inv_j`) |
//! | contact forces | `contact.rs` | each contact's delta, delta', normal, points, and its force into Q |
//! | constraint rows | `constraints.rs` | G, Phi, Phi', Baumgarte rhs (`ws.rows`, `ws.phi`, ...) |
//! | reduced solve | `solve.rs` | lambda and a (`ws.lambda`, `ws.acc`) |
//!
//! Around them: `onset.rs` (the onset memory updated after each accepted step and its tangent),
//! `events.rs` (the contact events), `stiff.rs` (the contacts' stiff directions and Jacobian for
//! the stiff integrators), `assemble.rs` (putting a state on the constraints), `diagnostics.rs`
//! (rank analysis, drift, energy, reactions), `mechanism.rs` (the model as an
//! [`OdeSystem`](crate::ode::OdeSystem)) and `blocks.rs`, the leaf of small helpers every stage
//! may use. The stages import each other without cycles (`tests/module_graph.rs` checks it); the
//! methods all extend [`Model`](crate::model::Model).

mod assemble;
mod blocks;
mod constraints;
mod contact;
mod diagnostics;
mod events;
mod forces;
mod forward;
mod kinematics;
mod mechanism;
mod onset;
mod solve;
mod stiff;

pub use assemble::AssemblyReport;
pub use diagnostics::Structure;
pub use kinematics::rotation;
pub use mechanism::Mechanism;
pub use onset::onset_rate_tangent;
pub use solve::RANK_TOL;

pub use crate::workspace::{Row, Workspace};
