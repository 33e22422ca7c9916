//! Actuation programs: how a gripper (a group of rods that move as one end effector) moves
//! its clamped nodes.
//!
//! A [`Program`] is a sequence of [`Phase`]s (translate, rotate about a pivot, hold), each with
//! a motion [`Law`] and end conditions. The gripper's state is one rigid transform, the
//! [`Pose`]: a driven node whose initial position is x₀ is at R(θ) x₀ + d. An [`Actuator`]
//! runs a program: [`Actuator::motion`] is a pure function of time (it may be called for trial
//! steps that are then rejected) and [`Actuator::commit`] advances the phase after each
//! accepted step, from a [`Measure`] of the drive's reaction (grip force or torque).
//!
//! Ends on `duration` and `travel` (and a profile's completion) are analytic: the motion
//! saturates exactly at the limit, inside a step, and the next phase starts at exactly that
//! time from exactly that pose. Ends on `width` and `grip_force`/`grip_torque` are measured:
//! they are decided after an accepted step.
//!
//! Mirrored members: a rod with `mirror = true` in a group whose program has a mirror line
//! x = c follows M ∘ P ∘ M, M(x, y) = (2c − x, y): the exact mirror image of the program's
//! motion. Measures are taken in the unmirrored frame ([`Measure::add`] maps a mirrored
//! member's forces there).
//!
//! No I/O and no scenario types here: the scenario reader builds programs, the solver runs
//! them.

pub mod actuator;
pub mod law;
pub mod phase;

pub use actuator::{Actuator, GripUnreached, PhaseSwitch};
pub use law::{Law, Table, TableIssue, Trapezoid};
pub use phase::{Ends, Movement, Phase, Program, VectorLaw};

/// The end effector's rigid transform: x = R(θ) x₀ + d.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Pose {
    /// Rotation (rad, counter-clockwise).
    pub theta: f64,
    /// Translation (m).
    pub d: [f64; 2],
}

impl Pose {
    pub const IDENTITY: Pose = Pose {
        theta: 0.0,
        d: [0.0, 0.0],
    };

    /// R(θ) x₀ + d. With θ = 0 exactly this is x₀ + d with no rotation arithmetic (so a pure
    /// translation gives the same bits as adding a displacement).
    pub fn apply(&self, x0: [f64; 2]) -> [f64; 2] {
        if self.theta == 0.0 {
            return [x0[0] + self.d[0], x0[1] + self.d[1]];
        }
        let r = rotate(self.theta, x0);
        [r[0] + self.d[0], r[1] + self.d[1]]
    }
}

/// R(θ) x.
pub fn rotate(theta: f64, x: [f64; 2]) -> [f64; 2] {
    let (s, c) = theta.sin_cos();
    [c * x[0] - s * x[1], s * x[0] + c * x[1]]
}

/// The mirror image of x in the line x = c: (2c − x, y).
pub fn mirror_point(x: [f64; 2], c: f64) -> [f64; 2] {
    [2.0 * c - x[0], x[1]]
}

/// The gripper's pose and its rate at one time.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Motion {
    pub pose: Pose,
    /// dθ/dt (rad/s).
    pub omega: f64,
    /// dd/dt (m/s).
    pub v: [f64; 2],
}

impl Motion {
    /// At rest in `pose`.
    pub fn at_rest(pose: Pose) -> Motion {
        Motion {
            pose,
            omega: 0.0,
            v: [0.0; 2],
        }
    }

    /// Where a driven node with initial position `x0` is. `mirror`: the program's mirror line
    /// for a member with `mirror = true`, None otherwise; a mirrored node is at M(P(M(x₀))).
    pub fn position_of(&self, x0: [f64; 2], mirror: Option<f64>) -> [f64; 2] {
        let p = &self.pose;
        match mirror {
            None => p.apply(x0),
            // M(P(M(x))) = x + (−d_x, d_y) when θ = 0: computed so, it is the exact mirror
            // of a displacement (the seed's ±a drives give the same bits).
            Some(_) if p.theta == 0.0 => [x0[0] - p.d[0], x0[1] + p.d[1]],
            Some(c) => mirror_point(p.apply(mirror_point(x0, c)), c),
        }
    }

    /// Velocity of a driven node with initial position `x0`: ω J R(θ) x₀ + v (J the 90°
    /// rotation), mirrored like [`Motion::position_of`].
    pub fn velocity_of(&self, x0: [f64; 2], mirror: Option<f64>) -> [f64; 2] {
        let x = match mirror {
            Some(c) => mirror_point(x0, c),
            None => x0,
        };
        let v = if self.omega == 0.0 {
            self.v
        } else {
            let r = rotate(self.pose.theta, x);
            [self.v[0] - self.omega * r[1], self.v[1] + self.omega * r[0]]
        };
        match mirror {
            Some(_) => [-v[0], v[1]],
            None => v,
        }
    }
}

/// What the solver measures after an accepted step, in the program's (unmirrored) frame: the
/// total force the drive applies to the group's clamped nodes, and its torque about the
/// current rotate phase's pivot ([`Actuator::pivot_world`]; 0 when there is none).
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize)]
pub struct Measure {
    pub drive_force: [f64; 2],
    pub drive_torque: f64,
}

impl Measure {
    /// Adds the drive force `f` on a clamped node at world position `x`. `mirror`: the
    /// mirror line for a mirrored member (its point and force are mirrored into the program's
    /// frame first); `pivot`: the pivot in world coordinates, for the torque.
    pub fn add(&mut self, x: [f64; 2], f: [f64; 2], mirror: Option<f64>, pivot: Option<[f64; 2]>) {
        let (x, f) = match mirror {
            Some(c) => (mirror_point(x, c), [-f[0], f[1]]),
            None => (x, f),
        };
        self.drive_force[0] += f[0];
        self.drive_force[1] += f[1];
        if let Some(p) = pivot {
            self.drive_torque += (x[0] - p[0]) * f[1] - (x[1] - p[1]) * f[0];
        }
    }
}

/// The centroid of a group's clamped nodes in the program's frame (what
/// [`Actuator::new`] takes for `width` ends): each item is a node's initial position and
/// whether its rod is a mirrored member; mirrored nodes are mapped by M first. (0, 0) when
/// there are none.
pub fn clamp_centroid(
    nodes: impl IntoIterator<Item = ([f64; 2], bool)>,
    mirror: Option<f64>,
) -> [f64; 2] {
    let (mut sx, mut sy, mut n) = (0.0, 0.0, 0usize);
    for (x, mirrored) in nodes {
        let x = match (mirrored, mirror) {
            (true, Some(c)) => mirror_point(x, c),
            _ => x,
        };
        sx += x[0];
        sy += x[1];
        n += 1;
    }
    if n == 0 {
        return [0.0; 2];
    }
    [sx / n as f64, sy / n as f64]
}

#[cfg(test)]
mod tests;
