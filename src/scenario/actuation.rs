//! `[[actuator]]` tables (programs of phases) and the rod keys `actuator` and `mirror`, read
//! into [`crate::actuation::Program`]s with located errors. The legacy `drive` table of a rod
//! becomes a one-phase program ([`Drive::program`]).

use super::reader::{self, ScenarioError, TableReader};
use super::{Drive, Scenario};
use crate::actuation::{Ends, Law, Movement, Phase, Program, Table, Trapezoid, VectorLaw};
use std::path::{Path, PathBuf};
use toml::Value;

/// One `[[actuator]]`: a named program that moves every rod that names it.
#[derive(Debug, Clone, serde::Serialize)]
pub struct ActuatorSpec {
    pub name: String,
    pub program: Program,
}

const ACTUATOR_KEYS: &[&str] = &["name", "mirror_x", "force_filter", "phase"];
/// The default `force_filter` (s): a 5 ms force sensor (32 Hz bandwidth).
pub const DEFAULT_FORCE_FILTER: f64 = 5e-3;
const PHASE_KEYS: &[&str] = &[
    "kind",
    "name",
    "law",
    "direction",
    "pivot",
    "sense",
    "speed",
    "velocity",
    "acceleration",
    "distance",
    "max_speed",
    "duration",
    "points",
    "file",
    "end",
];
const END_KEYS: &[&str] = &["duration", "travel", "width", "grip_force", "grip_torque"];
const KINDS: &[&str] = &["translate", "rotate", "hold"];
const LAWS: &[&str] = &[
    "constant_velocity",
    "constant_acceleration",
    "trapezoid",
    "s_curve",
    "table",
];
/// The keys of the laws' parameters, each used by some laws only.
const LAW_KEYS: &[&str] = &[
    "speed",
    "velocity",
    "acceleration",
    "distance",
    "max_speed",
    "duration",
    "points",
    "file",
];

impl Drive {
    /// The drive as a program: one translation with the same numbers as [`Drive::motion`]
    /// (stopped by `stop_time` / `stop_travel`, then held), or no phase for `fixed`.
    pub fn program(&self) -> Program {
        match *self {
            Drive::Fixed => Program::fixed(),
            Drive::ConstantAcceleration {
                acceleration,
                stop_time,
                stop_travel,
            } => Program::translation(
                VectorLaw::Acceleration(acceleration),
                stop_time,
                stop_travel,
            ),
            Drive::ConstantVelocity {
                velocity,
                stop_time,
                stop_travel,
            } => Program::translation(VectorLaw::Velocity(velocity), stop_time, stop_travel),
        }
    }
}

/// Which program moves each rod. Groups `0..sc.actuators.len()` are the `[[actuator]]`s in
/// order; after them comes one group per rod that has no `actuator` (its `drive`, `fixed` by
/// default), in rod order. Returns the programs and, per rod, `(group, mirror line)` with the
/// mirror line `Some(c)` for a member with `mirror = true`.
pub fn groups(sc: &Scenario) -> (Vec<Program>, Vec<(usize, Option<f64>)>) {
    let mut programs: Vec<Program> = sc.actuators.iter().map(|a| a.program.clone()).collect();
    let mut of_rod = Vec::with_capacity(sc.rods.len());
    for rod in &sc.rods {
        match rod.actuator {
            Some(g) => {
                let mirror = if rod.mirror {
                    programs[g].mirror_x
                } else {
                    None
                };
                of_rod.push((g, mirror));
            }
            None => {
                programs.push(rod.drive.program());
                of_rod.push((programs.len() - 1, None));
            }
        }
    }
    (programs, of_rod)
}

/// The top-level `[[actuator]]` array (empty when there is none).
pub fn parse_actuators(top: &TableReader) -> Result<Vec<ActuatorSpec>, ScenarioError> {
    let arr = match top.get("actuator") {
        None => return Ok(Vec::new()),
        Some(Value::Array(a)) => a,
        Some(other) => {
            return Err(top.err(
                "actuator",
                Some(other),
                "expected an array of [[actuator]] tables",
            ))
        }
    };
    let base = Path::new(top.file).parent().map(Path::to_path_buf);
    let mut out: Vec<ActuatorSpec> = Vec::new();
    for (i, v) in arr.iter().enumerate() {
        let a = top.table_value(&format!("actuator.{i}"), v, ACTUATOR_KEYS)?;
        let spec = parse_actuator(&a, base.as_deref())?;
        if let Some(j) = out.iter().position(|o| o.name == spec.name) {
            return Err(a.err_hint(
                "name",
                a.get("name"),
                format!("duplicate name (actuator.{j} has it already)"),
                "give every actuator its own name",
            ));
        }
        out.push(spec);
    }
    Ok(out)
}

fn parse_actuator(a: &TableReader, base: Option<&Path>) -> Result<ActuatorSpec, ScenarioError> {
    let name = a.str("name")?.to_string();
    if name.trim().is_empty() {
        return Err(a.err("name", a.get("name"), "must not be empty"));
    }
    let mirror_x = a.opt_f64("mirror_x")?;
    let force_filter = match a.opt_f64("force_filter")? {
        None => DEFAULT_FORCE_FILTER,
        Some(v) if v >= 0.0 && v.is_finite() => v,
        Some(_) => {
            return Err(a.err_hint(
                "force_filter",
                a.get("force_filter"),
                "must be a time constant ≥ 0 s",
                "e.g. 0.005 (a 5 ms force sensor), or 0 for the raw per-step reaction",
            ))
        }
    };
    let phases_v = match a.get("phase") {
        Some(Value::Array(p)) if !p.is_empty() => p,
        Some(Value::Array(_)) | None => {
            if let Some(e) = a.typo_error("phase") {
                return Err(e);
            }
            return Err(a.err_hint(
                "phase",
                None,
                "an actuator needs at least one phase",
                "add [[actuator.phase]] tables (kind = \"translate\", \"rotate\" or \"hold\")",
            ));
        }
        Some(other) => {
            return Err(a.err(
                "phase",
                Some(other),
                "expected an array of [[actuator.phase]] tables",
            ))
        }
    };
    let mut phases = Vec::with_capacity(phases_v.len());
    for (k, v) in phases_v.iter().enumerate() {
        let p = a.table_value(&format!("phase.{k}"), v, PHASE_KEYS)?;
        let last = k + 1 == phases_v.len();
        phases.push(parse_phase(&p, base, mirror_x, last)?);
    }
    a.finish()?;
    Ok(ActuatorSpec {
        name,
        program: Program {
            phases,
            mirror_x,
            force_filter,
        },
    })
}

/// What a phase's law keys gave: a scalar law or (translate only) a vector form.
enum ParsedLaw {
    Scalar(Law),
    Vector(VectorLaw),
}

fn parse_phase(
    p: &TableReader,
    base: Option<&Path>,
    mirror_x: Option<f64>,
    last: bool,
) -> Result<Phase, ScenarioError> {
    let kind = p.str("kind")?;
    let name = match p.opt_str("name")? {
        Some(n) if n.trim().is_empty() => {
            return Err(p.err("name", p.get("name"), "must not be empty"))
        }
        n => n.map(str::to_string),
    };
    let movement = match kind {
        "hold" => Movement::Hold,
        "translate" => parse_translate(p, base)?,
        "rotate" => parse_rotate(p, base)?,
        other => return Err(unknown(p, "kind", other, "phase kind", KINDS)),
    };
    let end = parse_end(p, &movement, mirror_x)?;
    check_ends(p, &movement, &end, last)?;
    p.finish()?;
    Ok(Phase::new(name, movement, end))
}

/// An "unknown X" error with a did-you-mean over `choices`.
fn unknown(
    p: &TableReader,
    key: &'static str,
    got: &str,
    what: &str,
    choices: &[&str],
) -> ScenarioError {
    let hint = match reader::did_you_mean(got, choices) {
        Some(m) => format!("did you mean \"{m}\"?"),
        None => format!("use one of: {}", choices.join(", ")),
    };
    p.err_hint(key, p.get(key), format!("unknown {what} {got:?}"), hint)
}

fn parse_translate(p: &TableReader, base: Option<&Path>) -> Result<Movement, ScenarioError> {
    match parse_law(p, base, false)? {
        ParsedLaw::Vector(law) => {
            if p.has("direction") {
                return Err(p.err_hint(
                    "direction",
                    p.get("direction"),
                    "not used with a vector velocity or acceleration",
                    "give either direction with a number (speed, acceleration) or the vector alone",
                ));
            }
            Ok(Movement::TranslateVector { law })
        }
        ParsedLaw::Scalar(law) => {
            let d = p.vec2("direction")?;
            let n = (d[0] * d[0] + d[1] * d[1]).sqrt();
            if n == 0.0 {
                return Err(p.err_hint(
                    "direction",
                    p.get("direction"),
                    "has zero length",
                    "give the direction of motion, e.g. [-1.0, 0.0] (its length does not matter)",
                ));
            }
            Ok(Movement::Translate {
                direction: [d[0] / n, d[1] / n],
                law,
            })
        }
    }
}

fn parse_rotate(p: &TableReader, base: Option<&Path>) -> Result<Movement, ScenarioError> {
    let pivot = p.vec2("pivot")?;
    let sense = match p.opt_str("sense")?.unwrap_or("ccw") {
        "ccw" => 1.0,
        "cw" => -1.0,
        other => return Err(unknown(p, "sense", other, "sense", &["ccw", "cw"])),
    };
    let ParsedLaw::Scalar(law) = parse_law(p, base, true)? else {
        unreachable!("parse_law gives vector forms only for translations")
    };
    Ok(Movement::Rotate { pivot, sense, law })
}

/// The law and its parameters. `rotate`: values are angles (rad) and the vector forms are
/// refused.
fn parse_law(
    p: &TableReader,
    base: Option<&Path>,
    rotate: bool,
) -> Result<ParsedLaw, ScenarioError> {
    let law = p.str("law")?;
    let (parsed, used): (ParsedLaw, &[&str]) = match law {
        "constant_velocity" if p.has("velocity") && !rotate => {
            let v = nonzero_vec(p, "velocity")?;
            (ParsedLaw::Vector(VectorLaw::Velocity(v)), &["velocity"])
        }
        "constant_velocity" => (
            ParsedLaw::Scalar(Law::ConstantVelocity {
                speed: p.positive("speed")?,
            }),
            &["speed"],
        ),
        "constant_acceleration"
            if matches!(p.get("acceleration"), Some(Value::Array(_))) && !rotate =>
        {
            let a = nonzero_vec(p, "acceleration")?;
            (
                ParsedLaw::Vector(VectorLaw::Acceleration(a)),
                &["acceleration"],
            )
        }
        "constant_acceleration" => (
            ParsedLaw::Scalar(Law::ConstantAcceleration {
                acceleration: p.positive("acceleration")?,
            }),
            &["acceleration"],
        ),
        "trapezoid" => (
            ParsedLaw::Scalar(parse_trapezoid(p)?),
            &["distance", "max_speed", "acceleration", "duration"],
        ),
        "s_curve" => (
            ParsedLaw::Scalar(Law::SCurve {
                distance: p.positive("distance")?,
                duration: p.positive("duration")?,
            }),
            &["distance", "duration"],
        ),
        "table" => (
            ParsedLaw::Scalar(parse_table(p, base)?),
            &["points", "file"],
        ),
        other => return Err(unknown(p, "law", other, "law", LAWS)),
    };
    // A parameter of another law is refused here, with the law named.
    for key in LAW_KEYS {
        if p.has(key) && !used.contains(key) {
            let value = p.table.get(*key);
            return Err(p.err_hint(
                key,
                value,
                format!("not used with law = {law:?}"),
                match (rotate, *key) {
                    (true, "velocity") => "a rotation takes `speed` (rad/s)".to_string(),
                    (true, "acceleration") => "a rotation takes a number (rad/s²)".to_string(),
                    _ => "remove it, or change `law`".to_string(),
                },
            ));
        }
    }
    Ok(parsed)
}

/// A vector that must not be zero (its direction is the direction of motion).
fn nonzero_vec(p: &TableReader, key: &'static str) -> Result<[f64; 2], ScenarioError> {
    let v = p.vec2(key)?;
    if v == [0.0, 0.0] {
        return Err(p.err_hint(
            key,
            p.get(key),
            "has zero length",
            "a vector law moves along its vector; use kind = \"hold\" to stay still",
        ));
    }
    Ok(v)
}

fn parse_trapezoid(p: &TableReader) -> Result<Law, ScenarioError> {
    let distance = p.positive("distance")?;
    let by_speed = p.has("max_speed") || p.has("acceleration");
    if by_speed && p.has("duration") {
        return Err(p.err_hint(
            "duration",
            p.get("duration"),
            "both duration and max_speed/acceleration are given",
            "give distance with either max_speed and acceleration, or duration",
        ));
    }
    if by_speed {
        let v = p.positive("max_speed")?;
        let a = p.positive("acceleration")?;
        return Ok(Law::Trapezoid(Trapezoid::from_speed(distance, v, a)));
    }
    if !p.has("duration") {
        return Err(p.err_hint(
            "duration",
            None,
            "missing: a trapezoid needs duration, or max_speed and acceleration",
            "e.g. duration = 0.5 (one third accelerating, one cruising, one decelerating)",
        ));
    }
    let duration = p.positive("duration")?;
    Ok(Law::Trapezoid(Trapezoid::from_duration(distance, duration)))
}

fn parse_table(p: &TableReader, base: Option<&Path>) -> Result<Law, ScenarioError> {
    match (p.has("points"), p.has("file")) {
        (true, true) => Err(p.err_hint(
            "file",
            p.get("file"),
            "both points and file are given",
            "keep one: points = [[t, value], ...] or file = \"profile.csv\"",
        )),
        (false, false) => Err(p.err_hint(
            "points",
            None,
            "missing: a table needs points or file",
            "give points = [[0.0, 0.0], [0.1, 0.005], ...] or file = \"profile.csv\" (columns t, value)",
        )),
        (true, false) => {
            let arr = p.array("points")?.expect("has points");
            let mut pts = Vec::with_capacity(arr.len());
            for (i, v) in arr.iter().enumerate() {
                pts.push(p.vec2_value(&format!("points.{i}"), v)?);
            }
            Table::new(&pts).map(Law::Table).map_err(|e| {
                let key = format!("points.{}", e.index);
                let value = arr.get(e.index).unwrap_or(&Value::Array(vec![])).clone();
                p.err_hint(&key, Some(&value), e.message, "times start at 0 and increase strictly")
            })
        }
        (false, true) => {
            let name = p.str("file")?;
            let path = match base {
                Some(b) => b.join(name),
                None => PathBuf::from(name),
            };
            let (pts, lines) = read_profile(&path).map_err(|m| {
                p.err_hint("file", p.get("file"), m, "two columns t, value; a header line is allowed")
            })?;
            Table::new(&pts).map(Law::Table).map_err(|e| {
                p.err_hint(
                    "file",
                    p.get("file"),
                    format!("{}, line {}: {}", path.display(), lines[e.index], e.message),
                    "times start at 0 and increase strictly",
                )
            })
        }
    }
}

/// A two-column CSV profile (t, value): the points and their line numbers. One header line
/// (whose first field is not a number) is skipped; blank lines and `#` comments too.
fn read_profile(path: &Path) -> Result<(Vec<[f64; 2]>, Vec<usize>), String> {
    let text = super::input::read_referenced(path, "profile")?;
    let (mut pts, mut lines) = (Vec::new(), Vec::new());
    let mut header_allowed = true;
    for (i, line) in text.lines().enumerate() {
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let nums: Vec<Option<f64>> = line.split(',').map(|f| f.trim().parse().ok()).collect();
        if std::mem::take(&mut header_allowed) && nums[0].is_none() {
            continue;
        }
        match nums.as_slice() {
            [Some(t), Some(s)] => {
                pts.push([*t, *s]);
                lines.push(i + 1);
            }
            _ => {
                return Err(format!(
                    "{}, line {}: expected two numbers `t, value`, found {line:?}",
                    path.display(),
                    i + 1,
                ))
            }
        }
    }
    if pts.is_empty() {
        return Err(format!("{}: no data rows", path.display()));
    }
    Ok((pts, lines))
}

fn parse_end(
    p: &TableReader,
    movement: &Movement,
    mirror_x: Option<f64>,
) -> Result<Ends, ScenarioError> {
    let Some(e) = p.opt_table("end", END_KEYS)? else {
        return Ok(Ends::default());
    };
    let end = Ends {
        duration: e.opt_positive("duration")?,
        travel: e.opt_positive("travel")?,
        width: e.opt_positive("width")?,
        grip_force: e.opt_positive("grip_force")?,
        grip_torque: e.opt_positive("grip_torque")?,
    };
    e.finish()?;
    let refuse =
        |key: &'static str, msg: &str, hint: &str| Err(e.err_hint(key, e.get(key), msg, hint));
    match movement {
        Movement::Hold => {
            for key in ["travel", "width", "grip_force", "grip_torque"] {
                if e.has(key) {
                    return refuse(
                        key,
                        "a hold does not move: only `duration` ends it",
                        "remove it",
                    );
                }
            }
        }
        Movement::Rotate { .. } if e.has("grip_force") => {
            return refuse(
                "grip_force",
                "not used in a rotate phase",
                "a rotation ends on grip_torque (N·m, about the pivot)",
            )
        }
        Movement::Translate { .. } | Movement::TranslateVector { .. } if e.has("grip_torque") => {
            return refuse(
                "grip_torque",
                "not used in a translate phase",
                "a translation ends on grip_force (N, along its direction)",
            )
        }
        _ => {}
    }
    if end.width.is_some() && mirror_x.is_none() {
        return refuse(
            "width",
            "needs the actuator's mirror_x (the width is measured across the mirror line)",
            "add mirror_x = <x of the mirror line> to the [[actuator]]",
        );
    }
    Ok(end)
}

/// Every phase must end, except a final hold; a force-controlled phase needs a safety limit.
fn check_ends(
    p: &TableReader,
    movement: &Movement,
    end: &Ends,
    last: bool,
) -> Result<(), ScenarioError> {
    let profile = match movement {
        Movement::Translate { law, .. } | Movement::Rotate { law, .. } => {
            law.profile_end().is_some()
        }
        _ => false,
    };
    let limit = end.duration.is_some() || end.travel.is_some() || profile;
    let grip = end.grip_force.is_some() || end.grip_torque.is_some();
    if grip && !limit {
        let key = if end.grip_force.is_some() {
            "grip_force"
        } else {
            "grip_torque"
        };
        let value = p.table.get("end").and_then(|t| t.get(key));
        return Err(p.err_hint(
            &format!("end.{key}"),
            value,
            "has no safety limit: if the grip is never reached the phase would never end",
            "add duration or travel to `end` (the run stops with an error if that limit comes first), or use a profiled law",
        ));
    }
    let ends = limit || grip || end.width.is_some();
    let hold = matches!(movement, Movement::Hold);
    if !(ends || hold && last) {
        let what = match movement {
            Movement::Hold => "a hold that is not the last phase".to_string(),
            Movement::Translate { law, .. } | Movement::Rotate { law, .. } => {
                format!("law {:?} has no end of its own", law.name())
            }
            Movement::TranslateVector { .. } => "a vector law has no end of its own".to_string(),
        };
        let value = p.get("end");
        return Err(p.err_hint(
            "end",
            value,
            format!("the phase never ends ({what}, and `end` gives no condition)"),
            "add end = { duration = ... } or { travel = ... } (only a final hold may last forever)",
        ));
    }
    Ok(())
}

/// The rod keys `actuator` (a name) and `mirror`: the actuator's index and the flag.
pub fn parse_rod_keys(
    r: &TableReader,
    actuators: &[ActuatorSpec],
    has_clamped: bool,
) -> Result<(Option<usize>, bool), ScenarioError> {
    let mirror = r.opt_bool("mirror")?.unwrap_or(false);
    let Some(name) = r.opt_str("actuator")? else {
        if mirror {
            return Err(r.err_hint(
                "mirror",
                r.get("mirror"),
                "mirror = true needs `actuator`",
                "name the [[actuator]] whose motion this rod mirrors",
            ));
        }
        return Ok((None, false));
    };
    let value = r.get("actuator");
    if r.has("drive") {
        return Err(r.err_hint(
            "actuator",
            value,
            "a rod with `actuator` may not also have `drive`",
            "remove `drive`: the actuator's program moves the clamped nodes",
        ));
    }
    let Some(idx) = actuators.iter().position(|a| a.name == name) else {
        let names: Vec<&str> = actuators.iter().map(|a| a.name.as_str()).collect();
        let hint = match reader::did_you_mean(name, &names) {
            Some(m) => format!("did you mean \"{m}\"?"),
            None if names.is_empty() => "no [[actuator]] is defined".to_string(),
            None => format!("known actuators: {}", names.join(", ")),
        };
        return Err(r.err_hint(
            "actuator",
            value,
            format!("unknown actuator {name:?}"),
            hint,
        ));
    };
    if !has_clamped {
        return Err(r.err_hint(
            "actuator",
            value,
            "an actuator moves the clamped nodes, but this rod has none",
            "list the driven nodes in `clamped`",
        ));
    }
    if mirror && actuators[idx].program.mirror_x.is_none() {
        return Err(r.err_hint(
            "mirror",
            r.get("mirror"),
            format!("actuator {name:?} has no mirror_x"),
            "add mirror_x = <x of the mirror line> to the [[actuator]]",
        ));
    }
    Ok((Some(idx), mirror))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::actuation::phase::{DURATION, GRIP_FORCE, PROFILE_COMPLETE, TRAVEL};
    use crate::actuation::{Actuator, Measure, Motion, Pose};

    /// Every drive of the shipped scenarios, and mixed ones with both stops.
    fn drives() -> Vec<Drive> {
        let acc = |a, st, sl| Drive::ConstantAcceleration {
            acceleration: a,
            stop_time: st,
            stop_travel: sl,
        };
        let vel = |v, st, sl| Drive::ConstantVelocity {
            velocity: v,
            stop_time: st,
            stop_travel: sl,
        };
        vec![
            Drive::Fixed,
            acc([-9.8, 0.0], None, None),
            acc([9.8, 0.0], None, None),
            acc([-9.8, 0.0], None, Some(0.007)),
            vel([0.0, -0.01], Some(0.001), None),
            acc([3.0, -4.0], Some(0.05), Some(0.002)),
            acc([3.0, -4.0], Some(0.01), Some(0.002)),
            acc([0.0, 0.0], None, Some(0.002)),
            vel([0.3, 0.4], None, Some(0.05)),
            vel([-0.3, 0.7], Some(0.1), Some(0.05)),
        ]
    }

    /// The stop time Drive::motion uses, recomputed the same way.
    fn stop_time(d: &Drive) -> Option<f64> {
        let (w, st, sl, accel) = match *d {
            Drive::Fixed => return None,
            Drive::ConstantAcceleration {
                acceleration,
                stop_time,
                stop_travel,
            } => (acceleration, stop_time, stop_travel, true),
            Drive::ConstantVelocity {
                velocity,
                stop_time,
                stop_travel,
            } => (velocity, stop_time, stop_travel, false),
        };
        let mag = (w[0] * w[0] + w[1] * w[1]).sqrt();
        let mut t = st.unwrap_or(f64::INFINITY);
        if let (Some(l), true) = (sl, mag > 0.0) {
            t = t.min(if accel {
                (2.0 * l / mag).sqrt()
            } else {
                l / mag
            });
        }
        t.is_finite().then_some(t)
    }

    #[test]
    fn drive_programs_reproduce_drive_motion_bit_for_bit() {
        let x0 = [0.009, -0.0133];
        for d in drives() {
            let mut act = Actuator::new(d.program(), [0.0; 2]);
            let mut times: Vec<f64> = (0..3000).map(|i| i as f64 * 1.7e-5).collect();
            times.extend((0..200).map(|i| i as f64 * 1e-3));
            if let Some(ts) = stop_time(&d) {
                times.extend([ts, ts * (1.0 - 1e-15), ts * (1.0 + 1e-15), ts + 1e-9]);
            }
            times.sort_by(f64::total_cmp);
            for &t in &times {
                let (disp, vel) = d.motion(t);
                let m = act.motion(t);
                assert_eq!(m.pose.d, disp, "{d:?} t = {t}");
                assert_eq!(m.pose.theta, 0.0);
                assert_eq!(m.velocity_of(x0, None), vel, "{d:?} t = {t}");
                assert_eq!(
                    m.position_of(x0, None),
                    [x0[0] + disp[0], x0[1] + disp[1]],
                    "{d:?} t = {t}"
                );
                // Committing (as the solver does after each step) changes none of it.
                act.commit(t, &Measure::default()).unwrap();
                assert_eq!(act.motion(t), m, "{d:?} t = {t} after commit");
            }
        }
    }

    const BASE: &str = r#"
name = "pick"
[solve]
t_end = 1.0
dt = 0.001
[[rod]]
name = "right"
nodes = 5
E = 1e6
density = 1000.0
clamped = [0, 1]
shape = { kind = "straight", start = [0.0, 0.0], end = [0.0, -0.1] }
section = { kind = "rect", b = 0.02, h = 0.01 }
actuator = "gripper"
[[rod]]
name = "left"
nodes = 5
E = 1e6
density = 1000.0
clamped = [0, 1]
shape = { kind = "straight", start = [-0.1, 0.0], end = [-0.1, -0.1] }
section = { kind = "rect", b = 0.02, h = 0.01 }
actuator = "gripper"
mirror = true
[[rod]]
name = "seed"
nodes = 5
E = 1e6
density = 1000.0
clamped = [0]
shape = { kind = "straight", start = [0.3, 0.0], end = [0.3, -0.1] }
section = { kind = "rect", b = 0.02, h = 0.01 }
drive = { kind = "constant_velocity", velocity = [0.0, -0.01], stop_time = 0.5 }

[[actuator]]
name = "gripper"
mirror_x = -0.05

[[actuator.phase]]
name = "close"
kind = "translate"
direction = [-2.0, 0.0]
law = "constant_velocity"
speed = 0.05
end = { grip_force = 4.0, travel = 0.03 }

[[actuator.phase]]
name = "hold"
kind = "hold"
end = { duration = 0.1 }

[[actuator.phase]]
name = "lift"
kind = "translate"
direction = [0.0, 1.0]
law = "s_curve"
distance = 0.05
duration = 0.4

[[actuator.phase]]
name = "transport"
kind = "translate"
direction = [3.0, 4.0]
law = "trapezoid"
distance = 0.1
max_speed = 0.2
acceleration = 1.0

[[actuator.phase]]
name = "place"
kind = "translate"
direction = [0.0, -1.0]
law = "table"
points = [[0.0, 0.0], [0.1, 0.02], [0.3, 0.05]]

[[actuator.phase]]
name = "open"
kind = "rotate"
pivot = [0.0, 0.0]
sense = "cw"
law = "constant_acceleration"
acceleration = 2.0
end = { travel = 0.2, width = 0.3 }
"#;

    #[test]
    fn a_full_pick_and_place_program_parses() {
        let sc = Scenario::from_str(BASE, "pick.toml", &[]).unwrap();
        assert_eq!(sc.actuators.len(), 1);
        let p = &sc.actuators[0].program;
        assert_eq!(p.mirror_x, Some(-0.05));
        let names: Vec<&str> = p
            .phases
            .iter()
            .map(|ph| ph.name.as_deref().unwrap())
            .collect();
        assert_eq!(
            names,
            ["close", "hold", "lift", "transport", "place", "open"]
        );
        let ph = &p.phases;
        assert_eq!(
            ph[0].movement,
            Movement::Translate {
                direction: [-1.0, 0.0],
                law: Law::ConstantVelocity { speed: 0.05 }
            }
        );
        assert_eq!(
            (ph[0].end.grip_force, ph[0].end.travel),
            (Some(4.0), Some(0.03))
        );
        assert_eq!(ph[0].analytic_end(), Some((0.03 / 0.05, TRAVEL)));
        assert_eq!(ph[1].analytic_end(), Some((0.1, DURATION)));
        assert_eq!(ph[2].analytic_end(), Some((0.4, PROFILE_COMPLETE)));
        let Movement::Translate {
            direction,
            law: Law::Trapezoid(tr),
        } = &ph[3].movement
        else {
            panic!("{:?}", ph[3].movement)
        };
        assert_eq!(*direction, [0.6, 0.8]);
        // V²/A = 0.04 < 0.1: cruise; T = V/A + D/V = 0.2 + 0.5.
        assert!((tr.duration - 0.7).abs() < 1e-15);
        assert_eq!(ph[4].analytic_end(), Some((0.3, PROFILE_COMPLETE)));
        let Movement::Rotate { pivot, sense, .. } = &ph[5].movement else {
            panic!()
        };
        assert_eq!((*pivot, *sense), ([0.0, 0.0], -1.0));
        assert_eq!(ph[5].end.width, Some(0.3));
        // Rods: two members (one mirrored), one legacy drive.
        let r = &sc.rods;
        assert_eq!((r[0].actuator, r[0].mirror), (Some(0), false));
        assert_eq!((r[1].actuator, r[1].mirror), (Some(0), true));
        assert_eq!((r[2].actuator, r[2].mirror), (None, false));
        assert_eq!(r[0].drive, Drive::Fixed);
        let (programs, of_rod) = groups(&sc);
        assert_eq!(programs.len(), 2);
        assert_eq!(of_rod, vec![(0, None), (0, Some(-0.05)), (1, None)]);
        assert_eq!(programs[1], r[2].drive.program());
    }

    #[test]
    fn the_parsed_program_runs_close_hold_lift() {
        let sc = Scenario::from_str(BASE, "pick.toml", &[]).unwrap();
        let mut act = Actuator::new(sc.actuators[0].program.clone(), [0.0, 0.0]);
        let squeeze = |f: f64| Measure {
            drive_force: [-f, 0.0],
            drive_torque: 0.0,
        };
        assert!(act.commit(0.1, &squeeze(1.0)).unwrap().is_empty());
        let sw = act.commit(0.2, &squeeze(4.5)).unwrap();
        assert_eq!(
            (sw[0].t, sw[0].reason, sw[0].to),
            (0.2, GRIP_FORCE, Some(1))
        );
        let closed = act.motion(0.2).pose;
        assert_eq!(
            closed,
            Pose {
                theta: 0.0,
                d: [-(0.05 * 0.2), 0.0]
            }
        );
        // Hold 0.1 s, then the lift: at its middle (0.2 s in) half the distance, up.
        let m = act.motion(0.2 + 0.1 + 0.2);
        assert!((m.pose.d[1] - 0.025).abs() < 1e-16 && m.pose.d[0] == closed.d[0]);
        // The mirrored member moves the other way in x, the same in y.
        let right = m.position_of([0.0, 0.0], None);
        let left = m.position_of([-0.1, 0.0], Some(-0.05));
        assert!((right[0] + left[0] + 0.1).abs() < 1e-17 && right[1] == left[1]);
        let sw = act.commit(0.75, &Measure::default()).unwrap();
        let reasons: Vec<&str> = sw.iter().map(|s| s.reason).collect();
        assert_eq!(reasons, [DURATION, PROFILE_COMPLETE]);
        assert_eq!(act.current_phase(), Some(3));
        // The transport starts from the lifted pose exactly.
        let lifted = Pose {
            theta: 0.0,
            d: [closed.d[0], 0.05],
        };
        assert_eq!(
            act.motion(sw[1].t),
            Motion {
                pose: lifted,
                ..act.motion(sw[1].t)
            }
        );
        assert_eq!(act.motion(sw[1].t).v, [0.0; 2]);
    }

    #[test]
    fn a_table_from_a_csv_file_beside_the_scenario() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(
            dir.path().join("profile.csv"),
            "t,angle\n# comment\n0.0, 0.0\n0.5, 0.25\n\n1.0, 0.3\n",
        )
        .unwrap();
        let text = BASE.replace(
            "points = [[0.0, 0.0], [0.1, 0.02], [0.3, 0.05]]",
            "file = \"profile.csv\"",
        );
        let file = dir.path().join("s.toml").display().to_string();
        let sc = Scenario::from_str(&text, &file, &[]).unwrap();
        let Movement::Translate { law, .. } = &sc.actuators[0].program.phases[4].movement else {
            panic!()
        };
        let Law::Table(tb) = law else {
            panic!("{law:?}")
        };
        let pts: Vec<(f64, f64)> = tb.points().collect();
        assert_eq!(pts, vec![(0.0, 0.0), (0.5, 0.25), (1.0, 0.3)]);
        // A bad row is named with its line.
        std::fs::write(
            dir.path().join("profile.csv"),
            "0.0,0.0\n0.5,0.25\n0.4,0.3\n",
        )
        .unwrap();
        let e = Scenario::from_str(&text, &file, &[]).unwrap_err();
        assert_eq!(e.key, "actuator.0.phase.4.file");
        assert!(
            e.message.contains("line 3: times must increase strictly"),
            "{}",
            e.message
        );
    }

    /// The example of docs/scenario-format.md parses, with the phases it describes.
    #[test]
    fn the_documented_example_is_valid() {
        let doc = std::fs::read_to_string(
            Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/scenario-format.md"),
        )
        .unwrap();
        let from = doc.find("### Example: a two-prong gripper").unwrap();
        let block = &doc[from..];
        let start = block.find("```toml\n").unwrap() + 8;
        let block = &block[start..];
        let block = &block[..block.find("```").unwrap()];
        let head = "name = \"doc\"\n[solve]\nt_end = 1.0\ndt = 1e-4\n";
        let sc = Scenario::from_str(&format!("{head}{block}"), "doc.toml", &[]).unwrap();
        let p = &sc.actuators[0].program;
        let names: Vec<&str> = p
            .phases
            .iter()
            .map(|ph| ph.name.as_deref().unwrap())
            .collect();
        assert_eq!(names, ["close", "hold", "lift", "open"]);
        assert_eq!(p.phases[0].end.grip_force, Some(2.0));
        assert_eq!(groups(&sc).1, vec![(0, None), (0, Some(-0.05))]);
    }
}
