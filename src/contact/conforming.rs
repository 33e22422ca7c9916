//! A conforming compliant contact (`[contact] points = "edges"`): the fruit's pressure is
//! distributed along the prong and integrated over the contact arc, so the force converges as
//! nodes are added even where a soft prong wraps the fruit.
//!
//! The prong's polyline (its face grown into the centreline by the contact offset) overlaps the
//! undeformed fruit, a circle of radius ρ₀ (fruit radius + offset), by g(s) = ρ₀ − |x(s) − c| > 0
//! over one or more arcs. The law (docs/model.md):
//!
//! - **Distribution: an elastic foundation** (Johnson, *Contact Mechanics*, 1985, §5.8, the
//!   Winkler model): the pressure at a point of the arc is proportional to the local overlap,
//!   p(s) = (F / (b A)) g(s), with A = ∫ g ds the overlap area over all the rod's arcs on this
//!   fruit. The nodal forces are the shape-function integrals of p b n over the arcs,
//!   f_j = (F / A) ∫ N_j g n ds (Gauss quadrature on each segment's part inside the circle).
//! - **Resultant: the Hertz line-contact law of the displaced area.** F = F_H(δ_e) with F_H the
//!   law of [`LineContact`] (Hertz's half-width, Johnson's approach of the fruit's centre) and δ_e
//!   the indentation at which a straight face would overlap the same area A (a circular
//!   segment of depth δ_e). For a narrow contact of a straight face δ_e is its depth and F is
//!   the Hertz law exactly; when the arc is long against the straight contact's chord
//!   2 √(2 ρ₀ δ) (a prong wrapping the fruit) the force grows with the displaced area rather than
//!   with the depth of its deepest point. A is a smooth function of the nodes wherever the arcs
//!   fall, so F is too: no contact count that depends on the discretisation.
//!
//! What the designer reads is one contact per connected arc (a region): its share of the force
//! F A_r / A, its deepest overlap, and the Hertz half-width and peak pressure of that force
//! spread over the arc in Hertz's proportion — a = a_H(F_r) ℓ_r / (2 c(F_r)), p₀ = 2 F_r / (π a b),
//! with ℓ_r the arc's length and 2 c(F_r) the chord of a straight contact carrying F_r: exactly
//! Hertz's a and p₀ for a narrow contact, a wider contact and a lower peak for a conforming one.

use super::compliant::{CompliantCircle, LineContact};

/// Gauss–Legendre points and weights on [0, 1] (four points: exact for degree 7).
const GAUSS: [(f64, f64); 4] = [
    (0.069_431_844_202_973_71, 0.173_927_422_568_726_93),
    (0.330_009_478_207_571_87, 0.326_072_577_431_273_07),
    (0.669_990_521_792_428_1, 0.326_072_577_431_273_07),
    (0.930_568_155_797_026_3, 0.173_927_422_568_726_93),
];

/// The overlap area of a straight face at depth δ in a circle of radius ρ₀: ∫ (ρ₀ − |x − c|) ds
/// along the line's chord, ρ₀ c − d² asinh(c/d) with d = ρ₀ − δ and c = √(ρ₀² − d²) (a series
/// in u = c/d for a shallow line, where the closed form cancels), and its derivative
/// dA/dδ = 2 d asinh(c/d). Depths are kept in [0, 0.9 ρ₀].
pub fn line_area(rho0: f64, delta: f64) -> (f64, f64) {
    let dl = delta.clamp(0.0, 0.9 * rho0);
    let d = rho0 - dl;
    let c = (dl * (2.0 * rho0 - dl)).sqrt();
    let u = c / d;
    // asinh(c/d) = ln((c + ρ₀)/d), as c² + d² = ρ₀²: one log, no hypot.
    let ash = ((dl + c) / d).ln_1p();
    let a = if u < 0.1 {
        // A / d² = 2 ∫₀ᵘ t² (1 + t²)^(−1/2) dt.
        let u2 = u * u;
        2.0 * d
            * d
            * u
            * u2
            * (1.0 / 3.0
                - u2 * (1.0 / 10.0
                    - u2 * (3.0 / 56.0
                        - u2 * (5.0 / 144.0 - u2 * (35.0 / 1408.0 - u2 * 63.0 / 3328.0)))))
    } else {
        rho0 * c - d * d * ash
    };
    (a, 2.0 * d * ash)
}

/// The chord 2 √(2 ρ₀ δ − δ²): the length of a straight face at depth δ inside the circle.
pub fn chord(rho0: f64, delta: f64) -> f64 {
    2.0 * (delta * (2.0 * rho0 - delta)).max(0.0).sqrt()
}

/// The depth δ of a straight face whose overlap area is `area` (to round-off).
pub fn line_depth(rho0: f64, area: f64) -> f64 {
    if area <= 0.0 {
        return 0.0;
    }
    let top = 0.9 * rho0;
    if area >= line_area(rho0, top).0 {
        return top;
    }
    // A ≈ (4/3) √(2 ρ₀) δ^{3/2} for a shallow line; then Newton, kept in [δ/2, 2δ].
    let mut d = (0.75 * area / (2.0 * rho0).sqrt()).powf(2.0 / 3.0).min(top);
    for _ in 0..60 {
        let (a, da) = line_area(rho0, d);
        if da <= 0.0 {
            break;
        }
        let next = (d - (a - area) / da).clamp(0.5 * d, (2.0 * d).min(top));
        let done = (next - d).abs() <= 1e-15 * d;
        d = next;
        if done {
            break;
        }
    }
    d
}

/// The resultant F (N) of overlap area A (m²) on a fruit of grown radius ρ₀, dF/dA, and the
/// equivalent indentation δ_e.
pub fn resultant(law: &LineContact, rho0: f64, area: f64) -> (f64, f64, f64) {
    let de = line_depth(rho0, area);
    let (f, k) = law.force(de);
    let da = line_area(rho0, de).1;
    let dfa = if da > 0.0 { k / da } else { 0.0 };
    (f, dfa, de)
}

/// The part [ξ₀, ξ₁] of segment a–b (as fractions of it) inside the circle of radius ρ₀ about
/// c, if any.
pub fn inside(a: [f64; 2], b: [f64; 2], c: [f64; 2], rho0: f64) -> Option<(f64, f64)> {
    let e = [b[0] - a[0], b[1] - a[1]];
    let d = [a[0] - c[0], a[1] - c[1]];
    let qa = e[0] * e[0] + e[1] * e[1];
    let qb = 2.0 * (d[0] * e[0] + d[1] * e[1]);
    let qc = d[0] * d[0] + d[1] * d[1] - rho0 * rho0;
    if qa == 0.0 {
        return None;
    }
    let disc = qb * qb - 4.0 * qa * qc;
    if disc <= 0.0 {
        return None;
    }
    let t = -0.5 * (qb + qb.signum() * disc.sqrt());
    let (r1, r2) = if t == 0.0 {
        let h = (-qc / qa).sqrt();
        (-h, h)
    } else {
        (t / qa, qc / t)
    };
    let lo = r1.min(r2).max(0.0);
    let hi = r1.max(r2).min(1.0);
    (hi > lo).then_some((lo, hi))
}

/// One connected contact arc: what the designer reads as "a contact".
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Region {
    pub obstacle: usize,
    /// The first and last node of its segments.
    pub first: usize,
    pub last: usize,
    /// Its overlap area ∫ g ds (m²), largest overlap (m) and arc length (m).
    pub area: f64,
    pub depth: f64,
    pub length: f64,
    /// Its share of the law's load, F A_r / A (N): ∫ p b ds over the arc, which the pressure
    /// figures are of.
    pub force: f64,
    /// The magnitude of its resultant, |∫ p n b ds| (N): the force it presses the fruit with
    /// (below `force` by the fan of the normals over the arc, O(a²/R²) for a narrow contact).
    pub resultant: f64,
    /// The force's centre along the polyline (segment, weight) and its direction (the
    /// normalised ∫ g n ds).
    pub segment: usize,
    pub weight: f64,
    pub normal: [f64; 2],
    /// Hertz's half-width (m) and peak pressure (Pa) of the force spread over the arc.
    pub half_width: f64,
    pub peak_pressure: f64,
}

/// A node's share of a conforming contact, as a contact of its own ([`Pressing::node_share`]):
/// the force F_n along n, ∂F_n/∂x (`dforce`) and ∂t/∂x = −n `dturn`ᵀ for t = (−n_y, n_x).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Share {
    pub force: f64,
    pub normal: [f64; 2],
    pub dforce: [f64; 2],
    pub dturn: [f64; 2],
}

/// A rod pressing into one fruit: the resultant, the regions, and what the Newton system needs.
#[derive(Debug, Clone, PartialEq)]
pub struct Pressing {
    pub obstacle: usize,
    /// Overlap area A (m²), resultant F (N), dF/dA and the equivalent indentation δ_e (m).
    pub area: f64,
    pub force: f64,
    pub dforce: f64,
    pub equivalent: f64,
    /// Nodes first..first + g.len() carry the force.
    pub first: usize,
    /// Per node j: G_j = ∫ N_j g n ds and h_j = ∂A/∂x_j.
    pub g: Vec<[f64; 2]>,
    pub h: Vec<[f64; 2]>,
    /// Per node j, for k = j − 1, j, j + 1: ∂G_j/∂x_k (row-major 2 × 2; zero off the span).
    pub dg: Vec<[[[f64; 2]; 2]; 3]>,
    pub regions: Vec<Region>,
}

impl Pressing {
    /// The fruit's force on node `j` (N): (F / A) G_j.
    pub fn node_force(&self, j: usize) -> [f64; 2] {
        match j.checked_sub(self.first).and_then(|k| self.g.get(k)) {
            Some(g) => {
                let s = self.force / self.area;
                [s * g[0], s * g[1]]
            }
            None => [0.0; 2],
        }
    }

    /// ∂f_j/∂x_k of the banded part, (F / A) ∂G_j/∂x_k, for |j − k| ≤ 1 (2 × 2).
    pub fn band_block(&self, j: usize, k: usize) -> [[f64; 2]; 2] {
        let s = self.force / self.area;
        let (Some(jj), Some(o)) = (j.checked_sub(self.first), (k + 1).checked_sub(j)) else {
            return [[0.0; 2]; 2];
        };
        match self.dg.get(jj).and_then(|d| d.get(o)) {
            Some(m) => [[s * m[0][0], s * m[0][1]], [s * m[1][0], s * m[1][1]]],
            None => [[0.0; 2]; 2],
        }
    }

    /// Node j's share of the fruit's force as a contact of its own: F_n = |f_j| along its
    /// direction n_j = f_j / |f_j| (the pressure-weighted normal of the part of the arc the
    /// node carries, not the fruit's normal at the node, which for a node off the fruit can
    /// lean far from it), with ∂F_n/∂x_j = B nⱼ and ∂n_j/∂x_j = t_j (Bᵀ t_j)ᵀ / F_n for the
    /// band's diagonal block B = ∂f_j/∂x_j (F_n's dependence on the other nodes left out).
    /// What friction at the node is decided from and acts along. None off the span.
    pub fn node_share(&self, j: usize) -> Option<Share> {
        let f = self.node_force(j);
        let force = f[0].hypot(f[1]);
        if !(force > 0.0) {
            return None;
        }
        let n = [f[0] / force, f[1] / force];
        let t = [-n[1], n[0]];
        let b = self.band_block(j, j);
        let bt = |v: [f64; 2]| {
            [
                b[0][0] * v[0] + b[1][0] * v[1],
                b[0][1] * v[0] + b[1][1] * v[1],
            ]
        };
        let (df, dt) = (bt(n), bt(t));
        Some(Share {
            force,
            normal: n,
            dforce: df,
            dturn: [dt[0] / force, dt[1] / force],
        })
    }

    /// The coefficient c of the rank-one part of ∂f/∂x, c G hᵀ: c = d(F/A)/dA.
    pub fn rank_one(&self) -> f64 {
        (self.dforce - self.force / self.area) / self.area
    }
}

/// Segment integrals over its part [ξ₀, ξ₁] inside the circle (in ξ: ds = L dξ).
struct Piece {
    ig: f64,
    ixg: f64,
    ing: [[f64; 2]; 2],
    jn: [[f64; 2]; 2],
    m: [[[[f64; 2]; 2]; 2]; 2],
    depth: f64,
}

fn piece(a: [f64; 2], b: [f64; 2], c: &CompliantCircle, lo: f64, hi: f64) -> Piece {
    let mut p = Piece {
        ig: 0.0,
        ixg: 0.0,
        ing: [[0.0; 2]; 2],
        jn: [[0.0; 2]; 2],
        m: [[[[0.0; 2]; 2]; 2]; 2],
        depth: 0.0,
    };
    let at = |xi: f64| {
        let x = [a[0] + xi * (b[0] - a[0]), a[1] + xi * (b[1] - a[1])];
        let d = [x[0] - c.center[0], x[1] - c.center[1]];
        let rho = d[0].hypot(d[1]);
        (rho, [d[0] / rho, d[1] / rho])
    };
    for (t, w) in GAUSS {
        let xi = lo + t * (hi - lo);
        let w = w * (hi - lo);
        let (rho, n) = at(xi);
        let g = c.reach - rho;
        let nn = [1.0 - xi, xi];
        p.ig += w * g;
        p.ixg += w * xi * g;
        for s in 0..2 {
            for d in 0..2 {
                p.ing[s][d] += w * nn[s] * g * n[d];
                p.jn[s][d] += w * nn[s] * n[d];
            }
            for r in 0..2 {
                for x in 0..2 {
                    for y in 0..2 {
                        let id = if x == y { 1.0 } else { 0.0 };
                        let k = -n[x] * n[y] + g / rho * (id - n[x] * n[y]);
                        p.m[s][r][x][y] += w * nn[s] * nn[r] * k;
                    }
                }
            }
        }
    }
    // The deepest point: the foot of the perpendicular from the centre, kept in the piece.
    let e = [b[0] - a[0], b[1] - a[1]];
    let ee = e[0] * e[0] + e[1] * e[1];
    let foot = ((c.center[0] - a[0]) * e[0] + (c.center[1] - a[1]) * e[1]) / ee;
    p.depth = c.reach - at(foot.clamp(lo, hi)).0;
    p
}

/// How a rod (configuration `q`, `n` nodes) presses into the compliant fruit `c`, if at all.
pub fn press(c: &CompliantCircle, q: &[f64], n: usize) -> Option<Pressing> {
    let node = |i: usize| [q[2 * i], q[2 * i + 1]];
    let pieces: Vec<(usize, f64, f64)> = (0..n.saturating_sub(1))
        .filter_map(|i| inside(node(i), node(i + 1), c.center, c.reach).map(|(l, h)| (i, l, h)))
        .collect();
    let (first, last) = (pieces.first()?.0, pieces.last()?.0 + 1);
    let span = last - first + 1;
    let mut out = Pressing {
        obstacle: c.obstacle,
        area: 0.0,
        force: 0.0,
        dforce: 0.0,
        equivalent: 0.0,
        first,
        g: vec![[0.0; 2]; span],
        h: vec![[0.0; 2]; span],
        dg: vec![[[[0.0; 2]; 2]; 3]; span],
        regions: Vec::new(),
    };
    // Per region: the arc length s from node `first` at each node, then the pieces.
    let mut acc: Vec<Acc> = Vec::new();
    let mut arc_at = vec![0.0; span];
    for i in first..last {
        arc_at[i + 1 - first] =
            arc_at[i - first] + (q[2 * i + 2] - q[2 * i]).hypot(q[2 * i + 3] - q[2 * i + 1]);
    }
    for &(i, lo, hi) in &pieces {
        add_piece(c, q, i, lo, hi, arc_at[i - first], &mut out, &mut acc);
    }
    if out.area <= 0.0 {
        return None;
    }
    let (f, dfa, de) = resultant(&c.law, c.reach, out.area);
    out.force = f;
    out.dforce = dfa;
    out.equivalent = de;
    out.regions = acc
        .iter()
        .filter(|r| r.area > 0.0)
        .map(|r| region(c, first, &arc_at, out.force * r.area / out.area, r))
        .collect();
    Some(out)
}

/// Segment i's part [lo, hi] inside the fruit (s0: the arc length at node i from node
/// `out.first`) into the sums of the pressing and of its region.
#[allow(clippy::too_many_arguments)]
fn add_piece(
    c: &CompliantCircle,
    q: &[f64],
    i: usize,
    lo: f64,
    hi: f64,
    s0: f64,
    out: &mut Pressing,
    acc: &mut Vec<Acc>,
) {
    let (a, b) = ([q[2 * i], q[2 * i + 1]], [q[2 * i + 2], q[2 * i + 3]]);
    let e = [b[0] - a[0], b[1] - a[1]];
    let l = e[0].hypot(e[1]);
    let t = [e[0] / l, e[1] / l];
    let p = piece(a, b, c, lo, hi);
    let j = i - out.first;
    out.area += l * p.ig;
    // ∂L/∂x_i = −t, ∂L/∂x_{i+1} = t.
    let dl = [[-t[0], -t[1]], t];
    for s in 0..2 {
        for d in 0..2 {
            out.g[j + s][d] += l * p.ing[s][d];
            out.h[j + s][d] += dl[s][d] * p.ig - l * p.jn[s][d];
        }
        for r in 0..2 {
            let blk = &mut out.dg[j + s][1 + r - s];
            for x in 0..2 {
                for y in 0..2 {
                    blk[x][y] += l * p.m[s][r][x][y] + p.ing[s][x] * dl[r][y];
                }
            }
        }
    }
    // A region goes on only through a node inside the circle (a piece ending at ξ = 1
    // followed by one starting at ξ = 0 on the next segment).
    let joined = acc
        .last()
        .is_some_and(|r| r.open && r.last == i && lo == 0.0);
    if !joined {
        acc.push(Acc {
            first: i,
            ..Acc::default()
        });
    }
    let r = acc.last_mut().expect("pushed");
    r.last = i + 1;
    r.open = hi == 1.0;
    r.area += l * p.ig;
    r.moment += l * (s0 * p.ig + l * p.ixg);
    for d in 0..2 {
        r.gn[d] += l * (p.ing[0][d] + p.ing[1][d]);
    }
    r.depth = r.depth.max(p.depth);
    r.length += l * (hi - lo);
}

/// A region's sums while the pieces are added.
#[derive(Default)]
struct Acc {
    first: usize,
    last: usize,
    open: bool,
    area: f64,
    moment: f64,
    gn: [f64; 2],
    depth: f64,
    length: f64,
}

fn region(c: &CompliantCircle, first: usize, arc_at: &[f64], force: f64, r: &Acc) -> Region {
    // The force's centre: the arc length s̄ = ∫ s g ds / A_r, on segment `seg`.
    let sbar = r.moment / r.area;
    let mut seg = r.first;
    while seg + 1 < r.last && arc_at[seg + 1 - first] <= sbar {
        seg += 1;
    }
    let l = arc_at[seg + 1 - first] - arc_at[seg - first];
    let weight = if l > 0.0 {
        ((sbar - arc_at[seg - first]) / l).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let norm = r.gn[0].hypot(r.gn[1]);
    let normal = if norm > 0.0 {
        [r.gn[0] / norm, r.gn[1] / norm]
    } else {
        [0.0; 2]
    };
    let (half_width, peak_pressure) = spread(&c.law, c.reach, force, r.length);
    Region {
        obstacle: c.obstacle,
        first: r.first,
        last: r.last,
        area: r.area,
        depth: r.depth,
        length: r.length,
        force,
        resultant: force / r.area * norm,
        segment: seg,
        weight,
        normal,
        half_width,
        peak_pressure,
    }
}

/// Hertz's half-width and peak pressure of force F spread over an arc of length ℓ in Hertz's
/// proportion: a = a_H(F) ℓ / (2 c(F)), c(F) the half-chord of a straight face carrying F at
/// the law's approach δ(F); p₀ = 2 F / (π a b).
pub fn spread(law: &LineContact, rho0: f64, f: f64, length: f64) -> (f64, f64) {
    if f <= 0.0 || length <= 0.0 {
        return (0.0, 0.0);
    }
    let chord = chord(rho0, law.approach(f).0);
    let a = if chord > 0.0 {
        law.half_width(f) * length / chord
    } else {
        law.half_width(f)
    };
    (a, 2.0 * f / (std::f64::consts::PI * a * law.b))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::contact::compliant::Material;

    /// A 2 cm wide flat prong of E = 1 MPa, ν = 0.5 on a 5 cm apple, face offset 5 mm.
    fn fruit() -> CompliantCircle {
        let apple = Material::preset("apple").unwrap();
        CompliantCircle {
            obstacle: 0,
            body: None,
            center: [0.0, 0.0],
            reach: 0.055,
            law: LineContact::new(0.05, f64::INFINITY, 0.02, 0.75 / 1e6, &apple),
            coulomb: crate::contact::friction::Coulomb::FRICTIONLESS,
        }
    }

    /// `n` nodes on an arc of radius `r` about (0, y0) from angle a0 to a1 (a straight line
    /// at height y0 when r is infinite: x from −a0 to a1 … given as ±half).
    fn arc(n: usize, r: f64, y0: f64, a0: f64, a1: f64) -> Vec<f64> {
        (0..n)
            .flat_map(|k| {
                let t = a0 + (a1 - a0) * k as f64 / (n - 1) as f64;
                if r.is_finite() {
                    [r * t.cos(), y0 + r * t.sin()]
                } else {
                    [t, y0]
                }
            })
            .collect()
    }

    #[test]
    fn the_line_area_and_its_depth_invert_each_other() {
        let rho = 0.055;
        for d in [1e-12, 1e-9, 1e-6, 3e-4, 1e-3, 0.01, 0.04] {
            let (a, da) = line_area(rho, d);
            assert!((line_depth(rho, a) - d).abs() < 1e-12 * d, "{d}");
            let h = 1e-6 * d;
            let fd = (line_area(rho, d + h).0 - line_area(rho, d - h).0) / (2.0 * h);
            assert!((fd - da).abs() < 1e-7 * da, "{d}: {fd} {da}");
            // Against a fine midpoint rule of ρ₀ − √(d² + x²) along the chord.
            let (dd, c) = (rho - d, 0.5 * chord(rho, d));
            let m = 20_000;
            let mid: f64 = (0..m)
                .map(|k| {
                    let x = -c + (k as f64 + 0.5) * 2.0 * c / m as f64;
                    rho - dd.hypot(x)
                })
                .sum::<f64>()
                * 2.0
                * c
                / m as f64;
            // (the sum cancels to round-off for the shallowest lines)
            if d > 1e-8 {
                assert!((mid - a).abs() < 1e-7 * a, "{d}: {mid} vs {a}");
            }
        }
        // The series and the closed form meet at the switch (u = 0.1).
        let d = rho * (1.0 - 1.0 / 1.01f64.sqrt());
        let (lo, hi) = (line_area(rho, d * (1.0 - 1e-13)).0, line_area(rho, d).0);
        assert!((hi - lo).abs() < 1e-11 * hi, "{lo} {hi}");
    }

    /// A straight face pressed δ into the fruit is a narrow Hertz contact: the resultant is the
    /// line-contact law at δ, one region, Hertz's half-width and peak pressure, wherever the
    /// nodes fall.
    #[test]
    fn a_straight_face_gives_the_hertz_law() {
        let c = fruit();
        for (n, shift) in [(11, 0.0), (11, 0.0037), (4, 0.01), (101, -0.0011)] {
            let delta = 2e-4;
            let mut q = arc(n, f64::INFINITY, c.reach - delta, -0.05, 0.05);
            for k in 0..n {
                q[2 * k] += shift;
            }
            let p = press(&c, &q, n).unwrap();
            let (f, _) = c.law.force(delta);
            // (to the Gauss rule's error on the chord's pieces)
            assert!((p.force - f).abs() < 1e-9 * f, "{n}: {} vs {f}", p.force);
            assert!((p.equivalent - delta).abs() < 1e-9 * delta);
            assert_eq!(p.regions.len(), 1);
            let g = p.regions[0];
            assert!((g.force - f).abs() < 1e-9 * f);
            assert!((g.depth - delta).abs() < 1e-15);
            assert!((g.half_width - c.law.half_width(f)).abs() < 1e-9 * g.half_width);
            assert!((g.peak_pressure - c.law.peak_pressure(f)).abs() < 1e-9 * g.peak_pressure);
            assert!((g.normal[1] - 1.0).abs() < 1e-12, "{:?}", g.normal);
            // The force's centre is above the fruit's centre.
            let x = crate::contact::edge::point(&q, g.segment, g.weight);
            assert!(x[0].abs() < 1e-12, "{n}: {x:?}");
            // The nodal forces add up to F straight up (the pressure's sideways parts cancel).
            let sum = (p.first..p.first + p.g.len()).fold([0.0; 2], |s, j| {
                let fj = p.node_force(j);
                [s[0] + fj[0], s[1] + fj[1]]
            });
            assert!(
                sum[0].abs() < 1e-9 * f && (sum[1] - f).abs() < 1e-3 * f,
                "{sum:?}"
            );
        }
    }

    /// The nodal forces' derivative: the banded part plus the rank-one part, against central
    /// differences, on a bent prong with two arcs in the fruit.
    #[test]
    fn the_force_derivative_matches_finite_differences() {
        let c = fruit();
        let n = 9;
        let mut q = arc(n, 0.06, -0.0055, 1.2, 2.0);
        // A bump that lifts node 4 out of the fruit: two regions.
        q[9] += 0.004;
        let p = press(&c, &q, n).unwrap();
        assert_eq!(p.regions.len(), 2, "{:?}", p.regions);
        let force = |q: &[f64]| -> Vec<f64> {
            let p = press(&c, q, n).unwrap();
            (0..n).flat_map(|j| p.node_force(j)).collect()
        };
        let area = |q: &[f64]| press(&c, q, n).unwrap().area;
        let cr = p.rank_one();
        let mut worst = 0.0f64;
        let scale = p.force / 1e-3;
        for k in 0..n {
            for y in 0..2 {
                let h = 1e-8;
                let (mut qp, mut qm) = (q.clone(), q.clone());
                qp[2 * k + y] += h;
                qm[2 * k + y] -= h;
                let (fp, fm) = (force(&qp), force(&qm));
                let da = (area(&qp) - area(&qm)) / (2.0 * h);
                let hk = if k >= p.first && k < p.first + p.h.len() {
                    p.h[k - p.first][y]
                } else {
                    0.0
                };
                assert!(
                    (da - hk).abs() < 1e-6 * p.area / 1e-3,
                    "h[{k}][{y}]: {da} vs {hk}"
                );
                for j in 0..n {
                    for x in 0..2 {
                        let fd = (fp[2 * j + x] - fm[2 * j + x]) / (2.0 * h);
                        let band = if j.abs_diff(k) <= 1 {
                            p.band_block(j, k)[x][y]
                        } else {
                            0.0
                        };
                        let gj = if j >= p.first && j < p.first + p.g.len() {
                            p.g[j - p.first][x]
                        } else {
                            0.0
                        };
                        let exact = band + cr * gj * hk;
                        worst = worst.max((fd - exact).abs() / scale);
                    }
                }
            }
        }
        assert!(worst < 1e-5, "worst relative error {worst}");
    }

    /// A prong wrapping the fruit (an arc of a slightly larger radius, centred a little off):
    /// the resultant and the region's figures converge at second order in the node spacing.
    #[test]
    fn a_wrapping_prong_converges_in_nodes() {
        let c = fruit();
        let at = |n: usize| {
            let q = arc(n, 0.0556, -0.001, 0.6, 2.4);
            let p = press(&c, &q, n).unwrap();
            assert_eq!(p.regions.len(), 1, "{n}: {:?}", p.regions);
            (p.force, p.regions[0].peak_pressure, p.regions[0].length)
        };
        // The polyline's chords cut into the fruit by their sagitta, O(Δl²): the figures
        // converge at second order (the errors against 730 nodes shrink ≈ 9× per step of 3).
        let (f1, f2, f3, f4) = (at(28), at(82), at(244), at(730));
        println!("(force, p0, length) at 28 / 82 / 244 / 730 nodes: {f1:?} {f2:?} {f3:?} {f4:?}");
        let err = |f: (f64, f64, f64)| ((f.0 - f4.0) / f4.0).abs();
        assert!(
            err(f2) < 0.15 * err(f1) && err(f3) < 0.15 * err(f2),
            "{f1:?} {f2:?} {f3:?}"
        );
        assert!(err(f3) < 0.002, "{}", err(f3));
        assert!(((f3.1 - f4.1) / f4.1).abs() < 0.002);
        // It is conforming: the arc is far longer than a straight face's chord of its depth.
        let p = press(&c, &arc(82, 0.0556, -0.001, 0.6, 2.4), 82).unwrap();
        let g = p.regions[0];
        assert!(g.length > 5.0 * chord(c.reach, g.depth));
        assert!(p.equivalent > 2.0 * g.depth);
    }
}
