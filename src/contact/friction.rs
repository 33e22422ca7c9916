//! Coulomb friction in the modified mass method: where stick and slip are decided.
//!
//! A contact is *stuck* (the whole node follows the surface point, S = 0) while the eq. 2
//! reaction R satisfies |R_t| ≤ μ_s R_n; past that it *slides*: the normal stays held
//! (S = I − nnᵀ) and the tangential reaction is the kinetic force −μ_k R_n s (s the slip
//! direction), which enters the Newton system as the row t·R + μ_k s (n·R) = 0. A sliding
//! contact whose solved slip velocity turns against its assumed direction is stuck again:
//! kinetic friction stopped it inside the step. Each switch re-solves the step, like an
//! adhesive release, and is reported. A contact that switches twice in one step keeps its state
//! for the rest of the step, so the method itself cannot chatter.

use super::constraint::{Constraint, Grip};

/// Static and kinetic coefficients of a contact pair.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Coulomb {
    pub mu_s: f64,
    pub mu_k: f64,
}

impl Coulomb {
    pub const FRICTIONLESS: Coulomb = Coulomb {
        mu_s: 0.0,
        mu_k: 0.0,
    };

    #[inline]
    pub fn is_frictionless(&self) -> bool {
        self.mu_s == 0.0 && self.mu_k == 0.0
    }
}

/// The scenario's coefficients: a default and named pairs (rod, particle or obstacle names).
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct FrictionTable {
    pub default: Coulomb,
    pub pairs: Vec<(String, String, Coulomb)>,
}

impl Default for FrictionTable {
    fn default() -> Self {
        Self {
            default: Coulomb::FRICTIONLESS,
            pairs: Vec::new(),
        }
    }
}

impl FrictionTable {
    /// The coefficients between `a` and `b` (either order); the last matching pair wins.
    pub fn between(&self, a: &str, b: &str) -> Coulomb {
        self.pairs
            .iter()
            .rev()
            .find(|(x, y, _)| (x == a && y == b) || (x == b && y == a))
            .map(|p| p.2)
            .unwrap_or(self.default)
    }

    /// Whether any pair has friction.
    pub fn any(&self) -> bool {
        !self.default.is_frictionless() || self.pairs.iter().any(|p| !p.2.is_frictionless())
    }
}

/// A change of friction state decided from a solved pass.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Switch {
    /// Stuck → sliding, in direction `sign` along the tangent.
    ToSlide { sign: f64 },
    /// Sliding → stuck.
    ToStick,
}

/// How many switches one contact may make in one step before it is held in its state.
pub const MAX_SWITCHES: u8 = 2;

/// Normal and tangential parts (R_n, R_t) of a reaction on a contact with normal n.
#[inline]
pub fn split(c: &Constraint, r: [f64; 2]) -> (f64, f64) {
    let (n, t) = (c.normal, c.tangent());
    (n[0] * r[0] + n[1] * r[1], t[0] * r[0] + t[1] * r[1])
}

/// Decide the friction state of a (non-corner) contact from its eq. 2 reaction `r` and its slip
/// velocity `v_t` relative to the surface along the tangent.
pub fn decide(c: &Constraint, r: [f64; 2], v_t: f64) -> Option<Switch> {
    if c.second.is_some() {
        return None;
    }
    let (rn, rt) = split(c, r);
    decide_on(c.coulomb, c.grip, c.switches, rn, rt, v_t)
}

/// What the Coulomb cone decides for a contact, in either dimension.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Cone {
    /// A stuck contact outside the cone: it slides, against its tangential reaction.
    Slide,
    /// A sliding contact whose slip turned against its direction: kinetic friction stopped it.
    Stick,
}

/// The one Coulomb decision of planar and 3D contacts (nodes, edges and a body's own
/// contacts), from the normal reaction `rn` (N, > 0 pressing), the size of the tangential
/// reaction `rt_abs` (N) and, for a sliding contact, its slip velocity along its slip
/// direction `slip_along` (m/s; < 0: turned round).
///
/// A stuck contact slides when |R_t| > μ_s max(R_n, 0) (and R_t ≠ 0): with R_n ≤ 0 any
/// tangential hold is outside the cone, so a stuck contact whose normal reaction pulls slides
/// before it may be released (holding the tangential velocity can itself make the normal
/// reaction adhesive: a node stopped dead on a curved or moving surface). A sliding contact
/// sticks when its slip turns round. Nothing switches without static friction or after
/// [`MAX_SWITCHES`] switches in the step.
#[inline]
pub fn decide_cone(
    coulomb: Coulomb,
    stuck: bool,
    switches: u8,
    rn: f64,
    rt_abs: f64,
    slip_along: f64,
) -> Option<Cone> {
    if coulomb.mu_s == 0.0 || switches >= MAX_SWITCHES {
        return None;
    }
    if stuck {
        (rt_abs != 0.0 && rt_abs > coulomb.mu_s * rn.max(0.0)).then_some(Cone::Slide)
    } else {
        (slip_along < 0.0).then_some(Cone::Stick)
    }
}

/// The planar decision ([`decide_cone`]) from the normal and tangential reaction (R_n, R_t)
/// and the slip velocity along the tangent; shared by node contacts and a body's own contacts.
pub fn decide_on(
    coulomb: Coulomb,
    grip: Grip,
    switches: u8,
    rn: f64,
    rt: f64,
    v_t: f64,
) -> Option<Switch> {
    let (stuck, slip_along) = match grip {
        Grip::Stick { .. } => (true, 0.0),
        Grip::Slide { sign } => (false, sign * v_t),
    };
    Some(
        match decide_cone(coulomb, stuck, switches, rn, rt.abs(), slip_along)? {
            // The surface holds the node with R_t; released, it slides the other way.
            Cone::Slide => Switch::ToSlide {
                sign: if rt > 0.0 { -1.0 } else { 1.0 },
            },
            Cone::Stick => Switch::ToStick,
        },
    )
}

/// Friction utilisation |R_t| / (μ_s R_n) of a contact (0 when frictionless or not pressed).
#[inline]
pub fn utilisation(c: &Constraint, r: [f64; 2]) -> f64 {
    let (rn, rt) = split(c, r);
    if c.coulomb.mu_s > 0.0 && rn > 0.0 {
        rt.abs() / (c.coulomb.mu_s * rn)
    } else {
        0.0
    }
}

/// The state a new contact starts in: stuck where there is static friction, else sliding.
pub fn initial_grip(c: &Constraint, qk: [f64; 2]) -> Grip {
    if c.coulomb.mu_s > 0.0 && c.second.is_none() {
        c.stuck_from(qk)
    } else {
        Grip::Slide { sign: 0.0 }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn contact(grip: Grip) -> Constraint {
        let mut c = Constraint::on_surface(0, [0.0, 1.0], 0.0);
        c.coulomb = Coulomb {
            mu_s: 0.5,
            mu_k: 0.4,
        };
        c.grip = grip;
        c
    }

    #[test]
    fn stick_holds_inside_the_cone_and_slides_outside() {
        let stuck = contact(Grip::Stick { anchor: [0.0; 2] });
        // t = (−1, 0): R = (−0.4, 1) has R_t = +0.4 ≤ 0.5.
        assert_eq!(decide(&stuck, [-0.4, 1.0], 0.0), None);
        // R_t = +0.6 > 0.5: the surface pushed along +t, so the node slides along −t.
        assert_eq!(
            decide(&stuck, [-0.6, 1.0], 0.0),
            Some(Switch::ToSlide { sign: -1.0 })
        );
        // Pulling (R_n ≤ 0): no tangential hold is inside the cone, so a stuck contact slides
        // first (the release is decided after, if it still pulls); with no tangential part
        // there is nothing to slide.
        assert_eq!(
            decide(&stuck, [-0.6, -1.0], 0.0),
            Some(Switch::ToSlide { sign: -1.0 })
        );
        assert_eq!(decide(&stuck, [0.0, -1.0], 0.0), None);
        assert!((utilisation(&stuck, [-0.4, 1.0]) - 0.8).abs() < 1e-15);
    }

    #[test]
    fn slide_sticks_when_the_slip_turns_round() {
        let s = contact(Grip::Slide { sign: 1.0 });
        assert_eq!(decide(&s, [0.0, 1.0], 0.1), None);
        assert_eq!(decide(&s, [0.0, 1.0], -1e-9), Some(Switch::ToStick));
        assert!((s.kinetic() - 0.4).abs() < 1e-15);
    }

    #[test]
    fn the_cone_is_one_decision_for_every_contact() {
        let mu = Coulomb {
            mu_s: 0.5,
            mu_k: 0.4,
        };
        // Stuck: inside the cone nothing changes, outside it slides; pulling, any tangential
        // hold is outside (slide first), none is nothing to slide.
        assert_eq!(decide_cone(mu, true, 0, 1.0, 0.5, 0.0), None);
        assert_eq!(decide_cone(mu, true, 0, 1.0, 0.51, 0.0), Some(Cone::Slide));
        assert_eq!(
            decide_cone(mu, true, 0, -0.02, 1e-12, 0.0),
            Some(Cone::Slide)
        );
        assert_eq!(decide_cone(mu, true, 0, -0.02, 0.0, 0.0), None);
        // Sliding: sticks when the slip turns round, whatever the reaction.
        assert_eq!(decide_cone(mu, false, 0, 1.0, 9.0, 0.1), None);
        assert_eq!(
            decide_cone(mu, false, 0, 1.0, 9.0, -1e-12),
            Some(Cone::Stick)
        );
        // No static friction, or the step's switches spent: no change.
        assert_eq!(
            decide_cone(Coulomb::FRICTIONLESS, true, 0, 1.0, 1.0, 0.0),
            None
        );
        assert_eq!(decide_cone(mu, true, MAX_SWITCHES, -1.0, 1.0, 0.0), None);
        // The planar decision is the cone's: the slip sign is against R_t.
        let stuck = Grip::Stick { anchor: [0.0; 2] };
        assert_eq!(
            decide_on(mu, stuck, 0, -0.02, -0.3, 0.0),
            Some(Switch::ToSlide { sign: 1.0 })
        );
        let sliding = Grip::Slide { sign: -1.0 };
        assert_eq!(
            decide_on(mu, sliding, 0, 1.0, 0.4, 0.2),
            Some(Switch::ToStick)
        );
    }

    #[test]
    fn pairs_override_the_default_in_either_order() {
        let t = FrictionTable {
            default: Coulomb {
                mu_s: 0.3,
                mu_k: 0.2,
            },
            pairs: vec![(
                "fruit".into(),
                "table".into(),
                Coulomb {
                    mu_s: 0.9,
                    mu_k: 0.8,
                },
            )],
        };
        assert_eq!(t.between("table", "fruit").mu_s, 0.9);
        assert_eq!(t.between("left", "fruit").mu_s, 0.3);
    }
}
