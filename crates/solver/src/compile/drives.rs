//! Pass 5: drives. Each drive prescribes one coordinate of an ideal joint and adds one
//! constraint row after the joint rows: d . axis_a - s(t) = 0 (translation) or theta - s(t) = 0
//! (rotation).

use std::collections::HashSet;

use super::ctx::{Ctx, list, v3};
use super::joints::Joints;
use super::rows::Rows;
use crate::error::Result;
use crate::model::Drive;
use crate::profile::{Profile, Spline};
use crate::scene::{DriveCoordinate, DriveSpec, JointKind, ProfileSpec, SceneSpec};

/// Compiles `spec.drives` on the joints of pass 3, appending their rows to `rows`; refuses more
/// rows in all than the constraint solver supports.
pub(crate) fn compile(
    spec: &SceneSpec,
    joints: &Joints,
    rows: &mut Rows,
    cx: &Ctx,
) -> Result<Vec<Drive>> {
    let mut drives = Vec::new();
    let mut names = HashSet::new();
    let mut driven = HashSet::new();
    for (i, d) in spec.drives.iter().enumerate() {
        let f = format!("drives[{i}]");
        if !names.insert(d.name.as_str()) {
            return Err(cx.err(
                format!("{f}.name"),
                format!("duplicate drive name '{}'", d.name),
            ));
        }
        let ji = *joints.index.get(d.joint.as_str()).ok_or_else(|| {
            cx.err(
                format!("{f}.joint"),
                format!(
                    "unknown joint '{}' (declared: {})",
                    d.joint,
                    list(spec.joints.iter().map(|j| &j.name))
                ),
            )
        })?;
        if joints.joints[ji].clearance.is_some() {
            return Err(cx.err(
                format!("{f}.joint"),
                format!("joint '{}' has clearance: its coordinate is not prescribed by a constraint and cannot be driven", d.joint),
            ));
        }
        let coordinate = coordinate(d, joints.joints[ji].kind, &f, cx)?;
        if !driven.insert((ji, coordinate)) {
            return Err(cx.err(
                format!("{f}.joint"),
                format!("joint '{}' is already driven in that coordinate", d.joint),
            ));
        }
        let profile = profile(&d.profile, &format!("{f}.profile"), cx)?;
        let fr = &joints.frames[ji];
        let di = drives.len();
        let row = rows.n;
        rows.push(match coordinate {
            DriveCoordinate::Translation => fr.along_axis(Some(di)),
            DriveCoordinate::Rotation => fr.angle(di),
        });
        drives.push(Drive {
            name: d.name.clone(),
            joint: ji,
            coordinate,
            profile,
            row,
        });
    }
    // The sparse factorisation indexes its entries with 32 bits; 50 000 rows keep even a full
    // triangle (1.25e9 entries) within that, far beyond any mechanism this program is for.
    if rows.n > 50_000 {
        return Err(cx.err(
            "joints",
            format!("{} constraint rows; at most 50000 are supported", rows.n),
        ));
    }
    Ok(drives)
}

/// The coordinate drive `d` (field path `f`) prescribes in a joint of kind `kind`.
fn coordinate(d: &DriveSpec, kind: JointKind, f: &str, cx: &Ctx) -> Result<DriveCoordinate> {
    match (kind, d.coordinate) {
        (JointKind::Prismatic, None | Some(DriveCoordinate::Translation)) => {
            Ok(DriveCoordinate::Translation)
        }
        (JointKind::Revolute, None | Some(DriveCoordinate::Rotation)) => {
            Ok(DriveCoordinate::Rotation)
        }
        (JointKind::Cylindrical, Some(c)) => Ok(c),
        (JointKind::Cylindrical, None) => Err(cx.err(
            format!("{f}.coordinate"),
            "a cylindrical joint needs coordinate = \"translation\" or \"rotation\"",
        )),
        (k, c) => Err(cx.err(
            format!("{f}.joint"),
            format!(
                "a {} joint has no {} coordinate to drive",
                k.name(),
                match c {
                    Some(DriveCoordinate::Rotation) => "rotation",
                    Some(DriveCoordinate::Translation) => "translation",
                    None => "drivable",
                }
            ),
        )),
    }
}

/// The function of time a profile block declares; `field` is its path.
fn profile(p: &ProfileSpec, field: &str, cx: &Ctx) -> Result<Profile> {
    Ok(match p {
        ProfileSpec::ConstantRate {
            initial,
            rate,
            ramp_time,
        } => Profile::ConstantRate {
            initial: *initial,
            rate: *rate,
            ramp: ramp(*ramp_time, field, cx)?,
        },
        ProfileSpec::Harmonic {
            mean,
            amplitude,
            omega,
            phase,
            ramp_time,
        } => Profile::Harmonic {
            mean: *mean,
            amplitude: *amplitude,
            omega: *omega,
            phase: *phase,
            ramp: ramp(*ramp_time, field, cx)?,
        },
        ProfileSpec::Tabulated { time, value } => {
            if time.len() != value.len() {
                return Err(cx.err(
                    format!("{field}.value"),
                    format!("has {} entries but time has {}", value.len(), time.len()),
                ));
            }
            if time.len() < 2 {
                return Err(cx.err(format!("{field}.time"), "needs at least two points"));
            }
            if let Some(i) = time.windows(2).position(|w| w[1] <= w[0]) {
                return Err(cx.err(
                    format!("{field}.time[{}]", i + 1),
                    "times must be strictly increasing",
                ));
            }
            Profile::Spline(Spline::new(time.clone(), value.clone()))
        }
        ProfileSpec::LegLength {
            anchor,
            center,
            cos_amplitude,
            sin_amplitude,
            omega,
            offset,
            ramp_time,
        } => {
            let (a, c, u, v) = (
                v3(*anchor),
                v3(*center),
                v3(*cos_amplitude),
                v3(*sin_amplitude),
            );
            // The leg must never pass through its anchor (the length would not be smooth).
            let min_len = (0..360)
                .map(|k| {
                    let th = k as f64 * std::f64::consts::PI / 180.0;
                    (c + u * th.cos() + v * th.sin() - a).norm()
                })
                .fold(f64::INFINITY, f64::min);
            if min_len < 1e-9 {
                return Err(cx.err(field, "the path passes through the anchor"));
            }
            Profile::LegLength {
                anchor: a,
                center: c,
                cos_amp: u,
                sin_amp: v,
                omega: *omega,
                offset: *offset,
                ramp: ramp(*ramp_time, field, cx)?,
            }
        }
    })
}

/// A profile's `ramp_time` (s): zero (no ramp) or positive and finite.
fn ramp(t: f64, field: &str, cx: &Ctx) -> Result<f64> {
    if t.is_finite() && t >= 0.0 {
        Ok(t)
    } else {
        Err(cx.err(
            format!("{field}.ramp_time"),
            format!("must be zero (no ramp) or a positive number of seconds, not {t}"),
        ))
    }
}
