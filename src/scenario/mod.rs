//! Scenario files: TOML, read with located errors, `--set` overrides by dotted path.
//!
//! See `docs/scenario-format.md` for every key.

pub mod actuation;
mod advice;
pub mod contact;
pub mod expect;
pub mod fin_ray;
pub mod friction;
pub mod geometry;
pub mod input;
pub mod joint;
pub mod material;
pub mod obstacle;
pub mod overrides;
pub mod reader;
pub mod three;

use crate::contact::friction::FrictionTable;
use crate::obstacle::Obstacle;
use crate::world::body::BodySpec;
pub use actuation::ActuatorSpec;
pub use input::{read_capped, MAX_SCENARIO_BYTES};
pub use reader::ScenarioError;
use reader::TableReader;
use toml::Value;

/// `[output] precision`: how the MCAP's `/sim/step` and `/sim/iteration` store their per-node
/// numbers: `f32` (protobuf `float`, with an exact 64-bit fingerprint of each step's state;
/// the default) or `f64` (`double`, the exact values).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Precision {
    #[default]
    F32,
    F64,
}

impl Precision {
    pub fn as_str(self) -> &'static str {
        match self {
            Precision::F32 => "f32",
            Precision::F64 => "f64",
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Mode {
    Dynamic,
    Static,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Stepping {
    Fixed,
    Proximity,
    /// Error-controlled: the step is sized so the embedded (backward Euler vs trapezoidal)
    /// estimate of the local position error stays within atol + rtol |Δq|.
    Adaptive,
}

/// The time integrator of dynamic mode.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Integrator {
    /// First order, L-stable, dissipative (the seed's).
    BackwardEuler,
    /// Variable-step two-step BDF: second order, L-stable. Nodes touching an obstacle in a
    /// step (and in the step before) drop to backward Euler locally.
    Bdf2,
    /// TR-BDF2 (γ = 2 − √2): a trapezoidal stage to t + γ dt, then BDF2 over t, t + γ dt,
    /// t + dt. Second order, L-stable, local error constant
    /// about 0.04 against BDF2's 2/9.
    /// Nodes touching an obstacle drop to backward Euler in a stage as under BDF2.
    TrBdf2,
}

/// `[solve]`.
#[derive(Debug, Clone, serde::Serialize)]
pub struct Solve {
    pub mode: Mode,
    pub t_end: f64,
    pub dt: f64,
    pub stepping: Stepping,
    pub dt_near: f64,
    pub near_distance: f64,
    /// Adaptive stepping: relative and absolute (m) local error tolerances, step bounds (s).
    pub rtol: f64,
    pub atol: f64,
    pub dt_min: f64,
    pub dt_max: f64,
    /// Split a step at the time a free node would cross an obstacle, so contact starts on
    /// the surface.
    pub time_of_impact: bool,
    /// Dynamic mode's time integrator.
    pub integrator: Integrator,
    pub gravity: [f64; 2],
    /// Newton force tolerance relative to the problem's force scale.
    pub force_tol: f64,
    /// Newton update tolerance relative to the problem's length scale (round-off floor).
    pub step_tol: f64,
    pub max_newton_iterations: u32,
    pub max_contact_passes: u32,
    /// How many times a failing step may halve dt before the run stops.
    pub max_backoff: u32,
    /// Static mode: the first load increment (fraction of the full load).
    pub load_step: f64,
    /// Static mode: an initial imperfection (fraction of the rod length, 0 = none) that lets
    /// the load ramp follow the stable branch past a bifurcation.
    pub imperfection: f64,
}

#[derive(Debug, Clone, serde::Serialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Shape {
    Straight {
        start: [f64; 2],
        end: [f64; 2],
    },
    Points {
        points: Vec<[f64; 2]>,
    },
    /// The seed's prong: x = x0 + a (L − s)², y = y0 − s, s = 0 … L.
    Parabola {
        x0: f64,
        y0: f64,
        a: f64,
        length: f64,
    },
}

#[derive(Debug, Clone, Copy, serde::Serialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Section {
    /// b out of plane, h in the bending plane.
    Rect {
        b: f64,
        h: f64,
    },
    Circle {
        radius: f64,
    },
}

impl Section {
    pub fn area(&self) -> f64 {
        match *self {
            Section::Rect { b, h } => b * h,
            Section::Circle { radius } => std::f64::consts::PI * radius * radius,
        }
    }
    pub fn inertia(&self) -> f64 {
        match *self {
            Section::Rect { b, h } => b * h * h * h / 12.0,
            Section::Circle { radius } => std::f64::consts::PI * radius.powi(4) / 4.0,
        }
    }
    /// Distance from the neutral axis to the outer fibre in the bending plane.
    pub fn half_height(&self) -> f64 {
        match *self {
            Section::Rect { h, .. } => h / 2.0,
            Section::Circle { radius } => radius,
        }
    }
}

#[derive(Debug, Clone, Copy, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum MassSpec {
    Density(f64),
    NodeMass(f64),
    /// The whole rod's mass (kg), lumped by Voronoi length like a density: refining the nodes
    /// keeps the prong's mass (`node_mass` multiplies it).
    Total(f64),
}

/// Prescribed motion of the clamped nodes.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Drive {
    Fixed,
    /// From rest, x(t) = x0 + ½ a t², until it stops (then it holds its position).
    ConstantAcceleration {
        acceleration: [f64; 2],
        stop_time: Option<f64>,
        stop_travel: Option<f64>,
    },
    /// x(t) = x0 + v t, until it stops.
    ConstantVelocity {
        velocity: [f64; 2],
        stop_time: Option<f64>,
        stop_travel: Option<f64>,
    },
}

impl Drive {
    /// Displacement of a driven node from its initial position at time t, and its velocity.
    pub fn motion(&self, t: f64) -> ([f64; 2], [f64; 2]) {
        match *self {
            Drive::Fixed => ([0.0; 2], [0.0; 2]),
            Drive::ConstantAcceleration {
                acceleration: a,
                stop_time,
                stop_travel,
            } => {
                let amag = (a[0] * a[0] + a[1] * a[1]).sqrt();
                let mut t_stop = stop_time.unwrap_or(f64::INFINITY);
                if let Some(d) = stop_travel {
                    if amag > 0.0 {
                        t_stop = t_stop.min((2.0 * d / amag).sqrt());
                    }
                }
                let te = t.min(t_stop);
                let moving = t < t_stop;
                let d = [0.5 * a[0] * te * te, 0.5 * a[1] * te * te];
                let v = if moving {
                    [a[0] * te, a[1] * te]
                } else {
                    [0.0; 2]
                };
                (d, v)
            }
            Drive::ConstantVelocity {
                velocity: v,
                stop_time,
                stop_travel,
            } => {
                let vmag = (v[0] * v[0] + v[1] * v[1]).sqrt();
                let mut t_stop = stop_time.unwrap_or(f64::INFINITY);
                if let Some(d) = stop_travel {
                    if vmag > 0.0 {
                        t_stop = t_stop.min(d / vmag);
                    }
                }
                let te = t.min(t_stop);
                let moving = t < t_stop;
                ([v[0] * te, v[1] * te], if moving { v } else { [0.0; 2] })
            }
        }
    }
}

#[derive(Debug, Clone, Copy, serde::Serialize)]
pub struct Load {
    pub node: usize,
    pub force: [f64; 2],
}

/// One `[[rod]]`.
#[derive(Debug, Clone, serde::Serialize)]
pub struct RodSpec {
    pub name: String,
    pub nodes: usize,
    pub shape: Shape,
    #[serde(rename = "E")]
    pub youngs_modulus: f64,
    pub section: Section,
    pub mass: MassSpec,
    pub clamped: Vec<usize>,
    pub drive: Drive,
    pub loads: Vec<Load>,
    /// Initial velocity of every node (m/s).
    pub velocity: [f64; 2],
    /// A `[[particle]]`: one node, no elasticity.
    pub particle: bool,
    /// The `[[actuator]]` that moves the clamped nodes (index into `Scenario::actuators`);
    /// None: the rod's own `drive`.
    pub actuator: Option<usize>,
    /// Follows the actuator's motion mirrored in its line x = `mirror_x`.
    pub mirror: bool,
    /// Poisson's ratio of the prong's material (its share of a compliant contact's E*).
    pub nu: f64,
    /// Kelvin–Voigt retardation time τ (s): viscous stress τ E ε̇ beside the elastic E ε;
    /// `loss_factor` / (2π `loss_frequency`), 0 = no material damping.
    pub damping_time: f64,
    /// The table it was read from (`rod.<i>`, `particle.<i>`; a generated finger's members
    /// share their `[[rod]]`'s), for messages.
    #[serde(skip)]
    pub source: String,
}

/// A whole scenario.
#[derive(Debug, Clone, serde::Serialize)]
pub struct Scenario {
    pub name: String,
    pub description: String,
    pub solve: Solve,
    pub rods: Vec<RodSpec>,
    pub obstacles: Vec<Obstacle>,
    /// Each obstacle's name (`obstacle.<i>` unless named).
    pub obstacle_names: Vec<String>,
    /// The obstacles that are free rigid bodies (fruit).
    pub bodies: Vec<BodySpec>,
    /// Coulomb coefficients (frictionless unless `[friction]` says otherwise).
    pub friction: FrictionTable,
    /// `[[actuator]]`s: programs of phases for groups of rods.
    pub actuators: Vec<ActuatorSpec>,
    /// `[expect]`: the outcome the scenario is built to show (judged by `replay check`).
    pub expect: expect::Expect,
    /// `[contact]`: which surface of a prong touches (centreline unless it says `face`).
    pub contact: contact::ContactSpec,
    /// Per obstacle: its material when it is a compliant fruit (None: rigid).
    pub materials: Vec<Option<crate::contact::compliant::Material>>,
    /// Flush recordings every this many steps.
    pub flush_every: u64,
    /// `[output] precision` of the MCAP's per-node numbers.
    pub precision: Precision,
    /// `[[joint]]`s: nodes of two rods held together (pin or rigid).
    pub joints: Vec<joint::JointSpec>,
    /// The scenario as TOML text, with overrides applied (stored in recordings).
    #[serde(skip)]
    pub text: String,
    /// Where it was read from (for messages).
    #[serde(skip)]
    pub file: String,
}

const TOP_KEYS: &[&str] = &[
    "name",
    "description",
    "solve",
    "rod",
    "particle",
    "obstacle",
    "friction",
    "output",
    "actuator",
    "expect",
    "contact",
    "joint",
    "dimension",
];
const SOLVE_KEYS: &[&str] = &[
    "mode",
    "t_end",
    "dt",
    "stepping",
    "dt_near",
    "near_distance",
    "rtol",
    "atol",
    "dt_min",
    "dt_max",
    "time_of_impact",
    "integrator",
    "gravity",
    "force_tol",
    "step_tol",
    "max_newton_iterations",
    "max_contact_passes",
    "max_backoff",
    "load_step",
    "imperfection",
];
const ROD_KEYS: &[&str] = &[
    "name",
    "nodes",
    "shape",
    "E",
    "section",
    "density",
    "node_mass",
    "mass",
    "nu",
    "clamped",
    "drive",
    "loads",
    "velocity",
    "actuator",
    "mirror",
    "loss_factor",
    "loss_frequency",
];
const PARTICLE_KEYS: &[&str] = &["name", "position", "velocity", "mass", "force"];
const OUTPUT_KEYS: &[&str] = &["flush_every", "precision"];

impl Scenario {
    /// Read a scenario file (once: [`input::read_text`]), apply `--set` overrides, validate.
    pub fn load(path: &std::path::Path, sets: &[String]) -> Result<Scenario, ScenarioError> {
        let text = input::read_text(path)?;
        Self::from_str(&text, &path.display().to_string(), sets)
    }

    pub fn from_str(text: &str, file: &str, sets: &[String]) -> Result<Scenario, ScenarioError> {
        let fail = |key: &str, value: &str, message: String, hint: Option<String>| ScenarioError {
            file: file.to_string(),
            key: key.to_string(),
            value: value.to_string(),
            message,
            hint,
        };
        if text.trim().is_empty() {
            return Err(fail(
                "",
                "",
                "the file is empty".into(),
                Some("a scenario needs at least `name`, a [solve] table and one [[rod]]".into()),
            ));
        }
        let mut root: toml::Table = text.parse().map_err(|e: toml::de::Error| {
            // One line, so the error stays one line.
            let msg = e
                .message()
                .lines()
                .map(str::trim)
                .filter(|l| !l.is_empty())
                .collect::<Vec<_>>()
                .join("; ");
            let (line, col) = e
                .span()
                .map(|s| {
                    let mut start = s.start.min(text.len());
                    while !text.is_char_boundary(start) {
                        start -= 1;
                    }
                    let before = &text[..start];
                    let line = before.matches('\n').count() + 1;
                    let col = before
                        .rsplit('\n')
                        .next()
                        .map(|l| l.chars().count() + 1)
                        .unwrap_or(1);
                    (line, col)
                })
                .unwrap_or((0, 0));
            fail(
                "",
                "",
                format!("TOML syntax error at line {line}, column {col}: {msg}"),
                None,
            )
        })?;
        apply_sets(&mut root, sets, file)?;
        contact::make_explicit(&mut root);
        let text = toml::to_string(&root).unwrap_or_else(|_| text.to_string());
        let mut sc = parse_root(&root, file)?;
        sc.text = text;
        sc.file = file.to_string();
        geometry::validate(&sc)?;
        Ok(sc)
    }
}

/// Apply `--set` overrides to a scenario's TOML table; an error names the file with the `--set`
/// text (on one line, whatever it holds), the key and the value.
pub(crate) fn apply_sets(
    root: &mut toml::Table,
    sets: &[String],
    file: &str,
) -> Result<(), ScenarioError> {
    for s in sets {
        overrides::apply(root, s).map_err(|(key, value, message, hint)| {
            let shown = if s.contains(['\n', '\r']) {
                s.escape_debug().to_string()
            } else {
                s.clone()
            };
            ScenarioError {
                file: format!("{file} (--set {shown})"),
                key,
                value,
                message,
                hint,
            }
        })?;
    }
    Ok(())
}

/// The hint for a scenario file that cannot be read: a "did you mean" when a `.toml` file
/// of a similar name is beside it (or in `scenarios/`), e.g. for `seed-grasp-r6.toml` or a
/// name given without `.toml` or without `scenarios/`.
fn missing_file_hint(path: &std::path::Path, e: &std::io::Error) -> String {
    use std::path::Path;
    let general = "check the path; shipped scenarios are listed by `gripsim scenarios`";
    if e.kind() != std::io::ErrorKind::NotFound {
        return general.into();
    }
    let Some(name) = path.file_name().map(|n| n.to_string_lossy().into_owned()) else {
        return general.into();
    };
    let want = if name.ends_with(".toml") {
        name
    } else {
        format!("{name}.toml")
    };
    let parent = path.parent().filter(|p| !p.as_os_str().is_empty());
    for dir in [parent.unwrap_or(Path::new(".")), Path::new("scenarios")] {
        let Ok(entries) = std::fs::read_dir(dir) else {
            continue;
        };
        let mut names: Vec<String> = entries
            .filter_map(|e| e.ok())
            .map(|e| e.file_name().to_string_lossy().into_owned())
            .filter(|n| n.ends_with(".toml"))
            .collect();
        names.sort();
        let refs: Vec<&str> = names.iter().map(String::as_str).collect();
        if let Some(best) = reader::did_you_mean(&want, &refs) {
            return format!("did you mean {}? ({general})", dir.join(best).display());
        }
    }
    general.into()
}

/// The scenario's `name` (it names the recording files), in both dimensions: letters,
/// digits, '-', '_' and '.', with at least one letter or digit ("." and ".." name folders).
pub(crate) fn scenario_name(top: &TableReader) -> Result<String, ScenarioError> {
    let name = top.str("name")?.to_string();
    if name.trim().is_empty() {
        return Err(top.err("name", top.get("name"), "must not be empty"));
    }
    if !name
        .chars()
        .all(|c| c.is_ascii_alphanumeric() || c == '-' || c == '_' || c == '.')
    {
        return Err(top.err_hint(
            "name",
            top.get("name"),
            "may only hold letters, digits, '-', '_' and '.' (it names the recording files)",
            "use e.g. \"seed-grasp-r5\"",
        ));
    }
    if name.chars().all(|c| c == '.') {
        // "." and ".." name folders: recordings/..rrd is a hidden file at best.
        return Err(top.err_hint(
            "name",
            top.get("name"),
            "must hold a letter or digit (it names the recording files)",
            "use e.g. \"seed-grasp-r5\"",
        ));
    }
    Ok(name)
}

fn parse_root(root: &toml::Table, file: &str) -> Result<Scenario, ScenarioError> {
    let top = TableReader::new(file, String::new(), root, TOP_KEYS);
    let name = scenario_name(&top)?;
    // `dimension = 2` says what the default is; any other value goes to the 3D reader
    // (`three::is_3d`), which explains it.
    if let Some(d) = top.get("dimension") {
        if d.as_integer() != Some(2) {
            return Err(top.err("dimension", Some(d), "a planar scenario has dimension = 2"));
        }
    }
    let description = top.opt_str("description")?.unwrap_or("").to_string();
    let solve = parse_solve(&top.table("solve", SOLVE_KEYS)?)?;

    let empty = Vec::new();
    let rods_v = match top.get("rod") {
        None => &empty,
        Some(Value::Array(a)) => a,
        Some(other) => {
            return Err(top.err("rod", Some(other), "expected an array of [[rod]] tables"))
        }
    };
    let particles_v = match top.get("particle") {
        None => &empty,
        Some(Value::Array(a)) => a,
        Some(other) => {
            return Err(top.err(
                "particle",
                Some(other),
                "expected an array of [[particle]] tables",
            ))
        }
    };
    let actuators = actuation::parse_actuators(&top)?;
    let joined = joint::mentioned(root);
    let mut rods: Vec<RodSpec> = Vec::new();
    let tables = rods_v
        .iter()
        .enumerate()
        .map(|(i, v)| (format!("rod.{i}"), v, false));
    let tables = tables.chain(
        particles_v
            .iter()
            .enumerate()
            .map(|(i, v)| (format!("particle.{i}"), v, true)),
    );
    let mut generated = Vec::new();
    for (path, v, is_particle) in tables {
        let (expanded, r) = if is_particle {
            let r = top.table_value(&path, v, PARTICLE_KEYS)?;
            (vec![parse_particle(&r, solve.mode)?], r)
        } else {
            let r = top.table_value(&path, v, ROD_KEYS)?;
            match parse_rod(&r, solve.mode, &actuators, &joined)? {
                (rod, None) => (vec![rod], r),
                (rod, Some(fr)) => {
                    let (members, joints) = fin_ray::expand(&r, rod, &fr, rods.len())?;
                    generated.extend(joints);
                    (members, r)
                }
            }
        };
        for rod in expanded {
            if let Some(o) = rods.iter().find(|o| o.name == rod.name) {
                return Err(r.err_hint(
                    "name",
                    r.get("name"),
                    format!(
                        "duplicate name {:?} (the {} before it has it already)",
                        rod.name, o.source
                    ),
                    "give every rod and particle its own name",
                ));
            }
            rods.push(rod);
        }
    }

    let (mut obstacles, mut obstacle_names, mut bodies) = (Vec::new(), Vec::new(), Vec::new());
    let mut materials = Vec::new();
    match top.get("obstacle") {
        None => {}
        Some(Value::Array(a)) => {
            for (i, v) in a.iter().enumerate() {
                let r = top.table_value(&format!("obstacle.{i}"), v, &[])?;
                let (o, name, body, material) = obstacle::parse(&r, i, solve.mode, solve.gravity)?;
                if obstacle_names.contains(&name) || rods.iter().any(|x| x.name == name) {
                    return Err(r.err_hint(
                        "name",
                        r.get("name"),
                        format!("duplicate name {name:?}"),
                        "give every rod, particle and obstacle its own name",
                    ));
                }
                obstacles.push(o);
                obstacle_names.push(name);
                materials.push(material);
                bodies.extend(body);
            }
        }
        Some(other) => {
            return Err(top.err(
                "obstacle",
                Some(other),
                "expected an array of [[obstacle]] tables",
            ))
        }
    }

    if rods.is_empty() && bodies.is_empty() {
        if let Some(e) = top.typo_error("rod").or_else(|| top.typo_error("particle")) {
            return Err(e);
        }
        return Err(top.err_hint(
            "rod",
            None,
            "missing required key",
            "add at least one [[rod]] (or [[particle]]) table, or a free obstacle",
        ));
    }
    let names: Vec<&str> = rods
        .iter()
        .map(|r| r.name.as_str())
        .chain(obstacle_names.iter().map(String::as_str))
        .collect();
    let friction = friction::parse(&top, &names)?;
    if friction.any() && solve.mode == Mode::Static {
        return Err(top.err_hint(
            "friction",
            top.get("friction"),
            "friction needs a dynamic run (stick and slip are decided from velocities)",
            "use mode = \"dynamic\", or remove [friction]",
        ));
    }
    let joints = joint::parse(&top, &rods, generated, solve.mode)?;
    let expect = expect::parse(&top)?;
    let contact = contact::parse(&top)?;
    let mut flush_every = 100;
    let mut precision = Precision::F32;
    if let Some(o) = top.opt_table("output", OUTPUT_KEYS)? {
        if let Some(n) = o.opt_usize("flush_every")? {
            if n == 0 {
                return Err(o.err("flush_every", o.get("flush_every"), "must be at least 1"));
            }
            flush_every = n as u64;
        }
        match o.opt_str("precision")? {
            None | Some("f32") => {}
            Some("f64") => precision = Precision::F64,
            Some(other) => {
                return Err(o.err(
                    "precision",
                    o.get("precision"),
                    format!("unknown precision {other:?}: use \"f32\" or \"f64\""),
                ))
            }
        }
        o.finish()?;
    }
    top.finish()?;
    Ok(Scenario {
        name,
        description,
        solve,
        rods,
        obstacles,
        obstacle_names,
        bodies,
        friction,
        actuators,
        expect,
        contact,
        materials,
        flush_every,
        precision,
        joints,
        text: String::new(),
        file: file.into(),
    })
}

/// The most time steps a dynamic run may take (t_end / dt): beyond it a run would not finish.
const MAX_STEPS: f64 = 1e9;

fn parse_solve(s: &TableReader) -> Result<Solve, ScenarioError> {
    let mode = match s.opt_str("mode")?.unwrap_or("dynamic") {
        "dynamic" => Mode::Dynamic,
        "static" => Mode::Static,
        other => {
            let hint = match reader::did_you_mean(other, &["dynamic", "static"]) {
                Some(m) => format!("did you mean \"{m}\"?"),
                None => "use \"dynamic\" or \"static\"".into(),
            };
            return Err(s.err_hint(
                "mode",
                s.get("mode"),
                format!("unknown mode {other:?}"),
                hint,
            ));
        }
    };
    let t_end = match mode {
        Mode::Dynamic => s.positive("t_end")?,
        Mode::Static => s.opt_positive("t_end")?.unwrap_or(0.0),
    };
    let dt = match mode {
        Mode::Dynamic => s.positive("dt")?,
        Mode::Static => s.opt_positive("dt")?.unwrap_or(1.0),
    };
    if mode == Mode::Dynamic {
        check_steps(s, dt, t_end)?;
    }
    let stepping = match s.opt_str("stepping")?.unwrap_or("fixed") {
        "fixed" => Stepping::Fixed,
        "proximity" => Stepping::Proximity,
        "adaptive" => Stepping::Adaptive,
        other => {
            let hint = match reader::did_you_mean(other, &["fixed", "proximity", "adaptive"]) {
                Some(m) => format!("did you mean \"{m}\"?"),
                None => "use \"fixed\", \"proximity\" or \"adaptive\"".into(),
            };
            return Err(s.err_hint(
                "stepping",
                s.get("stepping"),
                format!("unknown stepping {other:?}"),
                hint,
            ));
        }
    };
    let (dt_near, near_distance) = if stepping == Stepping::Proximity || s.has("dt_near") {
        // Checked whatever the stepping (docs/scenario-format.md), so a value that would fail
        // once `--set solve.stepping=proximity` switches it on fails now.
        let dn = s.positive("dt_near")?;
        if dn > dt {
            return Err(s.err_hint(
                "dt_near",
                s.get("dt_near"),
                format!("is larger than dt = {dt}"),
                "dt_near is the smaller step used near contact",
            ));
        }
        if mode == Mode::Dynamic && t_end / dn > MAX_STEPS {
            return Err(s.err_hint(
                "dt_near",
                s.get("dt_near"),
                format!(
                    "is too small: t_end / dt_near = {:.3e} steps (at most {MAX_STEPS:e})",
                    t_end / dn
                ),
                "use a larger dt_near or a shorter t_end",
            ));
        }
        let near = if stepping == Stepping::Proximity {
            s.positive("near_distance")?
        } else {
            s.opt_positive("near_distance")?.unwrap_or(0.0)
        };
        (dn, near)
    } else {
        // Accepted and ignored when stepping is fixed, so a --set can switch stepping.
        (
            s.opt_positive("dt_near")?.unwrap_or(dt),
            s.opt_positive("near_distance")?.unwrap_or(0.0),
        )
    };
    // Adaptive stepping: accepted (and ignored) with other steppings, so --set can switch.
    let rtol = s.opt_positive("rtol")?.unwrap_or(1e-3);
    let atol = s.opt_positive("atol")?.unwrap_or(1e-9);
    let dt_max = s
        .opt_positive("dt_max")?
        .unwrap_or(if mode == Mode::Dynamic {
            (t_end / 10.0).max(dt)
        } else {
            dt
        });
    let dt_min = s.opt_positive("dt_min")?.unwrap_or(dt_max * 1e-6);
    if dt_min > dt_max {
        return Err(s.err_hint(
            "dt_min",
            s.get("dt_min"),
            format!("is larger than dt_max = {dt_max}"),
            "dt_min and dt_max bound the adaptive step",
        ));
    }
    if stepping == Stepping::Adaptive && (dt < dt_min || dt > dt_max) {
        return Err(s.err_hint(
            "dt",
            s.get("dt"),
            format!("is outside [dt_min, dt_max] = [{dt_min}, {dt_max}]"),
            "with adaptive stepping dt is the first step; keep it within the bounds",
        ));
    }
    if stepping == Stepping::Adaptive && mode == Mode::Dynamic && t_end / dt_min > MAX_STEPS {
        // The step-count limit `dt` has: adaptive steps may shrink to dt_min.
        return Err(s.err_hint(
            "dt_min",
            s.get("dt_min").or(s.get("dt_max")),
            format!(
                "is too small: t_end / dt_min = {:.3e} steps (at most {MAX_STEPS:e}){}",
                t_end / dt_min,
                if s.has("dt_min") {
                    ""
                } else {
                    " (dt_min defaults to dt_max × 1e-6)"
                }
            ),
            "use a larger dt_min or a shorter t_end",
        ));
    }
    let time_of_impact = s.opt_bool("time_of_impact")?.unwrap_or(false);
    let integrator = parse_integrator(s)?;
    let gravity = s.opt_vec2("gravity")?.unwrap_or([0.0, -9.81]);
    check_magnitude(s, "gravity", &gravity, MAX_ACCELERATION, "m/s²")?;
    let force_tol = s.opt_positive("force_tol")?.unwrap_or(1e-9);
    let step_tol = s.opt_positive("step_tol")?.unwrap_or(1e-12);
    let max_newton_iterations = positive_int(s, "max_newton_iterations", 50)?;
    let max_contact_passes = positive_int(s, "max_contact_passes", 25)?;
    let max_backoff = match s.opt_usize("max_backoff")? {
        None => 8,
        Some(n) if n > 60 => {
            return Err(s.err_hint(
                "max_backoff",
                s.get("max_backoff"),
                "is unreasonably large (at most 60)",
                "each back-off halves dt; 60 halvings already reach 1e-18 dt",
            ))
        }
        Some(n) => n as u32,
    };
    let load_step = s.opt_positive("load_step")?.unwrap_or(0.25);
    if load_step > 1.0 {
        return Err(s.err("load_step", s.get("load_step"), "must be in (0, 1]"));
    }
    let imperfection = s.opt_f64("imperfection")?.unwrap_or(0.0);
    if !(0.0..=0.1).contains(&imperfection) {
        return Err(s.err_hint(
            "imperfection",
            s.get("imperfection"),
            "must be in [0, 0.1]",
            "a small fraction of the rod length, e.g. 1e-3",
        ));
    }
    s.finish()?;
    Ok(Solve {
        mode,
        t_end,
        dt,
        stepping,
        dt_near,
        near_distance,
        rtol,
        atol,
        dt_min,
        dt_max,
        time_of_impact,
        integrator,
        gravity,
        force_tol,
        step_tol,
        max_newton_iterations,
        max_contact_passes,
        max_backoff,
        load_step,
        imperfection,
    })
}

/// Largest accepted |gravity| and |drive acceleration|: 1e6 m/s² (about 100 000 g). Far above
/// any gripper, far below where f64 arithmetic on a step overflows (gravity = 1e308 ran to
/// the end with every number infinite or lost).
pub const MAX_ACCELERATION: f64 = 1e6;
/// Largest accepted |force| of a load or a particle: 1e9 N.
pub const MAX_FORCE: f64 = 1e9;

/// A dynamic run's step and end, in both dimensions: dt ≤ t_end and at most
/// [`MAX_STEPS`] steps.
pub(crate) fn check_steps(s: &TableReader, dt: f64, t_end: f64) -> Result<(), ScenarioError> {
    if dt > t_end {
        return Err(s.err_hint(
            "dt",
            s.get("dt"),
            format!("is larger than t_end = {t_end}"),
            "make dt smaller than t_end",
        ));
    }
    if t_end / dt > MAX_STEPS {
        return Err(s.err_hint(
            "dt",
            s.get("dt"),
            format!(
                "is too small: t_end / dt = {:.3e} steps (at most {MAX_STEPS:e})",
                t_end / dt
            ),
            "use a larger dt or a shorter t_end",
        ));
    }
    Ok(())
}

/// |v| (2 or 3 components) at most `cap`, in both dimensions.
pub(crate) fn check_magnitude(
    r: &TableReader,
    key: &str,
    v: &[f64],
    cap: f64,
    unit: &str,
) -> Result<(), ScenarioError> {
    let m = v.iter().fold(0.0f64, |a, x| a.hypot(*x));
    if m > cap {
        return Err(r.err_hint(
            key,
            r.table.get(key),
            format!("magnitude {m:.3e} {unit} is not physical here (at most {cap:e} {unit})"),
            "check the units (SI: m, s, kg, N)",
        ));
    }
    Ok(())
}

pub(crate) fn positive_int(
    s: &TableReader,
    key: &'static str,
    default: u32,
) -> Result<u32, ScenarioError> {
    match s.opt_usize(key)? {
        None => Ok(default),
        Some(0) => Err(s.err(key, s.get(key), "must be at least 1")),
        Some(n) if n > 100_000 => {
            Err(s.err(key, s.get(key), "is unreasonably large (at most 100000)"))
        }
        Some(n) => Ok(n as u32),
    }
}

/// A rod's `shape` keys: the curves', then the Fin Ray finger's (`fin_ray.rs`; `length` serves
/// both).
const SHAPE_KEYS: &[&str] = &[
    "kind",
    "start",
    "end",
    "points",
    "x0",
    "y0",
    "a",
    "length",
    "base_width",
    "ribs",
    "rib_angle",
    "base",
    "direction",
    "side",
    "rib_nodes",
    "rib_section",
    "rib_joint",
];
pub(crate) const SECTION_KEYS: &[&str] = &["kind", "b", "h", "radius"];
const DRIVE_KEYS: &[&str] = &[
    "kind",
    "acceleration",
    "velocity",
    "stop_time",
    "stop_travel",
];

fn parse_rod(
    r: &TableReader,
    mode: Mode,
    actuators: &[ActuatorSpec],
    joined: &[String],
) -> Result<(RodSpec, Option<fin_ray::FinRay>), ScenarioError> {
    let name = r.str("name")?.to_string();
    if name.trim().is_empty() {
        return Err(r.err("name", r.get("name"), "must not be empty"));
    }
    let nodes = r.usize("nodes")?;
    if nodes < 3 {
        return Err(r.err_hint(
            "nodes",
            r.get("nodes"),
            "a rod needs at least 3 nodes (one bending spring)",
            "use nodes = 3 or more",
        ));
    }
    if nodes > 1_000_000 {
        return Err(r.err("nodes", r.get("nodes"), "is too large (at most 1000000)"));
    }

    let sh = r.table("shape", SHAPE_KEYS)?;
    let mut finger = None;
    let shape = match sh.str("kind")? {
        "straight" => Shape::Straight {
            start: sh.vec2("start")?,
            end: sh.vec2("end")?,
        },
        "points" => {
            let arr = sh.array("points")?.ok_or_else(|| {
                sh.typo_error("points").unwrap_or_else(|| {
                    sh.err_hint(
                        "points",
                        None,
                        "missing required key",
                        "give points = [[x, y], ...], one per node",
                    )
                })
            })?;
            if arr.len() != nodes {
                return Err(sh.err_hint(
                    "points",
                    sh.get("points"),
                    format!("has {} points but the rod has nodes = {nodes}", arr.len()),
                    "give exactly one [x, y] per node",
                ));
            }
            let mut pts = Vec::with_capacity(arr.len());
            for (i, p) in arr.iter().enumerate() {
                pts.push(sh.vec2_value(&format!("points.{i}"), p)?);
            }
            Shape::Points { points: pts }
        }
        "parabola" => {
            let length = sh.positive("length")?;
            Shape::Parabola {
                x0: sh.f64("x0")?,
                y0: sh.f64("y0")?,
                a: sh.f64("a")?,
                length,
            }
        }
        "fin_ray" => {
            let (front, fr) = fin_ray::parse(&sh, read_section)?;
            finger = Some(fr);
            front
        }
        other => {
            let hint =
                match reader::did_you_mean(other, &["straight", "points", "parabola", "fin_ray"]) {
                    Some(m) => format!("did you mean \"{m}\"?"),
                    None => "use \"straight\", \"points\", \"parabola\" or \"fin_ray\"".into(),
                };
            return Err(sh.err_hint(
                "kind",
                sh.get("kind"),
                format!("unknown shape kind {other:?}"),
                hint,
            ));
        }
    };
    sh.finish()?;

    let e = r.positive("E")?;
    let section = read_section(&r.table("section", SECTION_KEYS)?)?;

    if r.has("mass") {
        if let Some(other) = ["density", "node_mass"].into_iter().find(|k| r.has(k)) {
            return Err(r.err_hint(
                "mass",
                r.get("mass"),
                format!("both {other} and mass are given"),
                "keep one: mass (kg, the whole rod, lumped by Voronoi length), density (kg/m³) or node_mass (kg per node)",
            ));
        }
    }
    if finger.is_some() && r.has("mass") {
        return Err(r.err_hint(
            "mass",
            r.get("mass"),
            "a fin_ray finger takes density or node_mass, not a total mass",
            "give density = ... (kg/m³) or node_mass = ... (kg per node)",
        ));
    }
    let mass = if r.has("mass") {
        MassSpec::Total(r.positive("mass")?)
    } else {
        match (r.has("density"), r.has("node_mass")) {
            (true, true) => return Err(r.err_hint(
                "node_mass",
                r.get("node_mass"),
                "both density and node_mass are given",
                "keep one: density (kg/m³, lumped by Voronoi length) or node_mass (kg per node)",
            )),
            (true, false) => MassSpec::Density(r.positive("density")?),
            (false, true) => MassSpec::NodeMass(r.positive("node_mass")?),
            (false, false) => {
                // A misspelt `densty` or `node_mas` is the likelier mistake: name it.
                if let Some(e) = r
                    .typo_error("density")
                    .or_else(|| r.typo_error("node_mass"))
                {
                    return Err(e);
                }
                return Err(r.err_hint(
                    "density",
                    None,
                    "missing required key",
                    "give density = ... (kg/m³), node_mass = ... (kg) or mass = ... (kg, total)",
                ));
            }
        }
    };

    let mut clamped = Vec::new();
    if finger.is_some() && r.has("clamped") {
        return Err(r.err_hint(
            "clamped",
            r.get("clamped"),
            "a fin_ray finger clamps nodes 0 and 1 of both flanks itself",
            "remove `clamped`",
        ));
    }
    if finger.is_some() {
        clamped = vec![0, 1];
    }
    if let Some(arr) = r.array("clamped")? {
        for (i, v) in arr.iter().enumerate() {
            let n = r.usize_value(&format!("clamped.{i}"), v)?;
            if n >= nodes {
                return Err(r.err_hint(
                    &format!("clamped.{i}"),
                    Some(v),
                    format!(
                        "node index out of range (the rod has nodes 0..{})",
                        nodes - 1
                    ),
                    "node indices are 0-based",
                ));
            }
            if clamped.contains(&n) {
                return Err(r.err(&format!("clamped.{i}"), Some(v), "node listed twice"));
            }
            clamped.push(n);
        }
    }
    clamped.sort_unstable();
    if clamped.len() == nodes {
        return Err(r.err(
            "clamped",
            r.get("clamped"),
            "every node is clamped: nothing is left to simulate",
        ));
    }
    // A joined rod may lean on its joints (its set of joined rods is checked as a whole).
    if mode == Mode::Static && clamped.len() < 2 && !joined.contains(&name) {
        return Err(r.err_hint(
            "clamped",
            r.get("clamped"),
            "a static solve needs at least two clamped nodes per rod (a free rod has no equilibrium)",
            "clamp e.g. nodes [0, 1]",
        ));
    }

    let (actuator, mirror) = actuation::parse_rod_keys(r, actuators, !clamped.is_empty())?;
    let drive = match r.opt_table("drive", DRIVE_KEYS)? {
        None => Drive::Fixed,
        Some(d) => {
            // stop_time and stop_travel only belong to the moving kinds.
            let dr = match d.str("kind")? {
                "fixed" => Drive::Fixed,
                "constant_acceleration" => Drive::ConstantAcceleration {
                    acceleration: {
                        let a = d.vec2("acceleration")?;
                        check_magnitude(&d, "acceleration", &a, MAX_ACCELERATION, "m/s²")?;
                        a
                    },
                    stop_time: d.opt_positive("stop_time")?,
                    stop_travel: d.opt_positive("stop_travel")?,
                },
                "constant_velocity" => Drive::ConstantVelocity {
                    velocity: d.vec2("velocity")?,
                    stop_time: d.opt_positive("stop_time")?,
                    stop_travel: d.opt_positive("stop_travel")?,
                },
                other => {
                    let hint = match reader::did_you_mean(
                        other,
                        &["fixed", "constant_acceleration", "constant_velocity"],
                    ) {
                        Some(m) => format!("did you mean \"{m}\"?"),
                        None => "use \"fixed\", \"constant_acceleration\" or \"constant_velocity\""
                            .into(),
                    };
                    return Err(d.err_hint(
                        "kind",
                        d.get("kind"),
                        format!("unknown drive kind {other:?}"),
                        hint,
                    ));
                }
            };
            d.finish()?;
            if dr != Drive::Fixed && clamped.is_empty() {
                return Err(r.err_hint(
                    "drive",
                    r.get("drive"),
                    "a drive moves the clamped nodes, but this rod has none",
                    "list the driven nodes in `clamped`",
                ));
            }
            dr
        }
    };

    let mut loads = Vec::new();
    if let Some(arr) = r.array("loads")? {
        for (i, v) in arr.iter().enumerate() {
            let l = r.table_value(&format!("loads.{i}"), v, &["node", "force"])?;
            let node = l.usize("node")?;
            if node >= nodes {
                return Err(l.err_hint(
                    "node",
                    l.get("node"),
                    format!(
                        "node index out of range (the rod has nodes 0..{})",
                        nodes - 1
                    ),
                    "node indices are 0-based",
                ));
            }
            if clamped.contains(&node) {
                return Err(l.err(
                    "node",
                    l.get("node"),
                    "a load on a clamped node does nothing",
                ));
            }
            let force = l.vec2("force")?;
            check_magnitude(&l, "force", &force, MAX_FORCE, "N")?;
            l.finish()?;
            loads.push(Load { node, force });
        }
    }
    let velocity = r.opt_vec2("velocity")?.unwrap_or([0.0; 2]);
    let nu = match r.opt_f64("nu")? {
        None => 0.5,
        Some(nu) if (0.0..=0.5).contains(&nu) => nu,
        Some(_) => {
            return Err(r.err_hint(
                "nu",
                r.get("nu"),
                "Poisson's ratio must be in [0, 0.5]",
                "an elastomer prong is about 0.5 (the default)",
            ))
        }
    };
    let loss_factor = r.opt_f64("loss_factor")?.unwrap_or(0.0);
    if !(0.0..=10.0).contains(&loss_factor) {
        return Err(r.err_hint(
            "loss_factor",
            r.get("loss_factor"),
            "must be in [0, 10]",
            "the loss factor tan δ of the material at loss_frequency (silicone rubbers ≈ 0.05–0.5)",
        ));
    }
    let loss_frequency = r.opt_positive("loss_frequency")?.unwrap_or(10.0);
    let damping_time = loss_factor / (2.0 * std::f64::consts::PI * loss_frequency);
    r.finish()?;
    let spec = RodSpec {
        name,
        nodes,
        shape,
        youngs_modulus: e,
        section,
        mass,
        clamped,
        drive,
        loads,
        velocity,
        particle: false,
        actuator,
        mirror,
        nu,
        damping_time,
        source: r.key_path("").trim_end_matches('.').to_string(),
    };
    Ok((spec, finger))
}

/// A `section` table (`rect` b, h or `circle` radius).
pub(crate) fn read_section(se: &TableReader) -> Result<Section, ScenarioError> {
    let section = match se.str("kind")? {
        "rect" => Section::Rect {
            b: se.positive("b")?,
            h: se.positive("h")?,
        },
        "circle" => Section::Circle {
            radius: se.positive("radius")?,
        },
        other => {
            let hint = match reader::did_you_mean(other, &["rect", "circle"]) {
                Some(m) => format!("did you mean \"{m}\"?"),
                None => "use \"rect\" (b, h) or \"circle\" (radius)".into(),
            };
            return Err(se.err_hint(
                "kind",
                se.get("kind"),
                format!("unknown section kind {other:?}"),
                hint,
            ));
        }
    };
    se.finish()?;
    Ok(section)
}

/// A `[[particle]]`: a single free node (the seed's bouncing point mass).
fn parse_particle(r: &TableReader, mode: Mode) -> Result<RodSpec, ScenarioError> {
    let name = r.str("name")?.to_string();
    if name.trim().is_empty() {
        return Err(r.err("name", r.get("name"), "must not be empty"));
    }
    if mode == Mode::Static {
        return Err(r.err_hint(
            "name",
            r.get("name"),
            "a particle has no static equilibrium",
            "use mode = \"dynamic\"",
        ));
    }
    let position = r.vec2("position")?;
    let velocity = r.opt_vec2("velocity")?.unwrap_or([0.0; 2]);
    let mass = r.positive("mass")?;
    let force = r.opt_vec2("force")?.unwrap_or([0.0; 2]);
    check_magnitude(r, "force", &force, MAX_FORCE, "N")?;
    r.finish()?;
    Ok(RodSpec {
        name,
        nodes: 1,
        shape: Shape::Points {
            points: vec![position],
        },
        youngs_modulus: 0.0,
        section: Section::Circle { radius: 0.0 },
        mass: MassSpec::NodeMass(mass),
        clamped: vec![],
        drive: Drive::Fixed,
        loads: if force != [0.0; 2] {
            vec![Load { node: 0, force }]
        } else {
            vec![]
        },
        velocity,
        particle: true,
        actuator: None,
        mirror: false,
        nu: 0.5,
        damping_time: 0.0,
        source: r.key_path("").trim_end_matches('.').to_string(),
    })
}

/// `[solve] integrator` (both dimensions): "backward_euler" (default), "bdf2" or "tr_bdf2".
pub(crate) fn parse_integrator(s: &TableReader) -> Result<Integrator, ScenarioError> {
    Ok(match s.opt_str("integrator")?.unwrap_or("backward_euler") {
        "backward_euler" => Integrator::BackwardEuler,
        "bdf2" => Integrator::Bdf2,
        "tr_bdf2" => Integrator::TrBdf2,
        other => {
            let names = ["backward_euler", "bdf2", "tr_bdf2"];
            let hint = match reader::did_you_mean(other, &names) {
                Some(m) => format!("did you mean \"{m}\"?"),
                None => "use \"backward_euler\", \"bdf2\" or \"tr_bdf2\"".into(),
            };
            return Err(s.err_hint(
                "integrator",
                s.get("integrator"),
                format!("unknown integrator {other:?}"),
                hint,
            ));
        }
    })
}
