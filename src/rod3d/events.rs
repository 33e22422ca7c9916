//! The event interface between the 3D core and its recorders, on the pattern of
//! [`crate::events`]: the core never does I/O, it calls [`Observer3::on_event`] with borrowed
//! views of its own state at the end of each accepted step; a sink copies what it needs.
//! [`Sim3::step_observed`] is generic over the observer, so with [`NullObserver3`] the call
//! compiles away and a run pays nothing for the interface.

use super::contact3::{Grip3, Surface3};
use super::edge3::EdgeContact3;
use super::energy::{material_frame, EdgeFrame};
use super::rod::{angle, pos};
use super::section::Section3;
use super::{Sim3, Solve3Error, StepReport3, World3};
use crate::obstacle3::{Pose3, Shape3};

/// One contact of a 3D rod node at the end of a step (vectors in world coordinates, N and m).
/// The 3D contact model fills these; a rod alone has none.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Contact3 {
    pub rod: usize,
    pub node: usize,
    /// The contact point on the obstacle's surface.
    pub point: [f64; 3],
    /// Unit outward normal of the obstacle there.
    pub normal: [f64; 3],
    /// Normal reaction and friction force on the node.
    pub reaction: [f64; 3],
    pub friction: [f64; 3],
    /// Signed gap (negative: penetration before the projection).
    pub gap: f64,
    /// Index into the shapes of [`Event3::Scene`] (0 if unknown).
    pub surface: usize,
    /// Stuck (true) or sliding (false).
    pub stick: bool,
    /// n·R, the normal part of the reaction as the solver has it (N; `reaction` is n (n·R),
    /// whose projection on n can differ from it in the last bit).
    pub normal_reaction: f64,
    /// 0 for a node contact; for an edge contact (src/rod3d/edge3.rs) the weight s ∈ (0, 1) of
    /// its point (1 − s) x_node + s x_node+1 on the segment from `node`, whose reaction the two
    /// nodes share as (1 − s) and s (frictionless: `friction` is zero).
    pub weight: f64,
}

impl Contact3 {
    /// The normal part n·R of the reaction (N).
    pub fn normal_force(&self) -> f64 {
        self.normal_reaction
    }
}

/// One obstacle or free body of a 3D world, sent once after [`Event3::Start`]: its shape in its
/// own frame and its pose at t = 0.
#[derive(Debug, Clone, PartialEq)]
pub struct Shape3Info {
    pub name: String,
    pub shape: Shape3,
    pub pose: Pose3,
    /// A free body (its pose is sent with each step), not a fixed obstacle.
    pub free: bool,
}

/// The pose and velocity of a free body at the end of a step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BodyPose3 {
    /// Index into the shapes of [`Event3::Scene`].
    pub shape: usize,
    pub position: [f64; 3],
    /// Unit quaternion [x, y, z, w] of the body's rotation.
    pub rotation: [f64; 4],
    pub velocity: [f64; 3],
    pub angular_velocity: [f64; 3],
}

/// A node that came into contact (`added`) or left it during a step (a node released and
/// caught again within one step is neither).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ContactChange3 {
    pub rod: usize,
    pub node: usize,
    pub added: bool,
}

/// Static facts about one 3D rod, sent once before the first step.
#[derive(Debug, Clone, PartialEq)]
pub struct Rod3Info {
    pub name: String,
    pub nodes: usize,
    pub rest_length: Vec<f64>,
    /// Section extents along m₁ (h) and m₂ (b) for drawing the material frame (m).
    pub half_extents: [f64; 2],
}

/// The state of one 3D rod at the end of a step. `q` and `v` are the DOFs x₀, θ₀, x₁, θ₁, …
/// (see [`super::rod`]); `frames` the reference frames of the edges, `ref_twist` the
/// reference twist at each node (0 at the ends).
#[derive(Debug, Clone, Copy)]
pub struct Rod3StepView<'a> {
    pub q: &'a [f64],
    pub v: &'a [f64],
    pub frames: &'a [EdgeFrame],
    pub ref_twist: &'a [f64],
}

impl Rod3StepView<'_> {
    pub fn nodes(&self) -> usize {
        self.q.len().div_ceil(4)
    }
    pub fn node(&self, i: usize) -> [f64; 3] {
        [self.q[pos(i)], self.q[pos(i) + 1], self.q[pos(i) + 2]]
    }
    pub fn velocity(&self, i: usize) -> [f64; 3] {
        [self.v[pos(i)], self.v[pos(i) + 1], self.v[pos(i) + 2]]
    }
    /// Material angle of edge i relative to its reference frame.
    pub fn theta(&self, i: usize) -> f64 {
        self.q[angle(i)]
    }
    /// Material frame (m₁, m₂) of edge i.
    pub fn material_frame(&self, i: usize) -> ([f64; 3], [f64; 3]) {
        material_frame(&self.frames[i], self.theta(i))
    }
    /// Twist θᵢ − θᵢ₋₁ + m_ref at interior node i (0 at the ends).
    pub fn twist(&self, i: usize) -> f64 {
        if i == 0 || i + 1 >= self.nodes() {
            return 0.0;
        }
        self.theta(i) - self.theta(i - 1) + self.ref_twist[i]
    }
}

/// What the 3D core reports.
#[derive(Debug, Clone, Copy)]
pub enum Event3<'a> {
    Start {
        rods: &'a [Rod3Info],
    },
    /// The obstacles (first) and free bodies of a world, right after `Start`.
    Scene {
        shapes: &'a [Shape3Info],
    },
    Step {
        step: u64,
        time: f64,
        dt: f64,
        newton_iterations: u32,
        rods: &'a [Rod3StepView<'a>],
        contacts: &'a [Contact3],
        /// The free bodies' poses (empty for a rod alone).
        bodies: &'a [BodyPose3],
        /// Contacts made and lost in this step.
        changes: &'a [ContactChange3],
        /// Corrector passes and stick/slip switches of the step.
        passes: u32,
        switches: u32,
    },
    /// The run's end: after the last step, or after the last accepted step of a run that
    /// failed (`error` says why).
    End {
        steps: u64,
        time: f64,
        error: Option<&'a str>,
    },
}

/// A sink of 3D events.
pub trait Observer3 {
    fn on_event(&mut self, e: &Event3<'_>);
    /// Whether this sink listens to steps at all (false: the world builds no step event).
    fn wants_steps(&self) -> bool {
        true
    }
}

/// Listens to nothing: with it, observing costs nothing.
pub struct NullObserver3;

impl Observer3 for NullObserver3 {
    #[inline(always)]
    fn on_event(&mut self, _: &Event3<'_>) {}
    #[inline(always)]
    fn wants_steps(&self) -> bool {
        false
    }
}

/// Any number of sinks, each sent every event in turn.
#[derive(Default)]
pub struct Observers3<'s> {
    pub sinks: Vec<&'s mut dyn Observer3>,
}

impl Observer3 for Observers3<'_> {
    fn on_event(&mut self, e: &Event3<'_>) {
        for s in self.sinks.iter_mut() {
            s.on_event(e);
        }
    }
    fn wants_steps(&self) -> bool {
        self.sinks.iter().any(|s| s.wants_steps())
    }
}

impl Sim3 {
    /// Static facts of this rod for [`Event3::Start`].
    pub fn info(&self, name: &str, half_extents: [f64; 2]) -> Rod3Info {
        Rod3Info {
            name: name.to_string(),
            nodes: self.rod.n,
            rest_length: self.rod.rest_length.clone(),
            half_extents,
        }
    }

    /// The current state as a step view.
    pub fn view(&self) -> Rod3StepView<'_> {
        Rod3StepView {
            q: &self.q,
            v: &self.v,
            frames: &self.frames,
            ref_twist: &self.ref_twist,
        }
    }

    /// [`Sim3::step`], then an [`Event3::Step`] (step number `step`) for `obs`.
    pub fn step_observed<O: Observer3>(
        &mut self,
        dt: f64,
        step: u64,
        obs: &mut O,
    ) -> Result<u32, Solve3Error> {
        let it = self.step(dt)?;
        let rods = [self.view()];
        obs.on_event(&Event3::Step {
            step,
            time: self.time,
            dt,
            newton_iterations: it,
            rods: &rods,
            contacts: &[],
            bodies: &[],
            changes: &[],
            passes: 1,
            switches: 0,
        });
        Ok(it)
    }
}

/// Half extents of a section along m₁ and m₂ (m).
pub fn half_extents(s: &Section3) -> [f64; 2] {
    match *s {
        Section3::Rect { b, h } => [0.5 * h, 0.5 * b],
        Section3::Circle { r } => [r, r],
    }
}

/// The buffers a world reuses to describe its steps to observers (allocated only while some
/// observer listens to steps).
#[derive(Debug, Default)]
pub struct Emit3 {
    contacts: Vec<Contact3>,
    bodies: Vec<BodyPose3>,
    changes: Vec<ContactChange3>,
    /// Whether each node of each rod was in contact at the end of the last step sent.
    before: Vec<Vec<bool>>,
}

impl World3 {
    /// The fixed obstacles, then the free bodies, as drawn: name, shape, pose at start, free.
    pub fn shape_infos(&self) -> Vec<Shape3Info> {
        self.obstacles
            .iter()
            .map(|o| (o, false))
            .chain(self.bodies.iter().map(|b| (&b.obstacle, true)))
            .map(|(o, free)| Shape3Info {
                name: o.name.clone(),
                shape: o.shape.clone(),
                pose: o.pose,
                free,
            })
            .collect()
    }

    /// The rods' static facts and the world's shapes: [`Event3::Start`] then [`Event3::Scene`].
    pub fn start_observed<O: Observer3>(&self, emit: &mut Emit3, obs: &mut O) {
        let rods: Vec<Rod3Info> = self
            .rods
            .iter()
            .zip(&self.rod_names)
            .zip(&self.sections)
            .map(|((sim, name), sec)| sim.info(name, half_extents(sec)))
            .collect();
        obs.on_event(&Event3::Start { rods: &rods });
        let shapes = self.shape_infos();
        obs.on_event(&Event3::Scene { shapes: &shapes });
        emit.before = self.contacts.iter().map(|c| vec![false; c.len()]).collect();
        for (r, cs) in self.contacts.iter().enumerate() {
            for (i, c) in cs.iter().enumerate() {
                emit.before[r][i] = c.is_some();
            }
        }
    }

    /// [`World3::step`], then (if `obs` listens to steps) an [`Event3::Step`] with the rods,
    /// contacts, body poses and contact changes. With [`NullObserver3`] this is `step`.
    pub fn step_observed<O: Observer3>(
        &mut self,
        dt: f64,
        emit: &mut Emit3,
        obs: &mut O,
    ) -> Result<StepReport3, Solve3Error> {
        let rep = self.step(dt)?;
        if obs.wants_steps() {
            self.fill(emit);
            let rods: Vec<Rod3StepView<'_>> = self.rods.iter().map(|s| s.view()).collect();
            obs.on_event(&Event3::Step {
                step: self.steps,
                time: self.time,
                dt,
                newton_iterations: rep.newton_iterations,
                rods: &rods,
                contacts: &emit.contacts,
                bodies: &emit.bodies,
                changes: &emit.changes,
                passes: rep.passes,
                switches: rep.switches,
            });
        }
        Ok(rep)
    }

    /// The initial state as step 0 (an [`Event3::Step`] with `dt` 0, no Newton iterations, no
    /// contact changes), after [`World3::start_observed`], if `obs` listens to steps: a
    /// recording then holds where the run started, as the planar one does.
    pub fn initial_observed<O: Observer3>(&self, emit: &mut Emit3, obs: &mut O) {
        if !obs.wants_steps() {
            return;
        }
        self.fill(emit);
        let rods: Vec<Rod3StepView<'_>> = self.rods.iter().map(|s| s.view()).collect();
        obs.on_event(&Event3::Step {
            step: self.steps,
            time: self.time,
            dt: 0.0,
            newton_iterations: 0,
            rods: &rods,
            contacts: &emit.contacts,
            bodies: &emit.bodies,
            changes: &emit.changes,
            passes: 0,
            switches: 0,
        });
    }

    /// [`Event3::End`].
    pub fn end_observed<O: Observer3>(&self, obs: &mut O) {
        obs.on_event(&Event3::End {
            steps: self.steps,
            time: self.time,
            error: None,
        });
    }

    /// [`Event3::End`] of a run that failed after its last accepted step.
    pub fn fail_observed<O: Observer3>(&self, obs: &mut O, error: &str) {
        obs.on_event(&Event3::End {
            steps: self.steps,
            time: self.time,
            error: Some(error),
        });
    }

    /// An edge contact at the end of a step: the surface point under its held point.
    fn edge_view(&self, r: usize, e: &EdgeContact3, nobs: usize) -> Contact3 {
        let o = match e.surface {
            Surface3::Obstacle(k) => &self.obstacles[k],
            Surface3::Body(b) => &self.bodies[b].obstacle,
        };
        let prox = o.query(&e.held_point(&self.rods[r].q));
        Contact3 {
            rod: r,
            node: e.segment,
            point: prox.closest.into(),
            normal: e.normal.into(),
            reaction: e.total_force().into(),
            friction: e.friction.into(),
            gap: prox.distance - e.offset,
            surface: match e.surface {
                Surface3::Obstacle(k) => k,
                Surface3::Body(b) => nobs + b,
            },
            stick: matches!(e.grip, super::contact3::Grip3::Stick { .. }),
            normal_reaction: e.force,
            weight: e.weight,
        }
    }

    /// The contacts, bodies and changes of the step just taken, into `emit`'s buffers.
    fn fill(&self, emit: &mut Emit3) {
        emit.contacts.clear();
        emit.changes.clear();
        emit.bodies.clear();
        if emit.before.len() != self.contacts.len() {
            emit.before = self.contacts.iter().map(|c| vec![false; c.len()]).collect();
        }
        let nobs = self.obstacles.len();
        for (r, cs) in self.contacts.iter().enumerate() {
            let q = &self.rods[r].q;
            for (i, c) in cs.iter().enumerate() {
                let now = c.is_some();
                if now != emit.before[r][i] {
                    emit.changes.push(ContactChange3 {
                        rod: r,
                        node: i,
                        added: now,
                    });
                    emit.before[r][i] = now;
                }
                let Some(c) = c else { continue };
                let x = [q[pos(i)], q[pos(i) + 1], q[pos(i) + 2]];
                let n = c.normal;
                let re = self.reactions[r][i];
                let rn = n.dot(&re);
                let fr = re - n * rn;
                let o = match c.surface {
                    Surface3::Obstacle(k) => &self.obstacles[k],
                    Surface3::Body(b) => &self.bodies[b].obstacle,
                };
                let prox = o.query(&crate::obstacle3::V3::from(x));
                emit.contacts.push(Contact3 {
                    rod: r,
                    node: i,
                    point: prox.closest.into(),
                    normal: n.into(),
                    reaction: (n * rn).into(),
                    friction: fr.into(),
                    gap: prox.distance - c.offset,
                    surface: match c.surface {
                        Surface3::Obstacle(k) => k,
                        Surface3::Body(b) => nobs + b,
                    },
                    stick: matches!(c.grip, Grip3::Stick { .. }),
                    normal_reaction: rn,
                    weight: 0.0,
                });
            }
            for e in &self.edges[r] {
                emit.contacts.push(self.edge_view(r, e, nobs));
            }
        }
        for (b, body) in self.bodies.iter().enumerate() {
            let p = body.obstacle.pose;
            let qt = nalgebra::UnitQuaternion::from_rotation_matrix(&p.rotation);
            emit.bodies.push(BodyPose3 {
                shape: nobs + b,
                position: p.position.into(),
                rotation: [qt.i, qt.j, qt.k, qt.w],
                velocity: body.v.into(),
                angular_velocity: body.omega().into(),
            });
        }
    }
}
