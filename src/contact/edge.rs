//! Edge (segment) contact: the closest point of a prong's segment to an obstacle may lie
//! between its nodes. A contact there holds the point p = (1 − s) x_i + s x_{i+1} at the
//! barycentric weight s ∈ (0, 1) of segment i on the obstacle's tangent line (on a free body,
//! relative to the body: a = Gᵀ n, G = [I | J r] the motion of the body point at lever r),
//!
//!   n·((1 − s) x_i + s x_{i+1}) − a·ΔX = h,
//!
//! a single equation on two nodes, and its force F on the segment is shared by them: (1 − s) F
//! on node i and s F on node i + 1 (on a body, −F acts at the contact point). The solver
//! borders these rows onto the rod's banded system with their forces as Lagrange multipliers
//! (src/solver/edges.rs; with free bodies src/solver/edges_coupled.rs). A closest point within
//! [`END`] of a node is left to the node's own contact (the modified-mass filter), so the two
//! never hold the same point twice.
//!
//! Coulomb friction as on a node (src/contact/friction.rs decides, with the same μ_s, μ_k and
//! rules): a *stuck* edge contact holds the whole point at an anchor on the tangent line (two
//! equations, n and t, and two multipliers: F = λ_n n + λ_t t); a *sliding* one holds the
//! normal only and carries the kinetic force, F = λ_n (n − k t), k = μ_k × slip sign (one
//! multiplier; its column n − k t differs from its row n).

use super::constraint::{BodyLink, Constraint, Grip};
use super::friction::Coulomb;
use super::Surfaces;
use crate::obstacle::{Obstacle, Proximity};

/// A segment's closest point closer than this (as a fraction of the segment) to one of its
/// nodes is that node's contact, not the segment's.
pub const END: f64 = 1e-3;

/// How often an edge contact may be re-linearised in one step (its closest point moved along
/// the segment); after that it is kept as it is until the next step re-linearises it.
pub const MAX_RELINEARISED: u8 = 4;

/// A node contact whose normal is within this angle (rad) of an edge contact's on the same
/// surface holds nearly the same point near that node: the two are never held together
/// (src/solver/edges.rs, the hand-over).
pub const FACET: f64 = std::f64::consts::FRAC_PI_6;

/// An active contact constraint on the interior of a segment.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EdgeContact {
    pub obstacle: usize,
    /// The segment's first node i (the segment joins nodes i and i + 1).
    pub segment: usize,
    /// The barycentric weight s of the held point: (1 − s) x_i + s x_{i+1}.
    pub weight: f64,
    /// Outward normal of the obstacle's tangent line the point is held on.
    pub normal: [f64; 2],
    /// n·p − a·ΔX must equal this (a = Gᵀ n on a free body; n·p on a fixed obstacle).
    pub target: f64,
    /// Released (or dropped) once in this step and re-added: kept for the rest of the step.
    pub locked: bool,
    /// The free body the surface belongs to, and the lever from its centroid to the contact
    /// point (world frame, where the contact was linearised).
    pub body: Option<BodyLink>,
    /// Stuck at an anchor on the tangent line (plus the body's motion G ΔX), or sliding.
    pub grip: Grip,
    pub coulomb: Coulomb,
    /// Stick/slip switches in this step.
    pub switches: u8,
    /// Re-linearisations in this step (at most [`MAX_RELINEARISED`]).
    pub relinearised: u8,
    /// The multipliers as the solve applied them: the force on the segment,
    /// F = λ_n n + λ_t t (N; λ_n > 0 pressing). Sliding, λ_t = −k λ_n.
    pub force: [f64; 2],
}

impl EdgeContact {
    /// The frictionless constraint holding segment `segment`'s point at weight `s` where
    /// `prox` says (a fixed obstacle).
    pub fn at(obstacle: usize, segment: usize, s: f64, prox: &Proximity) -> Self {
        let n = prox.normal;
        Self {
            obstacle,
            segment,
            weight: s,
            normal: n,
            target: n[0] * prox.closest[0] + n[1] * prox.closest[1],
            locked: false,
            body: None,
            grip: Grip::Slide { sign: 0.0 },
            coulomb: Coulomb::FRICTIONLESS,
            switches: 0,
            relinearised: 0,
            force: [0.0; 2],
        }
    }

    /// The held point at configuration `q`.
    #[inline]
    pub fn point(&self, q: &[f64]) -> [f64; 2] {
        point(q, self.segment, self.weight)
    }

    /// The constraint's violation n·p − h at `q` with the bodies still (negative: inside).
    #[inline]
    pub fn violation(&self, q: &[f64]) -> f64 {
        let p = self.point(q);
        self.normal[0] * p[0] + self.normal[1] * p[1] - self.target
    }

    /// The weights of its two nodes.
    #[inline]
    pub fn weights(&self) -> [f64; 2] {
        [1.0 - self.weight, self.weight]
    }

    /// Whether it holds node `i` (as one of its segment's two ends).
    #[inline]
    pub fn touches(&self, i: usize) -> bool {
        i == self.segment || i == self.segment + 1
    }

    /// The contact as a node contact would see it: its tangent, friction state and rules,
    /// body motion and stuck anchor ([`Constraint`]).
    #[inline]
    pub fn as_node(&self) -> Constraint {
        Constraint {
            obstacle: self.obstacle,
            normal: self.normal,
            target: self.target,
            locked: self.locked,
            second: None,
            body: self.body,
            grip: self.grip,
            coulomb: self.coulomb,
            switches: self.switches,
            law: None,
        }
    }

    #[inline]
    pub fn tangent(&self) -> [f64; 2] {
        [-self.normal[1], self.normal[0]]
    }

    #[inline]
    pub fn is_stuck(&self) -> bool {
        matches!(self.grip, Grip::Stick { .. })
    }

    /// Its unknowns in the Newton system: 2 stuck (n, t), 1 sliding.
    #[inline]
    pub fn unknowns(&self) -> usize {
        if self.is_stuck() {
            2
        } else {
            1
        }
    }

    /// Unknown u's (column, row) directions: the force on the segment per unit multiplier,
    /// and the direction the constraint holds the point along.
    #[inline]
    pub fn directions(&self, u: usize) -> ([f64; 2], [f64; 2]) {
        let (n, t) = (self.normal, self.tangent());
        if self.is_stuck() {
            let d = if u == 0 { n } else { t };
            (d, d)
        } else {
            let k = self.as_node().kinetic();
            ([n[0] - k * t[0], n[1] - k * t[1]], n)
        }
    }

    /// Gᵀ d: how body motion ΔX moves the contact point along d (zero on a fixed obstacle),
    /// and the generalised direction of a force along d at the point.
    #[inline]
    pub fn body_row(&self, d: [f64; 2]) -> [f64; 3] {
        match self.body {
            Some(l) => [d[0], d[1], l.lever[0] * d[1] - l.lever[1] * d[0]],
            None => [0.0; 3],
        }
    }

    /// Unknown u's constraint value at configuration `q` and body displacements `body_dx`
    /// (m; the Newton step drives it to zero): the normal violation, and while stuck the
    /// tangential distance from the anchor.
    pub fn residual(&self, u: usize, q: &[f64], body_dx: &[[f64; 3]]) -> f64 {
        let p = self.point(q);
        let c = self.as_node();
        let (_, d) = self.directions(u);
        match c.held_point(body_dx) {
            Some(h) => d[0] * (p[0] - h[0]) + d[1] * (p[1] - h[1]),
            None => self.normal[0] * p[0] + self.normal[1] * p[1] - c.normal_target(body_dx),
        }
    }

    /// The force F on the segment (N).
    #[inline]
    pub fn total_force(&self) -> [f64; 2] {
        let (n, t) = (self.normal, self.tangent());
        let [a, b] = self.force;
        [a * n[0] + b * t[0], a * n[1] + b * t[1]]
    }

    /// Node `segment + a`'s share of the force (a = 0, 1).
    #[inline]
    pub fn node_force(&self, a: usize) -> [f64; 2] {
        let f = self.total_force();
        let w = self.weights()[a];
        [w * f[0], w * f[1]]
    }

    /// Take the (scaled) Newton increments of its multipliers.
    pub fn take_increments(&mut self, d: &[f64], scale: f64) {
        self.force[0] += scale * d[0];
        if self.is_stuck() {
            self.force[1] += scale * d[1];
        } else {
            self.slide_friction();
        }
    }

    /// A sliding contact's friction from its normal force: λ_t = −k λ_n.
    #[inline]
    pub fn slide_friction(&mut self) {
        self.force[1] = -self.as_node().kinetic() * self.force[0];
    }

    /// The anchor of a stuck grip: where the held point was at the start of the step (`q0`),
    /// on the tangent line (relative to the body's start pose).
    pub fn stuck_at(&self, q0: &[f64]) -> Grip {
        self.as_node().stuck_from(self.point(q0))
    }
}

/// (1 − s) x_i + s x_{i+1}.
#[inline]
pub fn point(q: &[f64], i: usize, s: f64) -> [f64; 2] {
    [
        (1.0 - s) * q[2 * i] + s * q[2 * i + 2],
        (1.0 - s) * q[2 * i + 1] + s * q[2 * i + 3],
    ]
}

/// Whether a weight lies far enough inside the segment to be the segment's contact.
#[inline]
pub fn interior(s: f64) -> bool {
    s > END && s < 1.0 - END
}

/// A cheap lower bound on the signed distance of any point of segment a–b from obstacle `k`:
/// the bound at its midpoint less half its length (distances are 1-Lipschitz).
#[inline]
pub fn lower_bound(surf: &Surfaces, k: usize, a: [f64; 2], b: [f64; 2]) -> f64 {
    let mid = [0.5 * (a[0] + b[0]), 0.5 * (a[1] + b[1])];
    let half = 0.5 * (b[0] - a[0]).hypot(b[1] - a[1]);
    surf.lower_bound(k, mid) - half
}

/// The point of segment a–b closest to (deepest into) obstacle `k`: its weight s ∈ [0, 1] and
/// the obstacle's answer there. Exact for a circle, fixed or carried by a free body (the foot
/// of the perpendicular from its centre); otherwise a golden-section search of the signed distance along the segment,
/// which is convex for the convex obstacles (circle, ellipse, polygon, plane; grown by the
/// face offset they stay convex) and finds a local minimum on a sine surface.
pub fn closest_on_segment(surf: &Surfaces, k: usize, a: [f64; 2], b: [f64; 2]) -> (f64, Proximity) {
    let e = [b[0] - a[0], b[1] - a[1]];
    let at = |s: f64| surf.query(k, [a[0] + s * e[0], a[1] + s * e[1]]);
    let ee = e[0] * e[0] + e[1] * e[1];
    if let Obstacle::Circle(c) = &surf.obstacles[k] {
        // A free circle's centre where it is placed: one radius (and the offset) in from
        // the closest point of any query.
        let center = if surf.is_free(k) {
            let q = at(0.0);
            let d = c.radius + surf.offset;
            [
                q.closest[0] - d * q.normal[0],
                q.closest[1] - d * q.normal[1],
            ]
        } else {
            c.center
        };
        let s = if ee > 0.0 {
            (((center[0] - a[0]) * e[0] + (center[1] - a[1]) * e[1]) / ee).clamp(0.0, 1.0)
        } else {
            0.0
        };
        return (s, at(s));
    }
    crate::obstacle::deepest_along(at, |q| q.distance, 60)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::obstacle::{Circle, Plane};

    #[test]
    fn a_segment_across_a_small_disc_is_closest_at_the_foot_of_the_perpendicular() {
        let obs = [Obstacle::Circle(Circle::new([0.003, 0.0005], 0.002))];
        let surf = Surfaces::fixed(&obs);
        let (s, q) = closest_on_segment(&surf, 0, [-0.01, 0.0], [0.01, 0.0]);
        assert!((s - 0.65).abs() < 1e-15, "{s}");
        assert!(
            (q.distance - (0.0005 - 0.002)).abs() < 1e-15,
            "{}",
            q.distance
        );
        // The golden-section search on a 64-gon inscribed in the disc finds nearly the same point.
        let poly = crate::obstacle::Polygon::new(
            (0..64)
                .map(|j| {
                    let a = std::f64::consts::TAU * j as f64 / 64.0;
                    [0.003 + 0.002 * a.cos(), 0.0005 + 0.002 * a.sin()]
                })
                .collect(),
        );
        let obs = [Obstacle::Polygon(poly.unwrap())];
        let surf = Surfaces::fixed(&obs);
        let (s2, q2) = closest_on_segment(&surf, 0, [-0.01, 0.0], [0.01, 0.0]);
        assert!((s2 - 0.65).abs() < 0.01, "{s2}");
        assert!(q2.distance < -0.0014, "{}", q2.distance);
    }

    #[test]
    fn a_flat_obstacle_leaves_the_contact_to_the_nodes() {
        let obs = [Obstacle::Plane(Plane::new([0.0, 0.0], [0.0, 1.0]))];
        let surf = Surfaces::fixed(&obs);
        let (s, _) = closest_on_segment(&surf, 0, [0.0, 0.001], [0.01, 0.002]);
        assert_eq!(s, 0.0);
        let (s, _) = closest_on_segment(&surf, 0, [0.0, 0.001], [0.01, 0.001]);
        assert!(!interior(s), "{s}");
    }

    #[test]
    fn the_violation_and_weights_of_a_held_point() {
        let prox = Proximity {
            distance: -0.001,
            closest: [0.0, 0.0],
            normal: [0.0, 1.0],
        };
        let c = EdgeContact::at(0, 1, 0.25, &prox);
        let q = [0.0, 0.0, -0.01, -0.002, 0.01, 0.002];
        let p = c.point(&q);
        assert!(
            (p[0] + 0.005).abs() < 1e-17 && (p[1] + 0.001).abs() < 1e-17,
            "{p:?}"
        );
        assert!((c.violation(&q) + 0.001).abs() < 1e-17);
        assert_eq!(c.weights(), [0.75, 0.25]);
        assert!(c.touches(2) && !c.touches(0));
    }

    /// A contact on a free body at lever r, stuck at the point it held at the start.
    fn stuck_on_body() -> (EdgeContact, Vec<f64>) {
        let prox = Proximity {
            distance: -1e-4,
            closest: [0.002, 0.0],
            normal: [0.0, 1.0],
        };
        let mut c = EdgeContact::at(0, 0, 0.6, &prox);
        c.body = Some(BodyLink {
            body: 0,
            lever: [0.002, 0.03],
        });
        c.coulomb = Coulomb {
            mu_s: 0.5,
            mu_k: 0.4,
        };
        let q0 = vec![-0.01, 0.0001, 0.01, -0.0002, 0.02, 0.0];
        c.grip = c.stuck_at(&q0);
        (c, q0)
    }

    #[test]
    fn a_stuck_edge_holds_its_point_whole_and_follows_the_body() {
        let (c, q0) = stuck_on_body();
        assert_eq!(c.unknowns(), 2);
        assert_eq!(c.directions(0), ([0.0, 1.0], [0.0, 1.0]));
        assert_eq!(c.directions(1), ([-1.0, 0.0], [-1.0, 0.0]));
        // At the start (ΔX = 0) the point is off the line by its depth and on its anchor.
        let still = [[0.0; 3]];
        let p0 = c.point(&q0);
        assert!((c.residual(0, &q0, &still) - (p0[1] - 0.0)).abs() < 1e-18);
        assert!(c.residual(1, &q0, &still).abs() < 1e-18);
        // The rows are linear in ΔX with the coefficient −Gᵀ d.
        let dx = [[1e-4, -2e-4, 3e-3]];
        for u in 0..2 {
            let (_, d) = c.directions(u);
            let a = c.body_row(d);
            let lin = -(a[0] * dx[0][0] + a[1] * dx[0][1] + a[2] * dx[0][2]);
            let got = c.residual(u, &q0, &dx) - c.residual(u, &q0, &still);
            assert!((got - lin).abs() < 1e-18, "{u}: {got} vs {lin}");
        }
    }

    #[test]
    fn a_sliding_edge_carries_the_kinetic_force_in_its_normal_row() {
        let (mut c, _) = stuck_on_body();
        c.grip = Grip::Slide { sign: -1.0 };
        assert_eq!(c.unknowns(), 1);
        // k = μ_k × sign = −0.4: the column n − k t = (0, 1) + 0.4 (−1, 0).
        let (col, row) = c.directions(0);
        assert!((col[0] + 0.4).abs() < 1e-15 && col[1] == 1.0, "{col:?}");
        assert_eq!(row, [0.0, 1.0]);
        c.take_increments(&[2.0], 0.5);
        assert_eq!(c.force, [1.0, 0.4]);
        // Shared by the nodes with the weights (0.4, 0.6).
        let f = c.total_force();
        let n1 = c.node_force(1);
        assert!((n1[0] - 0.6 * f[0]).abs() < 1e-15 && (n1[1] - 0.6 * f[1]).abs() < 1e-15);
    }
}
