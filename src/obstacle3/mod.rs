//! 3D obstacles and fruit shapes (issue 16): sphere, ellipsoid, half-space (plane), box and a
//! closed triangle mesh read from an OBJ file. Every shape answers, for a point, its signed
//! distance (negative inside), the closest surface point and the outward normal there; a cheap
//! lower bound on the distance comes first so far-away shapes cost one subtraction.
//!
//! A shape lives in its own frame; [`Obstacle3`] places it with a [`Pose3`] (fixed obstacle, or
//! a free body's current pose). [`mass`] gives the mass properties of a solid shape.
//! Like the rest of the physics core this does no I/O (the OBJ reader takes the file's text).

pub mod mass;
pub mod mesh;
pub mod segment;

use nalgebra::{Matrix3, Rotation3, Unit, Vector3};

pub use mesh::TriMesh;

pub type V3 = Vector3<f64>;

/// The answer of a proximity query, in the frame the point was given in.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Proximity3 {
    /// Signed distance from the surface (negative inside).
    pub distance: f64,
    /// The closest surface point.
    pub closest: V3,
    /// Outward unit normal at `closest` (the gradient of the signed distance).
    pub normal: V3,
}

/// A solid shape in its own frame (centred on its origin; a plane is the half-space z ≤ 0).
#[derive(Debug, Clone, PartialEq)]
pub enum Shape3 {
    Sphere {
        radius: f64,
    },
    /// Semi-axes along the local x, y, z.
    Ellipsoid {
        semi_axes: [f64; 3],
    },
    /// The half-space below the local xy plane; the outward normal is local +z.
    Plane,
    /// Half extents along the local x, y, z.
    Box {
        half: [f64; 3],
    },
    Mesh(TriMesh),
}

/// Where a shape is: world point = position + rotation · local point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pose3 {
    pub position: V3,
    pub rotation: Rotation3<f64>,
}

impl Pose3 {
    pub fn at(position: [f64; 3]) -> Self {
        Self {
            position: V3::from(position),
            rotation: Rotation3::identity(),
        }
    }

    /// A pose whose local +z points along `normal` (for planes).
    pub fn facing(position: [f64; 3], normal: [f64; 3]) -> Self {
        let n = V3::from(normal).normalize();
        let rotation = Rotation3::rotation_between(&V3::z(), &n).unwrap_or_else(|| {
            Rotation3::from_axis_angle(&Unit::new_normalize(V3::x()), std::f64::consts::PI)
        });
        Self {
            position: V3::from(position),
            rotation,
        }
    }

    #[inline]
    pub fn to_local(&self, p: &V3) -> V3 {
        self.rotation.inverse_transform_vector(&(p - self.position))
    }

    #[inline]
    pub fn to_world(&self, p: &V3) -> V3 {
        self.position + self.rotation * p
    }
}

impl Shape3 {
    /// A lower bound on the signed distance of local point `p` (cheap).
    pub fn lower_bound(&self, p: &V3) -> f64 {
        match self {
            Shape3::Sphere { radius } => p.norm() - radius,
            Shape3::Ellipsoid { semi_axes } => {
                p.norm() - semi_axes.iter().cloned().fold(0.0, f64::max)
            }
            Shape3::Plane => p.z,
            Shape3::Box { half } => p.norm() - V3::from(*half).norm(),
            Shape3::Mesh(m) => (p - m.centre).norm() - m.radius,
        }
    }

    /// Signed distance, closest point and outward normal of local point `p`.
    pub fn query(&self, p: &V3) -> Proximity3 {
        match self {
            Shape3::Sphere { radius } => sphere(*radius, p),
            Shape3::Ellipsoid { semi_axes } => ellipsoid(semi_axes, p),
            Shape3::Plane => Proximity3 {
                distance: p.z,
                closest: V3::new(p.x, p.y, 0.0),
                normal: V3::z(),
            },
            Shape3::Box { half } => cuboid(half, p),
            Shape3::Mesh(m) => m.query(p),
        }
    }

    /// The point of the shape farthest along local direction `d` (unit), for a body resting on
    /// a plane; `None` for the unbounded half-space.
    pub fn support_points(&self, d: &V3) -> Vec<V3> {
        match self {
            Shape3::Sphere { radius } => vec![d * *radius],
            Shape3::Ellipsoid { semi_axes } => {
                let a = V3::from(*semi_axes);
                let w = d.component_mul(&a).component_mul(&a);
                let s = d.component_mul(&a).norm();
                vec![w / s]
            }
            Shape3::Plane => Vec::new(),
            Shape3::Box { half } => {
                let h = V3::from(*half);
                (0..8)
                    .map(|c| {
                        V3::new(
                            if c & 1 == 0 { -h.x } else { h.x },
                            if c & 2 == 0 { -h.y } else { h.y },
                            if c & 4 == 0 { -h.z } else { h.z },
                        )
                    })
                    .collect()
            }
            Shape3::Mesh(m) => m.vertices.clone(),
        }
    }
}

fn sphere(r: f64, p: &V3) -> Proximity3 {
    let l = p.norm();
    let normal = if l > 0.0 { p / l } else { V3::z() };
    Proximity3 {
        distance: l - r,
        closest: normal * r,
        normal,
    }
}

/// Closest point on the ellipsoid Σ (x_i/a_i)² = 1 to `p` (Eberly, "Distance from a point to
/// an ellipse, an ellipsoid, or a hyperellipsoid"): x_i = a_i² y_i / (a_i² + t) with t the root
/// of Σ (a_i y_i / (a_i² + t))² = 1, found by bisection (monotone in t). Signs are handled by
/// symmetry (|y|); a point on a principal plane inside is handled by the limit t → −a_min².
fn ellipsoid(a: &[f64; 3], p: &V3) -> Proximity3 {
    let y = [p.x.abs(), p.y.abs(), p.z.abs()];
    let a2 = [a[0] * a[0], a[1] * a[1], a[2] * a[2]];
    let f = |t: f64| -> f64 {
        (0..3)
            .map(|i| {
                let r = a[i] * y[i] / (a2[i] + t);
                r * r
            })
            .sum::<f64>()
            - 1.0
    };
    let amin2 = a2.iter().cloned().fold(f64::INFINITY, f64::min);
    // F decreases in t on (−a_min², ∞); F(t) ≤ |y|² max a² / t² − 1 bounds the upper end.
    let mut lo = -amin2;
    let amax = a.iter().cloned().fold(0.0, f64::max);
    let mut hi = (amax * (y[0] * y[0] + y[1] * y[1] + y[2] * y[2]).sqrt()).max(0.0);
    if f(hi) > 0.0 {
        hi *= 2.0;
    }
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if mid <= lo || mid >= hi {
            break;
        }
        if f(mid) > 0.0 {
            lo = mid
        } else {
            hi = mid
        }
    }
    let t = 0.5 * (lo + hi);
    let mut x = [0.0; 3];
    for i in 0..3 {
        x[i] = a2[i] * y[i] / (a2[i] + t);
    }
    // Inside with the point on a principal plane: the limit may leave x off the surface.
    let s: f64 = (0..3).map(|i| (x[i] / a[i]).powi(2)).sum();
    if (s - 1.0).abs() > 1e-9 {
        let k = (0..3).fold(0, |k, i| if a2[i] < a2[k] { i } else { k });
        let rest: f64 = (0..3)
            .filter(|&i| i != k)
            .map(|i| (x[i] / a[i]).powi(2))
            .sum();
        x[k] = a[k] * (1.0 - rest).max(0.0).sqrt();
    }
    let closest = V3::new(x[0].copysign(p.x), x[1].copysign(p.y), x[2].copysign(p.z));
    let g = V3::new(closest.x / a2[0], closest.y / a2[1], closest.z / a2[2]);
    let normal = g.normalize();
    let inside = (0..3).map(|i| (p[i] / a[i]).powi(2)).sum::<f64>() < 1.0;
    let d = (p - closest).norm();
    Proximity3 {
        distance: if inside { -d } else { d },
        closest,
        normal,
    }
}

fn cuboid(h: &[f64; 3], p: &V3) -> Proximity3 {
    let q = V3::new(p.x.abs() - h[0], p.y.abs() - h[1], p.z.abs() - h[2]);
    if q.max() > 0.0 {
        let closest = V3::new(
            p.x.clamp(-h[0], h[0]),
            p.y.clamp(-h[1], h[1]),
            p.z.clamp(-h[2], h[2]),
        );
        let d = p - closest;
        let l = d.norm();
        return Proximity3 {
            distance: l,
            closest,
            normal: d / l,
        };
    }
    // Inside: the nearest face.
    let k = q.imax();
    let mut closest = *p;
    closest[k] = h[k].copysign(p[k]);
    let mut normal = V3::zeros();
    normal[k] = 1.0f64.copysign(p[k]);
    Proximity3 {
        distance: q[k],
        closest,
        normal,
    }
}

/// A shape placed in the world.
#[derive(Debug, Clone, PartialEq)]
pub struct Obstacle3 {
    pub name: String,
    pub shape: Shape3,
    pub pose: Pose3,
}

impl Obstacle3 {
    pub fn new(name: &str, shape: Shape3, pose: Pose3) -> Self {
        Self {
            name: name.to_string(),
            shape,
            pose,
        }
    }

    /// Lower bound on the signed distance of world point `p`.
    #[inline]
    pub fn lower_bound(&self, p: &V3) -> f64 {
        self.shape.lower_bound(&self.pose.to_local(p))
    }

    /// Signed distance, closest point and outward normal of world point `p`, in world terms.
    pub fn query(&self, p: &V3) -> Proximity3 {
        let l = self.shape.query(&self.pose.to_local(p));
        Proximity3 {
            distance: l.distance,
            closest: self.pose.to_world(&l.closest),
            normal: self.pose.rotation * l.normal,
        }
    }
}

/// The skew matrix [a]× with [a]× b = a × b.
#[inline]
pub fn skew(a: &V3) -> Matrix3<f64> {
    Matrix3::new(0.0, -a.z, a.y, a.z, 0.0, -a.x, -a.y, a.x, 0.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sphere_and_plane_answer_exactly() {
        let s = Obstacle3::new(
            "s",
            Shape3::Sphere { radius: 0.5 },
            Pose3::at([1.0, 0.0, 0.0]),
        );
        let q = s.query(&V3::new(1.0, 0.0, 2.0));
        assert_eq!(q.distance, 1.5);
        assert_eq!(q.normal, V3::z());
        assert!(s.lower_bound(&V3::new(1.0, 0.0, 2.0)) <= q.distance);
        let p = Obstacle3::new(
            "t",
            Shape3::Plane,
            Pose3::facing([0.0, 0.0, 1.0], [0.0, 1.0, 0.0]),
        );
        let q = p.query(&V3::new(3.0, 0.25, -2.0));
        assert!((q.distance - 0.25).abs() < 1e-15);
        assert!((q.normal - V3::y()).norm() < 1e-15);
        assert!((q.closest - V3::new(3.0, 0.0, -2.0)).norm() < 1e-15);
    }

    #[test]
    fn ellipsoid_closest_point_is_on_the_surface_and_normal_to_it() {
        let a = [0.03, 0.02, 0.015];
        let e = Shape3::Ellipsoid { semi_axes: a };
        let mut worst: f64 = 0.0;
        for k in 0..200 {
            let t = k as f64 * 0.731;
            let r = 0.005 + 0.04 * ((k * 37 % 101) as f64 / 100.0);
            let p = V3::new(
                r * t.cos() * (0.3 * t).sin(),
                r * t.sin(),
                r * (0.3 * t).cos(),
            );
            let q = e.query(&p);
            let on: f64 = (0..3).map(|i| (q.closest[i] / a[i]).powi(2)).sum();
            assert!((on - 1.0).abs() < 1e-9, "{on}");
            // p − closest is along the normal, with the distance's sign.
            let d = p - q.closest;
            worst = worst.max((d - q.normal * q.distance).norm());
            assert!(e.lower_bound(&p) <= q.distance + 1e-15);
        }
        assert!(worst < 1e-9, "{worst}");
        // On an axis: exact.
        let q = e.query(&V3::new(0.05, 0.0, 0.0));
        assert!((q.distance - 0.02).abs() < 1e-15 && q.normal == V3::x());
        let q = e.query(&V3::new(0.0, 0.0, 0.01));
        assert!((q.distance + 0.005).abs() < 1e-12, "{}", q.distance);
    }

    #[test]
    fn box_inside_outside_edges() {
        let b = Shape3::Box {
            half: [1.0, 2.0, 3.0],
        };
        let q = b.query(&V3::new(0.5, 1.9, 0.0));
        assert!((q.distance + 0.1).abs() < 1e-15 && q.normal == V3::y());
        let q = b.query(&V3::new(2.0, 3.0, 0.0));
        assert!((q.distance - 2f64.sqrt()).abs() < 1e-15);
        assert!((q.normal - V3::new(1.0, 1.0, 0.0).normalize()).norm() < 1e-15);
        assert!(b.lower_bound(&V3::new(2.0, 3.0, 0.0)) <= q.distance);
    }

    #[test]
    fn a_rotated_pose_rotates_the_answer() {
        let rot = Rotation3::from_axis_angle(&V3::z_axis(), 0.5 * std::f64::consts::PI);
        let o = Obstacle3::new(
            "b",
            Shape3::Box {
                half: [1.0, 0.1, 0.1],
            },
            Pose3 {
                position: V3::new(0.0, 0.0, 0.0),
                rotation: rot,
            },
        );
        // The long side now lies along y.
        let q = o.query(&V3::new(0.0, 1.5, 0.0));
        assert!((q.distance - 0.5).abs() < 1e-12);
        assert!((q.normal - V3::y()).norm() < 1e-12);
    }
}
