//! The grasp rules of `replay check`: a fruit that slips in the gripper during the lift, and a
//! fruit that is dropped. The same decisions as the run summary's `grasp` section
//! (`record::grasp`): the gripper is the centroid of the clamped nodes, the lift begins when it
//! has risen by a quarter of the fruit's hold tolerance above where it was when a prong first
//! touched the fruit, and the verdict ends when the gripper first moves down again.
//!
//! A scenario may expect a slip or a drop (`[expect] grasp`, e.g. a demonstration of too little
//! friction): then that event is reported as expected, not flagged, and a fruit that is held
//! instead is flagged (`held`).

use crate::scenario::expect::GraspOutcome;
use serde::Serialize;

/// A flagged moment of a grasp.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct GraspFlag {
    /// `slip`: the fruit moved more than its hold tolerance relative to the gripper during the
    /// lift; `drop`: no prong touches it any more; `held`: neither, where the scenario expects
    /// one of them (`[expect] grasp`).
    pub kind: &'static str,
    pub step: u64,
    pub t: f64,
    /// The fruit's displacement relative to the gripper since the lift began (m).
    pub slip_m: f64,
    pub hold_tolerance_m: f64,
}

/// What the rule needs of the scenario, and its state.
#[derive(Debug, Clone)]
pub struct GraspRule {
    clamped: Vec<Vec<usize>>,
    /// 2 (planar: q = [x0, y0, x1, …]) or 3 (3D: node positions [x0, y0, z0, x1, …]).
    dim: usize,
    up: [f64; 3],
    tolerance: f64,
    first_touch: Option<f64>,
    reference: Option<[f64; 3]>,
    top: f64,
    over: bool,
    slipped: bool,
    dropped: bool,
    expect: GraspOutcome,
    last: (u64, f64, f64),
    max_slip: f64,
    pub flags: Vec<GraspFlag>,
}

/// What the rule found: the flags, and the events the scenario expects (reported, not flagged).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct GraspFindings {
    pub flags: Vec<GraspFlag>,
    pub expected: Vec<GraspFlag>,
}

impl GraspRule {
    /// For the first free body of a scenario (None without one).
    pub fn of(sc: &crate::Scenario) -> Option<GraspRule> {
        let b = sc.bodies.first()?;
        let g = sc.solve.gravity;
        let w = g[0].hypot(g[1]);
        Some(GraspRule {
            clamped: sc.rods.iter().map(|r| r.clamped.clone()).collect(),
            dim: 2,
            up: if w > 0.0 {
                [-g[0] / w, -g[1] / w, 0.0]
            } else {
                [0.0, 1.0, 0.0]
            },
            tolerance: b.hold_tolerance,
            first_touch: None,
            reference: None,
            top: f64::NEG_INFINITY,
            over: false,
            slipped: false,
            dropped: false,
            expect: sc.expect.grasp,
            last: (0, 0.0, 0.0),
            max_slip: 0.0,
            flags: Vec::new(),
        })
    }

    /// The rule in 3D: `clamped` the driven nodes of each rod (the gripper is their centroid),
    /// `gravity` the scene's, `tolerance` the fruit's hold tolerance (m).
    pub fn of3(
        clamped: Vec<Vec<usize>>,
        gravity: [f64; 3],
        tolerance: f64,
        expect: GraspOutcome,
    ) -> GraspRule {
        let w =
            (gravity[0] * gravity[0] + gravity[1] * gravity[1] + gravity[2] * gravity[2]).sqrt();
        GraspRule {
            clamped,
            dim: 3,
            up: if w > 0.0 {
                gravity.map(|g| -g / w)
            } else {
                [0.0, 0.0, 1.0]
            },
            tolerance,
            first_touch: None,
            reference: None,
            top: f64::NEG_INFINITY,
            over: false,
            slipped: false,
            dropped: false,
            expect,
            last: (0, 0.0, 0.0),
            max_slip: 0.0,
            flags: Vec::new(),
        }
    }

    /// The verdict against the scenario's expectation.
    pub fn finish(self) -> GraspFindings {
        let expected = |f: &GraspFlag| match self.expect {
            GraspOutcome::Held => false,
            GraspOutcome::Slipped => f.kind == "slip",
            GraspOutcome::Dropped => true,
        };
        let (expected, mut flags): (Vec<_>, Vec<_>) =
            self.flags.iter().cloned().partition(|f| expected(f));
        let missing = match self.expect {
            GraspOutcome::Held => false,
            GraspOutcome::Slipped => !self.slipped,
            GraspOutcome::Dropped => !self.dropped,
        };
        if missing {
            let (step, t, slip_m) = self.last;
            flags.push(GraspFlag {
                kind: "held",
                step,
                t,
                slip_m,
                hold_tolerance_m: self.tolerance,
            });
        }
        GraspFindings { flags, expected }
    }

    /// One step: the rods' positions, the fruit's centroid, whether a prong touches it.
    pub fn step(&mut self, step: u64, t: f64, q: &[&[f64]], fruit: [f64; 2], touching: bool) {
        self.step_in(step, t, q, [fruit[0], fruit[1], 0.0], touching);
    }

    /// One step of a 3D run: the rods' node positions (`[x0, y0, z0, x1, …]`), the fruit's
    /// centre, whether a prong touches it.
    pub fn step3(&mut self, step: u64, t: f64, x: &[&[f64]], fruit: [f64; 3], touching: bool) {
        self.step_in(step, t, x, fruit, touching);
    }

    /// Whether the lift has begun (the gripper rose by a quarter of the hold tolerance above
    /// where it was at the first touch).
    pub fn lifted(&self) -> bool {
        self.reference.is_some()
    }

    /// Whether the lift is over: the gripper came down again, or the fruit was dropped.
    pub fn lift_over(&self) -> bool {
        self.over
    }

    /// The fruit's largest displacement relative to the gripper during the lift so far (m).
    pub fn max_slip(&self) -> f64 {
        self.max_slip
    }

    /// The grasp outcome of the lift: `held` (in place within the tolerance, touching a
    /// prong), `slipped` (moved more than the tolerance, still touched), `dropped` (touching
    /// no prong); None without a lift.
    pub fn outcome(&self) -> Option<GraspOutcome> {
        self.lifted().then_some(if self.dropped {
            GraspOutcome::Dropped
        } else if self.slipped {
            GraspOutcome::Slipped
        } else {
            GraspOutcome::Held
        })
    }

    fn step_in(&mut self, step: u64, t: f64, q: &[&[f64]], fruit: [f64; 3], touching: bool) {
        if self.over {
            return;
        }
        let d = self.dim;
        let (mut c, mut n) = ([0.0; 3], 0.0);
        for (r, qs) in q.iter().enumerate() {
            for &i in self.clamped.get(r).map(Vec::as_slice).unwrap_or(&[]) {
                if d * i + d - 1 < qs.len() {
                    for k in 0..d {
                        c[k] += qs[d * i + k];
                    }
                    n += 1.0;
                }
            }
        }
        if n == 0.0 {
            return;
        }
        let c = c.map(|x| x / n);
        let rel = [0, 1, 2].map(|k| fruit[k] - c[k]);
        let mut height = c[0] * self.up[0] + c[1] * self.up[1];
        if d == 3 {
            height += c[2] * self.up[2];
        }
        if touching && self.first_touch.is_none() {
            self.first_touch = Some(height);
        }
        let Some(h0) = self.first_touch else { return };
        if self.reference.is_none() && height - h0 > 0.25 * self.tolerance {
            self.reference = Some(rel);
        }
        let Some(r0) = self.reference else { return };
        self.top = self.top.max(height);
        if height < self.top - 1e-6 {
            self.over = true;
            return;
        }
        let slip = if d == 2 {
            (rel[0] - r0[0]).hypot(rel[1] - r0[1])
        } else {
            let e = [0, 1, 2].map(|k| rel[k] - r0[k]);
            (e[0] * e[0] + e[1] * e[1] + e[2] * e[2]).sqrt()
        };
        self.last = (step, t, slip);
        self.max_slip = self.max_slip.max(slip);
        let flag = |kind| GraspFlag {
            kind,
            step,
            t,
            slip_m: slip,
            hold_tolerance_m: self.tolerance,
        };
        if !self.slipped && slip > self.tolerance {
            self.flags.push(flag("slip"));
            self.slipped = true;
        }
        if !touching {
            self.flags.push(flag("drop"));
            self.dropped = true;
            self.over = true;
        }
    }
}
