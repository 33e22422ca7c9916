//! Contact of 3D rod nodes with obstacles and free bodies by the modified mass method, and a
//! free body's own contacts with fixed obstacles (a fruit on a table).
//!
//! A contact node is described in a local orthonormal basis (n, t₁, t₂) of its contact normal.
//! Its filter is S = I − nnᵀ while it slides (the normal coordinate prescribed: n·x equals a
//! target, plus a·ΔX on a moving body with a = (n, r × n)) and S = 0 while it sticks (the whole
//! node follows an anchor point, plus G ΔX on a body). The reaction on the node is the residual
//! of its equations at the converged step; with Coulomb friction its tangential part must lie
//! within the cone |R_t| ≤ μ_s n·R while stuck. A sliding node carries the kinetic force
//! −μ_k (n·R) s along its slip direction s (the row t₁·R + μ_k n·R = 0 with t₁ = s), and sticks
//! again when its slip velocity turns against s. The decision is the planar one
//! ([`decide_cone`]). A contact whose normal reaction pulls (n·R < 0) carries no friction: a
//! stuck one slides first (any tangential hold is then outside the cone), one that still pulls
//! is released as adhesive; a node released so and caught again in the same step is held
//! frictionless (sliding without a direction, `locked`) for the rest of the step, and starts
//! the next step as a new contact does. Each change re-solves the step.
//!
//! The thickness offset: with `face` contact the centreline is held `offset` off the surface,
//! the support of the cross-section towards the obstacle, (h/2)|m₁·n| + (b/2)|m₂·n| for a
//! rectangle (h/2 for a flat prong facing the obstacle, as the planar `surface = "face"`),
//! or the radius of a round section, taken at the start of the step.

use crate::contact::compliant::PointContact;
use crate::contact::friction::{decide_cone, Cone, Coulomb};
use crate::obstacle3::V3;
use nalgebra::Matrix3;

/// What a node or body touches.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Surface3 {
    /// A fixed obstacle (index into the world's obstacles).
    Obstacle(usize),
    /// A free body (index into the world's bodies).
    Body(usize),
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Grip3 {
    /// The normal coordinate is held; `dir` is the unit slip direction the kinetic force
    /// opposes (zero: frictionless or no kinetic force).
    Slide { dir: V3 },
    /// The whole node is held at `anchor` (+ G ΔX on a body).
    Stick { anchor: V3 },
}

/// An active contact of one rod node.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Contact3 {
    pub surface: Surface3,
    pub normal: V3,
    /// n·x must equal target (+ a·ΔX on a body).
    pub target: f64,
    /// Lever from the body's centroid to the contact point (world; zero on fixed obstacles).
    pub lever: V3,
    pub offset: f64,
    pub grip: Grip3,
    pub coulomb: Coulomb,
    pub switches: u8,
    /// Released once in this step and re-added: kept for the rest of the step.
    pub locked: bool,
    /// A compliant fruit's Hertz law (None: rigid). The normal coordinate is then free and
    /// carries the law's force F(δ) at the indentation δ = target + a·ΔX − n·x; a stuck
    /// contact holds only the tangential coordinates (src/rod3d/compliant3.rs).
    pub law: Option<PointContact>,
}

impl Contact3 {
    /// The local basis as rows (n, t₁, t₂); t₁ is the slip direction when there is one.
    pub fn basis(&self) -> Matrix3<f64> {
        let n = self.normal;
        let t1 = match self.grip {
            Grip3::Slide { dir } if dir.norm() > 0.5 => dir,
            _ => {
                let pick = if n.x.abs() < 0.9 { V3::x() } else { V3::y() };
                (pick - n * n.dot(&pick)).normalize()
            }
        };
        let t2 = n.cross(&t1);
        Matrix3::from_rows(&[n.transpose(), t1.transpose(), t2.transpose()])
    }

    /// μ_k of a sliding contact with a slip direction (0 otherwise).
    pub fn kinetic(&self) -> f64 {
        match self.grip {
            Grip3::Slide { dir } if dir.norm() > 0.5 => self.coulomb.mu_k,
            _ => 0.0,
        }
    }

    /// How many local coordinates are prescribed: 1 sliding, 3 stuck (compliant: 0, 2).
    pub fn held(&self) -> usize {
        self.held_axes().len()
    }

    /// The prescribed local coordinates (0 the normal, 1 and 2 the tangents): the normal
    /// sliding, all three stuck; on a compliant fruit the normal is free (the law's force),
    /// so none sliding and the tangents stuck.
    pub fn held_axes(&self) -> std::ops::Range<usize> {
        match (self.grip, self.law.is_some()) {
            (Grip3::Slide { .. }, false) => 0..1,
            (Grip3::Stick { .. }, false) => 0..3,
            (Grip3::Slide { .. }, true) => 0..0,
            (Grip3::Stick { .. }, true) => 1..3,
        }
    }

    /// The state a new contact starts in: stuck where there is static friction (at the point of
    /// the surface plane where the node was at the start of the step), else sliding.
    pub fn initial_grip(&mut self, start: &V3) {
        self.grip = if self.coulomb.mu_s > 0.0 {
            Grip3::Stick {
                anchor: start + self.normal * (self.target - self.normal.dot(start)),
            }
        } else {
            Grip3::Slide { dir: V3::zeros() }
        };
    }
}

/// A change decided from a converged pass.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Change3 {
    Release,
    /// Slide along `dir` (zero: frictionless, a held contact that pulls).
    ToSlide {
        dir: V3,
    },
    ToStick,
}

/// Decide a node contact from its reaction `r` (world) and its slip velocity relative to the
/// surface `v_rel` (world, tangential part used).
pub fn decide(c: &Contact3, r: &V3, v_rel: &V3) -> Option<Change3> {
    let rn = c.normal.dot(r);
    decide_split(c, rn, &(r - c.normal * rn), v_rel)
}

/// [`decide`] from the normal reaction `rn` and the tangential reaction `rt` (world), by the
/// planar rules ([`decide_cone`]): inside the cone nothing changes; a stuck contact outside
/// it slides against R_t; a sliding one whose slip turned round sticks. A contact whose normal
/// reaction pulls (R_n < 0) carries no friction: stuck, it slides first (any R_t ≠ 0 is
/// outside the cone); otherwise it is released, or, when it was already released in this
/// step and caught again (`locked`), it is held frictionless (sliding without a direction) for
/// the rest of the step. Only that last change ignores [`MAX_SWITCHES`](
/// crate::contact::friction::MAX_SWITCHES): it is final within the step.
pub fn decide_split(c: &Contact3, rn: f64, rt: &V3, v_rel: &V3) -> Option<Change3> {
    let (stuck, slip_along) = match c.grip {
        Grip3::Stick { .. } => (true, 0.0),
        Grip3::Slide { dir } if dir.norm() > 0.5 => (false, dir.dot(v_rel)),
        Grip3::Slide { .. } => (false, 0.0),
    };
    let cone = decide_cone(c.coulomb, stuck, c.switches, rn, rt.norm(), slip_along);
    if rn < 0.0 {
        return match cone {
            Some(Cone::Slide) => Some(Change3::ToSlide {
                dir: -rt / rt.norm(),
            }),
            _ if !c.locked => Some(Change3::Release),
            _ if stuck || c.kinetic() != 0.0 => Some(Change3::ToSlide { dir: V3::zeros() }),
            _ => None,
        };
    }
    match cone? {
        Cone::Slide => Some(Change3::ToSlide {
            dir: -rt / rt.norm(),
        }),
        Cone::Stick => Some(Change3::ToStick),
    }
}

/// Friction utilisation |R_t| / (μ_s R_n) (0 when frictionless or not pressed).
pub fn utilisation(c: &Contact3, r: &V3) -> f64 {
    let rn = c.normal.dot(r);
    if c.coulomb.mu_s > 0.0 && rn > 0.0 {
        (r - c.normal * rn).norm() / (c.coulomb.mu_s * rn)
    } else {
        0.0
    }
}

/// A free body's contact with a fixed obstacle at one of its support points.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BodyContact3 {
    pub body: usize,
    pub obstacle: usize,
    pub normal: V3,
    /// Lever of the contact point from the centroid (world, at the start of the step).
    pub lever: V3,
    /// What G ΔX must achieve: n·(G ΔX) = gap (sliding), G ΔX = `anchor_move` (stuck).
    pub gap: f64,
    pub stuck: Option<V3>,
    /// Slip direction of a sliding contact (zero: none yet).
    pub dir: V3,
    pub coulomb: Coulomb,
    pub switches: u8,
    /// Reaction on the body from the last solve (world).
    pub force: V3,
    /// A compliant fruit's Hertz law on this obstacle (None: rigid). The normal is then free:
    /// the body carries F(δ) n at δ = gap − n·(G ΔX), and a stuck contact holds only the two
    /// tangential directions of [`BodyContact3::tangents`].
    pub law: Option<PointContact>,
}

impl BodyContact3 {
    /// Two tangents completing the normal to an orthonormal basis.
    pub fn tangents(&self) -> [V3; 2] {
        let n = self.normal;
        let pick = if n.x.abs() < 0.9 { V3::x() } else { V3::y() };
        let t1 = (pick - n * n.dot(&pick)).normalize();
        [t1, n.cross(&t1)]
    }

    /// The indentation δ = gap − n·(G ΔX) at the body displacement `dx`.
    pub fn indentation(&self, dx: &nalgebra::Vector6<f64>) -> f64 {
        let g = super::body3::lever_map(&self.lever);
        self.gap - self.normal.dot(&(g * dx))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::contact::friction::MAX_SWITCHES;

    fn contact(grip: Grip3) -> Contact3 {
        Contact3 {
            surface: Surface3::Obstacle(0),
            normal: V3::z(),
            target: 0.0,
            lever: V3::zeros(),
            offset: 0.0,
            grip,
            coulomb: Coulomb {
                mu_s: 0.5,
                mu_k: 0.4,
            },
            switches: 0,
            locked: false,
            law: None,
        }
    }

    #[test]
    fn the_cone_decides_stick_and_slip_in_any_tangent_direction() {
        let stuck = contact(Grip3::Stick {
            anchor: V3::zeros(),
        });
        let v = V3::zeros();
        assert_eq!(decide(&stuck, &V3::new(0.3, 0.4, 1.0), &v), None);
        assert!((utilisation(&stuck, &V3::new(0.3, 0.4, 1.0)) - 1.0).abs() < 1e-15);
        let Some(Change3::ToSlide { dir }) = decide(&stuck, &V3::new(0.36, 0.48, 1.0), &v) else {
            panic!("outside the cone must slide")
        };
        assert!((dir - V3::new(-0.6, -0.8, 0.0)).norm() < 1e-15);
        assert_eq!(
            decide(&stuck, &V3::new(0.0, 0.0, -1.0), &v),
            Some(Change3::Release)
        );
        let sliding = contact(Grip3::Slide { dir });
        assert_eq!(decide(&sliding, &V3::z(), &(dir * 0.1)), None);
        assert_eq!(
            decide(&sliding, &V3::z(), &(-dir * 1e-9)),
            Some(Change3::ToStick)
        );
        let b = sliding.basis();
        assert!((b * b.transpose() - Matrix3::identity()).abs().max() < 1e-15);
        assert_eq!(b.row(1).transpose(), dir);
    }

    #[test]
    fn a_contact_whose_normal_reaction_pulls_carries_no_friction() {
        let v = V3::zeros();
        let pull = V3::new(0.49, 0.0, -0.02);
        // Stuck: it slides first (against R_t), released only if it still pulls.
        let stuck = contact(Grip3::Stick {
            anchor: V3::zeros(),
        });
        assert_eq!(
            decide(&stuck, &pull, &v),
            Some(Change3::ToSlide {
                dir: V3::new(-1.0, 0.0, 0.0)
            })
        );
        let sliding = contact(Grip3::Slide {
            dir: V3::new(-1.0, 0.0, 0.0),
        });
        assert_eq!(decide(&sliding, &pull, &v), Some(Change3::Release));
        // With its switches spent, a stuck contact that pulls is released.
        let spent = Contact3 {
            switches: MAX_SWITCHES,
            ..stuck
        };
        assert_eq!(decide(&spent, &pull, &v), Some(Change3::Release));
        // Caught again in the step it was released in (locked): held without friction.
        let frictionless = Change3::ToSlide { dir: V3::zeros() };
        for c in [spent, sliding] {
            let locked = Contact3 { locked: true, ..c };
            assert_eq!(decide(&locked, &pull, &v), Some(frictionless));
        }
        let held = contact(Grip3::Slide { dir: V3::zeros() });
        let held = Contact3 {
            locked: true,
            switches: MAX_SWITCHES,
            ..held
        };
        assert_eq!(decide(&held, &pull, &v), None);
        assert_eq!(decide(&held, &V3::new(0.0, 0.0, 1.0), &V3::x()), None);
    }
}
