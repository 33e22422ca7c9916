//! A 3D run's events in the one contract of [`crate::events`] (dimension 3): the buffers a
//! [`World3`] run reuses to tell an [`Observer`] what it does, beside the 3D-only
//! [`super::events::Event3`] stream.
//!
//! * `RunStart`: dimension 3, the rods' facts, [`Scene::Spatial`] with the obstacles' and the
//!   bodies' shapes and start poses (obstacle index k, body b at `obstacles + b`, as in
//!   [`Shape3Info`](super::events::Shape3Info)).
//! * `StepEnd`: per rod, stride 3, the nodes' positions and velocities gathered from the DOFs
//!   x₀ θ₀ x₁ …; the contact reaction on each node (its node contact's plus its shares of
//!   edge contacts), the step's impulse (reaction × dt), the drive force at clamped nodes
//!   (the step's residual m (v − v₀)/dt + ∇E + damping − f_ext there, with the frames of the
//!   step's start), normal, gap, contact surface; bending stress
//!   σ = E (|κ₁ − κ̄₁| e₁ + |κ₂ − κ̄₂| e₂) / Δl (rect corners; a circle E r |κ − κ̄| / Δl) and
//!   twist stress τ = G J |m − m̄| / Δl · t / J with t the section's largest shear reach
//!   ([`shear_reach`]), Δl = (l̄ᵢ₋₁ + l̄ᵢ)/2; the material frames (θ, twist m, m₁).
//!   Every node, edge and body contact as a [`ContactView`] whose tangent is the direction of
//!   the friction force on the rod (friction ≥ 0); every body with the contact wrench its own
//!   momentum balance gives: F = m (v − v₀)/dt − m g − F_dead, T = (L − L₀)/dt.
//! * `ConstraintAdded`/`ConstraintReleased`, `FrictionChanged` and `BodyContactChanged` for the
//!   contacts that differ at the end of a step from the end of the last (pass 1: the world
//!   decides contact sets inside a step, the events report the step's net change);
//!   `PhaseChanged` when a move of the hand starts; `RunEnd`.
//!
//! Nothing here is built unless the observer [`Observer::wants_steps`].

use super::body3::lever_map;
use super::contact3::{Grip3, Surface3};
use super::energy::{material_frame, strains, EdgeFrame};
use super::events::half_extents;
use super::rod::{angle, pos};
use super::section::Section3;
use super::solver::{assemble, damping_into};
use super::symband::SymBand;
use super::world::World3;
use crate::events::{
    ContactChange, ContactView, Event, FrameView, FrictionChange, Observer, ReleaseReason, RodInfo,
    RodStepView, RunInfo, Scene,
};
use crate::obstacle3::V3;
use std::f64::consts::PI;

/// The largest shear stress of Saint-Venant torsion per unit twist rate and shear modulus
/// (m): a circle's radius r; for a rectangle with long side a and short side c,
/// c [1 − (8/π²) Σ_{n = 1, 3, 5, …} 1/(n² cosh(nπa/(2c)))] (Timoshenko & Goodier, Theory of
/// Elasticity, §109), at the middle of the long sides.
pub fn shear_reach(s: &Section3) -> f64 {
    match *s {
        Section3::Circle { r } => r,
        Section3::Rect { b, h } => {
            let (a, c) = if b >= h { (b, h) } else { (h, b) };
            let (mut sum, mut n) = (0.0, 1.0f64);
            loop {
                let term = 1.0 / (n * n * (n * PI * a / (2.0 * c)).cosh());
                if sum + term == sum || !term.is_finite() {
                    break;
                }
                sum += term;
                n += 2.0;
            }
            c * (1.0 - 8.0 / (PI * PI) * sum)
        }
    }
}

/// One rod's step-end arrays (stride 3).
#[derive(Debug, Default)]
struct RodOut {
    q: Vec<f64>,
    u: Vec<f64>,
    reaction: Vec<f64>,
    impulse: Vec<f64>,
    drive_force: Vec<f64>,
    normal: Vec<f64>,
    obstacle: Vec<usize>,
    normal2: Vec<f64>,
    obstacle2: Vec<usize>,
    in_contact: Vec<bool>,
    bending_stress: Vec<f64>,
    gap: Vec<f64>,
    twist_stress: Vec<f64>,
    theta: Vec<f64>,
    twist: Vec<f64>,
    m1: Vec<f64>,
    /// The DOFs, velocities, frames and reference twists at the start of the step.
    q0: Vec<f64>,
    v0: Vec<f64>,
    frames0: Vec<EdgeFrame>,
    twist0: Vec<f64>,
    grad: Vec<f64>,
}

/// What the last step ended with, to tell the next step's changes.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Held {
    surface: Surface3,
    stuck: bool,
}

/// The event buffers of a 3D run (see the module's text).
#[derive(Debug, Default)]
pub struct Spatial {
    rods: Vec<RodOut>,
    contacts: Vec<ContactView>,
    /// The bodies' velocity and angular momentum at the start of the step.
    body0: Vec<(V3, V3)>,
    held: Vec<Vec<Option<Held>>>,
    edges: Vec<Vec<(usize, Surface3, bool)>>,
    body_held: Vec<(usize, usize, V3, bool)>,
    names: Vec<String>,
    move_index: usize,
    /// The compliant fruit's bruise threshold (Pa; 0 without one): the contact views of its
    /// Hertz contacts carry it beside their peak pressure.
    pub bruise_pressure: f64,
}

impl Spatial {
    /// `RunStart` for `w` at t = 0 (and the buffers sized for it).
    pub fn start<O: Observer>(&mut self, w: &World3, name: &str, text: &str, obs: &mut O) {
        self.rods = w.rods.iter().map(|_| RodOut::default()).collect();
        self.held = w
            .contacts
            .clone()
            .iter()
            .map(|c| vec![None; c.len()])
            .collect();
        self.edges = vec![Vec::new(); w.rods.len()];
        self.body_held.clear();
        self.remember(w);
        let infos: Vec<RodInfo> = (0..w.rods.len()).map(|r| rod_info(w, r)).collect();
        let shapes = w.shape_infos();
        self.names = shapes.iter().map(|s| s.name.clone()).collect();
        let bodies = body_specs(w);
        obs.on_event(&Event::RunStart(&RunInfo {
            dimension: 3,
            scenario_name: name,
            scenario_text: text,
            rods: &infos,
            scene: Scene::Spatial { shapes: &shapes },
            obstacle_names: &self.names,
            bodies: &bodies,
            mode: crate::scenario::Mode::Dynamic,
        }));
    }

    /// Before a step: the state the step starts from (for the drive force and the bodies'
    /// contact wrench). Only when `obs` listens to steps.
    pub fn before_step<O: Observer>(&mut self, w: &World3, obs: &O) {
        if obs.wants_steps() {
            self.remember(w);
        }
    }

    /// The state now as the start of a step (the initial state's drive force and wrench are
    /// then zero).
    fn remember(&mut self, w: &World3) {
        for (o, s) in self.rods.iter_mut().zip(&w.rods) {
            copy(&mut o.q0, &s.q);
            copy(&mut o.v0, &s.v);
            o.frames0.clear();
            o.frames0.extend_from_slice(&s.frames);
            copy(&mut o.twist0, &s.ref_twist);
        }
        self.body0.clear();
        self.body0.extend(w.bodies.iter().map(|b| (b.v, b.l)));
    }

    /// `PhaseChanged` when the hand's move `current` (of `names`) differs from the last one.
    pub fn phase<O: Observer>(
        &mut self,
        w: &World3,
        current: usize,
        names: &[String],
        obs: &mut O,
    ) {
        if current == self.move_index {
            return;
        }
        let to = (current < names.len()).then_some(current);
        obs.on_event(&Event::PhaseChanged {
            step: w.steps,
            t: w.time,
            actuator: 0,
            from: self.move_index,
            to,
            name: to.map_or("", |k| names[k].as_str()),
            reason: if to.is_some() {
                "the last move ended"
            } else {
                "the hand's moves ended"
            },
        });
        self.move_index = current;
    }

    /// The step just taken (`dt`; 0 for the initial state): its contact changes, then
    /// `StepEnd`. Nothing unless `obs` listens to steps.
    pub fn step_end<O: Observer>(
        &mut self,
        w: &World3,
        dt: f64,
        iterations: u32,
        passes: u32,
        obs: &mut O,
    ) {
        if !obs.wants_steps() {
            return;
        }
        if dt > 0.0 {
            self.changes(w, obs);
        }
        self.fill(w, dt);
        let views: Vec<RodStepView<'_>> = self.rods.iter().map(RodOut::view).collect();
        let names: Vec<&str> = w.bodies.iter().map(|b| b.obstacle.name.as_str()).collect();
        let bodies = self.body_views(w, dt, &names);
        obs.on_event(&Event::StepEnd {
            step: w.steps,
            t: w.time,
            dt,
            newton_iterations: iterations,
            passes,
            rods: &views,
            bodies: &bodies,
            contacts: &self.contacts,
            joints: &[],
        });
    }

    /// `RunEnd` (with the error of a run that failed after its last accepted step).
    pub fn end<O: Observer>(&self, w: &World3, error: Option<&str>, obs: &mut O) {
        obs.on_event(&Event::RunEnd {
            steps: w.steps,
            t: w.time,
            error,
        });
    }

    fn fill(&mut self, w: &World3, dt: f64) {
        self.contacts.clear();
        for r in 0..w.rods.len() {
            self.fill_rod(w, r, dt);
            self.node_contacts(w, r, dt);
            for e in &w.edges[r] {
                let v = edge_view(w, r, e, dt);
                self.contacts.push(v);
            }
        }
        for bc in &w.body_contacts {
            let body = &w.bodies[bc.body];
            let (n, f) = (bc.normal, bc.force);
            let mut v = view_of(n, f, bc.coulomb.mu_s, bc.stuck.is_some());
            v.node = bc.body;
            v.obstacle = bc.obstacle;
            v.point = (body.centre() + bc.lever).into();
            if dt > 0.0 {
                let slip = lever_map(&bc.lever) * body.dx / dt;
                v.slip_velocity = V3::from(v.tangent).dot(&slip);
            }
            self.contacts.push(v);
        }
        self.pressures(w);
    }

    /// A compliant fruit's Hertz contacts into their views: the prongs' node contacts, then
    /// the fruit's own on the obstacles it rests on (as [`World3::pressed`] gives them).
    fn pressures(&mut self, w: &World3) {
        let pb = self.bruise_pressure;
        let fill = |v: &mut ContactView, p: &super::world::Pressed3| {
            v.indentation = p.indentation;
            (v.half_width, v.half_width_minor) = p.radii;
            v.peak_pressure = p.pressure;
            v.bruise_pressure = pb;
            if pb > 0.0 && p.pressure > pb {
                let r = pb / p.pressure;
                v.bruise_half_width = p.radii.0 * (1.0 - r * r).sqrt();
            }
        };
        for p in w.pressed() {
            let at = self
                .contacts
                .iter_mut()
                .find(|v| v.rod == p.rod && v.node == p.node && v.segment == usize::MAX);
            if let Some(v) = at {
                fill(v, &p);
            }
        }
        let on_table = w.pressed_on_obstacles();
        let mut k = 0;
        for (bc, v) in w
            .body_contacts
            .iter()
            .zip(self.contacts.iter_mut().filter(|v| v.rod == usize::MAX))
        {
            if bc.law.is_some() {
                if let Some(p) = on_table.get(k) {
                    fill(v, p);
                }
                k += 1;
            }
        }
    }
}

fn copy<T: Copy>(to: &mut Vec<T>, from: &[T]) {
    to.clear();
    to.extend_from_slice(from);
}

/// A contact view of force `f` on the rod across normal `n` (rod and body unset): normal
/// force n·f, friction |f − n (n·f)| along its own direction.
fn view_of(n: V3, f: V3, mu_s: f64, stuck: bool) -> ContactView {
    let rn = n.dot(&f);
    let ft = f - n * rn;
    let fm = ft.norm();
    let t = if fm > 0.0 { ft / fm } else { V3::zeros() };
    ContactView {
        normal: n.into(),
        tangent: t.into(),
        normal_force: rn,
        friction_force: fm,
        stuck,
        utilisation: if mu_s > 0.0 && rn > 0.0 {
            fm / (mu_s * rn)
        } else {
            0.0
        },
        mu_s,
        dim: 3,
        ..ContactView::BLANK
    }
}

/// A surface's index among the scene's shapes and the body it is (or `usize::MAX`).
fn surface_index(w: &World3, s: Surface3) -> (usize, usize) {
    match s {
        Surface3::Obstacle(k) => (k, usize::MAX),
        Surface3::Body(b) => (w.obstacles.len() + b, b),
    }
}

/// The surface point under `x` on `s`, and the signed gap less `offset`.
fn on_surface(w: &World3, s: Surface3, x: &V3, offset: f64) -> ([f64; 3], f64) {
    let o = match s {
        Surface3::Obstacle(k) => &w.obstacles[k],
        Surface3::Body(b) => &w.bodies[b].obstacle,
    };
    let p = o.query(x);
    (p.closest.into(), p.distance - offset)
}

/// How fast the held point `x` (velocity `v`) slips along `t` relative to the surface it is
/// held on by `lever` (m/s).
fn slip_along(w: &World3, s: Surface3, lever: &V3, v: V3, t: [f64; 3], dt: f64) -> f64 {
    if dt <= 0.0 {
        return 0.0;
    }
    let moved = match s {
        Surface3::Body(b) => lever_map(lever) * w.bodies[b].dx / dt,
        Surface3::Obstacle(_) => V3::zeros(),
    };
    (v - moved).dot(&V3::from(t))
}

fn edge_view(w: &World3, r: usize, e: &super::edge3::EdgeContact3, dt: f64) -> ContactView {
    let q = &w.rods[r].q;
    let stuck = matches!(e.grip, Grip3::Stick { .. });
    let mut v = view_of(e.normal, e.total_force(), e.coulomb.mu_s, stuck);
    let (k, b) = surface_index(w, e.surface);
    (v.rod, v.node, v.obstacle, v.body) = (r, e.segment, k, b);
    (v.segment, v.weight) = (e.segment, e.weight);
    v.point = on_surface(w, e.surface, &e.held_point(q), e.offset).0;
    let s = &w.rods[r];
    let [wa, wb] = e.weights();
    let (a, c) = (pos(e.segment), pos(e.segment + 1));
    let vel = V3::new(
        wa * s.v[a] + wb * s.v[c],
        wa * s.v[a + 1] + wb * s.v[c + 1],
        wa * s.v[a + 2] + wb * s.v[c + 2],
    );
    v.slip_velocity = slip_along(w, e.surface, &e.lever, vel, v.tangent, dt);
    v
}

impl Spatial {
    /// Rod r's node contacts as views.
    fn node_contacts(&mut self, w: &World3, r: usize, dt: f64) {
        let s = &w.rods[r];
        for (i, c) in w.contacts[r].iter().enumerate() {
            let Some(c) = c else { continue };
            let re = w.reactions[r][i];
            let stuck = matches!(c.grip, Grip3::Stick { .. });
            let mut v = view_of(c.normal, re, c.coulomb.mu_s, stuck);
            let (k, b) = surface_index(w, c.surface);
            (v.rod, v.node, v.obstacle, v.body) = (r, i, k, b);
            let x = V3::new(s.q[pos(i)], s.q[pos(i) + 1], s.q[pos(i) + 2]);
            v.point = on_surface(w, c.surface, &x, c.offset).0;
            let vel = V3::new(s.v[pos(i)], s.v[pos(i) + 1], s.v[pos(i) + 2]);
            v.slip_velocity = slip_along(w, c.surface, &c.lever, vel, v.tangent, dt);
            self.contacts.push(v);
        }
    }

    /// Rod r's per-node arrays.
    fn fill_rod(&mut self, w: &World3, r: usize, dt: f64) {
        let s = &w.rods[r];
        let n = s.rod.n;
        let o = &mut self.rods[r];
        let gather = |dofs: &[f64], out: &mut Vec<f64>| {
            out.clear();
            out.extend((0..n).flat_map(|i| [dofs[pos(i)], dofs[pos(i) + 1], dofs[pos(i) + 2]]));
        };
        gather(&s.q, &mut o.q);
        gather(&s.v, &mut o.u);
        let edge = w.edge_reactions(r);
        o.reaction.clear();
        o.normal.clear();
        o.obstacle.clear();
        o.in_contact.clear();
        o.gap.clear();
        for i in 0..n {
            let c = w.contacts[r][i];
            let f = edge[i] + c.map_or(V3::zeros(), |_| w.reactions[r][i]);
            o.reaction.extend_from_slice(f.as_slice());
            let nrm = c.map_or(V3::zeros(), |c| c.normal);
            o.normal.extend_from_slice(nrm.as_slice());
            o.obstacle
                .push(c.map_or(usize::MAX, |c| surface_index(w, c.surface).0));
            o.in_contact.push(c.is_some());
            o.gap.push(node_gap(w, r, i));
        }
        o.impulse.clear();
        o.impulse.extend(o.reaction.iter().map(|f| f * dt));
        copy(&mut o.normal2, &vec![0.0; 3 * n]);
        copy(&mut o.obstacle2, &vec![usize::MAX; n]);
        drive_forces(w, r, o, dt);
        stresses(w, r, o);
    }

    /// The bodies' views, their contact wrench from their own momentum balance over the step.
    fn body_views<'a>(
        &self,
        w: &World3,
        dt: f64,
        names: &[&'a str],
    ) -> Vec<crate::events::BodyView<'a>> {
        let nobs = w.obstacles.len();
        w.bodies
            .iter()
            .enumerate()
            .map(|(b, body)| {
                let (v0, l0) = self.body0.get(b).copied().unwrap_or((body.v, body.l));
                let (f, t) = if dt > 0.0 {
                    let f = body.mass * (body.v - v0) / dt - body.mass * w.gravity - body.force;
                    (f, (body.l - l0) / dt)
                } else {
                    (V3::zeros(), V3::zeros())
                };
                let qt =
                    nalgebra::UnitQuaternion::from_rotation_matrix(&body.obstacle.pose.rotation);
                crate::events::BodyView {
                    name: names[b],
                    obstacle: nobs + b,
                    position: body.centre().into(),
                    angle: 0.0,
                    rotation: [qt.i, qt.j, qt.k, qt.w],
                    velocity: body.v.into(),
                    angular_velocity: body.omega().into(),
                    contact_force: f.into(),
                    contact_torque: t.into(),
                    mass: body.mass,
                }
            })
            .collect()
    }
}

/// Signed distance of node i of rod r to the nearest surface less its offset there (m;
/// infinity without surfaces).
fn node_gap(w: &World3, r: usize, i: usize) -> f64 {
    let q = &w.rods[r].q;
    let x = V3::new(q[pos(i)], q[pos(i) + 1], q[pos(i) + 2]);
    if let Some(c) = w.contacts[r][i] {
        return on_surface(w, c.surface, &x, c.offset).1;
    }
    w.obstacles
        .iter()
        .chain(w.bodies.iter().map(|b| &b.obstacle))
        .map(|o| {
            let p = o.query(&x);
            p.distance - w.offset(r, i, &p.normal)
        })
        .fold(f64::INFINITY, f64::min)
}

/// The force the drive applies to rod r's clamped nodes over the step: the residual of the
/// step at its fixed position DOFs (zero on free nodes and for the initial state).
fn drive_forces(w: &World3, r: usize, o: &mut RodOut, dt: f64) {
    let s = &w.rods[r];
    let n = s.rod.n;
    o.drive_force.clear();
    o.drive_force.resize(3 * n, 0.0);
    if dt <= 0.0 || !(0..n).any(|i| s.fixed[pos(i)]) {
        return;
    }
    o.grad.clear();
    o.grad.resize(s.q.len(), 0.0);
    assemble(&s.rod, &o.frames0, &o.twist0, &s.q, &mut o.grad, None, &[]);
    if s.damping_time > 0.0 {
        let tau = s.damping_time;
        let g = &mut o.grad;
        damping_into(
            &s.rod,
            &o.frames0,
            &s.q,
            &o.q0,
            dt,
            tau,
            g,
            None::<&mut SymBand>,
            &[],
        );
    }
    for i in (0..n).filter(|&i| s.fixed[pos(i)]) {
        for a in 0..3 {
            let k = pos(i) + a;
            let m = s.rod.mass[k];
            o.drive_force[3 * i + a] = m * (s.v[k] - o.v0[k]) / dt + o.grad[k] - s.external(k);
        }
    }
}

/// Rod r's bending and twist stress at every node (0 at the ends) and its material frames.
fn stresses(w: &World3, r: usize, o: &mut RodOut) {
    let s = &w.rods[r];
    let (n, sec) = (s.rod.n, w.sections[r]);
    let e_mod = s.rod.ea / sec.area();
    let j = sec.torsion_constant();
    let [e1, e2] = half_extents(&sec);
    o.bending_stress.clear();
    o.bending_stress.resize(n, 0.0);
    o.twist_stress.clear();
    o.twist_stress.resize(n, 0.0);
    o.twist.clear();
    o.twist.resize(n, 0.0);
    for i in 1..n.saturating_sub(1) {
        let p = &s.rod.elastic[i];
        let edge = |k: usize| {
            let (a, b) = (pos(k), pos(k + 1));
            [
                s.q[b] - s.q[a],
                s.q[b + 1] - s.q[a + 1],
                s.q[b + 2] - s.q[a + 2],
            ]
        };
        let th = [s.q[angle(i - 1)], s.q[angle(i)]];
        let old = [&s.frames[i - 1], &s.frames[i]];
        let (k, m, _) = strains(edge(i - 1), edge(i), th, old, s.ref_twist[i]);
        let dl = 0.5 * (s.rod.rest_length[i - 1] + s.rod.rest_length[i]);
        let (d1, d2) = (k[0] - p.kappa_bar[0], k[1] - p.kappa_bar[1]);
        o.bending_stress[i] = match sec {
            Section3::Circle { r } => e_mod * r * d1.hypot(d2) / dl,
            Section3::Rect { .. } => e_mod * (d1.abs() * e1 + d2.abs() * e2) / dl,
        };
        let torque = p.gj * (m - p.twist_bar).abs();
        o.twist_stress[i] = if j > 0.0 {
            torque * shear_reach(&sec) / j
        } else {
            0.0
        };
        o.twist[i] = m;
    }
    o.theta.clear();
    o.m1.clear();
    for e in 0..n.saturating_sub(1) {
        let th = s.q[angle(e)];
        o.theta.push(th);
        o.m1.extend_from_slice(&material_frame(&s.frames[e], th).0);
    }
}

impl RodOut {
    fn view(&self) -> RodStepView<'_> {
        RodStepView {
            dim: 3,
            q: &self.q,
            u: &self.u,
            reaction: &self.reaction,
            impulse: &self.impulse,
            drive_force: &self.drive_force,
            normal: &self.normal,
            contact_obstacle: &self.obstacle,
            normal2: &self.normal2,
            contact_obstacle2: &self.obstacle2,
            in_contact: &self.in_contact,
            bending_stress: &self.bending_stress,
            gap: &self.gap,
            q_predictor: &self.q,
            twist_stress: &self.twist_stress,
            frames: Some(FrameView {
                theta: &self.theta,
                twist: &self.twist,
                m1: &self.m1,
            }),
        }
    }
}

/// Rod r's static facts: node masses, clamped nodes (a fixed position DOF), rest lengths; E,
/// area, I₁ and the half extent along m₁ for the planar readers' bending fields.
fn rod_info(w: &World3, r: usize) -> RodInfo {
    let s = &w.rods[r];
    let sec = w.sections[r];
    RodInfo {
        name: w.rod_names[r].clone(),
        nodes: s.rod.n,
        mass: (0..s.rod.n).map(|i| s.rod.mass[pos(i)]).collect(),
        clamped: (0..s.rod.n).map(|i| s.fixed[pos(i)]).collect(),
        rest_length: s.rod.rest_length.clone(),
        rest_curvature: vec![0.0; s.rod.n],
        youngs_modulus: s.rod.ea / sec.area(),
        area: sec.area(),
        inertia: sec.i1(),
        half_height: half_extents(&sec)[0],
        particle: false,
    }
}

/// The bodies as the planar [`crate::world::body::BodySpec`]: x and y of their centroid,
/// weight and velocity; the mean of the principal inertias.
fn body_specs(w: &World3) -> Vec<crate::world::body::BodySpec> {
    let nobs = w.obstacles.len();
    w.bodies
        .iter()
        .enumerate()
        .map(|(b, body)| {
            let c = body.centre();
            let size = body.obstacle.shape.lower_bound(&V3::zeros()).abs();
            crate::world::body::BodySpec {
                obstacle: nobs + b,
                name: body.obstacle.name.clone(),
                mass: body.mass,
                inertia: body.inertia.trace() / 3.0,
                weight: [body.mass * w.gravity.x, body.mass * w.gravity.y],
                centroid: [c.x, c.y],
                velocity: [body.v.x, body.v.y],
                angular_velocity: 0.0,
                radius: size,
                hold_tolerance: 0.0,
                depth: 2.0 * size,
            }
        })
        .collect()
}

impl Spatial {
    /// The contacts that differ from the end of the last step: `ConstraintAdded`/`Released`
    /// and `FrictionChanged` for node and edge contacts, `BodyContactChanged` for the bodies'
    /// own.
    fn changes<O: Observer>(&mut self, w: &World3, obs: &mut O) {
        let (step, t) = (w.steps, w.time);
        for r in 0..w.rods.len() {
            for i in 0..w.rods[r].rod.n {
                let now = w.contacts[r][i].map(|c| Held {
                    surface: c.surface,
                    stuck: matches!(c.grip, Grip3::Stick { .. }),
                });
                let was = self.held[r][i];
                if now == was {
                    continue;
                }
                let re = w.reactions[r][i];
                let change = |s: Surface3, n: V3, reaction: V3| ContactChange {
                    step,
                    t,
                    pass: 1,
                    rod: r,
                    node: i,
                    obstacle: surface_index(w, s).0,
                    normal: n.into(),
                    gap: 0.0,
                    reaction: reaction.into(),
                    z: 0.0,
                };
                match (was, now, w.contacts[r][i]) {
                    (Some(a), Some(b), Some(c)) if a.surface == b.surface => {
                        let v = view_of(c.normal, re, c.coulomb.mu_s, b.stuck);
                        obs.on_event(&Event::FrictionChanged(FrictionChange {
                            step,
                            t,
                            pass: 1,
                            rod: r,
                            node: i,
                            obstacle: surface_index(w, c.surface).0,
                            stuck: b.stuck,
                            normal_force: v.normal_force,
                            tangential_force: v.friction_force,
                            slip_velocity: 0.0,
                            segment: usize::MAX,
                            weight: 0.0,
                        }));
                    }
                    (was, _, now_c) => {
                        if let Some(a) = was {
                            let ev = change(a.surface, V3::zeros(), V3::zeros());
                            obs.on_event(&Event::ConstraintReleased(ev, ReleaseReason::Adhesive));
                        }
                        if let Some(c) = now_c {
                            let mut ev = change(c.surface, c.normal, V3::zeros());
                            let q = &w.rods[r].q;
                            let x = V3::new(q[pos(i)], q[pos(i) + 1], q[pos(i) + 2]);
                            ev.gap = on_surface(w, c.surface, &x, c.offset).1;
                            obs.on_event(&Event::ConstraintAdded(ev));
                        }
                    }
                }
                self.held[r][i] = now;
            }
            self.edge_changes(w, r, obs);
        }
        self.body_changes(w, obs);
    }

    fn edge_changes<O: Observer>(&mut self, w: &World3, r: usize, obs: &mut O) {
        let (step, t) = (w.steps, w.time);
        let now: Vec<(usize, Surface3, bool)> = w.edges[r]
            .iter()
            .map(|e| (e.segment, e.surface, matches!(e.grip, Grip3::Stick { .. })))
            .collect();
        let key = |x: &(usize, Surface3, bool)| (x.0, x.1);
        let find = |l: &[(usize, Surface3, bool)], k| l.iter().find(|x| key(x) == k).copied();
        for e in &w.edges[r] {
            let k = (e.segment, e.surface);
            let ev = ContactChange {
                step,
                t,
                pass: 1,
                rod: r,
                node: e.segment,
                obstacle: surface_index(w, e.surface).0,
                normal: e.normal.into(),
                gap: 0.0,
                reaction: [0.0; 3],
                z: 0.0,
            };
            let stuck = matches!(e.grip, Grip3::Stick { .. });
            match find(&self.edges[r], k) {
                None => obs.on_event(&Event::ConstraintAdded(ev)),
                Some(old) if old.2 != stuck => {
                    let v = view_of(e.normal, e.total_force(), e.coulomb.mu_s, stuck);
                    obs.on_event(&Event::FrictionChanged(FrictionChange {
                        step,
                        t,
                        pass: 1,
                        rod: r,
                        node: e.segment,
                        obstacle: ev.obstacle,
                        stuck,
                        normal_force: v.normal_force,
                        tangential_force: v.friction_force,
                        slip_velocity: 0.0,
                        segment: e.segment,
                        weight: e.weight,
                    }))
                }
                Some(_) => {}
            }
        }
        for old in &self.edges[r] {
            if find(&now, key(old)).is_none() {
                let ev = ContactChange {
                    step,
                    t,
                    pass: 1,
                    rod: r,
                    node: old.0,
                    obstacle: surface_index(w, old.1).0,
                    normal: [0.0; 3],
                    gap: 0.0,
                    reaction: [0.0; 3],
                    z: 0.0,
                };
                obs.on_event(&Event::ConstraintReleased(ev, ReleaseReason::Adhesive));
            }
        }
        self.edges[r] = now;
    }

    fn body_changes<O: Observer>(&mut self, w: &World3, obs: &mut O) {
        let now: Vec<(usize, usize, V3, bool)> = w
            .body_contacts
            .iter()
            .map(|c| (c.body, c.obstacle, c.lever, c.stuck.is_some()))
            .collect();
        let same = |a: &(usize, usize, V3, bool), b: &(usize, usize, V3, bool)| {
            a.0 == b.0 && a.1 == b.1 && (a.2 - b.2).norm() <= 1e-9 * (1.0 + a.2.norm())
        };
        let send = |obs: &mut O, c: &(usize, usize, V3, bool), added: bool, n: V3| {
            obs.on_event(&Event::BodyContactChanged {
                step: w.steps,
                t: w.time,
                pass: 1,
                body: c.0,
                obstacle: c.1,
                feature: 0,
                added,
                normal: n.into(),
                reaction: [0.0; 3],
            })
        };
        for (c, bc) in now.iter().zip(&w.body_contacts) {
            if !self.body_held.iter().any(|o| same(o, c)) {
                send(obs, c, true, bc.normal);
            }
        }
        for o in &self.body_held {
            if !now.iter().any(|c| same(o, c)) {
                send(obs, o, false, V3::zeros());
            }
        }
        self.body_held = now;
    }
}
