//! The edge contact sets after each pass (`[contact] points = "edges"`): detection of a
//! segment's interior against every obstacle (fixed, or carried by a free body), release when
//! the multiplier pulls, stick and slip (decided by `contact::friction`, as for nodes),
//! re-linearisation along the segment, and the hand-over between an edge contact and its
//! nodes' own contacts on the same surface.
//!
//! Hand-over. A node held on a surface and an edge contact of one of its segments on the same
//! surface, with normals within [`edge::FACET`] of each other, hold nearly the same point: the
//! edge row's free part is the other node's share, which vanishes as the contact nears the
//! held node, so the split of the force between the two is ill-conditioned (forces spike,
//! Newton stalls, and a stuck node's tangential hold fights the edge's). They are never held
//! together. A segment whose interior goes into the surface beside a held node takes the
//! contact from the node (the node is released, event `ConstraintReleased` with reason
//! `HandedOver`: a straight segment touches a convex surface at one point, so the node lifts
//! off); when the contact point slides onto the node (weight within `END` of it) the edge is
//! dropped and the node's own contact takes over. A node released so, or a pair dropped so,
//! that comes back in the same step is kept (locked) for the rest of the step: then the node
//! holds and the segment beside it gets no row until the next step.

use super::step::StepCtx;
use super::Simulation;
use crate::contact::edge::{self, EdgeContact, MAX_RELINEARISED};
use crate::contact::friction::{self, Switch};
use crate::contact::{BodyLink, Grip};
use crate::events::{Event, FrictionChange, Observer, ReleaseReason};
use crate::obstacle::Proximity;
use crate::scenario::contact::ContactPoints;

/// How a node's own contact stands to an edge contact of its segment on surface k.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Facet {
    /// Not held on k near the edge's normal: independent.
    Apart,
    /// Held on k within FACET, free to hand the contact to the edge.
    HandOver,
    /// Held on k within FACET and kept (locked in this step, or in a corner): the edge yields.
    Keeps,
}

impl Simulation {
    /// Whether rod `r`'s segments are tested (`[contact] points = "edges"`).
    pub(super) fn edges_on(&self, r: usize) -> bool {
        self.scenario.contact.points == ContactPoints::Edges && self.rods[r].n > 1
    }

    /// The edge contact holding segment i of rod r at weight `s` on surface k where `prox`
    /// says, linearised at the body's current trial displacement (zero at the start of a
    /// step); frictionless sliding until the caller sets its grip.
    pub(super) fn edge_on(
        &self,
        r: usize,
        i: usize,
        k: usize,
        s: f64,
        prox: &Proximity,
    ) -> EdgeContact {
        let mut e = EdgeContact::at(k, i, s, prox);
        e.coulomb = self.rod_coulomb[r][k];
        let bi = self.body_of[k];
        if bi != usize::MAX {
            let b = &self.bodies[bi];
            let pose = self.placement[k].map(|p| p.1).unwrap_or(b.pose);
            // The lever to the point of the body's surface (the face's, not the centreline's).
            let off = self.rod_offset[r];
            let n = prox.normal;
            let lever = [
                prox.closest[0] - off * n[0] - pose.c[0],
                prox.closest[1] - off * n[1] - pose.c[1],
            ];
            e.body = Some(BodyLink { body: bi, lever });
            let dx = if pose == b.pose { [0.0; 3] } else { b.dx };
            let a = e.body_row(n);
            e.target -= a[0] * dx[0] + a[1] * dx[1] + a[2] * dx[2];
        }
        e
    }

    /// `old` re-linearised at weight `s` where `prox` says, keeping its force and grip: a
    /// stuck point is anchored where its new point was at the start of the step. `start`:
    /// at the start of a step (switches, re-linearisations and the lock begin anew).
    pub(super) fn carried_edge(
        &self,
        r: usize,
        old: &EdgeContact,
        s: f64,
        prox: &Proximity,
        start: bool,
    ) -> EdgeContact {
        let mut e = self.edge_on(r, old.segment, old.obstacle, s, prox);
        e.force = old.force;
        if !start {
            e.switches = old.switches;
            e.relinearised = old.relinearised + 1;
            e.locked = old.locked;
        }
        e.grip = match old.grip {
            Grip::Stick { .. } => e.stuck_at(&self.work[r].q),
            g => g,
        };
        if !e.is_stuck() {
            e.slide_friction();
        }
        e
    }

    /// Segment i of rod r's closest point to surface k at configuration `q`.
    fn segment_closest(&self, r: usize, i: usize, k: usize, q: &[f64]) -> (f64, Proximity) {
        let a = [q[2 * i], q[2 * i + 1]];
        let b = [q[2 * i + 2], q[2 * i + 3]];
        edge::closest_on_segment(&self.rod_surfaces(r), k, a, b)
    }

    /// Node i of rod r against an edge contact on surface k with normal n.
    fn facet(&self, r: usize, i: usize, k: usize, n: [f64; 2]) -> Facet {
        let Some(c) = self.work[r].contact[i] else {
            return Facet::Apart;
        };
        let near = |o: usize, m: [f64; 2]| o == k && m[0] * n[0] + m[1] * n[1] > edge::FACET.cos();
        let second = c.second.is_some_and(|s| near(s.obstacle, s.normal));
        if second || (c.second.is_some() && near(c.obstacle, c.normal)) {
            return Facet::Keeps;
        }
        match (near(c.obstacle, c.normal), c.locked) {
            (false, _) => Facet::Apart,
            (true, true) => Facet::Keeps,
            (true, false) => Facet::HandOver,
        }
    }

    /// Whether segment i of rod r may hold an edge contact on surface k (normal n): no driven
    /// node, no node keeping the surface there, and not both nodes held whole (which leaves
    /// the row no freedom) by contacts that stay.
    fn segment_open(&self, r: usize, i: usize, k: usize, n: [f64; 2]) -> bool {
        let rod = &self.rods[r];
        if rod.clamped[i] || rod.clamped[i + 1] {
            return false;
        }
        let (f0, f1) = (self.facet(r, i, k, n), self.facet(r, i + 1, k, n));
        if f0 == Facet::Keeps || f1 == Facet::Keeps {
            return false;
        }
        let whole = |j: usize, f: Facet| {
            f != Facet::HandOver && self.work[r].contact[j].is_some_and(|c| c.holds_whole_node())
        };
        !(whole(i, f0) && whole(i + 1, f1))
    }

    /// Whether node i of rod r, inside surface k with normal n, lies beside an edge contact
    /// that holds that surface there (the edge's: not caught as the node's own).
    pub(super) fn beside_edge(&self, r: usize, i: usize, k: usize, n: [f64; 2]) -> bool {
        self.work[r].edges.iter().any(|e| {
            e.touches(i)
                && e.obstacle == k
                && e.normal[0] * n[0] + e.normal[1] * n[1] > edge::FACET.cos()
        })
    }

    /// The segments of rod `r` (configuration `q`) that a surface holds at an interior point:
    /// (segment, obstacle, weight, proximity), skipping pairs in `held` and in `skip`.
    pub(super) fn edge_candidates(
        &self,
        r: usize,
        held: &[EdgeContact],
        skip: &[(usize, usize)],
    ) -> Vec<(usize, usize, f64, Proximity)> {
        let rod = &self.rods[r];
        let q = &self.work[r].qn;
        let s = self.rod_surfaces(r);
        let mut out = Vec::new();
        for i in 0..rod.n - 1 {
            if rod.clamped[i] || rod.clamped[i + 1] {
                continue;
            }
            let a = [q[2 * i], q[2 * i + 1]];
            let b = [q[2 * i + 2], q[2 * i + 3]];
            for k in 0..s.len() {
                if held.iter().any(|e| e.segment == i && e.obstacle == k)
                    || skip.contains(&(i, k))
                    || edge::lower_bound(&s, k, a, b) >= 0.0
                {
                    continue;
                }
                let (w, prox) = edge::closest_on_segment(&s, k, a, b);
                if prox.distance < 0.0
                    && edge::interior(w)
                    && self.segment_open(r, i, k, prox.normal)
                {
                    out.push((i, k, w, prox));
                }
            }
        }
        out
    }

    /// Edge contacts carried into a step: re-linearised at the start positions, forces and
    /// grips kept (a point whose closest point moved onto a node is left to the node).
    pub(super) fn relinearise_edges_at_start(&mut self, r: usize) {
        if self.work[r].edges.is_empty() {
            return;
        }
        let old = std::mem::take(&mut self.work[r].edges);
        let mut out = Vec::with_capacity(old.len());
        for e in &old {
            if !self.segment_open(r, e.segment, e.obstacle, e.normal) {
                continue;
            }
            let (wt, prox) = self.segment_closest(r, e.segment, e.obstacle, &self.work[r].q);
            if edge::interior(wt) {
                out.push(self.carried_edge(r, e, wt, &prox, true));
            }
        }
        self.work[r].edges = out;
    }

    /// Rod `r`'s edge contacts after a pass: released when the multiplier pulls (a stuck one
    /// slides first), switched between stick and slip, re-linearised where the pass left the
    /// segment inside (at most [`MAX_RELINEARISED`] times a step), dropped when the contact
    /// point slid onto a node; new interior penetrations added; then the hand-over with the
    /// nodes' own contacts. Returns whether the set changed.
    pub(super) fn update_edges<O: Observer>(
        &mut self,
        ctx: &StepCtx,
        r: usize,
        pass: u32,
        obs: &mut O,
    ) -> bool {
        if !self.edges_on(r) {
            let had = !self.work[r].edges.is_empty();
            self.work[r].edges.clear();
            return had;
        }
        let tol = 1e-10 * self.rods[r].length;
        let old = std::mem::take(&mut self.work[r].edges);
        let mut out = Vec::with_capacity(old.len());
        // Pairs released here for pulling: not caught again from this pass's positions,
        // where they were still held; the next pass, solved without them, decides.
        let mut pulled = Vec::new();
        let mut changed = false;
        for mut e in old {
            let (i, k) = (e.segment, e.obstacle);
            // Stuck and pulling: slide first (Coulomb), release only if it still pulls.
            if e.force[0] < 0.0 && e.is_stuck() && self.edge_switch(ctx, r, &mut e, pass, obs) {
                out.push(e);
                changed = true;
                continue;
            }
            if e.force[0] < 0.0 && !e.locked {
                pulled.push((i, k));
                self.work[r].edge_released.push((i, k));
                changed = true;
                continue;
            }
            changed |= self.edge_switch(ctx, r, &mut e, pass, obs);
            if !self.segment_open(r, i, k, e.normal) {
                self.work[r].edge_released.push((i, k));
                changed = true;
                continue;
            }
            let (wt, prox) = self.segment_closest(r, i, k, &self.work[r].qn);
            // Static mode: held edges follow their surface in `follow_edges` (statics.rs).
            if !ctx.dynamic
                || prox.distance >= -tol
                || (e.locked && !edge::interior(wt))
                || e.relinearised >= MAX_RELINEARISED
            {
                // Held, or dropped or re-linearised as often as a step allows: kept as it
                // is for the rest of the step (the next step re-linearises it).
                out.push(e);
            } else if edge::interior(wt) {
                let ne = self.carried_edge(r, &e, wt, &prox, false);
                changed |= ne != e;
                out.push(ne);
            } else {
                // The contact point reached a node: the node's own contact takes over.
                self.work[r].edge_released.push((i, k));
                changed = true;
            }
        }
        // Static mode: the increment's first entry is held first (statics.rs).
        let fresh = if ctx.dynamic {
            self.edge_candidates(r, &out, &pulled)
        } else {
            Vec::new()
        };
        for (i, k, wt, prox) in fresh {
            let mut e = self.edge_on(r, i, k, wt, &prox);
            e.locked = self.work[r].edge_released.contains(&(i, k));
            if e.coulomb.mu_s > 0.0 {
                e.grip = e.stuck_at(&self.work[r].q);
            }
            out.push(e);
            changed = true;
        }
        self.work[r].edges = out;
        changed |= self.hand_over(ctx, r, pass, obs);
        self.work[r].mark_edge_nodes();
        changed
    }

    /// The hand-over: a node held on the surface of an edge contact of its segment, within
    /// FACET of its normal, is released to the edge (or, if it keeps the surface, the edge is
    /// dropped). Returns whether anything changed.
    fn hand_over<O: Observer>(&mut self, ctx: &StepCtx, r: usize, pass: u32, obs: &mut O) -> bool {
        let mut changed = false;
        let mut j = 0;
        while j < self.work[r].edges.len() {
            let e = self.work[r].edges[j];
            let f = [0, 1].map(|a| self.facet(r, e.segment + a, e.obstacle, e.normal));
            if f.contains(&Facet::Keeps) {
                self.work[r].edges.remove(j);
                self.work[r].edge_released.push((e.segment, e.obstacle));
                changed = true;
                continue;
            }
            for (a, fa) in f.iter().enumerate() {
                if *fa != Facet::HandOver {
                    continue;
                }
                let i = e.segment + a;
                let c = self.work[r].contact[i].expect("a held node");
                let ev = self.change(ctx, pass, r, i, c.obstacle, c.normal);
                obs.on_event(&Event::ConstraintReleased(ev, ReleaseReason::HandedOver));
                let w = &mut self.work[r];
                w.contact[i] = None;
                w.released.push(i);
                changed = true;
            }
            j += 1;
        }
        changed
    }

    /// The slip velocity of edge contact `e`'s held point along its tangent, relative to the
    /// surface (m/s).
    fn edge_slip(&self, ctx: &StepCtx, r: usize, e: &EdgeContact) -> f64 {
        if !ctx.dynamic {
            return 0.0;
        }
        let w = &self.work[r];
        let (p1, p0) = (e.point(&w.qn), e.point(&w.q));
        let mut d = [p1[0] - p0[0], p1[1] - p0[1]];
        if let Some((b, g)) = e.as_node().body_columns() {
            let x = self.bodies[b].dx;
            for a in 0..2 {
                d[a] -= g[0][a] * x[0] + g[1][a] * x[1] + g[2][a] * x[2];
            }
        }
        let t = e.tangent();
        (t[0] * d[0] + t[1] * d[1]) / ctx.dt
    }

    /// Stick/slip of edge contact `e` after a pass, by the node contacts' rules
    /// ([`friction::decide_on`]) on its multipliers and its held point's slip velocity.
    /// Returns whether it switched (then reported as `FrictionChanged`).
    fn edge_switch<O: Observer>(
        &self,
        ctx: &StepCtx,
        r: usize,
        e: &mut EdgeContact,
        pass: u32,
        obs: &mut O,
    ) -> bool {
        let v_t = self.edge_slip(ctx, r, e);
        let [rn, rt] = e.force;
        let Some(switch) = friction::decide_on(e.coulomb, e.grip, e.switches, rn, rt, v_t) else {
            return false;
        };
        e.switches += 1;
        e.grip = match switch {
            Switch::ToSlide { sign } => Grip::Slide { sign },
            Switch::ToStick => e.stuck_at(&self.work[r].q),
        };
        if !e.is_stuck() {
            e.slide_friction();
        }
        obs.on_event(&Event::FrictionChanged(FrictionChange {
            step: ctx.step,
            t: ctx.t1,
            pass: pass + 1,
            rod: r,
            node: e.segment,
            obstacle: e.obstacle,
            stuck: e.is_stuck(),
            normal_force: rn,
            tangential_force: rt,
            slip_velocity: v_t,
            segment: e.segment,
            weight: e.weight,
        }));
        true
    }

    /// The deepest point of rod `r`'s segments inside a rigid obstacle or free body (m, ≥ 0)
    /// in edge mode (0 otherwise): what the nodes' penetration misses between them.
    pub(super) fn segment_penetration(&self, r: usize) -> f64 {
        if self.scenario.contact.points != ContactPoints::Edges || self.rods[r].n < 2 {
            return 0.0;
        }
        let s = self.rod_surfaces(r);
        let q = &self.work[r].q;
        let mut pen = 0.0f64;
        for i in 0..self.rods[r].n - 1 {
            if self.rods[r].clamped[i] || self.rods[r].clamped[i + 1] {
                continue;
            }
            let a = [q[2 * i], q[2 * i + 1]];
            let b = [q[2 * i + 2], q[2 * i + 3]];
            for k in 0..s.len() {
                if edge::lower_bound(&s, k, a, b) < 0.0 {
                    pen = pen.max(-edge::closest_on_segment(&s, k, a, b).1.distance);
                }
            }
        }
        pen
    }
}
