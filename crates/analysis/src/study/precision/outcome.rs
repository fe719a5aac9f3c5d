//! A work-precision study's table: per method and setting, the error against the reference, the
//! right-hand-side evaluations and the wall time (what it measured, [`Outcome`], is data of
//! [`crate::storage::precision_file`], which writes and reads its file).

use crate::storage::precision_file::Outcome;

/// `x` in three significant digits; "-" when NaN (not measured, or the run failed).
fn sci(x: f64) -> String {
    if x.is_nan() {
        "-".into()
    } else {
        format!("{x:.2e}")
    }
}

impl Outcome {
    /// The markdown table: one row per run.
    pub fn markdown(&self) -> String {
        let mut s = format!(
            "# Work-precision: {}\n\n\
             Reference: {} (checked against {}; their distance is the floor below). \
             {} periods of {:.6} s, {} kept; {} one-period restarts.\n\n\
             * position: largest error of {} at the kept strobe times ({});\n\
             * restart: largest one-period error from reference strobe states ({});\n\
             * force: largest error of {} over the last period, relative to its peak;\n\
             * restart force: the same over the restarted periods.\n\n",
            self.name,
            self.reference,
            self.check,
            self.periods,
            self.period,
            self.kept,
            self.restarts,
            self.position.join(", "),
            self.position_unit,
            self.position_unit,
            if self.force.is_empty() {
                "no force observable".to_string()
            } else {
                self.force.join(", ")
            },
        );
        s += "| integrator | setting | position error | restart error | force error | restart force error | RHS evaluations | steps (rejected) | wall time (s) | RHS/s | note |\n";
        s += "|---|---|---|---|---|---|---|---|---|---|---|\n";
        s += &format!(
            "| floor (check) | | {} | {} | {} | {} | | | {:.3e} (reference) | | |\n",
            sci(self.floor.position),
            sci(self.floor.restart),
            sci(self.floor.force),
            sci(self.floor.restart_force),
            self.reference_wall
        );
        for r in &self.runs {
            let note = match &r.failure {
                Some(f) => format!("failed: {}", f.replace('|', "/").replace('\n', " ")),
                None if !r.warnings.is_empty() => {
                    format!("{} step-size warning(s)", r.warnings.len())
                }
                None => String::new(),
            };
            s += &format!(
                "| {} | {:e} | {} | {} | {} | {} | {} | {} ({}) | {:.3e} | {:.3e} | {} |\n",
                r.family,
                r.setting,
                sci(r.errors.position),
                sci(r.errors.restart),
                sci(r.errors.force),
                sci(r.errors.restart_force),
                r.stats.rhs_evals,
                r.stats.accepted,
                r.stats.rejected,
                r.wall,
                r.stats.rhs_evals as f64 / r.stats.wall.as_secs_f64().max(1e-12),
                note
            );
        }
        s
    }
}
