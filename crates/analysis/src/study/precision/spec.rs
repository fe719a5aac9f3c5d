//! The `[precision]` table of an analysis study (format in book/src/reference/study.md): the
//! methods, the tolerances or steps of each, the reference, and the observables compared.

use jointplay_solver::ode::Method;
use serde::Deserialize;

/// The `[precision]` table of an analysis study (every field optional).
#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PrecisionSpec {
    /// Observables compared at the strobe times (default: those in m or rad, else all).
    #[serde(default)]
    pub position: Vec<String>,
    /// Observables compared over the last period (default: those in N).
    #[serde(default)]
    pub force: Vec<String>,
    /// One-period restarts from reference strobe states (default: up to 10).
    #[serde(default)]
    pub restarts: Option<usize>,
    /// The reference method (default dop853 at 1e-12) and the check that confirms it (default
    /// dopri5 at 1e-12).
    #[serde(default)]
    pub reference: Option<MethodSpec>,
    #[serde(default)]
    pub check: Option<MethodSpec>,
    /// Absolute tolerance of the adaptive runs as a multiple of their relative tolerance.
    #[serde(default)]
    pub atol_scale: Option<f64>,
    /// Runs shorter than this (s) are repeated and the fastest repeat kept.
    #[serde(default)]
    pub min_time: Option<f64>,
    /// The integrators and their settings (default: every family over a standard range).
    #[serde(default)]
    pub methods: Vec<FamilySpec>,
}

/// One method: a family and its setting (the step in s, or the relative tolerance).
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MethodSpec {
    pub integrator: String,
    pub setting: f64,
}

/// One family over several settings.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FamilySpec {
    pub integrator: String,
    pub settings: Vec<f64>,
}

/// The default runs: each family with the settings its integrator's descriptor gives for them
/// ([`Method::default_settings`]: steps as multiples of `base_step`, the flow's own step or
/// 1/1000 of its period; tolerances by decades), in registry order; a family whose descriptor
/// gives none is left out.
pub(crate) fn default_runs(base_step: f64) -> Vec<(&'static str, Vec<f64>)> {
    Method::families()
        .map(|f| (f, Method::default_settings(f, base_step)))
        .filter(|(_, settings)| !settings.is_empty())
        .collect()
}
