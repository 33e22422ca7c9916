//! A free rigid body in the plane (a fruit): pose (centroid c, rotation θ from the shape as
//! given), mass, rotational inertia about the centroid, and the shape it carries.
//!
//! The shape is kept as given in the scenario (its initial placement, an [`Obstacle`]); a query
//! at a world point is answered by moving the point into that initial placement, asking the
//! shape, and moving the answer back. Every closed shape (circle, ellipse, polygon) can be free.

use crate::obstacle::{Obstacle, Proximity};

/// Mass properties and initial motion of a free body, built from its shape.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct BodySpec {
    /// Index of the body's shape in the scenario's obstacle list.
    pub obstacle: usize,
    pub name: String,
    /// kg.
    pub mass: f64,
    /// kg·m² about the centroid.
    pub inertia: f64,
    /// m g (N).
    pub weight: [f64; 2],
    /// Centroid of the shape as given (m).
    pub centroid: [f64; 2],
    pub velocity: [f64; 2],
    /// rad/s, counter-clockwise.
    pub angular_velocity: f64,
    /// Largest distance from the centroid to the outline (m): the body's size.
    pub radius: f64,
    /// A fruit is `held` when it ends the lift within this distance (m) of where it sat in
    /// the gripper when the lift began.
    pub hold_tolerance: f64,
    /// Extent out of the plane (m): `depth` as given, else the body's diameter 2 `radius` (a
    /// round fruit is as deep as it is wide). The length of its line contact on a table.
    pub depth: f64,
}

/// Area (m² per m of depth), centroid and polar second moment of area about the centroid
/// (m⁴ per m of depth) of a closed shape. `None` for open surfaces (plane, sine).
pub fn area_properties(shape: &Obstacle) -> Option<(f64, [f64; 2], f64)> {
    use std::f64::consts::PI;
    match shape {
        Obstacle::Circle(c) => {
            let a = PI * c.radius * c.radius;
            Some((a, c.center, a * c.radius * c.radius / 2.0))
        }
        Obstacle::Ellipse(e) => {
            let a = PI * e.a * e.b;
            Some((a, e.center, a * (e.a * e.a + e.b * e.b) / 4.0))
        }
        Obstacle::Polygon(p) => Some(polygon_properties(&p.vertices)),
        Obstacle::Plane(_) | Obstacle::Sine(_) => None,
    }
}

/// Area, centroid and polar moment about the centroid of a simple polygon (either orientation),
/// by the triangle fan from the first vertex (shoelace formulas).
fn polygon_properties(v: &[[f64; 2]]) -> (f64, [f64; 2], f64) {
    let n = v.len();
    let o = v[0];
    let (mut a2, mut cx, mut cy, mut j) = (0.0, 0.0, 0.0, 0.0);
    for i in 0..n {
        let p = [v[i][0] - o[0], v[i][1] - o[1]];
        let q = [v[(i + 1) % n][0] - o[0], v[(i + 1) % n][1] - o[1]];
        let cr = p[0] * q[1] - q[0] * p[1];
        a2 += cr;
        cx += (p[0] + q[0]) * cr;
        cy += (p[1] + q[1]) * cr;
        // ∫(x² + y²) dA over the triangle (origin, p, q).
        j += cr
            * (p[0] * p[0] + p[0] * q[0] + q[0] * q[0] + p[1] * p[1] + p[1] * q[1] + q[1] * q[1]);
    }
    let area = 0.5 * a2;
    let c = [cx / (3.0 * a2), cy / (3.0 * a2)];
    let j_origin = j / 12.0;
    // Parallel axis: J_c = J_o − A |c|², signs follow the orientation (area may be negative).
    let jc = j_origin - area * (c[0] * c[0] + c[1] * c[1]);
    (area.abs(), [o[0] + c[0], o[1] + c[1]], jc.abs())
}

/// Largest distance from `c` to the shape's outline.
pub fn outline_radius(shape: &Obstacle, c: [f64; 2]) -> f64 {
    match shape {
        Obstacle::Circle(o) => o.radius,
        Obstacle::Ellipse(e) => e.a.max(e.b),
        Obstacle::Polygon(p) => p
            .vertices
            .iter()
            .map(|v| (v[0] - c[0]).hypot(v[1] - c[1]))
            .fold(0.0, f64::max),
        Obstacle::Plane(_) | Obstacle::Sine(_) => f64::INFINITY,
    }
}

/// Where a body is: its centroid and its rotation from the shape as given.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Pose {
    pub c: [f64; 2],
    pub theta: f64,
}

impl Pose {
    /// The pose displaced by (dx, dy, dθ).
    #[inline]
    pub fn moved(&self, d: &[f64; 3]) -> Pose {
        Pose {
            c: [self.c[0] + d[0], self.c[1] + d[1]],
            theta: self.theta + d[2],
        }
    }
}

#[inline]
pub fn rotate(v: [f64; 2], theta: f64) -> [f64; 2] {
    if theta == 0.0 {
        return v;
    }
    let (s, c) = theta.sin_cos();
    [c * v[0] - s * v[1], s * v[0] + c * v[1]]
}

/// A body's shape placed at a pose: answers like an [`Obstacle`].
#[derive(Debug, Clone, Copy)]
pub struct Placed<'a> {
    pub shape: &'a Obstacle,
    /// Centroid of the shape as given.
    pub c0: [f64; 2],
    pub pose: Pose,
}

impl Placed<'_> {
    /// A world point in the shape's own (initial) placement.
    #[inline]
    pub fn to_shape(&self, p: [f64; 2]) -> [f64; 2] {
        let d = rotate(
            [p[0] - self.pose.c[0], p[1] - self.pose.c[1]],
            -self.pose.theta,
        );
        [self.c0[0] + d[0], self.c0[1] + d[1]]
    }

    /// A point of the shape's initial placement in the world.
    #[inline]
    pub fn to_world(&self, p: [f64; 2]) -> [f64; 2] {
        let d = rotate([p[0] - self.c0[0], p[1] - self.c0[1]], self.pose.theta);
        [self.pose.c[0] + d[0], self.pose.c[1] + d[1]]
    }

    #[inline]
    pub fn query(&self, p: [f64; 2]) -> Proximity {
        let q = self.shape.query(self.to_shape(p));
        Proximity {
            distance: q.distance,
            closest: self.to_world(q.closest),
            normal: rotate(q.normal, self.pose.theta),
        }
    }

    #[inline]
    pub fn lower_bound(&self, p: [f64; 2]) -> f64 {
        self.shape.lower_bound(self.to_shape(p))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::obstacle::{Circle, Polygon};

    #[test]
    fn polygon_mass_properties_match_closed_forms() {
        // A 0.2 × 0.1 rectangle, centre (1, 2): A = 0.02, J = A (w² + h²)/12.
        let r = Obstacle::Polygon(
            Polygon::new(vec![[0.9, 1.95], [1.1, 1.95], [1.1, 2.05], [0.9, 2.05]]).unwrap(),
        );
        let (a, c, j) = area_properties(&r).unwrap();
        assert!((a - 0.02).abs() < 1e-15);
        assert!((c[0] - 1.0).abs() < 1e-12 && (c[1] - 2.0).abs() < 1e-12);
        assert!((j - 0.02 * (0.04 + 0.01) / 12.0).abs() < 1e-15, "{j}");
        // Clockwise gives the same.
        let cw = Obstacle::Polygon(
            Polygon::new(vec![[0.9, 2.05], [1.1, 2.05], [1.1, 1.95], [0.9, 1.95]]).unwrap(),
        );
        let (a2, c2, j2) = area_properties(&cw).unwrap();
        assert!((a2 - a).abs() < 1e-15 && (j2 - j).abs() < 1e-15);
        assert!((c2[0] - c[0]).abs() < 1e-12);
    }

    #[test]
    fn placed_shape_answers_in_the_moved_frame() {
        let s = Obstacle::Circle(Circle::new([0.0, 0.0], 0.05));
        let placed = Placed {
            shape: &s,
            c0: [0.0, 0.0],
            pose: Pose {
                c: [1.0, 0.5],
                theta: 0.3,
            },
        };
        let q = placed.query([1.1, 0.5]);
        assert!((q.distance - 0.05).abs() < 1e-12);
        assert!((q.normal[0] - 1.0).abs() < 1e-12 && q.normal[1].abs() < 1e-12);
        assert!((q.closest[0] - 1.05).abs() < 1e-12);
    }
}
