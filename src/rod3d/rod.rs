//! A 3D rod built from its rest centreline: rest lengths, Voronoi lengths, masses, rest
//! curvatures and twists, the initial reference frames (space-parallel transport of a given
//! first director along the rest centreline) and the stiffnesses of its section.

use super::energy::{advance_frame, reference_twist, strains, EdgeFrame, NodeElastic};
use super::section::Section3;

/// What a 3D rod is made of.
#[derive(Debug, Clone, PartialEq)]
pub struct Rod3Spec {
    /// Rest centreline, one point per node (at least 2).
    pub points: Vec<[f64; 3]>,
    /// First material director m₁ of edge 0 at rest (projected normal to the edge).
    pub director: [f64; 3],
    /// Rest material angle of each edge relative to the space-parallel frame (a natural twist);
    /// empty means all zero.
    pub rest_theta: Vec<f64>,
    pub section: Section3,
    pub youngs_modulus: f64,
    pub shear_modulus: f64,
    pub density: f64,
}

/// A 3D rod ready to simulate. DOFs are ordered x₀, θ₀, x₁, θ₁, …, x_{n−1}: 4n − 1 unknowns,
/// node i at 4i … 4i+2, edge i's angle at 4i + 3.
#[derive(Debug, Clone)]
pub struct Rod3 {
    pub n: usize,
    pub rest_length: Vec<f64>,
    /// Per node; entries 0 and n − 1 are unused (no bending there).
    pub elastic: Vec<NodeElastic>,
    /// EA of every edge.
    pub ea: f64,
    pub ei1: f64,
    pub ei2: f64,
    pub gj: f64,
    /// Mass of every DOF (node masses on positions, rotary inertia on angles).
    pub mass: Vec<f64>,
    /// Initial configuration, reference frames and reference twists (the rest state).
    pub q0: Vec<f64>,
    pub frames0: Vec<EdgeFrame>,
    pub ref_twist0: Vec<f64>,
    pub length: f64,
}

/// Index of node i's first coordinate.
#[inline]
pub fn pos(i: usize) -> usize {
    4 * i
}

/// Index of edge i's material angle.
#[inline]
pub fn angle(i: usize) -> usize {
    4 * i + 3
}

fn normalize(a: [f64; 3]) -> [f64; 3] {
    let l = (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt();
    [a[0] / l, a[1] / l, a[2] / l]
}

fn edge(q: &[f64], i: usize) -> [f64; 3] {
    let (a, b) = (pos(i), pos(i + 1));
    [q[b] - q[a], q[b + 1] - q[a + 1], q[b + 2] - q[a + 2]]
}

/// Space-parallel reference frames of the centreline in `q`, starting from `director`.
fn space_parallel(q: &[f64], n: usize, director: [f64; 3]) -> Vec<EdgeFrame> {
    let t0 = normalize(edge(q, 0));
    let d = director;
    let dt = d[0] * t0[0] + d[1] * t0[1] + d[2] * t0[2];
    let a1 = normalize([d[0] - dt * t0[0], d[1] - dt * t0[1], d[2] - dt * t0[2]]);
    let mut frames = vec![EdgeFrame { t: t0, a1 }];
    for i in 1..n - 1 {
        let f = advance_frame(edge(q, i), &frames[i - 1]);
        frames.push(f);
    }
    frames
}

impl Rod3 {
    pub fn new(spec: &Rod3Spec) -> Rod3 {
        let n = spec.points.len();
        assert!(n >= 2, "a 3D rod needs at least two nodes");
        let mut q0 = vec![0.0; 4 * n - 1];
        for (i, p) in spec.points.iter().enumerate() {
            q0[pos(i)..pos(i) + 3].copy_from_slice(p);
            if i + 1 < n {
                q0[angle(i)] = spec.rest_theta.get(i).copied().unwrap_or(0.0);
            }
        }
        let rest_length: Vec<f64> = (0..n - 1)
            .map(|i| {
                let e = edge(&q0, i);
                (e[0] * e[0] + e[1] * e[1] + e[2] * e[2]).sqrt()
            })
            .collect();
        let frames0 = space_parallel(&q0, n, spec.director);
        let mut ref_twist0 = vec![0.0; n];
        for i in 1..n - 1 {
            ref_twist0[i] = reference_twist(&frames0[i - 1], &frames0[i], 0.0);
        }
        let s = &spec.section;
        let (ei1, ei2) = (spec.youngs_modulus * s.i1(), spec.youngs_modulus * s.i2());
        let gj = spec.shear_modulus * s.torsion_constant();
        let mut elastic = vec![
            NodeElastic {
                ei1: 0.0,
                ei2: 0.0,
                gj: 0.0,
                kappa_bar: [0.0; 2],
                twist_bar: 0.0,
            };
            n
        ];
        for i in 1..n - 1 {
            let dl = 0.5 * (rest_length[i - 1] + rest_length[i]);
            let th = [q0[angle(i - 1)], q0[angle(i)]];
            let old = [&frames0[i - 1], &frames0[i]];
            let (k, m, _) = strains(edge(&q0, i - 1), edge(&q0, i), th, old, ref_twist0[i]);
            elastic[i] = NodeElastic {
                ei1: ei1 / dl,
                ei2: ei2 / dl,
                gj: gj / dl,
                kappa_bar: k,
                twist_bar: m,
            };
        }
        let mut mass = vec![0.0; 4 * n - 1];
        let rho_a = spec.density * s.area();
        for (i, l) in rest_length.iter().enumerate() {
            for k in 0..3 {
                mass[pos(i) + k] += 0.5 * rho_a * l;
                mass[pos(i + 1) + k] += 0.5 * rho_a * l;
            }
            mass[angle(i)] = spec.density * s.polar() * l;
        }
        let length = rest_length.iter().sum();
        Rod3 {
            n,
            rest_length,
            elastic,
            ea: spec.youngs_modulus * s.area(),
            ei1,
            ei2,
            gj,
            mass,
            q0,
            frames0,
            ref_twist0,
            length,
        }
    }

    pub fn dofs(&self) -> usize {
        4 * self.n - 1
    }

    /// Edge i of configuration q.
    pub fn edge(&self, q: &[f64], i: usize) -> [f64; 3] {
        edge(q, i)
    }

    /// Node i of configuration q.
    pub fn node(&self, q: &[f64], i: usize) -> [f64; 3] {
        [q[pos(i)], q[pos(i) + 1], q[pos(i) + 2]]
    }
}
