//! Phases and programs: what a phase moves, by which law, and when it ends.

use super::law::Law;
use super::{rotate, Measure, Motion, Pose};

/// End reasons, as [`super::PhaseSwitch::reason`] reports them.
pub const DURATION: &str = "duration";
pub const TRAVEL: &str = "travel";
pub const PROFILE_COMPLETE: &str = "profile complete";
pub const WIDTH: &str = "width";
pub const GRIP_FORCE: &str = "grip_force";
pub const GRIP_TORQUE: &str = "grip_torque";

/// The vector forms of a translation (the seed's drives): every component has its own rate.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum VectorLaw {
    /// d = v τ.
    Velocity([f64; 2]),
    /// From rest: d = ½ a τ² (per component, as the seed's `constant_acceleration` drive).
    Acceleration([f64; 2]),
}

impl VectorLaw {
    fn vector(&self) -> [f64; 2] {
        match *self {
            VectorLaw::Velocity(v) | VectorLaw::Acceleration(v) => v,
        }
    }
}

/// What a phase moves.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Movement {
    /// The pose stays.
    Hold,
    /// d += s(τ) · direction (a unit vector, world frame).
    Translate { direction: [f64; 2], law: Law },
    /// d += a vector law's displacement.
    TranslateVector { law: VectorLaw },
    /// Rotation by φ = sense · s(τ) about the pivot, given in the gripper's initial frame: its
    /// world point at the phase's start stays fixed during the phase. `sense` is +1
    /// (counter-clockwise) or −1.
    Rotate {
        pivot: [f64; 2],
        sense: f64,
        law: Law,
    },
}

/// End conditions; the first reached ends the phase.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize)]
pub struct Ends {
    /// s after the phase's start (analytic).
    pub duration: Option<f64>,
    /// m along the direction, or rad for a rotation (analytic).
    pub travel: Option<f64>,
    /// Closing width ≤ value, m (measured after each step; needs a mirror line).
    pub width: Option<f64>,
    /// Drive force along the direction ≥ value, N (measured; translate phases).
    pub grip_force: Option<f64>,
    /// Drive torque about the pivot, in the rotation's sense, ≥ value, N·m (measured;
    /// rotate phases).
    pub grip_torque: Option<f64>,
}

/// One phase of a program.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Phase {
    pub name: Option<String>,
    pub movement: Movement,
    pub end: Ends,
    /// When the phase ends by itself (τ after its start) and why: the earliest of duration,
    /// travel and the profile's completion.
    #[serde(skip)]
    analytic: Option<(f64, &'static str)>,
}

/// How far a phase has moved: a translation or an angle, with its rate.
enum Progress {
    Shift { d: [f64; 2], v: [f64; 2] },
    Turn { phi: f64, omega: f64 },
    Still,
}

impl Phase {
    pub fn new(name: Option<String>, movement: Movement, end: Ends) -> Phase {
        let analytic = analytic_end(&movement, &end);
        Phase {
            name,
            movement,
            end,
            analytic,
        }
    }

    /// τ after the phase's start at which it ends by itself, and the reason.
    pub fn analytic_end(&self) -> Option<(f64, &'static str)> {
        self.analytic
    }

    /// The gripper's motion τ into the phase, which started at pose `start`.
    pub fn motion(&self, start: &Pose, tau: f64) -> Motion {
        let tau = tau.max(0.0);
        if let Some((te, _)) = self.analytic {
            if tau >= te {
                return Motion::at_rest(self.end_pose(start));
            }
        }
        self.apply(start, self.progress(tau))
    }

    /// The pose at the phase's analytic end (`start` if it has none). A `travel` end lands
    /// exactly on the travel for the scalar laws; the vector forms use the seed's arithmetic.
    pub fn end_pose(&self, start: &Pose) -> Pose {
        let Some((te, reason)) = self.analytic else {
            return *start;
        };
        let p = match &self.movement {
            Movement::Hold => Progress::Still,
            Movement::TranslateVector { law } => vector_progress(law, te, false),
            Movement::Translate { direction, law } => {
                let s = end_value(law, te, reason, self.end.travel);
                Progress::Shift {
                    d: [direction[0] * s, direction[1] * s],
                    v: [0.0; 2],
                }
            }
            Movement::Rotate { sense, law, .. } => Progress::Turn {
                phi: sense * end_value(law, te, reason, self.end.travel),
                omega: 0.0,
            },
        };
        self.apply(start, p).pose
    }

    fn progress(&self, tau: f64) -> Progress {
        match &self.movement {
            Movement::Hold => Progress::Still,
            Movement::TranslateVector { law } => vector_progress(law, tau, true),
            Movement::Translate { direction, law } => {
                let (s, ds) = law.eval(tau);
                Progress::Shift {
                    d: [direction[0] * s, direction[1] * s],
                    v: [direction[0] * ds, direction[1] * ds],
                }
            }
            Movement::Rotate { sense, law, .. } => {
                let (s, ds) = law.eval(tau);
                Progress::Turn {
                    phi: sense * s,
                    omega: sense * ds,
                }
            }
        }
    }

    fn apply(&self, start: &Pose, p: Progress) -> Motion {
        match (p, &self.movement) {
            (Progress::Shift { d, v }, _) => {
                // From the identity pose the displacement is taken as is (the seed's bits).
                let d = if start.d == [0.0, 0.0] {
                    d
                } else {
                    [start.d[0] + d[0], start.d[1] + d[1]]
                };
                Motion {
                    pose: Pose {
                        theta: start.theta,
                        d,
                    },
                    omega: 0.0,
                    v,
                }
            }
            (Progress::Turn { phi, omega }, Movement::Rotate { pivot, .. }) => {
                turn(start, start.apply(*pivot), phi, omega)
            }
            _ => Motion::at_rest(*start),
        }
    }

    /// The pivot's world point for a rotate phase that started at pose `start`.
    pub fn pivot_world(&self, start: &Pose) -> Option<[f64; 2]> {
        match &self.movement {
            Movement::Rotate { pivot, .. } => Some(start.apply(*pivot)),
            _ => None,
        }
    }

    /// The measured grip: drive force along the direction (translate) or drive torque in the
    /// rotation's sense (rotate); None for a hold.
    /// The largest acceleration the phase gives a point at distance `lever` (m) from its
    /// pivot (m/s²; rotations: angular acceleration × lever).
    pub fn peak_acceleration(&self, lever: impl Fn([f64; 2]) -> f64) -> f64 {
        match &self.movement {
            Movement::Hold => 0.0,
            Movement::Translate { law, .. } => law.peak_acceleration(),
            Movement::TranslateVector { law } => match law {
                VectorLaw::Velocity(_) => 0.0,
                VectorLaw::Acceleration(a) => a[0].hypot(a[1]),
            },
            Movement::Rotate { pivot, law, .. } => law.peak_acceleration() * lever(*pivot),
        }
    }

    pub fn grip(&self, m: &Measure) -> Option<f64> {
        match &self.movement {
            Movement::Hold => None,
            Movement::Translate { direction: u, .. } => {
                Some(m.drive_force[0] * u[0] + m.drive_force[1] * u[1])
            }
            Movement::TranslateVector { law } => {
                let w = law.vector();
                let n = (w[0] * w[0] + w[1] * w[1]).sqrt();
                if n > 0.0 {
                    Some((m.drive_force[0] * w[0] + m.drive_force[1] * w[1]) / n)
                } else {
                    None
                }
            }
            Movement::Rotate { sense, .. } => Some(sense * m.drive_torque),
        }
    }

    /// Name for messages: `'close'`, or `(unnamed)`.
    pub fn label(&self) -> String {
        match &self.name {
            Some(n) => format!("'{n}'"),
            None => "(unnamed)".into(),
        }
    }
}

/// Rotation about the world point `c` by φ from pose `start`: θ = θ₀ + φ,
/// d = R(φ)(d₀ − c) + c; velocity ḋ = ω J R(φ)(d₀ − c).
fn turn(start: &Pose, c: [f64; 2], phi: f64, omega: f64) -> Motion {
    let r = [start.d[0] - c[0], start.d[1] - c[1]];
    let (pose, rr) = if phi == 0.0 {
        (*start, r)
    } else {
        let rr = rotate(phi, r);
        (
            Pose {
                theta: start.theta + phi,
                d: [rr[0] + c[0], rr[1] + c[1]],
            },
            rr,
        )
    };
    Motion {
        pose,
        omega,
        v: [-omega * rr[1], omega * rr[0]],
    }
}

/// The seed drive's arithmetic: d = v τ or ½ a τ² per component (`moving`: the rate, else 0).
fn vector_progress(law: &VectorLaw, te: f64, moving: bool) -> Progress {
    let (d, v) = match *law {
        VectorLaw::Velocity(v) => ([v[0] * te, v[1] * te], v),
        VectorLaw::Acceleration(a) => (
            [0.5 * a[0] * te * te, 0.5 * a[1] * te * te],
            [a[0] * te, a[1] * te],
        ),
    };
    Progress::Shift {
        d,
        v: if moving { v } else { [0.0; 2] },
    }
}

/// s at a scalar law's analytic end: exactly ± the travel for a travel end.
fn end_value(law: &Law, te: f64, reason: &str, travel: Option<f64>) -> f64 {
    let s = law.eval(te).0;
    match travel {
        Some(l) if reason == TRAVEL => l.copysign(s),
        _ => s,
    }
}

/// The earliest analytic end: duration, travel, profile complete (ties in that order).
fn analytic_end(movement: &Movement, end: &Ends) -> Option<(f64, &'static str)> {
    let mut best: Option<(f64, &'static str)> = None;
    let mut offer = |t: Option<f64>, reason: &'static str| {
        if let Some(t) = t {
            if best.is_none_or(|(b, _)| t < b) {
                best = Some((t, reason));
            }
        }
    };
    offer(end.duration, DURATION);
    match movement {
        Movement::Hold => {}
        Movement::TranslateVector { law } => {
            // As the seed's drive: |a| or |v|, then √(2 L/|a|) or L/|v|; ignored at zero.
            let w = law.vector();
            let mag = (w[0] * w[0] + w[1] * w[1]).sqrt();
            if let Some(l) = end.travel {
                if mag > 0.0 {
                    offer(
                        Some(match law {
                            VectorLaw::Acceleration(_) => (2.0 * l / mag).sqrt(),
                            VectorLaw::Velocity(_) => l / mag,
                        }),
                        TRAVEL,
                    );
                }
            }
        }
        Movement::Translate { law, .. } | Movement::Rotate { law, .. } => {
            offer(end.travel.and_then(|l| law.time_to_travel(l)), TRAVEL);
            offer(law.profile_end(), PROFILE_COMPLETE);
        }
    }
    best
}

/// A gripper's program: its phases and the mirror line x = `mirror_x` for mirrored members
/// (and `width` ends). After the last phase the gripper holds its pose.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Program {
    pub phases: Vec<Phase>,
    pub mirror_x: Option<f64>,
    /// Time constant (s) of the first-order low-pass through which measured ends
    /// (`grip_force`, `grip_torque`) see the drive's reaction: a force sensor's bandwidth.
    /// 0: the raw reaction of each step (which, at a rigid impact, is an impulse divided by
    /// Δt and so depends on Δt).
    pub force_filter: f64,
}

impl Program {
    /// No motion (the seed's `fixed` drive).
    pub fn fixed() -> Program {
        Program {
            phases: Vec::new(),
            mirror_x: None,
            force_filter: 0.0,
        }
    }

    /// The seed's one-translation drive: a vector law stopped by `stop_time` or
    /// `stop_travel`, then a hold. Gives the same numbers as the seed's `Drive::motion`.
    pub fn translation(
        law: VectorLaw,
        stop_time: Option<f64>,
        stop_travel: Option<f64>,
    ) -> Program {
        let end = Ends {
            duration: stop_time,
            travel: stop_travel,
            ..Ends::default()
        };
        Program {
            phases: vec![Phase::new(None, Movement::TranslateVector { law }, end)],
            mirror_x: None,
            force_filter: 0.0,
        }
    }
}
