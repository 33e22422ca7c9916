//! The run summary: peak reactions and where they act, contact counts, final state. One
//! shape for both dimensions (docs/summary.schema.json, written from these types by
//! `GRIPSIM_BLESS=1 cargo test --release --test suite summary_schema_is_current`): a key that
//! does not apply to a run is `null` (or an empty list), never absent, and every vector has
//! `dimension` components.

use crate::events::{Event, Observer};
use schemars::JsonSchema;
use serde::Serialize;

/// The version of the summary's shape; it changes when a key is renamed, removed or changes
/// meaning (adding a key keeps it).
pub const SUMMARY_VERSION: u32 = 2;

/// A node of a rod (or, for a free body's own contact, of the obstacle it presses).
#[derive(Debug, Clone, Serialize, PartialEq, JsonSchema)]
pub struct NodeRef {
    pub rod: String,
    pub node: usize,
}

/// What one rod did over the run.
#[derive(Debug, Clone, Serialize, PartialEq, JsonSchema)]
pub struct RodSummary {
    pub name: String,
    /// Node positions at the end (m), `dimension` components each.
    pub final_positions: Vec<Vec<f64>>,
    /// Node velocities at the end (m/s), `dimension` components each.
    pub final_velocities: Vec<Vec<f64>>,
    /// Peak eq. 2 reaction magnitude per node (N).
    pub peak_reaction_per_node_n: Vec<f64>,
    /// Steps at whose end the node was constrained.
    pub contact_steps_per_node: Vec<u64>,
    /// Σ |R| dt per node (N·s).
    pub total_impulse_per_node_ns: Vec<f64>,
    /// Peak impulse-consistent force per node (N): the contact impulse over a sliding window
    /// of `force_window_s` divided by the window, a force that converges under dt refinement;
    /// zeros in 3D until the 3D run sends the shared events.
    pub peak_impulse_consistent_force_per_node_n: Vec<f64>,
    /// Peak bending stress per node (Pa); zeros in 3D until the 3D run reports stresses.
    pub peak_bending_stress_per_node_pa: Vec<f64>,
    /// Peak twist (shear) stress per node (Pa); empty in 2D (a planar rod does not twist),
    /// and in 3D until the 3D run reports stresses.
    pub peak_twist_stress_per_node_pa: Vec<f64>,
    /// First time the node was constrained (s), null if never.
    pub first_contact_time_s: Vec<Option<f64>>,
    /// Force of the drive on the clamped nodes at the end (N, sum over clamped nodes),
    /// `dimension` components; zeros in 3D until the 3D run reports drive forces.
    pub final_drive_force_n: Vec<f64>,
    /// Sum of the normal forces of the rod's contacts at the end (N).
    pub final_contact_force_n: f64,
    /// The tip: the last node, or node 0 when the last node is clamped and node 0 is not.
    pub tip_node: usize,
    /// Max over time of the tip's deflection from the rigidly driven shape (m):
    /// |x_tip(t) − x_tip(0) − (x_c(t) − x_c(0))|, x_c the first clamped node (the drives are
    /// translations, so this is the tip's distance from where the undeformed prong would put
    /// it); with no clamped node, the tip's displacement |x_tip(t) − x_tip(0)|.
    pub max_tip_deflection_m: f64,
}

/// The summary of one run (`gripsim run --summary FILE`).
#[derive(Debug, Clone, Serialize, PartialEq, JsonSchema)]
pub struct Summary {
    /// The version of this shape ([`SUMMARY_VERSION`]).
    pub summary_version: u32,
    /// 2 (planar) or 3: the number of components of every vector below.
    pub dimension: u8,
    pub scenario: String,
    pub gripsim_version: String,
    pub mode: String,
    pub completed: bool,
    pub error: Option<String>,
    pub steps: u64,
    pub newton_iterations: u64,
    pub contact_passes: u64,
    pub dt_backoffs: u64,
    /// Adaptive stepping: attempts the error estimate rejected.
    pub rejected_steps: u64,
    /// Second-order integrator: free node-steps that dropped to first order (a contact-state
    /// change, no smooth history), over every attempt the error estimate looked at; 0 under
    /// backward Euler.
    pub first_order_node_steps: u64,
    /// Steps split at a time of impact or of release (a contact-state change located inside
    /// the step).
    pub split_steps: u64,
    /// Jacobians the per-rod Newton solves factorised (BDF2's chord steps reuse one); 0 in
    /// 3D (not counted there).
    pub jacobian_factorizations: u64,
    /// Contacts that began, contacts that ended, and stick ↔ slip switches over the run, as
    /// the summary received them (`gripsim run`: accepted steps only).
    pub contacts_added: u64,
    pub contacts_released: u64,
    pub friction_switches: u64,
    pub simulated_time_s: f64,
    pub wall_time_s: f64,
    pub peak_reaction_force_n: f64,
    pub peak_reaction_node: Option<NodeRef>,
    pub peak_reaction_time_s: Option<f64>,
    /// Window (s) of the impulse-consistent force; 0 in 3D (not computed there yet, and the
    /// two keys after it 0 and null).
    pub force_window_s: f64,
    pub peak_impulse_consistent_force_n: f64,
    pub peak_impulse_consistent_node: Option<NodeRef>,
    pub contact_onset_time_s: Option<f64>,
    pub max_penetration_m: f64,
    /// Largest bending stress (Pa) and where; 0 and null in 3D until the 3D run reports
    /// stresses.
    pub max_bending_stress_pa: f64,
    pub max_bending_stress_node: Option<NodeRef>,
    /// Largest twist of an edge from its rest twist (rad); null in 2D.
    pub max_twist_rad: Option<f64>,
    /// Largest twist (shear) stress (Pa) and where; null in 2D, and in 3D until the 3D run
    /// reports stresses.
    pub max_twist_stress_pa: Option<f64>,
    pub max_twist_stress_node: Option<NodeRef>,
    pub rods: Vec<RodSummary>,
    /// The actuation phases in the order they ended (a phase still running at the end last,
    /// with `end_s` null).
    pub phases: Vec<PhaseSummary>,
    /// Grip, slip and drop of the first free body (null without one).
    pub grasp: Option<super::grasp::GraspSummary>,
    /// Dynamic mode: the rods' energy balance (J) — kinetic, elastic, gravity, dissipated by
    /// damping and by the integrator, work of the drives and the contacts; null in 3D until
    /// the 3D run computes it.
    pub energy: Option<crate::energy::balance::Balance>,
    /// What the balance misses, relative to its largest term (null with `energy`).
    pub energy_closure_rel: Option<f64>,
    /// Static mode: the smallest free-DOF Hessian eigenvalue at the end (N/m), and whether
    /// the equilibrium is unstable (negative).
    pub min_eigenvalue: Option<f64>,
    pub unstable_equilibrium: bool,
    /// Contact pressure on a compliant fruit and the bruise verdict (null when no contact
    /// with a compliant fruit happened, and in 3D until the 3D run reports pressures).
    pub contact_pressure: Option<PressureSummary>,
    /// Per `[[joint]]`: the largest force and moment it carried and the last (empty without
    /// joints).
    pub joints: Vec<JointSummary>,
}

/// One phase of an actuation program: when it ran and why it ended.
#[derive(Debug, Clone, Serialize, PartialEq, JsonSchema)]
pub struct PhaseSummary {
    /// The actuator (index: the `[[actuator]]` tables in order, then the rods' own drives).
    pub actuator: usize,
    /// The phase's index in its program.
    pub phase: usize,
    /// The phase's name (null when unnamed).
    pub name: Option<String>,
    /// When it began and ended (s); `end_s` null when the run ended in it.
    pub start_s: f64,
    pub end_s: Option<f64>,
    /// Which end condition ended it (null when the run ended in it).
    pub reason: Option<String>,
}

/// What one joint carried over the run.
#[derive(Debug, Clone, Serialize, PartialEq, Default, JsonSchema)]
pub struct JointSummary {
    /// The members (rod names) and their joined nodes.
    pub rods: [String; 2],
    pub nodes: [usize; 2],
    /// Largest |force| member a exerted on member b (N), and when (s).
    pub peak_force_n: f64,
    pub peak_force_time_s: f64,
    /// Largest |moment| of a rigid joint (N·m).
    pub peak_moment_nm: f64,
    /// At the last step: force (N) and moment (N·m).
    pub final_force_n: [f64; 2],
    pub final_moment_nm: f64,
}

/// What a compliant fruit felt over the run (Hertz line contact, docs/model.md): the solved
/// contact force of the law (it converges as dt → 0, unlike eq. 2's impact peak), the peak
/// pressure with where and when, the deepest indentation and the bruise verdict.
#[derive(Debug, Clone, Serialize, PartialEq, JsonSchema)]
pub struct PressureSummary {
    /// Largest normal force of one contact on a compliant fruit (N).
    pub peak_contact_force_n: f64,
    /// Largest Hertz peak pressure p₀ (Pa), where (rod, node, contact point) and when.
    pub max_pressure_pa: f64,
    pub max_pressure_node: NodeRef,
    /// The contact point (m), `dimension` components.
    pub max_pressure_point: Vec<f64>,
    pub max_pressure_time_s: f64,
    /// The contact half-width a at that moment (m).
    pub half_width_at_max_m: f64,
    /// The contact's minor half-width at that moment (m): an elliptical 3D contact's b ≤ a;
    /// a planar line contact's equals `half_width_at_max_m`.
    pub half_width_minor_at_max_m: f64,
    /// Deepest indentation of the fruit (m).
    pub max_indentation_m: f64,
    /// The fruit's bruise threshold (Pa) and whether the pressure went above it.
    pub bruise_pressure_pa: f64,
    pub bruised: bool,
    /// max p₀ / bruise threshold.
    pub bruise_ratio: f64,
    /// Widest part of one contact above the threshold (m, the full width 2 a √(1 − (p/p₀)²)).
    pub max_bruise_width_m: f64,
}

/// Cumulative contact impulse of one node as a piecewise-linear function of time, trimmed
/// to the last window: the impulse-consistent force is (C(t) − C(t − τ))/τ.
#[derive(Debug, Default, Clone)]
pub struct Window {
    /// (time, cumulative impulse x, y) breakpoints, oldest first.
    points: std::collections::VecDeque<(f64, f64, f64)>,
}

impl Window {
    /// No impulse has been added yet.
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// Add the impulse (jx, jy) of the step t0 → t1 and return the impulse-consistent force
    /// magnitude at t1 over a window of τ.
    pub fn push(&mut self, t0: f64, t1: f64, jx: f64, jy: f64, tau: f64) -> f64 {
        let (cx, cy) = self.points.back().map(|p| (p.1, p.2)).unwrap_or((0.0, 0.0));
        if self.points.is_empty() {
            self.points.push_back((t0, 0.0, 0.0));
        }
        let n = self.points.len();
        if jx == 0.0 && jy == 0.0 && n >= 2 && {
            let (a, b) = (self.points[n - 2], self.points[n - 1]);
            a.1 == b.1 && a.2 == b.2
        } {
            // No impulse on a flat stretch: extend it instead of adding a breakpoint (the
            // same function, so the same values; a node out of contact keeps two points).
            self.points[n - 1].0 = t1;
        } else {
            self.points.push_back((t1, cx + jx, cy + jy));
        }
        let from = t1 - tau;
        // Keep exactly one breakpoint at or before t − τ.
        while self.points.len() > 2 && self.points[1].0 <= from {
            self.points.pop_front();
        }
        let (ax, ay) = {
            let p0 = self.points[0];
            if p0.0 >= from {
                (p0.1, p0.2)
            } else {
                let p1 = self.points[1];
                let f = (from - p0.0) / (p1.0 - p0.0);
                (p0.1 + f * (p1.1 - p0.1), p0.2 + f * (p1.2 - p0.2))
            }
        };
        let (bx, by) = (cx + jx, cy + jy);
        (bx - ax).hypot(by - ay) / tau
    }
}

/// The tip of a rod: the last node, or node 0 when the last node is clamped and node 0 is not.
pub fn tip_node(clamped: &[bool]) -> usize {
    let n = clamped.len();
    if n > 1 && clamped[n - 1] && !clamped[0] {
        0
    } else {
        n.saturating_sub(1)
    }
}

/// A rod's tip node, its first clamped node, and their initial positions.
type Tip = (usize, Option<usize>, Option<([f64; 2], [f64; 2])>);

/// Collects a [`Summary`] from step events.
#[derive(Debug, Default)]
pub struct SummaryCollector {
    windows: Vec<Vec<Window>>,
    force_window: f64,
    ic_peak: f64,
    ic_at: Option<(usize, usize)>,
    names: Vec<String>,
    scenario: String,
    mode: String,
    rods: Vec<RodSummary>,
    peak: f64,
    peak_at: Option<(usize, usize, f64)>,
    stress: f64,
    stress_at: Option<(usize, usize)>,
    onset: Option<f64>,
    steps: u64,
    t: f64,
    error: Option<String>,
    ended: bool,
    /// Per rod: (tip node, first clamped node) and their initial positions.
    tips: Vec<Tip>,
    grasp: super::grasp::GraspTracker,
    pressure: Option<PressureSummary>,
    /// The obstacles' names (a body's own contact is named by the obstacle it presses).
    obstacles: Vec<String>,
    joints: Vec<JointSummary>,
    /// Contacts added, released and stick ↔ slip switches seen.
    changes: [u64; 3],
    phases: Phases,
}

/// The actuation phases from `PhaseChanged` events: the finished ones, and per actuator the
/// phase running now (index, name, start).
#[derive(Debug, Default)]
struct Phases {
    done: Vec<PhaseSummary>,
    running: Vec<Option<(usize, Option<String>, f64)>>,
    /// Per `[[actuator]]` table of the scenario: the name of its first phase (no event names
    /// it: a phase's name comes with the event that starts it).
    first_names: Vec<Option<String>>,
}

impl Phases {
    fn start(&mut self, text: &str) {
        let doc: Option<toml::Table> = text.parse().ok();
        self.first_names = doc
            .as_ref()
            .and_then(|d| d.get("actuator"))
            .and_then(toml::Value::as_array)
            .map(|a| {
                a.iter()
                    .map(|act| {
                        let first = act.get("phase").and_then(|p| p.get(0));
                        first
                            .and_then(|p| p.get("name"))
                            .and_then(toml::Value::as_str)
                            .map(str::to_string)
                    })
                    .collect()
            })
            .unwrap_or_default();
    }

    fn changed(
        &mut self,
        t: f64,
        actuator: usize,
        from: usize,
        to: Option<usize>,
        e: (&str, &str),
    ) {
        if self.running.len() <= actuator {
            self.running.resize(actuator + 1, None);
        }
        let (name, start) = match self.running[actuator].take() {
            Some((_, name, start)) => (name, start),
            None if from == 0 => (self.first_names.get(actuator).cloned().flatten(), 0.0),
            None => (None, 0.0),
        };
        self.done.push(PhaseSummary {
            actuator,
            phase: from,
            name,
            start_s: start,
            end_s: Some(t),
            reason: Some(e.1.to_string()),
        });
        // The event names the phase it starts as `'name'`, or `(unnamed)`.
        let label = e.0.strip_prefix('\'').and_then(|n| n.strip_suffix('\''));
        self.running[actuator] = to.map(|k| (k, label.map(str::to_string), t));
    }

    fn summary(&self) -> Vec<PhaseSummary> {
        let mut out = self.done.clone();
        for (a, r) in self.running.iter().enumerate() {
            if let Some((k, name, start)) = r {
                out.push(PhaseSummary {
                    actuator: a,
                    phase: *k,
                    name: name.clone(),
                    start_s: *start,
                    end_s: None,
                    reason: None,
                });
            }
        }
        out
    }
}

impl SummaryCollector {
    /// The joints' peaks and last values.
    fn joint_peaks(&mut self, t: f64, joints: &[crate::events::JointView]) {
        if self.joints.len() != joints.len() {
            self.joints = joints
                .iter()
                .map(|j| JointSummary {
                    rods: j
                        .rods
                        .map(|r| self.names.get(r).cloned().unwrap_or_default()),
                    nodes: j.nodes,
                    ..JointSummary::default()
                })
                .collect();
        }
        for (s, j) in self.joints.iter_mut().zip(joints) {
            let f = j.force[0].hypot(j.force[1]);
            if f > s.peak_force_n {
                s.peak_force_n = f;
                s.peak_force_time_s = t;
            }
            s.peak_moment_nm = s.peak_moment_nm.max(j.moment.abs());
            s.final_force_n = j.force;
            s.final_moment_nm = j.moment;
        }
    }

    /// With the default impulse-consistent force window of 1 ms.
    pub fn new() -> Self {
        Self::with_force_window(1e-3)
    }

    pub fn with_force_window(tau: f64) -> Self {
        Self {
            force_window: tau,
            ..Self::default()
        }
    }

    /// Finish with the solver's counters.
    pub fn finish(&self, stats: &crate::solver::RunStats, wall_time_s: f64) -> Summary {
        let node = |(r, n): (usize, usize)| NodeRef {
            rod: self.names[r].clone(),
            node: n,
        };
        Summary {
            summary_version: SUMMARY_VERSION,
            // The planar run's events (the 3D run builds its summary in rod3d::run3).
            dimension: 2,
            scenario: self.scenario.clone(),
            gripsim_version: env!("CARGO_PKG_VERSION").to_string(),
            mode: self.mode.clone(),
            completed: self.ended && self.error.is_none(),
            error: self.error.clone(),
            steps: stats.steps,
            newton_iterations: stats.newton_iterations,
            contact_passes: stats.contact_passes,
            dt_backoffs: stats.backoffs,
            rejected_steps: stats.rejected_steps,
            first_order_node_steps: stats.first_order_node_steps,
            split_steps: stats.split_steps,
            jacobian_factorizations: stats.jacobian_factorizations,
            contacts_added: self.changes[0],
            contacts_released: self.changes[1],
            friction_switches: self.changes[2],
            simulated_time_s: stats.t,
            wall_time_s,
            peak_reaction_force_n: self.peak,
            peak_reaction_node: self.peak_at.map(|(r, n, _)| node((r, n))),
            peak_reaction_time_s: self.peak_at.map(|(_, _, t)| t),
            force_window_s: self.force_window,
            peak_impulse_consistent_force_n: self.ic_peak,
            peak_impulse_consistent_node: self.ic_at.map(node),
            contact_onset_time_s: self.onset,
            max_penetration_m: stats.max_penetration,
            max_bending_stress_pa: self.stress,
            max_bending_stress_node: self.stress_at.map(node),
            max_twist_rad: None,
            max_twist_stress_pa: None,
            max_twist_stress_node: None,
            rods: self.rods.clone(),
            phases: self.phases.summary(),
            grasp: self.grasp.summary(),
            energy: Some(stats.energy.clone()),
            energy_closure_rel: Some(stats.energy.closure_rel()),
            min_eigenvalue: stats.min_eigenvalue,
            unstable_equilibrium: stats.unstable_equilibrium,
            contact_pressure: self.pressure.clone(),
            joints: self.joints.clone(),
        }
    }

    /// Fold one step's compliant contacts into the pressure summary.
    fn pressures(&mut self, t: f64, contacts: &[crate::events::ContactView]) {
        for c in contacts.iter().filter(|c| c.peak_pressure > 0.0) {
            let p = self.pressure.get_or_insert_with(|| PressureSummary {
                peak_contact_force_n: 0.0,
                max_pressure_pa: 0.0,
                max_pressure_node: NodeRef {
                    rod: String::new(),
                    node: 0,
                },
                max_pressure_point: vec![0.0; 2],
                max_pressure_time_s: 0.0,
                half_width_at_max_m: 0.0,
                half_width_minor_at_max_m: 0.0,
                max_indentation_m: 0.0,
                bruise_pressure_pa: c.bruise_pressure,
                bruised: false,
                bruise_ratio: 0.0,
                max_bruise_width_m: 0.0,
            });
            p.peak_contact_force_n = p.peak_contact_force_n.max(c.normal_force);
            p.max_indentation_m = p.max_indentation_m.max(c.indentation);
            p.max_bruise_width_m = p.max_bruise_width_m.max(2.0 * c.bruise_half_width);
            if c.peak_pressure > p.max_pressure_pa {
                p.max_pressure_pa = c.peak_pressure;
                // A body's own contact (a fruit on the table) names the obstacle it presses.
                let rod = match self.names.get(c.rod) {
                    Some(n) => n.clone(),
                    None => self.obstacles.get(c.obstacle).cloned().unwrap_or_default(),
                };
                p.max_pressure_node = NodeRef { rod, node: c.node };
                p.max_pressure_point
                    .copy_from_slice(&crate::events::xy(c.point));
                p.max_pressure_time_s = t;
                p.half_width_at_max_m = c.half_width;
                p.half_width_minor_at_max_m = c.half_width;
                p.bruise_pressure_pa = c.bruise_pressure;
                p.bruise_ratio = if c.bruise_pressure > 0.0 {
                    c.peak_pressure / c.bruise_pressure
                } else {
                    0.0
                };
                p.bruised = c.bruise_pressure > 0.0 && c.peak_pressure > c.bruise_pressure;
            }
        }
    }
}

impl SummaryCollector {
    /// Static mode: the peak reaction is the largest equilibrium contact force. A node's
    /// contact force is its reaction (already counted); an edge contact's is its multiplier,
    /// which its two nodes share, so the contacts are counted as well (at the contact's node,
    /// for an edge its segment's first node).
    fn static_contacts(&mut self, t: f64, contacts: &[crate::events::ContactView]) {
        for c in contacts.iter().filter(|c| c.rod != usize::MAX) {
            let f = c.normal_force.hypot(c.friction_force);
            if f > self.peak {
                self.peak = f;
                self.peak_at = Some((c.rod, c.node, t));
            }
        }
    }
}

/// |v| of node i's vector in `v` of stride `d` (2: `hypot`, the planar bits).
fn norm_at(v: &[f64], d: usize, i: usize) -> f64 {
    if d == 3 {
        let (x, y, z) = (v[3 * i], v[3 * i + 1], v[3 * i + 2]);
        (x * x + y * y + z * z).sqrt()
    } else {
        v[2 * i].hypot(v[2 * i + 1])
    }
}

impl Observer for SummaryCollector {
    fn on_event(&mut self, event: &Event<'_>) {
        self.grasp.on_event(event);
        match event {
            Event::RunStart(info) => {
                self.scenario = info.scenario_name.to_string();
                self.mode = format!("{:?}", info.mode).to_lowercase();
                self.names = info.rods.iter().map(|r| r.name.clone()).collect();
                self.obstacles = info.obstacle_names.to_vec();
                self.phases.start(info.scenario_text);
                self.rods = info
                    .rods
                    .iter()
                    .map(|r| RodSummary {
                        name: r.name.clone(),
                        final_positions: vec![vec![0.0; 2]; r.nodes],
                        final_velocities: vec![vec![0.0; 2]; r.nodes],
                        peak_reaction_per_node_n: vec![0.0; r.nodes],
                        contact_steps_per_node: vec![0; r.nodes],
                        total_impulse_per_node_ns: vec![0.0; r.nodes],
                        peak_impulse_consistent_force_per_node_n: vec![0.0; r.nodes],
                        peak_bending_stress_per_node_pa: vec![0.0; r.nodes],
                        peak_twist_stress_per_node_pa: Vec::new(),
                        first_contact_time_s: vec![None; r.nodes],
                        final_drive_force_n: vec![0.0; 2],
                        final_contact_force_n: 0.0,
                        tip_node: tip_node(&r.clamped),
                        max_tip_deflection_m: 0.0,
                    })
                    .collect();
                self.tips = info
                    .rods
                    .iter()
                    .map(|r| {
                        (
                            tip_node(&r.clamped),
                            r.clamped.iter().position(|c| *c),
                            None,
                        )
                    })
                    .collect();
                self.windows = info
                    .rods
                    .iter()
                    .map(|r| vec![Window::default(); r.nodes])
                    .collect();
            }
            Event::StepEnd {
                step,
                t,
                dt,
                rods,
                contacts,
                joints,
                ..
            } => {
                self.steps = *step;
                self.t = *t;
                self.pressures(*t, contacts);
                self.joint_peaks(*t, joints);
                for (ri, v) in rods.iter().enumerate() {
                    let s = &mut self.rods[ri];
                    let mut drive = [0.0; 2];
                    // The stride of the per-node vectors (3D: x and y here, |·| of all three).
                    let d = usize::from(v.dim.max(2));
                    for i in 0..s.final_positions.len() {
                        s.final_positions[i].copy_from_slice(&v.q[d * i..d * i + 2]);
                        s.final_velocities[i].copy_from_slice(&v.u[d * i..d * i + 2]);
                        drive[0] += v.drive_force[d * i];
                        drive[1] += v.drive_force[d * i + 1];
                        // A node with no reaction and no impulse, now or before, has
                        // nothing to add: skipping it saves the hypot calls and the window of
                        // every free node in every step (the sums and peaks are the same).
                        let idle = v.reaction[d * i..d * i + d].iter().all(|&x| x == 0.0)
                            && v.impulse[d * i..d * i + d].iter().all(|&x| x == 0.0)
                            && self.windows[ri][i].is_empty();
                        if !idle {
                            let rm = norm_at(v.reaction, d, i);
                            if rm > s.peak_reaction_per_node_n[i] {
                                s.peak_reaction_per_node_n[i] = rm;
                            }
                            if rm > self.peak {
                                self.peak = rm;
                                self.peak_at = Some((ri, i, *t));
                            }
                            s.total_impulse_per_node_ns[i] += norm_at(v.impulse, d, i);
                            if *dt > 0.0 {
                                let f = self.windows[ri][i].push(
                                    *t - *dt,
                                    *t,
                                    v.impulse[d * i],
                                    v.impulse[d * i + 1],
                                    self.force_window,
                                );
                                if f > s.peak_impulse_consistent_force_per_node_n[i] {
                                    s.peak_impulse_consistent_force_per_node_n[i] = f;
                                }
                                if f > self.ic_peak {
                                    self.ic_peak = f;
                                    self.ic_at = Some((ri, i));
                                }
                            }
                        }
                        if v.in_contact[i] {
                            s.contact_steps_per_node[i] += 1;
                            if s.first_contact_time_s[i].is_none() {
                                s.first_contact_time_s[i] = Some(*t);
                            }
                            if self.onset.is_none() {
                                self.onset = Some(*t);
                            }
                        }
                        let st = v.bending_stress[i];
                        if st > s.peak_bending_stress_per_node_pa[i] {
                            s.peak_bending_stress_per_node_pa[i] = st;
                        }
                        if st > self.stress {
                            self.stress = st;
                            self.stress_at = Some((ri, i));
                        }
                    }
                    s.final_drive_force_n.copy_from_slice(&drive);
                    s.final_contact_force_n = contacts
                        .iter()
                        .filter(|c| c.rod == ri)
                        .map(|c| c.normal_force)
                        .sum();
                    let (tip, base, start) = &mut self.tips[ri];
                    let at = |k: usize| [v.q[d * k], v.q[d * k + 1]];
                    let b = base.map(at).unwrap_or([0.0; 2]);
                    let (tip0, b0) = *start.get_or_insert((at(*tip), b));
                    let p = at(*tip);
                    let d =
                        (p[0] - tip0[0] - (b[0] - b0[0])).hypot(p[1] - tip0[1] - (b[1] - b0[1]));
                    if d > s.max_tip_deflection_m {
                        s.max_tip_deflection_m = d;
                    }
                }
                if self.mode == "static" {
                    self.static_contacts(*t, contacts);
                }
            }
            Event::ConstraintAdded(_) => self.changes[0] += 1,
            Event::ConstraintReleased(..) => self.changes[1] += 1,
            Event::FrictionChanged(_) => self.changes[2] += 1,
            Event::PhaseChanged {
                t,
                actuator,
                from,
                to,
                name,
                reason,
                ..
            } => self
                .phases
                .changed(*t, *actuator, *from, *to, (name, reason)),
            Event::RunEnd { error, .. } => {
                self.ended = true;
                self.error = error.map(|e| e.to_string());
            }
            _ => {}
        }
    }
}

#[cfg(test)]
mod tests {
    use super::Window;

    /// The window as first written: a breakpoint per step, flat stretches included.
    fn reference(
        points: &mut Vec<(f64, f64, f64)>,
        t0: f64,
        t1: f64,
        j: [f64; 2],
        tau: f64,
    ) -> f64 {
        let (cx, cy) = points.last().map(|p| (p.1, p.2)).unwrap_or((0.0, 0.0));
        if points.is_empty() {
            points.push((t0, 0.0, 0.0));
        }
        points.push((t1, cx + j[0], cy + j[1]));
        let from = t1 - tau;
        while points.len() > 2 && points[1].0 <= from {
            points.remove(0);
        }
        let (p0, p1) = (points[0], points[1]);
        let (ax, ay) = if p0.0 >= from {
            (p0.1, p0.2)
        } else {
            let f = (from - p0.0) / (p1.0 - p0.0);
            (p0.1 + f * (p1.1 - p0.1), p0.2 + f * (p1.2 - p0.2))
        };
        (cx + j[0] - ax).hypot(cy + j[1] - ay) / tau
    }

    /// Flat stretches (steps without impulse) kept as one segment give the same force, bit for
    /// bit, as a breakpoint per step, through contacts, gaps and a window of 7 steps.
    #[test]
    fn a_flat_stretch_is_one_segment_and_the_same_force() {
        let (dt, tau) = (1e-5, 7e-5);
        let mut w = Window::default();
        let mut r = Vec::new();
        for k in 0..200u32 {
            let on = (20..35).contains(&k) || k == 60 || (90..93).contains(&k);
            let j = if on {
                [1e-6 * f64::from(k % 5 + 1), -3e-7 * f64::from(k % 3)]
            } else {
                [0.0, 0.0]
            };
            let (t0, t1) = (f64::from(k) * dt, f64::from(k + 1) * dt);
            let a = w.push(t0, t1, j[0], j[1], tau);
            let b = reference(&mut r, t0, t1, j, tau);
            assert_eq!(a.to_bits(), b.to_bits(), "step {k}: {a} vs {b}");
        }
        // Out of contact since step 93: the window holds two points, not a point per step.
        assert!(w.points.len() <= 3, "{} points", w.points.len());
    }
}
