//! 3D grippers built from one prong definition by symmetry, and their actuation.
//!
//! A prong is given in its finger frame: base at the origin, hanging along −z, closing along
//! +x (towards the gripper's axis). An n-finger radial gripper places finger k at angle
//! 2πk/n around the gripper axis (world z through `centre`), its closing direction towards
//! the axis; two fingers make the parallel gripper (fingers facing each other). The first
//! `clamped` edges of every finger are held by the hand.
//!
//! The hand follows a program of moves ([`Move3`]) like the planar actuation programs:
//! translate, rotate about an axis, close at a speed until the grip force reaches a target
//! (force-controlled squeeze), hold, lift. The grip force is read through a sensor: the mean
//! over the fingers of their summed normal reactions, low-pass filtered with time constant
//! `sensor_tau` (f ← f + Δt/(τ + Δt) (raw − f)), so the impact spike of first contact (of order
//! m v / Δt with the modified mass method) does not end a squeeze, as in the planar actuation. The clamped material angles keep their rest values: a rotation about an axis normal
//! to the clamped edge is carried by the reference frame's transport, one with a component
//! along the edge is not (a twist of the base is not an actuation here).

use super::rod::{angle, pos, Rod3, Rod3Spec};
use super::world::World3;
use super::Sim3;
use crate::obstacle3::V3;
use nalgebra::{Rotation3, Unit};

/// One move of the hand.
#[derive(Debug, Clone, PartialEq)]
pub enum Move3 {
    /// Close the fingers at `speed` (m/s) until the grip force reaches `force` (N) or the
    /// closing travel reaches `max_travel` (m).
    Squeeze {
        speed: f64,
        force: f64,
        max_travel: f64,
    },
    /// Open or close by `travel` (m, negative opens) over `duration`.
    Close {
        travel: f64,
        duration: f64,
    },
    Hold {
        duration: f64,
    },
    Translate {
        by: [f64; 3],
        duration: f64,
    },
    /// Lift along +z by `height` over `duration`.
    Lift {
        height: f64,
        duration: f64,
    },
    /// Rotate by `angle` (rad) about `axis` through the gripper centre over `duration`.
    Rotate {
        axis: [f64; 3],
        angle: f64,
        duration: f64,
    },
}

#[derive(Debug, Clone)]
pub struct Finger {
    pub rod: usize,
    /// Rest positions of the clamped nodes relative to the gripper centre (world, at rest).
    pub clamp_rest: Vec<V3>,
    /// Unit closing direction at rest (towards the axis).
    pub closing: V3,
}

#[derive(Debug, Clone)]
pub struct Gripper3 {
    pub fingers: Vec<Finger>,
    pub centre: V3,
    pub clamped_nodes: usize,
    pub moves: Vec<Move3>,
    /// Index of the current move and the time it began.
    pub current: usize,
    pub move_start: f64,
    /// Hand state: closing travel, translation and rotation of the hand.
    pub travel: f64,
    pub offset: V3,
    pub rotation: Rotation3<f64>,
    /// Time the squeeze reached its force (s).
    pub squeezed_at: Option<f64>,
    /// Time constant of the grip force sensor (s) and its reading (N).
    pub sensor_tau: f64,
    pub sensed: f64,
}

/// Build `n` fingers of `prong` (finger frame) around `centre` at `radius` and add them to the
/// world. Finger k's base sits at centre + radius (cos a, sin a, 0), a = 2πk/n.
pub fn radial(
    world: &mut World3,
    prong: &Rod3Spec,
    n: usize,
    radius: f64,
    centre: [f64; 3],
    clamped_edges: usize,
) -> Gripper3 {
    let c = V3::from(centre);
    let mut fingers = Vec::new();
    for k in 0..n {
        let a = 2.0 * std::f64::consts::PI * k as f64 / n as f64;
        // Local +x (closing) must point from the base towards the axis: −(cos a, sin a, 0).
        let rot =
            Rotation3::from_axis_angle(&Unit::new_normalize(V3::z()), a + std::f64::consts::PI);
        let base = V3::new(radius * a.cos(), radius * a.sin(), 0.0);
        let points: Vec<[f64; 3]> = prong
            .points
            .iter()
            .map(|p| (c + base + rot * V3::from(*p)).into())
            .collect();
        let spec = Rod3Spec {
            points,
            director: (rot * V3::from(prong.director)).into(),
            ..prong.clone()
        };
        let mut sim = Sim3::new(Rod3::new(&spec));
        for e in 0..clamped_edges {
            sim.clamp_edge(e);
        }
        let clamp_rest = (0..=clamped_edges)
            .map(|i| sim.rod.node(&sim.q, i).into())
            .map(|p: V3| p - c)
            .collect();
        let rod = world.add_rod(&format!("finger{k}"), sim, section_of(prong));
        fingers.push(Finger {
            rod,
            clamp_rest,
            closing: rot * V3::x(),
        });
    }
    Gripper3 {
        fingers,
        centre: c,
        clamped_nodes: clamped_edges + 1,
        moves: Vec::new(),
        current: 0,
        move_start: 0.0,
        travel: 0.0,
        offset: V3::zeros(),
        rotation: Rotation3::identity(),
        squeezed_at: None,
        sensor_tau: 0.01,
        sensed: 0.0,
    }
}

fn section_of(p: &Rod3Spec) -> super::Section3 {
    p.section
}

impl Gripper3 {
    /// Summed normal reaction on each finger (N).
    pub fn finger_forces(&self, world: &World3) -> Vec<f64> {
        self.fingers
            .iter()
            .map(|f| {
                let edges: f64 = world.edges[f.rod].iter().map(|e| e.force).sum();
                world.contacts[f.rod]
                    .iter()
                    .zip(&world.reactions[f.rod])
                    .filter_map(|(c, r)| c.map(|c| c.normal.dot(r)))
                    .sum::<f64>()
                    + edges
            })
            .collect()
    }

    /// Mean finger force.
    pub fn grip_force(&self, world: &World3) -> f64 {
        let f = self.finger_forces(world);
        f.iter().sum::<f64>() / f.len().max(1) as f64
    }

    /// Whether every move is done.
    pub fn done(&self) -> bool {
        self.current >= self.moves.len()
    }

    /// Advance the hand to time t1 = t + dt (the sensed grip force at the end of the last step
    /// decides a squeeze) and set the clamp targets of every finger.
    pub fn drive(&mut self, world: &mut World3, t1: f64, dt: f64) {
        let raw = self.grip_force(world);
        self.sensed += dt / (self.sensor_tau + dt) * (raw - self.sensed);
        self.advance(t1, dt, self.sensed);
        for f in &self.fingers {
            let sim = &mut world.rods[f.rod];
            for (i, rest) in f.clamp_rest.iter().enumerate() {
                let p =
                    self.centre + self.offset + self.rotation * (rest + f.closing * self.travel);
                sim.target[pos(i)..pos(i) + 3].copy_from_slice(p.as_slice());
                if i + 1 < f.clamp_rest.len() {
                    sim.target[angle(i)] = sim.rod.q0[angle(i)];
                }
            }
        }
    }

    fn advance(&mut self, t1: f64, dt: f64, grip: f64) {
        let Some(m) = self.moves.get(self.current).cloned() else {
            return;
        };
        let elapsed = t1 - self.move_start;
        let frac = |duration: f64| (dt / duration).min(1.0);
        let finished = match m {
            Move3::Squeeze {
                speed,
                force,
                max_travel,
            } => {
                if grip >= force || self.travel >= max_travel {
                    self.squeezed_at.get_or_insert(t1);
                    true
                } else {
                    self.travel = (self.travel + speed * dt).min(max_travel);
                    false
                }
            }
            Move3::Close { travel, duration } => {
                self.travel += travel * frac(duration);
                elapsed >= duration - 1e-12 * duration
            }
            Move3::Hold { duration } => elapsed >= duration - 1e-12 * duration,
            Move3::Translate { by, duration } => {
                self.offset += V3::from(by) * frac(duration);
                elapsed >= duration - 1e-12 * duration
            }
            Move3::Lift { height, duration } => {
                self.offset += V3::z() * (height * frac(duration));
                elapsed >= duration - 1e-12 * duration
            }
            Move3::Rotate {
                axis,
                angle,
                duration,
            } => {
                let ax = Unit::new_normalize(V3::from(axis));
                self.rotation =
                    Rotation3::from_axis_angle(&ax, angle * frac(duration)) * self.rotation;
                elapsed >= duration - 1e-12 * duration
            }
        };
        if finished {
            self.current += 1;
            self.move_start = t1;
        }
    }
}
