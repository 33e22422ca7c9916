//! Static mode with obstacles: a load increment may not step through an obstacle.
//!
//! A load increment is solved like a dynamic step (predictor, then corrector passes that
//! update the constraint sets) with three differences, all here:
//!
//! - **New contacts enter in the order their chords meet the obstacle.** Each free point (a
//!   node; with `[contact] points = "edges"` also a segment, whose points move on the bilinear
//!   sweep of its two nodes' chords) is followed along its chord from the increment's start to
//!   the pass's solution. Where that chord first meets an obstacle moving inwards is found by
//!   conservative advancement: a point at signed distance d moved by less than d cannot have
//!   reached the surface (distances are 1-Lipschitz), and no point of a segment moves further
//!   than its faster node. Once the held contacts have settled, of the points that ended
//!   inside, the one whose chord entered first enters the constraint set (one per pass: what
//!   it holds decides where the others go), and Newton starts again from the increment's
//!   start. It is held where its chord entered — not at the surface point nearest its end,
//!   which for a deep end can be the obstacle's far side — unless it may merely have rolled
//!   over the surface ([`rolling`]), where the nearest point is the better guess.
//! - **A chord that went through an obstacle and ended outside it cuts the increment**
//!   (`StepError::Split`; `run_static` halves it) — deeper than rolling over the surface
//!   could take it ([`rolling`]) —, as does a contact released as adhesive and locked when it
//!   entered again in the same increment that still pulls at the end.
//! - **Held contacts follow the surface:** a node or an edge contact is re-linearised where
//!   the solution puts it whenever it is off its surface by more than 1e-10 L either way (a
//!   dynamic step re-linearises only points that went inside), and an edge contact also when
//!   its closest point moved along the segment by more than that; so the equilibrium found
//!   holds every contact on the surface, not on a tangent line.

use super::step::StepCtx;
use super::{Simulation, StepError};
use crate::contact::edge;
use crate::contact::{friction, Surfaces};
use crate::events::{Event, Observer};
use crate::obstacle::Proximity;

/// Conservative advancement gives up on a chord after this many steps (a chord that grazes
/// the surface for its whole length).
const MAX_SWEEP: usize = 4096;

/// A point within this fraction of the rod's length of the surface touches it.
const TOUCH: f64 = 1e-9;

/// Samples of a chord's depth after its entry, for the crossing test.
const DEPTH_SAMPLES: usize = 32;

impl Simulation {
    /// Static mode, after a pass has updated the held contacts: of the free points of each
    /// rod that ended inside an obstacle, the one whose chord entered first is held where it
    /// entered. Returns how many rods changed.
    pub(super) fn static_entries<O: Observer>(
        &mut self,
        ctx: &StepCtx,
        pass: u32,
        obs: &mut O,
    ) -> u32 {
        let mut changed = 0;
        for r in 0..self.rods.len() {
            let Some(t) = self.first_entry(r) else {
                continue;
            };
            match t.weight {
                None => self.hold_node(ctx, pass, r, &t, obs),
                Some(s) => {
                    let mut e = self.edge_on(r, t.node, t.obstacle, s, &t.prox);
                    let w = &mut self.work[r];
                    e.locked = w.edge_released.contains(&(t.node, t.obstacle));
                    w.edges.push(e);
                    w.mark_edge_nodes();
                }
            }
            // Newton starts again from the increment's start, where every point is outside
            // and the new contact near where it entered (not from the solution that went
            // through the obstacle).
            self.work[r].dq.fill(0.0);
            self.dirty[r] = true;
            changed += 1;
        }
        changed
    }

    fn hold_node<O: Observer>(
        &mut self,
        ctx: &StepCtx,
        pass: u32,
        r: usize,
        t: &Entry,
        obs: &mut O,
    ) {
        let i = t.node;
        let mut c = self.constraint_on(r, t.obstacle, &t.prox);
        let w = &self.work[r];
        c.locked = w.was_released(i);
        c.grip = friction::initial_grip(&c, [w.q[2 * i], w.q[2 * i + 1]]);
        let mut ev = self.change(ctx, pass, r, i, t.obstacle, c.normal);
        ev.gap = t.prox.distance;
        ev.reaction = [0.0; 3];
        self.work[r].contact[i] = Some(c);
        obs.on_event(&Event::ConstraintAdded(ev));
    }

    /// Of rod `r`'s free nodes and (edge mode) segments that end inside a fixed obstacle, the
    /// one whose chord entered it first, with where it entered (its end state when it started
    /// inside).
    fn first_entry(&self, r: usize) -> Option<Entry> {
        let rod = &self.rods[r];
        let w = &self.work[r];
        let s = self.rod_surfaces(r);
        let eps = TOUCH * rod.length;
        let fixed = |k: usize| self.body_of[k] == usize::MAX;
        let mut best: Option<Entry> = None;
        let mut offer = |t: Entry| {
            if best.is_none_or(|b| t.theta < b.theta) {
                best = Some(t);
            }
        };
        for i in (0..rod.n).filter(|&i| !rod.clamped[i] && w.contact[i].is_none()) {
            let (p0, p1) = ([w.q[2 * i], w.q[2 * i + 1]], [w.qn[2 * i], w.qn[2 * i + 1]]);
            for k in (0..s.len()).filter(|&k| fixed(k) && s.lower_bound(k, p1) < 0.0) {
                let end = s.query(k, p1);
                if end.distance >= 0.0 {
                    continue;
                }
                let travel = (p1[0] - p0[0]).hypot(p1[1] - p0[1]);
                let rolls = rolling(s.query(k, p0).distance, end.distance, travel);
                let (theta, prox) = match node_entry(&s, k, p0, p1, eps) {
                    Some((th, _)) if rolls => (th, end),
                    Some(at) => at,
                    None => (0.0, end),
                };
                offer(Entry {
                    theta,
                    obstacle: k,
                    node: i,
                    weight: None,
                    prox,
                });
            }
        }
        if self.edges_on(r) {
            for (i, k, wt, end) in self.edge_candidates(r, &w.edges, &[]) {
                let ends = segment_ends(&w.q, &w.qn, i);
                let start = segment_at(&s, k, ends, 0.0).1.distance;
                let rolls = rolling(start, end.distance, sweep_speed(ends));
                let (theta, weight, prox) = match segment_entry(&s, k, ends, eps) {
                    Some((th, we, q)) if !rolls && edge::interior(we) => (th, we, q),
                    Some((th, _, _)) => (th, wt, end),
                    None => (0.0, wt, end),
                };
                offer(Entry {
                    theta,
                    obstacle: k,
                    node: i,
                    weight: Some(weight),
                    prox,
                });
            }
        }
        best
    }

    /// Static mode, after a pass: rod `r`'s edge contacts follow the closest point of their
    /// segment (returns whether any moved). Re-linearising at the closest point is a
    /// fixed-point iteration on the contact's weight w ↦ F(w) that can overshoot for a heavily
    /// loaded segment (a small turn of the segment moves its closest point R/Δl times as far)
    /// and cycle; from the second move on, a contact takes the secant step on F(w) − w from
    /// its last two, which converges where the plain iteration cycles. A closest point at one
    /// of the segment's nodes keeps the contact at the interior weight next to it (released
    /// when the next segment or node takes over), so that the rod does not fall through the
    /// obstacle in the pass between them.
    pub(super) fn follow_edges(&mut self, r: usize) -> bool {
        let tol = 1e-10 * self.rods[r].length;
        let mut history = std::mem::take(&mut self.edge_history);
        let s = self.rod_surfaces(r);
        let q = &self.work[r].qn;
        let mut out = self.work[r].edges.clone();
        let mut changed = false;
        for e in out.iter_mut() {
            let (a, b) = (
                edge::point(q, e.segment, 0.0),
                edge::point(q, e.segment, 1.0),
            );
            let (wt, prox) = edge::closest_on_segment(&s, e.obstacle, a, b);
            let g = wt - e.weight;
            if prox.distance.abs() <= tol && g.abs() * (b[0] - a[0]).hypot(b[1] - a[1]) <= tol {
                continue;
            }
            let key = (r, e.segment, e.obstacle);
            let last = history.iter().position(|h| (h.0, h.1, h.2) == key);
            let mut w = wt;
            if let Some(j) = last {
                let (w0, g0) = (history[j].3, history[j].4);
                let slope = (g - g0) / (e.weight - w0);
                if slope.is_finite() && slope < -1e-3 {
                    w = e.weight - g / slope;
                }
                history[j] = (r, e.segment, e.obstacle, e.weight, g);
            } else {
                history.push((r, e.segment, e.obstacle, e.weight, g));
            }
            let w = w.clamp(2.0 * edge::END, 1.0 - 2.0 * edge::END);
            let prox = s.query(e.obstacle, edge::point(q, e.segment, w));
            let ne = self.carried_edge(r, e, w, &prox, false);
            changed |= ne != *e;
            *e = ne;
        }
        self.edge_history = history;
        if changed {
            self.work[r].edges = out;
        }
        changed
    }

    /// Static mode, once an increment's contact set has settled: cut the increment when a
    /// free point's chord went through a fixed obstacle, or a locked contact still pulls.
    pub(super) fn static_settled(&mut self, ctx: &StepCtx) -> Result<(), StepError> {
        for r in 0..self.rods.len() {
            if let Some((theta, node)) = self.crossing(r).or_else(|| self.locked_pull(ctx, r)) {
                self.rollback();
                return Err(StepError::Split {
                    theta,
                    rod: r,
                    node,
                    release: false,
                });
            }
        }
        Ok(())
    }

    /// The first free node (or, in edge mode, free segment) of rod `r` whose chord went
    /// through a fixed obstacle and ended outside it: (where it entered, the node).
    fn crossing(&self, r: usize) -> Option<(f64, usize)> {
        let rod = &self.rods[r];
        let w = &self.work[r];
        let s = self.rod_surfaces(r);
        let eps = TOUCH * rod.length;
        let fixed = |k: usize| self.body_of[k] == usize::MAX;
        let free = |i: usize| !rod.clamped[i] && w.contact[i].is_none();
        for i in (0..rod.n).filter(|&i| free(i)) {
            let (p0, p1) = ([w.q[2 * i], w.q[2 * i + 1]], [w.qn[2 * i], w.qn[2 * i + 1]]);
            for k in (0..s.len()).filter(|&k| fixed(k)) {
                if let Some(theta) = node_crossing(&s, k, p0, p1, eps) {
                    return Some((theta, i));
                }
            }
        }
        if !self.edges_on(r) {
            return None;
        }
        for i in (0..rod.n - 1).filter(|&i| free(i) && free(i + 1)) {
            let ends = segment_ends(&w.q, &w.qn, i);
            for k in (0..s.len()).filter(|&k| fixed(k)) {
                let held = w.edges.iter().any(|e| e.segment == i && e.obstacle == k);
                if let Some(theta) = segment_crossing(&s, k, ends, eps).filter(|_| !held) {
                    return Some((theta, i));
                }
            }
        }
        None
    }

    /// A contact of rod `r` locked in this increment (released, then entered again) that
    /// pulls at the settled solution: (1, its node).
    fn locked_pull(&self, ctx: &StepCtx, r: usize) -> Option<(f64, usize)> {
        let w = &self.work[r];
        let tol = ctx.opt.force_tol * w.force_scale;
        for (i, c) in w.contact.iter().enumerate() {
            let Some(c) = c.filter(|c| c.locked) else {
                continue;
            };
            let (rn, rn2) = crate::contact::normal_parts(&c, [w.r[2 * i], w.r[2 * i + 1]]);
            if rn < -tol || rn2 < -tol {
                return Some((1.0, i));
            }
        }
        let pulls = |j: usize| w.edges[j].force[0] < -tol;
        let e = (0..w.edges.len()).find(|&j| w.edges[j].locked && pulls(j))?;
        Some((1.0, w.edges[e].segment))
    }
}

/// A point of a rod that ended inside an obstacle, and where its chord entered it.
#[derive(Debug, Clone, Copy)]
struct Entry {
    /// Fraction of the chord (0 = the increment's start, 1 = the pass's solution).
    theta: f64,
    obstacle: usize,
    /// The node, or a segment's first node.
    node: usize,
    /// None: the node itself; Some(s): segment `node` at weight s.
    weight: Option<f64>,
    prox: Proximity,
}

/// Whether a point that moved by `travel` over the increment from signed distance `start` to
/// `end` may have rolled over the obstacle: both ends within `travel`/8 of its surface. Its
/// chord then dips below a convex surface of radius ≥ `travel` by up to `travel`/8 without
/// the point having gone through it, and a point that ends inside is held at the surface
/// point nearest its end. A point that came from further, or went in deeper, is held where
/// its chord entered (the surface point nearest a deep end can be the obstacle's far side),
/// and a chord of it that dipped in at all went through.
fn rolling(start: f64, end: f64, travel: f64) -> bool {
    start.abs().max(end.abs()) <= travel / 8.0
}

/// The largest distance a node of a segment's sweep moves.
fn sweep_speed(ends: [[f64; 2]; 4]) -> f64 {
    let [a0, b0, a1, b1] = ends;
    (a1[0] - a0[0])
        .hypot(a1[1] - a0[1])
        .max((b1[0] - b0[0]).hypot(b1[1] - b0[1]))
}

/// Segment i's two nodes at the increment's start and in the pass's solution: [a₀, b₀, a₁, b₁].
fn segment_ends(q: &[f64], qn: &[f64], i: usize) -> [[f64; 2]; 4] {
    let at = |x: &[f64], j: usize| [x[2 * j], x[2 * j + 1]];
    [at(q, i), at(q, i + 1), at(qn, i), at(qn, i + 1)]
}

/// Conservative advancement along a chord θ ∈ [0, 1] whose points move by at most `speed`
/// over it: the first θ where the point `at(θ)` (answer, and its velocity along the normal
/// there) is within `eps` of the surface moving inwards.
fn advance<T>(
    at: impl Fn(f64) -> (Proximity, f64, T),
    speed: f64,
    eps: f64,
) -> Option<(f64, Proximity, T)> {
    if !(speed > 0.0) {
        return None;
    }
    let mut th = 0.0;
    for _ in 0..MAX_SWEEP {
        let (q, vn, extra) = at(th);
        if q.distance < eps && vn < 0.0 {
            return Some((th, q, extra));
        }
        th += q.distance.abs().max(eps) / speed;
        if th >= 1.0 {
            return None;
        }
    }
    None
}

/// Where a node moving on the chord p₀ → p₁ first touches obstacle `k` moving inwards.
fn node_entry(
    s: &Surfaces,
    k: usize,
    p0: [f64; 2],
    p1: [f64; 2],
    eps: f64,
) -> Option<(f64, Proximity)> {
    let d = [p1[0] - p0[0], p1[1] - p0[1]];
    let speed = d[0].hypot(d[1]);
    if s.lower_bound(k, p0) > speed + eps {
        return None;
    }
    let at = |th: f64| {
        let q = s.query(k, [p0[0] + th * d[0], p0[1] + th * d[1]]);
        (q, d[0] * q.normal[0] + d[1] * q.normal[1], ())
    };
    advance(at, speed, eps).map(|(th, q, ())| (th, q))
}

/// Where a segment whose ends move on the chords a₀ → a₁ and b₀ → b₁ (`ends` = [a₀, b₀, a₁,
/// b₁]) first touches obstacle `k` moving inwards: (θ, weight, the obstacle's answer there).
fn segment_entry(
    s: &Surfaces,
    k: usize,
    ends: [[f64; 2]; 4],
    eps: f64,
) -> Option<(f64, f64, Proximity)> {
    let [a0, b0, a1, b1] = ends;
    let da = [a1[0] - a0[0], a1[1] - a0[1]];
    let db = [b1[0] - b0[0], b1[1] - b0[1]];
    let speed = sweep_speed(ends);
    if edge::lower_bound(s, k, a0, b0) > speed + eps {
        return None;
    }
    let at = |th: f64| {
        let (w, q) = segment_at(s, k, ends, th);
        let v = [(1.0 - w) * da[0] + w * db[0], (1.0 - w) * da[1] + w * db[1]];
        (q, v[0] * q.normal[0] + v[1] * q.normal[1], w)
    };
    advance(at, speed, eps).map(|(th, q, w)| (th, w, q))
}

/// The segment of the sweep at θ: its point closest to (deepest into) obstacle `k`.
fn segment_at(s: &Surfaces, k: usize, ends: [[f64; 2]; 4], th: f64) -> (f64, Proximity) {
    let [a0, b0, a1, b1] = ends;
    let lerp = |p: [f64; 2], q: [f64; 2]| [p[0] + th * (q[0] - p[0]), p[1] + th * (q[1] - p[1])];
    edge::closest_on_segment(s, k, lerp(a0, a1), lerp(b0, b1))
}

/// Whether a chord that entered at `theta`, from signed distance `start` to `end` (outside),
/// went through the obstacle: deeper than `eps`, or than `travel`/8 when the point may have
/// rolled over it ([`rolling`]); `depth(θ)` is the signed distance along it (sampled).
fn went_through(theta: f64, travel: f64, eps: f64, depth: impl Fn(f64) -> f64) -> bool {
    let (start, end) = (depth(0.0), depth(1.0));
    if end < -eps {
        return false;
    }
    let allowed = if rolling(start, end, travel) {
        (travel / 8.0).max(eps)
    } else {
        eps
    };
    let at = |j: usize| theta + (1.0 - theta) * j as f64 / DEPTH_SAMPLES as f64;
    (1..DEPTH_SAMPLES).any(|j| depth(at(j)) < -allowed)
}

/// A node's chord p₀ → p₁ that went through obstacle `k` and ended outside it: where it
/// entered.
fn node_crossing(s: &Surfaces, k: usize, p0: [f64; 2], p1: [f64; 2], eps: f64) -> Option<f64> {
    let (theta, _) = node_entry(s, k, p0, p1, eps)?;
    let d = [p1[0] - p0[0], p1[1] - p0[1]];
    let depth = |th: f64| s.query(k, [p0[0] + th * d[0], p0[1] + th * d[1]]).distance;
    went_through(theta, d[0].hypot(d[1]), eps, depth).then_some(theta)
}

/// A segment's sweep that went through obstacle `k` and ended outside it: where it entered.
fn segment_crossing(s: &Surfaces, k: usize, ends: [[f64; 2]; 4], eps: f64) -> Option<f64> {
    let (theta, _, _) = segment_entry(s, k, ends, eps)?;
    let depth = |th: f64| segment_at(s, k, ends, th).1.distance;
    went_through(theta, sweep_speed(ends), eps, depth).then_some(theta)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::obstacle::{Circle, Obstacle};

    fn disc() -> Vec<Obstacle> {
        vec![Obstacle::Circle(Circle::new([0.0, 0.0], 0.01))]
    }

    #[test]
    fn a_node_carried_through_a_disc_enters_where_its_chord_does() {
        let obs = disc();
        let s = Surfaces::fixed(&obs);
        // From 2 cm above the centre to 2 cm below it: enters at the top after 1/4 of the
        // chord, and went through.
        let (p0, p1) = ([0.0, 0.02], [0.0, -0.02]);
        let (th, q) = node_entry(&s, 0, p0, p1, 1e-12).unwrap();
        assert!((th - 0.25).abs() < 1e-9, "{th}");
        assert!(q.normal[1] > 0.999_999, "{:?}", q.normal);
        assert!(node_crossing(&s, 0, p0, p1, 1e-12).is_some());
        // Ending 1 mm above the bottom: the end's nearest surface is the bottom, the entry the top.
        let (_, q) = node_entry(&s, 0, p0, [0.0, -0.009], 1e-12).unwrap();
        assert!(q.normal[1] > 0.999_999, "{:?}", q.normal);
        // Passing beside it, or leaving it: no touch.
        assert!(node_entry(&s, 0, [0.011, 0.02], [0.011, -0.02], 1e-12).is_none());
        assert!(node_entry(&s, 0, [0.0, 0.01], [0.0, 0.02], 1e-12).is_none());
        // From 1 µm above the surface at x = −1 mm to 1 µm above it at x = 1 mm (rolling over
        // the top): the chord dips 49 µm in, less than 1/8 of its length: not a crossing.
        let y = 0.01 * (1.0 - 0.01f64).sqrt() + 1e-6;
        let (a, b) = ([-0.001, y], [0.001, y]);
        assert!(node_entry(&s, 0, a, b, 1e-12).is_some());
        assert!(node_crossing(&s, 0, a, b, 1e-12).is_none());
    }

    #[test]
    fn a_segment_carried_across_a_disc_enters_at_its_interior() {
        let obs = disc();
        let s = Surfaces::fixed(&obs);
        // A horizontal segment, nodes at x = ±0.02, lowered from y = 0.02 to −0.02: the nodes
        // pass beside the disc, the segment's middle touches its top at θ = 1/4 and goes
        // through.
        let ends = [[-0.02, 0.02], [0.02, 0.02], [-0.02, -0.02], [0.02, -0.02]];
        let (th, w, q) = segment_entry(&s, 0, ends, 1e-12).unwrap();
        assert!(
            (th - 0.25).abs() < 1e-9 && (w - 0.5).abs() < 1e-12,
            "{th} {w}"
        );
        assert!(q.normal[1] > 0.999_999, "{:?}", q.normal);
        assert!(segment_crossing(&s, 0, ends, 1e-12).is_some());
        assert!(node_entry(&s, 0, ends[0], ends[2], 1e-12).is_none());
    }
}
