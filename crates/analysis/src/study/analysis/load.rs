//! An analysis study read and checked ([`Loaded`]): the study file, its scene or system with
//! the study's edits, every error naming the field; and the flow of each parameter value,
//! compiled from the edited tree ([`Loaded::target_with`]).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use jointplay_solver::model::Model;
use jointplay_solver::scene::{SceneFile, SceneSpec};
use toml::{Table, Value};

use crate::flow::observe::Observable;
use crate::flow::systems::SystemSpec;
use crate::flow::{Flow, Target};
use crate::measures::sections::{Hyperplane, Plan};
use crate::study::spec::{edit, edited_scene, invalid};
use crate::{Error, Result};
use jointplay_solver::state::HybridState;

use crate::study::analysis::spec::*;

/// A loaded study: its text, spec and base tree.
#[derive(Debug, Clone)]
pub struct Loaded {
    pub path: PathBuf,
    pub text: String,
    pub spec: AnalysisStudy,
    /// The scene file or the system table after the study's edits.
    pub(crate) base: Base,
    /// Observable names; hyperplanes resolved to observable indices.
    pub planes: Vec<Hyperplane>,
    /// The parameter values of each job and its direction (+1 up, -1 down).
    pub jobs: Vec<(f64, i8)>,
}

#[derive(Debug, Clone)]
pub(crate) enum Base {
    Scene { path: PathBuf, tree: Table },
    System(Table),
}

/// One parameter set by path, with the field that asked for it (for error messages).
struct Edit {
    field: String,
    path: String,
    value: f64,
}
impl Loaded {
    /// Reads and checks a study file and its scene.
    pub fn load(path: &Path) -> Result<Loaded> {
        let text = std::fs::read_to_string(path).map_err(|e| Error::Io {
            file: path.to_path_buf(),
            message: e.to_string(),
        })?;
        Loaded::parse(&text, path)
    }

    /// Parses study text; scene paths are relative to `path`'s directory.
    pub fn parse(text: &str, path: &Path) -> Result<Loaded> {
        Loaded::parse_from(text, path, None)
    }

    /// Parses the study text an analysis file keeps, with the flow it keeps (its `flow_text`:
    /// the scene after the study's edits, or the system table) in place of the scene file,
    /// which need not be where the study once found it.
    pub fn parse_kept(text: &str, path: &Path, flow_text: &str) -> Result<Loaded> {
        Loaded::parse_from(text, path, Some(flow_text))
    }

    fn parse_from(text: &str, path: &Path, flow_text: Option<&str>) -> Result<Loaded> {
        let spec = AnalysisStudy::parse_spec(text, path)?;
        check_name(path, "study.name", &spec.study.name)?;
        check_analysis(&spec.analysis, path)?;
        let names = observable_names(&spec, path)?;
        let planes = section_planes(&spec, path, &names)?;
        check_indicators(&spec, path, &names, &planes)?;
        let base = match flow_text {
            None => base_of(&spec, path)?,
            Some(flow) => {
                let tree: Table =
                    toml::from_str(flow).map_err(|e| invalid(path, "flow_text", e.to_string()))?;
                match &spec.study.scene {
                    Some(scene) => Base::Scene {
                        path: path.parent().unwrap_or(Path::new(".")).join(scene),
                        tree,
                    },
                    None => Base::System(tree),
                }
            }
        };
        let jobs = sweep_jobs(&spec, path)?;
        let loaded = Loaded {
            path: path.to_path_buf(),
            text: text.to_string(),
            spec,
            base,
            planes,
            jobs,
        };
        // Build the first job (or the single run) now, so that a bad scene, path or observable
        // fails before anything runs.
        let first = loaded.jobs.first().map(|j| j.0);
        let target = loaded.target(first)?;
        loaded.check_span(&target)?;
        if let Some(c) = &loaded.spec.continuation {
            loaded.check_continuation(c)?;
        }
        for (i, f) in loaded.spec.figures.iter().enumerate() {
            loaded.spec.check_figure(&loaded.path, &loaded.jobs, i, f)?;
        }
        Ok(loaded)
    }

    /// Refuses a run that could never finish, as scenes do (`solver.step`): `analysis.periods`
    /// periods of `analysis.period` (or the drive's) that take more than 1e12 steps of the
    /// fixed step or the step bound, or of the drive period, which an adaptive method resolves
    /// with a step at least.
    fn check_span(&self, target: &Target) -> Result<()> {
        use jointplay_solver::ode::Accuracy;
        let (period, own) = match target {
            Target::Scene { model, period, .. } => (*period, model.settings.period),
            Target::System { sys, period, .. } => (*period, sys.builtin.period()),
        };
        let step = match target.method().accuracy() {
            Accuracy::Fixed { step } => step,
            Accuracy::Adaptive { max_step, .. } => max_step,
        };
        let step = own.map_or(step, |p| step.min(p));
        let a = &self.spec.analysis;
        let span = a.periods as f64 * period + a.phase;
        if span / step > 1e12 {
            let field = if a.period.is_some() {
                "analysis.period"
            } else {
                "analysis.periods"
            };
            return Err(invalid(
                &self.path,
                field,
                format!(
                    "{} periods of {period:e} s with steps of at most {step:.3e} s (the step bound or the drive period) mean at least {:.3e} steps; at most 1e12 are allowed",
                    a.periods,
                    span / step
                ),
            ));
        }
        Ok(())
    }

    /// Text of the flow (the edited scene or the system table) for the file.
    pub(crate) fn base_text(&self) -> String {
        match &self.base {
            Base::Scene { tree, .. } | Base::System(tree) => {
                toml::to_string(tree).unwrap_or_default()
            }
        }
    }

    /// The flow with the swept parameter set to `value`, ready to run.
    pub(crate) fn target(&self, value: Option<f64>) -> Result<Target> {
        let edits: Vec<Edit> = match (value, &self.spec.sweep) {
            (Some(v), Some(sw)) => std::iter::once(Edit {
                field: format!("sweep.parameter ('{}')", sw.parameter),
                path: sw.parameter.clone(),
                value: v,
            })
            .chain(sw.also.iter().enumerate().map(|(i, p)| Edit {
                field: format!("sweep.also[{i}] ('{p}')"),
                path: p.clone(),
                value: v,
            }))
            .collect(),
            _ => Vec::new(),
        };
        self.compile_edited(&edits)
    }

    /// The study's flow with parameters set by path: for a scene, scene paths as in a sweep
    /// (`joints.*.clearance.radial_clearance`; `*` sets every element), for a built-in system its
    /// parameter names (`gamma`, `omega`, ...). The study file is not changed; each call compiles
    /// a new flow from the study's source. Errors name the path.
    pub fn target_with(&self, edits: &[(&str, f64)]) -> Result<Target> {
        let edits: Vec<Edit> = edits
            .iter()
            .map(|&(path, value)| Edit {
                field: format!("parameter '{path}'"),
                path: path.to_string(),
                value,
            })
            .collect();
        self.compile_edited(&edits)
    }

    /// Compiles the study's source with `edits` applied (the first one names the edited scene in
    /// messages).
    fn compile_edited(&self, edits: &[Edit]) -> Result<Target> {
        match &self.base {
            Base::Scene { path: sp, tree } => {
                let mut tree = tree.clone();
                for ed in edits {
                    edit(&mut tree, &ed.path, Some(&Value::Float(ed.value))).map_err(|m| {
                        invalid(&self.path, &ed.field, format!("{m} in {}", sp.display()))
                    })?;
                }
                let text = toml::to_string(&tree)
                    .map_err(|e| invalid(&self.path, "study.scene", e.to_string()))?;
                let named = match edits.first() {
                    // The value as `{:?}` writes it (1e308, not 309 digits) and the path
                    // clipped, so that the message clipping keeps the study's name.
                    Some(ed) => PathBuf::from(format!(
                        "{} ({} = {:?} in {})",
                        sp.display(),
                        crate::clip(&ed.path),
                        ed.value,
                        self.path.display()
                    )),
                    // A value the study's own `set` put there is named with the study, as a
                    // comparison case's scene is.
                    None if !self.spec.study.set.is_empty()
                        || !self.spec.study.remove.is_empty() =>
                    {
                        PathBuf::from(format!(
                            "{} (edited by {})",
                            sp.display(),
                            self.path.display()
                        ))
                    }
                    None => sp.clone(),
                };
                let spec = if named == *sp {
                    SceneSpec::parse(&text, &named)?
                } else {
                    crate::study::spec::parse_edited(&text, &named)?
                };
                let scene = SceneFile {
                    path: named,
                    text,
                    spec,
                };
                let (model, state) = Model::compile(&scene)?;
                let mut obs = Vec::new();
                for (i, o) in self.spec.observables.iter().enumerate() {
                    obs.push(
                        Observable::for_model(&model, &o.path).map_err(|m| {
                            invalid(&self.path, format!("observables[{i}].path"), m)
                        })?,
                    );
                }
                let period = self.period(model.settings.period)?;
                Ok(Target::Scene {
                    model: Box::new(model),
                    state,
                    obs,
                    period,
                })
            }
            Base::System(table) => {
                let mut table = table.clone();
                for ed in edits {
                    if !table.contains_key(&ed.path) && ed.path != "start_time" {
                        // Let the parser name the allowed parameters.
                        let probe = SystemSpec::parse(&{
                            let mut t = table.clone();
                            t.insert(ed.path.clone(), Value::Float(ed.value));
                            t
                        });
                        if let Err((_, m)) = probe {
                            return Err(invalid(&self.path, &ed.field, m));
                        }
                    }
                    table.insert(ed.path.clone(), Value::Float(ed.value));
                }
                let sys = SystemSpec::parse(&table)
                    .map_err(|(k, m)| invalid(&self.path, format!("study.system.{k}"), m))?;
                let mut obs = Vec::new();
                for (i, o) in self.spec.observables.iter().enumerate() {
                    obs.push(
                        Observable::for_system(&sys.builtin, &o.path).map_err(|m| {
                            invalid(&self.path, format!("observables[{i}].path"), m)
                        })?,
                    );
                }
                let period = self.period(sys.builtin.period())?;
                Ok(Target::System { sys, obs, period })
            }
        }
    }

    /// The flow with the continuation parameter (and its `also` paths) set to `value`.
    pub fn continuation_target(&self, value: f64) -> Result<Target> {
        let Some(c) = &self.spec.continuation else {
            return Err(invalid(
                &self.path,
                "continuation",
                "no [continuation] table",
            ));
        };
        let edits: Vec<Edit> = std::iter::once(Edit {
            field: format!("continuation.parameter ('{}')", c.parameter),
            path: c.parameter.clone(),
            value,
        })
        .chain(c.also.iter().enumerate().map(|(i, p)| Edit {
            field: format!("continuation.also[{i}] ('{p}')"),
            path: p.clone(),
            value,
        }))
        .collect();
        self.compile_edited(&edits)
    }

    /// Checks the `[continuation]` table against the study: its numbers, its paths (the flow is
    /// compiled at both ends of the range), its grazing observable, and the period (a periodic
    /// orbit of a forced flow is one of the drive: `analysis.period`, when given, must be the
    /// drive's own).
    fn check_continuation(
        &self,
        c: &crate::study::continuation::spec::ContinuationSpec,
    ) -> Result<()> {
        c.check().map_err(|(f, m)| invalid(&self.path, f, m))?;
        if let Some(g) = &c.grazing
            && self.spec.observable(&g.observable).is_none()
        {
            return Err(invalid(
                &self.path,
                "continuation.grazing.observable",
                format!("'{}' is not an observable of this study", g.observable),
            ));
        }
        if matches!(self.base, Base::System(_)) && !c.also.is_empty() {
            return Err(invalid(
                &self.path,
                "continuation.also",
                "applies to scenes, not to systems",
            ));
        }
        for v in [c.from, c.to] {
            let own = match self.continuation_target(v)? {
                Target::Scene { model, .. } => model.settings.period,
                Target::System { sys, .. } => sys.builtin.period(),
            };
            let Some(own) = own else {
                return Err(invalid(
                    &self.path,
                    "continuation",
                    "the flow has no drive: periodic orbits are followed on the stroboscopic map of a periodic drive",
                ));
            };
            if let Some(p) = self.spec.analysis.period
                && (p - own).abs() > 1e-12 * own
            {
                return Err(invalid(
                    &self.path,
                    "analysis.period",
                    format!(
                        "{p} s is not the drive's period ({own} s at {} = {v}): a continuation shoots on the drive's stroboscopic map (use continuation.orbit_periods for a subharmonic)",
                        c.parameter
                    ),
                ));
            }
        }
        self.continuation_start()?;
        Ok(())
    }

    fn period(&self, own: Option<f64>) -> Result<f64> {
        self.spec.analysis.period.or(own).ok_or_else(|| {
            invalid(
                &self.path,
                "analysis.period",
                "the flow has no drive period: give analysis.period (s)",
            )
        })
    }

    pub(crate) fn plan(
        &self,
        method: jointplay_solver::ode::Method,
        start: f64,
        period: f64,
    ) -> Plan {
        let a = &self.spec.analysis;
        Plan {
            method,
            start,
            period,
            phase: a.phase,
            periods: a.periods,
            transient: a.transient,
            samples_per_period: a.samples_per_period,
            history_periods: a.history_periods,
            hyperplanes: self.planes.clone(),
        }
    }
}

impl Loaded {
    /// The study's `[continuation] start` state (None without one), read and checked: the file and
    /// the point exist, the state has the flow's size, sits at a strobe time and on the constraint
    /// manifold. Errors name the field.
    pub fn continuation_start(&self) -> Result<Option<HybridState>> {
        let Some(spec) = self.spec.continuation.as_ref() else {
            return Ok(None);
        };
        let Some(s) = &spec.start else {
            return Ok(None);
        };
        let target = self.continuation_target(spec.from)?;
        let mut flow = target.flow();
        let t_strobe = flow.start_time() + self.spec.analysis.phase;
        crate::study::continuation::start::read_start(&self.path, spec, s, &mut flow, t_strobe)
            .map(Some)
    }
}

/// Checks the `[analysis]` table: periods and transient, significant bits, phase and period.
fn check_analysis(a: &AnalysisSpec, path: &Path) -> Result<()> {
    if a.periods == 0 {
        return Err(invalid(path, "analysis.periods", "must be at least 1"));
    }
    if a.transient >= a.periods {
        return Err(invalid(
            path,
            "analysis.transient",
            format!(
                "must be less than analysis.periods ({}), so that some periods are kept",
                a.periods
            ),
        ));
    }
    if let Some(b) = a.significant_bits
        && !(1..=52).contains(&b)
    {
        return Err(invalid(
            path,
            "analysis.significant_bits",
            format!("{b} is not between 1 and 52 (the mantissa bits of a double)"),
        ));
    }
    finite(path, "analysis.phase", a.phase)?;
    if a.phase < 0.0 {
        return Err(invalid(path, "analysis.phase", "must not be negative"));
    }
    if let Some(p) = a.period
        && !(p.is_finite() && p > 0.0)
    {
        return Err(invalid(
            path,
            "analysis.period",
            "must be a positive number of seconds",
        ));
    }
    Ok(())
}

/// The study's observables by name (to their index), checked: at least one, each well named
/// and named once.
fn observable_names(spec: &AnalysisStudy, path: &Path) -> Result<BTreeMap<String, usize>> {
    if spec.observables.is_empty() {
        return Err(invalid(
            path,
            "observables",
            "name at least one observable ([[observables]] with name and path; only a \
             built-in system has a default, its state)",
        ));
    }
    let mut names = BTreeMap::new();
    for (i, o) in spec.observables.iter().enumerate() {
        check_name(path, &format!("observables[{i}].name"), &o.name)?;
        if names.insert(o.name.clone(), i).is_some() {
            return Err(invalid(
                path,
                format!("observables[{i}].name"),
                format!("duplicate name '{}'", o.name),
            ));
        }
    }
    Ok(names)
}

/// The study's `[[sections]]` as hyperplanes over observable indices, checked: names free
/// ('strobe' and earlier sections taken), finite values, at least one term, each term an
/// observable of the study with a finite coefficient.
fn section_planes(
    spec: &AnalysisStudy,
    path: &Path,
    names: &BTreeMap<String, usize>,
) -> Result<Vec<Hyperplane>> {
    let mut planes = Vec::new();
    for (i, s) in spec.sections.iter().enumerate() {
        check_name(path, &format!("sections[{i}].name"), &s.name)?;
        if s.name == "strobe" || spec.sections[..i].iter().any(|o| o.name == s.name) {
            return Err(invalid(
                path,
                format!("sections[{i}].name"),
                format!(
                    "'{}' is taken ('strobe' is the stroboscopic section)",
                    s.name
                ),
            ));
        }
        finite(path, &format!("sections[{i}].value"), s.value)?;
        if s.terms.is_empty() {
            return Err(invalid(
                path,
                format!("sections[{i}].terms"),
                "give at least one term",
            ));
        }
        let mut terms = Vec::new();
        for (k, c) in &s.terms {
            let j = *names.get(k).ok_or_else(|| {
                invalid(
                    path,
                    format!("sections[{i}].terms.{k}"),
                    "not an observable of this study",
                )
            })?;
            finite(path, &format!("sections[{i}].terms.{k}"), *c)?;
            terms.push((j, *c));
        }
        planes.push(Hyperplane {
            name: s.name.clone(),
            terms,
            value: s.value,
            direction: s.direction,
        });
    }
    Ok(planes)
}

/// Checks each chaos indicator the study asks for: its observable and section exist, and the
/// strobe section keeps as many samples as the indicator needs.
fn check_indicators(
    spec: &AnalysisStudy,
    path: &Path,
    names: &BTreeMap<String, usize>,
    planes: &[Hyperplane],
) -> Result<()> {
    let a = &spec.analysis;
    for asked in spec.asked() {
        let (key, z, indicator) = (asked.key(), &asked.series, asked.indicator);
        if !names.contains_key(&z.observable) {
            return Err(invalid(
                path,
                format!("{key}.observable"),
                format!("'{}' is not an observable of this study", z.observable),
            ));
        }
        if z.section != "strobe" && !planes.iter().any(|p| p.name == z.section) {
            return Err(invalid(
                path,
                format!("{key}.section"),
                format!(
                    "'{}' is neither 'strobe' nor a section of this study",
                    z.section
                ),
            ));
        }
        let kept = a.periods - a.transient;
        let least = indicator.least_samples();
        if z.section == "strobe" && kept < least {
            return Err(invalid(
                path,
                key,
                format!(
                    "the strobe section keeps {kept} samples (analysis.periods - analysis.transient), but the {} needs at least {least}",
                    indicator.title()
                ),
            ));
        }
    }
    Ok(())
}

/// The study's base tree: its scene (relative to the study file, with the study's edits) or
/// its system table (checked, and without scene-only sweeps and edits).
fn base_of(spec: &AnalysisStudy, path: &Path) -> Result<Base> {
    let dir = path.parent().unwrap_or(Path::new("."));
    Ok(match (&spec.study.scene, &spec.study.system) {
        (Some(scene), None) => {
            let sp = dir.join(scene);
            let (_, tree) = edited_scene(
                path,
                &sp,
                "study.scene",
                &[("study", &spec.study.set, &spec.study.remove)],
            )?;
            Base::Scene { path: sp, tree }
        }
        (None, Some(sys)) => {
            if spec.sweep.as_ref().is_some_and(|s| !s.also.is_empty()) {
                return Err(invalid(
                    path,
                    "sweep.also",
                    "applies to scenes, not to systems",
                ));
            }
            if !spec.study.set.is_empty() || !spec.study.remove.is_empty() {
                return Err(invalid(
                    path,
                    "study.set",
                    "edits apply to scenes; give a system's parameters in study.system",
                ));
            }
            // The base table must be valid even where a sweep overrides a value.
            SystemSpec::parse(sys)
                .map_err(|(k, m)| invalid(path, format!("study.system.{k}"), m))?;
            Base::System(sys.clone())
        }
        _ => {
            return Err(invalid(
                path,
                "study",
                "give either scene = \"FILE\" or system = { kind = ... }",
            ));
        }
    })
}
