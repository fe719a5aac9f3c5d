//! The contact laws of a clearance element (part of pass 4): each normal law's fields are checked
//! by its own function ([`hertz`], [`damped`], [`impact`]) after the elastic part they share
//! ([`elastic`]); then the friction law. The laws and their sources are in [`crate::contact`].

use super::ctx::{Ctx, positive};
use crate::clearance::Geometry;
use crate::contact::{
    Damping, Elastic, FrictionLaw, NormalLaw, hunt_crossley_restitution, point_contact_stiffness,
};
use crate::error::Result;
use crate::scene::{ContactModel, DampedSpec, ElasticSpec, FrictionSpec, ImpactSpec, NormalSpec};

/// The normal law of a clearance block with geometry `g`; `nf` is the field path of `normal`.
pub(crate) fn normal(n: &NormalSpec, g: &Geometry, nf: &str, cx: &Ctx) -> Result<NormalLaw> {
    let el = elastic(&n.elastic(), g, nf, cx)?;
    match n {
        NormalSpec::Hertz(_) => Ok(hertz(el)),
        NormalSpec::LankaraniNikravesh(d) => damped(Damping::LankaraniNikravesh, d, el, nf, cx),
        NormalSpec::HuntCrossley(d) => damped(Damping::HuntCrossley, d, el, nf, cx),
        NormalSpec::Flores(d) => damped(Damping::Flores, d, el, nf, cx),
        NormalSpec::Gonthier(d) => damped(Damping::Gonthier, d, el, nf, cx),
        NormalSpec::CarvalhoMartins(d) => damped(Damping::CarvalhoMartins, d, el, nf, cx),
        NormalSpec::Impact(s) => impact(s, el, nf, cx),
    }
}

/// The elastic part every normal law has: point contact K delta^n (K given, or from the
/// materials and the radii of `g`) or line contact (planar bearings only).
pub(crate) fn elastic(n: &ElasticSpec, g: &Geometry, nf: &str, cx: &Ctx) -> Result<Elastic> {
    match n.contact {
        ContactModel::Point => {
            if n.contact_length.is_some() {
                return Err(cx.err(
                    format!("{nf}.contact_length"),
                    "only line contact has a contact length",
                ));
            }
            let exponent = match n.exponent {
                None => 1.5,
                Some(e) => positive(Some(e), format!("{nf}.exponent"), "", cx)?,
            };
            let k = match (n.stiffness, material(n, nf, cx)?) {
                (Some(k), None) => positive(Some(k), format!("{nf}.stiffness"), "", cx)?,
                (None, Some((e, nu))) => {
                    let (ri, rj) = match *g {
                        Geometry::Spherical {
                            ball_radius,
                            clearance,
                        } => (ball_radius, ball_radius + clearance),
                        Geometry::Planar {
                            journal_radius,
                            bearing_radius,
                        } => (journal_radius, bearing_radius),
                        Geometry::Revolute {
                            journal_radius,
                            bushing_radius,
                            ..
                        } => (journal_radius, bushing_radius),
                        Geometry::Translational { .. } => {
                            return Err(cx.err(
                                format!("{nf}.youngs_modulus"),
                                "a slider's corners have no radius to derive a point-contact stiffness from: give stiffness (N/m^n)",
                            ));
                        }
                    };
                    point_contact_stiffness(ri, rj, e, nu, e, nu)
                }
                (Some(_), Some(_)) => {
                    return Err(cx.err(
                        format!("{nf}.stiffness"),
                        "give stiffness or youngs_modulus + poisson_ratio, not both",
                    ));
                }
                (None, None) => {
                    return Err(cx.err(
                        format!("{nf}.stiffness"),
                        "missing: give stiffness (N/m^n) or youngs_modulus (Pa) and poisson_ratio",
                    ));
                }
            };
            Ok(Elastic::Power { k, n: exponent })
        }
        ContactModel::Line => line_contact(n, g, nf, cx),
    }
}

/// Johnson's line contact of a journal in a planar bearing.
fn line_contact(n: &ElasticSpec, g: &Geometry, nf: &str, cx: &Ctx) -> Result<Elastic> {
    let Geometry::Planar {
        journal_radius,
        bearing_radius,
    } = *g
    else {
        return Err(cx.err(
            format!("{nf}.contact"),
            "line contact is available for planar revolute clearances (model = \"planar\")",
        ));
    };
    if n.stiffness.is_some() || n.exponent.is_some() {
        return Err(cx.err(
            format!("{nf}.stiffness"),
            "line contact derives its force from youngs_modulus and poisson_ratio; stiffness and exponent do not apply",
        ));
    }
    let Some((e, nu)) = material(n, nf, cx)? else {
        return Err(cx.err(
            format!("{nf}.youngs_modulus"),
            "missing: line contact needs youngs_modulus (Pa) and poisson_ratio",
        ));
    };
    let length = positive(
        n.contact_length,
        format!("{nf}.contact_length"),
        "line contact needs the contact length (m)",
        cx,
    )?;
    // Same material on both sides: 1/E* = 2 (1 - nu^2) / E.
    let e_star = e / (2.0 * (1.0 - nu * nu));
    Ok(Elastic::CylinderLine {
        c: std::f64::consts::PI * length * e_star,
        dr: bearing_radius - journal_radius,
    })
}

/// Young's modulus and Poisson's ratio, when given (both or neither).
fn material(n: &ElasticSpec, nf: &str, cx: &Ctx) -> Result<Option<(f64, f64)>> {
    match (n.youngs_modulus, n.poisson_ratio) {
        (None, None) => Ok(None),
        (Some(e), Some(nu)) => {
            positive(Some(e), format!("{nf}.youngs_modulus"), "", cx)?;
            if !(0.0..0.5).contains(&nu) {
                return Err(cx.err(
                    format!("{nf}.poisson_ratio"),
                    format!("must be in [0, 0.5), got {nu}"),
                ));
            }
            Ok(Some((e, nu)))
        }
        (Some(_), None) => Err(cx.err(
            format!("{nf}.poisson_ratio"),
            "missing: youngs_modulus needs poisson_ratio",
        )),
        (None, Some(_)) => Err(cx.err(
            format!("{nf}.youngs_modulus"),
            "missing: poisson_ratio needs youngs_modulus",
        )),
    }
}

/// `law = "hertz"`: the elastic force alone; it has no fields of its own.
fn hertz(el: Elastic) -> NormalLaw {
    NormalLaw::Hertz { el }
}

/// The hysteresis-damped laws of the Hunt-Crossley family (`kind`): the coefficient of
/// restitution and the floor of the onset velocity. Warns when the law restitutes, in an
/// isolated impact, more than 0.05 away from the requested c_e.
fn damped(kind: Damping, d: &DampedSpec, el: Elastic, nf: &str, cx: &Ctx) -> Result<NormalLaw> {
    let ce = match d.restitution {
        Some(e) if e > 0.0 && e <= 1.0 => e,
        Some(e) => {
            return Err(cx.err(
                format!("{nf}.restitution"),
                format!("must be in (0, 1], got {e}"),
            ));
        }
        None => {
            return Err(cx.err(
                format!("{nf}.restitution"),
                "missing: this law needs the coefficient of restitution",
            ));
        }
    };
    let v_floor = match d.onset_velocity_floor {
        None => 1e-3,
        Some(v) => positive(Some(v), format!("{nf}.onset_velocity_floor"), "", cx)?,
    };
    let got = hunt_crossley_restitution(kind.factor(ce));
    if (got - ce).abs() > 0.05 {
        let better: Vec<String> = [
            (Damping::CarvalhoMartins, "carvalho_martins"),
            (Damping::Flores, "flores"),
            (Damping::Gonthier, "gonthier"),
        ]
        .iter()
        .filter(|(k, _)| *k != kind)
        .map(|&(k, name)| (name, hunt_crossley_restitution(k.factor(ce))))
        .filter(|(_, e)| (e - ce).abs() <= 0.05)
        .map(|(name, e)| format!("law = \"{name}\" (restitutes {e:.3})"))
        .collect();
        cx.warn(
            format!("{nf}.restitution"),
            format!(
                "the {} law is outside its range at c_e = {ce}: it was derived for c_e near 1, \
                 and an isolated impact restitutes {got:.3}, not {ce}; use {}",
                kind.name(),
                if better.is_empty() {
                    "a law fitted to low restitution".to_string()
                } else {
                    better.join(" or ")
                }
            ),
        );
    }
    Ok(NormalLaw::Hysteresis {
        el,
        kind,
        restitution: ce,
        d: kind.factor(ce),
        v_floor,
    })
}

/// `law = "impact"` (ADAMS IMPACT): the damping ramp, on a point-contact force K delta^n.
fn impact(s: &ImpactSpec, el: Elastic, nf: &str, cx: &Ctx) -> Result<NormalLaw> {
    let c_max = match s.max_damping {
        Some(c) if c >= 0.0 => c,
        Some(c) => {
            return Err(cx.err(
                format!("{nf}.max_damping"),
                format!("must not be negative, got {c}"),
            ));
        }
        None => {
            return Err(cx.err(
                format!("{nf}.max_damping"),
                "missing: IMPACT needs max_damping (N s/m)",
            ));
        }
    };
    let d_max = positive(
        s.full_damping_penetration,
        format!("{nf}.full_damping_penetration"),
        "IMPACT needs the penetration at full damping (m)",
        cx,
    )?;
    let Elastic::Power { k, n: exponent } = el else {
        return Err(cx.err(
            format!("{nf}.contact"),
            "IMPACT is a point-contact law (K delta^n)",
        ));
    };
    Ok(NormalLaw::Impact {
        k,
        n: exponent,
        c_max,
        d_max,
    })
}

/// The friction law of a clearance block; `ff` is the field path of `friction`.
pub(crate) fn friction(fs: &FrictionSpec, ff: &str, cx: &Ctx) -> Result<FrictionLaw> {
    let mu = |m: f64| -> Result<f64> {
        if m >= 0.0 {
            Ok(m)
        } else {
            Err(cx.err(
                format!("{ff}.coefficient"),
                format!("must not be negative, got {m}"),
            ))
        }
    };
    Ok(match fs {
        FrictionSpec::None => FrictionLaw::None,
        FrictionSpec::Coulomb {
            coefficient,
            regularisation_velocity,
        } => FrictionLaw::Coulomb {
            mu: mu(*coefficient)?,
            v_reg: positive(
                Some(*regularisation_velocity),
                format!("{ff}.regularisation_velocity"),
                "",
                cx,
            )?,
        },
        FrictionSpec::Ambrosio {
            coefficient,
            v0,
            v1,
        } => {
            let v0 = positive(Some(*v0), format!("{ff}.v0"), "", cx)?;
            if *v1 <= v0 {
                return Err(cx.err(
                    format!("{ff}.v1"),
                    format!("must exceed v0 = {v0} m/s, got {v1}"),
                ));
            }
            FrictionLaw::Ambrosio {
                mu: mu(*coefficient)?,
                v0,
                v1: *v1,
            }
        }
        FrictionSpec::Threlfall { coefficient, v0 } => FrictionLaw::Threlfall {
            mu: mu(*coefficient)?,
            v0: positive(Some(*v0), format!("{ff}.v0"), "", cx)?,
        },
        FrictionSpec::LuGre {
            coefficient,
            static_coefficient,
            stribeck_velocity,
            bristle_stiffness,
            bristle_damping,
            viscous,
        } => {
            // g(v) must stay positive (it divides the bristle rate): mu_c > 0; the static
            // coefficient is the peak of the Stribeck curve, not below the Coulomb one.
            let mu_c = positive(Some(*coefficient), format!("{ff}.coefficient"), "", cx)?;
            if !(static_coefficient.is_finite() && *static_coefficient >= mu_c) {
                return Err(cx.err(
                    format!("{ff}.static_coefficient"),
                    format!(
                        "must be at least the Coulomb coefficient {mu_c}, got {static_coefficient}"
                    ),
                ));
            }
            let not_negative = |x: f64, field: &str| -> Result<f64> {
                if x.is_finite() && x >= 0.0 {
                    Ok(x)
                } else {
                    Err(cx.err(
                        format!("{ff}.{field}"),
                        format!("must be finite and not negative, got {x}"),
                    ))
                }
            };
            FrictionLaw::LuGre {
                mu_c,
                mu_s: *static_coefficient,
                v_s: positive(
                    Some(*stribeck_velocity),
                    format!("{ff}.stribeck_velocity"),
                    "",
                    cx,
                )?,
                sigma0: positive(
                    Some(*bristle_stiffness),
                    format!("{ff}.bristle_stiffness"),
                    "",
                    cx,
                )?,
                sigma1: not_negative(*bristle_damping, "bristle_damping")?,
                sigma2: not_negative(*viscous, "viscous")?,
            }
        }
    })
}
