//! The state machine that runs a program: which phase is current, since when, from which pose.

use super::phase::{Movement, Phase, Program, GRIP_FORCE, GRIP_TORQUE, PROFILE_COMPLETE, WIDTH};
use super::{Measure, Motion, Pose};

/// A phase change, as [`Actuator::commit`] reports it.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct PhaseSwitch {
    /// When the phase ended (an analytic end may lie inside the last step).
    pub t: f64,
    /// The phase that ended.
    pub from: usize,
    /// The phase that starts (None after the last: the gripper then holds its pose).
    pub to: Option<usize>,
    /// "duration", "travel", "profile complete", "width", "grip_force" or "grip_torque".
    pub reason: &'static str,
}

/// A force-controlled phase whose safety limit came before its grip force (or torque).
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct GripUnreached {
    /// The phase (0-based, as in the key path `actuator.N.phase.K`) and its name.
    pub phase: usize,
    pub name: Option<String>,
    /// "grip_force" (N) or "grip_torque" (N·m), and its value.
    pub quantity: &'static str,
    pub target: f64,
    /// The largest grip measured in the phase (None if no step ended inside it).
    pub peak: Option<f64>,
    /// The limit that ended the phase ("duration", "travel", "profile complete"), its value
    /// (s; m or rad; s for a profile) and when it was reached.
    pub limit: &'static str,
    pub limit_value: f64,
    pub t: f64,
}

impl std::fmt::Display for GripUnreached {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let rotate = self.quantity == GRIP_TORQUE;
        let unit = if rotate { "N·m" } else { "N" };
        let name = match &self.name {
            Some(n) => format!(" '{n}'"),
            None => String::new(),
        };
        write!(f, "phase {}{name} ", self.phase)?;
        match self.limit {
            PROFILE_COMPLETE => write!(f, "completed its profile ({} s)", short(self.limit_value))?,
            limit => {
                let lu = match limit {
                    super::phase::TRAVEL if rotate => "rad",
                    super::phase::TRAVEL => "m",
                    _ => "s",
                };
                write!(
                    f,
                    "reached its {limit} limit {} {lu}",
                    short(self.limit_value)
                )?
            }
        }
        write!(
            f,
            " at t = {} s before {} = {} {unit}",
            short(self.t),
            self.quantity,
            self.target
        )?;
        match self.peak {
            Some(p) => write!(f, " (peak {} {unit})", short(p)),
            None => write!(f, " (no step ended inside the phase)"),
        }
    }
}

impl std::error::Error for GripUnreached {}

/// x to 4 significant digits, written shortest (3.2, 0.0001235, 1.5e20).
fn short(x: f64) -> String {
    let r: f64 = format!("{x:.3e}").parse().unwrap_or(x);
    format!("{r}")
}

/// Runs a [`Program`]. The committed state (current phase, its start time and start pose)
/// changes only in [`Actuator::commit`]; [`Actuator::motion`] is pure.
#[derive(Debug, Clone)]
pub struct Actuator {
    program: Program,
    centroid0: [f64; 2],
    /// Current phase (== phases.len() once the program is done).
    phase: usize,
    start_t: f64,
    start: Pose,
    /// Largest grip measured in the current phase.
    peak: Option<f64>,
    /// The drive's reaction as the force sensor sees it (low-passed with the program's
    /// `force_filter`), and when it was last updated.
    sensed: Option<(f64, Measure)>,
}

/// Adaptive steps per force-sensor time constant while a phase ends on the sensed grip
/// ([`Actuator::grip_end_resolution`]).
pub const SENSOR_STEPS: f64 = 50.0;

/// The part of a grip end's target the sensed grip must have reached before the steps are
/// held to the sensor's resolution ([`Actuator::grip_end_resolution`]).
pub const GRIP_ONSET: f64 = 0.25;

impl Actuator {
    /// `clamp_centroid0`: the centroid of the group's clamped nodes at t = 0 in the program's
    /// frame ([`super::clamp_centroid`]); only `width` ends use it. The program starts at t = 0.
    pub fn new(program: Program, clamp_centroid0: [f64; 2]) -> Actuator {
        Actuator {
            program,
            centroid0: clamp_centroid0,
            phase: 0,
            start_t: 0.0,
            start: Pose::IDENTITY,
            peak: None,
            sensed: None,
        }
    }

    /// The reaction measured at t through the force sensor: a first-order low-pass with time
    /// constant `force_filter` (exact for a reaction held constant over the step), started at
    /// the first measure; the raw measure when the constant is 0.
    fn sense(&mut self, t: f64, m: &Measure) -> Measure {
        let tau = self.program.force_filter;
        let out = match self.sensed {
            Some((t0, f)) if tau > 0.0 => {
                let w = -(-(t - t0).max(0.0) / tau).exp_m1();
                Measure {
                    drive_force: [
                        f.drive_force[0] + w * (m.drive_force[0] - f.drive_force[0]),
                        f.drive_force[1] + w * (m.drive_force[1] - f.drive_force[1]),
                    ],
                    drive_torque: f.drive_torque + w * (m.drive_torque - f.drive_torque),
                }
            }
            _ => *m,
        };
        self.sensed = Some((t, out));
        out
    }

    pub fn program(&self) -> &Program {
        &self.program
    }

    /// The mirror line x = c for members with `mirror = true`.
    pub fn mirror_x(&self) -> Option<f64> {
        self.program.mirror_x
    }

    /// The committed phase (None once the program is done and the gripper holds).
    pub fn current_phase(&self) -> Option<usize> {
        (self.phase < self.program.phases.len()).then_some(self.phase)
    }

    /// The phase active at t, its start time and start pose: from the committed phase,
    /// through every analytic end ≤ t.
    fn state_at(&self, t: f64) -> (usize, f64, Pose) {
        let (mut k, mut t0, mut pose) = (self.phase, self.start_t, self.start);
        while let Some(ph) = self.program.phases.get(k) {
            match ph.analytic_end() {
                Some((tau, _)) if t >= t0 + tau => {
                    pose = ph.end_pose(&pose);
                    t0 += tau;
                    k += 1;
                }
                _ => break,
            }
        }
        (k, t0, pose)
    }

    /// The gripper's pose and rate at time t (≥ the last commit). Pure: call it for trial
    /// steps freely.
    pub fn motion(&self, t: f64) -> Motion {
        let (k, t0, pose) = self.state_at(t);
        match self.program.phases.get(k) {
            Some(ph) => ph.motion(&pose, t - t0),
            None => Motion::at_rest(pose),
        }
    }

    /// The pivot's world point (program frame) if the phase active at t is a rotation: the
    /// solver takes [`Measure::drive_torque`] about it.
    pub fn pivot_world(&self, t: f64) -> Option<[f64; 2]> {
        let (k, _, pose) = self.state_at(t);
        self.program.phases.get(k)?.pivot_world(&pose)
    }

    /// The first analytic phase end strictly after t, if any (a solver may shorten a step to
    /// land on it; it does not have to).
    pub fn next_end_after(&self, t: f64) -> Option<f64> {
        let (k, t0, _) = self.state_at(t);
        let (tau, _) = self.program.phases.get(k)?.analytic_end()?;
        Some(t0 + tau)
    }

    /// While the committed phase ends on the sensed grip (force or torque) through a sensor
    /// of time constant τ (`force_filter` > 0): the longest step that resolves that end,
    /// τ / [`SENSOR_STEPS`]. The end is seen at a step's end and the squeeze goes on to it,
    /// so the grip it ends on would follow the step length (adaptive BDF2 and TR-BDF2 ended
    /// jaw-grasp-hold's squeeze 9–11 % weak). Before the sensed grip has reached
    /// [`GRIP_ONSET`] of its target (the approach) the steps are free.
    pub fn grip_end_resolution(&self) -> Option<f64> {
        let ph = self.program.phases.get(self.phase)?;
        let tau = self.program.force_filter;
        let target = ph.end.grip_force.or(ph.end.grip_torque)?;
        let near = self.peak.is_some_and(|p| p >= GRIP_ONSET * target);
        (tau > 0.0 && near).then_some(tau / SENSOR_STEPS)
    }

    /// The closing width at pose `pose`: 2 |x of the transformed clamp centroid − c|.
    pub fn width(&self, pose: &Pose) -> Option<f64> {
        let c = self.program.mirror_x?;
        Some(2.0 * (pose.apply(self.centroid0)[0] - c).abs())
    }

    /// After an accepted step ending at t, with the drive's reaction measured at t: passes
    /// the analytic ends ≤ t, then ends the current phase if its width or grip condition is
    /// met. Returns the switches in order (empty, without allocating, when nothing changed),
    /// or the error of a force-controlled phase whose safety limit came first (the run should
    /// stop; the actuator is left at that phase).
    pub fn commit(&mut self, t: f64, m: &Measure) -> Result<Vec<PhaseSwitch>, GripUnreached> {
        let m = &self.sense(t, m);
        let mut out = Vec::new();
        while self.phase < self.program.phases.len() {
            let analytic = self.program.phases[self.phase]
                .analytic_end()
                .map(|(tau, r)| (self.start_t + tau, tau, r));
            // The measure at t belongs to this phase if the phase was under way just before t
            // and had not ended before t.
            let ours = self.start_t < t && analytic.is_none_or(|(te, _, _)| te >= t);
            let measured = if ours { self.measured_end(t, m) } else { None };
            match analytic {
                Some((te, tau, reason)) if te <= t => {
                    let reason = match measured {
                        Some(r) => r,
                        None => {
                            self.check_grip(te, tau, reason)?;
                            reason
                        }
                    };
                    let pose = self.program.phases[self.phase].end_pose(&self.start);
                    self.advance(te, pose, reason, &mut out);
                }
                _ => {
                    if let Some(reason) = measured {
                        let ph = &self.program.phases[self.phase];
                        let pose = ph.motion(&self.start, t - self.start_t).pose;
                        self.advance(t, pose, reason, &mut out);
                    }
                    break;
                }
            }
        }
        Ok(out)
    }

    /// The current phase's measured end at t, if met; records the peak grip.
    fn measured_end(&mut self, t: f64, m: &Measure) -> Option<&'static str> {
        let ph = &self.program.phases[self.phase];
        let g = ph.grip(m);
        if let Some(g) = g {
            if self.peak.is_none_or(|p| g > p) {
                self.peak = Some(g);
            }
        }
        let reached = |target: Option<f64>| matches!((g, target), (Some(g), Some(v)) if g >= v);
        if reached(ph.end.grip_force) {
            return Some(GRIP_FORCE);
        }
        if reached(ph.end.grip_torque) {
            return Some(GRIP_TORQUE);
        }
        if let Some(w) = ph.end.width {
            let te = ph.analytic_end().map_or(f64::INFINITY, |(tau, _)| tau);
            let pose = ph.motion(&self.start, (t - self.start_t).min(te)).pose;
            if self.width(&pose).is_some_and(|x| x <= w) {
                return Some(WIDTH);
            }
        }
        None
    }

    /// The error when the current phase is force-controlled and its limit came first.
    fn check_grip(&self, te: f64, tau: f64, limit: &'static str) -> Result<(), GripUnreached> {
        let ph: &Phase = &self.program.phases[self.phase];
        let (quantity, target) = match (ph.end.grip_force, ph.end.grip_torque) {
            (Some(f), _) => (GRIP_FORCE, f),
            (None, Some(tq)) => (GRIP_TORQUE, tq),
            (None, None) => return Ok(()),
        };
        let limit_value = match limit {
            super::phase::DURATION => ph.end.duration.unwrap_or(tau),
            super::phase::TRAVEL => ph.end.travel.unwrap_or(tau),
            _ => tau,
        };
        Err(GripUnreached {
            phase: self.phase,
            name: ph.name.clone(),
            quantity,
            target,
            peak: self.peak,
            limit,
            limit_value,
            t: te,
        })
    }

    fn advance(&mut self, t: f64, pose: Pose, reason: &'static str, out: &mut Vec<PhaseSwitch>) {
        let from = self.phase;
        self.phase += 1;
        self.start_t = t;
        self.start = pose;
        self.peak = None;
        let n = self.program.phases.len();
        out.push(PhaseSwitch {
            t,
            from,
            to: (self.phase < n).then_some(self.phase),
            reason,
        });
    }

    /// Whether the phase active at t rotates (for callers that only measure torque then).
    pub fn rotating_at(&self, t: f64) -> bool {
        let (k, _, _) = self.state_at(t);
        matches!(
            self.program.phases.get(k).map(|p| &p.movement),
            Some(Movement::Rotate { .. })
        )
    }
}
