//! A comparison study's file read back for its report ([`open`], then [`read_cases`]): the
//! study text, and per case its time, drive period, one body's motion and some joints' force
//! magnitudes, as plain data. The study layer parses the text and says which body and joints it
//! reports; nothing here knows a study's spec.

use std::collections::BTreeMap;
use std::path::Path;

use crate::storage::h5::{h5err, read_attr, read_rows, read_str};
use crate::{Error, Result};

/// The study text of the study file `path` (its root attribute `study`), or an error saying it
/// is not one.
pub fn open(path: &Path) -> Result<String> {
    let file = hdf5::File::open(path).map_err(h5err(path))?;
    read_str(&file, "study").map_err(|_| Error::Hdf5 {
        file: path.to_path_buf(),
        message: "not a study file (no 'study' attribute); `jointplay run STUDY` writes one".into(),
    })
}

/// What a report reads of each case: the cases by label, in order, the body whose motion it
/// reports and the joints whose forces it reports.
pub struct Asked<'a> {
    pub cases: &'a [&'a str],
    pub body: Option<&'a str>,
    pub joints: &'a [&'a str],
}

/// One case's recorded data.
pub struct CaseData {
    /// Sample times (s), at least two.
    pub time: Vec<f64>,
    /// The drive period (s), when the scene has one.
    pub period: Option<f64>,
    /// The asked body's position (m), velocity (m/s) and acceleration (m/s^2) per sample.
    pub body: Option<[Vec<[f64; 3]>; 3]>,
    /// Per asked joint, the magnitude of its force (N) per sample: the force on the journal of a
    /// clearance joint, the reaction of an ideal one.
    pub forces: BTreeMap<String, Vec<f64>>,
}

/// One case as the file holds it.
pub enum Case {
    /// The case failed: its error.
    Failed(String),
    /// Its data and wall time (s; NaN when not recorded).
    Recorded { data: CaseData, wall: f64 },
}

/// Reads the `asked` cases of the study file `path`, in the order asked.
pub fn read_cases(path: &Path, asked: &Asked) -> Result<Vec<Case>> {
    let e = h5err(path);
    let file = hdf5::File::open(path).map_err(&e)?;
    let cases_g = file.group("cases").map_err(&e)?;
    let mut out = Vec::new();
    for label in asked.cases {
        let g = cases_g.group(label).map_err(|err| Error::Hdf5 {
            file: path.to_path_buf(),
            message: format!("case '{label}' missing: {err}"),
        })?;
        if let Ok(err) = read_str(&g, "error") {
            out.push(Case::Failed(err));
            continue;
        }
        let data = CaseData::read(path, &g, asked, label)?;
        out.push(Case::Recorded {
            data,
            wall: read_attr::<f64>(&g, "wall_time_s").unwrap_or(f64::NAN),
        });
    }
    Ok(out)
}

/// The rows of a three-column dataset; `None` when it is missing or has another shape.
fn read_vec3(g: &hdf5::Group, name: &str) -> Option<Vec<[f64; 3]>> {
    if g.dataset(name).ok()?.shape().get(1) != Some(&3) {
        return None;
    }
    let rows = read_rows(g, name).ok()?;
    Some(rows.iter().map(|c| [c[0], c[1], c[2]]).collect())
}

/// Euclidean length of a 3-vector.
pub fn norm(v: &[f64; 3]) -> f64 {
    (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()
}

impl CaseData {
    /// Reads the case `label` from its group `g` of `path`: its time (at least two samples),
    /// drive period, the motion of `asked`'s body and its joints' force magnitudes.
    fn read(path: &Path, g: &hdf5::Group, asked: &Asked, label: &str) -> Result<CaseData> {
        let e = h5err(path);
        let time = g
            .dataset("time")
            .and_then(|d| d.read_raw::<f64>())
            .map_err(&e)?;
        if time.len() < 2 {
            return Err(Error::Hdf5 {
                file: path.to_path_buf(),
                message: format!("case '{label}' has fewer than two samples"),
            });
        }
        let period = read_attr::<f64>(g, "drive_period").ok();
        let body = match asked.body {
            Some(b) => {
                let bg = g.group(&format!("bodies/{b}")).map_err(|err| Error::Hdf5 {
                    file: path.to_path_buf(),
                    message: format!("case '{label}': body '{b}' not recorded: {err}"),
                })?;
                let get = |n: &str| {
                    read_vec3(&bg, n).ok_or_else(|| Error::Hdf5 {
                        file: path.to_path_buf(),
                        message: format!("case '{label}': bodies/{b}/{n} missing"),
                    })
                };
                Some([get("position")?, get("velocity")?, get("acceleration")?])
            }
            None => None,
        };
        let mut forces = BTreeMap::new();
        for j in asked.joints {
            let f = g
                .group(&format!("joints/{j}"))
                .ok()
                .and_then(|jg| {
                    read_vec3(&jg, "force_on_journal").or_else(|| read_vec3(&jg, "reaction_force"))
                })
                .ok_or_else(|| Error::Hdf5 {
                    file: path.to_path_buf(),
                    message: format!("case '{label}': no force recorded for joint '{j}'"),
                })?;
            forces.insert(j.to_string(), f.iter().map(norm).collect::<Vec<_>>());
        }
        Ok(CaseData {
            time,
            period,
            body,
            forces,
        })
    }
}
