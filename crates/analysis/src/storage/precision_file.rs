//! What a work-precision study measured ([`Outcome`]: per method and setting, the error against
//! the reference, the right-hand-side evaluations and the wall time) and its file (written
//! atomically, read back for figures and reports).

use std::path::{Path, PathBuf};
use std::time::Duration;

use jointplay_solver::ode::Stats;

use crate::storage::h5::{
    f64_attr, h5err, read_attr, read_str, read_strings, str_attr, u64_attr, write_atomically,
    write_strings, write1,
};
use crate::{Error, Result};

/// The error measures of one run (NaN where not measured).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Errors {
    pub position: f64,
    pub restart: f64,
    pub force: f64,
    pub restart_force: f64,
}

/// One tested run.
#[derive(Debug, Clone)]
pub struct RunRecord {
    pub family: String,
    pub setting: f64,
    pub integrator: String,
    pub errors: Errors,
    /// Fastest repeat (s) and how many repeats were run.
    pub wall: f64,
    pub repeats: usize,
    pub stats: Stats,
    /// None: finished; else the failure message.
    pub failure: Option<String>,
    pub warnings: Vec<String>,
}

/// What a work-precision run produced.
#[derive(Debug, Clone)]
pub struct Outcome {
    pub name: String,
    pub reference: String,
    pub check: String,
    /// Distance of the check from the reference, per measure.
    pub floor: Errors,
    pub reference_wall: f64,
    pub runs: Vec<RunRecord>,
    pub position: Vec<String>,
    pub force: Vec<String>,
    pub position_unit: String,
    pub restarts: usize,
    pub periods: usize,
    pub kept: usize,
    pub period: f64,
}

impl Outcome {
    /// Writes `dir/<name>.h5` (layout in book/src/reference/hdf5.md), recording the study's
    /// TOML text and its file.
    pub fn write(&self, dir: &Path, study_text: &str, study_file: &Path) -> Result<PathBuf> {
        let file = dir.join(format!("{}.h5", self.name));
        let n = self.runs.len();
        let col = |f: &dyn Fn(&RunRecord) -> f64| self.runs.iter().map(f).collect::<Vec<f64>>();
        write_atomically(dir, &self.name, env!("CARGO_PKG_VERSION"), |h| {
            str_attr(h, "kind", "work-precision")?;
            str_attr(h, "study_text", study_text)?;
            str_attr(h, "study_file", &study_file.display().to_string())?;
            str_attr(h, "reference", &self.reference)?;
            str_attr(h, "check", &self.check)?;
            f64_attr(h, "reference_wall_time", self.reference_wall)?;
            f64_attr(h, "period", self.period)?;
            u64_attr(h, "periods", self.periods as u64)?;
            u64_attr(h, "kept_periods", self.kept as u64)?;
            u64_attr(h, "restarts", self.restarts as u64)?;
            str_attr(h, "position_observables", &self.position.join(","))?;
            str_attr(h, "force_observables", &self.force.join(","))?;
            str_attr(h, "position_unit", &self.position_unit)?;
            let g = h.create_group("floor")?;
            for (k, v) in [
                ("position", self.floor.position),
                ("restart", self.floor.restart),
                ("force", self.floor.force),
                ("restart_force", self.floor.restart_force),
            ] {
                f64_attr(&g, k, v)?;
            }
            let g = h.create_group("runs")?;
            let strs = |name: &str, v: Vec<String>, desc: &str| write_strings(&g, name, &v, desc);
            strs(
                "family",
                self.runs.iter().map(|r| r.family.clone()).collect(),
                "integrator family",
            )?;
            strs(
                "integrator",
                self.runs.iter().map(|r| r.integrator.clone()).collect(),
                "integrator and its settings",
            )?;
            strs(
                "status",
                self.runs
                    .iter()
                    .map(|r| r.failure.clone().unwrap_or_else(|| "ok".into()))
                    .collect(),
                "'ok' or the failure message",
            )?;
            strs(
                "warnings",
                self.runs.iter().map(|r| r.warnings.join("\n")).collect(),
                "step-size warnings, one per line",
            )?;
            write1(
                &g,
                "setting",
                &col(&|r| r.setting),
                "s or 1",
                "fixed step (s) of a fixed-step method, relative tolerance of an adaptive one",
            )?;
            write1(
                &g,
                "position_error",
                &col(&|r| r.errors.position),
                &self.position_unit,
                "largest error of the position observables at the kept strobe times (NaN: failed)",
            )?;
            write1(
                &g,
                "restart_error",
                &col(&|r| r.errors.restart),
                &self.position_unit,
                "largest one-period error from reference strobe states (NaN: failed or none)",
            )?;
            write1(
                &g,
                "force_error",
                &col(&|r| r.errors.force),
                "1",
                "largest error of the force observables over the last period / their peak (NaN: none)",
            )?;
            write1(
                &g,
                "restart_force_error",
                &col(&|r| r.errors.restart_force),
                "1",
                "largest error of the force observables over the restarted periods / their peak (NaN: none)",
            )?;
            write1(
                &g,
                "wall_time",
                &col(&|r| r.wall),
                "s",
                "fastest repeat of the continuous run",
            )?;
            write1(
                &g,
                "rhs_evals",
                &col(&|r| r.stats.rhs_evals as f64),
                "1",
                "right-hand-side evaluations of the continuous run (Jacobian columns included)",
            )?;
            write1(
                &g,
                "jacobians",
                &col(&|r| r.stats.jacobians as f64),
                "1",
                "Jacobians formed (implicit methods; their columns are counted in rhs_evals)",
            )?;
            write1(
                &g,
                "steps",
                &col(&|r| r.stats.accepted as f64),
                "1",
                "accepted steps",
            )?;
            write1(
                &g,
                "rejected",
                &col(&|r| r.stats.rejected as f64),
                "1",
                "steps rejected by the error control",
            )?;
            write1(
                &g,
                "repeats",
                &col(&|r| r.repeats as f64),
                "1",
                "repeats of the continuous run",
            )?;
            u64_attr(&g, "count", n as u64)?;
            Ok(())
        })
        .map_err(|e| match e {
            Error::Hdf5 { message, .. } => Error::Hdf5 {
                file: file.clone(),
                message,
            },
            other => other,
        })
    }
}

/// True when `path` is a file written by `jointplay precision`.
pub fn is_precision_file(path: &Path) -> bool {
    hdf5::File::open(path)
        .ok()
        .and_then(|f| read_str(&f, "kind").ok())
        .is_some_and(|k| k == "work-precision")
}

impl Outcome {
    /// Reads back a file written by [`Outcome::write`] (what `plot` redraws from).
    pub fn read(path: &Path) -> Result<Outcome> {
        let e = h5err(path);
        let f = hdf5::File::open(path).map_err(&e)?;
        let s = |name: &str| read_str(&f, name).map_err(&e);
        let x = |name: &str| read_attr::<f64>(&f, name).map_err(&e);
        let n =
            |name: &str| -> Result<usize> { Ok(read_attr::<u64>(&f, name).map_err(&e)? as usize) };
        let list = |v: String| -> Vec<String> {
            v.split(',')
                .filter(|p| !p.is_empty())
                .map(str::to_string)
                .collect()
        };
        let floor = f.group("floor").map_err(&e)?;
        let fl = |name: &str| read_attr::<f64>(&floor, name).map_err(&e);
        let g = f.group("runs").map_err(&e)?;
        let col = |name: &str| -> Result<Vec<f64>> {
            Ok(g.dataset(name)
                .and_then(|d| d.read_1d::<f64>())
                .map_err(&e)?
                .to_vec())
        };
        let strs = |name: &str| read_strings(&g, name).map_err(&e);
        let (family, integrator, status, warnings) = (
            strs("family")?,
            strs("integrator")?,
            strs("status")?,
            strs("warnings")?,
        );
        let (setting, pe, re, fe, rfe) = (
            col("setting")?,
            col("position_error")?,
            col("restart_error")?,
            col("force_error")?,
            col("restart_force_error")?,
        );
        let jacobians = col("jacobians")?;
        let (wall, rhs, steps, rejected, repeats) = (
            col("wall_time")?,
            col("rhs_evals")?,
            col("steps")?,
            col("rejected")?,
            col("repeats")?,
        );
        let rows = family.len();
        let lengths = [
            integrator.len(),
            status.len(),
            warnings.len(),
            setting.len(),
            pe.len(),
            re.len(),
            fe.len(),
            rfe.len(),
            jacobians.len(),
            wall.len(),
            rhs.len(),
            steps.len(),
            rejected.len(),
            repeats.len(),
        ];
        if lengths.iter().any(|&l| l != rows) {
            return Err(Error::Hdf5 {
                file: path.to_path_buf(),
                message: format!(
                    "the /runs datasets differ in length ({rows} families, {lengths:?})"
                ),
            });
        }
        let runs = (0..rows)
            .map(|i| RunRecord {
                family: family[i].clone(),
                setting: setting[i],
                integrator: integrator[i].clone(),
                errors: Errors {
                    position: pe[i],
                    restart: re[i],
                    force: fe[i],
                    restart_force: rfe[i],
                },
                wall: wall[i],
                repeats: repeats[i] as usize,
                stats: Stats {
                    accepted: steps[i] as u64,
                    rejected: rejected[i] as u64,
                    rhs_evals: rhs[i] as u64,
                    wall: Duration::try_from_secs_f64(wall[i]).unwrap_or_default(),
                    jacobians: jacobians[i] as u64,
                    events: 0,
                },
                failure: (status[i] != "ok").then(|| status[i].clone()),
                warnings: warnings[i].lines().map(str::to_string).collect(),
            })
            .collect();
        Ok(Outcome {
            name: path
                .file_stem()
                .map(|s| s.to_string_lossy().to_string())
                .unwrap_or_default(),
            reference: s("reference")?,
            check: s("check")?,
            floor: Errors {
                position: fl("position")?,
                restart: fl("restart")?,
                force: fl("force")?,
                restart_force: fl("restart_force")?,
            },
            reference_wall: x("reference_wall_time")?,
            runs,
            position: list(s("position_observables")?),
            force: list(s("force_observables")?),
            position_unit: s("position_unit")?,
            restarts: n("restarts")?,
            periods: n("periods")?,
            kept: n("kept_periods")?,
            period: x("period")?,
        })
    }
}
