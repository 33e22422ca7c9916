//! After a converged pass: releases, stick/slip switches and new contacts, for rod nodes and
//! for the bodies' own contacts with fixed obstacles.

use super::*;
use crate::contact::friction::{decide_cone, Cone};

impl World3 {
    /// Decide the contact sets from the converged pass. Returns how many changed.
    pub(super) fn update_contacts(&mut self, dt: f64, report: &mut StepReport3) -> u32 {
        let mut changed = 0;
        for r in 0..self.rods.len() {
            for i in 0..self.rods[r].rod.n {
                let fixed = &self.rods[r].fixed;
                if fixed[pos(i)] || fixed[pos(i) + 1] || fixed[pos(i) + 2] {
                    continue;
                }
                changed += match self.contacts[r][i] {
                    Some(c) => self.decide_node(r, i, c, dt, report),
                    None => self.detect_node(r, i, report),
                };
            }
        }
        for r in 0..self.rods.len() {
            changed += self.update_edges(r, dt, report);
        }
        changed + self.update_body_contacts(dt, report)
    }

    fn decide_node(
        &mut self,
        r: usize,
        i: usize,
        mut c: Contact3,
        dt: f64,
        report: &mut StepReport3,
    ) -> u32 {
        let x = Self::node(&self.work[r].qn, i);
        let x0 = Self::node(&self.rods[r].q, i);
        let moved = lever_map(&c.lever) * self.body_dx(c.surface);
        let v_rel = (x - x0 - moved) / dt;
        let v_rel = v_rel - c.normal * c.normal.dot(&v_rel);
        // A compliant contact whose indentation has gone carries no force: released.
        let change = if self.law_released(r, i, &c) {
            Some(Change3::Release)
        } else {
            decide(&c, &self.reactions[r][i], &v_rel)
        };
        match change {
            None => return 0,
            Some(Change3::Release) => {
                self.contacts[r][i] = None;
                self.work[r].released[i] = true;
                report.released += 1;
                return 1;
            }
            Some(Change3::ToSlide { dir }) => c.grip = Grip3::Slide { dir },
            Some(Change3::ToStick) => {
                c.grip = Grip3::Stick {
                    anchor: x0 + c.normal * (c.target - c.normal.dot(&x0)),
                }
            }
        }
        c.switches += 1;
        report.switches += 1;
        self.contacts[r][i] = Some(c);
        1
    }

    /// Every surface a node can touch: fixed obstacles, then bodies.
    pub(super) fn surfaces(&self) -> impl Iterator<Item = Surface3> {
        (0..self.obstacles.len())
            .map(Surface3::Obstacle)
            .chain((0..self.bodies.len()).map(Surface3::Body))
    }

    /// A node that ended deeper inside a surface than its offset gets a contact there (the
    /// deepest one).
    fn detect_node(&mut self, r: usize, i: usize, report: &mut StepReport3) -> u32 {
        let x = Self::node(&self.work[r].qn, i);
        let reach = match self.sections[r] {
            Section3::Circle { r } => r,
            Section3::Rect { b, h } => 0.5 * (b + h),
        };
        let eps = 1e-10 * self.rods[r].rod.length;
        let mut best: Option<(f64, Surface3, Proximity3)> = None;
        for s in self.surfaces() {
            let o = self.surface(s);
            if o.lower_bound(&x) >= reach {
                continue;
            }
            let prox = o.query(&x);
            if prox.distance - reach >= -eps {
                continue; // deeper than −eps needs an offset above the reach
            }
            let depth = prox.distance - self.offset(r, i, &prox.normal);
            if depth < -eps && best.is_none_or(|b| depth < b.0) {
                best = Some((depth, s, prox));
            }
        }
        let Some((_, s, prox)) = best else { return 0 };
        let mut c = self.contact_at(r, i, s, &prox);
        c.locked = self.work[r].released[i];
        if c.locked {
            // Released for pulling in this step: caught again, it is held frictionless for
            // the rest of the step (a contact that pulls carries no friction).
            c.grip = Grip3::Slide { dir: V3::zeros() };
        } else {
            c.initial_grip(&Self::node(&self.rods[r].q, i));
        }
        self.contacts[r][i] = Some(c);
        report.added += 1;
        1
    }

    /// Bodies on fixed obstacles: stick/slip by [`decide_cone`] (a stuck contact that pulls
    /// slides first), release pulling contacts, add support points that went below a fixed
    /// obstacle.
    fn update_body_contacts(&mut self, dt: f64, report: &mut StepReport3) -> u32 {
        let mut changed = 0;
        // Kept in place (no new list each step).
        let mut all = std::mem::take(&mut self.body_contacts);
        all.retain_mut(|bc| {
            let n = bc.normal;
            let fn_ = n.dot(&bc.force);
            let ft = bc.force - n * fn_;
            let slip = lever_map(&bc.lever) * self.bodies[bc.body].dx / dt;
            let (stuck, slip_along) = match bc.stuck {
                Some(_) => (true, 0.0),
                None => (false, bc.dir.dot(&slip)),
            };
            let cone = decide_cone(bc.coulomb, stuck, bc.switches, fn_, ft.norm(), slip_along);
            // A compliant contact whose indentation has gone carries no force: released.
            let gone = bc.law.is_some() && bc.indentation(&self.bodies[bc.body].dx) <= 0.0;
            if gone || (fn_ < 0.0 && cone != Some(Cone::Slide)) {
                report.released += 1;
                changed += 1;
                return false;
            }
            match cone {
                Some(Cone::Slide) => {
                    bc.stuck = None;
                    bc.dir = -ft / ft.norm();
                }
                Some(Cone::Stick) => bc.stuck = Some(n * bc.gap),
                None => return true,
            }
            bc.switches += 1;
            changed += 1;
            report.switches += 1;
            true
        });
        self.body_contacts = all;
        changed + self.detect_body_contacts(report)
    }

    fn detect_body_contacts(&mut self, report: &mut StepReport3) -> u32 {
        let mut changed = 0;
        for b in 0..self.bodies.len() {
            let body = &self.bodies[b];
            let (c, rot) = (body.centre(), body.obstacle.pose.rotation);
            let size = body.obstacle.shape.lower_bound(&V3::zeros()).abs();
            for (k, o) in self.obstacles.iter().enumerate() {
                let n = o.query(&c).normal;
                for p in body.obstacle.shape.support_points(&(rot.inverse() * -n)) {
                    let pw = c + rot * p;
                    let prox = o.query(&pw);
                    if prox.distance >= -1e-12 * size {
                        continue;
                    }
                    let lever = pw - c;
                    let dup = self.body_contacts.iter().any(|e| {
                        e.body == b && e.obstacle == k && (e.lever - lever).norm() < 1e-6 * size
                    });
                    if dup {
                        continue;
                    }
                    let g = lever_map(&lever);
                    let gap = -prox.distance + prox.normal.dot(&(g * body.dx));
                    let coulomb = self.friction.between(&body.obstacle.name, &o.name);
                    self.body_contacts.push(BodyContact3 {
                        body: b,
                        obstacle: k,
                        normal: prox.normal,
                        lever,
                        gap,
                        stuck: (coulomb.mu_s > 0.0).then_some(prox.normal * gap),
                        dir: V3::zeros(),
                        coulomb,
                        switches: 0,
                        force: V3::zeros(),
                        law: self.table_law(b, k, &pw, &prox.normal),
                    });
                    report.added += 1;
                    changed += 1;
                }
            }
        }
        changed
    }
}
