//! Switching effects off: the scene's `disable = [...]` list.
//!
//! An entry names an effect, for the whole scene or for one joint (`"<joint>.<effect>"`):
//!
//! | entry | what goes | what it equals |
//! |---|---|---|
//! | `gravity` | the gravity vector | a scene without `gravity` |
//! | `springs`, `loads` | every spring-damper, every applied load | a scene without them |
//! | `clearance`, `J.clearance` | the clearance block of every joint (or of J): the joint is ideal | the joint without its `clearance` table |
//! | `friction`, `J.friction` | the friction law of every clearance joint (or of J) | `friction = { law = "none" }` |
//! | `contact_damping`, `J.contact_damping` | the damping of the normal law: Hertz with the same stiffness and exponent | `law = "hertz"` |
//! | `axial_contact`, `J.axial_contact` | the end-face contacts M, N of spatial revolute clearances; the axial position is held by a constraint row again | the block without `axial_clearance` and `face_radius` |
//! | `accelerations`, `diagnostics`, `energy` | recording of accelerations, of drift and energy, of energy alone | `[output]` with them off |
//!
//! The list is applied to the parsed scene before it is compiled, so a disabled effect is never
//! evaluated, stored or recorded, and the compiled model is the one of a scene that never
//! declared the effect: the state, the contact buffers and the outputs are sized to what remains
//! and no step branches on a disabled effect. An entry that disables nothing (no such joint, a
//! joint without clearance, no friction anywhere) is an error naming `disable[i]`, so a typo never
//! passes silently.

use crate::scene::{FrictionSpec, NormalSpec, SceneSpec};

/// The effects a `disable` entry can name.
pub const EFFECTS: [&str; 10] = [
    "gravity",
    "springs",
    "loads",
    "clearance",
    "friction",
    "contact_damping",
    "axial_contact",
    "accelerations",
    "diagnostics",
    "energy",
];

/// Effects that can be named per joint.
const JOINT_EFFECTS: [&str; 4] = ["clearance", "friction", "contact_damping", "axial_contact"];

/// Applies `spec.disable` to a copy of `spec`. Returns the edited scene and one line per entry
/// saying what it removed; errors are `(field, message)`.
pub fn apply(spec: &SceneSpec) -> Result<(SceneSpec, Vec<String>), (String, String)> {
    let mut s = spec.clone();
    let mut lines = Vec::new();
    for (i, entry) in spec.disable.iter().enumerate() {
        let field = format!("disable[{i}]");
        let (joint, effect) = match entry.split_once('.') {
            Some((j, e)) => (Some(j), e),
            None => (None, entry.as_str()),
        };
        if !EFFECTS.contains(&effect) {
            return Err((
                field,
                format!("unknown effect '{effect}'; known: {}", EFFECTS.join(", ")),
            ));
        }
        if let Some(j) = joint {
            if !JOINT_EFFECTS.contains(&effect) {
                return Err((
                    field,
                    format!(
                        "'{effect}' is not a joint effect; per joint: {}",
                        JOINT_EFFECTS.join(", ")
                    ),
                ));
            }
            if !s.joints.iter().any(|x| x.name == j) {
                return Err((field, format!("no joint '{j}'")));
            }
        }
        let none = |what: &str| Err((field.clone(), format!("nothing to disable: {what}")));
        match effect {
            "gravity" => {
                if s.gravity.take().is_none() {
                    return none("the scene has no gravity");
                }
                lines.push("gravity".into());
            }
            "springs" => {
                if s.springs.is_empty() {
                    return none("the scene has no springs");
                }
                lines.push(format!("{} springs", s.springs.len()));
                s.springs.clear();
            }
            "loads" => {
                if s.loads.is_empty() {
                    return none("the scene has no loads");
                }
                lines.push(format!("{} loads", s.loads.len()));
                s.loads.clear();
            }
            "accelerations" | "diagnostics" | "energy" => {
                let o = &mut s.output;
                let flag = match effect {
                    "accelerations" => &mut o.accelerations,
                    "diagnostics" => &mut o.diagnostics,
                    _ => &mut o.energy,
                };
                if !*flag {
                    return none(&format!("{effect} are not recorded"));
                }
                *flag = false;
                lines.push(format!("recording of {effect}"));
            }
            _ => {
                let mut hit = Vec::new();
                for jt in s
                    .joints
                    .iter_mut()
                    .filter(|x| joint.is_none_or(|j| x.name == j))
                {
                    if effect == "clearance" {
                        if jt.clearance.take().is_some() {
                            hit.push(jt.name.clone());
                        }
                        continue;
                    }
                    let Some(c) = jt.clearance.as_mut() else {
                        continue;
                    };
                    let done = match effect {
                        "friction" => {
                            let had = !matches!(c.friction, FrictionSpec::None);
                            c.friction = FrictionSpec::None;
                            had
                        }
                        "contact_damping" => {
                            let had = !matches!(c.normal, NormalSpec::Hertz(_));
                            c.normal = NormalSpec::Hertz(c.normal.elastic());
                            had
                        }
                        _ => {
                            let had = c.axial_clearance.is_some();
                            c.axial_clearance = None;
                            c.face_radius = None;
                            had
                        }
                    };
                    if done {
                        hit.push(jt.name.clone());
                    }
                }
                if hit.is_empty() {
                    return none(&match joint {
                        Some(j) => format!("joint '{j}' has no {}", effect.replace('_', " ")),
                        None => format!("no joint has {}", effect.replace('_', " ")),
                    });
                }
                lines.push(format!(
                    "{} in {}",
                    effect.replace('_', " "),
                    hit.join(", ")
                ));
            }
        }
    }
    Ok((s, lines))
}
