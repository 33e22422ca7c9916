//! The event interface between the 3D core and its recorders, on the pattern of
//! [`crate::events`]: the core never does I/O, it calls [`Observer3::on_event`] with borrowed
//! views of its own state at the end of each accepted step; a sink copies what it needs.
//! [`Sim3::step_observed`] is generic over the observer, so with [`NullObserver3`] the call
//! compiles away and a run pays nothing for the interface.

use super::energy::{material_frame, EdgeFrame};
use super::rod::{angle, pos};
use super::{Sim3, Solve3Error};

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
    Step {
        step: u64,
        time: f64,
        dt: f64,
        newton_iterations: u32,
        rods: &'a [Rod3StepView<'a>],
        contacts: &'a [Contact3],
    },
    End {
        steps: u64,
        time: f64,
    },
}

/// A sink of 3D events.
pub trait Observer3 {
    fn on_event(&mut self, e: &Event3<'_>);
}

/// Listens to nothing: with it, observing costs nothing.
pub struct NullObserver3;

impl Observer3 for NullObserver3 {
    #[inline(always)]
    fn on_event(&mut self, _: &Event3<'_>) {}
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
        });
        Ok(it)
    }
}
