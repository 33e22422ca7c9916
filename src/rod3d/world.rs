//! A 3D world: rods (prongs), fixed obstacles and free bodies (fruit), stepped together by
//! implicit Euler (or BDF2 / TR-BDF2, [`bdf3`]) + Newton with the modified mass method for
//! contact ([`super::contact3`]).
//!
//! One step, in the order it happens: carried contacts are re-linearised at the start of the
//! step; the predictor solves with them; detection adds the nodes that ended inside a surface
//! (deeper than their thickness offset) and the body points that ended below a fixed obstacle;
//! releases (adhesive reactions) and stick/slip switches are decided from the converged
//! reactions; every change re-solves (corrector passes) until the contact set settles. All rods
//! and bodies are one Newton system ([`super::system`]), so a reaction on a node is the
//! opposite of the force on the body and momentum is exchanged exactly.

use super::body3::{lever_map, Body3, G3};
use super::contact3::{decide, decide_split, BodyContact3, Change3, Contact3, Grip3, Surface3};
use super::edge3::EdgeContact3;
use super::energy::material_frame;
use super::rod::{angle, pos};
use super::section::Section3;
use super::solver::{Sim3, Solve3Error};
use super::symband::SymBand;
use super::system::{
    solve_bordered, BlockFactor, Border, Dense, KineticRow, Kkt, RodBlock, Weight,
};
use crate::contact::compliant::Material;
use crate::contact::friction::FrictionTable;
use crate::obstacle3::{Obstacle3, Proximity3, V3};
use nalgebra::{DMatrix, DVector, Matrix3, Vector6};

/// Which surface of a prong touches.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ContactSide3 {
    /// The centreline is held on the surface (the seed's model).
    Centreline,
    /// The section's face: the centreline is held its support distance off the surface.
    Face,
}

/// Counts of what happened in one step.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct StepReport3 {
    pub passes: u32,
    pub newton_iterations: u32,
    pub added: u32,
    pub released: u32,
    pub switches: u32,
}

struct Work3 {
    /// The rod's Jacobian in its contact bases, symmetric part (lower band).
    band: SymBand,
    /// The kinetic friction rows of its sliding nodes (the unsymmetric part).
    kinetic: Vec<KineticRow>,
    factor: BlockFactor,
    /// The contact nodes of the rod and their local bases (rows n, t₁, t₂).
    bases: Vec<(usize, Matrix3<f64>)>,
    /// Z = A⁻¹ B of the bordered solve: its columns and their weights.
    z: Vec<Vec<f64>>,
    zw: Vec<Weight>,
    grad: Vec<f64>,
    rhs: Vec<f64>,
    qn: Vec<f64>,
    elim: Vec<bool>,
    follow: Vec<Option<(usize, Vector6<f64>)>>,
    border: Border,
    /// Per prescribed coordinate that follows a body, its column of the border.
    border_col: Vec<usize>,
    rows: Vec<(usize, usize, f64)>,
    /// The kinetic rows' storage, kept from step to step.
    kinetic_pool: Vec<Vec<(usize, f64)>>,
    released: Vec<bool>,
    /// (segment, surface) pairs whose edge contact was released in this step.
    edge_released: Vec<(usize, Surface3)>,
    /// The pairs among them released because their normal force pulled.
    edge_pulled: Vec<(usize, Surface3)>,
    /// The second-order integrators' history and rows ([`bdf3`]).
    bdf: bdf3::Bdf3,
}

pub struct World3 {
    pub rods: Vec<Sim3>,
    pub rod_names: Vec<String>,
    pub sections: Vec<Section3>,
    pub obstacles: Vec<Obstacle3>,
    pub bodies: Vec<Body3>,
    pub gravity: V3,
    pub friction: FrictionTable,
    pub side: ContactSide3,
    /// Edge contact (`[contact] points = "edges"`): segments are held too, between their
    /// nodes ([`super::edge3`]).
    pub edge_contact: bool,
    /// Per rod, its edge contacts (empty unless `edge_contact`).
    pub edges: Vec<Vec<EdgeContact3>>,
    /// Per rod, per node.
    pub contacts: Vec<Vec<Option<Contact3>>>,
    /// Reaction on every contact node at the end of the last step (world, zero elsewhere).
    pub reactions: Vec<Vec<V3>>,
    pub body_contacts: Vec<BodyContact3>,
    /// Per fixed obstacle, its compliant material (None or missing: rigid); a body's is on
    /// the body ([`Body3::material`]).
    pub materials: Vec<Option<Material>>,
    /// Per rod, (1 − ν²)/E of its material (its part of 1/E* on a compliant fruit; missing:
    /// a rigid prong).
    pub prong_compliance: Vec<f64>,
    /// Newton converges when every free residual is at most `force_tol` × the force scale
    /// (the largest of EI/L², the loads and weights), or when an update is at most
    /// `step_tol` × the rod length: the planar solver's criteria and defaults.
    pub force_tol: f64,
    pub step_tol: f64,
    pub max_iterations: u32,
    /// The time integrator (`[solve] integrator`; default backward Euler).
    pub integrator: crate::scenario::Integrator,
    pub time: f64,
    pub steps: u64,
    work: Vec<Work3>,
    /// The bodies' predicted displacements while the contacts are re-linearised (kept from
    /// step to step: no allocation).
    guesses: Vec<Vector6<f64>>,
    /// The bodies' equations of the last linearisation and the dense system's storage.
    sys: BodySystem,
    dense: Dense,
}

/// The bodies' own equations (without contact forces) and their contacts' constraint rows,
/// with Σ Gᵀ f of their last forces (for the convergence test); storage kept from call to
/// call.
struct BodySystem {
    s: DMatrix<f64>,
    fb: DVector<f64>,
    forces: DVector<f64>,
    kkt: Kkt,
}

impl BodySystem {
    /// No bodies, no rows (no allocation).
    fn empty() -> BodySystem {
        BodySystem {
            s: DMatrix::zeros(0, 0),
            fb: DVector::zeros(0),
            forces: DVector::zeros(0),
            kkt: Kkt::default(),
        }
    }
}

impl World3 {
    pub fn new(gravity: [f64; 3]) -> World3 {
        World3 {
            rods: Vec::new(),
            rod_names: Vec::new(),
            sections: Vec::new(),
            obstacles: Vec::new(),
            bodies: Vec::new(),
            gravity: V3::from(gravity),
            friction: FrictionTable::default(),
            side: ContactSide3::Face,
            edge_contact: false,
            edges: Vec::new(),
            contacts: Vec::new(),
            reactions: Vec::new(),
            body_contacts: Vec::new(),
            materials: Vec::new(),
            prong_compliance: Vec::new(),
            force_tol: 1e-9,
            step_tol: 1e-12,
            max_iterations: 40,
            integrator: crate::scenario::Integrator::BackwardEuler,
            time: 0.0,
            steps: 0,
            work: Vec::new(),
            guesses: Vec::new(),
            sys: BodySystem::empty(),
            dense: Dense::default(),
        }
    }

    /// Add a rod (its clamps and loads already set on `sim`). Returns its index.
    pub fn add_rod(&mut self, name: &str, sim: Sim3, section: Section3) -> usize {
        let n = sim.rod.n;
        let nd = sim.rod.dofs();
        self.work.push(Work3 {
            band: SymBand::new(nd, 10),
            kinetic: Vec::new(),
            factor: BlockFactor::new(nd),
            bases: Vec::new(),
            z: Vec::new(),
            zw: Vec::new(),
            grad: vec![0.0; nd],
            rhs: vec![0.0; nd],
            qn: sim.q.clone(),
            elim: vec![false; nd],
            follow: vec![None; nd],
            border: Border::new(nd),
            border_col: vec![usize::MAX; nd],
            rows: Vec::new(),
            kinetic_pool: Vec::new(),
            released: vec![false; n],
            edge_released: Vec::new(),
            edge_pulled: Vec::new(),
            bdf: bdf3::Bdf3::new(nd, n),
        });
        self.rods.push(sim);
        self.rod_names.push(name.to_string());
        self.sections.push(section);
        self.contacts.push(vec![None; n]);
        self.edges.push(Vec::new());
        self.reactions.push(vec![V3::zeros(); n]);
        self.rods.len() - 1
    }

    /// The name of what a contact touches.
    pub fn surface_name(&self, s: Surface3) -> &str {
        match s {
            Surface3::Obstacle(k) => &self.obstacles[k].name,
            Surface3::Body(b) => &self.bodies[b].obstacle.name,
        }
    }

    fn surface(&self, s: Surface3) -> &Obstacle3 {
        match s {
            Surface3::Obstacle(k) => &self.obstacles[k],
            Surface3::Body(b) => &self.bodies[b].obstacle,
        }
    }

    /// The thickness offset of node i of rod r towards a surface with outward normal n, from the
    /// material frames at the start of the step.
    pub fn offset(&self, r: usize, i: usize, n: &V3) -> f64 {
        if self.side == ContactSide3::Centreline {
            return 0.0;
        }
        let sim = &self.rods[r];
        let edges = [i.checked_sub(1), (i + 1 < sim.rod.n).then_some(i)];
        let (mut sum, mut count) = (0.0, 0.0);
        for e in edges.into_iter().flatten() {
            sum += match self.sections[r] {
                Section3::Circle { r } => r,
                Section3::Rect { b, h } => {
                    let (m1, m2) = material_frame(&sim.frames[e], sim.q[angle(e)]);
                    0.5 * h * n.dot(&V3::from(m1)).abs() + 0.5 * b * n.dot(&V3::from(m2)).abs()
                }
            };
            count += 1.0;
        }
        sum / count
    }

    /// The largest thickness offset rod r can have (its section's reach; 0 for centreline
    /// contact): [`World3::offset`] never exceeds it.
    pub fn reach(&self, r: usize) -> f64 {
        match (self.side, self.sections[r]) {
            (ContactSide3::Centreline, _) => 0.0,
            (_, Section3::Circle { r }) => r,
            (_, Section3::Rect { b, h }) => 0.5 * (b + h),
        }
    }

    fn node(q: &[f64], i: usize) -> V3 {
        V3::new(q[pos(i)], q[pos(i) + 1], q[pos(i) + 2])
    }

    /// Body displacement ΔX of a surface (zero for fixed obstacles).
    fn body_dx(&self, s: Surface3) -> Vector6<f64> {
        match s {
            Surface3::Body(b) => self.bodies[b].dx,
            Surface3::Obstacle(_) => Vector6::zeros(),
        }
    }

    fn centre(&self, s: Surface3) -> V3 {
        match s {
            Surface3::Body(b) => self.bodies[b].centre(),
            Surface3::Obstacle(_) => V3::zeros(),
        }
    }

    /// A contact of rod r's node i holding it on `s` as seen from `prox` (at the current body
    /// displacement), with the friction of the pair.
    fn contact_at(&self, r: usize, i: usize, s: Surface3, prox: &Proximity3) -> Contact3 {
        let n = prox.normal;
        let offset = self.offset(r, i, &n);
        let (lever, target, coulomb) = self.hold_on(r, s, prox, offset);
        Contact3 {
            surface: s,
            normal: n,
            target,
            lever,
            offset,
            grip: Grip3::Slide { dir: V3::zeros() },
            coulomb,
            switches: 0,
            locked: false,
            law: self.law_at(r, i, s, prox),
        }
    }

    /// What holding a point of rod r on `s` where `prox` sees it (offset `offset` along the
    /// normal) takes: the lever from the body's centre (zero on an obstacle), the target
    /// n·x of the constraint at the current body displacement, and the pair's friction.
    pub(crate) fn hold_on(
        &self,
        r: usize,
        s: Surface3,
        prox: &Proximity3,
        offset: f64,
    ) -> (V3, f64, crate::contact::friction::Coulomb) {
        let n = prox.normal;
        let lever = match s {
            Surface3::Body(_) => prox.closest - self.centre(s),
            Surface3::Obstacle(_) => V3::zeros(),
        };
        let a = lever_map(&lever).transpose() * n;
        let target = n.dot(&prox.closest) + offset - a.dot(&self.body_dx(s));
        let coulomb = self
            .friction
            .between(&self.rod_names[r], self.surface_name(s));
        (lever, target, coulomb)
    }

    /// Where node i must be: projected onto its constraint at the current body displacement
    /// (on a compliant fruit only its held tangential coordinates: the normal is free).
    fn project(c: &Contact3, x: &V3, dx: &Vector6<f64>) -> V3 {
        let g = lever_map(&c.lever) * dx;
        match (c.grip, c.law.is_some()) {
            (Grip3::Stick { anchor }, false) => anchor + g,
            (Grip3::Slide { .. }, false) => {
                x + c.normal * (c.target + c.normal.dot(&g) - c.normal.dot(x))
            }
            (Grip3::Stick { anchor }, true) => {
                let d = anchor + g - x;
                x + d - c.normal * c.normal.dot(&d)
            }
            (Grip3::Slide { .. }, true) => *x,
        }
    }

    /// Re-linearise every carried contact at the start of the step (ΔX = 0).
    fn relinearise(&mut self) {
        for r in 0..self.rods.len() {
            for i in 0..self.rods[r].rod.n {
                let Some(old) = self.contacts[r][i] else {
                    continue;
                };
                let x = Self::node(&self.rods[r].q, i);
                let prox = self.surface(old.surface).query(&x);
                let mut c = self.contact_at(r, i, old.surface, &prox);
                c.grip = match old.grip {
                    Grip3::Stick { .. } => Grip3::Stick {
                        anchor: x + c.normal * (c.target - c.normal.dot(&x)),
                    },
                    g => g,
                };
                if let Grip3::Slide { dir } = c.grip {
                    let t = dir - c.normal * c.normal.dot(&dir);
                    if t.norm() > 1e-3 {
                        c.grip = Grip3::Slide { dir: t.normalize() };
                    } else {
                        // No slip direction (held frictionless after a pull, or turned along
                        // the normal): it starts the step as a new contact does.
                        c.initial_grip(&x);
                    }
                }
                self.contacts[r][i] = Some(c);
            }
        }
        for bc in &mut self.body_contacts {
            let body = &self.bodies[bc.body];
            let p = body.centre() + bc.lever;
            let prox = self.obstacles[bc.obstacle].query(&p);
            bc.normal = prox.normal;
            bc.gap = -prox.distance;
            bc.switches = 0;
            if bc.stuck.is_some() {
                bc.stuck = Some(-prox.normal * prox.distance);
            }
        }
        self.relinearise_edges();
    }

    /// One step of size dt with the world's integrator ([`bdf3`]; backward Euler by
    /// default). Fixed DOFs end the step on their targets.
    pub fn step(&mut self, dt: f64) -> Result<StepReport3, Solve3Error> {
        use crate::scenario::Integrator;
        let rep = match self.integrator {
            Integrator::BackwardEuler => self.stage(dt, Stage3::Euler)?,
            Integrator::Bdf2 => self.stage(dt, Stage3::Bdf2)?,
            Integrator::TrBdf2 => self.tr_bdf2(dt)?,
        };
        self.steps += 1;
        Ok(rep)
    }

    /// One implicit stage of size dt (a whole step but for TR-BDF2), its rows of `kind`.
    fn stage(&mut self, dt: f64, kind: Stage3) -> Result<StepReport3, Solve3Error> {
        self.bdf_begin(kind, dt);
        let g = self.gravity;
        for (sim, w) in self.rods.iter_mut().zip(&mut self.work) {
            sim.gravity = [g.x, g.y, g.z];
            for k in 0..sim.q.len() {
                w.qn[k] = if sim.fixed[k] {
                    sim.target[k]
                } else {
                    sim.q[k] + dt * sim.v[k]
                };
            }
            w.released.fill(false);
        }
        // Carried contacts are re-linearised at the start pose (ΔX = 0), then the bodies take
        // their predicted displacement as the first guess.
        let mut guesses = std::mem::take(&mut self.guesses);
        guesses.clear();
        for b in &mut self.bodies {
            b.begin(dt);
            guesses.push(std::mem::replace(&mut b.dx, Vector6::zeros()));
        }
        self.relinearise();
        for (b, g) in self.bodies.iter_mut().zip(&guesses) {
            b.dx = *g;
            b.place();
        }
        self.guesses = guesses;
        let mut report = StepReport3::default();
        let max_passes = 3 * self.rods.iter().map(|s| s.rod.n as u32).sum::<u32>().max(4);
        loop {
            report.newton_iterations += self.newton(dt)?;
            report.passes += 1;
            let changed = self.update_contacts(dt, &mut report);
            if changed == 0 {
                break;
            }
            if report.passes > max_passes {
                return Err(Solve3Error {
                    residual: 0.0,
                    iterations: report.newton_iterations,
                    reason: "the contact set did not settle",
                    at: None,
                });
            }
        }
        self.accept(dt);
        Ok(report)
    }

    fn accept(&mut self, dt: f64) {
        let second = self.bdf_accept();
        for (sim, w) in self.rods.iter_mut().zip(&self.work) {
            if !second {
                for k in 0..sim.q.len() {
                    sim.v[k] = (w.qn[k] - sim.q[k]) / dt;
                }
            }
            sim.q.copy_from_slice(&w.qn);
            sim.advance_frames();
            sim.time += dt;
        }
        for b in &mut self.bodies {
            b.finish(dt);
        }
        self.time += dt;
    }
}

mod bdf3;
use bdf3::Stage3;
mod compliant3;
mod edges3;
mod newton3;
mod start3;
pub use start3::Overlap3;
mod update3;

pub use compliant3::Pressed3;
