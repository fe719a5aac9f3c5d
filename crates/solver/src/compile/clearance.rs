//! Pass 4: clearance elements. A joint's `clearance` block becomes a [`Clearance`] contact
//! element: its geometry, its normal and friction laws ([`super::laws`]), and the constraint rows
//! that stay in the joint for what the contact leaves unconstrained.
//!
//! The scene file does not name a block's geometry: the joint kind implies it (ball in socket
//! for a spherical joint, journal in bushing for a revolute one) and, for a revolute joint,
//! `model` (spatial or planar). So the block is read as one struct of optional fields,
//! [`ClearanceSpec`], which keeps the file format, and sorted here into a per-geometry enum,
//! `Block` (what a tagged enum would give if the file carried the tag): each variant holds only
//! its geometry's fields, and a field of another geometry is refused with its path. The
//! [`Geometry`] is then built from the variant.

use super::ctx::{Ctx, positive};
use super::laws;
use super::rows::{JointFrame, Rows};
use crate::clearance::{Clearance, Geometry};
use crate::error::Result;
use crate::film::{DEFAULT_ECCENTRICITY_LIMIT, Film, FilmModel};
use crate::model::Prim;
use crate::scene::{ClearanceSpec, JointKind, JointSpec, LubricationSpec, RevoluteModel};

/// The element of joint `j` (index `joint`, field path `jf`) with its clearance block `c`; its
/// contacts start at slot `first`.
pub(crate) fn compile(
    c: &ClearanceSpec,
    j: &JointSpec,
    joint: usize,
    fr: &JointFrame,
    first: usize,
    jf: &str,
    cx: &Ctx,
) -> Result<Clearance> {
    let f = format!("{jf}.clearance");
    let geometry = geometry(c, j.kind, &f, cx)?;
    if matches!(geometry, Geometry::Translational { .. }) && j.reference_a.is_none() {
        return Err(cx.err(
            format!("{jf}.reference_a"),
            "missing: a prismatic joint with clearance needs the direction across its guide (normal to the guide's faces, in the plane of motion)",
        ));
    }
    let law = laws::normal(&c.normal, &geometry, &format!("{f}.normal"), cx)?;
    let friction = laws::friction(&c.friction, &format!("{f}.friction"), cx)?;
    let film = match &c.lubrication {
        Some(l) => Some(film(l, &geometry, &format!("{f}.lubrication"), cx)?),
        None => None,
    };
    Ok(Clearance {
        name: j.name.clone(),
        joint,
        housing: fr.a,
        journal: fr.b,
        sh: fr.sa,
        sj: fr.sb,
        axis_h: fr.axis_a,
        axis_j: fr.axis_b,
        ref_h: fr.ua,
        ref_j: fr.ub,
        geometry,
        law,
        friction,
        film,
        first,
        bristle: None,
    })
}

/// The oil film of a revolute clearance (`f`: the `lubrication` table's path).
fn film(l: &LubricationSpec, geometry: &Geometry, f: &str, cx: &Ctx) -> Result<Film> {
    let (radius, default_length) = match *geometry {
        Geometry::Planar { journal_radius, .. } => (journal_radius, None),
        Geometry::Revolute {
            journal_radius,
            bushing_length,
            ..
        } => (journal_radius, Some(bushing_length)),
        Geometry::Spherical { .. } | Geometry::Translational { .. } => {
            return Err(cx.err(
                f,
                "an oil film is modelled in revolute clearances (journal bearings), not in spherical or prismatic ones",
            ));
        }
    };
    if !l.viscosity.is_finite() || l.viscosity <= 0.0 {
        return Err(cx.err(
            format!("{f}.viscosity"),
            format!(
                "the oil's dynamic viscosity must be a positive number (Pa s), got {}",
                l.viscosity
            ),
        ));
    }
    let length = match (l.length, default_length) {
        (Some(x), _) if !x.is_finite() || x <= 0.0 => {
            return Err(cx.err(
                format!("{f}.length"),
                format!("the bearing length must be a positive number (m), got {x}"),
            ));
        }
        (Some(x), _) | (None, Some(x)) => x,
        (None, None) => {
            return Err(cx.err(
                format!("{f}.length"),
                "missing: the bearing length (m) a planar bearing's film acts over",
            ));
        }
    };
    let limit = l.eccentricity_limit.unwrap_or(DEFAULT_ECCENTRICITY_LIMIT);
    if !(limit > 0.0 && limit < 1.0) {
        return Err(cx.err(
            format!("{f}.eccentricity_limit"),
            format!("an eccentricity ratio between 0 and 1 (exclusive), got {limit}"),
        ));
    }
    let ratio = length / (2.0 * radius);
    match l.model {
        FilmModel::Short => {
            if ratio > 1.0 {
                cx.warn(
                    format!("{f}.length"),
                    format!(
                        "L/D = {ratio:.2}: the short-bearing film is accurate for L/D below about 0.5 and overestimates the load above"
                    ),
                );
            }
        }
        FilmModel::Finite => {
            if !(0.125..=1.0).contains(&ratio) {
                cx.warn(
                    format!("{f}.length"),
                    format!(
                        "L/D = {ratio:.2}: Butenschoen's finite-length fit is made for L/D from 1/8 to 1; outside, its coefficients are held at the nearest end of that range, an extrapolation no table checks"
                    ),
                );
            }
        }
        FilmModel::Long => {
            if ratio < 2.0 {
                cx.warn(
                    format!("{f}.length"),
                    format!(
                        "L/D = {ratio:.2}: the long-bearing film is accurate for L/D above about 4 and overestimates the load below (it leaves out the side leakage)"
                    ),
                );
            }
        }
    }
    Ok(Film {
        model: l.model,
        viscosity: l.viscosity,
        length,
        radius,
        clearance: geometry.radial_clearance(),
        eccentricity_limit: limit,
    })
}

/// The contact element replaces the joint's rows; what it leaves unconstrained stays a
/// constraint: the out-of-plane rows of a planar bearing or a slider in its guide, the axial
/// position of a spatial bearing without axial contact.
pub(crate) fn remaining_rows(geometry: &Geometry, fr: &JointFrame, rows: &mut Rows) {
    match geometry {
        Geometry::Planar { .. } => {
            fr.parallel().into_iter().for_each(|p| rows.push(p));
            rows.push(fr.along_axis(None));
        }
        Geometry::Revolute {
            journal_length: None,
            ..
        } => rows.push(fr.along_axis(None)),
        Geometry::Revolute {
            journal_length: Some(_),
            ..
        }
        | Geometry::Spherical { .. } => {}
        Geometry::Translational {
            half_width: Some(_),
            ..
        } => {}
        Geometry::Translational {
            half_width: None, ..
        } => {
            // The slider stays in the plane of axis_a and reference_a: no translation along
            // w_a, and its own normal to that plane, axis_b x u_b, parallel to w_a.
            rows.push(Prim::Distance {
                a: fr.a,
                u: fr.wa,
                sa: fr.sa,
                b: fr.b,
                sb: fr.sb,
                drive: None,
            });
            let wb = fr.axis_b.cross(&fr.ub);
            for u in [fr.axis_a, fr.ua] {
                rows.push(Prim::Perpendicular {
                    a: fr.a,
                    u,
                    b: fr.b,
                    v: wb,
                });
            }
        }
    }
}

/// A clearance block sorted by geometry: the fields of its geometry only, the radii of a
/// revolute block already resolved (m).
enum Block {
    /// Ball in socket.
    Spherical {
        ball_radius: Option<f64>,
        radial_clearance: Option<f64>,
    },
    /// Journal in bearing in the plane normal to the axis.
    Planar { journal: f64, bushing: f64 },
    /// Slider in a guide, in the plane of the axis and the reference direction.
    Translational {
        length: f64,
        height: f64,
        clearance: f64,
        /// The box's width (spatial model); none for the planar one.
        width: Option<f64>,
    },
    /// Journal free to translate and tilt in its bushing.
    Spatial {
        journal: f64,
        bushing: f64,
        bushing_length: Option<f64>,
        face_radius: Option<f64>,
        axial_clearance: Option<f64>,
    },
}

/// The geometry of a clearance block of a joint of kind `kind`; `f` is the block's field path.
fn geometry(c: &ClearanceSpec, kind: JointKind, f: &str, cx: &Ctx) -> Result<Geometry> {
    match Block::of(c, kind, f, cx)? {
        Block::Spherical {
            ball_radius,
            radial_clearance,
        } => Ok(Geometry::Spherical {
            ball_radius: positive(
                ball_radius,
                format!("{f}.ball_radius"),
                "the ball radius (m)",
                cx,
            )?,
            clearance: positive(
                radial_clearance,
                format!("{f}.radial_clearance"),
                "the radial clearance (m)",
                cx,
            )?,
        }),
        Block::Planar { journal, bushing } => Ok(Geometry::Planar {
            journal_radius: journal,
            bearing_radius: bushing,
        }),
        Block::Translational {
            length,
            height,
            clearance,
            width,
        } => Ok(Geometry::Translational {
            half_length: 0.5 * length,
            half_height: 0.5 * height,
            clearance,
            half_width: width.map(|w| 0.5 * w),
        }),
        Block::Spatial {
            journal,
            bushing,
            bushing_length,
            face_radius,
            axial_clearance,
        } => spatial(
            (journal, bushing),
            (bushing_length, face_radius, axial_clearance),
            f,
            cx,
        ),
    }
}

impl Block {
    /// Sorts the block `c` of a joint of kind `kind` (field path `f`) by its geometry.
    fn of(c: &ClearanceSpec, kind: JointKind, f: &str, cx: &Ctx) -> Result<Block> {
        // A joint without play is the ideal joint; the contact laws have no meaning there (the
        // point-contact stiffness grows without bound as the clearance closes).
        if c.radial_clearance == Some(0.0) {
            return Err(cx.err(
                format!("{f}.radial_clearance"),
                "zero clearance is the ideal joint: remove the clearance block (or give a positive clearance)",
            ));
        }
        match kind {
            JointKind::Spherical => Block::spherical(c, f, cx),
            JointKind::Revolute => Block::revolute(c, f, cx),
            JointKind::Prismatic => Block::translational(c, f, cx),
            k => Err(cx.err(
                f,
                format!(
                    "clearance is available for spherical, revolute and prismatic joints, not {}",
                    k.name()
                ),
            )),
        }
    }

    /// Ball in socket: ball radius and radial clearance.
    fn spherical(c: &ClearanceSpec, f: &str, cx: &Ctx) -> Result<Block> {
        if c.model.is_some() {
            return Err(cx.err(format!("{f}.model"), "only revolute joints have a model"));
        }
        refuse(
            &[
                (c.journal_radius, "journal_radius"),
                (c.bushing_radius, "bushing_radius"),
                (c.bushing_length, "bushing_length"),
                (c.face_radius, "face_radius"),
                (c.axial_clearance, "axial_clearance"),
                (c.slider_length, "slider_length"),
                (c.slider_height, "slider_height"),
                (c.slider_width, "slider_width"),
            ],
            f,
            "not a field of a spherical clearance (give ball_radius and radial_clearance)",
            cx,
        )?;
        Ok(Block::Spherical {
            ball_radius: c.ball_radius,
            radial_clearance: c.radial_clearance,
        })
    }

    /// Journal in bushing: the radii from any two of journal radius, bushing radius and radial
    /// clearance, then the planar or spatial model.
    fn revolute(c: &ClearanceSpec, f: &str, cx: &Ctx) -> Result<Block> {
        if c.ball_radius.is_some() {
            return Err(cx.err(
                format!("{f}.ball_radius"),
                "a revolute clearance has a journal_radius",
            ));
        }
        refuse(
            &[
                (c.slider_length, "slider_length"),
                (c.slider_height, "slider_height"),
                (c.slider_width, "slider_width"),
            ],
            f,
            "not a field of a revolute clearance (a prismatic joint's slider has it)",
            cx,
        )?;
        // Any two of journal radius, bushing radius and radial clearance, each positive.
        let given = |v: Option<f64>, n: &str| {
            v.map(|x| positive(Some(x), format!("{f}.{n}"), "", cx))
                .transpose()
        };
        let (rj, rb) = match (
            given(c.journal_radius, "journal_radius")?,
            given(c.bushing_radius, "bushing_radius")?,
            given(c.radial_clearance, "radial_clearance")?,
        ) {
            (Some(rj), Some(rb), cr) => {
                if let Some(cr) = cr
                    && ((rb - rj) - cr).abs() > 1e-9 * rb
                {
                    return Err(cx.err(
                        format!("{f}.radial_clearance"),
                        format!(
                            "{cr} m disagrees with bushing_radius - journal_radius = {} m",
                            rb - rj
                        ),
                    ));
                }
                (rj, rb)
            }
            (Some(rj), None, Some(cr)) => (rj, rj + cr),
            (None, Some(rb), Some(cr)) => {
                if cr >= rb {
                    return Err(cx.err(
                        format!("{f}.radial_clearance"),
                        format!("{cr} m leaves no journal inside a bushing of radius {rb} m"),
                    ));
                }
                (rb - cr, rb)
            }
            _ => {
                return Err(cx.err(
                    format!("{f}.radial_clearance"),
                    "missing: give two of journal_radius, bushing_radius and radial_clearance (m)",
                ));
            }
        };
        if rb <= rj {
            return Err(cx.err(
                format!("{f}.bushing_radius"),
                format!("the radial clearance must be positive: bushing radius {rb} m <= journal radius {rj} m"),
            ));
        }
        match c.model.unwrap_or_default() {
            RevoluteModel::Planar => {
                refuse(
                    &[
                        (c.bushing_length, "bushing_length"),
                        (c.face_radius, "face_radius"),
                        (c.axial_clearance, "axial_clearance"),
                    ],
                    f,
                    "not a field of a planar clearance",
                    cx,
                )?;
                Ok(Block::Planar {
                    journal: rj,
                    bushing: rb,
                })
            }
            RevoluteModel::Spatial => Ok(Block::Spatial {
                journal: rj,
                bushing: rb,
                bushing_length: c.bushing_length,
                face_radius: c.face_radius,
                axial_clearance: c.axial_clearance,
            }),
        }
    }

    /// Slider in guide: its length and height and the clearance per side, and for the spatial
    /// model (a box in a channel) its width.
    fn translational(c: &ClearanceSpec, f: &str, cx: &Ctx) -> Result<Block> {
        refuse(
            &[
                (c.ball_radius, "ball_radius"),
                (c.journal_radius, "journal_radius"),
                (c.bushing_radius, "bushing_radius"),
                (c.bushing_length, "bushing_length"),
                (c.face_radius, "face_radius"),
                (c.axial_clearance, "axial_clearance"),
            ],
            f,
            "not a field of a prismatic clearance (give slider_length, slider_height and radial_clearance)",
            cx,
        )?;
        let width = match c.model {
            None | Some(RevoluteModel::Planar) => {
                if c.slider_width.is_some() {
                    return Err(cx.err(
                        format!("{f}.slider_width"),
                        "a planar slider has no width: give model = \"spatial\" for a box in a channel",
                    ));
                }
                None
            }
            Some(RevoluteModel::Spatial) => Some(positive(
                c.slider_width,
                format!("{f}.slider_width"),
                "a spatial slider's width along axis_a x reference_a (m)",
                cx,
            )?),
        };
        Ok(Block::Translational {
            length: positive(
                c.slider_length,
                format!("{f}.slider_length"),
                "the slider's length along the axis (m)",
                cx,
            )?,
            height: positive(
                c.slider_height,
                format!("{f}.slider_height"),
                "the slider's height across the guide, along reference_a (m)",
                cx,
            )?,
            clearance: positive(
                c.radial_clearance,
                format!("{f}.radial_clearance"),
                "the gap on each side between slider and guide (m)",
                cx,
            )?,
            width,
        })
    }
}

/// Spatial journal-bushing geometry with journal radius `rj` and bushing radius `rb` from the
/// block's bushing length, face radius and axial clearance: the bushing length, and the end
/// faces when the block has axial contact.
fn spatial(
    (rj, rb): (f64, f64),
    (bushing_length, face_radius, axial_clearance): (Option<f64>, Option<f64>, Option<f64>),
    f: &str,
    cx: &Ctx,
) -> Result<Geometry> {
    let lb = positive(
        bushing_length,
        format!("{f}.bushing_length"),
        "the bushing length (m)",
        cx,
    )?;
    let journal_length = match axial_clearance {
        Some(ca) => Some(lb + 2.0 * positive(Some(ca), format!("{f}.axial_clearance"), "", cx)?),
        None => None,
    };
    let face_radius = match (face_radius, journal_length) {
        (Some(r), _) => {
            if r <= rb {
                return Err(cx.err(
                    format!("{f}.face_radius"),
                    format!("must exceed the bushing radius {rb} m, got {r} m"),
                ));
            }
            r
        }
        (None, Some(_)) => {
            return Err(cx.err(
                format!("{f}.face_radius"),
                "missing: axial contact needs the bushing end-face outer radius (m)",
            ));
        }
        (None, None) => rb,
    };
    Ok(Geometry::Revolute {
        journal_radius: rj,
        bushing_radius: rb,
        bushing_length: lb,
        face_radius,
        journal_length,
    })
}

/// An error naming the first of `fields` (value, key) that is given: a key of another geometry,
/// refused with `why`.
fn refuse(fields: &[(Option<f64>, &str)], f: &str, why: &str, cx: &Ctx) -> Result<()> {
    match fields.iter().find(|(v, _)| v.is_some()) {
        Some((_, n)) => Err(cx.err(format!("{f}.{n}"), why)),
        None => Ok(()),
    }
}
