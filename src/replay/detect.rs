//! Velocity spikes and sticking nodes in a recorded run. The rules, their reasoning and the
//! defaults are in docs/replay.md; in short:
//!
//! * **Spike** (per free node and step, dynamic runs): the velocity change not explained by the
//!   smooth forces, e = Δv − Δt f(q_{k+1})/m (elastic + gravity + loads, recomputed from the
//!   recorded positions as implicit Euler evaluates them), is split into what a perfectly
//!   inelastic, frictionless contact does (along the outward normal: cancel what the forces
//!   push into the surface over the step — support — and remove at most the normal velocity
//!   the node brought into the step — impact) and the rest.
//!   - `impact`: the impact part is large: ≥ `spike_floor`, implied acceleration ≥
//!     `spike_accel_ratio` × |g|, and the displacement it stands for, jump × Δt, ≥
//!     `spike_displacement`. The last term makes the severity scale with Δt: the same impact
//!     resolved with a 100 times smaller step is not a spike.
//!   - `unexplained`: the rest is large (≥ `spike_floor` and ≥ `spike_accel_ratio` × the
//!     node's acceleration scale max(|g|, |f|/m)), at any Δt: a jump no force and no contact
//!     can produce.
//!   - `alternating`: Δv reverses direction at least `alternation_flips` times within
//!     `alternation_window` steps with |Δv| ≥ max(`spike_floor`, `spike_accel_ratio` Δt |g|):
//!     an oscillation of a period no step resolves.
//! * **Sticking** (per free node):
//!   - `toggling`: ≥ `stick_toggles` constraint changes (added or released, `/sim/contact`)
//!     within `stick_window` steps;
//!   - `oscillating`: constrained, and moved by the corrector (|q − q_predictor| ≥
//!     `stick_correction_min`) in ≥ `stick_corrections` of the last `stick_window` steps with the
//!     correction reversing its normal direction at least once;
//!   - `adhesive_hold`: constrained at the end of a step while its eq. 2 reaction pulls it into
//!     the obstacle, R·n < −`adhesion_tolerance`.

use super::read::Run;
use crate::energy::{bend::bend, stretch::stretch};
use crate::model::Rod;
use serde::Serialize;

/// Thresholds of the rules (each one a `gripsim replay` flag).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, clap::Args)]
pub struct Thresholds {
    /// Spikes: smallest velocity jump (m/s) counted at all.
    #[arg(long, value_name = "M/S", default_value = "1e-3")]
    pub spike_floor: f64,
    /// Spikes: the jump's implied acceleration |jump|/dt must exceed this many times |g|
    /// (impacts) or the node's acceleration scale max(|g|, |f|/m) (unexplained jumps).
    #[arg(long, value_name = "RATIO", default_value = "10")]
    pub spike_accel_ratio: f64,
    /// Impact spikes: the displacement the jump stands for, |jump| x dt (m), must exceed this.
    #[arg(long, value_name = "M", default_value = "1e-5")]
    pub spike_displacement: f64,
    /// Alternating spikes: window (steps) in which the velocity change must reverse.
    #[arg(long, value_name = "STEPS", default_value = "8")]
    pub alternation_window: u64,
    /// Alternating spikes: reversals of the velocity change needed within the window.
    #[arg(long, value_name = "N", default_value = "4")]
    pub alternation_flips: u64,
    /// Sticking: window (steps) for the toggling and oscillating rules.
    #[arg(long, value_name = "STEPS", default_value = "20")]
    pub stick_window: u64,
    /// Sticking (toggling): constraint changes (added or released) needed within the window.
    #[arg(long, value_name = "N", default_value = "4")]
    pub stick_toggles: u64,
    /// Sticking (oscillating): corrected steps needed within the window.
    #[arg(long, value_name = "N", default_value = "4")]
    pub stick_corrections: u64,
    /// Sticking (oscillating): smallest corrector displacement |q - q_predictor| (m) counted.
    #[arg(long, value_name = "M", default_value = "1e-7")]
    pub stick_correction_min: f64,
    /// Sticking (adhesive hold): a constrained node with R.n below minus this (N) is flagged.
    #[arg(long, value_name = "N", default_value = "1e-6")]
    pub adhesion_tolerance: f64,
}

impl Thresholds {
    pub const DEFAULT: Thresholds = Thresholds {
        spike_floor: 1e-3,
        spike_accel_ratio: 10.0,
        spike_displacement: 1e-5,
        alternation_window: 8,
        alternation_flips: 4,
        stick_window: 20,
        stick_toggles: 4,
        stick_corrections: 4,
        stick_correction_min: 1e-7,
        adhesion_tolerance: 1e-6,
    };

    /// Reject values that make no sense (negative, NaN, empty windows).
    pub fn validate(&self) -> Result<(), String> {
        let pos = [
            ("--spike-floor", self.spike_floor),
            ("--spike-accel-ratio", self.spike_accel_ratio),
            ("--spike-displacement", self.spike_displacement),
            ("--stick-correction-min", self.stick_correction_min),
            ("--adhesion-tolerance", self.adhesion_tolerance),
        ];
        for (name, v) in pos {
            if !(v.is_finite() && v >= 0.0) {
                return Err(format!("{name} must be a finite number >= 0, got {v}"));
            }
        }
        let counts = [
            ("--alternation-window", self.alternation_window),
            ("--alternation-flips", self.alternation_flips),
            ("--stick-window", self.stick_window),
            ("--stick-toggles", self.stick_toggles),
            ("--stick-corrections", self.stick_corrections),
        ];
        for (name, v) in counts {
            if v == 0 {
                return Err(format!("{name} must be at least 1"));
            }
        }
        Ok(())
    }
}

impl Default for Thresholds {
    fn default() -> Self {
        Self::DEFAULT
    }
}

/// One velocity spike (or, for `alternating`, one episode of them).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Spike {
    /// `impact`, `unexplained` or `alternating`.
    pub kind: &'static str,
    pub rod: usize,
    pub rod_name: String,
    pub node: usize,
    /// The step whose velocity change triggered it (`alternating`: the first of the episode).
    pub step: u64,
    /// Time at the end of that step (s).
    pub t: f64,
    /// `alternating`: the last step of the episode; otherwise equal to `step`.
    pub last_step: u64,
    pub dt: f64,
    /// Δv = u_k − u_{k−1} (m/s).
    pub dv: [f64; 2],
    pub dv_norm: f64,
    /// |Δt f/m|: the velocity change the smooth forces give over the step (m/s).
    pub force_dv: f64,
    /// The flagged jump (m/s): the contact part (`impact`), the unexplained part
    /// (`unexplained`), or the largest |Δv| of the episode (`alternating`).
    pub jump: f64,
    /// The part of e = Δv − Δt f/m that removed the normal velocity the node brought into
    /// the step (m/s).
    pub impact_jump: f64,
    /// The part of e nothing explains (m/s).
    pub unexplained_jump: f64,
    /// Normal speed into the surface at the start of the step (m/s), for a node constrained
    /// at its end; else 0.
    pub approach_speed: f64,
    /// |jump| / dt (m/s²).
    pub accel: f64,
    /// The scale it is compared with (m/s²): |g| for an impact, max(|g|, |f|/m) otherwise.
    pub accel_ref: f64,
    pub accel_ratio: f64,
    /// |jump| × dt (m).
    pub displacement: f64,
    /// Node constrained at the end of the step.
    pub in_contact: bool,
    /// `alternating`: reversals of Δv in the episode; else 0.
    pub flips: u64,
}

/// One episode of a sticking node.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Sticking {
    /// `toggling`, `oscillating` or `adhesive_hold`.
    pub rule: &'static str,
    pub rod: usize,
    pub rod_name: String,
    pub node: usize,
    /// First step of the episode, and the time at its end (s).
    pub step: u64,
    pub t: f64,
    pub last_step: u64,
    pub last_t: f64,
    /// Constraint changes (`toggling`), corrected steps (`oscillating`) or held steps
    /// (`adhesive_hold`) in the episode.
    pub count: u64,
    /// `oscillating`: largest |q − q_predictor| (m); else 0.
    pub max_correction: f64,
    /// `adhesive_hold`: the most negative R·n (N); else 0.
    pub min_normal_reaction: f64,
}

/// Everything found in one run.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct Findings {
    pub spikes: Vec<Spike>,
    pub sticking: Vec<Sticking>,
}

/// Counts by kind.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct Counts {
    pub spikes: usize,
    pub impact: usize,
    pub unexplained: usize,
    pub alternating: usize,
    pub sticking: usize,
    pub toggling: usize,
    pub oscillating: usize,
    pub adhesive_hold: usize,
}

impl Findings {
    pub fn counts(&self) -> Counts {
        let s = |k: &str| self.spikes.iter().filter(|x| x.kind == k).count();
        let t = |k: &str| self.sticking.iter().filter(|x| x.rule == k).count();
        Counts {
            spikes: self.spikes.len(),
            impact: s("impact"),
            unexplained: s("unexplained"),
            alternating: s("alternating"),
            sticking: self.sticking.len(),
            toggling: t("toggling"),
            oscillating: t("oscillating"),
            adhesive_hold: t("adhesive_hold"),
        }
    }

    pub fn is_empty(&self) -> bool {
        self.spikes.is_empty() && self.sticking.is_empty()
    }
}

/// Elastic + gravity + load force on every node of `rod` at `q` (interleaved, N).
pub fn smooth_force(rod: &Rod, gravity: [f64; 2], q: &[f64], f: &mut [f64]) {
    let n = rod.n;
    for i in 0..n {
        f[2 * i] = rod.load[2 * i] + rod.mass[i] * gravity[0];
        f[2 * i + 1] = rod.load[2 * i + 1] + rod.mass[i] * gravity[1];
    }
    if n < 2 {
        return;
    }
    let mut g4 = [0.0; 4];
    for e in 0..n - 1 {
        let x = [q[2 * e], q[2 * e + 1], q[2 * e + 2], q[2 * e + 3]];
        stretch(&x, rod.ea, rod.rest_length[e], &mut g4, None);
        for k in 0..4 {
            f[2 * e + k] -= g4[k];
        }
    }
    let mut g6 = [0.0; 6];
    for i in 1..n - 1 {
        let x = [
            q[2 * i - 2],
            q[2 * i - 1],
            q[2 * i],
            q[2 * i + 1],
            q[2 * i + 2],
            q[2 * i + 3],
        ];
        bend(
            &x,
            rod.ei / rod.bend_length(i),
            rod.rest_curvature[i],
            &mut g6,
            None,
        );
        for k in 0..6 {
            f[2 * i - 2 + k] -= g6[k];
        }
    }
}

fn norm(v: [f64; 2]) -> f64 {
    v[0].hypot(v[1])
}

/// Scan a run with the rules of the module documentation.
pub fn detect(run: &Run, th: &Thresholds) -> Findings {
    let mut out = Findings::default();
    let rods: Vec<Rod> = run.scenario.rods.iter().map(Rod::new).collect();
    let g = run.scenario.solve.gravity;
    let gnorm = norm(g);
    let dynamic = run.dynamic();
    for (r, rod) in rods.iter().enumerate() {
        let name = run.rod_name(r).to_string();
        if dynamic {
            spikes(run, r, rod, &name, g, gnorm, th, &mut out.spikes);
        }
        toggling(run, r, rod, &name, th, &mut out.sticking);
        if dynamic {
            held(run, r, rod, &name, th, &mut out.sticking);
        }
    }
    out.spikes
        .sort_by(|a, b| (a.step, a.rod, a.node, a.kind).cmp(&(b.step, b.rod, b.node, b.kind)));
    out.sticking
        .sort_by(|a, b| (a.step, a.rod, a.node, a.rule).cmp(&(b.step, b.rod, b.node, b.rule)));
    out
}

/// State of the alternation scan of one node.
#[derive(Default, Clone)]
struct Alternation {
    /// Last large Δv and its step.
    last: Option<([f64; 2], u64)>,
    /// Steps at which a reversal happened (the later step of the pair), recent ones.
    flips: std::collections::VecDeque<u64>,
    /// The episode in progress: (first step, last step, flips, largest |Δv|, index into
    /// `run.steps` of the step with the largest |Δv|).
    open: Option<(u64, u64, u64, f64, usize)>,
}

#[allow(clippy::too_many_arguments)]
fn spikes(
    run: &Run,
    r: usize,
    rod: &Rod,
    name: &str,
    g: [f64; 2],
    gnorm: f64,
    th: &Thresholds,
    out: &mut Vec<Spike>,
) {
    let n = rod.n;
    let mut f = vec![0.0; 2 * n];
    let mut alt = vec![Alternation::default(); n];
    let mut alt_out: Vec<Spike> = Vec::new();
    for k in 1..run.steps.len() {
        let (prev, cur) = (&run.steps[k - 1].rods[r], &run.steps[k].rods[r]);
        let st = &run.steps[k];
        let dt = st.dt;
        if dt <= 0.0 {
            continue;
        }
        smooth_force(rod, g, &cur.q, &mut f);
        for i in 0..n {
            if rod.clamped[i] {
                continue;
            }
            let m = rod.mass[i];
            let dv = [
                cur.u[2 * i] - prev.u[2 * i],
                cur.u[2 * i + 1] - prev.u[2 * i + 1],
            ];
            let fdv = [dt * f[2 * i] / m, dt * f[2 * i + 1] / m];
            let e = [dv[0] - fdv[0], dv[1] - fdv[1]];
            // Scales the jumps are measured against: the node's own force for a jump nothing
            // explains; gravity for an impact (the elastic force at the end of an impact step
            // is largely the rod's answer to that impact, so it is no scale for it).
            let node_ref = gnorm.max(norm([f[2 * i], f[2 * i + 1]]) / m).max(1e-300);
            let impact_ref = gnorm.max(1e-300);
            let (mut impact, mut approach) = (0.0, 0.0);
            let mut rest = e;
            if cur.in_contact[i] {
                let nv = [cur.normal[2 * i], cur.normal[2 * i + 1]];
                let dot = |v: [f64; 2]| nv[0] * v[0] + nv[1] * v[1];
                // Support: the contact cancels what the forces push into the surface over
                // the step. Impact: it removes the normal velocity the node brought into the
                // step, and no more (perfectly inelastic). Nothing else along n, nothing along
                // the surface (frictionless).
                let support_max = (-dot(fdv)).max(0.0);
                approach = (-dot([prev.u[2 * i], prev.u[2 * i + 1]])).max(0.0);
                let en = dot(e);
                let support = en.clamp(0.0, support_max);
                impact = (en - support).clamp(0.0, approach);
                let explained = support + impact;
                rest = [e[0] - explained * nv[0], e[1] - explained * nv[1]];
            }
            let unexplained = norm(rest);
            let large =
                |j: f64, scale: f64| j >= th.spike_floor && j / dt >= th.spike_accel_ratio * scale;
            let flag_unexplained = large(unexplained, node_ref);
            let flag_impact = large(impact, impact_ref) && impact * dt >= th.spike_displacement;
            if flag_unexplained || flag_impact {
                let (jump, accel_ref) = if flag_unexplained {
                    (unexplained, node_ref)
                } else {
                    (impact, impact_ref)
                };
                out.push(Spike {
                    kind: if flag_unexplained {
                        "unexplained"
                    } else {
                        "impact"
                    },
                    rod: r,
                    rod_name: name.to_string(),
                    node: i,
                    step: st.step,
                    t: st.t,
                    last_step: st.step,
                    dt,
                    dv,
                    dv_norm: norm(dv),
                    force_dv: norm(fdv),
                    jump,
                    impact_jump: impact,
                    unexplained_jump: unexplained,
                    approach_speed: approach,
                    accel: jump / dt,
                    accel_ref,
                    accel_ratio: jump / dt / accel_ref,
                    displacement: jump * dt,
                    in_contact: cur.in_contact[i],
                    flips: 0,
                });
            }

            // Alternation: reversals of large Δv within a short window.
            let a = &mut alt[i];
            let dvn = norm(dv);
            let big = dvn >= th.spike_floor.max(th.spike_accel_ratio * dt * gnorm) && dvn > 0.0;
            let mut flipped = false;
            if !big {
                a.last = None;
            } else {
                if let Some((lv, lstep)) = a.last {
                    // Consecutive large changes pointing (more than 90 degrees) apart.
                    if lstep + 1 == st.step && lv[0] * dv[0] + lv[1] * dv[1] < 0.0 {
                        a.flips.push_back(st.step);
                        flipped = true;
                    }
                }
                a.last = Some((dv, st.step));
            }
            while a
                .flips
                .front()
                .is_some_and(|&s| s + th.alternation_window <= st.step)
            {
                a.flips.pop_front();
            }
            let enough = a.flips.len() as u64 >= th.alternation_flips;
            if enough && flipped {
                let first_flip = *a.flips.front().expect("non-empty");
                match a.open.as_mut() {
                    Some(ep) => {
                        ep.1 = st.step;
                        ep.2 += 1;
                        if dvn > ep.3 {
                            ep.3 = dvn;
                            ep.4 = k;
                        }
                    }
                    None => {
                        // The pattern starts with the Δv before the first reversal.
                        a.open = Some((first_flip - 1, st.step, a.flips.len() as u64, dvn, k));
                    }
                }
            } else if !enough {
                if let Some(ep) = a.open.take() {
                    alt_out.push(alternation_spike(run, r, name, i, ep, rod, g, gnorm));
                }
            }
        }
    }
    for (i, a) in alt.iter_mut().enumerate() {
        if let Some(ep) = a.open.take() {
            alt_out.push(alternation_spike(run, r, name, i, ep, rod, g, gnorm));
        }
    }
    out.extend(alt_out);
}

#[allow(clippy::too_many_arguments)]
fn alternation_spike(
    run: &Run,
    r: usize,
    name: &str,
    i: usize,
    ep: (u64, u64, u64, f64, usize),
    rod: &Rod,
    g: [f64; 2],
    gnorm: f64,
) -> Spike {
    let (first, last, flips, biggest, k) = ep;
    let st = &run.steps[k];
    let (prev, cur) = (&run.steps[k - 1].rods[r], &st.rods[r]);
    let mut f = vec![0.0; 2 * rod.n];
    smooth_force(rod, g, &cur.q, &mut f);
    let m = rod.mass[i];
    let dv = [
        cur.u[2 * i] - prev.u[2 * i],
        cur.u[2 * i + 1] - prev.u[2 * i + 1],
    ];
    let fdv = [st.dt * f[2 * i] / m, st.dt * f[2 * i + 1] / m];
    let accel_ref = gnorm.max(norm([f[2 * i], f[2 * i + 1]]) / m).max(1e-300);
    let first_t = run
        .steps
        .iter()
        .find(|s| s.step == first)
        .map(|s| s.t)
        .unwrap_or(st.t);
    Spike {
        kind: "alternating",
        rod: r,
        rod_name: name.to_string(),
        node: i,
        step: first,
        t: first_t,
        last_step: last,
        dt: st.dt,
        dv,
        dv_norm: norm(dv),
        force_dv: norm(fdv),
        jump: biggest,
        impact_jump: 0.0,
        unexplained_jump: norm([dv[0] - fdv[0], dv[1] - fdv[1]]),
        approach_speed: 0.0,
        accel: biggest / st.dt,
        accel_ref,
        accel_ratio: biggest / st.dt / accel_ref,
        displacement: biggest * st.dt,
        in_contact: cur.in_contact[i],
        flips,
    }
}

/// Time at the end of step `step` (the nearest recorded step at or after it).
fn time_of(run: &Run, step: u64) -> f64 {
    let k = run.steps.partition_point(|s| s.step < step);
    run.steps
        .get(k)
        .or(run.steps.last())
        .map(|s| s.t)
        .unwrap_or(0.0)
}

/// `toggling`: many constraint changes of one node within a window of steps.
fn toggling(run: &Run, r: usize, rod: &Rod, name: &str, th: &Thresholds, out: &mut Vec<Sticking>) {
    for i in 0..rod.n {
        let steps: Vec<u64> = run
            .contacts
            .iter()
            .filter(|c| c.rod == r && c.node == i)
            .map(|c| c.step)
            .collect();
        if (steps.len() as u64) < th.stick_toggles {
            continue;
        }
        // Mark every change that lies in some window holding enough changes.
        let mut marked = vec![false; steps.len()];
        let mut lo = 0;
        for hi in 0..steps.len() {
            while steps[hi] - steps[lo] >= th.stick_window {
                lo += 1;
            }
            if (hi - lo + 1) as u64 >= th.stick_toggles {
                for m in marked.iter_mut().take(hi + 1).skip(lo) {
                    *m = true;
                }
            }
        }
        // Episodes: runs of marked changes closer than a window.
        let mut j = 0;
        while j < steps.len() {
            if !marked[j] {
                j += 1;
                continue;
            }
            let start = j;
            while j + 1 < steps.len() && marked[j + 1] && steps[j + 1] - steps[j] < th.stick_window
            {
                j += 1;
            }
            out.push(Sticking {
                rule: "toggling",
                rod: r,
                rod_name: name.to_string(),
                node: i,
                step: steps[start],
                t: time_of(run, steps[start]),
                last_step: steps[j],
                last_t: time_of(run, steps[j]),
                count: (j - start + 1) as u64,
                max_correction: 0.0,
                min_normal_reaction: 0.0,
            });
            j += 1;
        }
    }
}

/// `oscillating` and `adhesive_hold`: what happens to a node while it is constrained.
fn held(run: &Run, r: usize, rod: &Rod, name: &str, th: &Thresholds, out: &mut Vec<Sticking>) {
    for i in 0..rod.n {
        if rod.clamped[i] {
            continue;
        }
        // Oscillating: corrected steps while constrained, in a window, with a reversal.
        // Each entry: (step index k, signed normal correction).
        let mut recent: std::collections::VecDeque<(usize, f64, f64)> = Default::default();
        let mut open: Option<(usize, usize, u64, f64)> = None; // (first k, last k, steps, max)
                                                               // Adhesive hold: consecutive steps held with R·n < −tolerance.
        let mut hold: Option<(usize, usize, u64, f64)> = None;
        let close_osc = |ep: (usize, usize, u64, f64), out: &mut Vec<Sticking>| {
            out.push(Sticking {
                rule: "oscillating",
                rod: r,
                rod_name: name.to_string(),
                node: i,
                step: run.steps[ep.0].step,
                t: run.steps[ep.0].t,
                last_step: run.steps[ep.1].step,
                last_t: run.steps[ep.1].t,
                count: ep.2,
                max_correction: ep.3,
                min_normal_reaction: 0.0,
            })
        };
        let close_hold = |ep: (usize, usize, u64, f64), out: &mut Vec<Sticking>| {
            out.push(Sticking {
                rule: "adhesive_hold",
                rod: r,
                rod_name: name.to_string(),
                node: i,
                step: run.steps[ep.0].step,
                t: run.steps[ep.0].t,
                last_step: run.steps[ep.1].step,
                last_t: run.steps[ep.1].t,
                count: ep.2,
                max_correction: 0.0,
                min_normal_reaction: ep.3,
            })
        };
        for k in 1..run.steps.len() {
            let st = &run.steps[k];
            let v = &st.rods[r];
            let step = st.step;
            // Drop corrections that left the window.
            while recent
                .front()
                .is_some_and(|&(kk, _, _)| run.steps[kk].step + th.stick_window <= step)
            {
                recent.pop_front();
            }
            let held = v.in_contact[i];
            let nv = [v.normal[2 * i], v.normal[2 * i + 1]];
            let mut corrected = false;
            if held {
                let c = [
                    v.q[2 * i] - v.q_predictor[2 * i],
                    v.q[2 * i + 1] - v.q_predictor[2 * i + 1],
                ];
                let size = norm(c);
                if size >= th.stick_correction_min && size > 0.0 {
                    recent.push_back((k, nv[0] * c[0] + nv[1] * c[1], size));
                    corrected = true;
                }
            }
            let reversal = recent
                .iter()
                .zip(recent.iter().skip(1))
                .any(|(a, b)| a.1 * b.1 < 0.0);
            let sticking = held && recent.len() as u64 >= th.stick_corrections && reversal;
            if sticking && corrected {
                let size = recent.back().map(|x| x.2).unwrap_or(0.0);
                match open.as_mut() {
                    Some(ep) => {
                        ep.1 = k;
                        ep.2 += 1;
                        ep.3 = ep.3.max(size);
                    }
                    None => {
                        let biggest = recent.iter().map(|x| x.2).fold(0.0, f64::max);
                        open = Some((recent[0].0, k, recent.len() as u64, biggest));
                    }
                }
            } else if !sticking {
                if let Some(ep) = open.take() {
                    close_osc(ep, out);
                }
            }

            let rn = nv[0] * v.reaction[2 * i] + nv[1] * v.reaction[2 * i + 1];
            if held && rn < -th.adhesion_tolerance {
                match hold.as_mut() {
                    Some(ep) if ep.1 + 1 == k => {
                        ep.1 = k;
                        ep.2 += 1;
                        ep.3 = ep.3.min(rn);
                    }
                    _ => {
                        if let Some(ep) = hold.take() {
                            close_hold(ep, out);
                        }
                        hold = Some((k, k, 1, rn));
                    }
                }
            }
        }
        if let Some(ep) = open.take() {
            close_osc(ep, out);
        }
        if let Some(ep) = hold.take() {
            close_hold(ep, out);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;

    #[derive(Parser)]
    struct Cli {
        #[command(flatten)]
        th: Thresholds,
    }

    #[test]
    fn flag_defaults_are_the_documented_defaults() {
        let cli = Cli::try_parse_from(["x"]).unwrap();
        assert_eq!(cli.th, Thresholds::DEFAULT);
        assert!(Thresholds::DEFAULT.validate().is_ok());
        let bad = Thresholds {
            stick_window: 0,
            ..Thresholds::DEFAULT
        };
        assert!(bad.validate().is_err());
    }
}
