//! The world: what moves. Rods (planar discrete elastic rods, and single-node particles) live in
//! [`crate::model`]; free rigid bodies (fruit) here: a pose, a velocity, and the contacts the
//! body itself has with fixed obstacles.

pub mod body;

use crate::contact::body::BodyContact;
use body::{BodySpec, Pose};

/// A free rigid body during a run.
#[derive(Debug, Clone)]
pub struct Body {
    pub spec: BodySpec,
    /// Pose at the start of the step.
    pub pose: Pose,
    /// (vx, vy, ω) at the start of the step.
    pub v: [f64; 3],
    /// Acceleration of the last accepted step (initial guess).
    pub a: [f64; 3],
    /// The step's displacement (Δc, Δθ): the Newton unknown.
    pub dx: [f64; 3],
    /// The displacement of the last accepted step.
    pub last_dx: [f64; 3],
    /// Generalised mass (m, m, I).
    pub m: [f64; 3],
    /// External force at full load: gravity on the centroid.
    pub fext: [f64; 3],
    /// Contacts with fixed obstacles, and their copy at the start of the step.
    pub contacts: Vec<BodyContact>,
    pub contacts_saved: Vec<BodyContact>,
    /// Reaction (normal, tangential) of each contact, as solved.
    pub reaction: Vec<[f64; 2]>,
    /// Residual scale (N): the body's weight, or its mass × 1 m/s² without gravity.
    pub force_scale: f64,
    /// (feature, obstacle) of contacts released in this step: re-detected, they are locked.
    pub released: Vec<(usize, usize)>,
}

impl Body {
    pub fn new(spec: &BodySpec, gravity: [f64; 2]) -> Self {
        let g = gravity[0].hypot(gravity[1]);
        Self {
            pose: Pose {
                c: spec.centroid,
                theta: 0.0,
            },
            v: [spec.velocity[0], spec.velocity[1], spec.angular_velocity],
            a: [0.0; 3],
            dx: [0.0; 3],
            last_dx: [0.0; 3],
            m: [spec.mass, spec.mass, spec.inertia],
            fext: [spec.mass * gravity[0], spec.mass * gravity[1], 0.0],
            contacts: Vec::new(),
            contacts_saved: Vec::new(),
            reaction: Vec::new(),
            force_scale: spec.mass * g.max(1.0),
            released: Vec::new(),
            spec: spec.clone(),
        }
    }

    /// The pose at the end of the step being solved.
    #[inline]
    pub fn trial_pose(&self) -> Pose {
        self.pose.moved(&self.dx)
    }

    /// Body residual c M (ΔX − dt V) − λ F (the eq. 2 form), without contact forces.
    #[inline]
    pub fn inertial_residual(&self, c: f64, dt: f64, lambda: f64) -> [f64; 3] {
        let mut g = [0.0; 3];
        for k in 0..3 {
            g[k] = c * self.m[k] * (self.dx[k] - dt * self.v[k]) - lambda * self.fext[k];
        }
        g
    }
}
