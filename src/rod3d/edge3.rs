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
//! contact; a contact whose multiplier pulls is released (once per step: caught again in that
//! step it is held frictionless for the rest of it); one whose segment turned so its deepest
//! point moved is re-linearised there.
//!
//! Coulomb friction as on a node ([`super::contact3`]), with the same μ_s, μ_k and rules: a
//! stuck edge contact holds the whole point at an anchor on the tangent plane (three equations
//! and multipliers: the force F = λ_n n + λ₁ t₁ + λ₂ t₂ on the segment, in the contact basis
//! (n, t₁, t₂)); a sliding one holds the normal only and carries the kinetic force,
//! F = λ (n − μ_k d) with d its slip direction (one multiplier; the column differs from the
//! row). It slides when |F_t| > μ_s max(F_n, 0) (a stuck contact that pulls slides before it
//! is released), sticks again when its point's slip velocity turns against d, at most
//! `MAX_SWITCHES` times a step ([`super::contact3::decide_split`]).

use super::body3::lever_map;
use super::contact3::{Contact3, Grip3, Surface3};
use super::rod::pos;
use crate::contact::friction::Coulomb;
use crate::obstacle3::V3;
use nalgebra::{Matrix3, Vector6};

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
    /// The tangential (friction) force on the segment (world, N).
    pub friction: V3,
    /// Stuck at an anchor (on the tangent plane, + G ΔX on a body) or sliding.
    pub grip: Grip3,
    pub coulomb: Coulomb,
    /// Stick/slip switches in this step.
    pub switches: u8,
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

    /// The reaction on node `segment + k` (k = 0, 1): its share of the force F (world, N).
    pub fn node_force(&self, k: usize) -> V3 {
        self.total_force() * self.weights()[k]
    }

    /// The force F = λ n + friction on the segment (world, N).
    pub fn total_force(&self) -> V3 {
        self.normal * self.force + self.friction
    }

    /// The contact as a node contact would see it (basis, friction rules).
    pub fn as_node(&self) -> Contact3 {
        Contact3 {
            surface: self.surface,
            normal: self.normal,
            target: self.target,
            lever: self.lever,
            offset: self.offset,
            grip: self.grip,
            coulomb: self.coulomb,
            switches: self.switches,
            locked: self.locked,
            law: None,
        }
    }

    /// Its unknowns in the Newton system: 3 stuck, 1 sliding.
    pub fn unknowns(&self) -> usize {
        self.as_node().held()
    }

    /// Unknown u's (column, row) directions (world): the force on the segment per unit
    /// multiplier, and the direction the constraint holds the point along.
    pub fn directions(&self, u: usize) -> (V3, V3) {
        let c = self.as_node();
        let b: Matrix3<f64> = c.basis();
        match self.grip {
            Grip3::Stick { .. } => {
                let d = b.row(u).transpose();
                (d, d)
            }
            Grip3::Slide { .. } => {
                let t1 = b.row(1).transpose();
                (self.normal - t1 * c.kinetic(), self.normal)
            }
        }
    }

    /// Unknown u's constraint value at configuration `q` and body displacement `dx` (m; the
    /// Newton step drives it to zero): the normal violation, and while stuck the tangential
    /// distances from the anchor.
    pub fn residual(&self, u: usize, q: &[f64], dx: &Vector6<f64>) -> f64 {
        match self.grip {
            Grip3::Stick { anchor } => {
                let (_, d) = self.directions(u);
                let a = lever_map(&self.lever).transpose() * d;
                d.dot(&(self.held_point(q) - anchor)) - a.dot(dx)
            }
            Grip3::Slide { .. } => self.violation(q, dx),
        }
    }

    /// Take the Newton increments of its multipliers.
    pub fn take_increments(&mut self, d: &[f64]) {
        match self.grip {
            Grip3::Stick { .. } => {
                let mut f = self.total_force();
                for (u, du) in d.iter().enumerate() {
                    f += self.directions(u).0 * *du;
                }
                self.force = self.normal.dot(&f);
                self.friction = f - self.normal * self.force;
            }
            Grip3::Slide { .. } => {
                self.force += d[0];
                self.slide_friction();
            }
        }
    }

    /// A sliding contact's friction from its normal force: −μ_k λ d.
    pub fn slide_friction(&mut self) {
        let (c, _) = self.directions(0);
        self.friction = c * self.force - self.normal * self.force;
    }

    /// Its anchor for a stuck grip: where the held point was at the start of the step
    /// (`q0`), on the tangent plane.
    pub fn anchor_at(&self, q0: &[f64]) -> V3 {
        let p0 = self.held_point(q0);
        p0 + self.normal * (self.target - self.normal.dot(&p0))
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
            friction: V3::zeros(),
            grip: Grip3::Slide { dir: V3::zeros() },
            coulomb: Coulomb::FRICTIONLESS,
            switches: 0,
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
