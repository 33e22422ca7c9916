use super::{norm, Proximity};

/// A rigid simple polygon (convex or not), vertices in either orientation.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Polygon {
    /// As given.
    pub vertices: Vec<[f64; 2]>,
    /// The same outline in a canonical order: counter-clockwise, starting at the
    /// lexicographically smallest vertex. Queries use it, so a polygon given clockwise or from
    /// another starting vertex answers bit for bit the same.
    #[serde(skip)]
    ring: Vec<[f64; 2]>,
    #[serde(skip)]
    centroid: [f64; 2],
    #[serde(skip)]
    bound_radius: f64,
}

fn cross(a: [f64; 2], b: [f64; 2]) -> f64 {
    a[0] * b[1] - a[1] * b[0]
}

/// Whether two segments cross or touch (an endpoint on the other segment, or a collinear
/// overlap, counts: either makes the outline non-simple).
fn segments_meet(p1: [f64; 2], p2: [f64; 2], q1: [f64; 2], q2: [f64; 2]) -> bool {
    let d = |a: [f64; 2], b: [f64; 2], c: [f64; 2]| {
        cross([b[0] - a[0], b[1] - a[1]], [c[0] - a[0], c[1] - a[1]])
    };
    // c on segment ab, given that a, b, c are collinear.
    let on = |a: [f64; 2], b: [f64; 2], c: [f64; 2]| {
        c[0] >= a[0].min(b[0])
            && c[0] <= a[0].max(b[0])
            && c[1] >= a[1].min(b[1])
            && c[1] <= a[1].max(b[1])
    };
    let (d1, d2, d3, d4) = (d(q1, q2, p1), d(q1, q2, p2), d(p1, p2, q1), d(p1, p2, q2));
    if ((d1 > 0.0 && d2 < 0.0) || (d1 < 0.0 && d2 > 0.0))
        && ((d3 > 0.0 && d4 < 0.0) || (d3 < 0.0 && d4 > 0.0))
    {
        return true;
    }
    (d1 == 0.0 && on(q1, q2, p1))
        || (d2 == 0.0 && on(q1, q2, p2))
        || (d3 == 0.0 && on(p1, p2, q1))
        || (d4 == 0.0 && on(p1, p2, q2))
}

/// The first pair (i, j), i < j, in lexicographic order, of non-adjacent edges that cross or
/// touch (edge i runs from vertex i to vertex i + 1). A sweep in x: edges sorted by their
/// left end, each tested only against the edges whose x and y ranges overlap its own, so a
/// 100 000-vertex outline is checked in milliseconds (it was every pair: 53 s). Outlines
/// whose edges nearly all overlap in both x and y (a dense zig-zag) still cost up to n²/2
/// tests. Also returns how many pairs were tested.
fn first_crossing(v: &[[f64; 2]]) -> (Option<(usize, usize)>, usize) {
    let n = v.len();
    let ends = |i: usize| (v[i], v[(i + 1) % n]);
    let range = |i: usize, k: usize| {
        let (a, b) = ends(i);
        (a[k].min(b[k]), a[k].max(b[k]))
    };
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by(|&a, &b| range(a, 0).0.total_cmp(&range(b, 0).0));
    let mut active: Vec<usize> = Vec::new();
    let mut best: Option<(usize, usize)> = None;
    let mut tested = 0;
    for &e in &order {
        let (x0, _) = range(e, 0);
        active.retain(|&a| range(a, 0).1 >= x0);
        let (y0, y1) = range(e, 1);
        for &a in &active {
            let (b0, b1) = range(a, 1);
            if b1 < y0 || b0 > y1 {
                continue;
            }
            let (i, j) = (a.min(e), a.max(e));
            if j == i + 1 || (i == 0 && j == n - 1) {
                continue;
            }
            if best.is_some_and(|b| b <= (i, j)) {
                continue;
            }
            let ((p1, p2), (q1, q2)) = (ends(i), ends(j));
            tested += 1;
            if segments_meet(p1, p2, q1, q2) {
                best = Some((i, j));
            }
        }
        active.push(e);
    }
    (best, tested)
}

impl Polygon {
    pub fn new(vertices: Vec<[f64; 2]>) -> Result<Self, String> {
        let n = vertices.len();
        if n < 3 {
            return Err(format!("{n} vertices (at least 3 are needed)"));
        }
        let mut area2 = 0.0;
        let mut size: f64 = 0.0;
        for i in 0..n {
            let (a, b) = (vertices[i], vertices[(i + 1) % n]);
            area2 += cross(a, b);
            let l = norm([b[0] - a[0], b[1] - a[1]]);
            if l == 0.0 {
                return Err(format!("vertices {i} and {} coincide", (i + 1) % n));
            }
            size = size.max(l);
        }
        if area2.abs() <= 1e-12 * size * size {
            return Err("zero area (the vertices are collinear)".into());
        }
        // Adjacent edges may only share their common vertex: an edge that doubles back along
        // the previous one is a zero-width spike.
        let fold = (0..n).find(|&i| {
            let (a, b, c) = (vertices[i], vertices[(i + 1) % n], vertices[(i + 2) % n]);
            let (e1, e2) = ([b[0] - a[0], b[1] - a[1]], [c[0] - b[0], c[1] - b[1]]);
            cross(e1, e2) == 0.0 && e1[0] * e2[0] + e1[1] * e2[1] < 0.0
        });
        let (crossing, _) = first_crossing(&vertices);
        // The first problem in edge order (a fold at edge i before a crossing of edge i).
        match (fold, crossing) {
            (Some(i), c) if c.is_none_or(|(ci, _)| i <= ci) => {
                return Err(format!(
                    "edges {i} and {} fold back onto each other at vertex {}",
                    (i + 1) % n,
                    (i + 1) % n
                ));
            }
            (_, Some((i, j))) => {
                return Err(format!(
                    "edges {i} and {j} cross or touch (the outline intersects itself)"
                ));
            }
            _ => {}
        }
        let mut ring = vertices.clone();
        if area2 < 0.0 {
            ring.reverse();
        }
        let first = (0..n)
            .min_by(|&i, &j| {
                ring[i][0]
                    .total_cmp(&ring[j][0])
                    .then(ring[i][1].total_cmp(&ring[j][1]))
            })
            .unwrap_or(0);
        ring.rotate_left(first);
        let centroid = [
            ring.iter().map(|v| v[0]).sum::<f64>() / n as f64,
            ring.iter().map(|v| v[1]).sum::<f64>() / n as f64,
        ];
        let bound_radius = ring
            .iter()
            .map(|v| norm([v[0] - centroid[0], v[1] - centroid[1]]))
            .fold(0.0, f64::max);
        Ok(Self {
            vertices,
            ring,
            centroid,
            bound_radius,
        })
    }

    pub fn lower_bound(&self, p: [f64; 2]) -> f64 {
        norm([p[0] - self.centroid[0], p[1] - self.centroid[1]]) - self.bound_radius
    }

    fn contains(&self, p: [f64; 2]) -> bool {
        let mut inside = false;
        let n = self.ring.len();
        let mut j = n - 1;
        for i in 0..n {
            let (a, b) = (self.ring[i], self.ring[j]);
            if (a[1] > p[1]) != (b[1] > p[1])
                && p[0] < (b[0] - a[0]) * (p[1] - a[1]) / (b[1] - a[1]) + a[0]
            {
                inside = !inside;
            }
            j = i;
        }
        inside
    }

    pub fn query(&self, p: [f64; 2]) -> Proximity {
        let n = self.ring.len();
        let mut best = (f64::INFINITY, [0.0; 2], 0usize);
        for i in 0..n {
            let (a, b) = (self.ring[i], self.ring[(i + 1) % n]);
            let e = [b[0] - a[0], b[1] - a[1]];
            let t = (((p[0] - a[0]) * e[0] + (p[1] - a[1]) * e[1]) / (e[0] * e[0] + e[1] * e[1]))
                .clamp(0.0, 1.0);
            let c = [a[0] + t * e[0], a[1] + t * e[1]];
            let d2 = (p[0] - c[0]).powi(2) + (p[1] - c[1]).powi(2);
            if d2 < best.0 {
                best = (d2, c, i);
            }
        }
        let (d2, c, i) = best;
        let dist = d2.sqrt();
        let inside = self.contains(p);
        let (a, b) = (self.ring[i], self.ring[(i + 1) % n]);
        let e = [b[0] - a[0], b[1] - a[1]];
        let el = norm(e);
        // Outward normal of the closest edge (right of the edge: the ring is counter-clockwise).
        let edge_n = [e[1] / el, -e[0] / el];
        let normal = if dist > 1e-12 * (1.0 + el) {
            let s = if inside { -1.0 } else { 1.0 };
            [s * (p[0] - c[0]) / dist, s * (p[1] - c[1]) / dist]
        } else {
            edge_n
        };
        Proximity {
            distance: if inside { -dist } else { dist },
            closest: c,
            normal,
        }
    }

    pub fn outline(&self) -> Vec<[f64; 2]> {
        let mut v = self.vertices.clone();
        v.push(self.vertices[0]);
        v
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every pair, as the check was before (the reference).
    fn brute_force(v: &[[f64; 2]]) -> Option<(usize, usize)> {
        let n = v.len();
        for i in 0..n {
            for j in i + 1..n {
                if j == i + 1 || (i == 0 && j == n - 1) {
                    continue;
                }
                if segments_meet(v[i], v[(i + 1) % n], v[j], v[(j + 1) % n]) {
                    return Some((i, j));
                }
            }
        }
        None
    }

    #[test]
    fn the_sweep_finds_the_same_first_crossing_as_every_pair() {
        // Random outlines on a small integer grid (many touch, overlap, cross), by a fixed LCG.
        let mut seed: u64 = 0x2545_f491_4f6c_dd1d;
        let mut next = || {
            seed = seed
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            ((seed >> 33) % 7) as f64
        };
        let mut crossing = 0;
        for case in 0..3000 {
            let n = 3 + case % 9;
            let v: Vec<[f64; 2]> = (0..n).map(|_| [next(), next()]).collect();
            let want = brute_force(&v);
            crossing += usize::from(want.is_some());
            assert_eq!(first_crossing(&v).0, want, "{v:?}");
        }
        assert!(crossing > 1000, "{crossing} of the outlines cross");
    }

    #[test]
    fn a_100k_vertex_outline_is_checked_in_linear_work() {
        // A 100 000-gon with a zig-zag rim (radius alternating 1 and 0.999): simple. The old check tested every
        // pair, n²/2 = 5e9 segment tests (53 s); the sweep tests a few per edge.
        let n = 100_000;
        let v: Vec<[f64; 2]> = (0..n)
            .map(|i| {
                let a = i as f64 / n as f64 * std::f64::consts::TAU;
                let r = if i % 2 == 0 { 1.0 } else { 0.999 };
                [r * a.cos(), r * a.sin()]
            })
            .collect();
        let (found, tested) = first_crossing(&v);
        eprintln!("simple: {tested} segment tests");
        assert_eq!(found, None);
        assert!(tested < 20 * n, "{tested} segment tests for {n} edges");
        assert!(Polygon::new(v.clone()).is_ok());
        // The same outline with one vertex pulled across the far side crosses, and is found.
        let mut bad = v;
        bad[n / 2] = [1.5, 0.0];
        let (found, tested) = first_crossing(&bad);
        eprintln!("crossing: {found:?} after {tested} segment tests");
        assert!(found.is_some());
        assert!(tested < 20 * n, "{tested} segment tests for {n} edges");
    }
}
