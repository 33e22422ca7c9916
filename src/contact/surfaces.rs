//! Every surface a node can touch: the scenario's obstacles, each either fixed where it was
//! given or carried by a free body at some pose.
//!
//! A thick prong touches with its face, `offset` (h/2, or the section radius) off its
//! centreline: its nodes then see every obstacle grown by `offset` (the Minkowski sum with a
//! disc of that radius). Signed distances are the face's gap, the closest point is where the
//! centreline is held (`offset` out along the normal from the obstacle's surface point), and
//! the normal is the obstacle's own. For a straight or smooth prong on a smooth obstacle this is
//! exact wherever the contact is not at the prong's tip (where a rectangle's corner would touch
//! first and the grown obstacle rounds it).

use crate::obstacle::{Obstacle, Proximity};
use crate::world::body::{Placed, Pose};

/// The obstacles and, for those that are free bodies, where the body is.
#[derive(Debug, Clone, Copy)]
pub struct Surfaces<'a> {
    pub obstacles: &'a [Obstacle],
    /// Per obstacle: `None` when fixed, else (centroid as given, current pose).
    pub placement: &'a [Option<([f64; 2], Pose)>],
    /// How far the contact surface of the points queried lies off them (m, ≥ 0).
    pub offset: f64,
    /// Per obstacle: true for a compliant fruit, whose contact is a force law, not a
    /// constraint: detection does not see it (its lower bound is +∞). Empty: none.
    pub compliant: &'a [bool],
}

impl<'a> Surfaces<'a> {
    /// Fixed obstacles only.
    pub fn fixed(obstacles: &'a [Obstacle]) -> Self {
        Self {
            obstacles,
            placement: &[],
            offset: 0.0,
            compliant: &[],
        }
    }

    /// The same surfaces seen by points whose contact surface lies `offset` off them.
    pub fn with_offset(self, offset: f64) -> Self {
        Self { offset, ..self }
    }

    pub fn len(&self) -> usize {
        self.obstacles.len()
    }

    pub fn is_empty(&self) -> bool {
        self.obstacles.is_empty()
    }

    #[inline]
    fn placed(&self, k: usize) -> Option<Placed<'a>> {
        match self.placement.get(k) {
            Some(Some((c0, pose))) => Some(Placed {
                shape: &self.obstacles[k],
                c0: *c0,
                pose: *pose,
            }),
            _ => None,
        }
    }

    /// Whether obstacle `k` is a free body.
    #[inline]
    pub fn is_free(&self, k: usize) -> bool {
        matches!(self.placement.get(k), Some(Some(_)))
    }

    #[inline]
    pub fn query(&self, k: usize, p: [f64; 2]) -> Proximity {
        let q = match self.placed(k) {
            Some(b) => b.query(p),
            None => self.obstacles[k].query(p),
        };
        grown(q, self.offset)
    }

    /// Whether [`Self::lower_bound`] of obstacle `k` is the signed distance [`Self::query`]
    /// gives, bit for bit (a fixed circle or plane: its bound is its query's distance).
    #[inline]
    pub fn bound_is_distance(&self, k: usize) -> bool {
        self.compliant.get(k) != Some(&true)
            && self.placed(k).is_none()
            && self.obstacles[k].bound_is_distance()
    }

    #[inline]
    pub fn lower_bound(&self, k: usize, p: [f64; 2]) -> f64 {
        if self.compliant.get(k) == Some(&true) {
            return f64::INFINITY;
        }
        let lb = match self.placed(k) {
            Some(b) => b.lower_bound(p),
            None => self.obstacles[k].lower_bound(p),
        };
        lb - self.offset
    }
}

/// An obstacle's answer for a point whose contact surface lies `offset` off it: the gap of the
/// surface, and the point `offset` out along the normal from the obstacle's closest point.
#[inline]
pub fn grown(q: Proximity, offset: f64) -> Proximity {
    if offset == 0.0 {
        return q;
    }
    Proximity {
        distance: q.distance - offset,
        closest: [
            q.closest[0] + offset * q.normal[0],
            q.closest[1] + offset * q.normal[1],
        ],
        normal: q.normal,
    }
}
