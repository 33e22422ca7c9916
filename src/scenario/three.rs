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

pub fn is_3d(text: &str) -> bool {
    text.parse::<toml::Table>()
        .ok()
        .and_then(|t| t.get("dimension").and_then(Value::as_integer))
        == Some(3)
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
            return Err(top.err("dimension", Some(dim), "a 3D scenario says dimension = 3"));
        }
        let name = top.str("name")?.to_string();
        if name.is_empty()
            || !name
                .chars()
                .all(|c| c.is_ascii_alphanumeric() || "-_.".contains(c))
        {
            return Err(top.err(
                "name",
                top.get("name"),
                "may only hold letters, digits, '-', '_' and '.' (it names the output files)",
            ));
        }
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
        solve.finish()?;
        let (prong, clamped_edges, damping_time) = parse_prong(&top.table("prong", PRONG)?)?;
        let (fingers, radius, centre, sensor_tau) = parse_gripper(&top)?;
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
        let moves = parse_moves(&top)?;
        let expect = super::expect::parse(&top)?;
        top.finish()?;
        Ok(Scenario3 {
            name,
            description,
            file: file.to_string(),
            dt,
            t_end,
            gravity,
            force_tol,
            step_tol,
            max_newton_iterations,
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
        })
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
            pts
        }
        None => {
            let n = p.usize("nodes")?;
            if n < 3 {
                return Err(p.err("nodes", p.get("nodes"), "a prong needs at least 3 nodes"));
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

fn parse_fruit(f: &TableReader<'_>, dir: &std::path::Path) -> Result<Fruit3, ScenarioError> {
    let shape = parse_shape(&f.table("shape", SHAPE)?, dir)?;
    if shape == Shape3::Plane {
        return Err(f.err("shape", f.get("shape"), "a fruit cannot be a plane"));
    }
    let fruit = Fruit3 {
        name: f.opt_str("name")?.unwrap_or("fruit").to_string(),
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
        let name = o
            .opt_str("name")?
            .map(str::to_string)
            .unwrap_or_else(|| format!("obstacle{k}"));
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
