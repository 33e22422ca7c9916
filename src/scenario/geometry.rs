//! Checks of a scenario that need its geometry: the rods' node positions, edges and rest
//! shapes, and where everything starts relative to the obstacles.

use super::{Scenario, ScenarioError, Shape};

/// Node positions of a shape.
pub fn shape_points(shape: &Shape, n: usize) -> Vec<[f64; 2]> {
    match shape {
        Shape::Straight { start, end } => (0..n)
            .map(|i| {
                let s = i as f64 / (n - 1) as f64;
                [
                    start[0] + s * (end[0] - start[0]),
                    start[1] + s * (end[1] - start[1]),
                ]
            })
            .collect(),
        Shape::Points { points } => points.clone(),
        Shape::Parabola { x0, y0, a, length } => (0..n)
            .map(|i| {
                let s = length * i as f64 / (n - 1) as f64;
                [x0 + a * (length - s) * (length - s), y0 - s]
            })
            .collect(),
    }
}

/// Checks that need the built geometry: no zero-length edge, no fold-back in the rest shape,
/// no node starting inside an obstacle.
pub fn validate(sc: &Scenario) -> Result<(), ScenarioError> {
    let err = |key: String, value: String, message: String, hint: &str| ScenarioError {
        file: sc.file.clone(),
        key,
        value,
        message,
        hint: Some(hint.to_string()),
    };
    for spec in &sc.rods {
        let pts = shape_points(&spec.shape, spec.nodes);
        let key = &spec.source;
        for (i, p) in pts.iter().enumerate() {
            if !(p[0].is_finite() && p[1].is_finite()) {
                return Err(err(
                    format!("{key}.shape"),
                    format!("node {i} at [{}, {}]", p[0], p[1]),
                    format!("node {i} of the shape is not finite (the numbers overflow)"),
                    "use coordinates of a realistic size (metres)",
                ));
            }
        }
        let size = pts
            .iter()
            .flat_map(|p| p.iter())
            .fold(0.0f64, |m, v| m.max(v.abs()))
            .max(1e-300);
        for i in 0..pts.len() - 1 {
            let l = (pts[i + 1][0] - pts[i][0]).hypot(pts[i + 1][1] - pts[i][1]);
            if !l.is_finite() {
                return Err(err(
                    format!("{key}.shape"),
                    format!("{:?}", pts[i]),
                    format!(
                        "the edge from node {i} to {} is too long to represent",
                        i + 1
                    ),
                    "use coordinates of a realistic size (metres)",
                ));
            }
            if l <= 1e-12 * size {
                return Err(err(
                    format!("{key}.shape"),
                    format!("{:?}", pts[i]),
                    format!("nodes {i} and {} coincide (zero-length edge)", i + 1),
                    "give the rod a non-zero length with distinct nodes",
                ));
            }
        }
        for i in 1..pts.len().saturating_sub(1) {
            let e1 = [pts[i][0] - pts[i - 1][0], pts[i][1] - pts[i - 1][1]];
            let e2 = [pts[i + 1][0] - pts[i][0], pts[i + 1][1] - pts[i][1]];
            if e1[0] * e2[0] + e1[1] * e2[1] <= 0.0 {
                return Err(err(
                    format!("{key}.shape"),
                    format!("{:?}", pts[i]),
                    format!("the rest shape turns by 90° or more at node {i}"),
                    "use more nodes or a smoother shape",
                ));
            }
        }
        // With face contact the surface is `off` outside the centreline.
        let off = sc.contact.offset(spec);
        for (oi, o) in sc.obstacles.iter().enumerate() {
            for (i, p) in pts.iter().enumerate() {
                let d = o.query(*p).distance - off;
                if !d.is_finite() {
                    return Err(err(
                        format!("obstacle.{oi}"),
                        String::new(),
                        format!(
                            "the distance from {} {:?} node {i} to this {} cannot be computed \
                             (the obstacle's numbers overflow)",
                            if spec.particle { "particle" } else { "rod" },
                            spec.name,
                            o.kind()
                        ),
                        "use obstacle dimensions of a realistic size (metres)",
                    ));
                }
                if d < 0.0 {
                    return Err(err(
                        if spec.particle {
                            format!("{key}.position")
                        } else {
                            format!("{key}.shape")
                        },
                        format!("node {i} at [{}, {}]", p[0], p[1]),
                        format!(
                            "{} {:?} node {i}{} starts {:.3e} m inside obstacle.{oi} ({})",
                            if spec.particle { "particle" } else { "rod" },
                            spec.name,
                            if off > 0.0 { "'s face" } else { "" },
                            -d,
                            o.kind()
                        ),
                        "move the rod or the obstacle so that the rod starts outside",
                    ));
                }
            }
        }
    }
    validate_bodies(sc)
}

/// A free body must not start inside a fixed obstacle.
fn validate_bodies(sc: &Scenario) -> Result<(), ScenarioError> {
    use crate::world::body::{Placed, Pose};
    let mut found = Vec::new();
    for b in &sc.bodies {
        let placed = Placed {
            shape: &sc.obstacles[b.obstacle],
            c0: b.centroid,
            pose: Pose {
                c: b.centroid,
                theta: 0.0,
            },
        };
        for (k, o) in sc.obstacles.iter().enumerate() {
            if sc.bodies.iter().any(|x| x.obstacle == k) {
                continue;
            }
            crate::contact::body::points(&placed, o, -1e-9 * b.radius, &mut found);
            if let Some((_, p, q)) = found.first() {
                return Err(ScenarioError {
                    file: sc.file.clone(),
                    key: format!("obstacle.{}", b.obstacle),
                    value: format!("[{}, {}]", p[0], p[1]),
                    message: format!(
                        "the free body {:?} starts {:.3e} m inside obstacle.{k} ({})",
                        b.name,
                        -q.distance,
                        o.kind()
                    ),
                    hint: Some("move the body so that it starts outside (touching is fine)".into()),
                });
            }
        }
    }
    Ok(())
}
