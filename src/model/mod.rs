//! Rods built from their scenario description: rest shape, section, masses, clamps, drive, loads.

use crate::energy::bend::curvature;
use crate::events::RodInfo;
use crate::scenario::geometry::shape_points;
use crate::scenario::{Drive, MassSpec, RodSpec};

/// A prong ready to simulate.
#[derive(Debug, Clone)]
pub struct Rod {
    pub name: String,
    pub n: usize,
    /// Initial positions, interleaved.
    pub q0: Vec<f64>,
    pub rest_length: Vec<f64>,
    /// Voronoi length of each node (half the adjacent rest edges); Δl of bending uses the
    /// mean of the two adjacent edges, i.e. the same value at interior nodes.
    pub voronoi: Vec<f64>,
    pub rest_curvature: Vec<f64>,
    pub mass: Vec<f64>,
    pub clamped: Vec<bool>,
    pub ea: f64,
    pub ei: f64,
    pub youngs_modulus: f64,
    pub area: f64,
    pub half_height: f64,
    pub drive: Drive,
    /// Dead loads per DOF (N), interleaved.
    pub load: Vec<f64>,
    /// Total rest length (m).
    pub length: f64,
    /// Initial velocity of every node (m/s).
    pub velocity: [f64; 2],
    /// Kelvin–Voigt retardation time τ (s): the viscous force of an element is τ times its
    /// stiffness along its strain times the strain rate (0: undamped).
    pub damping_time: f64,
}

impl Rod {
    pub fn new(spec: &RodSpec) -> Rod {
        let n = spec.nodes;
        let pts = shape_points(&spec.shape, n);
        let q0: Vec<f64> = pts.iter().flat_map(|p| [p[0], p[1]]).collect();
        let rest_length: Vec<f64> = (0..n - 1)
            .map(|i| {
                ((pts[i + 1][0] - pts[i][0]).powi(2) + (pts[i + 1][1] - pts[i][1]).powi(2)).sqrt()
            })
            .collect();
        let voronoi: Vec<f64> = (0..n)
            .map(|i| {
                let left = if i > 0 { rest_length[i - 1] } else { 0.0 };
                let right = if i + 1 < n { rest_length[i] } else { 0.0 };
                0.5 * (left + right)
            })
            .collect();
        let mut rest_curvature = vec![0.0; n];
        for i in 1..n.saturating_sub(1) {
            let x = [
                pts[i - 1][0],
                pts[i - 1][1],
                pts[i][0],
                pts[i][1],
                pts[i + 1][0],
                pts[i + 1][1],
            ];
            rest_curvature[i] = curvature(&x);
        }
        let area = spec.section.area();
        let mass = match spec.mass {
            MassSpec::Density(rho) => voronoi.iter().map(|l| rho * area * l).collect(),
            MassSpec::NodeMass(m) => vec![m; n],
            MassSpec::Total(m) => {
                let l: f64 = voronoi.iter().sum();
                voronoi.iter().map(|v| m * v / l).collect()
            }
        };
        let mut clamped = vec![false; n];
        for &c in &spec.clamped {
            clamped[c] = true;
        }
        let mut load = vec![0.0; 2 * n];
        for l in &spec.loads {
            load[2 * l.node] += l.force[0];
            load[2 * l.node + 1] += l.force[1];
        }
        let length: f64 = rest_length.iter().sum();
        Rod {
            name: spec.name.clone(),
            n,
            q0,
            // A particle has no length; 1 m sets its update tolerance scale.
            length: if n > 1 { length } else { 1.0 },
            velocity: spec.velocity,
            rest_length,
            voronoi,
            rest_curvature,
            mass,
            clamped,
            ea: spec.youngs_modulus * area,
            ei: spec.youngs_modulus * spec.section.inertia(),
            youngs_modulus: spec.youngs_modulus,
            area,
            half_height: spec.section.half_height(),
            drive: spec.drive,
            load,
            damping_time: spec.damping_time,
        }
    }

    pub fn info(&self) -> RodInfo {
        RodInfo {
            name: self.name.clone(),
            nodes: self.n,
            mass: self.mass.clone(),
            clamped: self.clamped.clone(),
            rest_length: self.rest_length.clone(),
            rest_curvature: self.rest_curvature.clone(),
            youngs_modulus: self.youngs_modulus,
            area: self.area,
            inertia: if self.youngs_modulus > 0.0 {
                self.ei / self.youngs_modulus
            } else {
                0.0
            },
            particle: self.n == 1,
            half_height: self.half_height,
        }
    }

    /// Bending Δl at interior node i: mean of the two adjacent rest edges.
    #[inline]
    pub fn bend_length(&self, i: usize) -> f64 {
        0.5 * (self.rest_length[i - 1] + self.rest_length[i])
    }

    /// Bending stress σ = E |κ − κ̄| / Δl · h/2 at every node of configuration q.
    pub fn bending_stress(&self, q: &[f64], out: &mut [f64]) {
        out[0] = 0.0;
        out[self.n - 1] = 0.0;
        for i in 1..self.n.saturating_sub(1) {
            let x = [
                q[2 * i - 2],
                q[2 * i - 1],
                q[2 * i],
                q[2 * i + 1],
                q[2 * i + 2],
                q[2 * i + 3],
            ];
            let k = curvature(&x);
            out[i] = self.youngs_modulus * (k - self.rest_curvature[i]).abs() / self.bend_length(i)
                * self.half_height;
        }
    }
}
