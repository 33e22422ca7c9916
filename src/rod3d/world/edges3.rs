//! Edge contacts ([`crate::rod3d::edge3`]) in the world's step: detection, re-linearisation
//! and release after each pass, and their rows in the Newton system.
//!
//! Each edge contact j is one more unknown of the small dense system the bodies already use
//! (after the bodies' 6 unknowns each, before their own contacts' multipliers): its increment
//! δλ_j. With A_j = (w₀ n, w₁ n) on its segment's two nodes, the rod's equations gain the
//! border column −A_jᵀ (in each node's contact basis, with a sliding node's kinetic row
//! combination), and the row A_j δx − a·δX = −(violation) joins the dense system, through the
//! rod's free coordinates (the `rows` of the Schur complement) and the body motion that a
//! node's prescribed coordinates follow. The current force λ_j A_jᵀ is in the rods' residual,
//! so node contacts' reactions leave it out. On a body, λ a enters the body's equations.

use super::*;
use crate::obstacle3::segment;
use crate::rod3d::edge3::{interior, EdgeContact3, MAX_RELINEARISED};

/// Node contacts whose normals are within this angle (rad) of a segment's contact normal make
/// the segment's penetration the faceting of their surface ([`World3::nodes_follow`]).
pub const FACET: f64 = std::f64::consts::FRAC_PI_6;

impl World3 {
    /// Edge contacts of every rod, in the order of their unknowns.
    pub(super) fn edge_count(&self) -> usize {
        self.edges
            .iter()
            .flatten()
            .map(EdgeContact3::unknowns)
            .sum()
    }

    /// The thickness offset of segment i of rod r towards a surface with outward normal n:
    /// its own section's support (from its material frame at the start of the step).
    pub fn edge_offset(&self, r: usize, i: usize, n: &V3) -> f64 {
        if self.side == ContactSide3::Centreline {
            return 0.0;
        }
        let sim = &self.rods[r];
        match self.sections[r] {
            Section3::Circle { r } => r,
            Section3::Rect { b, h } => {
                let (m1, m2) = material_frame(&sim.frames[i], sim.q[angle(i)]);
                0.5 * h * n.dot(&V3::from(m1)).abs() + 0.5 * b * n.dot(&V3::from(m2)).abs()
            }
        }
    }

    /// Whether segment i of rod r may hold an edge contact: no prescribed (clamped) DOF on its
    /// nodes, and not both nodes held whole (stuck), which leaves its row no freedom.
    fn segment_open(&self, r: usize, i: usize) -> bool {
        let fixed = &self.rods[r].fixed;
        if (pos(i)..pos(i + 1) + 3).any(|k| k % 4 != 3 && fixed[k]) {
            return false;
        }
        let whole = |j: usize| self.contacts[r][j].is_some_and(|c| c.held() == 3);
        !(whole(i) && whole(i + 1))
    }

    /// Whether a node of segment i already follows surface `s` with a normal within [`FACET`]
    /// of the segment's contact normal n. Then the segment's penetration is the faceting of a
    /// smooth surface the node follows (a chord from a point on it: depth at most L²κ/8 on a
    /// curvature κ), which node contact accepts, as with nodes only; an edge row there would
    /// nearly repeat the node's held rows (the row's free part is the other node's share,
    /// which vanishes as the deepest point nears the held node), so the split of the force
    /// between node and edge is ill-conditioned: forces spike and Newton stalls on the big
    /// fruit of the shipped grasps. A corner between the nodes (a box's or mesh's edge, where
    /// the normals turn by more) is held.
    fn nodes_follow(&self, r: usize, i: usize, s: Surface3, n: &V3) -> bool {
        (i..=i + 1).any(|j| {
            self.contacts[r][j].is_some_and(|c| c.surface == s && c.normal.dot(n) > FACET.cos())
        })
    }

    /// The edge contact of segment i of rod r (configuration `q`) at weight s on surface `s`
    /// as `prox` sees it at the current body displacement.
    fn edge_at(&self, r: usize, i: usize, w: f64, s: Surface3, prox: &Proximity3) -> EdgeContact3 {
        let n = prox.normal;
        let offset = self.edge_offset(r, i, &n);
        let (lever, target, coulomb) = self.hold_on(r, s, prox, offset);
        let mut e = EdgeContact3 {
            surface: s,
            segment: i,
            weight: w,
            normal: n,
            target,
            lever,
            offset,
            point: prox.closest,
            force: 0.0,
            friction: V3::zeros(),
            grip: Grip3::Slide { dir: V3::zeros() },
            coulomb,
            switches: 0,
            locked: false,
            relinearised: 0,
        };
        if coulomb.mu_s > 0.0 {
            e.grip = Grip3::Stick {
                anchor: e.anchor_at(&self.rods[r].q),
            };
        }
        e
    }

    /// Contact `new` (re-linearised at another point or plane) with `old`'s force and grip:
    /// a stuck point is anchored where its new point was at the start of the step (`q0`), a
    /// slip direction is turned into the new tangent plane.
    fn carry(old: &EdgeContact3, new: EdgeContact3, q0: &[f64]) -> EdgeContact3 {
        let mut e = EdgeContact3 {
            force: old.force,
            switches: old.switches,
            ..new
        };
        e.grip = match old.grip {
            Grip3::Stick { .. } => Grip3::Stick {
                anchor: e.anchor_at(q0),
            },
            Grip3::Slide { dir } => {
                let t = dir - e.normal * e.normal.dot(&dir);
                Grip3::Slide {
                    dir: if t.norm() > 1e-3 {
                        t.normalize()
                    } else {
                        V3::zeros()
                    },
                }
            }
        };
        match e.grip {
            Grip3::Stick { .. } => {
                e.friction = old.friction - e.normal * e.normal.dot(&old.friction)
            }
            Grip3::Slide { .. } => e.slide_friction(),
        }
        e
    }

    /// Segment i's deepest point on surface `s` at configuration `q`: (weight, proximity,
    /// depth below the offset).
    fn deepest(&self, r: usize, i: usize, s: Surface3, q: &[f64]) -> (f64, Proximity3, f64) {
        let (a, b) = (Self::node(q, i), Self::node(q, i + 1));
        let (w, prox) = segment::deepest(self.surface(s), &a, &b);
        let depth = prox.distance - self.edge_offset(r, i, &prox.normal);
        (w, prox, depth)
    }

    /// The edge contact segment i of rod r would get on surface `s` now (its deepest point
    /// there, at the current body displacement), whether or not it is inside; `None` when the
    /// deepest point is a node's.
    pub fn edge_contact_at(&self, r: usize, i: usize, s: Surface3) -> Option<EdgeContact3> {
        let (w, prox, _) = self.deepest(r, i, s, &self.rods[r].q);
        interior(w).then(|| self.edge_at(r, i, w, s, &prox))
    }

    /// Carried edge contacts re-linearised at the start of the step (ΔX = 0); a deepest point
    /// that moved onto a node is left to the node.
    pub(super) fn relinearise_edges(&mut self) {
        for r in 0..self.rods.len() {
            self.work[r].edge_released.clear();
            self.work[r].edge_pulled.clear();
            let old = std::mem::take(&mut self.edges[r]);
            let mut out = Vec::with_capacity(old.len());
            for e in old {
                let i = e.segment;
                if !self.edge_contact || !self.segment_open(r, i) {
                    continue;
                }
                let (w, prox, _) = self.deepest(r, i, e.surface, &self.rods[r].q);
                if interior(w) {
                    let fresh = self.edge_at(r, i, w, e.surface, &prox);
                    let mut ne = Self::carry(&e, fresh, &self.rods[r].q);
                    if matches!(ne.grip, Grip3::Slide { dir } if dir == V3::zeros()) {
                        // No slip direction (held frictionless after a pull, or turned along
                        // the normal): it starts the step as a new contact does.
                        ne.grip = fresh.grip;
                        ne.friction = V3::zeros();
                    }
                    ne.switches = 0;
                    out.push(ne);
                }
            }
            self.edges[r] = out;
        }
    }

    /// Rod r's edge contacts after a converged pass: released when the multiplier pulls,
    /// re-linearised where the pass left the segment inside, dropped when the deepest point
    /// moved onto a node; new interior penetrations added. Returns how many changed.
    pub(super) fn update_edges(&mut self, r: usize, dt: f64, report: &mut StepReport3) -> u32 {
        if !self.edge_contact || self.rods[r].rod.n < 2 {
            return 0;
        }
        let tol = 1e-10 * self.rods[r].rod.length;
        let mut changed = 0;
        let old = std::mem::take(&mut self.edges[r]);
        let mut out = Vec::with_capacity(old.len());
        // Pairs released here for pulling: not caught again from this pass's positions, where
        // they were still held (on a plane whose offset and normal are a pass old, the
        // segment can sit a first-order sliver inside: caught at once, the contact would be
        // locked while it pulls); the next pass, solved without them, decides.
        let mut pulled = Vec::new();
        for mut e in old {
            let i = e.segment;
            match self.edge_friction(r, &mut e, dt) {
                Some(Change3::Release) => {
                    pulled.push((i, e.surface));
                    self.work[r].edge_released.push((i, e.surface));
                    self.work[r].edge_pulled.push((i, e.surface));
                    report.released += 1;
                    changed += 1;
                    continue;
                }
                Some(_) => {
                    report.switches += 1;
                    changed += 1;
                }
                None => {}
            }
            if !self.segment_open(r, i) || self.nodes_follow(r, i, e.surface, &e.normal) {
                self.work[r].edge_released.push((i, e.surface));
                changed += 1;
                continue;
            }
            let (w, prox, depth) = self.deepest(r, i, e.surface, &self.work[r].qn);
            if depth >= -tol || e.locked && !interior(w) || e.relinearised >= MAX_RELINEARISED {
                // Held, or dropped or re-linearised as often as a step allows: kept as it
                // is for the rest of the step (the next step re-linearises it).
                out.push(e);
            } else if interior(w) {
                let ne = EdgeContact3 {
                    locked: e.locked,
                    relinearised: e.relinearised + 1,
                    ..self.edge_at(r, i, w, e.surface, &prox)
                };
                let ne = Self::carry(&e, ne, &self.rods[r].q);
                changed += u32::from(ne != e);
                out.push(ne);
            } else {
                // The deepest point reached a node: the node's. Caught again in this step, it
                // is kept (locked).
                self.work[r].edge_released.push((i, e.surface));
                changed += 1;
            }
        }
        let fresh = self.edge_candidates(r, &out, &pulled);
        for (i, s, w, prox) in fresh {
            let locked = self.work[r].edge_released.contains(&(i, s));
            let mut e = EdgeContact3 {
                locked,
                ..self.edge_at(r, i, w, s, &prox)
            };
            if self.work[r].edge_pulled.contains(&(i, s)) {
                // Released for pulling in this step: held frictionless for the rest of it.
                e.grip = Grip3::Slide { dir: V3::zeros() };
            }
            out.push(e);
            report.added += 1;
            changed += 1;
        }
        self.edges[r] = out;
        changed
    }

    /// The segments of rod r whose deepest point on a surface ended inside it (deeper than
    /// the segment's offset) away from their nodes: (segment, surface, weight, proximity),
    /// skipping pairs in `held` and in `skip`.
    fn edge_candidates(
        &self,
        r: usize,
        held: &[EdgeContact3],
        skip: &[(usize, Surface3)],
    ) -> Vec<(usize, Surface3, f64, Proximity3)> {
        let q = &self.work[r].qn;
        let reach = match self.sections[r] {
            Section3::Circle { r } => r,
            Section3::Rect { b, h } => 0.5 * (b + h),
        };
        let eps = 1e-10 * self.rods[r].rod.length;
        let mut out = Vec::new();
        for i in 0..self.rods[r].rod.n - 1 {
            if !self.segment_open(r, i) {
                continue;
            }
            let (a, b) = (Self::node(q, i), Self::node(q, i + 1));
            for s in self.surfaces() {
                if held.iter().any(|e| e.segment == i && e.surface == s)
                    || skip.contains(&(i, s))
                    || segment::lower_bound(self.surface(s), &a, &b) >= reach
                {
                    continue;
                }
                let (w, prox, depth) = self.deepest(r, i, s, q);
                if interior(w) && depth < -eps && !self.nodes_follow(r, i, s, &prox.normal) {
                    out.push((i, s, w, prox));
                }
            }
        }
        out
    }

    /// The deepest any segment point of rod r sits below its offset on any surface, away from
    /// the nodes (m; ≤ 0: none): what node contact misses between the nodes.
    pub fn segment_penetration(&self, r: usize) -> f64 {
        let q = &self.rods[r].q;
        let reach = match self.sections[r] {
            Section3::Circle { r } => r,
            Section3::Rect { b, h } => 0.5 * (b + h),
        };
        let mut worst = f64::NEG_INFINITY;
        for i in 0..self.rods[r].rod.n.saturating_sub(1) {
            let (a, b) = (Self::node(q, i), Self::node(q, i + 1));
            for s in self.surfaces() {
                if segment::lower_bound(self.surface(s), &a, &b) >= reach {
                    continue;
                }
                let (w, _, depth) = self.deepest(r, i, s, q);
                if interior(w) {
                    worst = worst.max(-depth);
                }
            }
        }
        worst
    }

    /// The reaction of rod r's edge contacts shared to its nodes by the weights (world, N).
    pub fn edge_reactions(&self, r: usize) -> Vec<V3> {
        let mut out = vec![V3::zeros(); self.rods[r].rod.n];
        for e in &self.edges[r] {
            out[e.segment] += e.node_force(0);
            out[e.segment + 1] += e.node_force(1);
        }
        out
    }

    /// Release and stick/slip of an edge contact from the converged pass, by the node
    /// contacts' rules ([`decide_split`]) on its force and its held point's slip velocity:
    /// the change, made here unless it is a release (the caller drops the contact).
    fn edge_friction(&self, r: usize, e: &mut EdgeContact3, dt: f64) -> Option<Change3> {
        let (q0, qn) = (&self.rods[r].q, &self.work[r].qn);
        let moved = lever_map(&e.lever) * self.body_dx(e.surface);
        let v = (e.held_point(qn) - e.held_point(q0) - moved) / dt;
        let v = v - e.normal * e.normal.dot(&v);
        let f = e.total_force();
        // Pulling is the multiplier's sign (n·F can differ from it in the last bit).
        let rn = if e.force < 0.0 {
            e.force
        } else {
            e.normal.dot(&f).max(0.0)
        };
        let change = decide_split(&e.as_node(), rn, &(f - e.normal * e.normal.dot(&f)), &v)?;
        match change {
            Change3::Release => return Some(change),
            Change3::ToSlide { dir } => {
                e.grip = Grip3::Slide { dir };
                e.slide_friction();
            }
            Change3::ToStick => {
                e.grip = Grip3::Stick {
                    anchor: e.anchor_at(q0),
                }
            }
        }
        e.switches += 1;
        Some(change)
    }

    /// Rod r's edge rows of the Newton system (after its node contacts are eliminated): the
    /// constraint right-hand sides and, on a body, G^T F in its equations; with `jac` the
    /// border columns, the Schur rows and the dense entries. A contact's unknowns are
    /// consecutive: 3 while stuck (n, t₁, t₂), 1 while sliding.
    pub(super) fn edge_rows(
        &mut self,
        r: usize,
        s: &mut DMatrix<f64>,
        fb: &mut DVector<f64>,
        jac: bool,
    ) {
        let nb = 6 * self.bodies.len();
        let mut col = nb
            + self.edges[..r]
                .iter()
                .flatten()
                .map(EdgeContact3::unknowns)
                .sum::<usize>();
        for e in &self.edges[r] {
            let dxb = self.body_dx(e.surface);
            let g = lever_map(&e.lever).transpose();
            if let Surface3::Body(b) = e.surface {
                let f = g * e.total_force();
                for k in 0..6 {
                    fb[6 * b + k] -= f[k];
                }
            }
            for u in 0..e.unknowns() {
                fb[col] = -e.residual(u, &self.work[r].qn, &dxb);
                if jac {
                    let (c, d) = e.directions(u);
                    if let Surface3::Body(b) = e.surface {
                        let (gc, gd) = (g * c, g * d);
                        for k in 0..6 {
                            s[(6 * b + k, col)] += gc[k];
                            s[(col, 6 * b + k)] -= gd[k];
                        }
                    }
                    let w = &mut self.work[r];
                    let at = (col, w.border.push(Weight::Unknown(col)));
                    for (k, wt) in e.weights().into_iter().enumerate() {
                        let ct = self.contacts[r][e.segment + k];
                        let node = e.segment + k;
                        node_column(w, node, (c * wt, d * wt), ct, at, s);
                    }
                }
                col += 1;
            }
        }
    }

    /// After a solve: each edge contact's multipliers take their increments.
    pub(super) fn update_edge_forces(&mut self, dx: &[f64]) {
        let mut k = 6 * self.bodies.len();
        for e in self.edges.iter_mut().flatten() {
            let m = e.unknowns();
            e.take_increments(&dx[k..k + m]);
            k += m;
        }
    }
}

/// The current edge forces λ A_jᵀ into rod r's right-hand side (−residual), world frame,
/// before the node contacts rotate it.
pub(super) fn add_edge_forces(w: &mut Work3, edges: &[EdgeContact3]) {
    for e in edges {
        for k in 0..2 {
            let (k0, f) = (pos(e.segment + k), e.node_force(k));
            for c in 0..3 {
                if !w.elim[k0 + c] {
                    w.rhs[k0 + c] += f[c];
                }
            }
        }
    }
}

/// Node i's part of edge unknown `at.0` (border column `at.1`): the unit force `fw.0` (world) it takes per unit
/// multiplier and the direction `fw.1` the row holds it along, in its contact basis when it
/// has one. Free coordinates get the border entry −f (a sliding node's t₁ row also
/// −μ_k f_n, its kinetic combination) and the row entry d; prescribed coordinates that follow
/// a body put d P into the edge's row of the dense system; a node touching a body passes
/// −Gᵀ Qᵀ f of the multiplier to the body's equations (its reaction changes).
fn node_column(
    w: &mut Work3,
    i: usize,
    fw: (V3, V3),
    ct: Option<Contact3>,
    at: (usize, usize),
    s: &mut DMatrix<f64>,
) {
    let (col, bcol) = at;
    let (f, d, mu) = match &ct {
        Some(c) => (c.basis() * fw.0, c.basis() * fw.1, c.kinetic()),
        None => (fw.0, fw.1, 0.0),
    };
    for c in 0..3 {
        let l = pos(i) + c;
        if !w.elim[l] {
            let kinetic = if c == 1 { mu * f[0] } else { 0.0 };
            w.border.col_mut(bcol)[l] -= f[c] + kinetic;
            w.rows.push((col, l, d[c]));
        } else if let Some((b, p)) = w.follow[l] {
            for e in 0..6 {
                s[(col, 6 * b + e)] += d[c] * p[e];
            }
        }
    }
    if let Some(ct) = ct {
        if let Surface3::Body(b) = ct.surface {
            let wm = lever_map(&ct.lever).transpose() * ct.basis().transpose();
            let add = wm * f;
            for e in 0..6 {
                s[(6 * b + e, col)] -= add[e];
            }
        }
    }
}
