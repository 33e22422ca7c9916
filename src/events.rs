//! The one event interface between the physics core and everything that records or
//! summarises a run.
//!
//! The core never does I/O. It calls [`Observer::on_event`] with borrowed views of its own
//! state; a sink copies what it needs. Building an event costs nothing beyond a few
//! references, and the per-iteration events (which carry the Newton iterate) are only built
//! when [`Observer::wants_iterations`] says somebody listens. The solver is generic over the
//! observer, so with [`NullObserver`] every call compiles away.

/// Which pass of the modified mass method produced a Newton iteration.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Phase {
    /// The first solve of a step, with the constraint set carried over from the last step.
    Predictor,
    /// A re-solve after the constraint set changed (new penetration or adhesive release).
    Corrector,
    /// A load increment of a static solve.
    Static,
}

impl Phase {
    pub fn as_str(self) -> &'static str {
        match self {
            Phase::Predictor => "predictor",
            Phase::Corrector => "corrector",
            Phase::Static => "static",
        }
    }
}

/// Why a constraint was released.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ReleaseReason {
    /// The eq. 2 reaction pulled the node into the obstacle (R·n < 0).
    Adhesive,
    /// Edge mode: a segment beside the node went into the same surface, and its edge contact
    /// took the contact from the node (docs/model.md, "Edge contact").
    HandedOver,
}

/// Static facts about the run, sent once before the first step.
#[derive(Debug, Clone)]
pub struct RunInfo<'a> {
    /// 2 (planar) or 3 (spatial): the stride of every per-node vector of the run's events.
    pub dimension: u8,
    pub scenario_name: &'a str,
    /// The scenario as TOML text (with `--set` overrides applied).
    pub scenario_text: &'a str,
    pub rods: &'a [RodInfo],
    /// What to draw and where the bodies start.
    pub scene: Scene<'a>,
    /// The obstacles' names (`obstacle.<i>` unless named).
    pub obstacle_names: &'a [String],
    /// Free bodies (fruit): which obstacle each carries, its mass and inertia (in 3D the
    /// centroid, weight and velocity hold their x and y components, the inertia is the
    /// trace's mean).
    pub bodies: &'a [crate::world::body::BodySpec],
    pub mode: crate::scenario::Mode,
}

/// The obstacles and bodies of a run, as its mechanics knows them.
#[derive(Debug, Clone, Copy)]
pub enum Scene<'a> {
    /// The planar obstacles (the free bodies' shapes among them).
    Planar {
        obstacles: &'a [crate::obstacle::Obstacle],
    },
    /// The 3D obstacles (first) and free bodies: shape, pose at t = 0, free or fixed.
    Spatial {
        shapes: &'a [crate::rod3d::events::Shape3Info],
    },
}

impl<'a> RunInfo<'a> {
    /// The planar obstacles (none in a 3D run).
    pub fn planar_obstacles(&self) -> &'a [crate::obstacle::Obstacle] {
        match self.scene {
            Scene::Planar { obstacles } => obstacles,
            Scene::Spatial { .. } => &[],
        }
    }
}

/// The x and y components of a dim-tagged 3-vector (a planar reader's view of it).
#[inline]
pub fn xy(v: [f64; 3]) -> [f64; 2] {
    [v[0], v[1]]
}

/// A planar 2-vector as a dim-tagged 3-vector (z = 0).
#[inline]
pub fn v3(v: [f64; 2]) -> [f64; 3] {
    [v[0], v[1], 0.0]
}

/// Static facts about one rod.
#[derive(Debug, Clone)]
pub struct RodInfo {
    pub name: String,
    pub nodes: usize,
    /// Node masses (kg).
    pub mass: Vec<f64>,
    /// True for nodes whose motion is prescribed by the drive.
    pub clamped: Vec<bool>,
    /// Rest edge lengths (m), `nodes - 1` of them.
    pub rest_length: Vec<f64>,
    /// Rest turning angle measure κ̄ = 2 tan(φ̄/2) at each node (0 at the ends).
    pub rest_curvature: Vec<f64>,
    /// Young's modulus (Pa), section area (m²), second moment (m⁴), and the section's
    /// half-height in the bending plane (m) used for bending stress.
    pub youngs_modulus: f64,
    pub area: f64,
    pub inertia: f64,
    pub half_height: f64,
    /// A single-node `[[particle]]`.
    pub particle: bool,
}

/// The state of one rod at the end of a step. All vectors are interleaved with stride `dim`:
/// `[x0, y0, x1, y1, …]` in 2D, `[x0, y0, z0, x1, …]` in 3D.
#[derive(Debug, Clone, Copy)]
pub struct RodStepView<'a> {
    /// 2 or 3: the stride of `q`, `u`, `reaction`, `impulse`, `drive_force`, `normal`,
    /// `normal2` and `q_predictor`.
    pub dim: u8,
    pub q: &'a [f64],
    pub u: &'a [f64],
    /// Eq. 2 reaction on each constrained node (N); zero for unconstrained nodes.
    pub reaction: &'a [f64],
    /// Contact impulse on each node over this step (N·s): reaction × dt.
    pub impulse: &'a [f64],
    /// Force the drive applies to each clamped node (N), from eq. 2; zero on free nodes.
    pub drive_force: &'a [f64],
    /// Outward obstacle normal at each constrained node; zero when not in contact.
    pub normal: &'a [f64],
    /// Which obstacle each node is constrained against (`usize::MAX` when free).
    pub contact_obstacle: &'a [usize],
    /// Outward normal of the second surface of a node held at the corner of two obstacles;
    /// zero when the node is held against one surface or none.
    pub normal2: &'a [f64],
    /// The second obstacle of a corner (`usize::MAX` when none).
    pub contact_obstacle2: &'a [usize],
    /// True for nodes constrained at the end of the step.
    pub in_contact: &'a [bool],
    /// Bending stress σ = E |κ − κ̄| / Δl · h/2 (Pa) at each node (0 at the ends).
    pub bending_stress: &'a [f64],
    /// Signed distance of each node to the nearest obstacle at the end of the step (m);
    /// `f64::INFINITY` when there is no obstacle.
    pub gap: &'a [f64],
    /// Predictor position of each node in this step (before any corrector pass).
    pub q_predictor: &'a [f64],
    /// Twist stress τ = G J |τ_twist| / (J / r_max) … of each node (Pa) in 3D; empty in 2D.
    pub twist_stress: &'a [f64],
    /// The material frames of a 3D rod; None in 2D.
    pub frames: Option<FrameView<'a>>,
}

/// A 3D rod's material frames at the end of a step.
#[derive(Debug, Clone, Copy)]
pub struct FrameView<'a> {
    /// Material angle θ of each edge relative to its reference frame (rad), `nodes − 1`.
    pub theta: &'a [f64],
    /// Twist θᵢ − θᵢ₋₁ + m_ref at each node (rad; 0 at the ends), `nodes`.
    pub twist: &'a [f64],
    /// First material director m₁ of each edge, `3 (nodes − 1)`.
    pub m1: &'a [f64],
}

/// A constraint added or released inside a step.
#[derive(Debug, Clone, Copy)]
pub struct ContactChange {
    pub step: u64,
    pub t: f64,
    /// Corrector pass that the change leads into (1 for the first corrector).
    pub pass: u32,
    pub rod: usize,
    pub node: usize,
    pub obstacle: usize,
    /// The outward normal (z = 0 in 2D).
    pub normal: [f64; 3],
    /// Signed distance of the predicted node position when it was detected (negative inside).
    pub gap: f64,
    /// Eq. 2 reaction of the node at the moment of release (zero when added; z = 0 in 2D).
    pub reaction: [f64; 3],
    /// Prescribed normal velocity change of the corrector (m/s) for an added constraint.
    pub z: f64,
}

/// A contact switched between stick and slip (decided from its eq. 2 reaction).
#[derive(Debug, Clone, Copy)]
pub struct FrictionChange {
    pub step: u64,
    pub t: f64,
    /// Corrector pass that the change leads into.
    pub pass: u32,
    /// The rod, or `usize::MAX` for a free body's own contact (then `node` is the body).
    pub rod: usize,
    pub node: usize,
    pub obstacle: usize,
    /// True for slip → stick, false for stick → slip.
    pub stuck: bool,
    /// Normal and tangential reaction when it switched (N).
    pub normal_force: f64,
    pub tangential_force: f64,
    /// Slip velocity along the contact tangent, relative to the surface (m/s).
    pub slip_velocity: f64,
    /// An edge contact's switch: its segment (= `node`) and the weight s of its point
    /// (1 − s) x_i + s x_{i+1}; `usize::MAX` and 0 for a node's or a body's own contact.
    pub segment: usize,
    pub weight: f64,
}

/// One active contact at the end of a step, with its friction state. Vectors hold 3
/// components, z = 0 in 2D; serialised with `dim` of them.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ContactView {
    /// The rod, or `usize::MAX` for a free body's own contact with a fixed obstacle (then
    /// `node` is the body's index); serialised as null then.
    pub rod: usize,
    pub node: usize,
    pub obstacle: usize,
    /// The free body the surface belongs to (`usize::MAX` for a fixed obstacle: null).
    pub body: usize,
    pub point: [f64; 3],
    pub normal: [f64; 3],
    /// The direction the friction force is measured along: t = (−n_y, n_x, 0) in 2D; in 3D
    /// the unit direction of the friction force on the rod (zero without friction).
    pub tangent: [f64; 3],
    /// Normal reaction (N, ≥ 0 when pressed) and tangential (friction) reaction along
    /// `tangent` (N; ≥ 0 in 3D).
    pub normal_force: f64,
    pub friction_force: f64,
    /// Slip velocity along `tangent` relative to the surface (m/s).
    pub slip_velocity: f64,
    pub stuck: bool,
    /// |R_t| / (μ_s R_n); 0 when frictionless.
    pub utilisation: f64,
    pub mu_s: f64,
    /// A compliant fruit's contact (Hertz line contact, docs/model.md): how far the face
    /// presses into the undeformed fruit (m), the contact half-width a (m) and, of an
    /// elliptical 3D patch, its minor half-width b ≤ a (m; = `half_width` in 2D), the peak
    /// pressure p₀ (Pa), the fruit's bruise threshold (Pa) and the half-width of the part of
    /// the contact above it (m). All 0 at a rigid obstacle (its pressure is not modelled).
    pub indentation: f64,
    pub half_width: f64,
    pub half_width_minor: f64,
    pub peak_pressure: f64,
    pub bruise_pressure: f64,
    pub bruise_half_width: f64,
    /// An edge contact (`[contact] points = "edges"`): the segment (its first node; `node` is
    /// the same) and the barycentric weight s of the contact point (1 − s) x_i + s x_{i+1},
    /// whose normal force is shared (1 − s, s) by the two nodes. Null and 0 for a node's
    /// contact.
    pub segment: usize,
    pub weight: f64,
    /// A conforming contact arc (edge mode, a compliant fruit): the first and last node of the
    /// arc's segments, every node of which shares its load. Null for any other contact.
    pub first: usize,
    pub last: usize,
    /// 2 or 3: how many components of `point`, `normal` and `tangent` are the run's.
    pub dim: u8,
}

impl ContactView {
    /// A planar view with nothing in it: no rod, obstacle or body, zero forces, no compliant
    /// contact, no segment (the defaults a builder fills in with `..BLANK`).
    pub const BLANK: ContactView = ContactView {
        rod: usize::MAX,
        node: 0,
        obstacle: usize::MAX,
        body: usize::MAX,
        point: [0.0; 3],
        normal: [0.0; 3],
        tangent: [0.0; 3],
        normal_force: 0.0,
        friction_force: 0.0,
        slip_velocity: 0.0,
        stuck: false,
        utilisation: 0.0,
        mu_s: 0.0,
        indentation: 0.0,
        half_width: 0.0,
        half_width_minor: 0.0,
        peak_pressure: 0.0,
        bruise_pressure: 0.0,
        bruise_half_width: 0.0,
        segment: usize::MAX,
        weight: 0.0,
        first: usize::MAX,
        last: usize::MAX,
        dim: 2,
    };
}

impl serde::Serialize for ContactView {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeStruct;
        let d = if self.dim == 3 { 3 } else { 2 };
        let idx = |i: usize| (i != usize::MAX).then_some(i as u64);
        let mut m = s.serialize_struct("ContactView", 24)?;
        m.serialize_field("rod", &idx(self.rod))?;
        m.serialize_field("node", &self.node)?;
        m.serialize_field("obstacle", &self.obstacle)?;
        m.serialize_field("body", &idx(self.body))?;
        m.serialize_field("point", &self.point[..d])?;
        m.serialize_field("normal", &self.normal[..d])?;
        m.serialize_field("tangent", &self.tangent[..d])?;
        m.serialize_field("normal_force", &self.normal_force)?;
        m.serialize_field("friction_force", &self.friction_force)?;
        m.serialize_field("slip_velocity", &self.slip_velocity)?;
        m.serialize_field("stuck", &self.stuck)?;
        m.serialize_field("utilisation", &self.utilisation)?;
        m.serialize_field("mu_s", &self.mu_s)?;
        m.serialize_field("indentation", &self.indentation)?;
        m.serialize_field("half_width", &self.half_width)?;
        m.serialize_field("half_width_minor", &self.half_width_minor)?;
        m.serialize_field("peak_pressure", &self.peak_pressure)?;
        m.serialize_field("bruise_pressure", &self.bruise_pressure)?;
        m.serialize_field("bruise_half_width", &self.bruise_half_width)?;
        m.serialize_field("segment", &idx(self.segment))?;
        m.serialize_field("weight", &self.weight)?;
        m.serialize_field("first", &idx(self.first))?;
        m.serialize_field("last", &idx(self.last))?;
        m.serialize_field("dim", &self.dim)?;
        m.end()
    }
}

/// A joint (`[[joint]]`) at the end of a step: what member a passes to member b there.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize)]
pub struct JointView {
    /// The members (rod indices) and their joined nodes.
    pub rods: [usize; 2],
    pub nodes: [usize; 2],
    /// The force member a exerts on member b (N).
    pub force: [f64; 2],
    /// The bending moment a rigid joint carries (N·m; 0 for a pin), positive when member b
    /// is turned counter-clockwise from its rest angle to member a.
    pub moment: f64,
}

/// A free body at the end of a step. Vectors hold 3 components (z = 0 in 2D; a planar
/// rotation and its rates are about z).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct BodyView<'a> {
    pub name: &'a str,
    pub obstacle: usize,
    /// Centroid (m), and rotation from the shape as given: the planar angle (rad, about z;
    /// 0 in 3D) and the unit quaternion [x, y, z, w].
    pub position: [f64; 3],
    pub angle: f64,
    pub rotation: [f64; 4],
    pub velocity: [f64; 3],
    pub angular_velocity: [f64; 3],
    /// Net contact force (N) and torque about the centroid (N·m) on the body over the step:
    /// from the prongs and from fixed obstacles.
    pub contact_force: [f64; 3],
    pub contact_torque: [f64; 3],
    pub mass: f64,
}

/// The unit quaternion [x, y, z, w] of a rotation by `angle` about z.
pub fn about_z(angle: f64) -> [f64; 4] {
    let (s, c) = (0.5 * angle).sin_cos();
    [0.0, 0.0, s, c]
}

/// One event of the run.
#[derive(Debug, Clone, Copy)]
pub enum Event<'a> {
    RunStart(&'a RunInfo<'a>),
    StepBegin {
        step: u64,
        t: f64,
        dt: f64,
    },
    /// One Newton iteration of one rod. Only sent when [`Observer::wants_iterations`].
    Iteration {
        step: u64,
        t: f64,
        phase: Phase,
        /// 0 for the predictor, 1.. for corrector passes, load increment for static solves.
        pass: u32,
        /// 1-based Newton iteration number within the pass.
        iteration: u32,
        rod: usize,
        /// Max-norm of the force residual on the free DOFs (N) at the start of this iteration.
        residual: f64,
        /// Max-norm of the Newton update (m).
        update: f64,
        /// The iterate after this iteration's update (interleaved positions, all nodes).
        q: &'a [f64],
    },
    ConstraintAdded(ContactChange),
    ConstraintReleased(ContactChange, ReleaseReason),
    /// A contact switched between stick and slip.
    FrictionChanged(FrictionChange),
    /// A free body's own contact with a fixed obstacle was added or released.
    BodyContactChanged {
        step: u64,
        t: f64,
        pass: u32,
        body: usize,
        obstacle: usize,
        /// The body's contact point (a polygon vertex index; 0 for round shapes).
        feature: usize,
        added: bool,
        normal: [f64; 3],
        /// Normal and tangential reaction when released (N; the third component 0 in 2D,
        /// the second the tangential magnitude in 3D).
        reaction: [f64; 3],
    },
    /// An actuation program moved to its next phase (`to` = None: the program ended).
    PhaseChanged {
        step: u64,
        t: f64,
        actuator: usize,
        from: usize,
        to: Option<usize>,
        name: &'a str,
        reason: &'a str,
    },
    /// The step size changed (proximity switch, back-off after a failure, or recovery).
    DtChanged {
        step: u64,
        t: f64,
        old: f64,
        new: f64,
        reason: &'a str,
    },
    /// Newton failed on a step; the step is retried with a smaller dt.
    NewtonFailed {
        step: u64,
        t: f64,
        dt: f64,
        rod: usize,
        node: usize,
        residual: f64,
        reason: &'a str,
    },
    /// Something the user should know that does not stop the run.
    Warning {
        step: u64,
        t: f64,
        message: &'a str,
    },
    /// End of an accepted step: the full state.
    StepEnd {
        step: u64,
        /// Time at the end of the step (s).
        t: f64,
        dt: f64,
        /// Newton iterations spent on this step (all rods, passes and retries).
        newton_iterations: u32,
        /// Corrector passes spent on this step.
        passes: u32,
        rods: &'a [RodStepView<'a>],
        /// Free bodies (fruit).
        bodies: &'a [BodyView<'a>],
        /// Every active contact, with its forces and friction state.
        contacts: &'a [ContactView],
        /// Every joint's force and moment (empty without `[[joint]]`s).
        joints: &'a [JointView],
    },
    /// The run ended; `error` is set when it stopped on a failure.
    RunEnd {
        steps: u64,
        t: f64,
        error: Option<&'a str>,
    },
}

/// Anything that listens to a run.
pub trait Observer {
    /// Whether per-iteration events should be built. Default: no.
    fn wants_iterations(&self) -> bool {
        false
    }
    /// Whether step-end state (and the initial state) should be built. Default: yes.
    fn wants_steps(&self) -> bool {
        true
    }
    fn on_event(&mut self, event: &Event<'_>);
}

/// Listens to nothing; the solver specialised on it does no event work at all.
#[derive(Debug, Default, Clone, Copy)]
pub struct NullObserver;

impl Observer for NullObserver {
    fn wants_steps(&self) -> bool {
        false
    }
    #[inline(always)]
    fn on_event(&mut self, _event: &Event<'_>) {}
}

/// Sends every event to several observers in order.
#[derive(Default)]
pub struct Fanout<'s> {
    pub sinks: Vec<&'s mut dyn Observer>,
}

impl<'s> Fanout<'s> {
    pub fn new() -> Self {
        Self { sinks: Vec::new() }
    }
    pub fn push(&mut self, sink: &'s mut dyn Observer) {
        self.sinks.push(sink);
    }
}

impl Observer for Fanout<'_> {
    fn wants_iterations(&self) -> bool {
        self.sinks.iter().any(|s| s.wants_iterations())
    }
    fn wants_steps(&self) -> bool {
        self.sinks.iter().any(|s| s.wants_steps())
    }
    fn on_event(&mut self, event: &Event<'_>) {
        for s in self.sinks.iter_mut() {
            s.on_event(event);
        }
    }
}

impl<T: Observer + ?Sized> Observer for &mut T {
    fn wants_iterations(&self) -> bool {
        (**self).wants_iterations()
    }
    fn wants_steps(&self) -> bool {
        (**self).wants_steps()
    }
    fn on_event(&mut self, event: &Event<'_>) {
        (**self).on_event(event)
    }
}

impl Event<'_> {
    /// A one-line text for the events of friction, the bodies' own contacts and actuation
    /// phases (the sinks log them as text).
    pub fn describe(&self) -> Option<(u64, f64, String)> {
        match *self {
            Event::FrictionChanged(f) => {
                let who = if f.rod == usize::MAX {
                    format!("body {}", f.node)
                } else if f.segment != usize::MAX {
                    format!("rod {} segment {} (s = {:.4})", f.rod, f.segment, f.weight)
                } else {
                    format!("rod {} node {}", f.rod, f.node)
                };
                Some((
                    f.step,
                    f.t,
                    format!(
                        "step {}: {who} on obstacle.{} {} (R_n {:.4} N, R_t {:.4} N, slip {:.3e} m/s)",
                        f.step,
                        f.obstacle,
                        if f.stuck { "slip → stick" } else { "stick → slip" },
                        f.normal_force,
                        f.tangential_force,
                        f.slip_velocity
                    ),
                ))
            }
            Event::BodyContactChanged {
                step,
                t,
                body,
                obstacle,
                feature,
                added,
                reaction,
                ..
            } => Some((
                step,
                t,
                format!(
                    "step {step}: body {body} point {feature} {} obstacle.{obstacle}{}",
                    if added { "touches" } else { "leaves" },
                    if added {
                        String::new()
                    } else {
                        format!(" (R_n {:.4} N)", reaction[0])
                    }
                ),
            )),
            Event::PhaseChanged {
                step,
                t,
                actuator,
                from,
                to,
                name,
                reason,
            } => Some((
                step,
                t,
                match to {
                    Some(k) => format!(
                        "step {step}: actuator {actuator} phase {from} → {k} ({name}): {reason}"
                    ),
                    None => format!(
                        "step {step}: actuator {actuator} phase {from} ended, program complete: {reason}"
                    ),
                },
            )),
            _ => None,
        }
    }
}

/// An [`Event::StepEnd`]'s state, owned, for an observer that sends a step on later or from
/// another thread (the `--detail auto` layer holds steps back until it knows whether a window
/// opens; the MCAP sink hands steps to its writer thread). [`Self::set`] reuses the buffers.
#[derive(Debug, Clone, Default)]
pub struct OwnedStepEnd {
    pub step: u64,
    pub t: f64,
    pub dt: f64,
    pub newton_iterations: u32,
    pub passes: u32,
    pub rods: Vec<OwnedRodStep>,
    pub bodies: Vec<OwnedBody>,
    pub contacts: Vec<ContactView>,
    pub joints: Vec<JointView>,
}

impl OwnedStepEnd {
    /// Copy a [`Event::StepEnd`]; any other event leaves `self` as it was and gives false.
    pub fn set(&mut self, ev: &Event<'_>) -> bool {
        let Event::StepEnd {
            step,
            t,
            dt,
            newton_iterations,
            passes,
            rods,
            bodies,
            contacts,
            joints,
        } = *ev
        else {
            return false;
        };
        (self.step, self.t, self.dt) = (step, t, dt);
        (self.newton_iterations, self.passes) = (newton_iterations, passes);
        self.rods.resize_with(rods.len(), Default::default);
        for (d, v) in self.rods.iter_mut().zip(rods) {
            d.set(v);
        }
        self.bodies.resize_with(bodies.len(), Default::default);
        for (d, b) in self.bodies.iter_mut().zip(bodies) {
            d.set(b);
        }
        copy_into(&mut self.contacts, contacts);
        copy_into(&mut self.joints, joints);
        true
    }

    /// The views of its rods and bodies, for an [`Event::StepEnd`] or an encoder.
    pub fn views(&self) -> (Vec<RodStepView<'_>>, Vec<BodyView<'_>>) {
        (
            self.rods.iter().map(OwnedRodStep::view).collect(),
            self.bodies.iter().map(OwnedBody::view).collect(),
        )
    }
}

/// An owned [`RodStepView`].
#[derive(Debug, Clone, Default)]
pub struct OwnedRodStep {
    dim: u8,
    q: Vec<f64>,
    u: Vec<f64>,
    reaction: Vec<f64>,
    impulse: Vec<f64>,
    drive_force: Vec<f64>,
    normal: Vec<f64>,
    contact_obstacle: Vec<usize>,
    normal2: Vec<f64>,
    contact_obstacle2: Vec<usize>,
    in_contact: Vec<bool>,
    bending_stress: Vec<f64>,
    gap: Vec<f64>,
    q_predictor: Vec<f64>,
    twist_stress: Vec<f64>,
    /// θ, twist and m₁ of a 3D rod's frames (`has_frames`).
    theta: Vec<f64>,
    twist: Vec<f64>,
    m1: Vec<f64>,
    has_frames: bool,
}

fn copy_into<T: Copy>(to: &mut Vec<T>, from: &[T]) {
    to.clear();
    to.extend_from_slice(from);
}

impl OwnedRodStep {
    pub fn set(&mut self, v: &RodStepView<'_>) {
        self.dim = v.dim;
        copy_into(&mut self.q, v.q);
        copy_into(&mut self.u, v.u);
        copy_into(&mut self.reaction, v.reaction);
        copy_into(&mut self.impulse, v.impulse);
        copy_into(&mut self.drive_force, v.drive_force);
        copy_into(&mut self.normal, v.normal);
        copy_into(&mut self.contact_obstacle, v.contact_obstacle);
        copy_into(&mut self.normal2, v.normal2);
        copy_into(&mut self.contact_obstacle2, v.contact_obstacle2);
        copy_into(&mut self.in_contact, v.in_contact);
        copy_into(&mut self.bending_stress, v.bending_stress);
        copy_into(&mut self.gap, v.gap);
        copy_into(&mut self.q_predictor, v.q_predictor);
        copy_into(&mut self.twist_stress, v.twist_stress);
        self.has_frames = v.frames.is_some();
        let f = v.frames.unwrap_or(FrameView {
            theta: &[],
            twist: &[],
            m1: &[],
        });
        copy_into(&mut self.theta, f.theta);
        copy_into(&mut self.twist, f.twist);
        copy_into(&mut self.m1, f.m1);
    }

    pub fn view(&self) -> RodStepView<'_> {
        RodStepView {
            dim: self.dim,
            q: &self.q,
            u: &self.u,
            reaction: &self.reaction,
            impulse: &self.impulse,
            drive_force: &self.drive_force,
            normal: &self.normal,
            contact_obstacle: &self.contact_obstacle,
            normal2: &self.normal2,
            contact_obstacle2: &self.contact_obstacle2,
            in_contact: &self.in_contact,
            bending_stress: &self.bending_stress,
            gap: &self.gap,
            q_predictor: &self.q_predictor,
            twist_stress: &self.twist_stress,
            frames: self.has_frames.then_some(FrameView {
                theta: &self.theta,
                twist: &self.twist,
                m1: &self.m1,
            }),
        }
    }
}

/// An owned [`BodyView`].
#[derive(Debug, Clone, Default)]
pub struct OwnedBody {
    name: String,
    obstacle: usize,
    position: [f64; 3],
    angle: f64,
    rotation: [f64; 4],
    velocity: [f64; 3],
    angular_velocity: [f64; 3],
    contact_force: [f64; 3],
    contact_torque: [f64; 3],
    mass: f64,
}

impl OwnedBody {
    pub fn set(&mut self, b: &BodyView<'_>) {
        if self.name != b.name {
            self.name.clear();
            self.name.push_str(b.name);
        }
        self.obstacle = b.obstacle;
        self.position = b.position;
        self.angle = b.angle;
        self.rotation = b.rotation;
        self.velocity = b.velocity;
        self.angular_velocity = b.angular_velocity;
        self.contact_force = b.contact_force;
        self.contact_torque = b.contact_torque;
        self.mass = b.mass;
    }

    pub fn view(&self) -> BodyView<'_> {
        BodyView {
            name: &self.name,
            obstacle: self.obstacle,
            position: self.position,
            angle: self.angle,
            rotation: self.rotation,
            velocity: self.velocity,
            angular_velocity: self.angular_velocity,
            contact_force: self.contact_force,
            contact_torque: self.contact_torque,
            mass: self.mass,
        }
    }
}
