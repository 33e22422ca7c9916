//! What a contact holds.
//!
//! A constrained node either has its normal coordinate prescribed (it slides: frictionless, or
//! with a kinetic friction force) or is held whole (stuck by static friction, or in the corner of
//! two surfaces). On a free body the prescription is relative to the body: with ΔX = (Δc, Δθ)
//! the body's displacement over the step and G = [I | J r] the motion of the body point at lever
//! r from its centroid (J the quarter turn),
//!
//! - sliding: n·x − a·ΔX = h with a = Gᵀ n,
//! - stuck:   x − G ΔX = anchor.
//!
//! On a fixed surface ΔX is absent (a = 0, G = 0), which is the seed's modified mass method.

use super::friction::Coulomb;

/// The second surface of a node held in a corner between two obstacles.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Corner {
    pub obstacle: usize,
    pub normal: [f64; 2],
    pub target: f64,
}

/// The free body a node is held against: which, and the lever from its centroid to the
/// contact point (world frame, where the constraint was linearised).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BodyLink {
    pub body: usize,
    pub lever: [f64; 2],
}

/// Friction state of a contact.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Grip {
    /// The normal is held; the node slides along the surface. `sign` is the direction of slip
    /// along the tangent t = (−n_y, n_x) that the kinetic force opposes (0 when frictionless).
    Slide { sign: f64 },
    /// The whole node follows the surface point `anchor` (plus the body's motion).
    Stick { anchor: [f64; 2] },
}

/// An active contact constraint on one node.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Constraint {
    pub obstacle: usize,
    pub normal: [f64; 2],
    /// Target of n·x_{k+1} − a·ΔX.
    pub target: f64,
    /// Released once in this step and re-added: may not be released again in this step.
    pub locked: bool,
    /// A second obstacle touched at the same time: the node is held at the corner.
    pub second: Option<Corner>,
    /// The free body the surface belongs to, if it moves.
    pub body: Option<BodyLink>,
    pub grip: Grip,
    pub coulomb: Coulomb,
    /// Stick/slip switches of this contact in the current step (a contact that keeps switching
    /// is held in its last state for the rest of the step).
    pub switches: u8,
    /// A compliant fruit's friction hold: the node presses into the fruit by the force law
    /// (its normal is not held) and static friction holds it along the surface. Then `normal`
    /// is the held direction, the surface's tangent t = (−n_y, n_x) for the fruit's outward
    /// normal n given here; `target` holds t·x − (Gᵀt)·ΔX where the node was at the start of
    /// the step. None for a rigid contact.
    pub law: Option<LawHold>,
}

/// What a compliant contact's friction hold needs besides the held direction.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LawHold {
    /// The fruit's outward normal at the node.
    pub surface_normal: [f64; 2],
    /// The pair's Coulomb coefficients (the constraint's own are frictionless: it is a
    /// tangential hold, not a surface).
    pub coulomb: Coulomb,
}

impl Constraint {
    /// A frictionless constraint on a fixed surface: n·x = target.
    pub fn on_surface(obstacle: usize, normal: [f64; 2], target: f64) -> Self {
        Self {
            obstacle,
            normal,
            target,
            locked: false,
            second: None,
            body: None,
            grip: Grip::Slide { sign: 0.0 },
            coulomb: Coulomb::FRICTIONLESS,
            switches: 0,
            law: None,
        }
    }

    /// A compliant contact's friction hold on obstacle `obstacle` (outward normal `n` at the
    /// node): the node at `qk` (its place at the start of the step) keeps its position along the
    /// surface's tangent relative to the surface (plus the body's motion, `body`).
    pub fn law_hold(
        obstacle: usize,
        n: [f64; 2],
        qk: [f64; 2],
        coulomb: Coulomb,
        body: Option<BodyLink>,
    ) -> Self {
        let t = [-n[1], n[0]];
        Self {
            body,
            law: Some(LawHold {
                surface_normal: n,
                coulomb,
            }),
            ..Self::on_surface(obstacle, t, t[0] * qk[0] + t[1] * qk[1])
        }
    }

    /// Where a node in a corner is held: n₁·p = h₁ and n₂·p = h₂ (the caller only makes
    /// corners of surfaces that are not nearly parallel).
    pub fn corner_point(&self) -> Option<[f64; 2]> {
        let s = self.second?;
        let (a, b) = (self.normal, s.normal);
        let det = a[0] * b[1] - a[1] * b[0];
        Some([
            (self.target * b[1] - a[1] * s.target) / det,
            (a[0] * s.target - self.target * b[0]) / det,
        ])
    }

    /// Whether the whole node is held (stuck, or in a corner), not only its normal.
    #[inline]
    pub fn holds_whole_node(&self) -> bool {
        self.second.is_some() || matches!(self.grip, Grip::Stick { .. })
    }

    /// The unit tangent t = (−n_y, n_x).
    #[inline]
    pub fn tangent(&self) -> [f64; 2] {
        [-self.normal[1], self.normal[0]]
    }

    /// Kinetic friction coefficient × slip sign of a sliding contact (0 when frictionless or
    /// stuck): the tangential reaction is −(this) × the normal reaction.
    #[inline]
    pub fn kinetic(&self) -> f64 {
        match self.grip {
            Grip::Slide { sign } if self.coulomb.mu_k > 0.0 => self.coulomb.mu_k * sign,
            _ => 0.0,
        }
    }

    /// The body motion G = [I | J r] of the contact point, as three columns (x, y, θ).
    #[inline]
    pub fn body_columns(&self) -> Option<(usize, [[f64; 2]; 3])> {
        self.body
            .map(|b| (b.body, [[1.0, 0.0], [0.0, 1.0], [-b.lever[1], b.lever[0]]]))
    }

    /// Where the node must be for body displacement `dx` (whole-node holds only).
    #[inline]
    pub fn held_point(&self, body_dx: &[[f64; 3]]) -> Option<[f64; 2]> {
        if let Some(p) = self.corner_point() {
            return Some(p);
        }
        let Grip::Stick { anchor } = self.grip else {
            return None;
        };
        Some(match self.body_columns() {
            None => anchor,
            Some((b, g)) => {
                let d = body_dx[b];
                [
                    anchor[0] + g[0][0] * d[0] + g[1][0] * d[1] + g[2][0] * d[2],
                    anchor[1] + g[0][1] * d[0] + g[1][1] * d[1] + g[2][1] * d[2],
                ]
            }
        })
    }

    /// The normal target with the body's displacement: n·x must equal this.
    #[inline]
    pub fn normal_target(&self, body_dx: &[[f64; 3]]) -> f64 {
        match self.body_columns() {
            None => self.target,
            Some((b, g)) => {
                let n = self.normal;
                let d = body_dx[b];
                let a = [
                    n[0] * g[0][0] + n[1] * g[0][1],
                    n[0] * g[1][0] + n[1] * g[1][1],
                    n[0] * g[2][0] + n[1] * g[2][1],
                ];
                self.target + a[0] * d[0] + a[1] * d[1] + a[2] * d[2]
            }
        }
    }

    /// Stick at the point of the surface line where the node was at the start of the step
    /// (`qk`): its tangential motion relative to the surface is then zero over the step.
    pub fn stuck_from(&self, qk: [f64; 2]) -> Grip {
        let n = self.normal;
        let d = self.target - (n[0] * qk[0] + n[1] * qk[1]);
        Grip::Stick {
            anchor: [qk[0] + d * n[0], qk[1] + d * n[1]],
        }
    }
}
