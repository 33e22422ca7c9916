//! An obstacle's `material`: a compliant fruit (Hertz line contact, docs/model.md).
//!
//! ```toml
//! [[obstacle]]
//! kind = "circle"
//! center = [-0.05, -0.05]
//! radius = 0.05
//! material = "apple"                              # a preset
//! # material = { preset = "apple", E = 2e6 }      # a preset with some values changed
//! # material = { E = 1.5e6, nu = 0.3, bruise_pressure = 1e5, failure_pressure = 3e5 }
//! ```
//!
//! Without `material` (or with `material = "rigid"`) the obstacle is rigid, the seed's model.

use super::reader::{did_you_mean, TableReader};
use super::ScenarioError;
use crate::contact::compliant::Material;
use crate::obstacle::Obstacle;
use toml::Value;

const MATERIAL_KEYS: &[&str] = &["preset", "E", "nu", "bruise_pressure", "failure_pressure"];

/// Read obstacle `r`'s `material` (None: rigid). Compliant materials are for fixed circles.
pub fn parse(
    r: &TableReader,
    shape: &Obstacle,
    free: bool,
) -> Result<Option<Material>, ScenarioError> {
    let Some((m, v)) = read(r)? else {
        return Ok(None);
    };
    match shape {
        Obstacle::Circle(_) => {}
        Obstacle::Plane(_) | Obstacle::Sine(_) => {
            return Err(r.err_hint(
                "material",
                Some(v),
                format!(
                    "a {} is an open surface, not a fruit: it cannot carry a material",
                    shape.kind()
                ),
                "put the material on the fruit (a circle); a table stays rigid",
            ))
        }
        _ => {
            return Err(r.err_hint(
                "material",
                Some(v),
                format!(
                    "a compliant material is implemented for circles only (this is a {}{}): \
                     the line-contact law needs the fruit's radius",
                    if free { "free " } else { "" },
                    shape.kind()
                ),
                "give the fruit as a circle, or remove `material` (rigid)",
            ))
        }
    }
    Ok(Some(m))
}

/// A table's `material` value (None: absent or `"rigid"`), with the value for messages.
fn read<'a>(r: &'a TableReader) -> Result<Option<(Material, &'a Value)>, ScenarioError> {
    let Some(v) = r.get("material") else {
        return Ok(None);
    };
    let m = match v {
        Value::String(name) if name == "rigid" => return Ok(None),
        Value::String(name) => preset(r, "material", v, name)?,
        Value::Table(_) => {
            let t = r.table_value("material", v, MATERIAL_KEYS)?;
            let mut m = match t.opt_str("preset")? {
                Some(name) => preset(&t, "preset", t.get("preset").unwrap_or(v), name)?,
                None => Material {
                    youngs_modulus: t.positive("E")?,
                    nu: 0.0,
                    bruise_pressure: t.positive("bruise_pressure")?,
                    failure_pressure: 0.0,
                    preset: None,
                },
            };
            if let Some(e) = t.opt_positive("E")? {
                m.youngs_modulus = e;
            }
            if let Some(nu) = t.opt_f64("nu")? {
                if !(0.0..=0.5).contains(&nu) {
                    return Err(t.err_hint(
                        "nu",
                        t.get("nu"),
                        "Poisson's ratio must be in [0, 0.5]",
                        "apple flesh is about 0.3",
                    ));
                }
                m.nu = nu;
            } else if m.preset.is_none() {
                m.nu = 0.3;
            }
            if let Some(p) = t.opt_positive("bruise_pressure")? {
                m.bruise_pressure = p;
            }
            m.failure_pressure = t
                .opt_positive("failure_pressure")?
                .unwrap_or(if m.preset.is_some() {
                    m.failure_pressure
                } else {
                    3.0 * m.bruise_pressure
                });
            t.finish()?;
            m
        }
        other => {
            return Err(r.err_hint(
                "material",
                Some(other),
                "expected a preset name or a table",
                "use e.g. material = \"apple\" or material = { E = 1.5e6, nu = 0.3, bruise_pressure = 1e5 }",
            ))
        }
    };
    Ok(Some((m, v)))
}

/// Read a 3D fruit's `material` (None: rigid). The Hertz point contact needs the fruit's
/// curvatures: a sphere or an ellipsoid; a box or a mesh is refused.
pub fn parse3(
    r: &TableReader,
    shape: &crate::obstacle3::Shape3,
) -> Result<Option<Material>, ScenarioError> {
    use crate::obstacle3::Shape3;
    let Some((m, v)) = read(r)? else {
        return Ok(None);
    };
    let kind = match shape {
        Shape3::Sphere { .. } | Shape3::Ellipsoid { .. } => return Ok(Some(m)),
        Shape3::Box { .. } => "box",
        Shape3::Mesh(_) => "mesh",
        Shape3::Plane => "plane",
    };
    Err(r.err_hint(
        "material",
        Some(v),
        format!(
            "a compliant material is implemented for spheres and ellipsoids only (this is a \
             {kind}): the Hertz point contact needs the fruit's principal curvatures, which a \
             {kind} does not have"
        ),
        "give the fruit as a sphere or an ellipsoid, or remove `material` (rigid)",
    ))
}

fn preset(r: &TableReader, key: &str, v: &Value, name: &str) -> Result<Material, ScenarioError> {
    Material::preset(name).ok_or_else(|| {
        let mut known: Vec<&str> = Material::PRESETS.to_vec();
        known.push("rigid");
        let hint = match did_you_mean(name, &known) {
            Some(m) => format!("did you mean \"{m}\"?"),
            None => format!("presets: {}", known.join(", ")),
        };
        r.err_hint(
            key,
            Some(v),
            format!("unknown material preset {name:?}"),
            hint,
        )
    })
}
