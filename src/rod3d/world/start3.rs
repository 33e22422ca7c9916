//! What may not overlap at t = 0 (issue 34 item 10): a rod's node (its face, with the
//! thickness offset towards the surface) inside a fixed obstacle or a free body, and a free
//! body inside a fixed obstacle (deeper than a compliant body rests under its weight). The
//! first step would throw either out with an impulse the
//! scenario never meant (a sphere started inside a table flew to z = +47.7 m in 0.02 s).

use super::World3;
use crate::obstacle3::V3;
use crate::rod3d::rod::pos;

/// The first overlap found at the start, with its depth (m).
#[derive(Debug, Clone, PartialEq)]
pub enum Overlap3 {
    /// Node `node` of rod `rod` starts `depth` inside `surface` (a fixed obstacle's index, or
    /// a body's when `body`); `face`: with the thickness offset.
    Node {
        rod: usize,
        node: usize,
        body: bool,
        surface: usize,
        depth: f64,
        at: [f64; 3],
        face: bool,
    },
    /// A point of free body `body` starts `depth` inside fixed obstacle `obstacle`.
    Body {
        body: usize,
        obstacle: usize,
        depth: f64,
        at: [f64; 3],
    },
}

impl World3 {
    /// The first overlap of the world as it is (at t = 0), if any. Touching is allowed: a
    /// depth up to 1e-9 × the size of the thing inside (round-off of a point placed on a
    /// surface) is not an overlap.
    pub fn start_overlap(&self) -> Option<Overlap3> {
        self.node_overlap().or_else(|| self.body_overlap())
    }

    fn node_overlap(&self) -> Option<Overlap3> {
        for (r, sim) in self.rods.iter().enumerate() {
            let tol = 1e-9 * sim.rod.length.max(1e-300);
            for i in 0..sim.rod.n {
                let x = V3::new(sim.q[pos(i)], sim.q[pos(i) + 1], sim.q[pos(i) + 2]);
                let fixed = self.obstacles.iter().map(|o| (false, o));
                let bodies = self.bodies.iter().map(|b| (true, &b.obstacle));
                for (k, (body, o)) in fixed.chain(bodies).enumerate() {
                    let p = o.query(&x);
                    let off = self.offset(r, i, &p.normal);
                    let depth = off - p.distance;
                    if depth > tol || !depth.is_finite() {
                        let surface = if body { k - self.obstacles.len() } else { k };
                        return Some(Overlap3::Node {
                            rod: r,
                            node: i,
                            body,
                            surface,
                            depth,
                            at: x.into(),
                            face: off > 0.0,
                        });
                    }
                }
            }
        }
        None
    }

    /// How deep a compliant body rests in fixed obstacle `k` under its own weight (the Hertz
    /// approach at m g along the obstacle's normal, m, with 1 % for a depth written rounded;
    /// 0 for a rigid body): a fruit may start at rest on its table, as it would lie there,
    /// not only touching it.
    fn rest_indentation(&self, b: usize, k: usize, p: &V3, n: &V3) -> f64 {
        let weight = self.bodies[b].mass * (-self.gravity.dot(n)).max(0.0);
        self.table_law(b, k, p, n)
            .map_or(0.0, |law| law.approach(weight) * 1.01)
    }

    /// A free body's deepest point along each fixed obstacle's normal at its centre (the
    /// points the body's contacts use: a sphere's and an ellipsoid's support point, a box's
    /// corners, a mesh's vertices).
    fn body_overlap(&self) -> Option<Overlap3> {
        for (b, body) in self.bodies.iter().enumerate() {
            let (c, rot) = (body.centre(), body.obstacle.pose.rotation);
            let size = body.obstacle.shape.lower_bound(&V3::zeros()).abs();
            for (k, o) in self.obstacles.iter().enumerate() {
                let inside = o.query(&c);
                let n = inside.normal;
                let mut points = body.obstacle.shape.support_points(&(rot.inverse() * -n));
                points.push(V3::zeros());
                for p in points {
                    let pw = c + rot * p;
                    let depth = -o.query(&pw).distance;
                    if depth > 1e-9 * size + self.rest_indentation(b, k, &pw, &n)
                        || !depth.is_finite()
                    {
                        return Some(Overlap3::Body {
                            body: b,
                            obstacle: k,
                            depth,
                            at: pw.into(),
                        });
                    }
                }
            }
        }
        None
    }
}
