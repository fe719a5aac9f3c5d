//! What a mechanism's tangent dynamics ([`crate::flow::tangent`]) keeps between calls: the
//! difference scheme of its Jacobian-vector products, a second workspace for the difference
//! quotients, and the contact rates at the ends of the last accepted step. Held by the
//! mechanism's flow ([`crate::flow::MechFlow`]) and made on first use.

use jointplay_solver::dynamics::Workspace;

/// The difference quotient of a mechanism's Jacobian-vector product (see the module overview).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Deserialize, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Difference {
    /// `(f(y + e v) - f(y - e v)) / 2e`: two right-hand sides per vector, error `(e / delta)^2`.
    #[default]
    Central,
    /// `(f(y + e v) - f(y)) / e` with the step's own `f(y)`: one right-hand side per vector,
    /// error `e / delta`.
    Forward,
}

impl Difference {
    pub fn name(self) -> &'static str {
        match self {
            Difference::Central => "central",
            Difference::Forward => "forward",
        }
    }
}

/// The scratch a mechanism's tangent needs: a second workspace for the difference quotients and
/// the contact rates at the ends of the last accepted step.
pub struct MechTangent {
    pub(crate) ws: Workspace,
    pub(crate) y: Vec<f64>,
    pub(crate) minus: Vec<f64>,
    pub(crate) rates0: Vec<(f64, f64, bool)>,
    pub(crate) rates1: Vec<(f64, f64, bool)>,
    pub(crate) scratch: Vec<(f64, f64, bool)>,
    pub(crate) difference: Difference,
}

impl MechTangent {
    /// The scratch of a flow of dimension `dim` whose mechanism's workspace is `ws`.
    pub fn new(ws: &Workspace, dim: usize) -> Self {
        MechTangent {
            ws: ws.clone(),
            y: vec![0.0; dim],
            minus: vec![0.0; dim],
            rates0: Vec::new(),
            rates1: Vec::new(),
            scratch: Vec::new(),
            difference: Difference::Central,
        }
    }
}
