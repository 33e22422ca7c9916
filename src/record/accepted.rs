//! Only what accepted steps did reaches the sinks' contact logs.
//!
//! The solver reports constraint changes as it makes them, inside an attempt at a step. An
//! attempt can be thrown away (a rejected adaptive step, a Newton back-off, a time-of-impact
//! split) and the step tried again: a second `StepBegin` with the same step number. The
//! [`AcceptedContacts`] wrapper holds a step's changes until its `StepEnd` and drops those of
//! an attempt that was retried, so a recording's `/sim/contact` and everything that counts
//! contact changes see accepted steps only (docs/replay.md).

use crate::events::{ContactChange, Event, Observer, ReleaseReason};

/// Wraps an observer: contact changes are passed on just before the `StepEnd` of the attempt
/// that made them, or dropped when that attempt is retried or the run ends without it.
pub struct AcceptedContacts<O: Observer> {
    pub inner: O,
    held: Vec<(ContactChange, Option<ReleaseReason>)>,
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
            Event::ConstraintAdded(c) => self.held.push((*c, None)),
            Event::ConstraintReleased(c, why) => self.held.push((*c, Some(*why))),
            Event::StepEnd { .. } => {
                for (c, why) in std::mem::take(&mut self.held) {
                    match why {
                        None => self.inner.on_event(&Event::ConstraintAdded(c)),
                        Some(w) => self.inner.on_event(&Event::ConstraintReleased(c, w)),
                    }
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
