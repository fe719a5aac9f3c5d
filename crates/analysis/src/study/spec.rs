//! Study files: several runs of one or more scenes, compared in one HDF5 file, figures and table.
//!
//! A study names a base scene and a list of cases. Each case may take another scene and edit the
//! scene's TOML tree before it is compiled:
//!
//! * `set = { "path" = value, ... }` replaces (or adds) the value at `path`;
//! * `remove = ["path", ...]` deletes it (e.g. a joint's `clearance` table, which makes it ideal).
//!
//! A path is a dot-separated list of keys. Where the tree holds an array of tables (bodies, joints,
//! drives, springs, loads), a segment selects the element whose `name` equals it, `*` selects every
//! element, and a number selects by position: `joints.S2.clearance.radial_clearance`,
//! `drives.*.profile.omega`. In an array of numbers (a vector) a segment selects a component by
//! index or every component (`*`): `bodies.ball.velocity.0`, `gravity.1`. A path with `*` edits
//! only the elements where the path up to its last key exists, and `set` adds that key there; a
//! path that edits nothing is an error, and a key the scene format does not know is refused when
//! the edited scene is parsed, so a typo never passes silently. Study-level `set` and `remove`
//! apply to every case before the case's own.
//!
//! The edited scene text is stored in the output file with each case, so every run can be repeated
//! from the file alone.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use jointplay_solver::model::Model;
use jointplay_solver::scene::{SceneFile, SceneSpec};
use rayon::prelude::*;
use serde::Deserialize;
use toml::{Table, Value};

use crate::progress::{Progress, Stop};
use crate::storage::run::RunResult;
use crate::study::run::simulate_until;
use crate::{Error, Result};

/// A study file.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StudySpec {
    pub study: StudyHeader,
    pub cases: Vec<CaseSpec>,
    #[serde(default)]
    pub report: ReportSpec,
}

/// The `[study]` table.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StudyHeader {
    pub name: String,
    #[serde(default)]
    pub description: String,
    /// Base scene, relative to the study file.
    pub scene: PathBuf,
    /// Edits applied to every case.
    #[serde(default)]
    pub set: BTreeMap<String, Value>,
    #[serde(default)]
    pub remove: Vec<String>,
}

/// One run of a study.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CaseSpec {
    /// Short label: legend entry and HDF5 group name (`/cases/<label>`).
    pub label: String,
    /// Scene of this case (relative to the study file); default the study's.
    #[serde(default)]
    pub scene: Option<PathBuf>,
    #[serde(default)]
    pub set: BTreeMap<String, Value>,
    #[serde(default)]
    pub remove: Vec<String>,
    /// Label of the case this one is compared with (default `report.reference`).
    #[serde(default)]
    pub reference: Option<String>,
}

/// What the figures and the table look at.
#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ReportSpec {
    /// The body whose motion is drawn and compared (e.g. the moving platform).
    #[serde(default)]
    pub body: Option<String>,
    /// Joints whose forces (contact force with clearance, reaction force when ideal) and orbits
    /// are drawn and tabulated.
    #[serde(default)]
    pub joints: Vec<String>,
    /// Global axes of the body's motion to draw and tabulate: any of "x", "y", "z" (default all).
    #[serde(default)]
    pub axes: Vec<String>,
    /// Default reference case for the deviations.
    #[serde(default)]
    pub reference: Option<String>,
    /// Band around the settled force range within which a force counts as settled, as a fraction
    /// of its settled mean (default 0.1).
    #[serde(default)]
    pub settle_tolerance: Option<f64>,
    /// Published values to set beside ours.
    #[serde(default)]
    pub published: Vec<Published>,
    /// Groups of cases drawn together, one set of figures each (`<study>-<name>-motion`,
    /// `-forces`, `-orbits`); without any, one set of every case (`<study>-motion`, ...).
    #[serde(default)]
    pub figures: Vec<FigureGroup>,
}

/// Cases drawn in one set of study figures.
#[derive(Debug, Clone, Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields)]
pub struct FigureGroup {
    /// Part of the figures' file names: letters, digits, '-' and '_'.
    pub name: String,
    /// Labels of the cases drawn, in this order.
    pub cases: Vec<String>,
}

/// One published value of a quantity of the report (see [`crate::study::report`] for the names).
#[derive(Debug, Clone, Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields)]
pub struct Published {
    pub case: String,
    pub quantity: String,
    pub value: f64,
    /// Where it comes from, e.g. "Fig. 9".
    #[serde(default)]
    pub source: String,
    /// Relative band of agreement, e.g. 0.04 for the paper's own ±4 % scatter: the table says
    /// whether ours lies within `value * (1 ± band)`.
    #[serde(default)]
    pub band: Option<f64>,
}

/// A loaded study with its cases' scenes edited and parsed.
#[derive(Debug, Clone)]
pub struct Study {
    pub path: PathBuf,
    pub text: String,
    pub spec: StudySpec,
    pub cases: Vec<Case>,
}

/// One case ready to compile.
#[derive(Debug, Clone)]
pub struct Case {
    pub label: String,
    /// The scene with this case's edits; `path` names the scene file and the case.
    pub scene: SceneFile,
}

pub(crate) fn invalid(file: &Path, field: impl Into<String>, message: impl Into<String>) -> Error {
    Error::Study {
        file: file.to_path_buf(),
        field: field.into(),
        message: message.into(),
    }
}

/// True when the TOML text is a study (has a `[study]` table) rather than a scene.
pub fn is_study(text: &str) -> bool {
    text.parse::<Table>()
        .map(|t| t.contains_key("study"))
        .unwrap_or(false)
}

impl StudySpec {
    /// The label of the case `c` is compared with: its own `reference`, else `report.reference`
    /// unless that is `c` itself.
    pub fn reference_of(&self, c: &CaseSpec) -> Option<String> {
        c.reference
            .clone()
            .or_else(|| self.report.reference.clone().filter(|r| *r != c.label))
    }
}

impl ReportSpec {
    /// Indices (0, 1, 2 for x, y, z) and names of the report axes.
    pub fn axis_list(&self) -> Vec<(usize, &'static str)> {
        let all = [(0, "x"), (1, "y"), (2, "z")];
        if self.axes.is_empty() {
            return all.to_vec();
        }
        all.into_iter()
            .filter(|(_, n)| self.axes.iter().any(|a| a == n))
            .collect()
    }
}

impl Study {
    /// Reads a study file, edits and parses the scene of every case.
    pub fn load(path: &Path) -> Result<Study> {
        let text = std::fs::read_to_string(path).map_err(|e| Error::Io {
            file: path.to_path_buf(),
            message: e.to_string(),
        })?;
        Study::parse(&text, path)
    }

    /// Parses study text; scene paths are relative to `path`'s directory.
    pub fn parse(text: &str, path: &Path) -> Result<Study> {
        let spec: StudySpec = jointplay_solver::scene::parse_toml(text, path)?;
        let dir = path.parent().unwrap_or(Path::new("."));
        if spec.cases.is_empty() {
            return Err(invalid(path, "cases", "a study needs at least one case"));
        }
        let seen = case_labels(&spec, path)?;
        check_references(&spec, path, &seen)?;
        check_report(&spec.report, path, &seen)?;
        let mut cases = Vec::new();
        for (i, c) in spec.cases.iter().enumerate() {
            cases.push(load_case(&spec, path, dir, i, c)?);
        }
        Ok(Study {
            path: path.to_path_buf(),
            text: text.to_string(),
            spec,
            cases,
        })
    }
}

/// The study's case labels (to their index), checked: each a plain name, none twice.
fn case_labels(spec: &StudySpec, path: &Path) -> Result<BTreeMap<String, usize>> {
    let mut seen = BTreeMap::new();
    for (i, c) in spec.cases.iter().enumerate() {
        let field = format!("cases[{i}].label");
        if !crate::plain_name(&c.label, "-_.") {
            return Err(invalid(
                path,
                field,
                format!(
                    "'{}': use letters, digits, '-', '_' or '.' (it names an HDF5 group)",
                    c.label
                ),
            ));
        }
        if seen.insert(c.label.clone(), i).is_some() {
            return Err(invalid(
                path,
                field,
                format!("duplicate label '{}'", c.label),
            ));
        }
    }
    Ok(seen)
}

/// Checks that the report's reference, each case's reference and each published value name
/// cases of the study (`seen`), and the published values and bands.
fn check_references(spec: &StudySpec, path: &Path, seen: &BTreeMap<String, usize>) -> Result<()> {
    let labels = |r: &str| seen.contains_key(r);
    if let Some(r) = &spec.report.reference
        && !labels(r)
    {
        return Err(invalid(path, "report.reference", format!("no case '{r}'")));
    }
    for (i, c) in spec.cases.iter().enumerate() {
        if let Some(r) = &c.reference
            && !labels(r)
        {
            return Err(invalid(
                path,
                format!("cases[{i}].reference"),
                format!("no case '{r}'"),
            ));
        }
    }
    for (i, p) in spec.report.published.iter().enumerate() {
        if !labels(&p.case) {
            return Err(invalid(
                path,
                format!("report.published[{i}].case"),
                format!("no case '{}'", p.case),
            ));
        }
        if !p.value.is_finite() {
            return Err(invalid(
                path,
                format!("report.published[{i}].value"),
                "must be finite",
            ));
        }
        if let Some(b) = p.band
            && !(b.is_finite() && b > 0.0)
        {
            return Err(invalid(
                path,
                format!("report.published[{i}].band"),
                format!("{b}: must be a positive fraction (0.04 for ±4 %)"),
            ));
        }
    }
    Ok(())
}

/// Checks the report's figures (plain names, each once, of cases of the study `seen`), its axes
/// and its settling tolerance.
fn check_report(report: &ReportSpec, path: &Path, seen: &BTreeMap<String, usize>) -> Result<()> {
    let labels = |r: &str| seen.contains_key(r);
    let mut names = std::collections::BTreeSet::new();
    for (i, g) in report.figures.iter().enumerate() {
        if !crate::plain_name(&g.name, "-_") {
            return Err(invalid(
                path,
                format!("report.figures[{i}].name"),
                format!("'{}': use letters, digits, '-' and '_'", g.name),
            ));
        }
        if !names.insert(g.name.as_str()) {
            return Err(invalid(
                path,
                format!("report.figures[{i}].name"),
                format!("duplicate name '{}'", g.name),
            ));
        }
        if g.cases.is_empty() {
            return Err(invalid(
                path,
                format!("report.figures[{i}].cases"),
                "name at least one case",
            ));
        }
        if let Some(c) = g.cases.iter().find(|c| !labels(c)) {
            return Err(invalid(
                path,
                format!("report.figures[{i}].cases"),
                format!("no case '{c}'"),
            ));
        }
    }
    for (i, a) in report.axes.iter().enumerate() {
        if !["x", "y", "z"].contains(&a.as_str()) {
            return Err(invalid(
                path,
                format!("report.axes[{i}]"),
                format!("'{a}': use \"x\", \"y\" or \"z\""),
            ));
        }
    }
    if let Some(tol) = report.settle_tolerance
        && !(tol.is_finite() && tol > 0.0)
    {
        return Err(invalid(
            path,
            "report.settle_tolerance",
            "must be a positive number",
        ));
    }
    Ok(())
}

/// Case `i`, `c`: its scene (the case's or the study's, relative to `dir`) with the study's and
/// the case's edits, parsed, and recording what the report reads.
fn load_case(spec: &StudySpec, path: &Path, dir: &Path, i: usize, c: &CaseSpec) -> Result<Case> {
    let scene_path = dir.join(c.scene.as_ref().unwrap_or(&spec.study.scene));
    let read_field = if c.scene.is_some() {
        format!("cases[{i}].scene")
    } else {
        "study.scene".into()
    };
    let (text, tree) = edited_scene(
        path,
        &scene_path,
        &read_field,
        &[
            ("study", &spec.study.set, &spec.study.remove),
            (&format!("cases[{i}]"), &c.set, &c.remove),
        ],
    )?;
    let unedited = c.set.is_empty()
        && c.remove.is_empty()
        && spec.study.set.is_empty()
        && spec.study.remove.is_empty();
    let edited = if unedited {
        text
    } else {
        toml::to_string(&tree).map_err(|e| invalid(path, format!("cases[{i}]"), e.to_string()))?
    };
    let named = PathBuf::from(format!(
        "{} (case '{}' of {})",
        scene_path.display(),
        c.label,
        path.display()
    ));
    let scene_spec = if unedited {
        SceneSpec::parse(&edited, &named)?
    } else {
        parse_edited(&edited, &named)?
    };
    // The report reads these from every case's file: a name no case records would be
    // found only once the whole study had run.
    check_recorded(path, &spec.report, &c.label, &scene_spec)?;
    Ok(Case {
        label: c.label.clone(),
        scene: SceneFile {
            path: named,
            text: edited,
            spec: scene_spec,
        },
    })
}

/// Refuses a `report.joints` entry or `report.body` that the scene of case `label` does not
/// declare or does not record (its `output.joints` / `output.bodies` leave it out).
fn check_recorded(path: &Path, report: &ReportSpec, label: &str, scene: &SceneSpec) -> Result<()> {
    for (i, j) in report.joints.iter().enumerate() {
        let declared = scene.joints.iter().any(|x| x.name == *j);
        let recorded = scene
            .output
            .joints
            .as_ref()
            .is_none_or(|o| o.iter().any(|x| x == j));
        if !declared || !recorded {
            return Err(invalid(
                path,
                format!("report.joints[{i}]"),
                if declared {
                    format!(
                        "'{}': case '{label}' does not record it (its output.joints leaves it out)",
                        crate::clip(j)
                    )
                } else {
                    format!(
                        "'{}': case '{label}' has no joint of that name",
                        crate::clip(j)
                    )
                },
            ));
        }
    }
    if let Some(b) = &report.body {
        let declared = scene.bodies.iter().any(|x| x.name == *b);
        let recorded = scene
            .output
            .bodies
            .as_ref()
            .is_none_or(|o| o.iter().any(|x| x == b));
        if !declared || !recorded {
            return Err(invalid(
                path,
                "report.body",
                if declared {
                    format!(
                        "'{}': case '{label}' does not record it (its output.bodies leaves it out)",
                        crate::clip(b)
                    )
                } else {
                    format!(
                        "'{}': case '{label}' has no body of that name",
                        crate::clip(b)
                    )
                },
            ));
        }
    }
    Ok(())
}

/// One finished case.
#[derive(Debug)]
pub struct CaseRun {
    pub label: String,
    pub model: Model,
    pub result: RunResult,
}

impl Study {
    /// Compiles every case, so that a bad one fails before any simulation starts, then runs
    /// them in parallel over rayon's thread pool. `progress` is told [`Progress::Start`] once the
    /// cases compile and [`Progress::Done`] as each case ends, its job being the case's index.
    /// The runs come back in the order of the cases, each failure wrapped with its case's label.
    pub fn run(&self, progress: &(dyn Fn(Progress) + Sync)) -> Result<Vec<Result<CaseRun>>> {
        self.run_until(progress, &Stop::new())
    }

    /// [`Study::run`] that ends early when `stop` is requested: a case then running ends with
    /// [`Error::Interrupted`] (wrapped with its label), and the cases not started end so at once.
    /// A running case also reports [`Progress::Fraction`].
    pub fn run_until(
        &self,
        progress: &(dyn Fn(Progress) + Sync),
        stop: &Stop,
    ) -> Result<Vec<Result<CaseRun>>> {
        let compiled = self
            .cases
            .iter()
            .map(|c| Model::compile(&c.scene))
            .collect::<Result<Vec<_>, _>>()?;
        let n = self.cases.len();
        progress(Progress::Start {
            total: n,
            pending: n,
        });
        // One case per task, so a free thread takes any case not yet started (an even split of
        // the list left a thread idle while the other ran the costlier half).
        Ok(compiled
            .into_par_iter()
            .zip(self.cases.par_iter().enumerate())
            .with_max_len(1)
            .map(|((model, state), (job, c))| {
                let mut last = 0.0;
                let mut fraction = |f: f64| {
                    if f - last >= 1e-3 {
                        last = f;
                        progress(Progress::Fraction { job, fraction: f });
                    }
                };
                let result = simulate_until(&model, state, &mut fraction, stop)
                    .and_then(RunResult::finished)
                    .map_err(|e| {
                        progress(Progress::Done { job, ok: false });
                        Error::Case {
                            label: c.label.clone(),
                            inner: Box::new(e),
                        }
                    })?;
                progress(Progress::Done { job, ok: true });
                Ok(CaseRun {
                    label: c.label.clone(),
                    model,
                    result,
                })
            })
            .collect())
    }
}

/// One group of scene edits: the study field it comes from (`study`, `cases[2]`), its `set` and its
/// `remove`.
pub(crate) type Edits<'a> = (&'a str, &'a BTreeMap<String, Value>, &'a [String]);

/// Reads the scene `scene_path` named by a study `study` (`read_field` is the study field naming
/// it) and applies `edits` in order. Returns the scene text as read and the edited tree; errors
/// name the study file and the field of the failing edit.
pub(crate) fn edited_scene(
    study: &Path,
    scene_path: &Path,
    read_field: &str,
    edits: &[Edits],
) -> Result<(String, Table)> {
    let text = std::fs::read_to_string(scene_path).map_err(|e| {
        invalid(
            study,
            read_field,
            format!("cannot read {}: {e}", scene_path.display()),
        )
    })?;
    let mut tree: Table = text.parse().map_err(|e: toml::de::Error| Error::Io {
        file: scene_path.to_path_buf(),
        message: e.to_string().trim_end().to_string(),
    })?;
    for (at, set, remove) in edits {
        for (p, v) in *set {
            edit(&mut tree, p, Some(v)).map_err(|m| {
                invalid(
                    study,
                    format!("{at}.set.\"{p}\""),
                    format!("{m} in {}", scene_path.display()),
                )
            })?;
        }
        for p in *remove {
            edit(&mut tree, p, None).map_err(|m| {
                invalid(
                    study,
                    format!("{at}.remove"),
                    format!("'{p}': {m} in {}", scene_path.display()),
                )
            })?;
        }
    }
    Ok((text, tree))
}

/// Sets (`Some`) or removes (`None`) the value at `path` in `tree`; errors when nothing matched.
pub fn edit(tree: &mut Table, path: &str, value: Option<&Value>) -> Result<(), String> {
    let segs: Vec<&str> = path.split('.').collect();
    if segs.iter().any(|s| s.is_empty()) {
        return Err("empty path segment".into());
    }
    let wild = segs.contains(&"*");
    let n = walk(tree, &segs, value, wild)?;
    if n == 0 {
        Err("matches nothing".into())
    } else {
        Ok(())
    }
}

/// The values at `path` in `tree`, selected as [`edit`] selects them (names, positions, `*`, a
/// vector's components): one value for a path without `*`, every match for one with it. An
/// error names what is missing.
pub fn lookup<'t>(tree: &'t Table, path: &str) -> Result<Vec<&'t Value>, String> {
    let segs: Vec<&str> = path.split('.').collect();
    if segs.iter().any(|s| s.is_empty()) {
        return Err("empty path segment".into());
    }
    let mut found = Vec::new();
    find(tree, &segs, segs.contains(&"*"), &mut found)?;
    if found.is_empty() {
        return Err("matches nothing".into());
    }
    Ok(found)
}

fn find<'t>(
    t: &'t Table,
    segs: &[&str],
    wild: bool,
    found: &mut Vec<&'t Value>,
) -> Result<(), String> {
    let (head, rest) = (segs[0], &segs[1..]);
    let v = match t.get(head) {
        None if wild => return Ok(()),
        None => {
            return Err(format!(
                "no key '{head}' (a field left at its default is not in the scene)"
            ));
        }
        Some(v) => v,
    };
    if rest.is_empty() {
        found.push(v);
        return Ok(());
    }
    match v {
        Value::Table(sub) => find(sub, rest, wild, found),
        Value::Array(items) if !items.iter().all(Value::is_table) => {
            if rest.len() > 1 {
                return Err(format!(
                    "'{head}.{}' is a number; nothing lies below it",
                    rest[0]
                ));
            }
            if rest[0] == "*" {
                found.extend(items);
                return Ok(());
            }
            match rest[0].parse::<usize>() {
                Ok(k) if k < items.len() => {
                    found.push(&items[k]);
                    Ok(())
                }
                Ok(k) => Err(format!(
                    "index {k} is out of range: '{head}' has {} components",
                    items.len()
                )),
                Err(_) => Err(format!(
                    "'{head}' is an array of numbers: select a component by index (0, 1, ...) or '*', not '{}'",
                    rest[0]
                )),
            }
        }
        Value::Array(items) => {
            let sel = rest[0];
            let before = found.len();
            for (k, item) in items.iter().enumerate() {
                let Value::Table(it) = item else { continue };
                let hit = sel == "*"
                    || sel.parse::<usize>() == Ok(k)
                    || it.get("name").and_then(Value::as_str) == Some(sel);
                if hit {
                    if rest.len() == 1 {
                        found.push(item);
                    } else {
                        find(it, &rest[1..], wild, found)?;
                    }
                }
            }
            if found.len() == before && !wild {
                return Err(format!("no element '{sel}' in '{head}'"));
            }
            Ok(())
        }
        _ if wild => Ok(()),
        _ => Err(format!("'{head}' is a value, not a table")),
    }
}

fn walk(t: &mut Table, segs: &[&str], value: Option<&Value>, wild: bool) -> Result<usize, String> {
    let (head, rest) = (segs[0], &segs[1..]);
    if rest.is_empty() {
        // A wildcard path adds the key wherever its parent table exists; the scene's schema
        // refuses a key it does not know when the edited scene is parsed.
        return Ok(match value {
            Some(v) => {
                t.insert(head.to_string(), v.clone());
                1
            }
            None => usize::from(t.remove(head).is_some()),
        });
    }
    match t.get_mut(head) {
        None if wild => Ok(0),
        None => Err(format!("no key '{head}'")),
        Some(Value::Table(sub)) => walk(sub, rest, value, wild),
        Some(Value::Array(items)) if !items.iter().all(Value::is_table) => {
            component(head, items, rest, value)
        }
        Some(Value::Array(items)) => {
            let sel = rest[0];
            let after = &rest[1..];
            if after.is_empty() {
                return Err(format!(
                    "'{head}.{sel}' selects a whole element; name a field in it"
                ));
            }
            let mut n = 0;
            for (k, item) in items.iter_mut().enumerate() {
                let Value::Table(it) = item else {
                    continue;
                };
                let hit = sel == "*"
                    || sel.parse::<usize>() == Ok(k)
                    || it.get("name").and_then(Value::as_str) == Some(sel);
                if hit {
                    n += walk(it, after, value, wild)?;
                }
            }
            if n == 0 && !wild {
                return Err(format!("no element '{sel}' in '{head}'"));
            }
            Ok(n)
        }
        Some(_) if wild => Ok(0),
        Some(_) => Err(format!("'{head}' is a value, not a table")),
    }
}

/// Sets component `rest[0]` (an index, or `*` for every component) of the numeric array `head`
/// (`velocity.0`, `gravity.1`, `points.B.2`): a number replaces a number, so the array keeps its
/// length and type. Components cannot be removed.
fn component(
    head: &str,
    items: &mut [Value],
    rest: &[&str],
    value: Option<&Value>,
) -> Result<usize, String> {
    let sel = rest[0];
    if rest.len() > 1 {
        return Err(format!(
            "'{head}.{sel}' is a number; nothing lies below it ('{}')",
            rest[1..].join(".")
        ));
    }
    if !items.iter().all(|v| v.is_integer() || v.is_float()) {
        return Err(format!(
            "'{head}' is not an array of numbers; only a number's component can be set"
        ));
    }
    let Some(v) = value else {
        return Err(format!(
            "'{head}.{sel}': a component cannot be removed (set it instead)"
        ));
    };
    if !(v.is_integer() || v.is_float()) {
        return Err(format!(
            "'{head}.{sel}': a component of a numeric array takes a number, not {}",
            v.type_str()
        ));
    }
    let n = items.len();
    if sel == "*" {
        items.iter_mut().for_each(|x| *x = v.clone());
        return Ok(n);
    }
    match sel.parse::<usize>() {
        Ok(k) if k < n => {
            items[k] = v.clone();
            Ok(1)
        }
        Ok(k) => Err(format!(
            "index {k} is out of range: '{head}' has {n} components (0 to {})",
            n.saturating_sub(1)
        )),
        Err(_) => Err(format!(
            "'{head}' is an array of numbers: select a component by index (0, 1, ...) or '*', not '{sel}'"
        )),
    }
}

/// Parses `text`, a scene tree that a study's edits wrote out again (named `named` in
/// messages). A parse error's line and excerpt are of that text, not of the user's file, so
/// only its field and sentence are kept: `FIELD: TOML parse error at line L, column C`, lines of
/// the text framed by `|`, then the sentence, becomes `FIELD: the sentence`.
pub(crate) fn parse_edited(text: &str, named: &Path) -> Result<SceneSpec> {
    SceneSpec::parse(text, named).map_err(|e| match e {
        jointplay_solver::Error::Parse { file, message } => {
            const AT: &str = "TOML parse error at line";
            let Some(i) = message.find(AT) else {
                return jointplay_solver::Error::Parse { file, message }.into();
            };
            let excerpt = |l: &str| {
                let t = l.trim_start();
                t.starts_with('|')
                    || t.split_once(" |")
                        .is_some_and(|(n, _)| n.trim().parse::<u64>().is_ok())
            };
            let sentence: Vec<&str> = message[i..]
                .lines()
                .skip(1)
                .filter(|l| !excerpt(l))
                .collect();
            let message = format!("{}{}", &message[..i], sentence.join("\n").trim());
            jointplay_solver::Error::Parse { file, message }.into()
        }
        other => other.into(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    const SCENE: &str = r#"
name = "s"
[[joints]]
name = "A"
clearance = { radial_clearance = 3e-4 }
[[joints]]
name = "B"
[[drives]]
name = "d1"
profile = { omega = 3.14 }
[[drives]]
name = "d2"
profile = { omega = 3.14 }
"#;

    #[test]
    fn edits_by_name_wildcard_and_index() {
        let mut t: Table = SCENE.parse().unwrap();
        edit(&mut t, "drives.*.profile.omega", Some(&Value::Float(1.57))).unwrap();
        edit(
            &mut t,
            "joints.A.clearance.radial_clearance",
            Some(&Value::Float(2e-4)),
        )
        .unwrap();
        edit(
            &mut t,
            "joints.1.kind",
            Some(&Value::String("fixed".into())),
        )
        .unwrap();
        let d = t["drives"].as_array().unwrap();
        assert!(
            d.iter()
                .all(|x| x["profile"]["omega"].as_float() == Some(1.57))
        );
        let j = t["joints"].as_array().unwrap();
        assert_eq!(j[0]["clearance"]["radial_clearance"].as_float(), Some(2e-4));
        assert_eq!(j[1]["kind"].as_str(), Some("fixed"));
        // Wildcards edit only where the path exists: B has no clearance.
        edit(
            &mut t,
            "joints.*.clearance.radial_clearance",
            Some(&Value::Float(1e-4)),
        )
        .unwrap();
        assert!(
            t["joints"].as_array().unwrap()[1]
                .get("clearance")
                .is_none()
        );
        edit(&mut t, "joints.A.clearance", None).unwrap();
        assert!(
            t["joints"].as_array().unwrap()[0]
                .get("clearance")
                .is_none()
        );
    }

    #[test]
    fn edits_that_match_nothing_are_errors() {
        let mut t: Table = SCENE.parse().unwrap();
        assert!(
            edit(
                &mut t,
                "joints.C.clearance.radial_clearance",
                Some(&Value::Float(1.0))
            )
            .is_err()
        );
        assert!(
            edit(
                &mut t,
                "joints.*.clearnce.stiffness",
                Some(&Value::Float(1.0))
            )
            .is_err()
        );
        assert!(edit(&mut t, "joints.B.clearance", None).is_err());
        assert!(edit(&mut t, "solver..step", None).is_err());
        assert!(edit(&mut t, "joints.A", None).is_err());
    }

    /// `*` adds a key under every element where its parent table exists (A has a clearance, B
    /// none); the scene's schema judges the key when the scene is parsed.
    #[test]
    fn a_wildcard_adds_a_key_where_the_parent_table_exists() {
        let mut t: Table = SCENE.parse().unwrap();
        edit(
            &mut t,
            "joints.*.clearance.onset_velocity_floor",
            Some(&Value::Float(1e-4)),
        )
        .unwrap();
        let j = t["joints"].as_array().unwrap();
        assert_eq!(
            j[0]["clearance"]["onset_velocity_floor"].as_float(),
            Some(1e-4)
        );
        assert!(j[1].get("clearance").is_none());
    }

    /// A component of a numeric array is set by index or `*`; a component is never removed, an
    /// index out of range names the length, and a non-number is refused.
    #[test]
    fn a_component_of_a_numeric_array_is_set_by_index() {
        let mut t: Table = "gravity = [0.0, -9.81, 0.0]\n[[bodies]]\nname = \"b\"\nvelocity = [1.0, 2.0, 3.0]\npoints = { B = [0.1, 0.2, 0.3] }\n"
            .parse()
            .unwrap();
        edit(&mut t, "bodies.b.velocity.0", Some(&Value::Float(5.0))).unwrap();
        edit(&mut t, "gravity.1", Some(&Value::Integer(-10))).unwrap();
        edit(&mut t, "bodies.*.points.B.2", Some(&Value::Float(0.5))).unwrap();
        let b = &t["bodies"].as_array().unwrap()[0];
        assert_eq!(b["velocity"].as_array().unwrap()[0].as_float(), Some(5.0));
        assert_eq!(
            b["points"]["B"].as_array().unwrap()[2].as_float(),
            Some(0.5)
        );
        assert_eq!(t["gravity"].as_array().unwrap()[1].as_integer(), Some(-10));
        edit(&mut t, "gravity.*", Some(&Value::Float(0.0))).unwrap();
        assert!(
            t["gravity"]
                .as_array()
                .unwrap()
                .iter()
                .all(|g| g.as_float() == Some(0.0))
        );
        let err = |t: &mut Table, p: &str, v: Option<&Value>| edit(t, p, v).unwrap_err();
        assert_eq!(
            err(&mut t, "bodies.b.velocity.3", Some(&Value::Float(1.0))),
            "index 3 is out of range: 'velocity' has 3 components (0 to 2)"
        );
        assert!(err(&mut t, "bodies.b.velocity.0", None).contains("cannot be removed"));
        assert!(err(&mut t, "bodies.b.velocity.x", Some(&Value::Float(1.0))).contains("by index"));
        assert!(
            err(
                &mut t,
                "bodies.b.velocity.0",
                Some(&Value::String("fast".into()))
            )
            .contains("takes a number")
        );
        assert!(
            err(&mut t, "bodies.b.velocity.0.1", Some(&Value::Float(1.0))).contains("is a number")
        );
    }
}
