//! Rods built from their scenario description: rest shape, section, masses, clamps, drive, loads.

use crate::energy::bend::curvature;
use crate::events::RodInfo;
use crate::scenario::{Drive, MassSpec, RodSpec, Scenario, ScenarioError, Shape};

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
}

/// Node positions of a shape.
pub fn shape_points(shape: &Shape, n: usize) -> Vec<[f64; 2]> {
    match shape {
        Shape::Straight { start, end } => (0..n)
            .map(|i| {
                let s = i as f64 / (n - 1) as f64;
                [
                    start[0] + s * (end[0] - start[0]),
                    start[1] + s * (end[1] - start[1]),
                ]
            })
            .collect(),
        Shape::Points { points } => points.clone(),
        Shape::Parabola { x0, y0, a, length } => (0..n)
            .map(|i| {
                let s = length * i as f64 / (n - 1) as f64;
                [x0 + a * (length - s) * (length - s), y0 - s]
            })
            .collect(),
    }
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

/// Checks that need the built geometry: no zero-length edge, no fold-back in the rest shape,
/// no node starting inside an obstacle.
pub fn validate_geometry(sc: &Scenario) -> Result<(), ScenarioError> {
    let err = |key: String, value: String, message: String, hint: &str| ScenarioError {
        file: sc.file.clone(),
        key,
        value,
        message,
        hint: Some(hint.to_string()),
    };
    for (ri, spec) in sc.rods.iter().enumerate() {
        let pts = shape_points(&spec.shape, spec.nodes);
        let key = if spec.particle {
            format!(
                "particle.{}",
                ri - sc.rods.iter().filter(|r| !r.particle).count()
            )
        } else {
            format!("rod.{ri}")
        };
        for (i, p) in pts.iter().enumerate() {
            if !(p[0].is_finite() && p[1].is_finite()) {
                return Err(err(
                    format!("{key}.shape"),
                    format!("node {i} at [{}, {}]", p[0], p[1]),
                    format!("node {i} of the shape is not finite (the numbers overflow)"),
                    "use coordinates of a realistic size (metres)",
                ));
            }
        }
        let size = pts
            .iter()
            .flat_map(|p| p.iter())
            .fold(0.0f64, |m, v| m.max(v.abs()))
            .max(1e-300);
        for i in 0..pts.len() - 1 {
            let l = (pts[i + 1][0] - pts[i][0]).hypot(pts[i + 1][1] - pts[i][1]);
            if !l.is_finite() {
                return Err(err(
                    format!("{key}.shape"),
                    format!("{:?}", pts[i]),
                    format!(
                        "the edge from node {i} to {} is too long to represent",
                        i + 1
                    ),
                    "use coordinates of a realistic size (metres)",
                ));
            }
            if l <= 1e-12 * size {
                return Err(err(
                    format!("{key}.shape"),
                    format!("{:?}", pts[i]),
                    format!("nodes {i} and {} coincide (zero-length edge)", i + 1),
                    "give the rod a non-zero length with distinct nodes",
                ));
            }
        }
        for i in 1..pts.len().saturating_sub(1) {
            let e1 = [pts[i][0] - pts[i - 1][0], pts[i][1] - pts[i - 1][1]];
            let e2 = [pts[i + 1][0] - pts[i][0], pts[i + 1][1] - pts[i][1]];
            if e1[0] * e2[0] + e1[1] * e2[1] <= 0.0 {
                return Err(err(
                    format!("{key}.shape"),
                    format!("{:?}", pts[i]),
                    format!("the rest shape turns by 90° or more at node {i}"),
                    "use more nodes or a smoother shape",
                ));
            }
        }
        for (oi, o) in sc.obstacles.iter().enumerate() {
            for (i, p) in pts.iter().enumerate() {
                let d = o.query(*p).distance;
                if !d.is_finite() {
                    return Err(err(
                        format!("obstacle.{oi}"),
                        String::new(),
                        format!(
                            "the distance from {} {:?} node {i} to this {} cannot be computed \
                             (the obstacle's numbers overflow)",
                            if spec.particle { "particle" } else { "rod" },
                            spec.name,
                            o.kind()
                        ),
                        "use obstacle dimensions of a realistic size (metres)",
                    ));
                }
                if d < 0.0 {
                    return Err(err(
                        if spec.particle {
                            format!("{key}.position")
                        } else {
                            format!("{key}.shape")
                        },
                        format!("node {i} at [{}, {}]", p[0], p[1]),
                        format!(
                            "{} {:?} node {i} starts {:.3e} m inside obstacle.{oi} ({})",
                            if spec.particle { "particle" } else { "rod" },
                            spec.name,
                            -d,
                            o.kind()
                        ),
                        "move the rod or the obstacle so that the rod starts outside",
                    ));
                }
            }
        }
    }
    Ok(())
}
