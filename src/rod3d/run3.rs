//! Running a 3D scenario: the world built from [`Scenario3`], stepped while the hand's moves
//! last (or to `t_end`), with an optional CSV of every node (x, y, z, the twist angle of the
//! edge it starts, its contact and reaction) and of the fruit's pose, and a summary.

use super::body3::Body3;
use super::contact3::Surface3;
use super::events::{Emit3, NullObserver3, Observer3};
use super::gripper::{radial, Gripper3, Move3};
use super::rod::{angle, pos};
use super::spatial::Spatial;
use super::world::World3;
use crate::actuation::phase;
use crate::events::{NullObserver, Observer};
use crate::obstacle3::{Obstacle3, Pose3, V3};
use crate::record::grasp::{GraspSummary, Verdict};
use crate::record::summary::{
    tip_node, NodeRef, PhaseSummary, RodSummary, Summary, SUMMARY_VERSION,
};
use crate::replay::grasp::GraspRule;
use crate::scenario::expect::GraspOutcome;
use crate::scenario::three::Scenario3;
use std::io::Write as _;

/// What a 3D run did.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Summary3 {
    pub name: String,
    pub steps: u64,
    pub t_end: f64,
    pub newton_iterations: u64,
    pub contact_passes: u64,
    pub contacts_added: u64,
    pub contacts_released: u64,
    pub friction_switches: u64,
    /// Summed normal reaction on each finger at the end (N).
    pub finger_forces: Vec<f64>,
    pub max_grip_force: f64,
    /// Time the squeeze reached its force (s), if it did.
    pub squeezed_at: Option<f64>,
    pub fruit_start: Option<[f64; 3]>,
    pub fruit_end: Option<[f64; 3]>,
    /// Largest depth of a node (with edge contact, of any point of a segment) below its
    /// thickness offset after any step (m; ≤ 0: none).
    pub worst_penetration: f64,
    /// Largest twist angle of any edge (rad).
    pub max_twist: f64,
    /// Did the hand hold the fruit through its lift? (A free fruit only; the planar rule and
    /// key names, `record::grasp`.)
    pub grasp: Option<Grasp3>,
    /// A compliant fruit's contact pressure and bruise verdict (None: a rigid fruit).
    pub contact_pressure: Option<Pressure3>,
    /// The per-rod and per-node figures of the one summary ([`Summary3::to_summary`]).
    #[serde(skip)]
    pub tally: Tally3,
}

/// A compliant fruit's contacts over the run, with the planar summary's key names
/// (`record::summary::PressureSummary`): the Hertz contact of the largest peak pressure,
/// where and when, the deepest indentation and the bruise verdict.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Pressure3 {
    /// Largest normal force of one contact on the fruit (N, the law's).
    pub peak_contact_force_n: f64,
    /// Largest Hertz peak pressure p₀ (Pa), where (rod, node, surface point; on an obstacle
    /// the fruit rests on: its name, node 0) and when.
    pub max_pressure_pa: f64,
    pub max_pressure_node: crate::record::summary::NodeRef,
    pub max_pressure_point: [f64; 3],
    pub max_pressure_time_s: f64,
    /// The contact ellipse's semi-axes a ≥ b at that moment (m; equal on a sphere under a
    /// flat face).
    pub half_width_at_max_m: f64,
    pub half_width_minor_at_max_m: f64,
    /// Deepest indentation of the fruit (m).
    pub max_indentation_m: f64,
    /// The fruit's bruise threshold (Pa) and whether the pressure went above it.
    pub bruise_pressure_pa: f64,
    pub bruised: bool,
    /// max p₀ / bruise threshold.
    pub bruise_ratio: f64,
    /// The scenario expects the fruit to bruise (`[expect] bruised`).
    pub bruise_expected: bool,
    /// Widest part of one contact above the threshold (m, the full width 2 a √(1 − (p_b/p₀)²)
    /// along the ellipse's major axis).
    pub max_bruise_width_m: f64,
}

impl Pressure3 {
    fn new(bruise_pressure: f64, expected: bool) -> Pressure3 {
        Pressure3 {
            peak_contact_force_n: 0.0,
            max_pressure_pa: 0.0,
            max_pressure_node: crate::record::summary::NodeRef {
                rod: String::new(),
                node: 0,
            },
            max_pressure_point: [0.0; 3],
            max_pressure_time_s: 0.0,
            half_width_at_max_m: 0.0,
            half_width_minor_at_max_m: 0.0,
            max_indentation_m: 0.0,
            bruise_pressure_pa: bruise_pressure,
            bruised: false,
            bruise_ratio: 0.0,
            bruise_expected: expected,
            max_bruise_width_m: 0.0,
        }
    }

    /// Take in the compliant contacts at the end of a step: the prongs' on the fruit, then the
    /// fruit's on the obstacles it rests on (the table: named by the obstacle, node 0).
    fn step(&mut self, w: &World3) {
        for p in w.pressed() {
            self.take(&p, &w.rod_names[p.rod], p.node, w.time);
        }
        for p in w.pressed_on_obstacles() {
            self.take(&p, w.surface_name(p.surface), 0, w.time);
        }
        self.bruise_ratio = self.max_pressure_pa / self.bruise_pressure_pa;
        self.bruised = self.max_pressure_pa >= self.bruise_pressure_pa;
    }

    fn take(&mut self, p: &super::world::Pressed3, name: &str, node: usize, t: f64) {
        self.peak_contact_force_n = self.peak_contact_force_n.max(p.force);
        self.max_indentation_m = self.max_indentation_m.max(p.indentation);
        // The full width of the ellipse's major axis where p > the threshold:
        // 2 a √(1 − (p_b/p₀)²) (Hertz: p = p₀ √(1 − (x/a)²) along it).
        if p.pressure > self.bruise_pressure_pa {
            let r = self.bruise_pressure_pa / p.pressure;
            let w = 2.0 * p.radii.0 * (1.0 - r * r).sqrt();
            self.max_bruise_width_m = self.max_bruise_width_m.max(w);
        }
        if p.pressure > self.max_pressure_pa {
            self.max_pressure_pa = p.pressure;
            self.max_pressure_node = crate::record::summary::NodeRef {
                rod: name.to_string(),
                node,
            };
            self.max_pressure_point = p.point.into();
            self.max_pressure_time_s = t;
            (self.half_width_at_max_m, self.half_width_minor_at_max_m) = p.radii;
        }
    }

    /// In the one summary's terms.
    fn to_summary(&self) -> crate::record::summary::PressureSummary {
        crate::record::summary::PressureSummary {
            peak_contact_force_n: self.peak_contact_force_n,
            max_pressure_pa: self.max_pressure_pa,
            max_pressure_node: self.max_pressure_node.clone(),
            max_pressure_point: self.max_pressure_point.to_vec(),
            max_pressure_time_s: self.max_pressure_time_s,
            half_width_at_max_m: self.half_width_at_max_m,
            half_width_minor_at_max_m: self.half_width_minor_at_max_m,
            max_indentation_m: self.max_indentation_m,
            bruise_pressure_pa: self.bruise_pressure_pa,
            bruised: self.bruised,
            bruise_ratio: self.bruise_ratio,
            max_bruise_width_m: self.max_bruise_width_m,
        }
    }
}

/// Per-rod and per-node figures of a 3D run, in the one summary's terms
/// ([`crate::record::summary::RodSummary`]), gathered after every step.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Tally3 {
    pub rods: Vec<RodSummary>,
    /// Per rod: the tip, the first clamped node, and their positions at the start.
    tips: Vec<(usize, Option<usize>, V3, V3)>,
    /// Largest node reaction (N) with its rod, node and time; the first contact's time.
    peak: f64,
    peak_at: Option<(usize, usize, f64)>,
    onset: Option<f64>,
    /// The hand's moves: (index, kind, start, end, reason).
    phases: Vec<PhaseSummary>,
}

impl Tally3 {
    fn new(w: &World3) -> Tally3 {
        let mut t = Tally3::default();
        for (r, sim) in w.rods.iter().enumerate() {
            let n = sim.rod.n;
            let clamped: Vec<bool> = (0..n).map(|i| sim.fixed[pos(i)]).collect();
            let tip = tip_node(&clamped);
            let base = clamped.iter().position(|c| *c);
            let at = |i: usize| V3::new(sim.q[pos(i)], sim.q[pos(i) + 1], sim.q[pos(i) + 2]);
            t.tips
                .push((tip, base, at(tip), base.map_or(V3::zeros(), at)));
            t.rods.push(RodSummary {
                name: w.rod_names[r].clone(),
                final_positions: vec![vec![0.0; 3]; n],
                final_velocities: vec![vec![0.0; 3]; n],
                peak_reaction_per_node_n: vec![0.0; n],
                contact_steps_per_node: vec![0; n],
                total_impulse_per_node_ns: vec![0.0; n],
                peak_impulse_consistent_force_per_node_n: vec![0.0; n],
                peak_bending_stress_per_node_pa: vec![0.0; n],
                peak_twist_stress_per_node_pa: Vec::new(),
                first_contact_time_s: vec![None; n],
                final_drive_force_n: vec![0.0; 3],
                final_contact_force_n: 0.0,
                tip_node: tip,
                max_tip_deflection_m: 0.0,
            });
        }
        t.step(w, 0.0);
        t
    }

    /// Fold the state after a step of `dt` into the figures.
    fn step(&mut self, w: &World3, dt: f64) {
        for (r, sim) in w.rods.iter().enumerate() {
            let s = &mut self.rods[r];
            for i in 0..sim.rod.n {
                s.final_positions[i].copy_from_slice(&sim.q[pos(i)..pos(i) + 3]);
                s.final_velocities[i].copy_from_slice(&sim.v[pos(i)..pos(i) + 3]);
                if w.contacts[r][i].is_none() {
                    continue;
                }
                let f = w.reactions[r][i].norm();
                s.peak_reaction_per_node_n[i] = s.peak_reaction_per_node_n[i].max(f);
                s.total_impulse_per_node_ns[i] += f * dt;
                if f > self.peak {
                    self.peak = f;
                    self.peak_at = Some((r, i, w.time));
                }
                s.contact_steps_per_node[i] += u64::from(dt > 0.0);
                s.first_contact_time_s[i].get_or_insert(w.time);
                self.onset.get_or_insert(w.time);
            }
            let (tip, base, tip0, base0) = self.tips[r];
            let at = |i: usize| V3::new(sim.q[pos(i)], sim.q[pos(i) + 1], sim.q[pos(i) + 2]);
            let b = base.map_or(V3::zeros(), at);
            let d = (at(tip) - tip0 - (b - base0)).norm();
            s.max_tip_deflection_m = s.max_tip_deflection_m.max(d);
        }
    }

    /// Record the moves that ended when the hand advanced to `t1` (from move `from` on).
    fn moves(&mut self, g: &Gripper3, from: usize, start: f64, t1: f64) {
        for k in from..g.current {
            let m = &g.moves[k];
            let reason = match m {
                Move3::Squeeze { .. } if g.travel >= max_travel(m) => phase::TRAVEL,
                Move3::Squeeze { .. } => phase::GRIP_FORCE,
                _ => phase::DURATION,
            };
            let name = move_name(m);
            self.phases.push(PhaseSummary {
                actuator: 0,
                phase: k,
                name: Some(name.to_string()),
                start_s: if k == from { start } else { t1 },
                end_s: Some(t1),
                reason: Some(reason.to_string()),
            });
        }
    }
}

impl Tally3 {
    /// The move the run ended in, if any (no end, no reason).
    fn running(&mut self, g: &Gripper3) {
        if let Some(m) = g.moves.get(g.current) {
            self.phases.push(PhaseSummary {
                actuator: 0,
                phase: g.current,
                name: Some(move_name(m).to_string()),
                start_s: g.move_start,
                end_s: None,
                reason: None,
            });
        }
    }
}

fn move_name(m: &Move3) -> &'static str {
    match m {
        Move3::Squeeze { .. } => "squeeze",
        Move3::Close { .. } => "close",
        Move3::Hold { .. } => "hold",
        Move3::Translate { .. } => "translate",
        Move3::Lift { .. } => "lift",
        Move3::Rotate { .. } => "rotate",
    }
}

fn max_travel(m: &Move3) -> f64 {
    match m {
        Move3::Squeeze { max_travel, .. } => *max_travel,
        _ => f64::INFINITY,
    }
}

impl Summary3 {
    /// The one summary of both dimensions (`record::summary::Summary`, dimension 3). Until
    /// the 3D run sends the shared event stream, what it does not compute is 0 or null, each
    /// said in its key's description: impulse-consistent forces, bending and twist stresses,
    /// drive forces, the energy balance, first slip and friction utilisation, and contact
    /// pressure. The counters a 3D run does not have (back-offs, rejected and split steps) are
    /// 0: its dt is fixed.
    pub fn to_summary(&self, wall_time_s: f64) -> Summary {
        let t = &self.tally;
        let node = |(r, n): (usize, usize)| NodeRef {
            rod: t.rods[r].name.clone(),
            node: n,
        };
        let mut rods = t.rods.clone();
        for (r, f) in rods.iter_mut().zip(&self.finger_forces) {
            r.final_contact_force_n = *f;
        }
        Summary {
            summary_version: SUMMARY_VERSION,
            dimension: 3,
            scenario: self.name.clone(),
            gripsim_version: env!("CARGO_PKG_VERSION").to_string(),
            mode: "dynamic".to_string(),
            completed: true,
            error: None,
            steps: self.steps,
            newton_iterations: self.newton_iterations,
            contact_passes: self.contact_passes,
            dt_backoffs: 0,
            rejected_steps: 0,
            first_order_node_steps: 0,
            split_steps: 0,
            jacobian_factorizations: 0,
            contacts_added: self.contacts_added,
            contacts_released: self.contacts_released,
            friction_switches: self.friction_switches,
            simulated_time_s: self.t_end,
            wall_time_s,
            peak_reaction_force_n: t.peak,
            peak_reaction_node: t.peak_at.map(|(r, n, _)| node((r, n))),
            peak_reaction_time_s: t.peak_at.map(|(_, _, t)| t),
            force_window_s: 0.0,
            peak_impulse_consistent_force_n: 0.0,
            peak_impulse_consistent_node: None,
            contact_onset_time_s: t.onset,
            max_penetration_m: self.worst_penetration.max(0.0),
            max_bending_stress_pa: 0.0,
            max_bending_stress_node: None,
            max_twist_rad: Some(self.max_twist),
            max_twist_stress_pa: None,
            max_twist_stress_node: None,
            rods,
            phases: t.phases.clone(),
            grasp: self.grasp.as_ref().map(|g| self.grasp_summary(g)),
            energy: None,
            energy_closure_rel: None,
            min_eigenvalue: None,
            unstable_equilibrium: false,
            contact_pressure: self.contact_pressure.as_ref().map(Pressure3::to_summary),
            joints: Vec::new(),
        }
    }

    fn grasp_summary(&self, g: &Grasp3) -> GraspSummary {
        let v = |p: Option<[f64; 3]>| p.map_or(vec![0.0; 3], |p| p.to_vec());
        GraspSummary {
            verdict: match g.verdict {
                None => Verdict::NoLift,
                Some(GraspOutcome::Held) => Verdict::Held,
                Some(GraspOutcome::Slipped) => Verdict::Slipped,
                Some(GraspOutcome::Dropped) => Verdict::Dropped,
            },
            fruit: g.fruit.clone(),
            fruit_mass_kg: g.fruit_mass_kg,
            held: g.held,
            dropped: g.dropped,
            hold_tolerance_m: g.hold_tolerance_m,
            lift_start_time_s: g.lift_start_time_s,
            peak_grip_force_n: g.peak_grip_force_n,
            peak_total_grip_force_n: g.peak_total_grip_force_n,
            min_safety_margin: g.min_safety_margin,
            safety_margin_at_lift: g.safety_margin_at_lift,
            max_slip_m: g.max_slip_m,
            first_slip_time_s: None,
            max_friction_utilisation: 0.0,
            initial_position_m: v(self.fruit_start),
            final_position_m: v(self.fruit_end),
            final_velocity_m_s: g.final_velocity_m_s.to_vec(),
        }
    }
}

/// The grasp of a free fruit in a 3D run: the rule of `replay check` ([`GraspRule`]) run live,
/// with the friction margin at the lift.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Grasp3 {
    pub fruit: String,
    pub fruit_mass_kg: f64,
    /// `held`, `slipped` or `dropped`; null without a lift.
    pub verdict: Option<GraspOutcome>,
    pub held: bool,
    pub dropped: bool,
    pub hold_tolerance_m: f64,
    pub lift_start_time_s: Option<f64>,
    /// μ_s ΣN / (m g) over the fingers' contacts on the fruit when the lift began, and its
    /// minimum over the lift (frictionless edge contacts count no friction).
    pub safety_margin_at_lift: Option<f64>,
    pub min_safety_margin: Option<f64>,
    /// Largest displacement of the fruit relative to the gripper during the lift (m).
    pub max_slip_m: f64,
    /// Largest total normal force of one finger on the fruit (N).
    pub peak_grip_force_n: f64,
    /// Largest total normal force on the fruit from all fingers (N).
    pub peak_total_grip_force_n: f64,
    /// The fruit's velocity at the end of the run (m/s).
    pub final_velocity_m_s: [f64; 3],
}

/// The live grasp: the rule and the margins.
struct GraspLive {
    rule: GraspRule,
    out: Grasp3,
    weight: f64,
    x: Vec<Vec<f64>>,
}

impl GraspLive {
    fn new(sc: &Scenario3, w: &World3) -> Option<GraspLive> {
        let f = sc.fruit.as_ref().filter(|f| f.free)?;
        let b = w.bodies.first()?;
        let clamped = w
            .rods
            .iter()
            .map(|s| (0..s.rod.n).filter(|&i| s.fixed[pos(i)]).collect())
            .collect();
        Some(GraspLive {
            rule: GraspRule::of3(clamped, sc.gravity, f.hold_tolerance, sc.expect.grasp),
            weight: b.mass * w.gravity.norm(),
            x: w.rods.iter().map(|s| vec![0.0; 3 * s.rod.n]).collect(),
            out: Grasp3 {
                fruit: f.name.clone(),
                fruit_mass_kg: b.mass,
                verdict: None,
                held: false,
                dropped: false,
                hold_tolerance_m: f.hold_tolerance,
                lift_start_time_s: None,
                safety_margin_at_lift: None,
                min_safety_margin: None,
                max_slip_m: 0.0,
                peak_grip_force_n: 0.0,
                peak_total_grip_force_n: 0.0,
                final_velocity_m_s: [0.0; 3],
            },
        })
    }

    fn step(&mut self, w: &World3, step: u64) {
        let on = |s: Surface3| s == Surface3::Body(0);
        let (mut mu_n, mut touching, mut total) = (0.0, false, 0.0);
        for r in 0..w.rods.len() {
            let mut finger = 0.0;
            for (c, re) in w.contacts[r].iter().zip(&w.reactions[r]) {
                if let Some(c) = c.filter(|c| on(c.surface)) {
                    let n = c.normal.dot(re).max(0.0);
                    finger += n;
                    mu_n += c.coulomb.mu_s * n;
                    touching = true;
                }
            }
            for e in w.edges[r].iter().filter(|e| on(e.surface)) {
                finger += e.force.max(0.0);
                touching = true;
            }
            self.out.peak_grip_force_n = self.out.peak_grip_force_n.max(finger);
            total += finger;
            let q = &w.rods[r].q;
            for (i, x) in self.x[r].chunks_exact_mut(3).enumerate() {
                x.copy_from_slice(&q[pos(i)..pos(i) + 3]);
            }
        }
        self.out.peak_total_grip_force_n = self.out.peak_total_grip_force_n.max(total);
        self.out.final_velocity_m_s = w.bodies[0].v.into();
        let c = w.bodies[0].centre();
        let xs: Vec<&[f64]> = self.x.iter().map(Vec::as_slice).collect();
        let was = self.rule.lifted();
        self.rule
            .step3(step, w.time, &xs, [c.x, c.y, c.z], touching);
        let margin = if self.weight > 0.0 {
            mu_n / self.weight
        } else {
            f64::INFINITY
        };
        if !was && self.rule.lifted() {
            self.out.lift_start_time_s = Some(w.time);
            self.out.safety_margin_at_lift = Some(margin);
        }
        // Over the lift, as the planar summary's: a dropped fruit's margin counts (0).
        let dropped = self.rule.outcome() == Some(GraspOutcome::Dropped);
        if self.rule.lifted() && (!self.rule.lift_over() || dropped) {
            let m = self.out.min_safety_margin.map_or(margin, |m| m.min(margin));
            self.out.min_safety_margin = Some(m);
        }
    }

    fn finish(mut self) -> Grasp3 {
        self.out.verdict = self.rule.outcome();
        self.out.held = self.out.verdict == Some(GraspOutcome::Held);
        self.out.dropped = self.out.verdict == Some(GraspOutcome::Dropped);
        self.out.max_slip_m = self.rule.max_slip();
        self.out
    }
}

/// The world and the gripper of a scenario, at t = 0.
pub fn build(sc: &Scenario3) -> Result<(World3, Gripper3), String> {
    let mut w = World3::new(sc.gravity);
    w.side = sc.side;
    w.edge_contact = sc.points == crate::scenario::contact::ContactPoints::Edges;
    w.friction = sc.friction.clone();
    w.force_tol = sc.force_tol;
    w.step_tol = sc.step_tol;
    w.max_iterations = sc.max_newton_iterations;
    w.integrator = sc.integrator;
    let mut g = radial(
        &mut w,
        &sc.prong,
        sc.fingers,
        sc.radius,
        sc.centre,
        sc.clamped_edges,
    );
    for sim in &mut w.rods {
        sim.damping_time = sc.damping_time;
    }
    g.moves = sc.moves.clone();
    g.sensor_tau = sc.sensor_tau;
    // The prong's part of 1/E*: (1 − ν²)/E with ν = E/(2G) − 1.
    let (e, g_mod) = (sc.prong.youngs_modulus, sc.prong.shear_modulus);
    let nu = (e / (2.0 * g_mod) - 1.0).clamp(0.0, 0.5);
    w.prong_compliance = vec![(1.0 - nu * nu) / e; w.rods.len()];
    if let Some(f) = &sc.fruit {
        if f.free {
            let mut b = Body3::new(&f.name, f.shape.clone(), f.density, f.centre)?;
            b.material = f.material.clone();
            w.bodies.push(b);
        } else {
            w.obstacles.push(Obstacle3::new(
                &f.name,
                f.shape.clone(),
                Pose3::at(f.centre),
            ));
            w.materials.push(f.material.clone());
        }
    }
    w.obstacles.extend(sc.obstacles.iter().cloned());
    Ok((w, g))
}

/// Depth of the deepest node below its offset on any surface (m); with edge contact, of the
/// deepest point between the nodes too. A node's offset is at most
/// its section's reach, so a surface that cannot beat the deepest depth so far by the reach is
/// skipped without querying it (by its cheap lower bound on the distance) or without the
/// offset (by the distance): the same maximum, at a fraction of the queries. The contact
/// nodes (on their surfaces: depth about 0) go first, so that the bound skips more of the
/// others (a maximum does not depend on the order).
pub fn worst_penetration(w: &World3) -> f64 {
    let mut worst = f64::NEG_INFINITY;
    if w.edge_contact {
        for r in 0..w.rods.len() {
            worst = worst.max(w.segment_penetration(r));
        }
    }
    for contacts_first in [true, false] {
        for r in 0..w.rods.len() {
            let q = &w.rods[r].q;
            let reach = w.reach(r);
            for i in 0..w.rods[r].rod.n {
                let contact = w.contacts[r][i].map(|c| c.offset);
                if contact.is_some() != contacts_first {
                    continue;
                }
                let x = V3::new(q[pos(i)], q[pos(i) + 1], q[pos(i) + 2]);
                let most = contact.unwrap_or(reach);
                // A compliant fruit is indented, not penetrated (its indentation is reported
                // with the contact pressure).
                let rigid = w
                    .obstacles
                    .iter()
                    .enumerate()
                    .filter(|&(k, _)| w.material(Surface3::Obstacle(k)).is_none())
                    .map(|(_, o)| o)
                    .chain(
                        w.bodies
                            .iter()
                            .filter(|b| b.material.is_none())
                            .map(|b| &b.obstacle),
                    );
                for o in rigid {
                    if most - o.lower_bound(&x) <= worst {
                        continue;
                    }
                    let p = o.query(&x);
                    if most - p.distance <= worst {
                        continue;
                    }
                    let off = contact.unwrap_or_else(|| w.offset(r, i, &p.normal));
                    worst = worst.max(off - p.distance);
                }
            }
        }
    }
    worst
}

fn csv_rows(out: &mut impl std::io::Write, w: &World3, step: u64) -> std::io::Result<()> {
    for (r, sim) in w.rods.iter().enumerate() {
        for i in 0..sim.rod.n {
            let q = &sim.q;
            let twist = if i + 1 < sim.rod.n {
                format!("{:e}", q[angle(i)])
            } else {
                String::new()
            };
            let (surface, re) = match w.contacts[r][i] {
                Some(c) => (w.surface_name(c.surface).to_string(), w.reactions[r][i]),
                None => (String::new(), V3::zeros()),
            };
            writeln!(
                out,
                "{step},{:e},{},{i},{:e},{:e},{:e},{twist},{surface},{:e},{:e},{:e}",
                w.time,
                w.rod_names[r],
                q[pos(i)],
                q[pos(i) + 1],
                q[pos(i) + 2],
                re.x,
                re.y,
                re.z
            )?;
        }
    }
    for b in &w.bodies {
        let c = b.centre();
        let angle = b.obstacle.pose.rotation.angle();
        writeln!(
            out,
            "{step},{:e},{},0,{:e},{:e},{:e},{angle:e},,,,",
            w.time, b.obstacle.name, c.x, c.y, c.z
        )?;
    }
    Ok(())
}

/// The number of steps to run: to `t_end`, or until the moves end (at most 10⁷ steps).
fn step_limit(sc: &Scenario3) -> u64 {
    match sc.t_end {
        Some(t) => (t / sc.dt).round().max(1.0) as u64,
        None => 10_000_000,
    }
}

/// Run `sc`, writing the CSV (if any) to `csv` (as the planar files are,
/// [`crate::record::OutputFile`]: under a `.partial` name renamed at the end of a completed
/// run; a failed run's file keeps the `.partial` name and ends at the last accepted step).
pub fn run(sc: &Scenario3, csv: Option<&std::path::Path>) -> Result<Summary3, String> {
    run_observed(sc, csv, &mut NullObserver3)
}

/// [`run`], sending the world's events ([`super::events::Event3`]) to `obs`.
pub fn run_observed<O: Observer3>(
    sc: &Scenario3,
    csv: Option<&std::path::Path>,
    obs: &mut O,
) -> Result<Summary3, String> {
    run_until(sc, csv, obs, &|| false)
}

/// The message of a run that `stop` ended early: "interrupted at step N".
pub const INTERRUPTED: &str = "interrupted at step";

/// [`run_observed`], asking `stop` before every step: when it says true the run ends there
/// as a failed run does (the files keep their `.partial` names), with the error
/// "interrupted at step N" ([`INTERRUPTED`]).
pub fn run_until<O: Observer3>(
    sc: &Scenario3,
    csv: Option<&std::path::Path>,
    obs: &mut O,
    stop: &dyn Fn() -> bool,
) -> Result<Summary3, String> {
    let mut events = Events {
        text: "",
        obs: &mut NullObserver,
    };
    run_both(sc, csv, obs, &mut events, stop)
}

/// [`run`] sending the one event stream of [`crate::events`] (dimension 3,
/// [`super::spatial`]) to `obs`, with `text` as the scenario's text.
pub fn run_events<E: Observer>(
    sc: &Scenario3,
    text: &str,
    obs: &mut E,
) -> Result<Summary3, String> {
    let mut events = Events { text, obs };
    run_both(sc, None, &mut NullObserver3, &mut events, &|| false)
}

/// Where a run sends the one event stream: an observer, and the scenario text for its
/// `RunStart`.
pub struct Events<'a, E: Observer> {
    pub text: &'a str,
    pub obs: &'a mut E,
}

/// [`run_until`], sending the 3D events to `obs` and the one event stream to `events`.
pub fn run_both<O: Observer3, E: Observer>(
    sc: &Scenario3,
    csv: Option<&std::path::Path>,
    obs: &mut O,
    events: &mut Events<'_, E>,
    stop: &dyn Fn() -> bool,
) -> Result<Summary3, String> {
    let (s, result) = run_full(sc, csv, obs, events, stop)?;
    result.map(|()| s)
}

/// [`run_both`], keeping the summary of a run that stopped (an error or `stop`) as far as it
/// went: `Err` only when the run could not start (its world or its CSV file).
pub fn run_full<O: Observer3, E: Observer>(
    sc: &Scenario3,
    csv: Option<&std::path::Path>,
    obs: &mut O,
    events: &mut Events<'_, E>,
    stop: &dyn Fn() -> bool,
) -> Result<(Summary3, Result<(), String>), String> {
    let (mut w, mut g) = build(sc)?;
    let out = csv.map(crate::record::OutputFile::new);
    let mut file = match &out {
        Some(o) => {
            let f = o.create().map_err(|e| e.to_string())?;
            let mut f = crate::record::csv::PagedRows::new(f);
            writeln!(f, "step,t,object,node,x,y,z,twist,contact,rx,ry,rz")
                .map_err(|e| e.to_string())?;
            Some(f)
        }
        None => None,
    };
    let mut sp = Spatial::default();
    sp.bruise_pressure = sc
        .fruit
        .as_ref()
        .and_then(|f| f.material.as_ref())
        .map_or(0.0, |m| m.bruise_pressure);
    let live = events.obs.wants_steps();
    if live {
        sp.start(&w, &sc.name, events.text, events.obs);
    }
    let mut ev = live.then_some((&mut sp, &mut *events.obs));
    let mut s = new_summary(sc, &w);
    let result = run_loop(
        sc,
        &mut w,
        &mut g,
        file.as_mut(),
        obs,
        &mut ev,
        stop,
        &mut s,
    );
    if let Err(e) = &result {
        // The sinks close their files with the error as the run's end.
        w.fail_observed(obs, e);
    }
    if let Some((sp, o)) = ev {
        sp.end(&w, result.as_ref().err().map(String::as_str), o);
    }
    let flushed = file.map(|mut f| std::io::Write::flush(&mut f));
    if let Some(o) = &out {
        if let Some(Err(e)) = flushed {
            o.discard();
            return Err(format!("{}: {e}", o.writing().display()));
        }
        o.settle(result.is_ok()).map_err(|e| e.to_string())?;
    }
    Ok((s, result))
}

/// The one event stream's buffers and observer, while someone listens to it.
type Live<'a, E> = Option<(&'a mut Spatial, &'a mut E)>;

/// The names of the hand's moves, for `PhaseChanged`.
fn move_names(g: &Gripper3) -> Vec<String> {
    g.moves
        .iter()
        .map(|m| {
            let d = format!("{m:?}").to_lowercase();
            d.split([' ', '{']).next().unwrap_or_default().to_string()
        })
        .collect()
}

/// The summary of a run of `w` before its first step.
fn new_summary(sc: &Scenario3, w: &World3) -> Summary3 {
    let fruit_start = w.bodies.first().map(|b| b.centre().into());
    Summary3 {
        name: sc.name.clone(),
        steps: 0,
        t_end: 0.0,
        newton_iterations: 0,
        contact_passes: 0,
        contacts_added: 0,
        contacts_released: 0,
        friction_switches: 0,
        finger_forces: Vec::new(),
        max_grip_force: 0.0,
        squeezed_at: None,
        fruit_start,
        fruit_end: None,
        worst_penetration: f64::NEG_INFINITY,
        max_twist: 0.0,
        grasp: None,
        contact_pressure: None,
        tally: Tally3::new(w),
    }
}

/// Run the world to its end, counting into `s`. A run that stops early leaves in `s` what
/// it counted, with its time and the fruit's position at the last accepted step.
#[allow(clippy::too_many_arguments)]
fn run_loop<E: Observer>(
    sc: &Scenario3,
    w: &mut World3,
    g: &mut Gripper3,
    csv: Option<&mut crate::record::csv::PagedRows<std::fs::File>>,
    obs: &mut impl Observer3,
    ev: &mut Live<'_, E>,
    stop: &dyn Fn() -> bool,
    s: &mut Summary3,
) -> Result<(), String> {
    let result = run_steps(sc, w, g, csv, obs, ev, stop, s);
    s.t_end = w.time;
    s.fruit_end = w.bodies.first().map(|b| b.centre().into());
    s.finger_forces = g.finger_forces(w);
    s.squeezed_at = g.squeezed_at;
    result
}

#[allow(clippy::too_many_arguments)]
fn run_steps<E: Observer>(
    sc: &Scenario3,
    w: &mut World3,
    g: &mut Gripper3,
    mut csv: Option<&mut crate::record::csv::PagedRows<std::fs::File>>,
    obs: &mut impl Observer3,
    ev: &mut Live<'_, E>,
    stop: &dyn Fn() -> bool,
    s: &mut Summary3,
) -> Result<(), String> {
    let mut emit = Emit3::default();
    w.start_observed(&mut emit, obs);
    w.initial_observed(&mut emit, obs);
    let names = move_names(g);
    if let Some((sp, o)) = ev.as_mut() {
        sp.step_end(w, 0.0, 0, 0, *o);
    }
    let mut grasp = GraspLive::new(sc, w);
    let mut pressure = sc
        .fruit
        .as_ref()
        .and_then(|f| f.material.as_ref())
        .map(|m| Pressure3::new(m.bruise_pressure, sc.expect.bruised));
    if let Some(f) = csv.as_deref_mut() {
        csv_rows(f, w, 0).map_err(|e| e.to_string())?;
    }
    let limit = step_limit(sc);
    while s.steps < limit && (sc.t_end.is_some() || !g.done()) {
        if stop() {
            return Err(format!("{INTERRUPTED} {}", s.steps));
        }
        let t1 = (s.steps + 1) as f64 * sc.dt;
        let (was, since) = (g.current, g.move_start);
        g.drive(w, t1, sc.dt);
        if let Some((sp, o)) = ev.as_mut() {
            sp.before_step(w, *o);
        }
        s.tally.moves(g, was, since, t1);
        let rep = w
            .step_observed(sc.dt, &mut emit, obs)
            .map_err(|e| format!("step {} (t = {t1:e} s): {e}", s.steps + 1))?;
        if let Some((sp, o)) = ev.as_mut() {
            sp.step_end(w, sc.dt, rep.newton_iterations, rep.passes, *o);
            sp.phase(w, g.current, &names, *o);
        }
        s.steps += 1;
        s.newton_iterations += rep.newton_iterations as u64;
        s.contact_passes += rep.passes as u64;
        s.contacts_added += rep.added as u64;
        s.contacts_released += rep.released as u64;
        s.friction_switches += rep.switches as u64;
        s.max_grip_force = s.max_grip_force.max(g.grip_force(w));
        s.worst_penetration = s.worst_penetration.max(worst_penetration(w));
        for sim in &w.rods {
            for e in 0..sim.rod.n - 1 {
                s.max_twist = s
                    .max_twist
                    .max((sim.q[angle(e)] - sim.rod.q0[angle(e)]).abs());
            }
        }
        if let Some(g) = grasp.as_mut() {
            g.step(w, s.steps);
        }
        if let Some(p) = pressure.as_mut() {
            p.step(w);
        }
        s.tally.step(w, sc.dt);
        if let Some(f) = csv.as_deref_mut() {
            csv_rows(f, w, s.steps)
                .and_then(|()| f.rows_end())
                .map_err(|e| e.to_string())?;
        }
    }
    s.grasp = grasp.map(GraspLive::finish);
    s.contact_pressure = pressure;
    if sc.t_end.is_none() && !g.done() {
        return Err(format!(
            "the hand's moves did not end within {limit} steps (t = {:e} s): give solve.t_end, \
             or check the moves (a squeeze whose force is never reached)",
            w.time
        ));
    }
    w.end_observed(obs);
    s.tally.running(g);
    Ok(())
}
