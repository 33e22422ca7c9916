//! `--detail auto`: record what matters.
//!
//! [`AutoDetail`] sits between the run's events and the recording sinks (one layer for all of
//! them). It keeps owned copies of the last `window` steps — each with its Newton iterations
//! and events — in a delay line, and decides for each step, by the time it leaves the line,
//! whether the sinks get it:
//!
//! * **in full** (state, events and every Newton iteration): a step with an event — a
//!   constraint added or released, a free body's contact, a stick/slip switch, a dt change, a
//!   failed Newton solve, a warning, an actuation phase change — or with Newton trouble (more
//!   than twice the run's usual iterations), or on which the live spike detector flags a
//!   node; and the `window` steps before and after such a step;
//! * **sampled** (state and events, no iterations): every `every`-th step (step numbers that
//!   are multiples of `every`), the first step and the last one;
//! * not at all: the rest.
//!
//! A recorded step keeps its own step number and time, so a reader sees a gap as a jump in the
//! step numbers (`gripsim replay` never compares across one). The sinks are told the rule
//! ([`super::Detail::Auto`]) and write it into `/sim/meta` and the `.rrd`'s text log.
//!
//! The choice of `every` ([`AutoRule::for_scenario`]) and `window` is documented in
//! docs/recording-format.md.

use super::AutoRule;
use crate::events::{Event, Observer, OwnedStepEnd, Phase};
use crate::replay::detect::{ContactSample, Detector, RodSample};
use std::collections::VecDeque;
use std::ops::Range;

/// Steps recorded in full before and after each event: 20 covers the sticking rule's
/// shortest window (20 × solve.dt, docs/replay.md) and the few steps an impact takes to settle
/// (the approach, the corrector passes, the rebound), and costs at most 41 steps per event.
pub const WINDOW: u64 = 20;

/// Node-steps the sampled part of a run is meant to hold: `every` is chosen so that
/// steps × nodes / every stays under this (a 1 s two-prong grasp at dt = 1e-5: 100 000 steps ×
/// 20 nodes / 100).
pub const NODE_STEP_BUDGET: u64 = 20_000;

impl AutoRule {
    /// The rule for a scenario: `every` so that the sampled steps hold at most
    /// [`NODE_STEP_BUDGET`] node-steps (at the scenario's nominal step `solve.dt`; static runs
    /// count their load steps), rounded up to 1, 2 or 5 × 10ⁿ (round step numbers);
    /// `window` = [`WINDOW`]. (`gripsim run` then flushes the files every `flush_every × every`
    /// steps, always a recorded step.)
    pub fn for_scenario(sc: &crate::Scenario) -> AutoRule {
        let nodes: u64 = sc.rods.iter().map(|r| r.nodes as u64).sum::<u64>().max(1);
        let steps = match sc.solve.mode {
            crate::scenario::Mode::Dynamic if sc.solve.dt > 0.0 => {
                (sc.solve.t_end / sc.solve.dt).ceil()
            }
            _ if sc.solve.load_step > 0.0 => (1.0 / sc.solve.load_step).ceil(),
            _ => 1.0,
        };
        let steps = if steps.is_finite() && steps > 0.0 {
            steps.min(1e15) as u64
        } else {
            1
        };
        let raw = (steps.saturating_mul(nodes))
            .div_ceil(NODE_STEP_BUDGET)
            .max(1);
        AutoRule {
            every: super::nice_up(raw as f64).round() as u64,
            window: WINDOW,
        }
    }
}

/// What becomes of a held step (ordered: a step only ever moves up).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
enum Mark {
    Drop,
    /// State and events, no iterations.
    Sample,
    /// Everything.
    Full,
}

/// An event of a held step, its borrowed parts stored in the step's arenas.
#[derive(Debug, Clone)]
enum Held {
    /// An event without borrowed parts.
    Plain(Event<'static>),
    Iteration {
        step: u64,
        t: f64,
        phase: Phase,
        pass: u32,
        iteration: u32,
        rod: usize,
        residual: f64,
        update: f64,
        q: Range<usize>,
    },
    Dt {
        step: u64,
        t: f64,
        old: f64,
        new: f64,
        reason: Range<usize>,
    },
    Failed {
        step: u64,
        t: f64,
        dt: f64,
        rod: usize,
        node: usize,
        residual: f64,
        reason: Range<usize>,
    },
    Warning {
        step: u64,
        t: f64,
        message: Range<usize>,
    },
    Phase {
        step: u64,
        t: f64,
        actuator: usize,
        from: usize,
        to: Option<usize>,
        name: Range<usize>,
        reason: Range<usize>,
    },
    /// The step's end: its state is in [`HeldStep`]'s `end`.
    End,
}

/// One step with everything the run said about it, owned (its buffers are reused).
#[derive(Debug, Clone)]
pub(crate) struct HeldStep {
    events: Vec<Held>,
    /// Iterates of the step's Newton iterations, one after another.
    floats: Vec<f64>,
    /// Texts of its events.
    text: String,
    end: OwnedStepEnd,
    mark: Mark,
    /// The step had an event that opens a window.
    eventful: bool,
}

impl Default for HeldStep {
    fn default() -> Self {
        Self {
            events: Vec::new(),
            floats: Vec::new(),
            text: String::new(),
            end: OwnedStepEnd::default(),
            mark: Mark::Drop,
            eventful: false,
        }
    }
}

impl HeldStep {
    /// No event kept yet.
    pub(crate) fn is_empty(&self) -> bool {
        self.events.is_empty()
    }

    pub(crate) fn clear(&mut self) {
        self.events.clear();
        self.floats.clear();
        self.text.clear();
        self.mark = Mark::Drop;
        self.eventful = false;
    }

    fn text(&mut self, s: &str) -> Range<usize> {
        let a = self.text.len();
        self.text.push_str(s);
        a..self.text.len()
    }

    fn end(&mut self, ev: &Event<'_>) {
        if !self.end.set(ev) {
            return;
        }
        self.events.push(Held::End);
    }

    /// Keep an event of this step; true when it opens a window.
    pub(crate) fn keep(&mut self, ev: &Event<'_>) -> bool {
        let held = match *ev {
            Event::StepBegin { step, t, dt } => Held::Plain(Event::StepBegin { step, t, dt }),
            Event::Iteration {
                step,
                t,
                phase,
                pass,
                iteration,
                rod,
                residual,
                update,
                q,
            } => {
                let a = self.floats.len();
                self.floats.extend_from_slice(q);
                Held::Iteration {
                    step,
                    t,
                    phase,
                    pass,
                    iteration,
                    rod,
                    residual,
                    update,
                    q: a..self.floats.len(),
                }
            }
            Event::ConstraintAdded(c) => Held::Plain(Event::ConstraintAdded(c)),
            Event::ConstraintReleased(c, why) => Held::Plain(Event::ConstraintReleased(c, why)),
            Event::FrictionChanged(f) => Held::Plain(Event::FrictionChanged(f)),
            Event::BodyContactChanged { .. } => Held::Plain(body_contact(ev)),
            Event::DtChanged {
                step,
                t,
                old,
                new,
                reason,
            } => Held::Dt {
                step,
                t,
                old,
                new,
                reason: self.text(reason),
            },
            Event::NewtonFailed {
                step,
                t,
                dt,
                rod,
                node,
                residual,
                reason,
            } => Held::Failed {
                step,
                t,
                dt,
                rod,
                node,
                residual,
                reason: self.text(reason),
            },
            Event::Warning { step, t, message } => Held::Warning {
                step,
                t,
                message: self.text(message),
            },
            Event::PhaseChanged {
                step,
                t,
                actuator,
                from,
                to,
                name,
                reason,
            } => {
                let (name, reason) = (self.text(name), self.text(reason));
                Held::Phase {
                    step,
                    t,
                    actuator,
                    from,
                    to,
                    name,
                    reason,
                }
            }
            Event::StepEnd { .. } => {
                self.end(ev);
                return false;
            }
            // Not part of a step: passed on at once by the layer.
            Event::RunStart(_) | Event::RunEnd { .. } => return false,
        };
        let eventful = !matches!(
            held,
            Held::Iteration { .. } | Held::Plain(Event::StepBegin { .. })
        );
        self.events.push(held);
        eventful
    }

    /// Send the kept events on (the iterations only when `full`).
    pub(crate) fn send(&self, out: &mut dyn Observer, full: bool) {
        for h in &self.events {
            let tx = |r: &Range<usize>| &self.text[r.clone()];
            let ev = match h {
                Held::Plain(e) => *e,
                Held::Iteration { .. } if !full => continue,
                &Held::Iteration {
                    step,
                    t,
                    phase,
                    pass,
                    iteration,
                    rod,
                    residual,
                    update,
                    ref q,
                } => Event::Iteration {
                    step,
                    t,
                    phase,
                    pass,
                    iteration,
                    rod,
                    residual,
                    update,
                    q: &self.floats[q.clone()],
                },
                &Held::Dt {
                    step,
                    t,
                    old,
                    new,
                    ref reason,
                } => Event::DtChanged {
                    step,
                    t,
                    old,
                    new,
                    reason: tx(reason),
                },
                &Held::Failed {
                    step,
                    t,
                    dt,
                    rod,
                    node,
                    residual,
                    ref reason,
                } => Event::NewtonFailed {
                    step,
                    t,
                    dt,
                    rod,
                    node,
                    residual,
                    reason: tx(reason),
                },
                Held::Warning { step, t, message } => Event::Warning {
                    step: *step,
                    t: *t,
                    message: tx(message),
                },
                &Held::Phase {
                    step,
                    t,
                    actuator,
                    from,
                    to,
                    ref name,
                    ref reason,
                } => Event::PhaseChanged {
                    step,
                    t,
                    actuator,
                    from,
                    to,
                    name: tx(name),
                    reason: tx(reason),
                },
                Held::End => {
                    self.send_end(out);
                    continue;
                }
            };
            out.on_event(&ev);
        }
    }

    fn send_end(&self, out: &mut dyn Observer) {
        let e = &self.end;
        let (rods, bodies) = e.views();
        out.on_event(&Event::StepEnd {
            step: e.step,
            t: e.t,
            dt: e.dt,
            newton_iterations: e.newton_iterations,
            passes: e.passes,
            rods: &rods,
            bodies: &bodies,
            contacts: &e.contacts,
            joints: &e.joints,
        });
    }
}

/// A `BodyContactChanged` event with no borrowed parts.
fn body_contact(ev: &Event<'_>) -> Event<'static> {
    match *ev {
        Event::BodyContactChanged {
            step,
            t,
            pass,
            body,
            obstacle,
            feature,
            added,
            normal,
            reaction,
        } => Event::BodyContactChanged {
            step,
            t,
            pass,
            body,
            obstacle,
            feature,
            added,
            normal,
            reaction,
        },
        _ => unreachable!("called with a BodyContactChanged"),
    }
}

/// What the layer did: steps sent in full, sampled, left out, and the windows opened.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct AutoStats {
    pub full: u64,
    pub sampled: u64,
    pub dropped: u64,
    /// Steps that opened a window (had an event, Newton trouble or a spike).
    pub eventful: u64,
}

/// The `--detail auto` layer in front of the recording sinks (module documentation).
pub struct AutoDetail<O: Observer> {
    pub inner: O,
    pub rule: AutoRule,
    /// The last `window` steps, oldest first.
    line: VecDeque<HeldStep>,
    /// The step being reported.
    cur: HeldStep,
    spare: Vec<HeldStep>,
    /// Steps still to send in full after the last eventful one.
    after: u64,
    /// The live spike detector (spikes open windows), when the run gives one.
    detector: Option<Detector>,
    spikes: usize,
    /// Newton iterations of the steps so far (for "more than twice the usual").
    iterations: u64,
    steps: u64,
    pub stats: AutoStats,
}

impl<O: Observer> AutoDetail<O> {
    /// The layer over `inner` with `rule` (`every` ≥ 1); `detector` (the spike rules of
    /// `gripsim replay check` on the live run) lets a flagged spike open a window.
    pub fn new(inner: O, rule: AutoRule, detector: Option<Detector>) -> Self {
        Self {
            inner,
            rule: AutoRule {
                every: rule.every.max(1),
                window: rule.window,
            },
            line: VecDeque::new(),
            cur: HeldStep::default(),
            spare: Vec::new(),
            after: 0,
            detector,
            spikes: 0,
            iterations: 0,
            steps: 0,
            stats: AutoStats::default(),
        }
    }

    /// Feed the live detector one accepted step; true when it flagged a new spike.
    fn spiked(&mut self, ev: &Event<'_>) -> bool {
        let (
            Some(d),
            Event::StepEnd {
                step, t, dt, rods, ..
            },
        ) = (self.detector.as_mut(), ev)
        else {
            return false;
        };
        for h in &self.cur.events {
            match h {
                Held::Plain(Event::ConstraintAdded(c)) => d.contact(ContactSample::of(c, true)),
                Held::Plain(Event::ConstraintReleased(c, _)) => {
                    d.contact(ContactSample::of(c, false))
                }
                _ => {}
            }
        }
        let samples: Vec<RodSample<'_>> = rods.iter().map(RodSample::from).collect();
        d.step(*step, *t, *dt, &samples);
        let n = d.found().spikes.len();
        std::mem::replace(&mut self.spikes, n) < n
    }

    /// Newton trouble: more than twice the run's mean iterations per step so far, plus one.
    fn trouble(&mut self, step: u64, iterations: u32) -> bool {
        if step == 0 {
            return false;
        }
        let hard =
            self.steps > 0 && iterations as u64 * self.steps > 2 * self.iterations + self.steps;
        self.iterations += iterations as u64;
        self.steps += 1;
        hard
    }

    /// The step in `cur` ended: mark it, put it on the line, send what leaves the line.
    fn close_step(&mut self, ev: &Event<'_>) {
        let Event::StepEnd {
            step,
            newton_iterations,
            ..
        } = *ev
        else {
            return;
        };
        let spiked = self.spiked(ev);
        let trouble = self.trouble(step, newton_iterations);
        let mut held = std::mem::replace(&mut self.cur, self.spare.pop().unwrap_or_default());
        self.cur.clear();
        held.eventful |= spiked || trouble;
        if held.eventful {
            self.stats.eventful += 1;
            for h in self.line.iter_mut() {
                h.mark = Mark::Full;
            }
            held.mark = Mark::Full;
            self.after = self.rule.window;
        } else if self.after > 0 {
            held.mark = Mark::Full;
            self.after -= 1;
        } else if step == 0 || step.is_multiple_of(self.rule.every) {
            held.mark = Mark::Sample;
        }
        self.line.push_back(held);
        while self.line.len() as u64 > self.rule.window {
            self.send_oldest();
        }
    }

    fn send_oldest(&mut self) {
        let Some(mut h) = self.line.pop_front() else {
            return;
        };
        match h.mark {
            Mark::Full => self.stats.full += 1,
            Mark::Sample => self.stats.sampled += 1,
            Mark::Drop => self.stats.dropped += 1,
        }
        if h.mark != Mark::Drop {
            h.send(&mut self.inner, h.mark == Mark::Full);
        }
        h.clear();
        self.spare.push(h);
    }

    /// The run ended: the last step is always sent, the whole line in full when the run
    /// failed (the approach to the failure), then what the unfinished step said.
    fn end(&mut self, failed: bool) {
        if let Some(last) = self.line.back_mut() {
            last.mark = last.mark.max(Mark::Sample);
        }
        if failed {
            for h in self.line.iter_mut() {
                h.mark = Mark::Full;
            }
        }
        while !self.line.is_empty() {
            self.send_oldest();
        }
        // Events after the last step (a program's end, a warning) and, when the run failed, the
        // attempt that failed.
        self.cur.send(&mut self.inner, failed);
        self.cur.clear();
    }
}

impl<O: Observer> Observer for AutoDetail<O> {
    fn wants_iterations(&self) -> bool {
        self.inner.wants_iterations()
    }
    fn wants_steps(&self) -> bool {
        self.inner.wants_steps()
    }
    fn on_event(&mut self, event: &Event<'_>) {
        if !self.inner.wants_steps() {
            // Nobody records steps: nothing to choose from, nothing copied.
            return self.inner.on_event(event);
        }
        match event {
            Event::RunStart(_) => self.inner.on_event(event),
            Event::RunEnd { error, .. } => {
                self.end(error.is_some());
                self.inner.on_event(event);
            }
            Event::StepEnd { .. } => {
                self.cur.keep(event);
                self.close_step(event);
            }
            _ => {
                let eventful = self.cur.keep(event);
                self.cur.eventful |= eventful;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::events::{ContactChange, ReleaseReason, RodStepView};

    /// Records the step numbers it gets and how many iterations came with each.
    #[derive(Default)]
    struct Steps {
        got: Vec<(u64, usize)>,
        iterations: usize,
        contacts: Vec<u64>,
        ended: bool,
    }

    impl Observer for Steps {
        fn wants_iterations(&self) -> bool {
            true
        }
        fn on_event(&mut self, e: &Event<'_>) {
            match e {
                Event::Iteration { .. } => self.iterations += 1,
                Event::StepEnd { step, .. } => {
                    self.got.push((*step, std::mem::take(&mut self.iterations)))
                }
                Event::ConstraintAdded(c) | Event::ConstraintReleased(c, _) => {
                    self.contacts.push(c.step)
                }
                Event::RunEnd { .. } => self.ended = true,
                _ => {}
            }
        }
    }

    fn change(step: u64) -> ContactChange {
        ContactChange {
            step,
            t: step as f64,
            pass: 1,
            rod: 0,
            node: 0,
            obstacle: 0,
            normal: [0.0, 1.0, 0.0],
            gap: 0.0,
            reaction: [0.0; 3],
            z: 0.0,
        }
    }

    /// Steps 0..=last of one node, two Newton iterations each (step 0 none), a constraint
    /// added in `added` and released in `released`.
    fn feed(layer: &mut AutoDetail<Steps>, last: u64, added: u64, released: u64) {
        let q = [0.0, 0.0];
        let (b, i) = ([false], [usize::MAX]);
        let rod = RodStepView {
            dim: 2,
            q: &q,
            u: &q,
            reaction: &q,
            impulse: &q,
            drive_force: &q,
            normal: &q,
            contact_obstacle: &i,
            normal2: &q,
            contact_obstacle2: &i,
            in_contact: &b,
            bending_stress: &[0.0],
            gap: &[1.0],
            q_predictor: &q,
            twist_stress: &[],
            frames: None,
        };
        for step in 0..=last {
            let t = step as f64;
            layer.on_event(&Event::StepBegin { step, t, dt: 1.0 });
            for iteration in 1..=(2 * u32::from(step > 0)) {
                layer.on_event(&Event::Iteration {
                    step,
                    t,
                    phase: Phase::Predictor,
                    pass: 0,
                    iteration,
                    rod: 0,
                    residual: 1.0,
                    update: 1.0,
                    q: &q,
                });
            }
            if step == added {
                layer.on_event(&Event::ConstraintAdded(change(step)));
            }
            if step == released {
                layer.on_event(&Event::ConstraintReleased(
                    change(step),
                    ReleaseReason::Adhesive,
                ));
            }
            layer.on_event(&Event::StepEnd {
                step,
                t,
                dt: 1.0,
                newton_iterations: 2 * u32::from(step > 0),
                passes: 0,
                rods: &[rod],
                bodies: &[],
                contacts: &[],
                joints: &[],
            });
        }
        layer.on_event(&Event::RunEnd {
            steps: last,
            t: last as f64,
            error: None,
        });
    }

    #[test]
    fn windows_around_events_every_kth_step_and_the_ends() {
        let rule = AutoRule {
            every: 25,
            window: 3,
        };
        let mut layer = AutoDetail::new(Steps::default(), rule, None);
        feed(&mut layer, 103, 40, 60);
        let got = &layer.inner.got;
        let full: Vec<u64> = (37..=43).chain(57..=63).collect();
        let mut want: Vec<u64> = [0, 25, 50, 75, 100, 103].into();
        want.extend(&full);
        want.sort();
        assert_eq!(got.iter().map(|g| g.0).collect::<Vec<_>>(), want);
        for &(step, its) in got {
            let expect = if full.contains(&step) { 2 } else { 0 };
            assert_eq!(its, expect, "iterations of step {step}");
        }
        assert_eq!(layer.inner.contacts, [40, 60]);
        assert!(layer.inner.ended);
        assert_eq!(
            layer.stats,
            AutoStats {
                full: 14,
                sampled: 6,
                dropped: 84,
                eventful: 2
            }
        );
    }

    #[test]
    fn newton_trouble_is_more_than_twice_the_mean_plus_one() {
        let mut layer = AutoDetail::new(
            Steps::default(),
            AutoRule {
                every: 1000,
                window: 2,
            },
            None,
        );
        // Two iterations a step, then one step with six (> 2 x 2 + 1).
        for (step, its) in [
            (1u64, 2u32),
            (2, 2),
            (3, 2),
            (4, 2),
            (5, 6),
            (6, 2),
            (7, 2),
            (8, 2),
        ] {
            assert_eq!(layer.trouble(step, its), step == 5, "step {step}");
        }
    }

    #[test]
    fn every_k_fits_the_budget() {
        let path =
            std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios/two-prong-grasp.toml");
        let at = |t: &str| {
            let sc = crate::Scenario::load(&path, &[format!("solve.t_end={t}")]).unwrap();
            AutoRule::for_scenario(&sc)
        };
        // 20 nodes at dt = 1e-5: 6 000 steps x 20 / 20 000 = 6 -> 10; 1 s: 100 000 x 20 /
        // 20 000 = 100; 0.3 s: 30 -> 50; 1 ms: 100 steps, every one.
        assert_eq!(at("0.06").every, 10);
        assert_eq!(at("1").every, 100);
        assert_eq!(at("0.3").every, 50);
        assert_eq!(at("0.001").every, 1);
        assert_eq!(at("1").window, WINDOW);
    }
}
