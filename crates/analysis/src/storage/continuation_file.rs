//! A continuation in HDF5 (layout in book/src/reference/hdf5.md): the group `/continuation` of
//! the analysis file, and the state kept after every point in `<study>.continuation.h5`, from
//! which a stopped continuation resumes.

use jointplay_solver::state::HybridState;
use nalgebra::{Complex, DMatrix};

use crate::Result;
use crate::measures::periodic::Orbit;
use crate::storage::branches::*;

/// A start state read from the HDF5 file `path` ([`read_start`]): the final state of a finished
/// run, or point `point` (from the end when negative; default the last) of branch `branch` of
/// a continuation, with that point's parameter. An error names the field of the start it
/// concerns ("file", "branch" or "point") and says why.
pub fn read_start(
    path: &std::path::Path,
    branch: Option<usize>,
    point: Option<i64>,
) -> std::result::Result<(HybridState, Option<f64>), (&'static str, String)> {
    let file = hdf5::File::open(path)
        .map_err(|e| ("file", format!("cannot open {}: {e}", path.display())))?;
    let Some(b) = branch else {
        let complete: u8 = crate::storage::h5::read_attr(&file, "complete").unwrap_or(0);
        if complete != 1 {
            return Err((
                "file",
                format!(
                    "{} is not a finished run of the program (attribute complete = 1): its last state is where it stopped",
                    path.display()
                ),
            ));
        }
        let state = crate::storage::hybrid::read_state(&file).map_err(|e| {
            (
                "file",
                format!(
                    "{} has no final state ({e}); a sweep's file holds one per value: start from a run file or a branch point",
                    path.display()
                ),
            )
        })?;
        return Ok((state, None));
    };
    let g = file
        .group(&format!("continuation/branch_{b}"))
        .map_err(|_| {
            (
                "branch",
                format!("{} has no /continuation/branch_{b}", path.display()),
            )
        })?;
    let read = |name: &str| crate::storage::h5::read_rows(&g, name);
    let e = |err: hdf5::Error| ("branch", format!("{}: {err}", path.display()));
    let params = read("parameter").map_err(e)?;
    let n = params.len() as i64;
    let i = point.unwrap_or(-1);
    let j = if i < 0 { n + i } else { i };
    if !(0..n).contains(&j) {
        return Err((
            "point",
            format!("branch {b} has {n} points: {i} is not one of them"),
        ));
    }
    let j = j as usize;
    let t: f64 = crate::storage::h5::read_attr(&g, "strobe_time").map_err(e)?;
    let y = read("state").map_err(e)?.swap_remove(j);
    let onset = read("onset")
        .ok()
        .and_then(|mut o| (o.len() > j).then(|| o.swap_remove(j)))
        .unwrap_or_default();
    let mut state = HybridState::new(t, y);
    state.onset = onset;
    Ok((state, Some(params[j][0])))
}

/// What a continuation's files record of the study that runs it: the study text (a continuation
/// resumes only with the study that began it), the `[continuation]` table's parameter, range and
/// tolerances, the observables by name, and which of them is the grazing gap's.
#[derive(Debug, Clone)]
pub struct Layout<'a> {
    /// The study's TOML text.
    pub study: &'a str,
    /// The continued parameter's path and SI unit.
    pub parameter: &'a str,
    pub unit: &'a str,
    pub from: f64,
    pub to: f64,
    pub tolerance: f64,
    /// The arclength bracket a special point is located to (parameter units).
    pub locate: f64,
    /// The study's observables, in its order.
    pub observables: Vec<&'a str>,
    /// The observable whose smallest value along an orbit is the grazing gap, when grazing is
    /// followed.
    pub gap_observable: Option<usize>,
}

/// The file a continuation's state goes to after every point, beside the analysis file `path`
/// (`out/s.h5` -> `out/s.continuation.h5`): a small HDF5 file with the root attribute `study` and
/// `/continuation`, replaced atomically after every point and removed once the state is in the
/// analysis file.
pub fn snapshot_path(path: &std::path::Path) -> std::path::PathBuf {
    path.with_extension("continuation.h5")
}

/// Writes `/continuation` into the analysis file `path` (replacing one written before); layout in
/// book/src/reference/hdf5.md. `failure` is the error of a continuation that could not start.
///
/// The file is never rewritten in place: a copy with the new `/continuation` is written
/// ([`crate::storage::durable::Unnamed`]) and moved over it ([`crate::storage::durable::replace`]); the state file of
/// [`snapshot_path`] is then removed.
pub fn write(
    path: &std::path::Path,
    layout: &Layout,
    c: std::result::Result<&Continuation, &crate::Error>,
) -> Result<()> {
    use crate::storage::durable;
    let name = durable::with_suffix(path, ".partial");
    let e = crate::storage::h5::h5err(&name);
    let file = crate::storage::h5::open_in_memory(path).map_err(&e)?;
    if file.group("continuation").is_ok() {
        file.unlink("continuation").map_err(&e)?;
    }
    write_group(&file, &name, layout, c)?;
    let bytes = crate::storage::h5::image(&file).map_err(&e)?;
    file.close().map_err(&e)?;
    durable::write_new(path, &bytes)?;
    durable::remove(&snapshot_path(path))
}

/// Writes the state of a continuation that goes on into the file of [`snapshot_path`] of the
/// analysis file `path`: a new file, read back as [`read_unfinished`] reads it, then moved into
/// place, so that a kill at any moment leaves the previous point's state or this one's, whole.
pub fn write_snapshot(path: &std::path::Path, layout: &Layout, c: &Continuation) -> Result<()> {
    use crate::storage::durable;
    let snap = snapshot_path(path);
    let name = durable::with_suffix(&snap, ".partial");
    let e = crate::storage::h5::h5err(&name);
    let file = crate::storage::h5::create_in_memory(&name).map_err(&e)?;
    crate::storage::h5::str_attr(&file, "study", layout.study).map_err(&e)?;
    crate::storage::h5::str_attr(&file, "program_version", env!("CARGO_PKG_VERSION"))
        .map_err(&e)?;
    write_group(&file, &name, layout, Ok(c))?;
    if c.unfinished.is_some() && read_group(&file, &name, layout)?.is_none() {
        return Err(crate::Error::Write {
            file: name.clone(),
            message: "the continuation's state does not read back as written".into(),
        });
    }
    let bytes = crate::storage::h5::image(&file).map_err(&e)?;
    file.close().map_err(&e)?;
    durable::write_new(&snap, &bytes)
}

/// Writes `/continuation` into `file` (named `path` in errors).
fn write_group(
    file: &hdf5::File,
    path: &std::path::Path,
    layout: &Layout,
    c: std::result::Result<&Continuation, &crate::Error>,
) -> Result<()> {
    use crate::storage::h5::{f64_attr, h5err, str_attr, u8_attr_set, u64_attr, write1};
    let e = h5err(path);
    let obs = &layout.observables;
    (|| -> hdf5::Result<()> {
        let g = file.create_group("continuation")?;
        str_attr(&g, "parameter", layout.parameter)?;
        str_attr(&g, "parameter_unit", layout.unit)?;
        f64_attr(&g, "from", layout.from)?;
        f64_attr(&g, "to", layout.to)?;
        f64_attr(&g, "tolerance", layout.tolerance)?;
        f64_attr(&g, "locate", layout.locate)?;
        str_attr(&g, "spurious_reason", crate::measures::periodic::SPURIOUS_REASON)?;
        let c = match c {
            Ok(c) => c,
            Err(err) => {
                str_attr(&g, "error", &err.to_string())?;
                return u8_attr_set(&g, "complete", 0);
            }
        };
        f64_attr(&g, "wall_time", c.wall)?;
        u8_attr_set(
            &g,
            "complete",
            u8::from(c.unfinished.is_none() && c.branches.iter().all(|b| !b.failed)),
        )?;
        u8_attr_set(&g, "finished", u8::from(c.unfinished.is_none()))?;
        u64_attr(&g, "branches", c.branches.len() as u64)?;
        let gap_unit = layout
            .gap_observable
            .and_then(|i| c.units.get(i))
            .map_or("", String::as_str);
        for (i, b) in c.branches.iter().enumerate() {
            let bg = g.create_group(&format!("branch_{i}"))?;
            match c.unfinished.as_ref().filter(|_| i + 1 == c.branches.len()) {
                Some(u) => {
                    let open = Branch {
                        end: "not finished: the continuation stopped here (`jointplay run STUDY --out DIR --resume` goes on)".into(),
                        ..b.clone()
                    };
                    write_branch(&bg, &open, obs, &c.units, layout.unit, gap_unit)?;
                    f64_attr(&bg, "next_step", u.step)?;
                }
                None => write_branch(&bg, b, obs, &c.units, layout.unit, gap_unit)?,
            }
        }
        if let Some(u) = &c.unfinished {
            u64_attr(&g, "points_done", u.points_done as u64)?;
            u64_attr(&g, "pending", u.queue.len() as u64)?;
            for (i, p) in u.queue.iter().enumerate() {
                let pg = g.create_group(&format!("pending_{i}"))?;
                // Its first point is an orbit of the branch it leaves (of its own periods).
                let b = Branch {
                    k: p.start.orbit.k,
                    origin: p.origin.clone(),
                    points: vec![p.start.clone()],
                    end: "waiting".into(),
                    failed: false,
                };
                write_branch(&pg, &b, obs, &c.units, layout.unit, gap_unit)?;
                u64_attr(&pg, "branch_periods", p.k as u64)?;
                if let Some((ty, ts)) = &p.switch {
                    let mut v = ty.clone();
                    v.push(*ts);
                    write1(
                        &pg,
                        "switch",
                        &v,
                        "SI",
                        "the first step's tangent (state, then scaled parameter)",
                    )?;
                }
            }
        }
        write_specials(
            &g.create_group("special")?,
            &c.specials,
            obs,
            &c.units,
            layout.unit,
        )
    })()
    .map_err(&e)
}

/// Reads back the continuation of the analysis file `path` when it stopped before its end
/// (`finished = 0`, written by [`write()`] from a [`Report`](crate::study::continuation::branch::Report)'s snapshot or an interrupted run): the
/// branches, the special points and where it stands. None when the file has no continuation or
/// a finished one.
///
/// The state written after the last point ([`write_snapshot`]) is read when there is one, else
/// the analysis file's `/continuation`.
pub fn read_unfinished(path: &std::path::Path, layout: &Layout) -> Result<Option<Continuation>> {
    let snap = snapshot_path(path);
    if snap.exists() {
        return read_from(&snap, layout);
    }
    read_from(path, layout)
}

fn read_from(path: &std::path::Path, layout: &Layout) -> Result<Option<Continuation>> {
    let file = hdf5::File::open(path).map_err(crate::storage::h5::h5err(path))?;
    read_group(&file, path, layout)
}

/// Whether a continuation into the analysis file `path` has begun: its state file
/// ([`snapshot_path`]) exists, or the file holds `/continuation` (finished or not).
pub fn begun(path: &std::path::Path) -> bool {
    snapshot_path(path).exists()
        || hdf5::File::open(path).is_ok_and(|f| f.group("continuation").is_ok())
}

/// Whether the analysis file `path` holds a finished continuation (and no state of one that
/// goes on beside it, [`snapshot_path`]).
pub fn is_finished(path: &std::path::Path) -> Result<bool> {
    if snapshot_path(path).exists() {
        return Ok(false);
    }
    let file = hdf5::File::open(path).map_err(crate::storage::h5::h5err(path))?;
    Ok(match file.group("continuation") {
        Ok(g) => crate::storage::h5::read_attr::<u8>(&g, "finished").unwrap_or(1) == 1,
        Err(_) => false,
    })
}

/// The unfinished continuation of `file` (named `path` in errors), as [`read_unfinished`].
fn read_group(
    file: &hdf5::File,
    path: &std::path::Path,
    layout: &Layout,
) -> Result<Option<Continuation>> {
    use crate::storage::h5::{read_attr, read_rows, read_strings};
    let Ok(g) = file.group("continuation") else {
        return Ok(None);
    };
    if read_attr::<u8>(&g, "finished").unwrap_or(1) == 1 {
        return Ok(None);
    }
    let text = crate::storage::h5::read_str(file, "study").unwrap_or_default();
    if text != layout.study {
        return Err(crate::Error::Io {
            file: path.to_path_buf(),
            message: "written by another study text: a continuation goes on only with the study that began it".into(),
        });
    }
    let obs = &layout.observables;
    (|| -> hdf5::Result<Option<Continuation>> {
        let n: u64 = read_attr(&g, "branches")?;
        let mut branches = Vec::new();
        for i in 0..n {
            branches.push(read_branch(&g.group(&format!("branch_{i}"))?, obs)?);
        }
        let step: f64 = match n.checked_sub(1) {
            Some(last) => {
                let bg = g.group(&format!("branch_{last}"))?;
                read_attr(&bg, "next_step")?
            }
            None => 0.0,
        };
        let mut queue = Vec::new();
        for i in 0..read_attr::<u64>(&g, "pending")? {
            let pg = g.group(&format!("pending_{i}"))?;
            let b = read_branch(&pg, obs)?;
            let switch = match pg.dataset("switch") {
                Ok(d) => {
                    let mut v: Vec<f64> = d.read_raw()?;
                    let ts = v.pop().unwrap_or(0.0);
                    Some((v, ts))
                }
                Err(_) => None,
            };
            let start = b
                .points
                .into_iter()
                .next()
                .ok_or("a pending branch without its point")?;
            queue.push(Pending {
                start,
                k: read_attr::<u64>(&pg, "branch_periods")? as usize,
                origin: b.origin,
                switch,
            });
        }
        let sg = g.group("special")?;
        let kinds = read_strings(&sg, "kind")?;
        let col = |name: &str| read_rows(&sg, name);
        let (branch, after, param, bracket) = (
            sg.dataset("branch")?.read_raw::<u64>()?,
            sg.dataset("after")?.read_raw::<u64>()?,
            sg.dataset("parameter")?.read_raw::<f64>()?,
            sg.dataset("bracket")?.read_raw::<f64>()?,
        );
        let (states, re, im) = (
            col("state")?,
            col("multipliers_re")?,
            col("multipliers_im")?,
        );
        let strobe: Vec<Vec<f64>> = obs
            .iter()
            .map(|o| sg.dataset(&format!("strobe/{o}"))?.read_raw::<f64>())
            .collect::<hdf5::Result<_>>()?;
        let mut specials = Vec::new();
        for (i, kind) in kinds.iter().enumerate() {
            let kind = Kind::ALL
                .into_iter()
                .find(|k| k.name() == kind)
                .ok_or_else(|| format!("unknown special point '{kind}'"))?;
            specials.push(Special {
                kind,
                branch: branch[i] as usize,
                after: after[i] as usize,
                parameter: param[i],
                bracket: bracket[i],
                state: states[i].clone(),
                multipliers: re[i]
                    .iter()
                    .zip(&im[i])
                    .map(|(a, b)| Complex::new(*a, *b))
                    .collect(),
                strobe: vec![strobe.iter().map(|v| v[i]).collect()],
            });
        }
        Ok(Some(Continuation {
            branches,
            specials,
            wall: read_attr(&g, "wall_time")?,
            units: Vec::new(),
            unfinished: Some(Unfinished {
                step,
                queue,
                points_done: read_attr::<u64>(&g, "points_done")? as usize,
            }),
        }))
    })()
    .map_err(|err| crate::Error::Io {
        file: path.to_path_buf(),
        message: format!("cannot read the unfinished continuation to resume it: {err}"),
    })
}

/// One branch as [`write_branch`] wrote it (the points' monodromy matrices are not kept: a
/// resumed continuation needs only their multipliers).
fn read_branch(g: &hdf5::Group, obs: &[&str]) -> hdf5::Result<Branch> {
    use crate::storage::h5::{read_attr, read_rows, read_str};
    let k = read_attr::<u64>(g, "orbit_periods")? as usize;
    let parameter: Vec<f64> = g.dataset("parameter")?.read_raw()?;
    let n = parameter.len();
    let mut points = Vec::with_capacity(n);
    if n > 0 {
        let t: f64 = read_attr(g, "strobe_time")?;
        let period: f64 = read_attr(g, "period")?;
        let spurious = read_attr::<u64>(g, "spurious")? as usize;
        let scaled: Vec<f64> = g.dataset("scaled")?.read_raw()?;
        let state = read_rows(g, "state")?;
        let tangent = read_rows(g, "tangent")?;
        let onset = read_rows(g, "onset").ok();
        let (re, im) = (
            read_rows(g, "multipliers_re")?,
            read_rows(g, "multipliers_im")?,
        );
        let residual: Vec<f64> = g.dataset("residual")?.read_raw()?;
        let iterations: Vec<u64> = g.dataset("iterations")?.read_raw()?;
        let events: Vec<u64> = g.dataset("events")?.read_raw()?;
        let gap: Option<Vec<f64>> = g.dataset("gap").and_then(|d| d.read_raw()).ok();
        let strobe: Vec<Vec<Vec<f64>>> = obs
            .iter()
            .map(|o| read_rows(g, &format!("strobe/{o}")))
            .collect::<hdf5::Result<_>>()?;
        for i in 0..n {
            let mut tan = tangent[i].clone();
            let ts = tan.pop().unwrap_or(0.0);
            let mut st = HybridState::new(t, state[i].clone());
            st.onset = onset.as_ref().map(|o| o[i].clone()).unwrap_or_default();
            let orbit = Orbit {
                state: st,
                k,
                period,
                residual: residual[i],
                iterations: iterations[i] as usize,
                multipliers: re[i]
                    .iter()
                    .zip(&im[i])
                    .map(|(a, b)| Complex::new(*a, *b))
                    .collect(),
                spurious,
                events: events[i],
                monodromy: DMatrix::zeros(0, 0),
                basis: None,
            };
            points.push(Point {
                parameter: parameter[i],
                orbit,
                iterations: iterations[i] as usize,
                strobe: (0..k)
                    .map(|j| strobe.iter().map(|o| o[i][j]).collect())
                    .collect(),
                gap: gap.as_ref().map(|g| g[i]).filter(|g| !g.is_nan()),
                tangent_y: tan,
                tangent_s: ts,
                s: scaled[i],
            });
        }
    }
    Ok(Branch {
        k,
        origin: read_str(g, "origin")?,
        points,
        end: read_str(g, "end")?,
        failed: read_attr::<u8>(g, "failed")? == 1,
    })
}

/// Writes branch `b` into its group `g`: its attributes, each point's orbit and stability, what a
/// resumed continuation needs, the grazing gap (in `gap_unit`) when computed, and the observables
/// `obs` (in `units`) at the strobe points; `unit` is the parameter's.
fn write_branch(
    g: &hdf5::Group,
    b: &Branch,
    obs: &[&str],
    units: &[String],
    unit: &str,
    gap_unit: &str,
) -> hdf5::Result<()> {
    use crate::storage::h5::{f64_attr, str_attr, u8_attr_set, u64_attr, write_table, write1};
    u64_attr(g, "orbit_periods", b.k as u64)?;
    str_attr(g, "origin", &b.origin)?;
    str_attr(g, "end", &b.end)?;
    u8_attr_set(g, "failed", u8::from(b.failed))?;
    if let Some(p) = b.points.first() {
        f64_attr(g, "strobe_time", p.orbit.state.t)?;
        f64_attr(g, "period", p.orbit.period)?;
        u64_attr(g, "spurious", p.orbit.spurious as u64)?;
    }
    write_points(g, b, unit)?;
    write_stability(g, b)?;
    write_resume(g, b)?;
    let col = |f: &dyn Fn(&Point) -> f64| b.points.iter().map(f).collect::<Vec<f64>>();
    if b.points.iter().any(|p| p.gap.is_some()) {
        write1(
            g,
            "gap",
            &col(&|p| p.gap.unwrap_or(f64::NAN)),
            gap_unit,
            "grazing level minus the largest value of the contact observable along the orbit",
        )?;
    }
    let s = g.create_group("strobe")?;
    for (j, name) in obs.iter().enumerate() {
        let v: Vec<f64> = b
            .points
            .iter()
            .flat_map(|p| p.strobe.iter().map(|row| row[j]))
            .collect();
        let u = units.get(j).map_or("", String::as_str);
        write_table(
            &s,
            name,
            &v,
            b.k,
            u,
            "the observable at the orbit's strobe points, one column per drive period",
        )?;
    }
    Ok(())
}

/// Each point's parameter (in `unit`), strobe state and Floquet multipliers.
fn write_points(g: &hdf5::Group, b: &Branch, unit: &str) -> hdf5::Result<()> {
    use crate::storage::h5::{write_table, write1};
    let col = |f: &dyn Fn(&Point) -> f64| b.points.iter().map(f).collect::<Vec<f64>>();
    write1(
        g,
        "parameter",
        &col(&|p| p.parameter),
        unit,
        "the parameter",
    )?;
    let n = b.points.first().map_or(0, |p| p.orbit.state.y.len());
    let state: Vec<f64> = b
        .points
        .iter()
        .flat_map(|p| p.orbit.state.y.clone())
        .collect();
    write_table(
        g,
        "state",
        &state,
        n.max(1),
        "SI",
        "the strobe point (continuous state)",
    )?;
    let m = b.points.first().map_or(0, |p| p.orbit.multipliers.len());
    let re: Vec<f64> = b
        .points
        .iter()
        .flat_map(|p| p.orbit.multipliers.iter().map(|z| z.re))
        .collect();
    let im: Vec<f64> = b
        .points
        .iter()
        .flat_map(|p| p.orbit.multipliers.iter().map(|z| z.im))
        .collect();
    write_table(
        g,
        "multipliers_re",
        &re,
        m.max(1),
        "1",
        "Floquet multipliers on the manifold, largest modulus first: real parts",
    )?;
    write_table(
        g,
        "multipliers_im",
        &im,
        m.max(1),
        "1",
        "their imaginary parts",
    )?;
    Ok(())
}

/// Each point's stability, multipliers outside the unit circle, residual, corrector iterations and
/// impacts.
fn write_stability(g: &hdf5::Group, b: &Branch) -> hdf5::Result<()> {
    use crate::storage::h5::{write_column, write1};
    let col = |f: &dyn Fn(&Point) -> f64| b.points.iter().map(f).collect::<Vec<f64>>();
    let stable: Vec<u8> = b
        .points
        .iter()
        .map(|p| u8::from(p.orbit.stable()))
        .collect();
    write_column(
        g,
        "stable",
        &stable,
        None,
        "1: every multiplier inside the unit circle",
    )?;
    let unstable: Vec<u64> = b
        .points
        .iter()
        .map(|p| p.orbit.unstable_count() as u64)
        .collect();
    write_column(
        g,
        "unstable",
        &unstable,
        None,
        "multipliers outside the unit circle",
    )?;
    write1(
        g,
        "residual",
        &col(&|p| p.orbit.residual),
        "SI",
        "largest component of P^k(y) - y",
    )?;
    let it: Vec<u64> = b.points.iter().map(|p| p.iterations as u64).collect();
    write_column(
        g,
        "iterations",
        &it,
        None,
        "Newton iterations of the corrector",
    )?;
    let ev: Vec<u64> = b.points.iter().map(|p| p.orbit.events).collect();
    write_column(g, "events", &ev, None, "impacts along one orbit")?;
    Ok(())
}

/// What a resumed continuation needs of each point: the scaled parameter, the tangent and the
/// contacts' onset memory.
fn write_resume(g: &hdf5::Group, b: &Branch) -> hdf5::Result<()> {
    use crate::storage::h5::{write_table, write1};
    let col = |f: &dyn Fn(&Point) -> f64| b.points.iter().map(f).collect::<Vec<f64>>();
    let n = b.points.first().map_or(0, |p| p.orbit.state.y.len());
    // What a resumed continuation needs: the scaled parameter, the tangent and the contacts'
    // onset memory of each point.
    write1(
        g,
        "scaled",
        &col(&|p| p.s),
        "1",
        "the scaled parameter (p - from) / (to - from) the continuation steps in",
    )?;
    let tangent: Vec<f64> = b
        .points
        .iter()
        .flat_map(|p| p.tangent_y.iter().copied().chain([p.tangent_s]))
        .collect();
    write_table(
        g,
        "tangent",
        &tangent,
        n + 1,
        "SI",
        "unit tangent of the branch: the state part, then the scaled parameter's",
    )?;
    let nc = b.points.first().map_or(0, |p| p.orbit.state.onset.len());
    if nc > 0 {
        let onset: Vec<f64> = b
            .points
            .iter()
            .flat_map(|p| p.orbit.state.onset.clone())
            .collect();
        write_table(
            g,
            "onset",
            &onset,
            nc,
            "m/s",
            "approach velocity at the onset of each contact at the strobe point (NaN: out of contact)",
        )?;
    }
    Ok(())
}

fn write_specials(
    g: &hdf5::Group,
    sp: &[Special],
    obs: &[&str],
    units: &[String],
    unit: &str,
) -> hdf5::Result<()> {
    use crate::storage::h5::{write_column, write_strings, write_table, write1};
    let kinds: Vec<String> = sp.iter().map(|s| s.kind.name().to_string()).collect();
    write_strings(
        g,
        "kind",
        &kinds,
        "fold, period-doubling, neimark-sacker or grazing",
    )?;
    let branch: Vec<u64> = sp.iter().map(|s| s.branch as u64).collect();
    write_column(g, "branch", &branch, None, "the branch it was found on")?;
    let after: Vec<u64> = sp.iter().map(|s| s.after as u64).collect();
    write_column(
        g,
        "after",
        &after,
        None,
        "index of the branch point before it",
    )?;
    write1(
        g,
        "parameter",
        &sp.iter().map(|s| s.parameter).collect::<Vec<_>>(),
        unit,
        "located parameter",
    )?;
    write1(
        g,
        "bracket",
        &sp.iter().map(|s| s.bracket).collect::<Vec<_>>(),
        unit,
        "arclength bracket reached: the bound on the parameter's error",
    )?;
    let n = sp.first().map_or(1, |s| s.state.len());
    let st: Vec<f64> = sp.iter().flat_map(|s| s.state.clone()).collect();
    write_table(
        g,
        "state",
        &st,
        n,
        "SI",
        "strobe point of the orbit nearest it",
    )?;
    let m = sp.first().map_or(1, |s| s.multipliers.len());
    let re: Vec<f64> = sp
        .iter()
        .flat_map(|s| s.multipliers.iter().map(|z| z.re))
        .collect();
    let im: Vec<f64> = sp
        .iter()
        .flat_map(|s| s.multipliers.iter().map(|z| z.im))
        .collect();
    write_table(
        g,
        "multipliers_re",
        &re,
        m,
        "1",
        "multipliers there: real parts",
    )?;
    write_table(g, "multipliers_im", &im, m, "1", "imaginary parts")?;
    let s = g.create_group("strobe")?;
    for (j, name) in obs.iter().enumerate() {
        let v: Vec<f64> = sp.iter().map(|x| x.strobe[0][j]).collect();
        let u = units.get(j).map_or("", String::as_str);
        write1(&s, name, &v, u, "the observable at the first strobe point")?;
    }
    Ok(())
}
