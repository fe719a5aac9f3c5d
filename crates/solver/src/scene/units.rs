//! Quantities a scene may give with a unit: angles in degrees, rates in revolutions per minute,
//! lengths in millimetres. A field that takes one is either a number, in SI units as everywhere
//! else (m, rad, m/s, rad/s), or a string `"<number> <unit>"`; either way the scene holds SI
//! values from the moment it is read, so nothing downstream sees a unit.
//!
//! | dimension | units (SI first) |
//! |---|---|
//! | angle | `rad`, `deg` (also `°`): \\( \pi/180 \\) rad |
//! | angular rate | `rad/s`, `deg/s`, `rpm` (\\( 2\pi/60 \\) rad/s), `rev/s` and `Hz` (\\( 2\pi \\) rad/s) |
//! | length | `m`, `mm` |
//! | speed | `m/s`, `mm/s` |
//!
//! A drive's profile values are an angle or a length depending on the coordinate it drives;
//! [`check_drives`] refuses a unit of the other kind (`"120 rpm"` on a prismatic joint), naming
//! the drive and the field.

use serde::de::{Deserializer, Visitor};

/// What a quantity measures.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Dim {
    Angle,
    AngularRate,
    Length,
    Speed,
}

impl Dim {
    fn name(self) -> &'static str {
        match self {
            Dim::Angle => "an angle",
            Dim::AngularRate => "an angular rate",
            Dim::Length => "a length",
            Dim::Speed => "a speed",
        }
    }
}

/// Each unit: its name, its dimension and its factor to SI.
const UNITS: [(&str, Dim, f64); 12] = [
    ("rad", Dim::Angle, 1.0),
    ("deg", Dim::Angle, std::f64::consts::PI / 180.0),
    ("°", Dim::Angle, std::f64::consts::PI / 180.0),
    ("rad/s", Dim::AngularRate, 1.0),
    ("deg/s", Dim::AngularRate, std::f64::consts::PI / 180.0),
    ("rpm", Dim::AngularRate, std::f64::consts::TAU / 60.0),
    ("rev/s", Dim::AngularRate, std::f64::consts::TAU),
    ("Hz", Dim::AngularRate, std::f64::consts::TAU),
    ("m", Dim::Length, 1.0),
    ("mm", Dim::Length, 1e-3),
    ("m/s", Dim::Speed, 1.0),
    ("mm/s", Dim::Speed, 1e-3),
];

/// The value in SI and the dimension of `"<number> <unit>"` (`"30 deg"`, `"120rpm"`, `"0.1 mm"`).
pub fn quantity(text: &str) -> Result<(f64, Dim), String> {
    let t = text.trim();
    let split = t
        .char_indices()
        .find(|&(i, c)| {
            !(c.is_ascii_digit()
                || matches!(c, '.' | '+' | '-' | '_')
                || (matches!(c, 'e' | 'E')
                    && t[i + 1..]
                        .starts_with(|d: char| d.is_ascii_digit() || d == '-' || d == '+')))
        })
        .map_or(t.len(), |(i, _)| i);
    let (number, unit) = (t[..split].trim(), t[split..].trim());
    let known = || UNITS.map(|u| u.0).join(", ");
    let value: f64 = number.replace('_', "").parse().map_err(|_| {
        format!("\"{text}\" is not a number with a unit (for example \"30 deg\" or \"120 rpm\")")
    })?;
    if unit.is_empty() {
        return Err(format!(
            "\"{text}\" has no unit: write the number without quotes for SI units, or add one of {}",
            known()
        ));
    }
    let &(_, dim, factor) = UNITS.iter().find(|u| u.0 == unit).ok_or_else(|| {
        format!(
            "unknown unit '{unit}' in \"{text}\": use one of {}",
            known()
        )
    })?;
    let si = value * factor;
    if !si.is_finite() {
        return Err(format!("\"{text}\" is not finite"));
    }
    Ok((si, dim))
}

/// A number (SI), or a string with a unit of one of `dims`.
struct Quantity(&'static [Dim]);

impl Visitor<'_> for Quantity {
    type Value = f64;
    fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        let names: Vec<&str> = self.0.iter().map(|d| d.name()).collect();
        write!(
            f,
            "a number in SI units or a string with a unit ({})",
            names.join(" or ")
        )
    }
    fn visit_f64<E: serde::de::Error>(self, v: f64) -> Result<f64, E> {
        Ok(v)
    }
    fn visit_i64<E: serde::de::Error>(self, v: i64) -> Result<f64, E> {
        Ok(v as f64)
    }
    fn visit_u64<E: serde::de::Error>(self, v: u64) -> Result<f64, E> {
        Ok(v as f64)
    }
    fn visit_str<E: serde::de::Error>(self, v: &str) -> Result<f64, E> {
        let (si, dim) = quantity(v).map_err(E::custom)?;
        if !self.0.contains(&dim) {
            let want: Vec<&str> = self.0.iter().map(|d| d.name()).collect();
            return Err(E::custom(format!(
                "\"{v}\" is {}, this field takes {}",
                dim.name(),
                want.join(" or ")
            )));
        }
        Ok(si)
    }
}

fn read<'de, D: Deserializer<'de>>(d: D, dims: &'static [Dim]) -> Result<f64, D::Error> {
    d.deserialize_any(Quantity(dims))
}

/// An angle: rad, or a string in rad or deg.
pub fn angle<'de, D: Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
    read(d, &[Dim::Angle])
}

/// An optional angle.
pub fn option_angle<'de, D: Deserializer<'de>>(d: D) -> Result<Option<f64>, D::Error> {
    read(d, &[Dim::Angle]).map(Some)
}

/// An angular rate or frequency: rad/s, or a string in rad/s, deg/s, rpm, rev/s or Hz.
pub fn angular_rate<'de, D: Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
    read(d, &[Dim::AngularRate])
}

/// A drive coordinate's value: m or rad (which one, [`check_drives`] checks against the joint).
pub fn coordinate<'de, D: Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
    read(d, &[Dim::Angle, Dim::Length])
}

/// A drive coordinate's rate: m/s or rad/s.
pub fn coordinate_rate<'de, D: Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
    read(d, &[Dim::AngularRate, Dim::Speed])
}

/// A length: m, or a string in m or mm.
pub fn length<'de, D: Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
    read(d, &[Dim::Length])
}

/// An optional length.
pub fn option_length<'de, D: Deserializer<'de>>(d: D) -> Result<Option<f64>, D::Error> {
    read(d, &[Dim::Length]).map(Some)
}

/// Refuses a drive whose profile gives a unit of the wrong kind for the coordinate it drives
/// (an angle or an angular rate on a translation, a length or a speed on a rotation): the
/// profile's values have been read into SI already, so this reads the unit strings of `doc`
/// again. Returns the field's path (`drives[0].profile.rate`) and the message.
pub fn check_drives(doc: &toml::Table, spec: &super::SceneSpec) -> Result<(), (String, String)> {
    use super::{DriveCoordinate, JointKind};
    let Some(drives) = doc.get("drives").and_then(|d| d.as_array()) else {
        return Ok(());
    };
    for (i, (d, ds)) in drives.iter().zip(&spec.drives).enumerate() {
        let Some(profile) = d.get("profile").and_then(|p| p.as_table()) else {
            continue;
        };
        let coordinate = ds.coordinate.or_else(|| {
            let joint = spec.joints.iter().find(|j| j.name == ds.joint)?;
            match joint.kind {
                JointKind::Revolute => Some(DriveCoordinate::Rotation),
                JointKind::Prismatic => Some(DriveCoordinate::Translation),
                // Cylindrical joints name their coordinate; the others take no drive (the
                // compiler says so).
                JointKind::Cylindrical
                | JointKind::Spherical
                | JointKind::Universal
                | JointKind::Planar
                | JointKind::Fixed => None,
            }
        });
        let Some(coordinate) = coordinate else {
            continue;
        };
        let rotation = coordinate == DriveCoordinate::Rotation;
        for (key, value) in profile {
            let Some(text) = value.as_str() else {
                continue;
            };
            let Ok((_, dim)) = quantity(text) else {
                continue;
            };
            let angular = matches!(dim, Dim::Angle | Dim::AngularRate);
            if angular != rotation {
                return Err((
                    format!("drives[{i}].profile.{key}"),
                    format!(
                        "\"{text}\" is {}, but drive '{}' drives a {} (joint '{}'): give {}",
                        dim.name(),
                        ds.name,
                        if rotation { "rotation" } else { "translation" },
                        ds.joint,
                        if rotation {
                            "an angle (rad, deg) or an angular rate (rad/s, deg/s, rpm, rev/s, Hz)"
                        } else {
                            "a length (m, mm) or a speed (m/s, mm/s)"
                        }
                    ),
                ));
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::{Dim, quantity};

    #[test]
    fn quantities_are_read_into_si() {
        let pi = std::f64::consts::PI;
        // Exact conversions: the factors are the definitions of the units.
        assert_eq!(quantity("180 deg").unwrap(), (pi, Dim::Angle));
        assert_eq!(quantity("90°").unwrap(), (pi / 2.0, Dim::Angle));
        assert_eq!(quantity("60 rpm").unwrap(), (2.0 * pi, Dim::AngularRate));
        assert_eq!(quantity(" 1 Hz ").unwrap(), (2.0 * pi, Dim::AngularRate));
        assert_eq!(
            quantity("-2.5e-1 rad/s").unwrap(),
            (-0.25, Dim::AngularRate)
        );
        assert_eq!(quantity("0.1 mm").unwrap(), (0.1 * 1e-3, Dim::Length));
        assert_eq!(quantity("1e3mm/s").unwrap(), (1.0, Dim::Speed));
        assert_eq!(quantity("1_000 mm").unwrap(), (1.0, Dim::Length));
        for bad in ["deg", "30", "30 furlong", "1e400 deg", "3 0 deg", ""] {
            assert!(quantity(bad).is_err(), "{bad}");
        }
    }
}
