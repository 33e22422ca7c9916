//! The run summary: peak reactions and where they act, contact counts, final state.

use crate::events::{Event, Observer};
use serde::Serialize;

#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct NodeRef {
    pub rod: String,
    pub node: usize,
}

#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct RodSummary {
    pub name: String,
    pub final_positions: Vec<[f64; 2]>,
    pub final_velocities: Vec<[f64; 2]>,
    /// Peak eq. 2 reaction magnitude per node (N).
    pub peak_reaction_per_node_n: Vec<f64>,
    /// Steps at whose end the node was constrained.
    pub contact_steps_per_node: Vec<u64>,
    /// Σ |R| dt per node (N·s).
    pub total_impulse_per_node_ns: Vec<f64>,
    /// Peak bending stress per node (Pa).
    pub peak_bending_stress_per_node_pa: Vec<f64>,
    /// First time the node was constrained (s), null if never.
    pub first_contact_time_s: Vec<Option<f64>>,
    /// Force of the drive on the clamped nodes at the end (N, sum over clamped nodes).
    pub final_drive_force_n: [f64; 2],
}

#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct Summary {
    pub scenario: String,
    pub gripsim_version: String,
    pub mode: String,
    pub completed: bool,
    pub error: Option<String>,
    pub steps: u64,
    pub newton_iterations: u64,
    pub contact_passes: u64,
    pub dt_backoffs: u64,
    pub simulated_time_s: f64,
    pub wall_time_s: f64,
    pub peak_reaction_force_n: f64,
    pub peak_reaction_node: Option<NodeRef>,
    pub peak_reaction_time_s: Option<f64>,
    pub contact_onset_time_s: Option<f64>,
    pub max_penetration_m: f64,
    pub max_bending_stress_pa: f64,
    pub max_bending_stress_node: Option<NodeRef>,
    pub rods: Vec<RodSummary>,
}

/// Collects a [`Summary`] from step events.
#[derive(Debug, Default)]
pub struct SummaryCollector {
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
}

impl SummaryCollector {
    pub fn new() -> Self {
        Self::default()
    }

    /// Finish with the solver's counters.
    pub fn finish(&self, stats: &crate::solver::RunStats, wall_time_s: f64) -> Summary {
        let node = |(r, n): (usize, usize)| NodeRef {
            rod: self.names[r].clone(),
            node: n,
        };
        Summary {
            scenario: self.scenario.clone(),
            gripsim_version: env!("CARGO_PKG_VERSION").to_string(),
            mode: self.mode.clone(),
            completed: self.ended && self.error.is_none(),
            error: self.error.clone(),
            steps: stats.steps,
            newton_iterations: stats.newton_iterations,
            contact_passes: stats.contact_passes,
            dt_backoffs: stats.backoffs,
            simulated_time_s: stats.t,
            wall_time_s,
            peak_reaction_force_n: self.peak,
            peak_reaction_node: self.peak_at.map(|(r, n, _)| node((r, n))),
            peak_reaction_time_s: self.peak_at.map(|(_, _, t)| t),
            contact_onset_time_s: self.onset,
            max_penetration_m: stats.max_penetration,
            max_bending_stress_pa: self.stress,
            max_bending_stress_node: self.stress_at.map(node),
            rods: self.rods.clone(),
        }
    }
}

impl Observer for SummaryCollector {
    fn on_event(&mut self, event: &Event<'_>) {
        match event {
            Event::RunStart(info) => {
                self.scenario = info.scenario_name.to_string();
                self.mode = format!("{:?}", info.mode).to_lowercase();
                self.names = info.rods.iter().map(|r| r.name.clone()).collect();
                self.rods = info
                    .rods
                    .iter()
                    .map(|r| RodSummary {
                        name: r.name.clone(),
                        final_positions: vec![[0.0; 2]; r.nodes],
                        final_velocities: vec![[0.0; 2]; r.nodes],
                        peak_reaction_per_node_n: vec![0.0; r.nodes],
                        contact_steps_per_node: vec![0; r.nodes],
                        total_impulse_per_node_ns: vec![0.0; r.nodes],
                        peak_bending_stress_per_node_pa: vec![0.0; r.nodes],
                        first_contact_time_s: vec![None; r.nodes],
                        final_drive_force_n: [0.0; 2],
                    })
                    .collect();
            }
            Event::StepEnd { step, t, rods, .. } => {
                self.steps = *step;
                self.t = *t;
                for (ri, v) in rods.iter().enumerate() {
                    let s = &mut self.rods[ri];
                    let mut drive = [0.0; 2];
                    for i in 0..s.final_positions.len() {
                        s.final_positions[i] = [v.q[2 * i], v.q[2 * i + 1]];
                        s.final_velocities[i] = [v.u[2 * i], v.u[2 * i + 1]];
                        drive[0] += v.drive_force[2 * i];
                        drive[1] += v.drive_force[2 * i + 1];
                        let rm = v.reaction[2 * i].hypot(v.reaction[2 * i + 1]);
                        if rm > s.peak_reaction_per_node_n[i] {
                            s.peak_reaction_per_node_n[i] = rm;
                        }
                        if rm > self.peak {
                            self.peak = rm;
                            self.peak_at = Some((ri, i, *t));
                        }
                        s.total_impulse_per_node_ns[i] +=
                            v.impulse[2 * i].hypot(v.impulse[2 * i + 1]);
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
                    s.final_drive_force_n = drive;
                }
            }
            Event::RunEnd { error, .. } => {
                self.ended = true;
                self.error = error.map(|e| e.to_string());
            }
            _ => {}
        }
    }
}
