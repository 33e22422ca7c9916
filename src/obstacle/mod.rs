//! Rigid obstacles (the fruit, a table). One file per kind; each gives the signed distance of a
//! point (negative inside), the closest surface point and the outward unit normal there, plus a
//! cheap lower bound on the signed distance so far-away nodes cost nothing.

mod circle;
mod ellipse;
mod plane;
mod polygon;
mod sine;

pub use circle::Circle;
pub use ellipse::Ellipse;
pub use plane::Plane;
pub use polygon::Polygon;
pub use sine::Sine;

/// What an obstacle says about a point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Proximity {
    /// Signed distance (m): positive outside, negative inside.
    pub distance: f64,
    /// The closest point on the surface.
    pub closest: [f64; 2],
    /// Outward unit normal at the closest point.
    pub normal: [f64; 2],
}

/// Every obstacle kind, one enum arm each.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Obstacle {
    Circle(Circle),
    Plane(Plane),
    Sine(Sine),
    Ellipse(Ellipse),
    Polygon(Polygon),
}

impl Obstacle {
    /// Signed distance, closest point and outward normal.
    #[inline]
    pub fn query(&self, p: [f64; 2]) -> Proximity {
        match self {
            Obstacle::Circle(o) => o.query(p),
            Obstacle::Plane(o) => o.query(p),
            Obstacle::Sine(o) => o.query(p),
            Obstacle::Ellipse(o) => o.query(p),
            Obstacle::Polygon(o) => o.query(p),
        }
    }

    /// A lower bound on the signed distance that costs a few flops.
    #[inline]
    pub fn lower_bound(&self, p: [f64; 2]) -> f64 {
        match self {
            Obstacle::Circle(o) => o.query(p).distance,
            Obstacle::Plane(o) => o.query(p).distance,
            Obstacle::Sine(o) => o.lower_bound(p),
            Obstacle::Ellipse(o) => o.lower_bound(p),
            Obstacle::Polygon(o) => o.lower_bound(p),
        }
    }

    /// Whether [`Self::lower_bound`] is the signed distance itself (the same computation as
    /// [`Self::query`]'s).
    pub fn bound_is_distance(&self) -> bool {
        matches!(self, Obstacle::Circle(_) | Obstacle::Plane(_))
    }

    pub fn kind(&self) -> &'static str {
        match self {
            Obstacle::Circle(_) => "circle",
            Obstacle::Plane(_) => "plane",
            Obstacle::Sine(_) => "sine",
            Obstacle::Ellipse(_) => "ellipse",
            Obstacle::Polygon(_) => "polygon",
        }
    }

    /// A polyline of the surface for drawing, clipped to the box `[min, max]` where the surface
    /// is unbounded.
    pub fn outline(&self, min: [f64; 2], max: [f64; 2]) -> Vec<[f64; 2]> {
        match self {
            Obstacle::Circle(o) => o.outline(),
            Obstacle::Plane(o) => o.outline(min, max),
            Obstacle::Sine(o) => o.outline(min, max),
            Obstacle::Ellipse(o) => o.outline(),
            Obstacle::Polygon(o) => o.outline(),
        }
    }
}

#[inline]
pub(crate) fn norm(v: [f64; 2]) -> f64 {
    (v[0] * v[0] + v[1] * v[1]).sqrt()
}

/// The weight s ∈ [0, 1] of the point of a segment deepest into a surface, for the segment
/// contacts of both solvers: `at(s)` is the surface's answer at s and `distance` its signed
/// distance. A golden-section search of at most `iters` steps (to a bracket of 1e-13), exact
/// for a distance convex along the segment, a local minimum otherwise; then the two ends, which
/// win ties (a face the segment lies flat on is the nodes' business).
pub fn deepest_along<P>(
    at: impl Fn(f64) -> P,
    distance: impl Fn(&P) -> f64,
    iters: usize,
) -> (f64, P) {
    const INV_PHI: f64 = 0.618_033_988_749_894_9;
    let (mut lo, mut hi) = (0.0f64, 1.0f64);
    let mut x1 = hi - INV_PHI * (hi - lo);
    let mut x2 = lo + INV_PHI * (hi - lo);
    let (mut f1, mut f2) = (distance(&at(x1)), distance(&at(x2)));
    for _ in 0..iters {
        if f1 <= f2 {
            hi = x2;
            x2 = x1;
            f2 = f1;
            x1 = hi - INV_PHI * (hi - lo);
            f1 = distance(&at(x1));
        } else {
            lo = x1;
            x1 = x2;
            f1 = f2;
            x2 = lo + INV_PHI * (hi - lo);
            f2 = distance(&at(x2));
        }
        if hi - lo < 1e-13 {
            break;
        }
    }
    let mid = 0.5 * (lo + hi);
    let mut best = (mid, at(mid));
    for s in [0.0, 1.0] {
        let q = at(s);
        if distance(&q) <= distance(&best.1) {
            best = (s, q);
        }
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;

    /// For every kind: the normal is a unit vector, closest + distance·normal = p, and the
    /// distance's gradient (finite differences) is the normal.
    fn check(o: &Obstacle, pts: &[[f64; 2]]) {
        for &p in pts {
            let q = o.query(p);
            assert!(
                (norm(q.normal) - 1.0).abs() < 1e-12,
                "{o:?} {p:?} normal {:?}",
                q.normal
            );
            let r = [
                q.closest[0] + q.distance * q.normal[0],
                q.closest[1] + q.distance * q.normal[1],
            ];
            assert!(
                (r[0] - p[0]).abs() < 1e-9 && (r[1] - p[1]).abs() < 1e-9,
                "{o:?} {p:?}: {q:?}"
            );
            assert!(o.lower_bound(p) <= q.distance + 1e-12, "{o:?} {p:?} bound");
            if o.bound_is_distance() {
                // `contact::gap` then takes the bound for the distance.
                assert_eq!(
                    o.lower_bound(p).to_bits(),
                    q.distance.to_bits(),
                    "{o:?} {p:?}"
                );
            }
            let h = 1e-7;
            let gx = (o.query([p[0] + h, p[1]]).distance - o.query([p[0] - h, p[1]]).distance)
                / (2.0 * h);
            let gy = (o.query([p[0], p[1] + h]).distance - o.query([p[0], p[1] - h]).distance)
                / (2.0 * h);
            assert!(
                (gx - q.normal[0]).abs() < 1e-5 && (gy - q.normal[1]).abs() < 1e-5,
                "{o:?} {p:?}: grad ({gx},{gy}) vs {:?}",
                q.normal
            );
        }
    }

    fn grid(c: [f64; 2], s: f64) -> Vec<[f64; 2]> {
        let mut v = Vec::new();
        for i in 0..9 {
            for j in 0..9 {
                v.push([
                    c[0] + s * (i as f64 - 4.1) / 4.0,
                    c[1] + s * (j as f64 - 3.9) / 4.0,
                ]);
            }
        }
        v
    }

    #[test]
    fn circle_consistent() {
        check(
            &Obstacle::Circle(Circle::new([-0.05, -0.05], 0.05)),
            &grid([-0.05, -0.05], 0.09),
        );
    }

    #[test]
    fn plane_consistent() {
        let n = [0.6, 0.8];
        check(
            &Obstacle::Plane(Plane::new([0.1, 0.2], n)),
            &grid([0.0, 0.0], 1.0),
        );
    }

    #[test]
    fn ellipse_consistent() {
        let e = Obstacle::Ellipse(Ellipse::new([0.01, -0.02], 0.05, 0.03, 0.4));
        // Points away from the medial axis (where the closest point is not unique).
        let pts: Vec<[f64; 2]> = grid([0.01, -0.02], 0.1)
            .into_iter()
            .filter(|p| {
                let q = e.query(*p);
                q.distance > -0.02
            })
            .collect();
        check(&e, &pts);
    }

    #[test]
    fn sine_consistent_and_normal_formula() {
        let (a, k, c) = (0.02, 20.0, -0.01);
        let s = Obstacle::Sine(Sine::new(a, k, c));
        let pts: Vec<[f64; 2]> = (0..40)
            .map(|i| {
                [
                    i as f64 * 0.013 - 0.2,
                    c + a * (i as f64 * 0.013 * k).sin() + 0.004 * ((i % 5) as f64 - 2.0),
                ]
            })
            .collect();
        check(&s, &pts);
        // On the surface, the normal is (−A k cos kx, 1)/√(1 + (A k cos kx)²).
        for i in 0..50 {
            let x = -0.3 + 0.0123 * i as f64;
            let p = [x, a * (k * x).sin() + c];
            let q = s.query(p);
            let d = a * k * (k * x).cos();
            let n = [-d / (1.0 + d * d).sqrt(), 1.0 / (1.0 + d * d).sqrt()];
            assert!(q.distance.abs() < 1e-12);
            assert!(
                (q.normal[0] - n[0]).abs() < 1e-12 && (q.normal[1] - n[1]).abs() < 1e-12,
                "x={x}: {:?} vs {n:?}",
                q.normal
            );
        }
    }

    #[test]
    fn polygon_consistent() {
        let p = Obstacle::Polygon(
            Polygon::new(vec![
                [0.0, 0.0],
                [0.1, 0.0],
                [0.12, 0.05],
                [0.05, 0.09],
                [-0.01, 0.05],
            ])
            .unwrap(),
        );
        let pts: Vec<[f64; 2]> = grid([0.05, 0.04], 0.2)
            .into_iter()
            .filter(|q| p.query(*q).distance > -0.01)
            .collect();
        check(&p, &pts);
        // Clockwise input gives the same answers.
        let cw = Obstacle::Polygon(
            Polygon::new(vec![
                [-0.01, 0.05],
                [0.05, 0.09],
                [0.12, 0.05],
                [0.1, 0.0],
                [0.0, 0.0],
            ])
            .unwrap(),
        );
        for q in &pts {
            let (a, b) = (p.query(*q).distance, cw.query(*q).distance);
            assert!((a - b).abs() < 1e-15, "{a} vs {b}");
        }
    }

    #[test]
    fn polygon_rejects_degenerate() {
        assert!(Polygon::new(vec![[0.0, 0.0], [1.0, 0.0]]).is_err());
        assert!(Polygon::new(vec![[0.0, 0.0], [1.0, 0.0], [2.0, 0.0]]).is_err());
        assert!(Polygon::new(vec![[0.0, 0.0], [1.0, 1.0], [1.0, 0.0], [0.0, 1.0]]).is_err());
        // An edge doubling back along the previous one.
        assert!(Polygon::new(vec![[0.0, 0.0], [2.0, 0.0], [1.0, 0.0], [1.0, 1.0]]).is_err());
        // A vertex touching a non-adjacent edge.
        assert!(Polygon::new(vec![
            [0.0, 0.0],
            [4.0, 0.0],
            [4.0, 4.0],
            [2.0, 0.0],
            [0.0, 4.0]
        ])
        .is_err());
        // A straight angle (collinear neighbours going on) is fine.
        assert!(Polygon::new(vec![[0.0, 0.0], [1.0, 0.0], [2.0, 0.0], [1.0, 1.0]]).is_ok());
    }
}
