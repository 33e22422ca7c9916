//! Only what accepted steps did reaches the sinks' contact logs.
//!
//! The solver reports constraint changes as it makes them, inside an attempt at a step. An
//! attempt can be thrown away (a rejected adaptive step, a Newton back-off, a time-of-impact
//! split) and the step tried again: a second `StepBegin` with the same step number. The
//! [`AcceptedContacts`] wrapper holds a step's changes until its `StepEnd` and drops those of
//! an attempt that was retried, so a recording's `/sim/contact` and everything that counts
//! contact changes see accepted steps only (docs/replay.md).

use crate::events::{Event, Observer};

/// Wraps an observer: contact changes (constraints, friction states, free bodies' own
/// contacts) are passed on just before the `StepEnd` of the attempt
/// that made them, or dropped when that attempt is retried or the run ends without it.
pub struct AcceptedContacts<O: Observer> {
    pub inner: O,
    /// The current attempt's changes (constraints, friction states, free bodies' contacts).
    held: Vec<Event<'static>>,
    /// Changes dropped with discarded attempts.
    pub discarded: u64,
}

impl<O: Observer> AcceptedContacts<O> {
    pub fn new(inner: O) -> Self {
        Self {
            inner,
            held: Vec::new(),
            discarded: 0,
        }
    }

    fn drop_held(&mut self) {
        self.discarded += self.held.len() as u64;
        self.held.clear();
    }
}

impl<O: Observer> Observer for AcceptedContacts<O> {
    fn wants_iterations(&self) -> bool {
        self.inner.wants_iterations()
    }
    /// Always: a `StepEnd` is what says an attempt was accepted.
    fn wants_steps(&self) -> bool {
        true
    }
    fn on_event(&mut self, event: &Event<'_>) {
        match event {
            // A new attempt: whatever the last one changed was thrown away with it.
            Event::StepBegin { .. } => {
                self.drop_held();
                self.inner.on_event(event);
            }
            Event::ConstraintAdded(c) => self.held.push(Event::ConstraintAdded(*c)),
            Event::ConstraintReleased(c, why) => {
                self.held.push(Event::ConstraintReleased(*c, *why))
            }
            Event::FrictionChanged(f) => self.held.push(Event::FrictionChanged(*f)),
            &Event::BodyContactChanged {
                step,
                t,
                pass,
                body,
                obstacle,
                feature,
                added,
                normal,
                reaction,
            } => self.held.push(Event::BodyContactChanged {
                step,
                t,
                pass,
                body,
                obstacle,
                feature,
                added,
                normal,
                reaction,
            }),
            Event::StepEnd { .. } => {
                for e in std::mem::take(&mut self.held) {
                    self.inner.on_event(&e);
                }
                self.inner.on_event(event);
            }
            Event::RunEnd { .. } => {
                self.drop_held();
                self.inner.on_event(event);
            }
            _ => self.inner.on_event(event),
        }
    }
}
