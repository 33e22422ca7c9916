//! `[[obstacle]]` tables: fixed shapes (the seed's rigid fruit, a table) and free rigid
//! bodies (a fruit that can be lifted or dropped).

use super::reader::{did_you_mean, TableReader};
use super::{Mode, ScenarioError};
use crate::obstacle::{Circle, Ellipse, Obstacle, Plane, Polygon, Sine};
use crate::world::body::{area_properties, outline_radius, BodySpec};

const KINDS: &[&str] = &["circle", "plane", "sine", "ellipse", "polygon"];
const KEYS: &[&str] = &[
    "kind",
    "center",
    "radius",
    "point",
    "normal",
    "amplitude",
    "wavenumber",
    "offset",
    "a",
    "b",
    "angle",
    "vertices",
    "name",
    "free",
    "mass",
    "density",
    "depth",
    "inertia",
    "velocity",
    "angular_velocity",
    "hold_tolerance",
    "material",
];

/// Keys every obstacle takes: a name, and what makes it a free rigid body.
const BODY_KEYS: &[&str] = &[
    "name",
    "free",
    "mass",
    "density",
    "depth",
    "inertia",
    "velocity",
    "angular_velocity",
    "hold_tolerance",
];

/// Read one `[[obstacle]]` table: its shape, its name, and (with `free = true`) the rigid
/// body that carries it.
pub fn parse(
    r: &TableReader,
    index: usize,
    mode: Mode,
    gravity: [f64; 2],
) -> Result<Parsed, ScenarioError> {
    let r = TableReader::new(r.file, r.path.clone(), r.table, KEYS);
    let shape = parse_shape(&r)?;
    let name = match r.opt_str("name")? {
        Some(n) if n.trim().is_empty() => {
            return Err(r.err("name", r.get("name"), "must not be empty"))
        }
        Some(n) => n.to_string(),
        None => format!("obstacle.{index}"),
    };
    let body = if r.opt_bool("free")?.unwrap_or(false) {
        Some(parse_body(&r, index, &shape, &name, mode, gravity)?)
    } else {
        for k in BODY_KEYS.iter().filter(|k| !matches!(**k, "name" | "free")) {
            if r.has(k) {
                return Err(r.err_hint(
                    k,
                    r.get(k),
                    "only a free obstacle takes this key",
                    "add `free = true` to make the obstacle a rigid body that moves",
                ));
            }
        }
        None
    };
    let material = super::material::parse(&r, &shape, body.is_some())?;
    r.finish()?;
    Ok((shape, name, body, material))
}

/// An obstacle's shape, name, rigid body (when free) and material (when compliant).
pub type Parsed = (
    Obstacle,
    String,
    Option<BodySpec>,
    Option<crate::contact::compliant::Material>,
);

/// The rigid body of a `free = true` obstacle: mass from `mass` or `density` × area × `depth`,
/// inertia about the centroid from the shape (or `inertia`), initial velocities.
fn parse_body(
    r: &TableReader,
    index: usize,
    shape: &Obstacle,
    name: &str,
    mode: Mode,
    gravity: [f64; 2],
) -> Result<BodySpec, ScenarioError> {
    let Some((area, centroid, polar)) = area_properties(shape) else {
        return Err(r.err_hint(
            "free",
            r.get("free"),
            format!(
                "a {} is not a closed shape and cannot be a free body",
                shape.kind()
            ),
            "free bodies are circles, ellipses and polygons",
        ));
    };
    if mode == Mode::Static {
        return Err(r.err_hint(
            "free",
            r.get("free"),
            "a free body has no static equilibrium of its own",
            "use mode = \"dynamic\"",
        ));
    }
    let mass = match (r.opt_positive("mass")?, r.opt_positive("density")?) {
        (Some(_), Some(_)) => {
            return Err(r.err_hint(
                "density",
                r.get("density"),
                "give either mass or density, not both",
                "remove one of them",
            ))
        }
        (Some(m), None) => m,
        (None, Some(rho)) => rho * area * r.positive("depth")?,
        (None, None) => {
            if let Some(e) = r.typo_error("mass").or_else(|| r.typo_error("density")) {
                return Err(e);
            }
            return Err(r.err_hint(
                "mass",
                None,
                "a free body needs a mass",
                "add `mass = ...` (kg), or `density = ...` (kg/m³) with `depth = ...` (m)",
            ));
        }
    };
    let depth = r.opt_positive("depth")?;
    let inertia = match r.opt_positive("inertia")? {
        Some(j) => j,
        None => mass * polar / area,
    };
    let radius = outline_radius(shape, centroid);
    let hold_tolerance = match r.opt_positive("hold_tolerance")? {
        Some(t) => t,
        None => 0.1 * radius,
    };
    for (k, v) in [("mass", mass), ("inertia", inertia)] {
        if !v.is_finite() || v <= 0.0 {
            return Err(r.err(
                k,
                r.get(k),
                format!("gives a {k} of {v:e}, not a positive number"),
            ));
        }
    }
    Ok(BodySpec {
        obstacle: index,
        name: name.to_string(),
        mass,
        inertia,
        weight: [mass * gravity[0], mass * gravity[1]],
        centroid,
        velocity: r.opt_vec2("velocity")?.unwrap_or([0.0; 2]),
        angular_velocity: r.opt_f64("angular_velocity")?.unwrap_or(0.0),
        radius,
        hold_tolerance,
        depth: depth.unwrap_or(2.0 * radius),
    })
}

/// The shape of an `[[obstacle]]` table.
fn parse_shape(r: &TableReader) -> Result<Obstacle, ScenarioError> {
    let kind = r.str("kind")?;
    // Only the keys of this kind are allowed; checked first, so a misspelt key is reported
    // as such rather than as a missing one.
    let allowed: &[&str] = match kind {
        "circle" => &["kind", "center", "radius"],
        "plane" => &["kind", "point", "normal"],
        "sine" => &["kind", "amplitude", "wavenumber", "offset"],
        "ellipse" => &["kind", "center", "a", "b", "angle"],
        "polygon" => &["kind", "vertices"],
        _ => &[],
    };
    if !allowed.is_empty() {
        let mut keys: Vec<&String> = r.table.keys().collect();
        keys.sort();
        for k in keys {
            if !allowed.contains(&k.as_str()) && !BODY_KEYS.contains(&k.as_str()) && k != "material"
            {
                let mut e = r.err(
                    k,
                    r.table.get(k),
                    format!("unknown key for {} {kind} obstacle", article(kind)),
                );
                e.hint = Some(match did_you_mean(k, allowed) {
                    Some(m) => format!("did you mean `{m}`?"),
                    None => format!("{} {kind} takes: {}", article(kind), allowed.join(", ")),
                });
                return Err(e);
            }
        }
    }
    let o = match kind {
        "circle" => Obstacle::Circle(Circle::new(r.vec2("center")?, r.positive("radius")?)),
        "plane" => {
            let point = r.vec2("point")?;
            let n = r.vec2("normal")?;
            // hypot: no overflow for huge components, no underflow for tiny ones.
            let len = n[0].hypot(n[1]);
            if len == 0.0 {
                return Err(r.err_hint(
                    "normal",
                    r.get("normal"),
                    "the normal is the zero vector",
                    "give the outward normal, e.g. [0.0, 1.0]",
                ));
            }
            Obstacle::Plane(Plane::new(point, [n[0] / len, n[1] / len]))
        }
        "sine" => {
            let k = r.f64("wavenumber")?;
            if k < 0.0 {
                return Err(r.err("wavenumber", r.get("wavenumber"), "must not be negative"));
            }
            Obstacle::Sine(Sine::new(r.f64("amplitude")?, k, r.f64_or("offset", 0.0)?))
        }
        "ellipse" => {
            let a = r.positive("a")?;
            let b = r.positive("b")?;
            if a.max(b) / a.min(b) > 1e6 {
                return Err(r.err_hint(
                    "b",
                    r.get("b"),
                    format!(
                        "degenerate ellipse: axis ratio {:.3e} exceeds 1e6",
                        a.max(b) / a.min(b)
                    ),
                    "use a polygon or a plane for a flat obstacle",
                ));
            }
            Obstacle::Ellipse(Ellipse::new(
                r.vec2("center")?,
                a,
                b,
                r.f64_or("angle", 0.0)?,
            ))
        }
        "polygon" => {
            let arr = r.array("vertices")?.ok_or_else(|| {
                r.err_hint(
                    "vertices",
                    None,
                    "missing required key",
                    "give vertices = [[x, y], ...] (at least 3)",
                )
            })?;
            let mut v = Vec::with_capacity(arr.len());
            for (i, p) in arr.iter().enumerate() {
                v.push(r.vec2_value(&format!("vertices.{i}"), p)?);
            }
            let poly = Polygon::new(v).map_err(|m| {
                r.err_hint(
                    "vertices",
                    r.get("vertices"),
                    format!("degenerate polygon: {m}"),
                    "give at least 3 distinct vertices of a simple (non-self-intersecting) outline",
                )
            })?;
            Obstacle::Polygon(poly)
        }
        other => {
            let hint = match did_you_mean(other, KINDS) {
                Some(m) => format!("did you mean \"{m}\"?"),
                None => format!("kinds: {}", KINDS.join(", ")),
            };
            return Err(r.err_hint(
                "kind",
                r.get("kind"),
                format!("unknown obstacle kind {other:?}"),
                hint,
            ));
        }
    };
    Ok(o)
}

/// "an" before a vowel ("an ellipse"), "a" otherwise.
fn article(word: &str) -> &'static str {
    if word.starts_with(['a', 'e', 'i', 'o', 'u']) {
        "an"
    } else {
        "a"
    }
}
