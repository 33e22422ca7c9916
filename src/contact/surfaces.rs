//! Every surface a node can touch: the scenario's obstacles, each either fixed where it was
//! given or carried by a free body at some pose.

use crate::obstacle::{Obstacle, Proximity};
use crate::world::body::{Placed, Pose};

/// The obstacles and, for those that are free bodies, where the body is.
#[derive(Debug, Clone, Copy)]
pub struct Surfaces<'a> {
    pub obstacles: &'a [Obstacle],
    /// Per obstacle: `None` when fixed, else (centroid as given, current pose).
    pub placement: &'a [Option<([f64; 2], Pose)>],
}

impl<'a> Surfaces<'a> {
    /// Fixed obstacles only.
    pub fn fixed(obstacles: &'a [Obstacle]) -> Self {
        Self {
            obstacles,
            placement: &[],
        }
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
        match self.placed(k) {
            Some(b) => b.query(p),
            None => self.obstacles[k].query(p),
        }
    }

    #[inline]
    pub fn lower_bound(&self, k: usize, p: [f64; 2]) -> f64 {
        match self.placed(k) {
            Some(b) => b.lower_bound(p),
            None => self.obstacles[k].lower_bound(p),
        }
    }
}
