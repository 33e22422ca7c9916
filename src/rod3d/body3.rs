//! A free fruit in 3D: a 6-DOF rigid body of uniform density whose mass and inertia come from
//! its shape ([`crate::obstacle3::mass`]). Its unknowns in a step are ΔX = (Δc, φ): the
//! centroid's displacement and the rotation vector of the step (R_{k+1} = exp(φ) R_k).
//!
//! Implicit Euler on momentum and angular momentum L (world frame):
//! m (Δc − dt v_k)/dt² − m g − F = f_c,  (I_k φ − dt L_k)/dt² − T = τ_c,
//! with I_k = R_k I_body R_kᵀ the world inertia at the start of the step and f_c, τ_c the
//! contact forces and torques; afterwards v = Δc/dt, L = I_k φ/dt. A body point at lever r from
//! the centroid moves by G ΔX = Δc + φ × r (linearised), and a force f there acts on the body
//! as Gᵀ f = (f, r × f).

use crate::obstacle3::mass::mass_properties;
use crate::obstacle3::{skew, Obstacle3, Pose3, Shape3, V3};
use nalgebra::{Matrix3, Rotation3, SMatrix, Vector6};

pub type M6 = SMatrix<f64, 6, 6>;
pub type G3 = SMatrix<f64, 3, 6>;

#[derive(Debug, Clone)]
pub struct Body3 {
    /// The shape about its centroid (a mesh is moved so its centroid is the origin), placed at
    /// `obstacle.pose` (position = centroid).
    pub obstacle: Obstacle3,
    pub mass: f64,
    /// Inertia about the centroid in the body frame.
    pub inertia: Matrix3<f64>,
    pub v: V3,
    /// Angular momentum about the centroid (world frame).
    pub l: V3,
    /// Dead force on the centroid (besides gravity).
    pub force: V3,
    /// Pose at the start of the current step.
    pub start: Pose3,
    /// Displacement over the current step: (Δc, φ).
    pub dx: Vector6<f64>,
    /// A compliant fruit's material (None: rigid).
    pub material: Option<crate::contact::compliant::Material>,
}

impl Body3 {
    /// A body of `shape` (centred on its own origin, or a mesh anywhere: it is re-centred on its
    /// centroid) with its centroid at `centre`, at rest.
    pub fn new(name: &str, shape: Shape3, density: f64, centre: [f64; 3]) -> Result<Body3, String> {
        let mp = mass_properties(&shape, density)
            .ok_or_else(|| "a plane cannot be a free body".to_string())?;
        let shape = match shape {
            Shape3::Mesh(mut m) => {
                for v in &mut m.vertices {
                    *v -= mp.centroid;
                }
                m.centre -= mp.centroid;
                Shape3::Mesh(m)
            }
            s => s,
        };
        let pose = Pose3::at(centre);
        Ok(Body3 {
            obstacle: Obstacle3::new(name, shape, pose),
            mass: mp.mass,
            inertia: mp.inertia,
            v: V3::zeros(),
            l: V3::zeros(),
            force: V3::zeros(),
            start: pose,
            dx: Vector6::zeros(),
            material: None,
        })
    }

    pub fn centre(&self) -> V3 {
        self.obstacle.pose.position
    }

    /// World inertia at the start of the step.
    pub fn world_inertia(&self) -> Matrix3<f64> {
        let r = self.start.rotation.matrix();
        r * self.inertia * r.transpose()
    }

    /// Angular velocity ω = I⁻¹ L at the current pose.
    pub fn omega(&self) -> V3 {
        let r = self.obstacle.pose.rotation.matrix();
        let iw = r * self.inertia * r.transpose();
        iw.try_inverse()
            .map(|i| i * self.l)
            .unwrap_or_else(V3::zeros)
    }

    /// Begin a step: remember the pose, guess ΔX = dt (v, ω).
    pub fn begin(&mut self, dt: f64) {
        self.start = self.obstacle.pose;
        let w = self.omega();
        self.dx = Vector6::new(
            dt * self.v.x,
            dt * self.v.y,
            dt * self.v.z,
            dt * w.x,
            dt * w.y,
            dt * w.z,
        );
    }

    /// Place the body at start + ΔX.
    pub fn place(&mut self) {
        let dc = V3::new(self.dx[0], self.dx[1], self.dx[2]);
        let phi = V3::new(self.dx[3], self.dx[4], self.dx[5]);
        self.obstacle.pose = Pose3 {
            position: self.start.position + dc,
            rotation: Rotation3::new(phi) * self.start.rotation,
        };
    }

    /// Residual of the body's own equations at ΔX (without contact forces) and its Jacobian
    /// (c = 1/dt²).
    pub fn residual(&self, dt: f64, gravity: &V3) -> (Vector6<f64>, M6) {
        let c = 1.0 / (dt * dt);
        let iw = self.world_inertia();
        let dc = V3::new(self.dx[0], self.dx[1], self.dx[2]);
        let phi = V3::new(self.dx[3], self.dx[4], self.dx[5]);
        let rt = c * self.mass * (dc - dt * self.v) - self.mass * gravity - self.force;
        let rr = c * (iw * phi - dt * self.l);
        let mut j = M6::zeros();
        j.fixed_view_mut::<3, 3>(0, 0)
            .copy_from(&(Matrix3::identity() * (c * self.mass)));
        j.fixed_view_mut::<3, 3>(3, 3).copy_from(&(iw * c));
        (Vector6::new(rt.x, rt.y, rt.z, rr.x, rr.y, rr.z), j)
    }

    /// End the step: velocities from ΔX.
    pub fn finish(&mut self, dt: f64) {
        self.place();
        let iw = self.world_inertia();
        self.v = V3::new(self.dx[0], self.dx[1], self.dx[2]) / dt;
        self.l = iw * V3::new(self.dx[3], self.dx[4], self.dx[5]) / dt;
    }

    pub fn momentum(&self) -> V3 {
        self.mass * self.v
    }

    pub fn kinetic_energy(&self) -> f64 {
        0.5 * self.mass * self.v.norm_squared() + 0.5 * self.omega().dot(&self.l)
    }
}

/// G = [I | −[r]×]: the linearised motion Δc + φ × r of the body point at lever r.
pub fn lever_map(r: &V3) -> G3 {
    let mut g = G3::zeros();
    g.fixed_view_mut::<3, 3>(0, 0)
        .copy_from(&Matrix3::identity());
    g.fixed_view_mut::<3, 3>(0, 3).copy_from(&(-skew(r)));
    g
}
