//! Does the gripper hold the fruit? Grip force, friction margin, slip and drop of the first
//! free body, from step events.
//!
//! - The gripper's position is the centroid of every rod's driven nodes; the fruit's position
//!   relative to it is tracked every step.
//! - The lift begins at the first step where that centroid has risen (against gravity) by more
//!   than a quarter of the hold tolerance above where it was when a prong first touched the
//!   fruit (a jaw that swings in about a pivot rises a little while it closes; that is not a
//!   lift); the fruit's position relative to the gripper then is the reference.
//! - The verdict is taken at the end of the lift: the last step before the gripper first moves
//!   down again (to place the fruit), or the end of the run.
//! - `held`: the lift happened and the fruit is then within its `hold_tolerance` of the
//!   reference, touching a prong. `dropped`: the lift happened and the fruit then touches no
//!   prong.
//! - Safety margin: Σ μ_s N over the prong contacts on the fruit divided by its weight, its
//!   minimum over the lift (≥ 1 is needed to hold a fruit at rest).

use crate::events::{xy, ContactView, Event, RodStepView};
use schemars::JsonSchema;
use serde::Serialize;

/// How a grasp ended.
#[derive(Debug, Clone, Copy, Serialize, PartialEq, Eq, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum Verdict {
    /// The lift happened and the fruit ended it within its hold tolerance, touching a prong.
    Held,
    /// The lift happened and the fruit moved beyond its hold tolerance but still touches.
    Slipped,
    /// The lift happened and the fruit touches no prong at its end.
    Dropped,
    /// The gripper never lifted.
    NoLift,
}

impl Verdict {
    /// From a lift (or none) and the held and dropped flags.
    pub fn of(lifted: bool, held: bool, dropped: bool) -> Verdict {
        match (lifted, held, dropped) {
            (false, ..) => Verdict::NoLift,
            (true, true, _) => Verdict::Held,
            (true, _, true) => Verdict::Dropped,
            (true, false, false) => Verdict::Slipped,
        }
    }

    /// The word printed for it: HELD, SLIPPED, DROPPED or "no lift".
    pub fn word(self) -> &'static str {
        match self {
            Verdict::Held => "HELD",
            Verdict::Slipped => "SLIPPED",
            Verdict::Dropped => "DROPPED",
            Verdict::NoLift => "no lift",
        }
    }
}

/// Grip, slip and drop of the first free body.
#[derive(Debug, Clone, Serialize, PartialEq, JsonSchema)]
pub struct GraspSummary {
    /// `held`, `slipped`, `dropped`, or `no_lift` when the gripper never lifted.
    pub verdict: Verdict,
    pub fruit: String,
    pub fruit_mass_kg: f64,
    /// True when the fruit ends the lift where it sat in the gripper (within hold_tolerance_m).
    pub held: bool,
    /// True when the fruit ends the lift touching no prong.
    pub dropped: bool,
    pub hold_tolerance_m: f64,
    /// Whether (and when) the gripper lifted.
    pub lift_start_time_s: Option<f64>,
    /// Largest total normal force of one prong on the fruit (N).
    pub peak_grip_force_n: f64,
    /// Largest total normal force on the fruit from all prongs (N).
    pub peak_total_grip_force_n: f64,
    /// Min over the lift of Σ μ_s N / (m g); null without a lift.
    pub min_safety_margin: Option<f64>,
    /// The margin at the moment the lift began.
    pub safety_margin_at_lift: Option<f64>,
    /// Largest displacement of the fruit relative to the gripper during the lift (m).
    pub max_slip_m: f64,
    /// First stick → slip of a prong contact on the fruit (s); null in 3D until the 3D run
    /// reports stick ↔ slip switches.
    pub first_slip_time_s: Option<f64>,
    /// Largest friction utilisation |R_t| / (μ_s R_n) of a prong contact on the fruit; 0 in
    /// 3D until the 3D run reports it.
    pub max_friction_utilisation: f64,
    /// The fruit's centroid at the start of the run (m), `dimension` components.
    pub initial_position_m: Vec<f64>,
    /// The fruit at the end of the lift (see `held`; in 3D at the end of the run),
    /// `dimension` components.
    pub final_position_m: Vec<f64>,
    pub final_velocity_m_s: Vec<f64>,
}

/// Collects a [`GraspSummary`].
#[derive(Debug, Default, Clone)]
pub struct GraspTracker {
    fruit: Option<(String, usize, f64, [f64; 2], f64)>,
    clamped: Vec<Vec<usize>>,
    start_height: Option<f64>,
    rel_ref: Option<[f64; 2]>,
    out: Option<GraspSummary>,
    touching: bool,
    last_rel: [f64; 2],
    /// Highest the gripper has been since the lift began; whether it has come down since.
    top: f64,
    descended: bool,
    last_touching: bool,
}

impl GraspTracker {
    pub fn on_event(&mut self, e: &Event<'_>) {
        match e {
            Event::RunStart(info) => {
                self.clamped = info
                    .rods
                    .iter()
                    .map(|r| (0..r.nodes).filter(|&i| r.clamped[i]).collect())
                    .collect();
                self.fruit = info.bodies.first().map(|b| {
                    (
                        b.name.clone(),
                        b.obstacle,
                        b.mass,
                        b.weight,
                        b.hold_tolerance,
                    )
                });
                self.out = self.fruit.as_ref().map(|f| GraspSummary {
                    verdict: Verdict::NoLift,
                    fruit: f.0.clone(),
                    fruit_mass_kg: f.2,
                    held: false,
                    dropped: false,
                    hold_tolerance_m: f.4,
                    lift_start_time_s: None,
                    peak_grip_force_n: 0.0,
                    peak_total_grip_force_n: 0.0,
                    min_safety_margin: None,
                    safety_margin_at_lift: None,
                    max_slip_m: 0.0,
                    first_slip_time_s: None,
                    max_friction_utilisation: 0.0,
                    initial_position_m: info.bodies[0].centroid.to_vec(),
                    final_position_m: vec![0.0; 2],
                    final_velocity_m_s: vec![0.0; 2],
                });
            }
            Event::FrictionChanged(f) => {
                let fruit_obstacle = self.fruit.as_ref().map(|f| f.1);
                if let Some(o) = self.out.as_mut() {
                    if f.rod != usize::MAX && !f.stuck && Some(f.obstacle) == fruit_obstacle {
                        o.first_slip_time_s.get_or_insert(f.t);
                    }
                }
            }
            Event::StepEnd {
                t,
                rods,
                bodies,
                contacts,
                ..
            } => {
                if let Some(b) = bodies.first() {
                    self.step(*t, rods, xy(b.position), xy(b.velocity), contacts);
                }
            }
            Event::RunEnd { .. } => self.finish(),
            _ => {}
        }
    }

    fn step(
        &mut self,
        t: f64,
        rods: &[RodStepView<'_>],
        pos: [f64; 2],
        vel: [f64; 2],
        contacts: &[ContactView],
    ) {
        let (Some(f), Some(o)) = (self.fruit.as_ref(), self.out.as_mut()) else {
            return;
        };
        let w = f.3[0].hypot(f.3[1]);
        let up = if w > 0.0 {
            [-f.3[0] / w, -f.3[1] / w]
        } else {
            [0.0, 1.0]
        };
        let (mut cx, mut cy, mut n) = (0.0, 0.0, 0.0);
        for (r, v) in rods.iter().enumerate() {
            let d = usize::from(v.dim.max(2));
            for &i in self.clamped.get(r).map(Vec::as_slice).unwrap_or(&[]) {
                cx += v.q[d * i];
                cy += v.q[d * i + 1];
                n += 1.0;
            }
        }
        let clamp = if n > 0.0 { [cx / n, cy / n] } else { [0.0; 2] };
        let rel = [pos[0] - clamp[0], pos[1] - clamp[1]];
        let height = clamp[0] * up[0] + clamp[1] * up[1];
        let mut per_rod = vec![0.0f64; rods.len()];
        let (mut total, mut mu_n) = (0.0, 0.0);
        self.touching = false;
        for c in contacts
            .iter()
            .filter(|c| c.rod != usize::MAX && c.obstacle == f.1)
        {
            self.touching = true;
            let nf = c.normal_force.max(0.0);
            per_rod[c.rod] += nf;
            total += nf;
            mu_n += c.mu_s * nf;
            o.max_friction_utilisation = o.max_friction_utilisation.max(c.utilisation);
        }
        o.peak_grip_force_n = per_rod.iter().fold(o.peak_grip_force_n, |a, b| a.max(*b));
        o.peak_total_grip_force_n = o.peak_total_grip_force_n.max(total);
        let margin = if w > 0.0 { mu_n / w } else { f64::INFINITY };
        if self.touching && self.start_height.is_none() {
            self.start_height = Some(height);
        }
        let rise = self.start_height.map_or(0.0, |h0| height - h0);
        if self.rel_ref.is_none() && n > 0.0 && rise > 0.25 * o.hold_tolerance_m {
            self.rel_ref = Some(rel);
            o.lift_start_time_s = Some(t);
            o.safety_margin_at_lift = Some(margin);
            self.top = height;
        }
        if self.rel_ref.is_some() && !self.descended {
            self.top = self.top.max(height);
            self.descended = height < self.top - 1e-6;
        }
        if self.descended {
            return;
        }
        if let Some(r0) = self.rel_ref {
            o.min_safety_margin = Some(o.min_safety_margin.map_or(margin, |m| m.min(margin)));
            o.max_slip_m = o.max_slip_m.max((rel[0] - r0[0]).hypot(rel[1] - r0[1]));
        }
        o.final_position_m.copy_from_slice(&pos);
        o.final_velocity_m_s.copy_from_slice(&vel);
        self.last_rel = rel;
        self.last_touching = self.touching;
    }

    fn finish(&mut self) {
        let Some(o) = self.out.as_mut() else { return };
        if let Some(r0) = self.rel_ref {
            let d = (self.last_rel[0] - r0[0]).hypot(self.last_rel[1] - r0[1]);
            o.held = self.last_touching && d <= o.hold_tolerance_m;
            o.dropped = !self.last_touching;
        }
        o.verdict = Verdict::of(self.rel_ref.is_some(), o.held, o.dropped);
    }

    pub fn summary(&self) -> Option<GraspSummary> {
        self.out.clone()
    }
}
