//! `shape = { kind = "fin_ray", ... }`: a `[[rod]]` that expands at load time into the rods and
//! joints of one Fin Ray finger.
//!
//! The front flank runs from `base` along `direction` for `length`; the back flank from
//! `base + base_width · m` (m: the unit normal on the `side` of the direction) to the front
//! flank's tip, where the two are joined rigidly. Rib k (1 … `ribs`) starts at front-flank node
//! round(k (n − 1) / (ribs + 1)) and runs at `rib_angle` from m (positive: toward the tip) to
//! the back-flank node nearest to where that line crosses the back flank; its ends are joined
//! to the flanks by `rib_joint` (pin by default). Both flanks are clamped at nodes 0 and 1.

use super::geometry::shape_points;
use super::joint::{JointKind, JointSpec};
use super::reader::TableReader;
use super::{RodSpec, ScenarioError, Section, Shape};

/// A Fin Ray finger as read from its `shape` table (the front flank's shape and the rod's
/// other keys stay in the rod).
#[derive(Debug, Clone)]
pub struct FinRay {
    /// The front flank's base and tip.
    start: [f64; 2],
    end: [f64; 2],
    /// Unit vector from the base to the tip.
    direction: [f64; 2],
    /// Unit normal from the front flank toward the back flank.
    normal: [f64; 2],
    base_width: f64,
    ribs: usize,
    rib_angle_deg: f64,
    rib_nodes: usize,
    rib_section: Option<Section>,
    rib_joint: JointKind,
}

/// Read a `fin_ray` shape: the front flank's [`Shape`] and the rest of the finger.
pub fn parse(
    sh: &TableReader,
    read_section: impl Fn(&TableReader) -> Result<Section, ScenarioError>,
) -> Result<(Shape, FinRay), ScenarioError> {
    let length = sh.positive("length")?;
    let base_width = sh.f64("base_width")?;
    if !(base_width > 0.0 && base_width < length) {
        return Err(sh.err_hint(
            "base_width",
            sh.get("base_width"),
            format!("must be in (0, length) = (0, {length}) m"),
            "the distance between the flanks' feet, less than the finger's length",
        ));
    }
    let ribs = sh.usize("ribs")?;
    if !(1..=200).contains(&ribs) {
        return Err(sh.err_hint(
            "ribs",
            sh.get("ribs"),
            "must be from 1 to 200",
            "a Fin Ray finger has at least one rib (a single flank is a plain rod)",
        ));
    }
    let rib_angle_deg = sh.f64_or("rib_angle", 0.0)?;
    if !(rib_angle_deg > -90.0 && rib_angle_deg < 90.0) {
        return Err(sh.err_hint(
            "rib_angle",
            sh.get("rib_angle"),
            "must be in (-90, 90) degrees",
            "0: ribs perpendicular to the front flank; positive: tilted toward the tip",
        ));
    }
    let base = sh.opt_vec2("base")?.unwrap_or([0.0, 0.0]);
    let dir = sh.opt_vec2("direction")?.unwrap_or([0.0, 1.0]);
    let norm = dir[0].hypot(dir[1]);
    if !(norm > 0.0 && norm.is_finite()) {
        return Err(sh.err_hint(
            "direction",
            sh.get("direction"),
            "must be a non-zero vector",
            "the direction from the finger's base to its tip, e.g. [0.0, -1.0]",
        ));
    }
    let d = [dir[0] / norm, dir[1] / norm];
    let normal =
        match sh.opt_str("side")?.unwrap_or("right") {
            "right" => [d[1], -d[0]],
            "left" => [-d[1], d[0]],
            other => return Err(sh.err_hint(
                "side",
                sh.get("side"),
                format!("unknown side {other:?}"),
                "use \"right\" or \"left\" (where the back flank lies, looking from base to tip)",
            )),
        };
    let rib_nodes = sh.opt_usize("rib_nodes")?.unwrap_or(7);
    if !(3..=100_000).contains(&rib_nodes) {
        return Err(sh.err_hint(
            "rib_nodes",
            sh.get("rib_nodes"),
            "must be from 3 to 100000",
            "a rib needs at least 3 nodes (one bending spring)",
        ));
    }
    let rib_section = match sh.opt_table("rib_section", super::SECTION_KEYS)? {
        None => None,
        Some(se) => Some(read_section(&se)?),
    };
    let rib_joint = match sh.opt_str("rib_joint")?.unwrap_or("pin") {
        "pin" => JointKind::Pin,
        "rigid" => JointKind::Rigid,
        other => {
            return Err(sh.err_hint(
                "rib_joint",
                sh.get("rib_joint"),
                format!("unknown joint kind {other:?}"),
                "use \"pin\" (the default) or \"rigid\"",
            ))
        }
    };
    let fr = FinRay {
        start: base,
        end: [base[0] + length * d[0], base[1] + length * d[1]],
        direction: d,
        normal,
        base_width,
        ribs,
        rib_angle_deg,
        rib_nodes,
        rib_section,
        rib_joint,
    };
    let front = Shape::Straight {
        start: fr.start,
        end: fr.end,
    };
    Ok((front, fr))
}

/// One generated rib: its front- and back-flank nodes and its shape.
struct Rib {
    front: usize,
    back: usize,
    shape: Shape,
}

/// Lay the ribs out on the flanks of `n` nodes each; errors name `nodes` or
/// `shape.rib_angle` of the rod table `r`.
fn ribs(
    r: &TableReader,
    fr: &FinRay,
    front: &Shape,
    back: &Shape,
    n: usize,
) -> Result<Vec<Rib>, ScenarioError> {
    let pf = shape_points(front, n);
    let pb = shape_points(back, n);
    let (b0, tip) = (pb[0], pb[n - 1]);
    let e = [tip[0] - b0[0], tip[1] - b0[1]];
    let (s, c) = fr.rib_angle_deg.to_radians().sin_cos();
    let u = [
        c * fr.normal[0] + s * fr.direction[0],
        c * fr.normal[1] + s * fr.direction[1],
    ];
    let cross = |a: [f64; 2], b: [f64; 2]| a[0] * b[1] - a[1] * b[0];
    let min_nodes = 6 * (fr.ribs + 1) + 1;
    let too_few = |what: String| {
        r.err_hint(
            "nodes",
            r.get("nodes"),
            format!(
                "too few nodes for {} ribs on distinct flank nodes: {what}",
                fr.ribs
            ),
            format!("use nodes = {min_nodes} or more (six edges between ribs)"),
        )
    };
    let mut out: Vec<Rib> = Vec::with_capacity(fr.ribs);
    for k in 1..=fr.ribs {
        let i = (k as f64 * (n - 1) as f64 / (fr.ribs + 1) as f64).round() as usize;
        let p = pf[i];
        let rel = [b0[0] - p[0], b0[1] - p[1]];
        let sigma = -cross(u, rel) / cross(u, e);
        let t = (rel[0] + sigma * e[0]) * u[0] + (rel[1] + sigma * e[1]) * u[1];
        if !(sigma > 0.0 && sigma < 1.0 && t > 0.0) {
            return Err(r.err_hint(
                "shape.rib_angle",
                r.get("shape").and_then(|v| v.get("rib_angle")),
                format!(
                    "rib {k} (from front-flank node {i}) does not meet the back flank at this \
                     angle"
                ),
                "use a rib_angle nearer 0",
            ));
        }
        let j = (sigma * (n - 1) as f64).round() as usize;
        for (flank, node) in [("front", i), ("back", j)] {
            if node < 2 || node > n - 2 {
                return Err(too_few(format!(
                    "rib {k} falls on {flank}-flank node {node} (a clamped node or the tip)"
                )));
            }
            if let Some(prev) = out.last() {
                let before = if flank == "front" {
                    prev.front
                } else {
                    prev.back
                };
                if node <= before {
                    return Err(too_few(format!(
                        "ribs {} and {k} share {flank}-flank node {node}",
                        k - 1
                    )));
                }
            }
        }
        let shape = Shape::Straight {
            start: p,
            end: pb[j],
        };
        out.push(Rib {
            front: i,
            back: j,
            shape,
        });
    }
    Ok(out)
}

/// Expand a parsed `fin_ray` rod (`spec`: its shape the front flank, its keys read) into the
/// finger's rods (`<name>.front`, `<name>.back`, `<name>.rib1` …) and joints, the joints'
/// rod indices counted from `first` (the index the front flank will get).
pub fn expand(
    r: &TableReader,
    spec: RodSpec,
    fr: &FinRay,
    first: usize,
) -> Result<(Vec<RodSpec>, Vec<JointSpec>), ScenarioError> {
    let n = spec.nodes;
    let (start, end) = (fr.start, fr.end);
    let back_shape = Shape::Straight {
        start: [
            start[0] + fr.base_width * fr.normal[0],
            start[1] + fr.base_width * fr.normal[1],
        ],
        end,
    };
    let layout = ribs(r, fr, &spec.shape, &back_shape, n)?;
    let name = spec.name.clone();
    let mut front = spec;
    front.name = format!("{name}.front");
    let mut back = front.clone();
    back.name = format!("{name}.back");
    back.shape = back_shape;
    back.loads.clear();
    let mut rods = vec![front, back];
    let joint = |a: usize, i: usize, b: usize, j: usize, kind| JointSpec {
        rods: [first + a, first + b],
        nodes: [i, j],
        kind,
    };
    let mut joints = vec![joint(0, n - 1, 1, n - 1, JointKind::Rigid)];
    for (k, rib) in layout.into_iter().enumerate() {
        let mut spec = rods[0].clone();
        spec.name = format!("{name}.rib{}", k + 1);
        spec.nodes = fr.rib_nodes;
        spec.shape = rib.shape;
        if let Some(s) = &fr.rib_section {
            spec.section = *s;
        }
        spec.clamped.clear();
        spec.loads.clear();
        spec.drive = super::Drive::Fixed;
        spec.actuator = None;
        spec.mirror = false;
        rods.push(spec);
        joints.push(joint(0, rib.front, 2 + k, 0, fr.rib_joint));
        joints.push(joint(1, rib.back, 2 + k, fr.rib_nodes - 1, fr.rib_joint));
    }
    Ok((rods, joints))
}
