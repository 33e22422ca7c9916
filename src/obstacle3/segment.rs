//! The point of a segment deepest in (closest to) a 3D shape, for edge contact
//! (src/rod3d/edge3.rs): a prong's segment can cut into a small fruit or across the edge of a
//! box or mesh between its two nodes.
//!
//! Exact for a sphere (the foot of the perpendicular from its centre, clamped to the segment)
//! and for a plane (the signed distance is linear along the segment, so an end is deepest and
//! the contact is the nodes'). For an ellipsoid the root of the signed distance's slope along
//! the segment (regula falsi, [`deepest_convex`]). Otherwise a golden-section search of the
//! signed distance along the segment: the signed distance of a convex solid (box) is a convex
//! function, so the search finds the deepest point; on a non-convex mesh it finds a local
//! minimum.

use super::{Obstacle3, Proximity3, Shape3, V3};

/// A cheap lower bound on the signed distance of any point of segment a–b from `o`: the bound
/// at its midpoint less half its length (signed distances are 1-Lipschitz).
#[inline]
pub fn lower_bound(o: &Obstacle3, a: &V3, b: &V3) -> f64 {
    o.lower_bound(&(0.5 * (a + b))) - 0.5 * (b - a).norm()
}

/// The weight s ∈ [0, 1] of the point (1 − s) a + s b of segment a–b deepest in `o` (least
/// signed distance), and `o`'s answer there. The ends win ties (a face the segment lies
/// flat on is the nodes' business).
pub fn deepest(o: &Obstacle3, a: &V3, b: &V3) -> (f64, Proximity3) {
    let e = b - a;
    let at = |s: f64| o.query(&(a + e * s));
    match o.shape {
        Shape3::Sphere { .. } => {
            let ee = e.norm_squared();
            let s = if ee > 0.0 {
                ((o.pose.position - a).dot(&e) / ee).clamp(0.0, 1.0)
            } else {
                0.0
            };
            return (s, at(s));
        }
        Shape3::Plane => {
            let (qa, qb) = (at(0.0), at(1.0));
            return if qb.distance < qa.distance {
                (1.0, qb)
            } else {
                (0.0, qa)
            };
        }
        Shape3::Ellipsoid { .. } => return deepest_convex(&at, &e),
        _ => {}
    }
    crate::obstacle::deepest_along(at, |q| q.distance, 80)
}

/// The deepest point of a segment in a smooth convex solid (an ellipsoid): its signed
/// distance f(s) is convex with f'(s) = n(s)·e (the outward normal at the closest point), so
/// an end is deepest when f' does not change sign, and otherwise the root of f' is found by
/// regula falsi with the Illinois rule on its bracket (a few queries, where a golden-section
/// search of f needs some sixty of the ellipsoid's iterative closest-point queries).
fn deepest_convex(at: &impl Fn(f64) -> Proximity3, e: &V3) -> (f64, Proximity3) {
    let (q0, q1) = (at(0.0), at(1.0));
    let (mut g0, mut g1) = (q0.normal.dot(e), q1.normal.dot(e));
    if g0 >= 0.0 || g1 <= 0.0 {
        // Monotone along the segment: the lower end is deepest (ends win ties).
        return if q1.distance < q0.distance {
            (1.0, q1)
        } else {
            (0.0, q0)
        };
    }
    let (mut lo, mut hi) = (0.0f64, 1.0f64);
    let mut side = 0i8;
    for _ in 0..100 {
        let s = ((lo * g1 - hi * g0) / (g1 - g0)).clamp(lo, hi);
        let s = if s <= lo || s >= hi {
            0.5 * (lo + hi)
        } else {
            s
        };
        let q = at(s);
        let g = q.normal.dot(e);
        if g.abs() <= 1e-14 * e.norm() {
            return (s, q);
        }
        if g < 0.0 {
            (lo, g0) = (s, g);
            if side == -1 {
                g1 *= 0.5;
            }
            side = -1;
        } else {
            (hi, g1) = (s, g);
            if side == 1 {
                g0 *= 0.5;
            }
            side = 1;
        }
        if hi - lo < 1e-13 {
            break;
        }
    }
    let mid = 0.5 * (lo + hi);
    let best = (mid, at(mid));
    if q0.distance <= best.1.distance {
        return (0.0, q0);
    }
    if q1.distance <= best.1.distance {
        return (1.0, q1);
    }
    best
}

#[cfg(test)]
mod tests {
    use super::super::{Pose3, TriMesh};
    use super::*;

    #[test]
    fn a_segment_over_a_sphere_is_deepest_at_the_foot_of_the_perpendicular() {
        let o = Obstacle3::new(
            "s",
            Shape3::Sphere { radius: 0.002 },
            Pose3::at([0.003, 0.0005, -0.001]),
        );
        let (a, b) = (V3::new(-0.01, 0.0, 0.0), V3::new(0.01, 0.0, 0.0));
        let (s, q) = deepest(&o, &a, &b);
        assert!((s - 0.65).abs() < 1e-15, "{s}");
        let d = (0.0005f64.powi(2) + 0.001f64.powi(2)).sqrt() - 0.002;
        assert!((q.distance - d).abs() < 1e-15, "{}", q.distance);
        assert!(lower_bound(&o, &a, &b) <= q.distance);
        // The golden-section search on an ellipsoid with equal semi-axes finds the same point.
        let e = Obstacle3::new(
            "e",
            Shape3::Ellipsoid {
                semi_axes: [0.002; 3],
            },
            o.pose,
        );
        let (se, qe) = deepest(&e, &a, &b);
        assert!((se - 0.65).abs() < 1e-7, "{se}");
        assert!((qe.distance - d).abs() < 1e-12, "{}", qe.distance);
    }

    #[test]
    fn a_ridge_of_a_box_or_mesh_is_found_between_the_nodes_and_a_face_is_left_to_them() {
        // A cube turned 45° about y: its top is a ridge along y at x = 0.
        let rot = nalgebra::Rotation3::from_axis_angle(&V3::y_axis(), std::f64::consts::FRAC_PI_4);
        let pose = Pose3 {
            position: V3::zeros(),
            rotation: rot,
        };
        let top = 0.01 * std::f64::consts::SQRT_2;
        let bx = Obstacle3::new("b", Shape3::Box { half: [0.01; 3] }, pose);
        let cube = TriMesh::from_obj(super::super::mesh::CUBE_OBJ, 0.02).unwrap();
        let mesh = Obstacle3::new("m", Shape3::Mesh(cube), pose);
        let (a, b) = (
            V3::new(-0.004, 0.0, top - 0.001),
            V3::new(0.006, 0.0, top - 0.001),
        );
        for o in [&bx, &mesh] {
            let (s, q) = deepest(o, &a, &b);
            assert!((s - 0.4).abs() < 1e-9, "{}: {s}", o.name);
            assert!((q.distance + 0.001 / std::f64::consts::SQRT_2).abs() < 1e-12);
        }
        let plane = Obstacle3::new("p", Shape3::Plane, Pose3::at([0.0; 3]));
        let (s, _) = deepest(&plane, &a, &b);
        assert_eq!(s, 0.0);
        let flat = Obstacle3::new("f", Shape3::Box { half: [0.01; 3] }, Pose3::at([0.0; 3]));
        let (a, b) = (V3::new(-0.004, 0.0, 0.009), V3::new(0.006, 0.0, 0.009));
        let (s, _) = deepest(&flat, &a, &b);
        assert!(s == 0.0 || s == 1.0, "{s}");
    }
}
