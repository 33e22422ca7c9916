//! `[[joint]]`: a node of one rod joined to a node of another (or of the same rod).
//!
//! `rods = ["a", "b"]`, `nodes = [i, j]`, `kind = "rigid" | "pin"`. Both nodes must start at
//! the same point (within 1e-9 of the longer member's length); a node may be joined to a given
//! rod once; a joint between two driven nodes has nothing to solve and is refused.

use super::geometry::shape_points;
use super::reader::TableReader;
use super::{Mode, RodSpec, ScenarioError};
use toml::Value;

/// How a joint holds its members.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum JointKind {
    /// Positions coincide; rotation free.
    Pin,
    /// Positions coincide and the angle between the members' edges at the joint keeps its
    /// rest value through a bending spring with the members' stiffness.
    Rigid,
}

/// One `[[joint]]`, by rod index.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct JointSpec {
    pub rods: [usize; 2],
    pub nodes: [usize; 2],
    pub kind: JointKind,
}

const JOINT_KEYS: &[&str] = &["rods", "nodes", "kind"];

/// Relative tolerance on the members' start positions at a joint (× the longer rod's length).
pub const COINCIDE_RTOL: f64 = 1e-9;

/// The rod names the `[[joint]]` tables mention (before the rods are read: a joined rod may
/// hold fewer clamps in a static run). Malformed tables are reported by [`parse`].
pub fn mentioned(root: &toml::Table) -> Vec<String> {
    let Some(Value::Array(a)) = root.get("joint") else {
        return Vec::new();
    };
    a.iter()
        .filter_map(|v| v.get("rods").and_then(Value::as_array))
        .flat_map(|r| r.iter().filter_map(Value::as_str).map(str::to_string))
        .collect()
}

/// Read every `[[joint]]` against the rods already read, after the `generated` joints of
/// `fin_ray` fingers.
pub fn parse(
    top: &TableReader,
    rods: &[RodSpec],
    generated: Vec<JointSpec>,
    mode: Mode,
) -> Result<Vec<JointSpec>, ScenarioError> {
    let ngen = generated.len();
    let none = Vec::new();
    let list = match top.get("joint") {
        None => &none,
        Some(Value::Array(a)) => a,
        Some(other) => {
            return Err(top.err(
                "joint",
                Some(other),
                "expected an array of [[joint]] tables",
            ))
        }
    };
    let mut joints: Vec<JointSpec> = generated;
    for (k, v) in list.iter().enumerate() {
        let t = top.table_value(&format!("joint.{k}"), v, JOINT_KEYS)?;
        let j = parse_one(&t, rods)?;
        check_twice(&t, &joints, ngen, &j, rods)?;
        t.finish()?;
        joints.push(j);
    }
    if mode == Mode::Static {
        check_static_clamps(top, rods, &joints)?;
    }
    Ok(joints)
}

fn parse_one(t: &TableReader, rods: &[RodSpec]) -> Result<JointSpec, ScenarioError> {
    let names = pair(t, "rods")?;
    let mut idx = [0usize; 2];
    for (a, v) in names.iter().enumerate() {
        let name = t.str_value("rods", v)?;
        idx[a] = rods.iter().position(|r| r.name == name).ok_or_else(|| {
            let known: Vec<&str> = rods.iter().map(|r| r.name.as_str()).collect();
            let hint = match super::reader::did_you_mean(name, &known) {
                Some(s) => format!("did you mean {s:?}?"),
                None => format!("the rods are {known:?}"),
            };
            t.err_hint("rods", Some(v), format!("no rod is named {name:?}"), hint)
        })?;
    }
    let nodes_v = pair(t, "nodes")?;
    let mut nodes = [0usize; 2];
    for a in 0..2 {
        nodes[a] = t.usize_value("nodes", &nodes_v[a])?;
        let spec = &rods[idx[a]];
        if nodes[a] >= spec.nodes {
            return Err(t.err_hint(
                "nodes",
                Some(&nodes_v[a]),
                format!(
                    "rod {:?} has no node {} (it has {} nodes, 0 to {})",
                    spec.name,
                    nodes[a],
                    spec.nodes,
                    spec.nodes - 1
                ),
                "number the nodes from 0 along each rod",
            ));
        }
    }
    if idx[0] == idx[1] && nodes[0] == nodes[1] {
        return Err(t.err("nodes", t.get("nodes"), "joins a node to itself"));
    }
    let kind = match t.opt_str("kind")? {
        None | Some("rigid") => JointKind::Rigid,
        Some("pin") => JointKind::Pin,
        Some(other) => {
            let hint = match super::reader::did_you_mean(other, &["rigid", "pin"]) {
                Some(s) => format!("did you mean {s:?}?"),
                None => "use \"rigid\" or \"pin\"".into(),
            };
            return Err(t.err_hint(
                "kind",
                t.get("kind"),
                format!("unknown joint kind {other:?}"),
                hint,
            ));
        }
    };
    let j = JointSpec {
        rods: idx,
        nodes,
        kind,
    };
    check_members(t, rods, &j)?;
    Ok(j)
}

/// A two-element array under `key`.
fn pair<'a>(t: &TableReader<'a>, key: &'static str) -> Result<&'a [Value], ScenarioError> {
    let v = t.required(key)?;
    match v {
        Value::Array(a) if a.len() == 2 => Ok(a),
        other => Err(t.err_hint(
            key,
            Some(other),
            "expected two entries, one per member",
            if key == "rods" {
                "e.g. rods = [\"front\", \"rib1\"]"
            } else {
                "e.g. nodes = [10, 0]"
            },
        )),
    }
}

/// The members start at one point, are not both driven, and a rigid joint has an edge on each.
fn check_members(t: &TableReader, rods: &[RodSpec], j: &JointSpec) -> Result<(), ScenarioError> {
    let (a, b) = (&rods[j.rods[0]], &rods[j.rods[1]]);
    let pa = shape_points(&a.shape, a.nodes)[j.nodes[0]];
    let pb = shape_points(&b.shape, b.nodes)[j.nodes[1]];
    let gap = ((pa[0] - pb[0]).powi(2) + (pa[1] - pb[1]).powi(2)).sqrt();
    let len = |r: &RodSpec| {
        let p = shape_points(&r.shape, r.nodes);
        p.windows(2)
            .map(|w| ((w[1][0] - w[0][0]).powi(2) + (w[1][1] - w[0][1]).powi(2)).sqrt())
            .sum::<f64>()
    };
    let tol = COINCIDE_RTOL * len(a).max(len(b));
    if gap.is_nan() || gap > tol {
        return Err(t.err_hint(
            "nodes",
            t.get("nodes"),
            format!(
                "the members start apart: {:?} node {} at ({:.9}, {:.9}) m, {:?} node {} at \
                 ({:.9}, {:.9}) m, {gap:.3e} m apart (at most {tol:.3e} m)",
                a.name, j.nodes[0], pa[0], pa[1], b.name, j.nodes[1], pb[0], pb[1]
            ),
            "a joint's two nodes must start at the same point: check the shapes' ends",
        ));
    }
    let clamped = |r: &RodSpec, i: usize| r.clamped.contains(&i);
    if clamped(a, j.nodes[0]) && clamped(b, j.nodes[1]) {
        return Err(t.err_hint(
            "nodes",
            t.get("nodes"),
            "both nodes are clamped: the joint has nothing to hold",
            "join a free node, or drop the joint",
        ));
    }
    if j.kind == JointKind::Rigid && (a.particle || b.particle) {
        return Err(t.err_hint(
            "kind",
            t.get("kind"),
            "a rigid joint needs an edge on each member (a particle has none)",
            "use kind = \"pin\"",
        ));
    }
    Ok(())
}

/// A node joined twice to the same rod.
fn check_twice(
    t: &TableReader,
    earlier: &[JointSpec],
    ngen: usize,
    j: &JointSpec,
    rods: &[RodSpec],
) -> Result<(), ScenarioError> {
    let ends = |x: &JointSpec| {
        [
            (x.rods[0], x.nodes[0], x.rods[1]),
            (x.rods[1], x.nodes[1], x.rods[0]),
        ]
    };
    for (k, e) in earlier.iter().enumerate() {
        for (r, i, other) in ends(j) {
            if ends(e).contains(&(r, i, other)) {
                let by = if k < ngen {
                    format!(
                        "the fin_ray finger of {} joins them already",
                        rods[r].source
                    )
                } else {
                    format!("joint.{} joins them already", k - ngen)
                };
                return Err(t.err_hint(
                    "nodes",
                    t.get("nodes"),
                    format!(
                        "{:?} node {i} is joined to rod {:?} twice ({by})",
                        rods[r].name, rods[other].name
                    ),
                    "join a node to a rod once",
                ));
            }
        }
    }
    Ok(())
}

/// Static mode: every network of joined rods holds at least two clamped nodes.
fn check_static_clamps(
    top: &TableReader,
    rods: &[RodSpec],
    joints: &[JointSpec],
) -> Result<(), ScenarioError> {
    let comp = components(rods.len(), joints);
    let ngen = joints.len()
        - top
            .get("joint")
            .and_then(Value::as_array)
            .map_or(0, Vec::len);
    for (k, j) in joints.iter().enumerate().skip(ngen) {
        let c = comp[j.rods[0]];
        let clamps: usize = (0..rods.len())
            .filter(|&r| comp[r] == c)
            .map(|r| rods[r].clamped.len())
            .sum();
        if clamps < 2 {
            let k = k - ngen;
            let v = top
                .get("joint")
                .and_then(|a| a.get(k))
                .and_then(|t| t.get("rods"));
            return Err(top.err_hint(
                &format!("joint.{k}.rods"),
                v,
                "a static solve needs at least two clamped nodes in each set of joined rods \
                 (a free frame has no equilibrium)",
                "clamp e.g. nodes [0, 1] of one member",
            ));
        }
    }
    Ok(())
}

/// The connected component of every rod under the joints (a rod alone is its own).
pub fn components(n: usize, joints: &[JointSpec]) -> Vec<usize> {
    let mut comp: Vec<usize> = (0..n).collect();
    loop {
        let mut changed = false;
        for j in joints {
            let (a, b) = (comp[j.rods[0]], comp[j.rods[1]]);
            if a != b {
                let m = a.min(b);
                for c in comp.iter_mut() {
                    if *c == a || *c == b {
                        *c = m;
                    }
                }
                changed = true;
            }
        }
        if !changed {
            return comp;
        }
    }
}
