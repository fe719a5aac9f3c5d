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
//! | `lubrication`, `J.lubrication` | the oil film of lubricated revolute clearances: the joint is dry | the block without its `lubrication` table |
//! | `accelerations`, `diagnostics`, `energy` | recording of accelerations, of drift and energy, of energy alone | `[output]` with them off |
//!
//! Each entry is parsed into a [`Disable`] (an [`Effect`], for one joint or all) and applied to the
//! parsed scene before it is compiled, so a disabled effect is never evaluated, stored or
//! recorded, and the compiled model is the one of a scene that never declared the effect: the
//! state, the contact buffers and the outputs are sized to what remains and no step branches on a
//! disabled effect. An entry that names no effect, or disables nothing (no such joint, a joint
//! without clearance, no friction anywhere), is an error naming `disable[i]`, so a typo never
//! passes silently.

use crate::error::{Error, Result};
use crate::scene::{ClearanceSpec, FrictionSpec, NormalSpec, SceneSpec};

/// An effect a `disable` entry can name.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Effect {
    Gravity,
    Springs,
    Loads,
    /// An effect of clearance joints, which an entry can also name for one joint.
    Joint(JointEffect),
    /// A recorded quantity.
    Recording(Recorded),
}

/// The effects of a clearance joint.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum JointEffect {
    /// The whole clearance block: the joint is ideal.
    Clearance,
    Friction,
    /// The damping of the normal law.
    ContactDamping,
    /// The end-face contacts of spatial revolute clearances.
    AxialContact,
    /// The oil film of lubricated revolute clearances.
    Lubrication,
}

/// The recorded quantities an entry can switch off.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Recorded {
    Accelerations,
    Diagnostics,
    Energy,
}

impl Effect {
    /// Every effect, in the order the error messages list them.
    pub const ALL: [Effect; 11] = [
        Effect::Gravity,
        Effect::Springs,
        Effect::Loads,
        Effect::Joint(JointEffect::Clearance),
        Effect::Joint(JointEffect::Friction),
        Effect::Joint(JointEffect::ContactDamping),
        Effect::Joint(JointEffect::AxialContact),
        Effect::Joint(JointEffect::Lubrication),
        Effect::Recording(Recorded::Accelerations),
        Effect::Recording(Recorded::Diagnostics),
        Effect::Recording(Recorded::Energy),
    ];

    /// The name an entry gives the effect.
    pub fn name(self) -> &'static str {
        match self {
            Effect::Gravity => "gravity",
            Effect::Springs => "springs",
            Effect::Loads => "loads",
            Effect::Joint(e) => e.name(),
            Effect::Recording(r) => r.name(),
        }
    }
}

impl JointEffect {
    /// Every joint effect, in the order the error messages list them.
    pub const ALL: [JointEffect; 5] = [
        JointEffect::Clearance,
        JointEffect::Friction,
        JointEffect::ContactDamping,
        JointEffect::AxialContact,
        JointEffect::Lubrication,
    ];

    pub fn name(self) -> &'static str {
        match self {
            JointEffect::Clearance => "clearance",
            JointEffect::Friction => "friction",
            JointEffect::ContactDamping => "contact_damping",
            JointEffect::AxialContact => "axial_contact",
            JointEffect::Lubrication => "lubrication",
        }
    }
}

impl Recorded {
    pub fn name(self) -> &'static str {
        match self {
            Recorded::Accelerations => "accelerations",
            Recorded::Diagnostics => "diagnostics",
            Recorded::Energy => "energy",
        }
    }
}

/// One parsed `disable` entry.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Disable {
    /// An effect for the whole scene.
    All(Effect),
    /// A clearance-joint effect for the joint with this name.
    Joint(String, JointEffect),
}

impl Disable {
    /// Parses an entry: `"<effect>"` or `"<joint>.<effect>"`. The error says what is wrong with it.
    pub fn parse(entry: &str) -> Result<Disable> {
        let (joint, name) = match entry.split_once('.') {
            Some((j, e)) => (Some(j), e),
            None => (None, entry),
        };
        let Some(effect) = Effect::ALL.into_iter().find(|e| e.name() == name) else {
            return Err(Error::UnknownEffect {
                name: name.to_string(),
                known: Effect::ALL.map(Effect::name).join(", "),
            });
        };
        match (joint, effect) {
            (None, e) => Ok(Disable::All(e)),
            (Some(j), Effect::Joint(e)) => Ok(Disable::Joint(j.to_string(), e)),
            (Some(_), Effect::Gravity | Effect::Springs | Effect::Loads | Effect::Recording(_)) => {
                Err(Error::NotJointEffect {
                    name: name.to_string(),
                    per_joint: JointEffect::ALL.map(JointEffect::name).join(", "),
                })
            }
        }
    }
}

/// Applies `spec.disable` to a copy of `spec`. Returns the edited scene and one line per entry
/// saying what it removed; an error comes with the field of its entry (`disable[2]`).
pub fn apply(spec: &SceneSpec) -> Result<(SceneSpec, Vec<String>), (String, Error)> {
    let mut s = spec.clone();
    let mut lines = Vec::new();
    for (i, entry) in spec.disable.iter().enumerate() {
        let field = format!("disable[{i}]");
        let d = Disable::parse(entry).map_err(|m| (field.clone(), m))?;
        let line = disable(&mut s, &d).map_err(|m| (field, m))?;
        lines.push(line);
    }
    Ok((s, lines))
}

/// Removes one effect from `s`; returns what it removed, or why there was nothing to remove.
fn disable(s: &mut SceneSpec, d: &Disable) -> Result<String> {
    let none = |what: &str| {
        Err(Error::NothingToDisable {
            what: what.to_string(),
        })
    };
    let (joint, effect) = match d {
        Disable::Joint(j, e) => {
            if !s.joints.iter().any(|x| &x.name == j) {
                return Err(Error::NoJoint { joint: j.clone() });
            }
            (Some(j.as_str()), *e)
        }
        Disable::All(Effect::Joint(e)) => (None, *e),
        Disable::All(Effect::Gravity) => {
            if s.gravity.take().is_none() {
                return none("the scene has no gravity");
            }
            return Ok("gravity".into());
        }
        Disable::All(Effect::Springs) => {
            if s.springs.is_empty() {
                return none("the scene has no springs");
            }
            let line = format!("{} springs", s.springs.len());
            s.springs.clear();
            return Ok(line);
        }
        Disable::All(Effect::Loads) => {
            if s.loads.is_empty() {
                return none("the scene has no loads");
            }
            let line = format!("{} loads", s.loads.len());
            s.loads.clear();
            return Ok(line);
        }
        Disable::All(Effect::Recording(r)) => {
            let o = &mut s.output;
            let flag = match r {
                Recorded::Accelerations => &mut o.accelerations,
                Recorded::Diagnostics => &mut o.diagnostics,
                Recorded::Energy => &mut o.energy,
            };
            if !*flag {
                return none(&format!("{} are not recorded", r.name()));
            }
            *flag = false;
            return Ok(format!("recording of {}", r.name()));
        }
    };
    let what = effect.name().replace('_', " ");
    let mut hit = Vec::new();
    for jt in s
        .joints
        .iter_mut()
        .filter(|x| joint.is_none_or(|j| x.name == j))
    {
        if disable_in_joint(&mut jt.clearance, effect) {
            hit.push(jt.name.clone());
        }
    }
    if hit.is_empty() {
        return none(&match joint {
            Some(j) => format!("joint '{j}' has no {what}"),
            None => format!("no joint has {what}"),
        });
    }
    Ok(format!("{what} in {}", hit.join(", ")))
}

/// Removes a clearance-joint effect from one joint's clearance block; whether it had it.
fn disable_in_joint(clearance: &mut Option<ClearanceSpec>, effect: JointEffect) -> bool {
    let Some(c) = clearance else {
        return false;
    };
    match effect {
        JointEffect::Clearance => {
            *clearance = None;
            true
        }
        JointEffect::Friction => {
            let had = !matches!(c.friction, FrictionSpec::None);
            c.friction = FrictionSpec::None;
            had
        }
        JointEffect::ContactDamping => {
            let had = !matches!(c.normal, NormalSpec::Hertz(_));
            c.normal = NormalSpec::Hertz(c.normal.elastic());
            had
        }
        JointEffect::AxialContact => {
            let had = c.axial_clearance.is_some();
            c.axial_clearance = None;
            c.face_radius = None;
            had
        }
        JointEffect::Lubrication => c.lubrication.take().is_some(),
    }
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use super::*;
    use crate::model::Model;
    use crate::scene::SceneFile;

    #[test]
    fn every_effect_parses_from_its_name_for_the_scene_and_joint_effects_per_joint() {
        for e in Effect::ALL {
            let parse = |entry: &str| Disable::parse(entry).map_err(|e| e.to_string());
            assert_eq!(parse(e.name()), Ok(Disable::All(e)));
            let scoped = parse(&format!("S2.{}", e.name()));
            match e {
                Effect::Joint(j) => assert_eq!(scoped, Ok(Disable::Joint("S2".into(), j))),
                Effect::Gravity | Effect::Springs | Effect::Loads | Effect::Recording(_) => {
                    assert_eq!(
                        scoped,
                        Err(format!(
                            "'{}' is not a joint effect; per joint: clearance, friction, contact_damping, axial_contact, lubrication",
                            e.name()
                        ))
                    )
                }
            }
        }
        assert_eq!(
            Disable::parse("wobble").map_err(|e| e.to_string()),
            Err(
                "unknown effect 'wobble'; known: gravity, springs, loads, clearance, friction, \
                 contact_damping, axial_contact, lubrication, accelerations, diagnostics, energy"
                    .into()
            )
        );
        assert!(matches!(
            Disable::parse("S2.fricton"),
            Err(Error::UnknownEffect { name, .. }) if name == "fricton"
        ));
    }

    /// Compiles the bundled 4-UPS-RPU scene with `disable = list`.
    fn compile(list: &str) -> crate::Result<Model> {
        let path =
            Path::new(env!("CARGO_MANIFEST_DIR")).join("../../data/scenes/4ups-rpu-mixed.toml");
        let text = std::fs::read_to_string(&path).unwrap().replacen(
            "\n[ground]",
            &format!("\ndisable = {list}\n\n[ground]"),
            1,
        );
        let spec = crate::scene::SceneSpec::parse(&text, &path)?;
        Model::compile(&SceneFile { path, text, spec }).map(|(m, _)| m)
    }

    #[test]
    fn an_unknown_entry_names_the_file_its_index_and_the_entry() {
        let err = compile(r#"["gravity", "S2.friction", "wobble"]"#)
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("4ups-rpu-mixed.toml: disable[2]: unknown effect 'wobble'"),
            "{err}"
        );
        let err = compile(r#"["S2.gravity"]"#).unwrap_err().to_string();
        assert!(
            err.contains("disable[0]: 'gravity' is not a joint effect"),
            "{err}"
        );
    }

    #[test]
    fn contact_damping_leaves_hertz_with_the_same_elastic_force() {
        let m = compile(r#"["contact_damping", "R1.axial_contact"]"#).unwrap();
        assert_eq!(m.disabled.len(), 2);
        let full = compile("[]").unwrap();
        for (c, f) in m.clearances.iter().zip(&full.clearances) {
            let crate::contact::NormalLaw::Hertz { el } = c.law else {
                panic!("{}: {:?}", c.name, c.law)
            };
            let crate::contact::NormalLaw::Hysteresis { el: full_el, .. } = f.law else {
                panic!("{}: {:?}", f.name, f.law)
            };
            assert_eq!(format!("{el:?}"), format!("{full_el:?}"), "{}", c.name);
        }
        let r1 = m.clearances.iter().find(|c| c.name == "R1").unwrap();
        assert_eq!(r1.geometry.n_contacts(), 2);
    }
}
