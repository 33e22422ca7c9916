//! Updating the constraint sets after a pass: adhesive releases, stick/slip switches (decided by
//! `contact::friction`), re-linearisation, corners, and new penetrations — for rod nodes and for
//! the free bodies' own contacts.

use super::step::StepCtx;
use super::Simulation;
use crate::contact::body::{self as bodyc, dot3, BodyContact};
use crate::contact::friction::{self, Switch};
use crate::contact::{self, BodyLink, Constraint, Grip, Surfaces};
use crate::events::{ContactChange, Event, FrictionChange, Observer, ReleaseReason};
use crate::obstacle::Proximity;
use crate::world::body::Placed;

impl Simulation {
    pub(super) fn surfaces(&self) -> Surfaces<'_> {
        Surfaces {
            obstacles: &self.obstacles,
            placement: &self.placement,
            offset: 0.0,
            compliant: &[],
        }
    }

    /// The surfaces as rod `r`'s nodes see them: grown by the rod's contact offset, without
    /// the compliant fruits it presses into by its force law.
    pub(super) fn rod_surfaces(&self, r: usize) -> Surfaces<'_> {
        Surfaces {
            compliant: self.compliant_mask(r),
            ..self.surfaces().with_offset(self.rod_offset[r])
        }
    }

    /// Which obstacles rod `r` meets through the compliant law (none for a particle, which
    /// has no face: it meets every obstacle as rigid).
    pub(super) fn compliant_mask(&self, r: usize) -> &[bool] {
        if self.work[r].compliant.is_empty() {
            &[]
        } else {
            &self.compliant
        }
    }

    /// Where the free bodies are for detection: at the start of the step, or at the pose being
    /// solved.
    pub(super) fn place_bodies(&mut self, at_start: bool) {
        for b in &self.bodies {
            let pose = if at_start { b.pose } else { b.trial_pose() };
            self.placement[b.spec.obstacle] = Some((b.spec.centroid, pose));
        }
        for w in &mut self.work {
            for c in &mut w.compliant {
                if let Some(Some((_, pose))) = c.body.and(self.placement.get(c.obstacle)) {
                    c.center = pose.c;
                }
            }
        }
    }

    /// Body `bi`'s shape at the start of the step and at the pose being solved.
    fn placements(&self, bi: usize) -> (Placed<'_>, Placed<'_>) {
        let b = &self.bodies[bi];
        let (shape, c0) = (&self.obstacles[b.spec.obstacle], b.spec.centroid);
        (
            Placed {
                shape,
                c0,
                pose: b.pose,
            },
            Placed {
                shape,
                c0,
                pose: b.trial_pose(),
            },
        )
    }

    /// The constraint holding rod `r`'s node on surface `k` where `prox` says, linearised at the
    /// body's current trial displacement (zero at the start of a step).
    pub(super) fn constraint_on(&self, r: usize, k: usize, prox: &Proximity) -> Constraint {
        let mut c = contact::constraint_at(k, prox);
        c.coulomb = self.rod_coulomb[r][k];
        let bi = self.body_of[k];
        if bi != usize::MAX {
            let b = &self.bodies[bi];
            let pose = self.placement[k].map(|p| p.1).unwrap_or(b.pose);
            // The lever to the point of the body's surface (the face's, not the centreline's).
            let off = self.rod_offset[r];
            let lever = [
                prox.closest[0] - off * prox.normal[0] - pose.c[0],
                prox.closest[1] - off * prox.normal[1] - pose.c[1],
            ];
            c.body = Some(BodyLink { body: bi, lever });
            let dx = if pose == b.pose { [0.0; 3] } else { b.dx };
            let n = c.normal;
            let a = [n[0], n[1], lever[0] * n[1] - lever[1] * n[0]];
            c.target -= dot3(&a, &dx);
        }
        c
    }

    /// A carried or deepened constraint of node (r, i), re-linearised at `p`; friction state
    /// kept (a stuck node is re-anchored where it is at the start of the step).
    pub(super) fn relinearised(
        &self,
        r: usize,
        i: usize,
        c: &Constraint,
        p: [f64; 2],
        start: bool,
    ) -> Constraint {
        let s = self.rod_surfaces(r);
        let mut nc = self.constraint_on(r, c.obstacle, &s.query(c.obstacle, p));
        nc.second = c
            .second
            .map(|sc| contact::corner_at(sc.obstacle, &s.query(sc.obstacle, p)));
        nc.grip = match c.grip {
            Grip::Stick { .. } if start => nc.stuck_from(p),
            g => g,
        };
        if !start {
            nc.locked = c.locked;
            nc.switches = c.switches;
            if let Grip::Stick { .. } = c.grip {
                let w = &self.work[r];
                nc.grip = nc.stuck_from([w.q[2 * i], w.q[2 * i + 1]]);
            }
        }
        nc
    }

    /// Update every constraint set after a pass. Returns how many rods and bodies changed
    /// (each is re-solved in the next pass).
    pub(super) fn update_contacts<O: Observer>(
        &mut self,
        ctx: &StepCtx,
        pass: u32,
        obs: &mut O,
    ) -> u32 {
        let mut changed = 0;
        for r in 0..self.rods.len() {
            if self.update_rod_contacts(ctx, r, pass, obs) {
                self.dirty[r] = true;
                changed += 1;
            }
        }
        for bi in 0..self.bodies.len() {
            if self.update_body_contacts(ctx, bi, pass, obs) {
                self.group_dirty = true;
                changed += 1;
            }
        }
        changed
    }

    fn update_rod_contacts<O: Observer>(
        &mut self,
        ctx: &StepCtx,
        r: usize,
        pass: u32,
        obs: &mut O,
    ) -> bool {
        let mut changed = false;
        // Edge mode: a conforming contact's friction is decided per contact arc, below.
        let per_node = !self.work[r].edge_mode;
        for i in 0..self.rods[r].n {
            if self.rods[r].clamped[i] {
                continue;
            }
            changed |= match self.work[r].contact[i] {
                Some(c) if c.law.is_some() => {
                    per_node && self.update_law_hold(ctx, r, i, c, pass, obs)
                }
                Some(c) => self.update_held(ctx, r, i, c, pass, obs),
                None => {
                    self.detect_new(ctx, r, i, pass, obs)
                        || (per_node && self.update_law_free(ctx, r, i, pass, obs))
                }
            };
        }
        if !per_node {
            changed |= self.update_law_arcs(ctx, r, pass, obs);
        }
        changed |= self.update_edges(ctx, r, pass, obs);
        if !ctx.dynamic {
            changed |= self.follow_edges(r);
        }
        // A rod solved alone that now presses into a fruit on a free body is solved with it.
        changed |= !self.is_member[r] && self.presses_body(r);
        changed
    }

    pub(super) fn change(
        &self,
        ctx: &StepCtx,
        pass: u32,
        r: usize,
        i: usize,
        k: usize,
        normal: [f64; 2],
    ) -> ContactChange {
        let w = &self.work[r];
        let p = [w.qn[2 * i], w.qn[2 * i + 1]];
        ContactChange {
            step: ctx.step,
            t: ctx.t1,
            pass: pass + 1,
            rod: r,
            node: i,
            obstacle: k,
            normal: crate::events::v3(normal),
            gap: self.rod_surfaces(r).query(k, p).distance,
            reaction: [w.r[2 * i], w.r[2 * i + 1], 0.0],
            z: 0.0,
        }
    }

    /// A constrained node after a pass: released when its reaction pulls, switched between
    /// stick and slip when friction says so, else re-linearised or held in a corner.
    fn update_held<O: Observer>(
        &mut self,
        ctx: &StepCtx,
        r: usize,
        i: usize,
        c: Constraint,
        pass: u32,
        obs: &mut O,
    ) -> bool {
        let w = &self.work[r];
        let reaction = [w.r[2 * i], w.r[2 * i + 1]];
        // The reaction's normal parts: along n, or on n₁ and n₂ in a corner.
        let (rn, rn2) = contact::normal_parts(&c, reaction);
        if rn < 0.0 && matches!(c.grip, Grip::Stick { .. }) {
            // Stuck and pulling: slide first (Coulomb), release only if it still pulls.
            if let Some(nc) = self.friction_switch(ctx, r, i, &c, reaction, pass, obs) {
                self.work[r].contact[i] = Some(nc);
                return true;
            }
        }
        if rn < 0.0 && !c.locked {
            // In a corner the node stays on the other surface, unless that one pulls too.
            let keep = c.second.filter(|_| rn2 >= 0.0);
            let mut kept = keep.map(|s| Constraint::on_surface(s.obstacle, s.normal, s.target));
            if let Some(k) = kept.as_mut() {
                k.coulomb = self.rod_coulomb[r][k.obstacle];
            }
            let ev = self.change(ctx, pass, r, i, c.obstacle, c.normal);
            obs.on_event(&Event::ConstraintReleased(ev, ReleaseReason::Adhesive));
            if let (None, Some(s)) = (keep, c.second) {
                let ev = self.change(ctx, pass, r, i, s.obstacle, s.normal);
                obs.on_event(&Event::ConstraintReleased(ev, ReleaseReason::Adhesive));
            }
            let w = &mut self.work[r];
            w.contact[i] = kept;
            // Mark so that a re-penetration in this step locks it.
            w.contact_saved_mark(i);
            return true;
        }
        if let (true, Some(s)) = (rn2 < 0.0, c.second) {
            self.work[r].contact[i] = Some(Constraint { second: None, ..c });
            let ev = self.change(ctx, pass, r, i, s.obstacle, s.normal);
            obs.on_event(&Event::ConstraintReleased(ev, ReleaseReason::Adhesive));
            return true;
        }
        if let Some(nc) = self.friction_switch(ctx, r, i, &c, reaction, pass, obs) {
            self.work[r].contact[i] = Some(nc);
            return true;
        }
        let nc = self.deepened(ctx, r, i, c, pass, obs);
        if nc != c {
            self.work[r].contact[i] = Some(nc);
            return true;
        }
        false
    }

    /// Slip velocity of a contact along its tangent, relative to the surface (m/s).
    fn slip_velocity(&self, ctx: &StepCtx, r: usize, i: usize, c: &Constraint) -> f64 {
        self.velocity_along(ctx, r, i, c, c.tangent())
    }

    /// Node i's velocity along `t` relative to the surface of its contact `c` (its body's
    /// motion taken out; m/s; 0 in a static solve).
    pub(super) fn velocity_along(
        &self,
        ctx: &StepCtx,
        r: usize,
        i: usize,
        c: &Constraint,
        t: [f64; 2],
    ) -> f64 {
        if !ctx.dynamic {
            return 0.0;
        }
        let w = &self.work[r];
        let mut d = [w.dq[2 * i], w.dq[2 * i + 1]];
        if let Some((b, g)) = c.body_columns() {
            let x = self.bodies[b].dx;
            for a in 0..2 {
                d[a] -= g[0][a] * x[0] + g[1][a] * x[1] + g[2][a] * x[2];
            }
        }
        (t[0] * d[0] + t[1] * d[1]) / ctx.dt
    }

    #[allow(clippy::too_many_arguments)]
    fn friction_switch<O: Observer>(
        &self,
        ctx: &StepCtx,
        r: usize,
        i: usize,
        c: &Constraint,
        reaction: [f64; 2],
        pass: u32,
        obs: &mut O,
    ) -> Option<Constraint> {
        let v_t = self.slip_velocity(ctx, r, i, c);
        let switch = friction::decide(c, reaction, v_t)?;
        let w = &self.work[r];
        let mut nc = *c;
        nc.switches += 1;
        nc.grip = match switch {
            Switch::ToSlide { sign } => Grip::Slide { sign },
            Switch::ToStick => c.stuck_from([w.q[2 * i], w.q[2 * i + 1]]),
        };
        let (rn, rt) = friction::split(c, reaction);
        obs.on_event(&Event::FrictionChanged(FrictionChange {
            step: ctx.step,
            t: ctx.t1,
            pass: pass + 1,
            rod: r,
            node: i,
            obstacle: c.obstacle,
            stuck: matches!(switch, Switch::ToStick),
            normal_force: rn,
            tangential_force: rt,
            slip_velocity: v_t,
            segment: usize::MAX,
            weight: 0.0,
        }));
        Some(nc)
    }

    /// A held node that the pass left inside a surface: re-linearised there; inside a second
    /// fixed obstacle: held in the corner.
    fn deepened<O: Observer>(
        &self,
        ctx: &StepCtx,
        r: usize,
        i: usize,
        c: Constraint,
        pass: u32,
        obs: &mut O,
    ) -> Constraint {
        let rod = &self.rods[r];
        let w = &self.work[r];
        let relin_tol = 1e-10 * rod.length;
        let p = [w.qn[2 * i], w.qn[2 * i + 1]];
        let s = self.rod_surfaces(r);
        let mut nc = c;
        let stuck = matches!(c.grip, Grip::Stick { .. });
        let gap = s.query(c.obstacle, p).distance;
        // Static mode also follows a node that slid off its tangent point (the equilibrium
        // holds it on the surface, not on a tangent line).
        if !stuck && (gap < -relin_tol || (!ctx.dynamic && gap > relin_tol)) {
            nc = self.relinearised(r, i, &c, p, false);
        }
        if c.body.is_some() {
            return nc;
        }
        if let Some(sc) = c.second {
            let prox = s.query(sc.obstacle, p);
            if prox.distance < -relin_tol {
                nc.second = Some(contact::corner_at(sc.obstacle, &prox));
            }
        } else if let Some((k, prox)) = contact::deepest_other(&s, p, c.obstacle, -relin_tol) {
            if self.body_of[k] != usize::MAX {
                return nc;
            }
            // Held on one obstacle but inside another: a corner (or, for nearly parallel
            // surfaces, the other one instead).
            let (mut held, corner) = contact::add_surface(&nc, k, &prox);
            if held.obstacle != nc.obstacle {
                held.coulomb = self.rod_coulomb[r][held.obstacle];
            }
            nc = held;
            let mut ev = self.change(ctx, pass, r, i, k, corner.normal);
            ev.gap = prox.distance;
            ev.reaction = [0.0; 3];
            ev.z = self.prescribed_z(ctx, r, i, corner.normal, corner.target);
            obs.on_event(&Event::ConstraintAdded(ev));
        }
        nc
    }

    /// The corrector's prescribed normal velocity change of an added constraint (m/s).
    fn prescribed_z(&self, ctx: &StepCtx, r: usize, i: usize, n: [f64; 2], target: f64) -> f64 {
        if !ctx.dynamic {
            return 0.0;
        }
        let w = &self.work[r];
        let qk = [w.q[2 * i], w.q[2 * i + 1]];
        let un = n[0] * w.u[2 * i] + n[1] * w.u[2 * i + 1];
        (target - (n[0] * qk[0] + n[1] * qk[1])) / ctx.dt - un
    }

    /// A free node after a pass: constrained on the surface it penetrates most, if any.
    fn detect_new<O: Observer>(
        &mut self,
        ctx: &StepCtx,
        r: usize,
        i: usize,
        pass: u32,
        obs: &mut O,
    ) -> bool {
        if !ctx.dynamic {
            // Static mode: the increment's first entry is held first (solver/statics.rs).
            return false;
        }
        let w = &self.work[r];
        let p = [w.qn[2 * i], w.qn[2 * i + 1]];
        let Some((k, prox)) = contact::deepest(&self.rod_surfaces(r), p, 0.0) else {
            return false;
        };
        if self.beside_edge(r, i, k, prox.normal) {
            // The edge contact beside it holds that surface there (re-linearised towards
            // the node, or handing the contact to it: src/solver/edge_sets.rs).
            return false;
        }
        let mut c = self.constraint_on(r, k, &prox);
        c.locked = w.was_released(i);
        c.grip = friction::initial_grip(&c, [w.q[2 * i], w.q[2 * i + 1]]);
        let mut ev = self.change(ctx, pass, r, i, k, c.normal);
        ev.gap = prox.distance;
        ev.reaction = [0.0; 3];
        ev.z = self.prescribed_z(ctx, r, i, c.normal, c.target);
        self.work[r].contact[i] = Some(c);
        obs.on_event(&Event::ConstraintAdded(ev));
        true
    }

    /// A free body's own contacts after a pass (or at the start of the step): releases, stick
    /// and slip, re-linearisation, new contacts with fixed obstacles.
    fn update_body_contacts<O: Observer>(
        &mut self,
        ctx: &StepCtx,
        bi: usize,
        pass: u32,
        obs: &mut O,
    ) -> bool {
        let mut changed = false;
        let mut j = 0;
        while j < self.bodies[bi].contacts.len() {
            let b = &self.bodies[bi];
            let c = b.contacts[j];
            let lam = b.reaction.get(j).copied().unwrap_or([0.0; 2]);
            // Stuck and pulling: slide first (Coulomb), release only if it still pulls.
            let slides_first = lam[0] < 0.0
                && c.is_stuck()
                && friction::decide_on(c.coulomb, c.grip, c.switches, lam[0], lam[1], 0.0)
                    .is_some();
            // A compliant contact ends where its point leaves the surface (no force).
            let left = c.law.is_some() && c.indentation(&b.dx) <= 0.0;
            if left || (lam[0] < 0.0 && !c.locked && !slides_first) {
                let b = &mut self.bodies[bi];
                b.contacts.remove(j);
                if j < b.reaction.len() {
                    b.reaction.remove(j);
                }
                b.released.push((c.feature, c.obstacle));
                self.body_event(ctx, pass, bi, &c, false, lam, obs);
                changed = true;
                continue;
            }
            let rt = if c.is_stuck() {
                lam[1]
            } else {
                -c.coulomb.mu_k * lam[0] * slide_sign(&c)
            };
            let v_t = if ctx.dynamic {
                (dot3(&c.row(c.tangent()), &b.dx) - c.stick_target) / ctx.dt
            } else {
                0.0
            };
            if let Some(s) = friction::decide_on(c.coulomb, c.grip, c.switches, lam[0], rt, v_t) {
                let c = &mut self.bodies[bi].contacts[j];
                c.switches += 1;
                c.grip = match s {
                    Switch::ToSlide { sign } => Grip::Slide { sign },
                    Switch::ToStick => Grip::Stick { anchor: [0.0; 2] },
                };
                let c = *c;
                obs.on_event(&Event::FrictionChanged(FrictionChange {
                    step: ctx.step,
                    t: ctx.t1,
                    pass: pass + 1,
                    rod: usize::MAX,
                    node: bi,
                    obstacle: c.obstacle,
                    stuck: c.is_stuck(),
                    normal_force: lam[0],
                    tangential_force: rt,
                    slip_velocity: v_t,
                    segment: usize::MAX,
                    weight: 0.0,
                }));
                changed = true;
            }
            j += 1;
        }
        changed |= self.relinearise_body_contacts(bi, ctx, false);
        changed |= self.detect_body_contacts(ctx, bi, pass, obs);
        changed
    }

    /// Re-linearise a body's contacts at its pose (start of the step, or the trial pose where a
    /// sliding point went deeper than the tolerance). Returns whether any changed.
    pub(super) fn relinearise_body_contacts(
        &mut self,
        bi: usize,
        ctx: &StepCtx,
        at_start: bool,
    ) -> bool {
        let b = &self.bodies[bi];
        let (start, trial) = self.placements(bi);
        let at = if at_start { start } else { trial };
        let dx = if at_start { [0.0; 3] } else { b.dx };
        let tol = 1e-10 * b.spec.radius;
        let mut out = Vec::with_capacity(b.contacts.len());
        let mut changed = false;
        for c in &b.contacts {
            let Some((w, q)) = bodyc::feature_point(&at, &self.obstacles[c.obstacle], c.feature)
            else {
                out.push(*c);
                continue;
            };
            // A compliant contact's point sits inside by its indentation: re-linearised only
            // where the linearised indentation has drifted from the true one.
            let keep = match c.law {
                Some(_) => (q.distance + c.indentation(&dx)).abs() <= tol,
                None => c.is_stuck() || q.distance >= -tol,
            };
            if !at_start && keep {
                out.push(*c);
                continue;
            }
            let w0 = start.to_world(at.to_shape(w));
            let mut nc = bodyc::linearise(c.obstacle, c.feature, &at, w, w0, &q, &dx);
            (nc.grip, nc.coulomb, nc.locked, nc.switches, nc.law) =
                (c.grip, c.coulomb, c.locked, c.switches, c.law);
            if at_start {
                (nc.locked, nc.switches) = (false, 0);
            }
            changed |= nc != *c;
            out.push(nc);
        }
        let _ = ctx;
        self.bodies[bi].contacts = out;
        changed
    }

    fn detect_body_contacts<O: Observer>(
        &mut self,
        ctx: &StepCtx,
        bi: usize,
        pass: u32,
        obs: &mut O,
    ) -> bool {
        let b = &self.bodies[bi];
        let (start, trial) = self.placements(bi);
        let mut found = Vec::new();
        let mut added = Vec::new();
        for (k, o) in self.obstacles.iter().enumerate() {
            if self.body_of[k] != usize::MAX {
                continue;
            }
            bodyc::points(&trial, o, 0.0, &mut found);
            for (feature, w, q) in &found {
                if b.contacts
                    .iter()
                    .any(|c| c.obstacle == k && c.feature == *feature)
                {
                    continue;
                }
                let w0 = start.to_world(trial.to_shape(*w));
                let mut c = bodyc::linearise(k, *feature, &trial, *w, w0, q, &b.dx);
                c.coulomb = self.body_coulomb[bi][k];
                c.law = self.body_law(bi, k);
                c.locked = b.released.contains(&(*feature, k));
                if c.coulomb.mu_s > 0.0 {
                    c.grip = Grip::Stick { anchor: [0.0; 2] };
                }
                added.push(c);
            }
        }
        let any = !added.is_empty();
        for c in added {
            self.body_event(ctx, pass, bi, &c, true, [0.0; 2], obs);
            self.bodies[bi].contacts.push(c);
        }
        any
    }

    #[allow(clippy::too_many_arguments)]
    fn body_event<O: Observer>(
        &self,
        ctx: &StepCtx,
        pass: u32,
        bi: usize,
        c: &BodyContact,
        added: bool,
        reaction: [f64; 2],
        obs: &mut O,
    ) {
        obs.on_event(&Event::BodyContactChanged {
            step: ctx.step,
            t: ctx.t1,
            pass: pass + 1,
            body: bi,
            obstacle: c.obstacle,
            feature: c.feature,
            added,
            normal: crate::events::v3(c.normal),
            reaction: crate::events::v3(reaction),
        });
    }
}

fn slide_sign(c: &BodyContact) -> f64 {
    match c.grip {
        Grip::Slide { sign } => sign,
        Grip::Stick { .. } => 0.0,
    }
}
