//! An indentation probe: a rigid round obstacle (a roller) pressed into a driven prong or
//! finger, read step by step as force against indentation and the length of the prong's
//! surface wrapped on the roller (`scenarios/fin-ray-roller.toml`, docs/verification.md,
//! "Roller indentation").

use crate::events::{Event, Observer};
use crate::obstacle::Obstacle;
use crate::solver::SimError;
use crate::{Scenario, Simulation};

/// One step of an indentation run.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IndentSample {
    /// Time at the end of the step (s).
    pub t: f64,
    /// How far the drive has carried the clamped base toward the roller since the step that
    /// first touched it (m); 0 before the first contact.
    pub indentation: f64,
    /// The net contact force on the roller (N): |Σ normal force × normal| over its contacts.
    pub force: f64,
    /// Contacts on the roller.
    pub contacts: usize,
    /// The roller's arc between its two outermost contact points, radius × angle (m): the
    /// length of surface wrapped on it (0 for one contact point).
    pub wrap: f64,
    /// The length of the probed rod lying within [`NEAR`] of an obstacle's surface: the
    /// segments both of whose nodes have a gap below it (m).
    pub near: f64,
}

/// The gap (m) under which [`IndentSample::near`] counts a segment as hugging the roller.
pub const NEAR: f64 = 0.5e-3;

/// Collects [`IndentSample`]s from the step-end events.
struct Probe {
    roller: usize,
    center: [f64; 2],
    radius: f64,
    base: (usize, usize),
    start: Option<[f64; 2]>,
    touched: Option<f64>,
    samples: Vec<IndentSample>,
}

impl Observer for Probe {
    fn on_event(&mut self, event: &Event<'_>) {
        let Event::StepEnd {
            t, rods, contacts, ..
        } = event
        else {
            return;
        };
        let q = rods[self.base.0].q;
        let p = [q[2 * self.base.1], q[2 * self.base.1 + 1]];
        let start = *self.start.get_or_insert(p);
        let travel = ((p[0] - start[0]).powi(2) + (p[1] - start[1]).powi(2)).sqrt();
        let mine: Vec<_> = contacts
            .iter()
            .filter(|c| c.obstacle == self.roller)
            .collect();
        if !mine.is_empty() && self.touched.is_none() {
            self.touched = Some(travel);
        }
        let (mut f, mut lo, mut hi) = ([0.0; 2], f64::INFINITY, f64::NEG_INFINITY);
        for c in &mine {
            f[0] += c.normal_force * c.normal[0];
            f[1] += c.normal_force * c.normal[1];
            let a = (c.point[1] - self.center[1]).atan2(c.point[0] - self.center[0]);
            lo = lo.min(a);
            hi = hi.max(a);
        }
        let gap = rods[self.base.0].gap;
        let near = (0..gap.len().saturating_sub(1))
            .filter(|&i| gap[i] < NEAR && gap[i + 1] < NEAR)
            .map(|i| (q[2 * i + 2] - q[2 * i]).hypot(q[2 * i + 3] - q[2 * i + 1]))
            .sum();
        self.samples.push(IndentSample {
            t: *t,
            indentation: self.touched.map_or(0.0, |t0| travel - t0),
            force: f[0].hypot(f[1]),
            contacts: mine.len(),
            wrap: if mine.is_empty() {
                0.0
            } else {
                self.radius * (hi - lo)
            },
            near,
        });
    }
}

/// Runs `scenario` and reads, every step, the contacts on its circle obstacle `roller` and the
/// travel of node `node` of rod `rod` (a clamped node carried by the drive). The roller must
/// sit on the side of the prong it faces (its contact angles do not wrap past ±π).
pub fn indentation_run(
    scenario: &Scenario,
    roller: usize,
    rod: usize,
    node: usize,
) -> Result<Vec<IndentSample>, SimError> {
    let Obstacle::Circle(c) = &scenario.obstacles[roller] else {
        panic!("indentation_run: obstacle {roller} is not a circle");
    };
    let (center, radius) = (c.center, c.radius);
    let mut probe = Probe {
        roller,
        center,
        radius,
        base: (rod, node),
        start: None,
        touched: None,
        samples: Vec::new(),
    };
    let mut sim = Simulation::new(scenario);
    sim.run(&mut probe)?;
    Ok(probe.samples)
}

/// The mean of the touching samples whose indentation lies within `half` of `d` (a window
/// that smooths the step-to-step ripple of a driven contact); None when there are none.
pub fn mean_near(samples: &[IndentSample], d: f64, half: f64) -> Option<IndentSample> {
    let w: Vec<&IndentSample> = samples
        .iter()
        .filter(|s| s.contacts > 0 && (s.indentation - d).abs() <= half)
        .collect();
    if w.is_empty() {
        return None;
    }
    let k = w.len() as f64;
    let mean = |f: fn(&IndentSample) -> f64| w.iter().map(|s| f(s)).sum::<f64>() / k;
    Some(IndentSample {
        t: mean(|s| s.t),
        indentation: mean(|s| s.indentation),
        force: mean(|s| s.force),
        contacts: w.iter().map(|s| s.contacts).max().unwrap_or(0),
        wrap: mean(|s| s.wrap),
        near: mean(|s| s.near),
    })
}
