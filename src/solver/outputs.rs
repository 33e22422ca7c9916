//! What a step reports: the rods' step-end arrays, every active contact with its friction
//! state, the free bodies' poses and the net contact wrench on them.

use super::{BodyOut, Simulation};
use crate::contact::{self, friction, Grip};
use crate::events::{v3, BodyView, ContactView, Event, Observer, RodStepView};

impl Simulation {
    pub(super) fn fill_outputs(&mut self, r: usize, dt: f64, initial: bool) {
        let rod = &self.rods[r];
        let w = &self.work[r];
        let surfaces = contact::Surfaces {
            obstacles: &self.obstacles,
            placement: &self.placement,
            offset: self.rod_offset[r],
            compliant: if w.compliant.is_empty() {
                &[]
            } else {
                &self.compliant
            },
        };
        let o = &mut self.out[r];
        for i in 0..rod.n {
            let c = if initial { None } else { w.contact[i] };
            let pressed = if initial || rod.clamped[i] {
                None
            } else {
                w.pressed[i]
            };
            let (rx, ry) = if initial {
                (0.0, 0.0)
            } else {
                (w.r[2 * i], w.r[2 * i + 1])
            };
            let old = [o.reaction[2 * i], o.reaction[2 * i + 1]];
            if rod.clamped[i] {
                o.reaction[2 * i] = 0.0;
                o.reaction[2 * i + 1] = 0.0;
                o.drive_force[2 * i] = rx;
                o.drive_force[2 * i + 1] = ry;
            } else {
                o.drive_force[2 * i] = 0.0;
                o.drive_force[2 * i + 1] = 0.0;
                let g = contact_force(w, i, c.is_some(), pressed, [rx, ry], initial);
                o.reaction[2 * i] = g[0];
                o.reaction[2 * i + 1] = g[1];
            }
            node_impulse(o, w, i, dt, initial, old);
            let held = held_by(w, i, c, pressed, rod.clamped[i], initial);
            let n = held.map_or([0.0; 2], |h| h.0);
            o.normal[2 * i] = n[0];
            o.normal[2 * i + 1] = n[1];
            o.obstacle[i] = held.map_or(usize::MAX, |h| h.1);
            o.in_contact[i] = held.is_some();
            // The second surface of a corner.
            let second = c.filter(|_| !rod.clamped[i]).and_then(|c| c.second);
            o.normal2[2 * i] = second.map_or(0.0, |s| s.normal[0]);
            o.normal2[2 * i + 1] = second.map_or(0.0, |s| s.normal[1]);
            o.obstacle2[i] = second.map_or(usize::MAX, |s| s.obstacle);
            o.gap[i] = contact::gap(&surfaces, [w.q[2 * i], w.q[2 * i + 1]], rod.length);
            if let Some(p) = pressed {
                // Into a compliant fruit the gap is minus the indentation.
                o.gap[i] = o.gap[i].min(-p.indentation);
            }
        }
        if initial {
            o.q_pred.copy_from_slice(&w.q);
        }
        rod.bending_stress(&w.q, &mut o.stress);
    }

    pub(super) fn emit_step_end<O: Observer>(
        &self,
        obs: &mut O,
        dt: f64,
        newton_iterations: u32,
        passes: u32,
    ) {
        let views: Vec<RodStepView<'_>> = self
            .out
            .iter()
            .zip(&self.work)
            .map(|(o, w)| RodStepView {
                dim: 2,
                q: &w.q,
                u: &w.u,
                reaction: &o.reaction,
                impulse: &o.impulse,
                drive_force: &o.drive_force,
                normal: &o.normal,
                contact_obstacle: &o.obstacle,
                normal2: &o.normal2,
                contact_obstacle2: &o.obstacle2,
                in_contact: &o.in_contact,
                bending_stress: &o.stress,
                gap: &o.gap,
                q_predictor: &o.q_pred,
                twist_stress: &[],
                frames: None,
            })
            .collect();
        let names: Vec<&str> = self.bodies.iter().map(|b| b.spec.name.as_str()).collect();
        let bodies: Vec<BodyView<'_>> = self
            .bodies
            .iter()
            .zip(&self.body_out)
            .zip(&names)
            .map(|((b, o), name)| BodyView {
                name,
                obstacle: b.spec.obstacle,
                position: v3(b.pose.c),
                angle: b.pose.theta,
                rotation: crate::events::about_z(b.pose.theta),
                velocity: [b.v[0], b.v[1], 0.0],
                angular_velocity: [0.0, 0.0, b.v[2]],
                contact_force: v3(o.force),
                contact_torque: [0.0, 0.0, o.torque],
                mass: b.spec.mass,
            })
            .collect();
        let joints: Vec<crate::events::JointView> = self
            .joints
            .joints
            .iter()
            .map(|j| crate::events::JointView {
                rods: j.rods,
                nodes: j.nodes,
                force: j.force,
                moment: j.moment,
            })
            .collect();
        obs.on_event(&Event::StepEnd {
            step: self.step,
            t: self.t,
            dt,
            newton_iterations,
            passes,
            rods: &views,
            bodies: &bodies,
            contacts: &self.contact_out,
            joints: &joints,
        });
    }

    /// Every active contact (rod nodes, then the bodies' own), and the net contact wrench on
    /// each body: minus the reactions of the nodes held on it, plus its own contacts' forces.
    pub(super) fn fill_contact_outputs(&mut self, dt: f64) {
        self.contact_out.clear();
        self.body_out
            .iter_mut()
            .for_each(|o| *o = BodyOut::default());
        for r in 0..self.rods.len() {
            for i in 0..self.rods[r].n {
                if self.rods[r].clamped[i] {
                    continue;
                }
                if let Some(v) = self.compliant_contact_view(r, i, dt) {
                    if v.body != usize::MAX {
                        let f = [v.normal_force * v.normal[0], v.normal_force * v.normal[1]];
                        self.add_fruit_force(r, i, v.obstacle, v.body, f);
                    }
                    self.contact_out.push(v);
                }
                // A compliant contact's friction hold is reported with the contact above.
                if let Some(c) = self.work[r].contact[i].filter(|c| c.law.is_none()) {
                    let v = self.node_contact_view(r, i, &c, dt);
                    self.add_body_force(&v);
                    self.contact_out.push(v);
                }
            }
        }
        for r in 0..self.rods.len() {
            for j in 0..self.work[r].edges.len() {
                let v = self.edge_contact_view(r, j, dt);
                let e = self.work[r].edges[j];
                if let Some(l) = e.body {
                    // −F on the body at the contact point, as the step applied it (Gᵀ F with
                    // the lever the contact was linearised at).
                    let (o, f) = (&mut self.body_out[l.body], e.total_force());
                    o.force[0] -= f[0];
                    o.force[1] -= f[1];
                    o.torque -= l.lever[0] * f[1] - l.lever[1] * f[0];
                }
                self.contact_out.push(v);
            }
            for j in 0..self.work[r].pressings.len() {
                self.pressing_body_force(r, j);
                for k in 0..self.work[r].pressings[j].regions.len() {
                    let v = self.region_view(r, &self.work[r].pressings[j].regions[k], dt);
                    self.contact_out.push(v);
                }
            }
        }
        for bi in 0..self.bodies.len() {
            self.body_contact_views(bi, dt);
        }
        for v in &mut self.contact_out {
            v.tangent = [-v.normal[1], v.normal[0], 0.0];
        }
    }

    /// A rod's contact on a free body, into the body's net contact wrench: minus the force on
    /// the prong (normal and friction), at the contact point.
    fn add_body_force(&mut self, v: &ContactView) {
        let Some(o) = self.body_out.get_mut(v.body) else {
            return;
        };
        let t = [-v.normal[1], v.normal[0]];
        let f = [
            -(v.normal_force * v.normal[0] + v.friction_force * t[0]),
            -(v.normal_force * v.normal[1] + v.friction_force * t[1]),
        ];
        let c = self.bodies[v.body].pose.c;
        let lever = [v.point[0] - c[0], v.point[1] - c[1]];
        o.force[0] += f[0];
        o.force[1] += f[1];
        o.torque += lever[0] * f[1] - lever[1] * f[0];
    }

    /// Node (r, i)'s compliant contact with fruit `k` on free body `b`, into the body's net
    /// contact wrench as the step applied it: minus the fruit's force on the node (`normal`:
    /// the law's, through the fruit's centre — a circle's radial pressure has no moment) and
    /// minus the friction at the fruit's surface point the solver used.
    fn add_fruit_force(&mut self, r: usize, i: usize, k: usize, b: usize, normal: [f64; 2]) {
        let fr = self.node_friction(r, i, k, 0.0);
        let o = &mut self.body_out[b];
        o.force[0] -= normal[0];
        o.force[1] -= normal[1];
        if let Some((f, lever, _, _)) = fr {
            o.force[0] -= f[0];
            o.force[1] -= f[1];
            o.torque -= lever[0] * f[1] - lever[1] * f[0];
        }
    }

    /// Edge contact j of rod r: its point on the face, normal, the forces the step applied
    /// (shared by the segment's nodes) and its friction state.
    fn edge_contact_view(&self, r: usize, j: usize, dt: f64) -> ContactView {
        let w = &self.work[r];
        let e = w.edges[j];
        let p = e.point(&w.q);
        let off = self.rod_offset[r];
        // The held point's motion over the step relative to the surface.
        let mut slip = e.point(&w.dq);
        if let Some((b, g)) = e.as_node().body_columns() {
            let x = self.bodies[b].last_dx;
            for a in 0..2 {
                slip[a] -= g[0][a] * x[0] + g[1][a] * x[1] + g[2][a] * x[2];
            }
        }
        let t = e.tangent();
        let [rn, rt] = e.force;
        ContactView {
            rod: r,
            node: e.segment,
            obstacle: e.obstacle,
            body: e.body.map_or(usize::MAX, |l| l.body),
            point: v3([p[0] - off * e.normal[0], p[1] - off * e.normal[1]]),
            normal: v3(e.normal),
            normal_force: rn,
            friction_force: rt,
            slip_velocity: if dt > 0.0 {
                (t[0] * slip[0] + t[1] * slip[1]) / dt
            } else {
                0.0
            },
            stuck: e.is_stuck(),
            utilisation: if e.coulomb.mu_s > 0.0 && rn > 0.0 {
                rt.abs() / (e.coulomb.mu_s * rn)
            } else {
                0.0
            },
            mu_s: e.coulomb.mu_s,
            segment: e.segment,
            weight: e.weight,
            ..RIGID
        }
    }

    fn node_contact_view(
        &self,
        r: usize,
        i: usize,
        c: &contact::Constraint,
        dt: f64,
    ) -> ContactView {
        let w = &self.work[r];
        let reaction = [w.r[2 * i], w.r[2 * i + 1]];
        let (rn, rt) = friction::split(c, reaction);
        let mut slip = [w.dq[2 * i], w.dq[2 * i + 1]];
        if let Some((b, g)) = c.body_columns() {
            let x = self.bodies[b].last_dx;
            for a in 0..2 {
                slip[a] -= g[0][a] * x[0] + g[1][a] * x[1] + g[2][a] * x[2];
            }
        }
        let t = c.tangent();
        // The contact point is on the prong's face (its centreline at centreline contact).
        let off = self.rod_offset[r];
        ContactView {
            rod: r,
            node: i,
            obstacle: c.obstacle,
            body: c.body.map_or(usize::MAX, |l| l.body),
            point: [
                w.q[2 * i] - off * c.normal[0],
                w.q[2 * i + 1] - off * c.normal[1],
                0.0,
            ],
            normal: v3(c.normal),
            normal_force: rn,
            friction_force: rt,
            slip_velocity: if dt > 0.0 {
                (t[0] * slip[0] + t[1] * slip[1]) / dt
            } else {
                0.0
            },
            stuck: matches!(c.grip, Grip::Stick { .. }) || c.second.is_some(),
            utilisation: friction::utilisation(c, reaction),
            mu_s: c.coulomb.mu_s,
            ..RIGID
        }
    }

    /// Node (r, i)'s contact with a compliant fruit, if it presses into one: its force, the
    /// indentation, and the Hertz half-width and peak pressure of that force.
    fn compliant_contact_view(&self, r: usize, i: usize, dt: f64) -> Option<ContactView> {
        let w = &self.work[r];
        let p = w.pressed[i]?;
        let fruit = w.compliant.iter().find(|c| c.obstacle == p.obstacle)?;
        let law = fruit.law;
        let bruise = self.scenario.materials[p.obstacle]
            .as_ref()
            .map_or(0.0, |m| m.bruise_pressure);
        let off = self.rod_offset[r];
        let x = [w.q[2 * i], w.q[2 * i + 1]];
        let t = [-p.normal[1], p.normal[0]];
        let (friction, stuck, slip) = match self.node_friction(r, i, p.obstacle, dt) {
            Some((f, _, stuck, slip)) => (f[0] * t[0] + f[1] * t[1], stuck, slip),
            None => (0.0, false, 0.0),
        };
        let mu_s = fruit.coulomb.mu_s;
        Some(ContactView {
            rod: r,
            node: i,
            obstacle: p.obstacle,
            body: fruit.body.unwrap_or(usize::MAX),
            // The face's point, pressed δ into the fruit's undeformed surface.
            point: v3([x[0] - off * p.normal[0], x[1] - off * p.normal[1]]),
            normal: v3(p.normal),
            normal_force: p.force,
            friction_force: friction,
            slip_velocity: slip,
            stuck,
            utilisation: if mu_s > 0.0 && p.force > 0.0 {
                friction.abs() / (mu_s * p.force)
            } else {
                0.0
            },
            mu_s,
            indentation: p.indentation,
            half_width: law.half_width(p.force),
            peak_pressure: law.peak_pressure(p.force),
            bruise_pressure: bruise,
            bruise_half_width: law.width_above(p.force, bruise),
            ..RIGID
        })
    }

    /// Friction of compliant obstacle `k` on node (r, i) over the step just accepted: (the
    /// force on the node, the fruit's surface point about its centre the step applied it at,
    /// stuck, slip velocity along the fruit's tangent). Stuck: the hold's reaction along the
    /// surface; sliding: the kinetic force at the law's normal force.
    fn node_friction(
        &self,
        r: usize,
        i: usize,
        k: usize,
        dt: f64,
    ) -> Option<([f64; 2], [f64; 2], bool, f64)> {
        let w = &self.work[r];
        let fruit = w.compliant.iter().find(|c| c.obstacle == k)?;
        let x = [w.q[2 * i], w.q[2 * i + 1]];
        let d = [x[0] - fruit.center[0], x[1] - fruit.center[1]];
        let rho = d[0].hypot(d[1]);
        // Edge mode: the node's share of the arc acts along its own direction.
        let share = w
            .pressings
            .iter()
            .filter(|_| w.edge_mode)
            .find(|p| p.obstacle == k)
            .and_then(|p| p.node_share(i));
        let n = share.map_or([d[0] / rho, d[1] / rho], |s| s.normal);
        let surface = [fruit.law.r_fruit * n[0], fruit.law.r_fruit * n[1]];
        if let Some(c) = w.contact[i].filter(|c| c.law.is_some() && c.obstacle == k) {
            let h = c.normal;
            let rt = h[0] * w.r[2 * i] + h[1] * w.r[2 * i + 1];
            let lever = c.body.map_or(surface, |l| l.lever);
            return Some(([rt * h[0], rt * h[1]], lever, true, 0.0));
        }
        let s = w.law_slip[i].filter(|s| s.obstacle == k)?;
        let f = if w.edge_mode {
            let p = w.pressings.iter().find(|p| p.obstacle == k)?;
            super::edges::sliding(w, p, i)?.0
        } else {
            w.pressed[i]?.kinetic(fruit.coulomb.mu_k, s.sign).0
        };
        let mut dq = [w.dq[2 * i], w.dq[2 * i + 1]];
        if let (Some(b), true) = (fruit.body, dt > 0.0) {
            let x = self.bodies[b].last_dx;
            dq[0] -= x[0] - surface[1] * x[2];
            dq[1] -= x[1] + surface[0] * x[2];
        }
        let slip = if dt > 0.0 {
            (-n[1] * dq[0] + n[0] * dq[1]) / dt
        } else {
            0.0
        };
        Some((f, surface, false, slip))
    }

    /// A conforming compliant contact (edge mode): one connected contact arc, its resultant at
    /// the force's centre on the face, its deepest overlap, and the Hertz half-width and peak
    /// pressure of its load over the arc.
    /// A conforming contact on a free body (edge mode), into the body's net contact wrench:
    /// every node's share of the fruit's force and its friction.
    fn pressing_body_force(&mut self, r: usize, j: usize) {
        let w = &self.work[r];
        let p = &w.pressings[j];
        let Some(b) = w
            .compliant
            .iter()
            .find(|c| c.obstacle == p.obstacle)
            .and_then(|c| c.body)
        else {
            return;
        };
        let (k, first, len) = (p.obstacle, p.first, p.g.len());
        let forces: Vec<(usize, [f64; 2])> = (first..(first + len).min(self.rods[r].n))
            .map(|i| (i, p.node_force(i)))
            .collect();
        for (i, f) in forces {
            self.add_fruit_force(r, i, k, b, f);
        }
    }

    fn region_view(
        &self,
        r: usize,
        g: &crate::contact::conforming::Region,
        dt: f64,
    ) -> ContactView {
        let bruise = self.scenario.materials[g.obstacle]
            .as_ref()
            .map_or(0.0, |m| m.bruise_pressure);
        // Friction over the arc's nodes, along the arc's tangent: stuck when every node that
        // carries friction is held.
        let t = [-g.normal[1], g.normal[0]];
        let (mut friction, mut stuck, mut slip, mut any) = (0.0, true, 0.0f64, false);
        for i in g.first..=g.last.min(self.rods[r].n - 1) {
            if let Some((f, _, st, v)) = self.node_friction(r, i, g.obstacle, dt) {
                friction += f[0] * t[0] + f[1] * t[1];
                stuck &= st;
                if v.abs() > slip.abs() {
                    slip = v;
                }
                any = true;
            }
        }
        let fruit = self.work[r]
            .compliant
            .iter()
            .find(|c| c.obstacle == g.obstacle);
        let mu_s = fruit.map_or(0.0, |c| c.coulomb.mu_s);
        let x = crate::contact::edge::point(&self.work[r].q, g.segment, g.weight);
        let off = self.rod_offset[r];
        let above = if g.peak_pressure > bruise {
            g.half_width * (1.0 - (bruise / g.peak_pressure).powi(2)).sqrt()
        } else {
            0.0
        };
        ContactView {
            rod: r,
            node: g.segment,
            obstacle: g.obstacle,
            point: v3([x[0] - off * g.normal[0], x[1] - off * g.normal[1]]),
            normal: v3(g.normal),
            normal_force: g.resultant,
            body: fruit.and_then(|c| c.body).unwrap_or(usize::MAX),
            friction_force: friction,
            slip_velocity: slip,
            stuck: any && stuck,
            utilisation: if mu_s > 0.0 && g.resultant > 0.0 {
                friction.abs() / (mu_s * g.resultant)
            } else {
                0.0
            },
            mu_s,
            indentation: g.depth,
            half_width: g.half_width,
            peak_pressure: g.peak_pressure,
            bruise_pressure: bruise,
            bruise_half_width: above,
            segment: g.segment,
            weight: g.weight,
            first: g.first,
            last: g.last.min(self.rods[r].n - 1),
            ..RIGID
        }
    }

    fn body_contact_views(&mut self, bi: usize, dt: f64) {
        let b = &self.bodies[bi];
        for (j, c) in b.contacts.iter().enumerate() {
            let lam = b.reaction.get(j).copied().unwrap_or([0.0; 2]);
            let rt = match c.grip {
                Grip::Slide { sign } => -c.coulomb.mu_k * sign * lam[0],
                Grip::Stick { .. } => lam[1],
            };
            let t = c.tangent();
            let f = [
                lam[0] * c.normal[0] + rt * t[0],
                lam[0] * c.normal[1] + rt * t[1],
            ];
            let o = &mut self.body_out[bi];
            o.force[0] += f[0];
            o.force[1] += f[1];
            o.torque += c.lever[0] * f[1] - c.lever[1] * f[0];
            let slip = if dt > 0.0 {
                (crate::contact::body::dot3(&c.row(t), &b.last_dx) - c.stick_target) / dt
            } else {
                0.0
            };
            let (indentation, half_width, peak_pressure, bruise, above) = match c.law {
                Some(law) => {
                    let bruise = self.scenario.materials[b.spec.obstacle]
                        .as_ref()
                        .map_or(0.0, |m| m.bruise_pressure);
                    (
                        c.indentation(&b.last_dx),
                        law.half_width(lam[0]),
                        law.peak_pressure(lam[0]),
                        bruise,
                        law.width_above(lam[0], bruise),
                    )
                }
                None => (0.0, 0.0, 0.0, 0.0, 0.0),
            };
            self.contact_out.push(ContactView {
                rod: usize::MAX,
                node: bi,
                obstacle: c.obstacle,
                body: usize::MAX,
                point: v3([b.pose.c[0] + c.lever[0], b.pose.c[1] + c.lever[1]]),
                indentation,
                half_width,
                peak_pressure,
                bruise_pressure: bruise,
                bruise_half_width: above,
                normal: v3(c.normal),
                normal_force: lam[0],
                friction_force: rt,
                slip_velocity: slip,
                stuck: c.is_stuck(),
                utilisation: if c.coulomb.mu_s > 0.0 && lam[0] > 0.0 {
                    rt.abs() / (c.coulomb.mu_s * lam[0])
                } else {
                    0.0
                },
                mu_s: c.coulomb.mu_s,
                ..RIGID
            });
        }
    }
}

/// The fields of a rigid contact that a compliant one adds (and the defaults of the rest).
const RIGID: ContactView = ContactView::BLANK;

/// A free node's contact force at the end of a step: its eq. 2 reaction `r` when a constraint
/// (its own or an edge's) holds it (the residual keeps its own contact's part; its shares of
/// the edge contacts' forces are added back), plus a compliant fruit's force on it and its
/// share of a conforming compliant contact's nodal force (edge mode).
fn contact_force(
    w: &super::newton::RodWork,
    i: usize,
    constrained: bool,
    pressed: Option<crate::contact::compliant::Pressed>,
    r: [f64; 2],
    initial: bool,
) -> [f64; 2] {
    let edge = w.edges.iter().any(|e| e.touches(i));
    let mut g = if constrained || edge { r } else { [0.0; 2] };
    for e in w.edges.iter().filter(|e| e.touches(i) && !initial) {
        let f = e.node_force(i - e.segment);
        g[0] += f[0];
        g[1] += f[1];
    }
    if let Some(p) = pressed {
        g[0] += p.force * p.normal[0];
        g[1] += p.force * p.normal[1];
    }
    for p in w.pressings.iter().filter(|_| !initial) {
        let f = p.node_force(i);
        g[0] += f[0];
        g[1] += f[1];
    }
    g
}

/// What holds node `i` (normal, obstacle): a constraint, else an edge constraint (free nodes),
/// else a compliant fruit it presses into (itself or by an edge), else nothing.
fn held_by(
    w: &super::newton::RodWork,
    i: usize,
    c: Option<crate::contact::Constraint>,
    pressed: Option<crate::contact::compliant::Pressed>,
    clamped: bool,
    initial: bool,
) -> Option<([f64; 2], usize)> {
    if let Some(c) = c.filter(|_| !clamped) {
        return Some((c.normal, c.obstacle));
    }
    let edge = w
        .edges
        .iter()
        .find(|e| e.touches(i) && !initial && !clamped);
    edge.map(|e| (e.normal, e.obstacle))
        .or(pressed.map(|p| (p.normal, p.obstacle)))
        .or(w
            .pressings
            .iter()
            .flat_map(|p| &p.regions)
            .find(|g| !initial && g.first <= i && i <= g.last)
            .map(|g| (g.normal, g.obstacle)))
}

/// Node `i`'s contact impulse over the step, by the integrator's rule, and the history the
/// next BDF2 step's impulse builds on (`old`: the reaction at the step's start).
fn node_impulse(
    o: &mut super::RodOut,
    w: &super::newton::RodWork,
    i: usize,
    dt: f64,
    initial: bool,
    old: [f64; 2],
) {
    if w.bdf.second[i] && w.bdf.trap && dt > 0.0 && !initial {
        // TR-BDF2's trapezoidal stage: m (u₁ − u₀) = β (f₀ + R₀ + f₁ + R₁), so its
        // impulse is β (R₀ + R₁) (R₀: the last step's end reaction, `old`).
        for k in 2 * i..2 * i + 2 {
            o.impulse[k] = w.bdf.beta * (o.reaction[k] + old[k - 2 * i]);
        }
    } else if w.bdf.second[i] && dt > 0.0 {
        // BDF2's contact impulse: m (Δu_k − α Δu_{k−1}) = β (f + R) per step, so the
        // impulse J_k = β R + α J_{k−1} makes the impulses add up to the momentum
        // change (R dt does not), and it is ∫ R dt to second order.
        // The history's last interval is the last step's, or the step before a
        // sliver and the sliver together (`impulse_hist`).
        let b = &w.bdf;
        for k in 2 * i..2 * i + 2 {
            o.impulse[k] = b.beta * o.reaction[k] + b.alpha * o.impulse_hist[k];
        }
    } else {
        o.impulse[2 * i] = o.reaction[2 * i] * dt;
        o.impulse[2 * i + 1] = o.reaction[2 * i + 1] * dt;
    }
    for k in 2 * i..2 * i + 2 {
        o.impulse_hist[k] = if w.bdf.merged && !initial {
            o.impulse_hist[k] + o.impulse[k]
        } else {
            o.impulse[k]
        };
    }
}
