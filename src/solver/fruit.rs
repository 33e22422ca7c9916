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
                    crate::contact::conforming::inside(x(i), x(i + 1), c.center, c.reach)
                        .is_some()
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
    /// The friction hold of rod `r`'s node at `p` (its place at the start of the step) on
    /// compliant obstacle `k`, with the fruit's normal there.
    pub(super) fn law_hold_at(&self, r: usize, k: usize, p: [f64; 2]) -> Option<Constraint> {
        let c = self.work[r].compliant.iter().find(|c| c.obstacle == k)?;
        let d = [p[0] - c.center[0], p[1] - c.center[1]];
        let rho = d[0].hypot(d[1]);
        if rho == 0.0 || c.coulomb.mu_s == 0.0 {
            return None;
        }
        let n = [d[0] / rho, d[1] / rho];
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
        let x = [w.qn[2 * i], w.qn[2 * i + 1]];
        let force = if w.edge_mode {
            let p = w.pressings.iter().find(|p| p.obstacle == k)?;
            p.node_normal(i, x, c.center)?.0
        } else {
            c.press(x)?.force
        };
        Some((force, c.coulomb))
    }

    /// The compliant fruit node i presses into (with static friction), if any.
    fn law_pressed(&self, r: usize, i: usize) -> Option<usize> {
        let w = &self.work[r];
        if !w.edge_mode {
            return w.pressed[i].map(|p| p.obstacle);
        }
        let x = [w.qn[2 * i], w.qn[2 * i + 1]];
        w.pressings.iter().map(|p| p.obstacle).find(|&k| {
            w.compliant
                .iter()
                .find(|c| c.obstacle == k)
                .and_then(|c| w.pressings.iter().find(|p| p.obstacle == k)?.node_normal(i, x, c.center))
                .is_some()
        })
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
        let Some(mut hold) = self.law_hold_at(r, k, qk) else {
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
        if !ctx.dynamic {
            return 0.0;
        }
        let w = &self.work[r];
        let mut d = [w.dq[2 * i], w.dq[2 * i + 1]];
        if let Some((b, g)) = hold.body_columns() {
            let x = self.bodies[b].dx;
            for a in 0..2 {
                d[a] -= g[0][a] * x[0] + g[1][a] * x[1] + g[2][a] * x[2];
            }
        }
        let t = hold.normal;
        (t[0] * d[0] + t[1] * d[1]) / ctx.dt
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
