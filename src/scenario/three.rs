//! 3D scenarios (`dimension = 3`, issue 16): one prong definition made into a two-finger
//! parallel or n-finger radial gripper, a fruit (sphere, ellipsoid, box or an OBJ mesh; free or
//! fixed), fixed obstacles (a table plane, shapes), Coulomb friction, and the hand's program of
//! moves. Vectors are `[x, y, z]`. The planar format is unchanged; a file without
//! `dimension = 3` is a planar scenario. Every error names the file, the key and the value.
//!
//! ```toml
//! name = "3d-two-finger-sphere"
//! dimension = 3
//! [solve]
//! dt = 2e-4
//! t_end = 0.2                      # optional: default, when the moves end
//! gravity = [0.0, 0.0, -9.81]
//! integrator = "backward_euler"    # optional: or "bdf2", "tr_bdf2" (fixed dt)
//! [prong]                          # in the finger frame: hanging along −z, closing along +x
//! nodes = 10
//! shape = { kind = "parabola", a = 0.8, length = 0.1 }   # x = −a (length − s)², z = −s
//! # shape = { kind = "straight", length = 0.05 }  or  points = [[x, y, z], ...]
//! E = 1e6
//! nu = 0.5                         # or G = ...
//! density = 5000.0
//! section = { kind = "rect", b = 0.02, h = 0.01 }       # h along the closing direction
//! clamped_edges = 1
//! [gripper]
//! kind = "parallel"                # or "radial" with fingers = n
//! radius = 0.06                    # the finger-frame origins (prong tips) from the axis
//! centre = [0.0, 0.0, 0.0]
//! sensor_tau = 0.01                # grip force sensor time constant (s), default 0.01
//! [contact]
//! surface = "face"                 # or "centreline"
//! points = "nodes"                 # or "edges": segments are held between their nodes too
//! [friction]
//! mu_s = 0.5
//! mu_k = 0.4
//! [fruit]
//! shape = { kind = "sphere", radius = 0.04 }   # ellipsoid semi_axes, box half, mesh file + scale
//! centre = [0.0, 0.0, -0.09]
//! density = 900.0
//! free = true
//! hold_tolerance = 0.004           # slip allowed in the gripper's lift (m), default 0.1 × its radius
//! [expect]
//! grasp = "held"                   # or "slipped", "dropped" (replay check, run --check)
//! [[obstacle]]
//! name = "table"
//! shape = { kind = "plane" }
//! at = [0.0, 0.0, -0.13]
//! normal = [0.0, 0.0, 1.0]
//! [[move]]
//! kind = "squeeze"                 # close at speed until the grip force
//! speed = 0.05
//! force = 1.0
//! max_travel = 0.03
//! [[move]]
//! kind = "lift"                    # also: hold, close, translate, rotate
//! height = 0.02
//! duration = 0.1
//! ```

use super::contact::ContactPoints;
use super::reader::{ScenarioError, TableReader};
use crate::contact::friction::{Coulomb, FrictionTable};
use crate::obstacle3::{Obstacle3, Pose3, Shape3, TriMesh};
use crate::rod3d::gripper::Move3;
use crate::rod3d::limits::{check_gripper, SizeError};
use crate::rod3d::{ContactSide3, Rod3Spec, Section3};
use toml::Value;

const TOP: &[&str] = &[
    "name",
    "description",
    "dimension",
    "solve",
    "prong",
    "gripper",
    "contact",
    "friction",
    "fruit",
    "obstacle",
    "move",
    "expect",
];
const SOLVE: &[&str] = &[
    "dt",
    "t_end",
    "gravity",
    "force_tol",
    "step_tol",
    "max_newton_iterations",
    "integrator",
];
const PRONG: &[&str] = &[
    "nodes",
    "shape",
    "points",
    "E",
    "nu",
    "G",
    "density",
    "section",
    "clamped_edges",
    "director",
    "loss_factor",
    "loss_frequency",
];
const SHAPE: &[&str] = &[
    "kind",
    "a",
    "length",
    "radius",
    "semi_axes",
    "half",
    "file",
    "scale",
];
const SECTION: &[&str] = &["kind", "b", "h", "r"];
const GRIPPER: &[&str] = &["kind", "fingers", "radius", "centre", "sensor_tau"];
const FRUIT: &[&str] = &[
    "name",
    "shape",
    "centre",
    "density",
    "free",
    "hold_tolerance",
    "material",
];
const OBSTACLE: &[&str] = &["name", "shape", "at", "normal"];
const MOVE: &[&str] = &[
    "kind",
    "speed",
    "force",
    "max_travel",
    "travel",
    "duration",
    "by",
    "height",
    "axis",
    "angle",
];

/// Largest `scale` of a mesh (from the file's units to metres).
const MAX_MESH_SCALE: f64 = 1e6;

/// The fruit: its shape about its centre, where it is, and whether it moves.
#[derive(Debug, Clone, PartialEq)]
pub struct Fruit3 {
    pub name: String,
    pub shape: Shape3,
    pub centre: [f64; 3],
    pub density: f64,
    pub free: bool,
    /// How far the fruit may move in the gripper during the lift (m): the grasp rule's
    /// tolerance (default 0.1 × its bounding radius, as a planar free body's).
    pub hold_tolerance: f64,
    /// A compliant fruit's material (None: rigid; src/scenario/material.rs).
    pub material: Option<crate::contact::compliant::Material>,
}

#[derive(Debug, Clone, PartialEq)]
pub struct Scenario3 {
    pub name: String,
    pub description: String,
    pub file: String,
    pub dt: f64,
    pub t_end: Option<f64>,
    pub gravity: [f64; 3],
    pub force_tol: f64,
    pub step_tol: f64,
    pub max_newton_iterations: u32,
    /// `[solve] integrator` (the planar key and values; src/rod3d/world/bdf3.rs).
    pub integrator: super::Integrator,
    /// The prong in its finger frame.
    pub prong: Rod3Spec,
    pub clamped_edges: usize,
    /// Kelvin–Voigt retardation time of the prong's material, `loss_factor` / (2π
    /// `loss_frequency`) (s; 0: undamped).
    pub damping_time: f64,
    pub fingers: usize,
    pub radius: f64,
    pub centre: [f64; 3],
    /// Time constant of the grip force sensor (s).
    pub sensor_tau: f64,
    pub side: ContactSide3,
    /// `[contact] points`: nodes only (default) or edges too (src/rod3d/edge3.rs).
    pub points: ContactPoints,
    pub friction: FrictionTable,
    pub fruit: Option<Fruit3>,
    pub obstacles: Vec<Obstacle3>,
    pub moves: Vec<Move3>,
    /// `[expect]`: the grasp outcome the scenario is built to show (default held).
    pub expect: super::expect::Expect,
}

/// Whether a scenario text says `dimension = 3` (anything unreadable is left to the planar
/// reader, whose errors are the established ones).
/// Whether the file at `path` is a `dimension = 3` scenario: read through the same 16 MiB cap
/// as every scenario (an endless or huge file is not 3D; `Scenario::load` then refuses it).
pub fn file_is_3d(path: &std::path::Path) -> bool {
    match super::read_capped(path) {
        Ok(b) if b.len() as u64 <= super::MAX_SCENARIO_BYTES => {
            std::str::from_utf8(&b).is_ok_and(is_3d)
        }
        _ => false,
    }
}

/// A text with a `dimension` key of any type or value but the integer 2 (the planar default,
/// read by the planar reader) is read by the 3D reader, which says what is wrong with one that
/// is not the integer 3 (`3.0`, `"3"`): the planar reader would report the 3D keys instead.
pub fn is_3d(text: &str) -> bool {
    text.parse::<toml::Table>().ok().is_some_and(|t| {
        t.get("dimension")
            .is_some_and(|d| d.as_integer() != Some(2))
    })
}

/// `dimension` is the integer 3 here; anything else (3.0, "3") is a type error that says so.
fn dimension_error(top: &TableReader<'_>, dim: &Value) -> ScenarioError {
    let message = match dim {
        Value::Integer(_) => {
            "a 3D scenario says dimension = 3 (a planar one dimension = 2, the default)".to_string()
        }
        other => format!(
            "expected the integer 3, found {} {}",
            super::reader::type_name(other),
            super::reader::show(other)
        ),
    };
    top.err_hint(
        "dimension",
        Some(dim),
        message,
        "write dimension = 3 (no quotes, no decimal point) for a 3D scenario, or dimension = 2 \
         (or no dimension key) for a planar one",
    )
}

/// Nothing starts inside anything ([`crate::rod3d::World3::start_overlap`] on the world the
/// run would build): the error names both things, the depth, and the key that places the
/// fruit or the obstacle.
fn start_check(top: &TableReader<'_>, sc: &Scenario3) -> Result<(), ScenarioError> {
    use crate::rod3d::world::Overlap3;
    let fruit_err = |message: String| -> Result<(), ScenarioError> {
        let f = top.table("fruit", FRUIT)?;
        Err(f.err_hint(
            "centre",
            f.get("centre"),
            message,
            "move the fruit, the obstacle or the gripper so that nothing starts inside \
             anything (touching is fine)",
        ))
    };
    let (w, _) =
        crate::rod3d::run3::build(sc).map_err(|e| top.err("fruit", top.get("fruit"), e))?;
    let fixed_fruit = usize::from(sc.fruit.as_ref().is_some_and(|f| !f.free));
    let show = |p: [f64; 3]| format!("[{:.4e}, {:.4e}, {:.4e}]", p[0], p[1], p[2]);
    match w.start_overlap() {
        None => Ok(()),
        Some(Overlap3::Body {
            obstacle,
            depth,
            at,
            ..
        }) => fruit_err(format!(
            "the fruit {:?} starts {depth:.3e} m inside obstacle {:?} (its point at {} m)",
            w.bodies[0].obstacle.name,
            w.obstacles[obstacle].name,
            show(at)
        )),
        Some(Overlap3::Node {
            rod,
            node,
            body,
            surface,
            depth,
            at,
            face,
        }) => {
            let what = format!(
                "{} node {node}{} (at {} m) starts {depth:.3e} m inside",
                w.rod_names[rod],
                if face { "'s face" } else { "" },
                show(at)
            );
            if body || surface < fixed_fruit {
                let name = sc.fruit.as_ref().map_or("", |f| f.name.as_str());
                return fruit_err(format!("{what} the fruit {name:?}"));
            }
            let k = surface - fixed_fruit;
            let all = top.array("obstacle")?.map(|a| a.as_slice()).unwrap_or(&[]);
            let o = top.table_value(&format!("obstacle.{k}"), &all[k], OBSTACLE)?;
            Err(o.err_hint(
                "at",
                o.get("at"),
                format!("{what} obstacle {:?}", sc.obstacles[k].name),
                "move the obstacle or the gripper so that the prongs start outside (touching \
                 is fine)",
            ))
        }
    }
}

/// The gripper's size against [`crate::rod3d::limits`]: nodes per prong, fingers, nodes in
/// all (before the world is built).
fn check_sizes(top: &TableReader<'_>, nodes: usize, fingers: usize) -> Result<(), ScenarioError> {
    match check_gripper(nodes, fingers) {
        Ok(()) => Ok(()),
        Err(SizeError::Nodes(m) | SizeError::Fingers(m)) => {
            let p = top.table("prong", PRONG)?;
            let key = if p.has("points") { "points" } else { "nodes" };
            Err(p.err(key, p.get(key), m))
        }
    }
}

fn vec3(r: &TableReader<'_>, key: &'static str) -> Result<[f64; 3], ScenarioError> {
    let v = r.required(key)?;
    vec3_value(r, key, v)
}

fn vec3_value(r: &TableReader<'_>, key: &str, v: &Value) -> Result<[f64; 3], ScenarioError> {
    match v {
        Value::Array(a) if a.len() == 3 => {
            let mut out = [0.0; 3];
            for (k, x) in a.iter().enumerate() {
                out[k] = r.num_value(key, x).map_err(|mut e| {
                    e.value = super::reader::show(v);
                    e
                })?;
            }
            Ok(out)
        }
        other => Err(r.err_hint(
            key,
            Some(other),
            "expected a 3D vector [x, y, z]",
            "a 3D scenario's vectors have three components",
        )),
    }
}

fn opt_vec3(
    r: &TableReader<'_>,
    key: &'static str,
    default: [f64; 3],
) -> Result<[f64; 3], ScenarioError> {
    match r.get(key) {
        None => Ok(default),
        Some(v) => vec3_value(r, key, v),
    }
}

impl Scenario3 {
    /// Parse a 3D scenario's text; `dir` is where relative mesh files are looked up.
    pub fn from_str(
        text: &str,
        file: &str,
        dir: &std::path::Path,
    ) -> Result<Scenario3, ScenarioError> {
        let root: toml::Table = text.parse().map_err(|e: toml::de::Error| ScenarioError {
            file: file.to_string(),
            key: String::new(),
            value: String::new(),
            message: format!(
                "TOML syntax error: {}",
                e.message().lines().next().unwrap_or("")
            ),
            hint: None,
        })?;
        let top = TableReader::new(file, String::new(), &root, TOP);
        let dim = top.required("dimension")?;
        if dim.as_integer() != Some(3) {
            return Err(dimension_error(&top, dim));
        }
        let name = super::scenario_name(&top)?;
        let description = top.opt_str("description")?.unwrap_or("").to_string();
        let solve = top.table("solve", SOLVE)?;
        // The planar solve limits (src/scenario/mod.rs).
        let dt = solve.positive("dt")?;
        let t_end = solve.opt_positive("t_end")?;
        if let Some(t) = t_end {
            super::check_steps(&solve, dt, t)?;
        }
        let gravity = opt_vec3(&solve, "gravity", [0.0, 0.0, -9.81])?;
        super::check_magnitude(&solve, "gravity", &gravity, super::MAX_ACCELERATION, "m/s²")?;
        let force_tol = solve.opt_positive("force_tol")?.unwrap_or(1e-9);
        let step_tol = solve.opt_positive("step_tol")?.unwrap_or(1e-12);
        let max_newton_iterations = super::positive_int(&solve, "max_newton_iterations", 40)?;
        let integrator = super::parse_integrator(&solve)?;
        refuse_adaptive(&solve)?;
        solve.finish()?;
        let (prong, clamped_edges, damping_time) = parse_prong(&top.table("prong", PRONG)?)?;
        let (fingers, radius, centre, sensor_tau) = parse_gripper(&top)?;
        check_sizes(&top, prong.points.len(), fingers)?;
        let (side, points) = parse_contact(&top)?;
        let friction = parse_friction(&top)?;
        let fruit = match top.opt_table("fruit", FRUIT)? {
            None => None,
            Some(f) => {
                let fruit = parse_fruit(&f, dir)?;
                if fruit.material.is_some() && points == ContactPoints::Edges {
                    return Err(f.err_hint(
                        "material",
                        f.get("material"),
                        "a compliant fruit is held at the prongs' nodes only: edge contact \
                         ([contact] points = \"edges\") has no compliant law in 3D",
                        "remove [contact] points = \"edges\", or the fruit's material",
                    ));
                }
                Some(fruit)
            }
        };
        let obstacles = parse_obstacles(&top, dir)?;
        unique_names(&top, fingers, fruit.as_ref(), &obstacles)?;
        let moves = parse_moves(&top)?;
        let expect = super::expect::parse(&top)?;
        top.finish()?;
        let sc = Scenario3 {
            name,
            description,
            file: file.to_string(),
            dt,
            t_end,
            gravity,
            force_tol,
            step_tol,
            max_newton_iterations,
            integrator,
            prong,
            clamped_edges,
            damping_time,
            fingers,
            radius,
            centre,
            sensor_tau,
            side,
            points,
            friction,
            fruit,
            obstacles,
            moves,
            expect,
        };
        start_check(&top, &sc)?;
        Ok(sc)
    }

    /// [`Scenario3::from_str`] after the `--set KEY=VALUE` overrides `sets`
    /// ([`super::overrides`], the planar rules: every array on the path must exist, a bad key
    /// or index is refused naming the file, the `--set` and the key).
    pub fn from_str_with(
        text: &str,
        file: &str,
        dir: &std::path::Path,
        sets: &[String],
    ) -> Result<Scenario3, ScenarioError> {
        if sets.is_empty() {
            return Self::from_str(text, file, dir);
        }
        // A syntax error is reported by the reader itself, on the text as written.
        let Ok(mut root) = text.parse::<toml::Table>() else {
            return Self::from_str(text, file, dir);
        };
        super::apply_sets(&mut root, sets, file)?;
        let text = toml::to_string(&root).map_err(|e| ScenarioError {
            file: file.to_string(),
            key: String::new(),
            value: String::new(),
            message: format!("the overridden scenario does not serialise: {e}"),
            hint: None,
        })?;
        let shown = format!("{file} (--set {})", sets.join(" --set "));
        Self::from_str(&text, &shown, dir).map(|mut sc| {
            sc.file = file.to_string();
            sc
        })
    }

    /// What a person should know before running: a mesh large enough to slow every step.
    pub fn warnings(&self) -> Vec<String> {
        let fruit = self.fruit.iter().map(|f| ("fruit".to_string(), &f.shape));
        let obstacles = self
            .obstacles
            .iter()
            .enumerate()
            .map(|(k, o)| (format!("obstacle.{k}"), &o.shape));
        fruit
            .chain(obstacles)
            .filter_map(|(key, shape)| match shape {
                Shape3::Mesh(m) => crate::rod3d::limits::mesh_cost_warning(m.triangles.len())
                    .map(|w| format!("{key}.shape: {w}")),
                _ => None,
            })
            .collect()
    }

    /// Read and parse a 3D scenario file.
    pub fn load(path: &std::path::Path) -> Result<Scenario3, ScenarioError> {
        Self::load_with(path, &[])
    }

    /// Read a 3D scenario file and apply `--set` overrides (see [`Scenario3::from_str_with`]).
    pub fn load_with(path: &std::path::Path, sets: &[String]) -> Result<Scenario3, ScenarioError> {
        let file = path.display().to_string();
        let err = |message: String| ScenarioError {
            file: file.clone(),
            key: String::new(),
            value: String::new(),
            message,
            hint: None,
        };
        let bytes =
            super::read_capped(path).map_err(|e| err(format!("cannot read the file: {e}")))?;
        if bytes.len() as u64 > super::MAX_SCENARIO_BYTES {
            return Err(err(format!(
                "larger than {} MiB: not a scenario file (reading stopped there)",
                super::MAX_SCENARIO_BYTES >> 20
            )));
        }
        let text = String::from_utf8(bytes).map_err(|e| err(format!("not UTF-8 text: {e}")))?;
        let dir = path.parent().unwrap_or(std::path::Path::new("."));
        Self::from_str_with(&text, &file, dir, sets)
    }
}

fn parse_friction(top: &TableReader<'_>) -> Result<FrictionTable, ScenarioError> {
    let Some(f) = top.opt_table("friction", &["mu_s", "mu_k"])? else {
        return Ok(FrictionTable::default());
    };
    let mu_s = f.f64("mu_s")?;
    let mu_k = f.f64_or("mu_k", mu_s)?;
    if !(mu_s >= 0.0) {
        return Err(f.err("mu_s", f.get("mu_s"), "must be ≥ 0"));
    }
    if !(0.0..=mu_s).contains(&mu_k) {
        return Err(f.err("mu_k", f.get("mu_k"), "must lie between 0 and mu_s"));
    }
    f.finish()?;
    Ok(FrictionTable {
        default: Coulomb { mu_s, mu_k },
        pairs: Vec::new(),
    })
}

/// The gripper: finger count, radius, centre and the grip sensor's time constant.
fn parse_gripper(top: &TableReader<'_>) -> Result<(usize, f64, [f64; 3], f64), ScenarioError> {
    let g = top.table("gripper", GRIPPER)?;
    let fingers = match g.str("kind")? {
        "parallel" => 2,
        "radial" => {
            let n = g.usize("fingers")?;
            if n < 2 {
                return Err(g.err(
                    "fingers",
                    g.get("fingers"),
                    "a radial gripper needs at least 2 fingers",
                ));
            }
            if let Err(SizeError::Fingers(m)) = check_gripper(3, n) {
                return Err(g.err("fingers", g.get("fingers"), m));
            }
            n
        }
        other => {
            return Err(g.err_hint(
                "kind",
                g.get("kind"),
                format!("unknown gripper kind {other:?}"),
                "use \"parallel\" or \"radial\"",
            ))
        }
    };
    let radius = g.positive("radius")?;
    let centre = opt_vec3(&g, "centre", [0.0; 3])?;
    let sensor_tau = g.opt_positive("sensor_tau")?.unwrap_or(0.01);
    g.finish()?;
    Ok((fingers, radius, centre, sensor_tau))
}

/// `[contact] surface`: the face (default) or the centreline; `points`: the nodes (default)
/// or the edges too, spelled as in the planar format ([`super::contact`]).
fn parse_contact(top: &TableReader<'_>) -> Result<(ContactSide3, ContactPoints), ScenarioError> {
    let Some(c) = top.opt_table("contact", &["surface", "points"])? else {
        return Ok((ContactSide3::Face, ContactPoints::Nodes));
    };
    let side = match c.opt_str("surface")? {
        None | Some("face") => ContactSide3::Face,
        Some("centreline" | "centerline") => ContactSide3::Centreline,
        Some(other) => {
            return Err(c.err_hint(
                "surface",
                c.get("surface"),
                format!("unknown contact surface {other:?}"),
                "use \"face\" or \"centreline\"",
            ))
        }
    };
    let points = match c.opt_str("points")? {
        None | Some("nodes") => ContactPoints::Nodes,
        Some("edges") => ContactPoints::Edges,
        Some(other) => {
            return Err(c.err_hint(
                "points",
                c.get("points"),
                format!("unknown contact points {other:?}"),
                "use \"edges\" (segments too) or \"nodes\"",
            ))
        }
    };
    c.finish()?;
    Ok((side, points))
}

/// The prong's nodes in its finger frame: `points`, or `nodes` along a `shape`.
fn prong_points(p: &TableReader<'_>) -> Result<Vec<[f64; 3]>, ScenarioError> {
    let points = match p.array("points")? {
        Some(a) => {
            if p.has("shape") || p.has("nodes") {
                return Err(p.err(
                    "points",
                    p.get("points"),
                    "give either points or nodes + shape",
                ));
            }
            let mut pts = Vec::new();
            for v in a {
                pts.push(vec3_value(p, "points", v)?);
            }
            if pts.len() < 3 {
                return Err(p.err("points", p.get("points"), "a prong needs at least 3 nodes"));
            }
            if let Err(SizeError::Nodes(m)) = check_gripper(pts.len(), 1) {
                return Err(p.err("points", p.get("points"), m));
            }
            pts
        }
        None => {
            let n = p.usize("nodes")?;
            if n < 3 {
                return Err(p.err("nodes", p.get("nodes"), "a prong needs at least 3 nodes"));
            }
            if let Err(SizeError::Nodes(m)) = check_gripper(n, 1) {
                return Err(p.err("nodes", p.get("nodes"), m));
            }
            let s = p.table("shape", SHAPE)?;
            let length = s.positive("length")?;
            let a = match s.str("kind")? {
                "straight" => 0.0,
                "parabola" => s.f64("a")?,
                other => {
                    return Err(s.err_hint(
                        "kind",
                        s.get("kind"),
                        format!("unknown prong shape {other:?}"),
                        "use \"straight\" or \"parabola\"",
                    ))
                }
            };
            s.finish()?;
            (0..n)
                .map(|i| {
                    let z = length * i as f64 / (n - 1) as f64;
                    [-a * (length - z) * (length - z), 0.0, -z]
                })
                .collect()
        }
    };
    let key = if p.has("points") { "points" } else { "shape" };
    let size = points
        .iter()
        .flatten()
        .fold(0.0f64, |m, v| m.max(v.abs()))
        .max(1e-300);
    for (i, w) in points.windows(2).enumerate() {
        let l = (0..3)
            .map(|a| (w[1][a] - w[0][a]).powi(2))
            .sum::<f64>()
            .sqrt();
        if !(l > 1e-12 * size) || !l.is_finite() {
            return Err(p.err_hint(
                key,
                p.get(key),
                format!(
                    "nodes {i} and {} {} (edge length {l:e} m)",
                    i + 1,
                    if l.is_finite() {
                        "coincide"
                    } else {
                        "are too far apart to represent"
                    }
                ),
                "give the prong distinct nodes of a realistic size (metres)",
            ));
        }
    }
    Ok(points)
}

/// Young's and shear moduli: `E`, and `G` or Poisson's ratio `nu` (default 0.5).
fn prong_moduli(p: &TableReader<'_>) -> Result<(f64, f64), ScenarioError> {
    let e = p.positive("E")?;
    let g = match (p.opt_positive("G")?, p.opt_f64("nu")?) {
        (Some(_), Some(_)) => {
            return Err(p.err("nu", p.get("nu"), "give either G or nu, not both"))
        }
        (Some(g), None) => g,
        (None, nu) => {
            let nu = nu.unwrap_or(0.5);
            if !(-1.0 < nu && nu <= 0.5) {
                return Err(p.err("nu", p.get("nu"), "Poisson's ratio must lie in (-1, 0.5]"));
            }
            e / (2.0 * (1.0 + nu))
        }
    };
    Ok((e, g))
}

fn prong_section(p: &TableReader<'_>) -> Result<Section3, ScenarioError> {
    let sec = p.table("section", SECTION)?;
    let section = match sec.str("kind")? {
        "rect" => Section3::Rect {
            b: sec.positive("b")?,
            h: sec.positive("h")?,
        },
        "circle" => Section3::Circle {
            r: sec.positive("r")?,
        },
        other => {
            return Err(sec.err_hint(
                "kind",
                sec.get("kind"),
                format!("unknown section {other:?}"),
                "use \"rect\" or \"circle\"",
            ))
        }
    };
    sec.finish()?;
    Ok(section)
}

/// Material damping as the planar prong's: a loss factor tan δ (default 0) at a frequency
/// (Hz, default 10) gives the Kelvin–Voigt retardation time τ = tan δ / (2π f).
fn prong_damping(p: &TableReader<'_>) -> Result<f64, ScenarioError> {
    let loss_factor = p.opt_f64("loss_factor")?.unwrap_or(0.0);
    if !(0.0..=10.0).contains(&loss_factor) {
        return Err(p.err_hint(
            "loss_factor",
            p.get("loss_factor"),
            "must be in [0, 10]",
            "the loss factor tan δ of the material at loss_frequency (silicone rubbers ≈ 0.05–0.5)",
        ));
    }
    let loss_frequency = p.opt_positive("loss_frequency")?.unwrap_or(10.0);
    Ok(loss_factor / (2.0 * std::f64::consts::PI * loss_frequency))
}

/// The prong (finger frame), its clamped edges and its damping time.
fn parse_prong(p: &TableReader<'_>) -> Result<(Rod3Spec, usize, f64), ScenarioError> {
    let points = prong_points(p)?;
    let (e, g) = prong_moduli(p)?;
    let density = p.positive("density")?;
    let section = prong_section(p)?;
    let damping_time = prong_damping(p)?;
    let clamped = p.opt_usize("clamped_edges")?.unwrap_or(1);
    if clamped == 0 || clamped + 1 >= points.len() {
        return Err(p.err(
            "clamped_edges",
            p.get("clamped_edges"),
            format!(
                "must lie between 1 and {} (the prong has {} nodes)",
                points.len() - 2,
                points.len()
            ),
        ));
    }
    let director = opt_vec3(p, "director", [1.0, 0.0, 0.0])?;
    p.finish()?;
    let spec = Rod3Spec {
        points,
        director,
        rest_theta: Vec::new(),
        section,
        youngs_modulus: e,
        shear_modulus: g,
        density,
    };
    Ok((spec, clamped, damping_time))
}

fn parse_shape(s: &TableReader<'_>, dir: &std::path::Path) -> Result<Shape3, ScenarioError> {
    let shape = match s.str("kind")? {
        "sphere" => Shape3::Sphere {
            radius: s.positive("radius")?,
        },
        "ellipsoid" => {
            let a = vec3(s, "semi_axes")?;
            if a.iter().any(|x| !(*x > 0.0)) {
                return Err(s.err(
                    "semi_axes",
                    s.get("semi_axes"),
                    "every semi-axis must be > 0",
                ));
            }
            Shape3::Ellipsoid { semi_axes: a }
        }
        "box" => {
            let h = vec3(s, "half")?;
            if h.iter().any(|x| !(*x > 0.0)) {
                return Err(s.err("half", s.get("half"), "every half extent must be > 0"));
            }
            Shape3::Box { half: h }
        }
        "plane" => Shape3::Plane,
        "mesh" => {
            let f = s.str("file")?;
            let scale = s.opt_positive("scale")?.unwrap_or(1.0);
            if scale > MAX_MESH_SCALE {
                return Err(s.err_hint(
                    "scale",
                    s.get("scale"),
                    format!("is too large (at most {MAX_MESH_SCALE:e})"),
                    "the factor from the file's units to metres: 0.001 for millimetres",
                ));
            }
            let path = dir.join(f);
            let text = super::input::read_referenced(&path, "mesh")
                .map_err(|m| s.err("file", s.get("file"), m))?;
            Shape3::Mesh(
                TriMesh::from_obj(&text, scale).map_err(|m| s.err("file", s.get("file"), m))?,
            )
        }
        other => {
            return Err(s.err_hint(
                "kind",
                s.get("kind"),
                format!("unknown shape {other:?}"),
                "use sphere, ellipsoid, box, plane or mesh",
            ))
        }
    };
    s.finish()?;
    Ok(shape)
}

/// A fruit's or obstacle's `name` (it names CSV rows and recording entities): not empty, no
/// control character (newline, NUL), no ',' or '"' (a CSV cell holds it as written).
fn object_name(r: &TableReader<'_>) -> Result<Option<String>, ScenarioError> {
    let Some(name) = r.opt_str("name")? else {
        return Ok(None);
    };
    if name.trim().is_empty() {
        return Err(r.err("name", r.get("name"), "must not be empty"));
    }
    if let Some(c) = name
        .chars()
        .find(|c| c.is_control() || *c == ',' || *c == '"')
    {
        return Err(r.err_hint(
            "name",
            r.get("name"),
            format!("must not hold the character {c:?} (it names CSV rows and recording entities)"),
            "use letters, digits, spaces, '-', '_' or '.'",
        ));
    }
    Ok(Some(name.to_string()))
}

/// Every object of the world has its own name: the fingers are `finger0` … `finger{n-1}`,
/// then the fruit, then the obstacles.
fn unique_names(
    top: &TableReader<'_>,
    fingers: usize,
    fruit: Option<&Fruit3>,
    obstacles: &[Obstacle3],
) -> Result<(), ScenarioError> {
    let is_finger = |n: &str| {
        n.strip_prefix("finger")
            .and_then(|k| k.parse::<usize>().ok().filter(|k| k.to_string() == n[6..]))
            .is_some_and(|k| k < fingers)
    };
    let mut seen: Vec<(&str, String)> = Vec::new();
    let named = fruit
        .map(|f| (f.name.as_str(), "fruit".to_string()))
        .into_iter()
        .chain(
            obstacles
                .iter()
                .enumerate()
                .map(|(k, o)| (o.name.as_str(), format!("obstacle.{k}"))),
        );
    for (name, key) in named {
        let clash = if is_finger(name) {
            Some(format!(
                "finger {name:?} (the gripper's fingers are finger0 … finger{})",
                fingers - 1
            ))
        } else {
            seen.iter()
                .find(|(n, _)| *n == name)
                .map(|(_, k)| format!("{k}.name"))
        };
        if let Some(other) = clash {
            let r = match key.strip_prefix("obstacle.") {
                None => top.table("fruit", FRUIT)?,
                Some(k) => {
                    let all = top.array("obstacle")?.map(|a| a.as_slice()).unwrap_or(&[]);
                    let k: usize = k.parse().unwrap_or(0);
                    top.table_value(&key, &all[k], OBSTACLE)?
                }
            };
            return Err(r.err_hint(
                "name",
                r.get("name"),
                format!("duplicate name {name:?}: {other} has it already"),
                "give the fruit and every obstacle a name of its own",
            ));
        }
        seen.push((name, key));
    }
    Ok(())
}

fn parse_fruit(f: &TableReader<'_>, dir: &std::path::Path) -> Result<Fruit3, ScenarioError> {
    let shape = parse_shape(&f.table("shape", SHAPE)?, dir)?;
    if shape == Shape3::Plane {
        return Err(f.err("shape", f.get("shape"), "a fruit cannot be a plane"));
    }
    let fruit = Fruit3 {
        name: object_name(f)?.unwrap_or_else(|| "fruit".into()),
        shape: shape.clone(),
        centre: vec3(f, "centre")?,
        density: f.positive("density")?,
        free: f.opt_bool("free")?.unwrap_or(true),
        hold_tolerance: 0.0,
        material: super::material::parse3(f, &shape)?,
    };
    let radius = match &fruit.shape {
        Shape3::Sphere { radius } => *radius,
        Shape3::Ellipsoid { semi_axes } => semi_axes.iter().fold(0.0f64, |a, b| a.max(*b)),
        Shape3::Box { half } => (half[0] * half[0] + half[1] * half[1] + half[2] * half[2]).sqrt(),
        Shape3::Mesh(m) => m.radius,
        Shape3::Plane => 0.0,
    };
    let fruit = Fruit3 {
        hold_tolerance: f.opt_positive("hold_tolerance")?.unwrap_or(0.1 * radius),
        ..fruit
    };
    f.finish()?;
    Ok(fruit)
}

fn parse_obstacles(
    top: &TableReader<'_>,
    dir: &std::path::Path,
) -> Result<Vec<Obstacle3>, ScenarioError> {
    let mut out = Vec::new();
    for (k, v) in top
        .array("obstacle")?
        .map(|a| a.as_slice())
        .unwrap_or(&[])
        .iter()
        .enumerate()
    {
        let o = top.table_value(&format!("obstacle.{k}"), v, OBSTACLE)?;
        let shape = parse_shape(&o.table("shape", SHAPE)?, dir)?;
        let at = vec3(&o, "at")?;
        let pose = if shape == Shape3::Plane {
            let n = opt_vec3(&o, "normal", [0.0, 0.0, 1.0])?;
            if n.iter().map(|x| x * x).sum::<f64>() < 1e-24 {
                return Err(o.err("normal", o.get("normal"), "must not be zero"));
            }
            Pose3::facing(at, n)
        } else {
            Pose3::at(at)
        };
        let name = object_name(&o)?.unwrap_or_else(|| format!("obstacle{k}"));
        o.finish()?;
        out.push(Obstacle3::new(&name, shape, pose));
    }
    Ok(out)
}

fn parse_moves(top: &TableReader<'_>) -> Result<Vec<Move3>, ScenarioError> {
    let mut out = Vec::new();
    for (k, v) in top
        .array("move")?
        .map(|a| a.as_slice())
        .unwrap_or(&[])
        .iter()
        .enumerate()
    {
        let m = top.table_value(&format!("move.{k}"), v, MOVE)?;
        let mv = match m.str("kind")? {
            "squeeze" => Move3::Squeeze {
                speed: m.positive("speed")?,
                force: m.positive("force")?,
                max_travel: m.positive("max_travel")?,
            },
            "close" => Move3::Close {
                travel: m.f64("travel")?,
                duration: m.positive("duration")?,
            },
            "hold" => Move3::Hold {
                duration: m.positive("duration")?,
            },
            "translate" => Move3::Translate {
                by: vec3(&m, "by")?,
                duration: m.positive("duration")?,
            },
            "lift" => Move3::Lift {
                height: m.f64("height")?,
                duration: m.positive("duration")?,
            },
            "rotate" => {
                let axis = vec3(&m, "axis")?;
                if axis.iter().map(|x| x * x).sum::<f64>() < 1e-24 {
                    return Err(m.err("axis", m.get("axis"), "must not be zero"));
                }
                Move3::Rotate {
                    axis,
                    angle: m.f64("angle")?,
                    duration: m.positive("duration")?,
                }
            }
            other => {
                return Err(m.err_hint(
                    "kind",
                    m.get("kind"),
                    format!("unknown move {other:?}"),
                    "use squeeze, close, hold, translate, lift or rotate",
                ))
            }
        };
        m.finish()?;
        out.push(mv);
    }
    if out.is_empty() {
        return Err(top.err_hint(
            "move",
            None,
            "a 3D scenario needs at least one [[move]]",
            "add e.g. [[move]] kind = \"squeeze\"",
        ));
    }
    Ok(out)
}

/// The planar step-size keys: a 3D run takes fixed steps, so each is refused by name (not
/// accepted and ignored).
fn refuse_adaptive(solve: &TableReader<'_>) -> Result<(), ScenarioError> {
    const KEYS: [&str; 8] = [
        "stepping",
        "rtol",
        "atol",
        "dt_min",
        "dt_max",
        "time_of_impact",
        "dt_near",
        "near_distance",
    ];
    for key in KEYS {
        if solve.has(key) {
            return Err(solve.err_hint(
                key,
                solve.get(key),
                "a 3D run takes fixed steps: adaptive stepping and time of impact are planar \
                 only",
                "remove the key; [solve] dt is the 3D step (integrator = \"bdf2\" or \
                 \"tr_bdf2\" for second order)",
            ));
        }
    }
    Ok(())
}
