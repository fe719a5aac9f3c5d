//! What a motion is, measured over any flow ([`crate::flow::Flow`]): each measure in one file,
//! knowing nothing of studies or files.
//!
//! * [`sections`]: N drive periods of a flow with the stroboscopic and hyperplane Poincare
//!   sections, the crossings located on the integrator's dense output.
//! * [`lyapunov`]: Lyapunov spectra through contacts and impacts (variational equations with
//!   saltation at events, Benettin's QR reorthonormalisation), and the two-trajectory estimate.
//! * [`zero_one`]: the 0-1 test for chaos (Gottwald and Melbourne).
//! * [`chaos`]: the chaos indicators of a run or a sweep value, and a classification of the
//!   motion from them (period-k, quasi-periodic, chaotic).
//! * [`periodic`]: periodic orbits of the stroboscopic map by shooting, with their Floquet
//!   multipliers.

pub mod chaos;
pub mod indicator;
pub mod lyapunov;
pub mod periodic;
pub mod registry;
pub mod sections;
pub mod zero_one;
