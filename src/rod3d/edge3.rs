//! Edge (segment) contact in 3D (`[contact] points = "edges"`, as the planar
//! src/contact/edge.rs): a prong's segment can cut into a fruit smaller than a segment, or
//! across the edge of a box or mesh, between its two nodes. A contact there holds the point
//! p = (1 − s) x_i + s x_{i+1} at the barycentric weight s ∈ (0, 1) of segment i on the
//! surface's tangent plane (plus the body's motion a·ΔX, a = Gᵀ n, on a free body), moved off
//! it by the thickness offset of the segment's own section (its material frame at the start
//! of the step):
//!
//!   n·((1 − s) x_i + s x_{i+1}) = target + a·ΔX,
//!
//! one equation on two nodes with one Lagrange multiplier λ, the normal force (N, positive
//! when pressing). Its reaction λ n is shared by the nodes, (1 − s) λ n on node i and s λ n on
//! node i + 1, and on a free body −λ n acts at the contact point (force and moment Gᵀ(−λ n)).
//! The multipliers join the small dense system the 3D Newton already solves for the bodies
//! (src/rod3d/world/edges3.rs). The predictor/corrector logic is the nodes': a segment whose
//! deepest point ended inside a surface (deeper than its offset, away from its nodes) gets a
//! contact; a contact whose multiplier pulls is released (once per step); one whose segment
//! turned so its deepest point moved is re-linearised there.
//!
//! Edge contacts are frictionless: the tangential force at a point between nodes is not
//! modelled (docs/model.md, "Edge contact in 3D").

use super::body3::lever_map;
use super::contact3::Surface3;
use super::rod::pos;
use crate::obstacle3::V3;
use nalgebra::Vector6;

/// A segment's deepest point closer than this (as a fraction of the segment) to one of its
/// nodes is that node's contact, not the segment's (the planar rule).
pub const END: f64 = crate::contact::edge::END;

/// How often an edge contact may be re-linearised in one step (its deepest point moved along
/// the segment); after that it is kept as it is until the next step re-linearises it.
pub const MAX_RELINEARISED: u8 = 4;

/// Whether a weight lies far enough inside the segment to be the segment's contact.
#[inline]
pub fn interior(s: f64) -> bool {
    s > END && s < 1.0 - END
}

/// An active contact of the interior of a segment.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EdgeContact3 {
    pub surface: Surface3,
    /// The segment's first node i (the segment joins nodes i and i + 1).
    pub segment: usize,
    /// The barycentric weight s of the held point (1 − s) x_i + s x_{i+1}.
    pub weight: f64,
    /// Outward normal of the surface's tangent plane the point is held on.
    pub normal: V3,
    /// n·p must equal target (+ a·ΔX on a body).
    pub target: f64,
    /// Lever from the body's centroid to the contact point (world; zero on fixed obstacles).
    pub lever: V3,
    /// The segment's thickness offset towards the surface (m).
    pub offset: f64,
    /// The surface point touched, when the contact was made or re-linearised (world).
    pub point: V3,
    /// The multiplier λ: the normal force on the segment (N, positive when pressing).
    pub force: f64,
    /// Released (or dropped) once in this step and re-added: kept for the rest of the step.
    pub locked: bool,
    /// Re-linearisations in this step (at most [`MAX_RELINEARISED`]).
    pub relinearised: u8,
}

impl EdgeContact3 {
    /// The weights (1 − s, s) of its two nodes.
    #[inline]
    pub fn weights(&self) -> [f64; 2] {
        [1.0 - self.weight, self.weight]
    }

    /// The held point of the segment at configuration `q`.
    pub fn held_point(&self, q: &[f64]) -> V3 {
        let [w0, w1] = self.weights();
        let (k0, k1) = (pos(self.segment), pos(self.segment + 1));
        V3::new(
            w0 * q[k0] + w1 * q[k1],
            w0 * q[k0 + 1] + w1 * q[k1 + 1],
            w0 * q[k0 + 2] + w1 * q[k1 + 2],
        )
    }

    /// a = Gᵀ n: how the body's displacement ΔX moves the surface along n at the contact
    /// point (zero on a fixed obstacle, whose lever is zero and ΔX is zero).
    pub fn body_row(&self) -> Vector6<f64> {
        lever_map(&self.lever).transpose() * self.normal
    }

    /// The constraint's violation n·p − target − a·ΔX (m; negative: inside).
    pub fn violation(&self, q: &[f64], dx: &Vector6<f64>) -> f64 {
        self.normal.dot(&self.held_point(q)) - self.target - self.body_row().dot(dx)
    }

    /// The reaction on node `segment + k` (k = 0, 1): its share of λ n (world, N).
    pub fn node_force(&self, k: usize) -> V3 {
        self.normal * (self.force * self.weights()[k])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_violation_and_shares_of_a_held_point() {
        let c = EdgeContact3 {
            surface: Surface3::Obstacle(0),
            segment: 1,
            weight: 0.25,
            normal: V3::z(),
            target: -0.001,
            lever: V3::zeros(),
            offset: 0.0,
            point: V3::zeros(),
            force: 2.0,
            locked: false,
            relinearised: 0,
        };
        let mut q = vec![0.0; 11];
        q[pos(1)..pos(1) + 3].copy_from_slice(&[-0.01, 0.0, -0.002]);
        q[pos(2)..pos(2) + 3].copy_from_slice(&[0.01, 0.0, 0.002]);
        let p = c.held_point(&q);
        assert!((p - V3::new(-0.005, 0.0, -0.001)).norm() < 1e-17, "{p:?}");
        assert!(c.violation(&q, &Vector6::zeros()).abs() < 1e-18);
        assert_eq!(c.node_force(0), V3::new(0.0, 0.0, 1.5));
        assert_eq!(c.node_force(1), V3::new(0.0, 0.0, 0.5));
        assert!(interior(0.5) && !interior(0.0) && !interior(0.9999));
    }
}
