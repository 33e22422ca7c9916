//! A free body's own contacts with fixed obstacles (a fruit resting on a table or sitting on a
//! fixed support): the body's boundary points deepest into the obstacle, and the constraints
//! on the body's displacement ΔX = (Δc, Δθ) that hold them on the surface.
//!
//! Contact points: a circle's is exact against any obstacle (its centre's closest point, one
//! radius in); an ellipse's is its support point, iterated with the obstacle's normal (exact
//! against a plane); a polygon's are its vertices (exact against a plane; against a curved
//! obstacle an edge touching it between vertices is not seen).

use super::constraint::Grip;
use super::friction::Coulomb;
use crate::obstacle::{Obstacle, Proximity};
use crate::world::body::{rotate, Placed};

/// A contact between a free body and a fixed obstacle, linearised at some body pose.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BodyContact {
    pub obstacle: usize,
    /// Which point of the body: the vertex index of a polygon, 0 otherwise.
    pub feature: usize,
    pub normal: [f64; 2],
    /// The contact point's lever from the centroid (world frame).
    pub lever: [f64; 2],
    /// a·ΔX = target holds the point on the surface (a = Gᵀ n).
    pub target: f64,
    /// b·ΔX = stick_target keeps the point where it was at the start of the step along the
    /// tangent (b = Gᵀ t); b·ΔX − stick_target is the slip over the step.
    pub stick_target: f64,
    pub grip: Grip,
    pub coulomb: Coulomb,
    pub locked: bool,
    pub switches: u8,
    /// A compliant fruit on the obstacle: its normal force is the law's F(δ) of the point's
    /// indentation δ = target − a·ΔX, not a constraint's multiplier (None: rigid).
    pub law: Option<super::compliant::LineContact>,
}

impl BodyContact {
    #[inline]
    pub fn tangent(&self) -> [f64; 2] {
        [-self.normal[1], self.normal[0]]
    }
    /// Gᵀ d for a direction d: the generalised direction of a force along d at the point.
    #[inline]
    pub fn row(&self, d: [f64; 2]) -> [f64; 3] {
        let r = self.lever;
        [d[0], d[1], r[0] * d[1] - r[1] * d[0]]
    }
    #[inline]
    pub fn is_stuck(&self) -> bool {
        matches!(self.grip, Grip::Stick { .. })
    }
    /// A compliant contact's indentation at body displacement `dx` (m, > 0 pressed).
    #[inline]
    pub fn indentation(&self, dx: &[f64; 3]) -> f64 {
        self.target - dot3(&self.row(self.normal), dx)
    }
    /// A compliant contact's normal force and its stiffness dF/dδ at `dx` ((0, 0) for a rigid one).
    #[inline]
    pub fn law_force(&self, dx: &[f64; 3]) -> (f64, f64) {
        match self.law {
            Some(l) => l.force(self.indentation(dx)),
            None => (0.0, 0.0),
        }
    }
}

#[inline]
pub fn dot3(a: &[f64; 3], b: &[f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// The body points (feature, world point, the obstacle's answer there) that are within
/// `below` of the fixed obstacle `o`.
pub fn points(
    body: &Placed,
    o: &Obstacle,
    below: f64,
    out: &mut Vec<(usize, [f64; 2], Proximity)>,
) {
    out.clear();
    match body.shape {
        Obstacle::Polygon(p) => {
            for (i, v) in p.vertices.iter().enumerate() {
                let w = body.to_world(*v);
                let q = o.query(w);
                if q.distance < below {
                    out.push((i, w, q));
                }
            }
        }
        _ => {
            if let Some((w, q)) = support_contact(body, o) {
                if q.distance < below {
                    out.push((0, w, q));
                }
            }
        }
    }
}

/// The world point of `feature` of the body (for re-linearising a carried contact).
pub fn feature_point(body: &Placed, o: &Obstacle, feature: usize) -> Option<([f64; 2], Proximity)> {
    match body.shape {
        Obstacle::Polygon(p) => {
            let w = body.to_world(*p.vertices.get(feature)?);
            Some((w, o.query(w)))
        }
        _ => support_contact(body, o),
    }
}

/// The deepest point of a circle or ellipse body towards obstacle `o`.
fn support_contact(body: &Placed, o: &Obstacle) -> Option<([f64; 2], Proximity)> {
    let c = body.pose.c;
    let mut n = o.query(c).normal;
    let mut best = None;
    for _ in 0..20 {
        let w = support(body, [-n[0], -n[1]])?;
        let q = o.query(w);
        let done = (q.normal[0] - n[0]).abs() + (q.normal[1] - n[1]).abs() < 1e-14;
        n = q.normal;
        best = Some((w, q));
        if done {
            break;
        }
    }
    best
}

/// The boundary point of a circle or ellipse body furthest along direction `d`.
fn support(body: &Placed, d: [f64; 2]) -> Option<[f64; 2]> {
    let c = body.pose.c;
    match body.shape {
        Obstacle::Circle(s) => Some([c[0] + s.radius * d[0], c[1] + s.radius * d[1]]),
        Obstacle::Ellipse(e) => {
            // In the ellipse's own axes the support point of (u, v) is (a² u, b² v)/√(a²u² + b²v²).
            let phi = e.angle + body.pose.theta;
            let l = rotate(d, -phi);
            let s = ((e.a * l[0]).powi(2) + (e.b * l[1]).powi(2)).sqrt();
            let p = rotate([e.a * e.a * l[0] / s, e.b * e.b * l[1] / s], phi);
            Some([c[0] + p[0], c[1] + p[1]])
        }
        _ => None,
    }
}

/// A body contact linearised at the current trial displacement `dx` (pose `body.pose`), for
/// the point `w` answered by `q`; `w0` is the same body point at the start of the step.
pub fn linearise(
    obstacle: usize,
    feature: usize,
    body: &Placed,
    w: [f64; 2],
    w0: [f64; 2],
    q: &Proximity,
    dx: &[f64; 3],
) -> BodyContact {
    let n = q.normal;
    let lever = [w[0] - body.pose.c[0], w[1] - body.pose.c[1]];
    let mut c = BodyContact {
        obstacle,
        feature,
        normal: n,
        lever,
        target: 0.0,
        stick_target: 0.0,
        grip: Grip::Slide { sign: 0.0 },
        coulomb: Coulomb::FRICTIONLESS,
        locked: false,
        switches: 0,
        law: None,
    };
    let (a, b, t) = (c.row(n), c.row(c.tangent()), c.tangent());
    c.target = n[0] * (q.closest[0] - w[0]) + n[1] * (q.closest[1] - w[1]) + dot3(&a, dx);
    c.stick_target = t[0] * (w0[0] - w[0]) + t[1] * (w0[1] - w[1]) + dot3(&b, dx);
    c
}
