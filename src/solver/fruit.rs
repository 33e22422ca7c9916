//! Compliant fruits carried by free bodies, in the step: which rods press into one (they are
//! solved with the bodies, since the force depends on where the body is).

use super::step::StepCtx;
use super::Simulation;
use crate::contact::compliant::{LawSlip, LineContact};
use crate::contact::friction::{self, Coulomb, Switch};
use crate::contact::{self, BodyLink, Constraint, Grip};
use crate::events::{Event, FrictionChange, Observer};
use crate::obstacle::Obstacle;

impl Simulation {
    /// Whether rod `r` presses (at its current iterate) into a compliant fruit carried by a
    /// free body: node mode, a free node inside the fruit grown by the face offset; edge mode,
    /// a segment crossing it.
    pub(super) fn presses_body(&self, r: usize) -> bool {
        let rod = &self.rods[r];
        let w = &self.work[r];
        let x = |i: usize| [w.q[2 * i] + w.dq[2 * i], w.q[2 * i + 1] + w.dq[2 * i + 1]];
        w.compliant.iter().filter(|c| c.body.is_some()).any(|c| {
            if w.edge_mode {
                (0..rod.n.saturating_sub(1)).any(|i| {
                    crate::contact::conforming::inside(x(i), x(i + 1), c.center, c.reach).is_some()
                })
            } else {
                (0..rod.n).any(|i| !rod.clamped[i] && c.press(x(i)).is_some())
            }
        })
    }
}

impl Simulation {
    /// The law of body `bi`'s compliant fruit pressed on fixed obstacle `k` (None when the
    /// fruit is rigid): Hertz line contact of the fruit's radius against the obstacle's (a
    /// plane or any shape but a circle is flat here; a fixed circle adds its curvature), over
    /// the fruit's depth, with E* of the fruit's material and the obstacle's (rigid unless it
    /// has a material of its own).
    pub(super) fn body_law(&self, bi: usize, k: usize) -> Option<LineContact> {
        let b = &self.bodies[bi];
        let m = self.scenario.materials.get(b.spec.obstacle)?.as_ref()?;
        let Obstacle::Circle(fruit) = &self.obstacles[b.spec.obstacle] else {
            return None;
        };
        let r_other = match &self.obstacles[k] {
            Obstacle::Circle(c) => c.radius,
            _ => f64::INFINITY,
        };
        let other = self
            .scenario
            .materials
            .get(k)
            .and_then(|m| m.as_ref())
            .map_or(0.0, |m| m.compliance());
        Some(LineContact::new(
            fruit.radius,
            r_other,
            b.spec.depth,
            other,
            m,
        ))
    }
}

/// Coulomb friction at compliant contacts (node mode): the law's normal force F decides, as
/// the eq. 2 normal reaction does on a rigid surface. A node that presses into a fruit with
/// static friction is held along the surface (a [`LawHold`] constraint: its tangential
/// motion relative to the fruit is zero over the step) while the tangential reaction
/// |R_t| ≤ μ_s F; past it the hold is let go and the node slides with the kinetic force
/// −μ_k F s t inside Newton; a slide whose solved slip velocity turns round is held again.
impl Simulation {
    /// The friction hold of rod `r`'s node i at `p` (its place at the start of the step) on
    /// compliant obstacle `k`: along the fruit's surface at the node (node mode), or along the
    /// direction of the node's share of a conforming contact (edge mode: the part of the arc
    /// it carries).
    pub(super) fn law_hold_at(
        &self,
        r: usize,
        i: usize,
        k: usize,
        p: [f64; 2],
    ) -> Option<Constraint> {
        let w = &self.work[r];
        let c = w.compliant.iter().find(|c| c.obstacle == k)?;
        let d = [p[0] - c.center[0], p[1] - c.center[1]];
        let rho = d[0].hypot(d[1]);
        if rho == 0.0 || c.coulomb.mu_s == 0.0 {
            return None;
        }
        let share = w
            .pressings
            .iter()
            .filter(|_| w.edge_mode)
            .find(|p| p.obstacle == k)
            .and_then(|p| p.node_share(i));
        let n = share.map_or([d[0] / rho, d[1] / rho], |s| s.normal);
        let body = c.body.map(|b| BodyLink {
            body: b,
            lever: [c.law.r_fruit * n[0], c.law.r_fruit * n[1]],
        });
        Some(Constraint::law_hold(k, n, p, c.coulomb, body))
    }

    /// Node i's pressing into compliant obstacle `k` at its current iterate: the normal
    /// force friction is decided from (node mode: the law's F at the node; edge mode: the
    /// node's share of the conforming contact's force along the fruit's normal there) and the
    /// pair's coefficients.
    fn law_press(&self, r: usize, i: usize, k: usize) -> Option<(f64, Coulomb)> {
        let w = &self.work[r];
        let c = w.compliant.iter().find(|c| c.obstacle == k)?;
        let force = if w.edge_mode {
            let p = w.pressings.iter().find(|p| p.obstacle == k)?;
            p.node_share(i)?.force
        } else {
            c.press([w.qn[2 * i], w.qn[2 * i + 1]])?.force
        };
        Some((force, c.coulomb))
    }

    /// The compliant fruit node i presses into (with static friction), if any.
    fn law_pressed(&self, r: usize, i: usize) -> Option<usize> {
        let w = &self.work[r];
        if !w.edge_mode {
            return w.pressed[i].map(|p| p.obstacle);
        }
        w.pressings
            .iter()
            .find(|p| p.node_share(i).is_some())
            .map(|p| p.obstacle)
    }

    /// A node held by friction on a compliant fruit, after a pass: let go when it left the
    /// fruit or when a rigid surface now holds it; sliding when the tangential reaction is
    /// outside the cone of the law's normal force.
    pub(super) fn update_law_hold<O: Observer>(
        &mut self,
        ctx: &StepCtx,
        r: usize,
        i: usize,
        c: Constraint,
        pass: u32,
        obs: &mut O,
    ) -> bool {
        let Some((force, coulomb)) = self.law_press(r, i, c.obstacle) else {
            // Left the fruit: let go, and not held again in this step (a node at the edge
            // of a conforming arc, pressed and not by turns, would cycle).
            self.work[r].contact[i] = None;
            self.work[r].contact_saved_mark(i);
            return true;
        };
        let w = &self.work[r];
        let p = [w.qn[2 * i], w.qn[2 * i + 1]];
        if contact::deepest(&self.rod_surfaces(r), p, 0.0).is_some() {
            self.work[r].contact[i] = None;
            return true;
        }
        let rt = c.normal[0] * w.r[2 * i] + c.normal[1] * w.r[2 * i + 1];
        let grip = Grip::Stick { anchor: p };
        let Some(Switch::ToSlide { sign }) =
            friction::decide_on(coulomb, grip, c.switches, force, rt, 0.0)
        else {
            return false;
        };
        let w = &mut self.work[r];
        w.contact[i] = None;
        w.law_slip[i] = Some(LawSlip {
            obstacle: c.obstacle,
            sign,
            switches: c.switches + 1,
            weight: 1.0,
        });
        self.law_event(ctx, pass, r, i, c.obstacle, false, force, rt, 0.0, obs);
        true
    }

    /// A free node pressing into a compliant fruit with static friction, after a pass: held
    /// where it starts pressing; a sliding one held again when its slip turns round.
    pub(super) fn update_law_free<O: Observer>(
        &mut self,
        ctx: &StepCtx,
        r: usize,
        i: usize,
        pass: u32,
        obs: &mut O,
    ) -> bool {
        let w = &self.work[r];
        let (k, slip) = match (w.law_slip[i], self.law_pressed(r, i)) {
            (Some(s), _) => (s.obstacle, Some(s)),
            (None, Some(k)) => (k, None),
            (None, None) => return false,
        };
        let Some((force, coulomb)) = self.law_press(r, i, k) else {
            self.work[r].law_slip[i] = None;
            return false;
        };
        let qk = [w.q[2 * i], w.q[2 * i + 1]];
        if slip.is_none() && w.was_released(i) {
            return false;
        }
        let Some(mut hold) = self.law_hold_at(r, i, k, qk) else {
            return false;
        };
        if let Some(s) = slip {
            let v_t = self.law_slip_velocity(ctx, r, i, &hold);
            let grip = Grip::Slide { sign: s.sign };
            let rt = -coulomb.mu_k * force * s.sign;
            if friction::decide_on(coulomb, grip, s.switches, force, rt, v_t).is_none() {
                return false;
            }
            hold.switches = s.switches + 1;
            self.law_event(ctx, pass, r, i, k, true, force, rt, v_t, obs);
        }
        let w = &mut self.work[r];
        w.law_slip[i] = None;
        w.contact[i] = Some(hold);
        true
    }

    /// The node's slip velocity along the fruit's tangent relative to the fruit's surface
    /// (the hold's direction; its body's motion taken out).
    fn law_slip_velocity(&self, ctx: &StepCtx, r: usize, i: usize, hold: &Constraint) -> f64 {
        self.velocity_along(ctx, r, i, hold, hold.normal)
    }

    #[allow(clippy::too_many_arguments)]
    fn law_event<O: Observer>(
        &self,
        ctx: &StepCtx,
        pass: u32,
        r: usize,
        i: usize,
        k: usize,
        stuck: bool,
        normal_force: f64,
        tangential_force: f64,
        slip_velocity: f64,
        obs: &mut O,
    ) {
        obs.on_event(&Event::FrictionChanged(FrictionChange {
            step: ctx.step,
            t: ctx.t1,
            pass: pass + 1,
            rod: r,
            node: i,
            obstacle: k,
            stuck,
            normal_force,
            tangential_force,
            slip_velocity,
            segment: usize::MAX,
            weight: 0.0,
        }));
    }
}

/// Friction of a conforming contact (edge mode), decided per contact arc: an arc is one
/// contact, the Coulomb law of its resultant. A stuck arc holds each of its nodes along the
/// fruit's surface (the nodes' holds) while the tangential force of the holds, summed along the
/// arc's tangent, stays within μ_s times the arc's normal force (the sum of its nodes' shares
/// along the fruit's normal); past that every node of the arc slides, each with the kinetic
/// force of its share, and the arc is stuck again when its slip velocity (its nodes'
/// weighted by their shares) turns round. Per node, the stick forces would follow the rod's
/// axial stiffness, not the pressure, and the ends of the arc would slide first and let the
/// rest go at the kinetic coefficient: below μ_s ΣN.
impl Simulation {
    pub(super) fn update_law_arcs<O: Observer>(
        &mut self,
        ctx: &StepCtx,
        r: usize,
        pass: u32,
        obs: &mut O,
    ) -> bool {
        let mut changed = self.drop_law_nodes_outside(r);
        let arcs: Vec<(usize, usize, usize, [f64; 2])> = self.work[r]
            .pressings
            .iter()
            .flat_map(|p| {
                p.regions
                    .iter()
                    .map(|g| (g.obstacle, g.first, g.last, g.normal))
            })
            .collect();
        for (k, first, last, normal) in arcs {
            changed |= self.update_law_arc(ctx, r, k, first, last, normal, pass, obs);
        }
        changed
    }

    /// Holds and slides of nodes that no longer press into their fruit are let go.
    fn drop_law_nodes_outside(&mut self, r: usize) -> bool {
        let mut changed = false;
        for i in 0..self.rods[r].n {
            let k = match (self.work[r].contact[i], self.work[r].law_slip[i]) {
                (Some(c), _) if c.law.is_some() => c.obstacle,
                (_, Some(s)) => s.obstacle,
                _ => continue,
            };
            if self.law_press(r, i, k).is_none() {
                let w = &mut self.work[r];
                if w.contact[i].is_some_and(|c| c.law.is_some()) {
                    w.contact[i] = None;
                    changed = true;
                }
                w.law_slip[i] = None;
            }
        }
        changed
    }

    /// One arc (nodes first..=last on obstacle `k`, resultant along `normal`).
    #[allow(clippy::too_many_arguments)]
    fn update_law_arc<O: Observer>(
        &mut self,
        ctx: &StepCtx,
        r: usize,
        k: usize,
        first: usize,
        last: usize,
        normal: [f64; 2],
        pass: u32,
        obs: &mut O,
    ) -> bool {
        let t = [-normal[1], normal[0]];
        let nodes: Vec<(usize, f64)> = (first..=last.min(self.rods[r].n - 1))
            .filter(|&i| !self.rods[r].clamped[i])
            .filter(|&i| self.work[r].contact[i].is_none_or(|c| c.law.is_some()))
            .filter_map(|i| self.law_press(r, i, k).map(|(f, _)| (i, f)))
            .collect();
        let Some(coulomb) = self.work[r]
            .compliant
            .iter()
            .find(|c| c.obstacle == k)
            .map(|c| c.coulomb)
            .filter(|c| c.mu_s > 0.0)
        else {
            return false;
        };
        let w = &self.work[r];
        let slide = nodes
            .iter()
            .find_map(|&(i, _)| w.law_slip[i].filter(|s| s.obstacle == k));
        let switches = nodes
            .iter()
            .map(|&(i, _)| match (w.contact[i], w.law_slip[i]) {
                (Some(c), _) => c.switches,
                (_, Some(s)) => s.switches,
                _ => 0,
            })
            .max()
            .unwrap_or(0);
        let n_sum: f64 = nodes.iter().map(|&(_, f)| f).sum();
        let (grip, rt, v_t) = self.arc_tangent(ctx, r, k, &nodes, t, coulomb, slide, n_sum);
        let switch = friction::decide_on(coulomb, grip, switches, n_sum, rt, v_t);
        let stuck = match (switch, slide) {
            (Some(Switch::ToSlide { sign }), _) => Err(sign),
            (Some(Switch::ToStick), _) => Ok(()),
            (None, Some(s)) => Err(s.sign),
            (None, None) => Ok(()),
        };
        if let (Some(_), Some(&(i, _))) = (switch, nodes.first()) {
            self.law_event(ctx, pass, r, i, k, stuck.is_ok(), n_sum, rt, v_t, obs);
        }
        let sw = switches + u8::from(switch.is_some());
        let weights = self.arc_weights(r, k, &nodes, t, rt, n_sum);
        self.set_arc(r, k, &nodes, &weights, stuck, sw)
    }

    /// An arc's grip, tangential resultant R_t along `t` and slip velocity: when it slides,
    /// μ_k ΣN against its slip and its nodes' slip velocity weighted by the kinetic force each
    /// carries; when it sticks, the holds' tangential reactions summed.
    #[allow(clippy::too_many_arguments)]
    fn arc_tangent(
        &self,
        ctx: &StepCtx,
        r: usize,
        k: usize,
        nodes: &[(usize, f64)],
        t: [f64; 2],
        coulomb: friction::Coulomb,
        slide: Option<LawSlip>,
        n_sum: f64,
    ) -> (Grip, f64, f64) {
        let w = &self.work[r];
        match slide {
            Some(s) => {
                // The arc's slip velocity: its nodes' by the parts of the kinetic force they
                // carry.
                let (mut v, mut wsum) = (0.0, 0.0);
                for &(i, _) in nodes {
                    let Some(sl) = w.law_slip[i].filter(|s| s.obstacle == k) else {
                        continue;
                    };
                    if let Some(h) = self.law_hold_at(r, i, k, [w.q[2 * i], w.q[2 * i + 1]]) {
                        v += sl.weight * self.law_slip_velocity(ctx, r, i, &h);
                        wsum += sl.weight;
                    }
                }
                let v = if wsum != 0.0 { v / wsum } else { 0.0 };
                (
                    Grip::Slide { sign: s.sign },
                    -coulomb.mu_k * n_sum * s.sign,
                    v,
                )
            }
            None => {
                let mut rt = 0.0;
                for &(i, _) in nodes {
                    if let Some(c) = w.contact[i] {
                        let f = c.normal[0] * w.r[2 * i] + c.normal[1] * w.r[2 * i + 1];
                        rt += f * (c.normal[0] * t[0] + c.normal[1] * t[1]);
                    }
                }
                (Grip::Stick { anchor: [0.0; 2] }, rt, 0.0)
            }
        }
    }

    /// How an arc's kinetic force is shared among its nodes: as the holds shared the friction
    /// when the arc let go (a share by pressure instead would shift force along the prong in
    /// one step and move its nodes by their own elasticity, which reads as a reversed slip).
    fn arc_weights(
        &self,
        r: usize,
        k: usize,
        nodes: &[(usize, f64)],
        t: [f64; 2],
        rt: f64,
        n_sum: f64,
    ) -> Vec<f64> {
        let w = &self.work[r];
        nodes
            .iter()
            .map(|&(i, f)| match (w.contact[i], w.law_slip[i]) {
                (Some(c), _) if c.law.is_some() && rt != 0.0 => {
                    let fi = c.normal[0] * w.r[2 * i] + c.normal[1] * w.r[2 * i + 1];
                    fi * (c.normal[0] * t[0] + c.normal[1] * t[1]) / rt
                }
                (_, Some(s)) if s.obstacle == k => s.weight,
                _ if rt == 0.0 && n_sum > 0.0 => f / n_sum,
                _ => 0.0,
            })
            .collect()
    }

    /// Every node of an arc held (`Ok`) or sliding in direction `Err(sign)`; returns whether
    /// any node changed.
    fn set_arc(
        &mut self,
        r: usize,
        k: usize,
        nodes: &[(usize, f64)],
        weights: &[f64],
        stuck: Result<(), f64>,
        switches: u8,
    ) -> bool {
        let mut changed = false;
        for (&(i, _), &weight) in nodes.iter().zip(weights) {
            let w = &self.work[r];
            let held = w.contact[i].is_some_and(|c| c.law.is_some() && c.obstacle == k);
            match stuck {
                Ok(()) if !held => {
                    let qk = [w.q[2 * i], w.q[2 * i + 1]];
                    let Some(mut h) = self.law_hold_at(r, i, k, qk) else {
                        continue;
                    };
                    h.switches = switches;
                    let w = &mut self.work[r];
                    w.contact[i] = Some(h);
                    w.law_slip[i] = None;
                    changed = true;
                }
                Ok(()) => {
                    if let Some(c) = self.work[r].contact[i].as_mut() {
                        c.switches = switches;
                    }
                }
                Err(sign) => {
                    let w = &mut self.work[r];
                    let slip = Some(LawSlip {
                        obstacle: k,
                        sign,
                        switches,
                        weight,
                    });
                    changed |= held || w.law_slip[i].map(|s| s.sign) != Some(sign);
                    if held {
                        w.contact[i] = None;
                    }
                    w.law_slip[i] = slip;
                }
            }
        }
        changed
    }
}
