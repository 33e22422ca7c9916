//! What the `.rrd` draws of a compliant contact (issue 11): the pressure as a colour along the
//! contact in the scene, and a zoom of the most pressed contact in which the indentation is
//! drawn to scale.
//!
//! The compliant law is Hertz's line contact (docs/model.md): over the contact half-width a the
//! pressure is p(x) = p₀ √(1 − x²/a²) (a wrapping arc in edge mode spreads its load in
//! proportion to the overlap, src/contact/conforming.rs: there the drawing shows the contact's
//! p₀ and a, not the shape of its distribution). A contact is drawn on the prong's face, where the fruit's
//! pressed surface is; a free fruit's own contact with a fixed obstacle (a fruit on the table)
//! at the fruit's pressed point. Both are where the fruit is at the step: a free fruit's
//! contacts move with it. The colour of a pressure is its ratio to the fruit's bruise threshold:
//! green (0) → yellow (½) → red (the threshold) → purple above it (bruising, the colour of
//! `replay check`'s bruise ring). A fruit without a threshold is coloured against the contact's
//! own peak.
//!
//! The zoom works in the contact's own frame, in millimetres: x along the fruit's surface
//! tangent t = (n_y, −n_x), y along the outward normal n, the origin on the undeformed surface
//! under the contact point. The fruit's surface is drawn where the fruit is (a free fruit at
//! its pose at the step); what presses it is a prong ([`Face::Rod`]) or, for the fruit's own
//! contact, the fixed obstacle's surface ([`Face::Surface`], seen from the fruit by
//! [`from_the_fruit`]). The undeformed fruit surface, the prong's face (its centre line
//! offset by the half-thickness) and centre line, the indentation δ as an arrow from the
//! undeformed surface to the face, the pressure profile below the face (depth ∝ p) with the
//! bruise threshold as a line, and a scale bar are all drawn at true scale.

use crate::events::{v3, xy, ContactView};

/// Pieces a contact's pressure profile is drawn with.
pub const SEGMENTS: usize = 16;

/// Colour of the bruise ring in `replay check --rrd`, and of a pressure above the threshold.
pub const BRUISE_COLOR: [u8; 3] = [150, 60, 200];

/// The pressure at distance x from the centre of a Hertz line contact of peak p₀ and
/// half-width a (0 outside).
pub fn hertz(p0: f64, a: f64, x: f64) -> f64 {
    if a <= 0.0 || x.abs() >= a {
        0.0
    } else {
        p0 * (1.0 - (x / a) * (x / a)).sqrt()
    }
}

/// The colour of pressure `p` against the bruise threshold (or, with none, against `peak`).
pub fn pressure_color(p: f64, bruise: f64, peak: f64) -> [u8; 3] {
    let reference = if bruise > 0.0 { bruise } else { peak };
    if reference <= 0.0 {
        return [60, 170, 90];
    }
    let r = p / reference;
    if r > 1.0 && bruise > 0.0 {
        return BRUISE_COLOR;
    }
    let r = r.clamp(0.0, 1.0);
    const STOPS: [[f64; 3]; 3] = [
        [60.0, 170.0, 90.0],
        [240.0, 200.0, 20.0],
        [220.0, 40.0, 40.0],
    ];
    let (lo, hi, f) = if r < 0.5 {
        (STOPS[0], STOPS[1], 2.0 * r)
    } else {
        (STOPS[1], STOPS[2], 2.0 * r - 1.0)
    };
    let mix = |k: usize| (lo[k] + f * (hi[k] - lo[k])).round() as u8;
    [mix(0), mix(1), mix(2)]
}

/// Whether a contact carries a compliant fruit's pressure.
pub fn is_pressed(c: &ContactView) -> bool {
    c.half_width > 0.0 && c.peak_pressure > 0.0
}

/// The pieces of a pressed contact along the prong's face, in scene coordinates (m), each with
/// the colour of the pressure at its middle.
pub fn patch(c: &ContactView) -> Vec<([[f64; 2]; 2], [u8; 3])> {
    let t = tangent(xy(c.normal));
    let a = c.half_width;
    (0..SEGMENTS)
        .map(|k| {
            let x0 = -a + 2.0 * a * k as f64 / SEGMENTS as f64;
            let x1 = -a + 2.0 * a * (k + 1) as f64 / SEGMENTS as f64;
            let at = |x: f64| [c.point[0] + x * t[0], c.point[1] + x * t[1]];
            let p = hertz(c.peak_pressure, a, 0.5 * (x0 + x1));
            (
                [at(x0), at(x1)],
                pressure_color(p, c.bruise_pressure, c.peak_pressure),
            )
        })
        .collect()
}

/// The contact frame's tangent: (t, n) is right-handed like (x, y).
fn tangent(n: [f64; 2]) -> [f64; 2] {
    [n[1], -n[0]]
}

/// The most pressed contact of a step (largest peak pressure; the first of equals).
pub fn most_pressed(contacts: &[ContactView]) -> Option<&ContactView> {
    contacts
        .iter()
        .filter(|c| is_pressed(c))
        .fold(None, |best: Option<&ContactView>, c| match best {
            Some(b) if b.peak_pressure >= c.peak_pressure => Some(b),
            _ => Some(c),
        })
}

/// The closest point of a surface to a point (m): a fruit or an obstacle where it is.
pub type Surface<'a> = &'a dyn Fn([f64; 2]) -> [f64; 2];

/// What presses the fruit in a zoom.
pub enum Face<'a> {
    /// A prong: its centre line (interleaved node positions); the face is offset from it.
    Rod(&'a [f64]),
    /// A fixed obstacle's surface (a free fruit's own contact), and its name.
    Surface(Surface<'a>, &'a str),
}

/// A free fruit's own contact with a fixed obstacle as the zoom reads a prong's: the normal
/// turned to the fruit's outward one (−n) and the point moved to the obstacle's surface
/// (`closest`: the surface's closest point to the contact's), the face that presses the fruit.
pub fn from_the_fruit(c: &ContactView, closest: [f64; 2]) -> ContactView {
    ContactView {
        normal: [-c.normal[0], -c.normal[1], 0.0],
        tangent: [c.normal[1], -c.normal[0], 0.0],
        point: v3(closest),
        ..*c
    }
}

/// The zoom of one contact, in the contact frame (mm).
#[derive(Debug, Clone, PartialEq)]
pub struct Zoom {
    /// Half-width of the window (mm).
    pub window: f64,
    /// The undeformed fruit surface across the window.
    pub fruit: Vec<[f64; 2]>,
    /// The prong's face and centre line, clipped to the window (a fixed obstacle: its
    /// surface, and no centre line), and the face's name.
    pub face: Vec<[f64; 2]>,
    pub centerline: Vec<[f64; 2]>,
    pub face_name: String,
    /// From the undeformed surface (origin) to the face: (0, −δ).
    pub indentation: [f64; 2],
    /// The pressure profile below the face: pieces with their colours.
    pub profile: Vec<([[f64; 2]; 2], [u8; 3])>,
    /// The bruise threshold's depth in the profile, as a line across it (none without one).
    pub threshold: Option<[[f64; 2]; 2]>,
    /// A scale bar (its two ends) and its length (mm).
    pub scale: ([[f64; 2]; 2], f64),
}

/// The zoom of contact `c` (`n` the fruit's outward normal, `point` on the pressing face) of
/// `face` against the fruit's surface `fruit` (drawn from its closest points; `None` draws none).
pub fn zoom(c: &ContactView, face: Face<'_>, fruit: Option<Surface<'_>>) -> Zoom {
    let n = xy(c.normal);
    let t = tangent(n);
    let d = c.indentation.max(0.0);
    // The origin: the undeformed surface under the contact point.
    let s0 = [c.point[0] + d * n[0], c.point[1] + d * n[1]];
    let local = |p: [f64; 2]| {
        let v = [p[0] - s0[0], p[1] - s0[1]];
        [
            1e3 * (v[0] * t[0] + v[1] * t[1]),
            1e3 * (v[0] * n[0] + v[1] * n[1]),
        ]
    };
    let w = (2.5 * c.half_width).max(10.0 * d).max(5e-4);
    let wm = 1e3 * w;
    // A surface across the window, from its closest points to the tangent line through s0.
    let across = |closest: Surface<'_>| -> Vec<[f64; 2]> {
        (0..=40)
            .map(|k| {
                let x = -w + 2.0 * w * k as f64 / 40.0;
                local(closest([s0[0] + x * t[0], s0[1] + x * t[1]]))
            })
            .collect()
    };
    let fruit = fruit.map_or_else(Vec::new, across);
    let (face, centerline, face_name) = match face {
        Face::Rod(q) => {
            let (face, centerline) = rod_face(c, q, &local, wm);
            (face, centerline, "prong face".to_string())
        }
        Face::Surface(closest, name) => (across(closest), Vec::new(), name.to_string()),
    };
    let (a, dm) = (1e3 * c.half_width, 1e3 * d);
    let reference = c.peak_pressure.max(c.bruise_pressure);
    let depth = 0.3 * wm / reference;
    let profile = (0..SEGMENTS)
        .map(|k| {
            let x0 = -a + 2.0 * a * k as f64 / SEGMENTS as f64;
            let x1 = -a + 2.0 * a * (k + 1) as f64 / SEGMENTS as f64;
            let y = |x: f64| -dm - depth * hertz(c.peak_pressure, a, x);
            let p = hertz(c.peak_pressure, a, 0.5 * (x0 + x1));
            (
                [[x0, y(x0)], [x1, y(x1)]],
                pressure_color(p, c.bruise_pressure, c.peak_pressure),
            )
        })
        .collect();
    let threshold = (c.bruise_pressure > 0.0).then(|| {
        let y = -dm - depth * c.bruise_pressure;
        [[-1.2 * a, y], [1.2 * a, y]]
    });
    let len = scale_length(wm);
    let y0 = -dm - 0.45 * wm;
    Zoom {
        window: wm,
        fruit,
        face,
        centerline,
        face_name,
        indentation: [0.0, -dm],
        profile,
        threshold,
        scale: ([[-wm, y0], [-wm + len, y0]], len),
    }
}

/// A prong's face and centre line in the zoom's frame (`local`), clipped to the window: the
/// face is the centre line moved by the offset between the contact's centre-line point and its
/// face point.
fn rod_face(
    c: &ContactView,
    q: &[f64],
    local: &dyn Fn([f64; 2]) -> [f64; 2],
    wm: f64,
) -> (Vec<[f64; 2]>, Vec<[f64; 2]>) {
    let n = c.normal;
    let node = |i: usize| [q[2 * i], q[2 * i + 1]];
    let xc = if c.segment != usize::MAX && c.segment + 1 < q.len() / 2 {
        let (a, b) = (node(c.segment), node(c.segment + 1));
        [
            (1.0 - c.weight) * a[0] + c.weight * b[0],
            (1.0 - c.weight) * a[1] + c.weight * b[1],
        ]
    } else {
        node(c.node.min(q.len() / 2 - 1))
    };
    let off = 1e3 * ((xc[0] - c.point[0]) * n[0] + (xc[1] - c.point[1]) * n[1]);
    let line: Vec<[f64; 2]> = (0..q.len() / 2).map(|i| local(node(i))).collect();
    let centerline = clip(&line, wm);
    let face = centerline.iter().map(|p| [p[0], p[1] - off]).collect();
    (face, centerline)
}

impl Zoom {
    /// Where the zoom's names go (each at an end of what it names, so they do not pile up in
    /// the middle), and the contact's description above it all.
    pub fn labels(&self, description: String) -> Vec<([f64; 2], String)> {
        let mut out = Vec::new();
        let mut name = |p: Option<&[f64; 2]>, text: &str| {
            if let Some(p) = p {
                out.push((*p, text.to_string()));
            }
        };
        name(self.fruit.last(), "undeformed fruit");
        name(self.face.last(), &self.face_name);
        name(self.centerline.first(), "centre line");
        name(self.threshold.as_ref().map(|l| &l[1]), "bruise threshold");
        let top = self
            .centerline
            .iter()
            .chain(&self.fruit)
            .map(|p| p[1])
            .fold(0.0f64, f64::max);
        out.push(([0.0, top + 0.4 * self.window], description));
        out
    }
}

/// A 1, 2 or 5 × 10ᵏ length near a third of the window (mm).
fn scale_length(w: f64) -> f64 {
    let target = w / 1.5;
    let e = 10f64.powf(target.log10().floor());
    [5.0, 2.0, 1.0]
        .into_iter()
        .map(|m| m * e)
        .find(|l| *l <= target)
        .unwrap_or(e)
}

/// The parts of polyline `p` with |x| ≤ w, joined (a prong crosses the window once).
fn clip(p: &[[f64; 2]], w: f64) -> Vec<[f64; 2]> {
    let mut out: Vec<[f64; 2]> = Vec::new();
    for s in p.windows(2) {
        let (a, b) = (s[0], s[1]);
        let lerp = |x: f64| {
            let f = (x - a[0]) / (b[0] - a[0]);
            [x, a[1] + f * (b[1] - a[1])]
        };
        let (lo, hi) = (a[0].min(b[0]), a[0].max(b[0]));
        if hi < -w || lo > w {
            continue;
        }
        let a2 = if a[0].abs() > w {
            lerp(w.copysign(a[0]))
        } else {
            a
        };
        let b2 = if b[0].abs() > w {
            lerp(w.copysign(b[0]))
        } else {
            b
        };
        if out.last() != Some(&a2) {
            out.push(a2);
        }
        out.push(b2);
    }
    out
}

/// A millimetre figure with 3 significant digits.
pub fn mm(x: f64) -> String {
    let v = 1e3 * x;
    if v >= 10.0 {
        format!("{v:.1} mm")
    } else if v >= 1.0 {
        format!("{v:.2} mm")
    } else {
        format!("{:.1} µm", 1e3 * v)
    }
}

/// A pressure in kPa or MPa.
pub fn pressure(p: f64) -> String {
    if p >= 1e6 {
        format!("{:.3} MPa", p / 1e6)
    } else {
        format!("{:.1} kPa", p / 1e3)
    }
}

/// What the zoom's label says about contact `c`, at `place` (`rod "left" node 7`, or
/// `"apple" on "table"`).
pub fn describe(c: &ContactView, place: &str) -> String {
    let ratio = if c.bruise_pressure > 0.0 {
        format!(
            "\n= {:.2} × the bruise threshold {}",
            c.peak_pressure / c.bruise_pressure,
            pressure(c.bruise_pressure)
        )
    } else {
        String::new()
    };
    format!(
        "{place}\nF {:.4} N, p₀ {}{ratio}\n2a {}, δ {} (to scale)",
        c.normal_force,
        pressure(c.peak_pressure),
        mm(2.0 * c.half_width),
        mm(c.indentation)
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::obstacle::{Circle, Obstacle};

    fn contact() -> ContactView {
        ContactView {
            rod: 0,
            node: 1,
            obstacle: 0,
            body: usize::MAX,
            point: [0.0, 0.05 - 1e-3, 0.0],
            normal: [0.0, 1.0, 0.0],
            tangent: [-1.0, 0.0, 0.0],
            normal_force: 10.0,
            friction_force: 0.0,
            slip_velocity: 0.0,
            stuck: false,
            utilisation: 0.0,
            mu_s: 0.0,
            indentation: 1e-3,
            half_width: 4e-3,
            half_width_minor: 4e-3,
            peak_pressure: 8e4,
            bruise_pressure: 1e5,
            bruise_half_width: 0.0,
            segment: usize::MAX,
            weight: 0.0,
            first: usize::MAX,
            last: usize::MAX,
            dim: 2,
        }
    }

    #[test]
    fn colours_run_from_green_to_red_at_the_threshold_and_purple_above() {
        assert_eq!(pressure_color(0.0, 1e5, 1.0), [60, 170, 90]);
        assert_eq!(pressure_color(5e4, 1e5, 1.0), [240, 200, 20]);
        assert_eq!(pressure_color(1e5, 1e5, 1.0), [220, 40, 40]);
        assert_eq!(pressure_color(1.01e5, 1e5, 1.0), BRUISE_COLOR);
        // Without a threshold: against the contact's own peak, never purple.
        assert_eq!(pressure_color(2.0, 0.0, 2.0), [220, 40, 40]);
    }

    #[test]
    fn the_patch_spans_the_contact_width_on_the_face() {
        let c = contact();
        let p = patch(&c);
        assert_eq!(p.len(), SEGMENTS);
        let (first, last) = (p[0].0[0], p[SEGMENTS - 1].0[1]);
        // t = (n_y, −n_x) = (1, 0): from x = −a to +a.
        assert!((first[0] + 4e-3).abs() < 1e-15 && (last[0] - 4e-3).abs() < 1e-15);
        assert!((first[1] - c.point[1]).abs() < 1e-15);
        // The middle is the most pressed: yellowish-red, the ends green-ish.
        assert!(p[SEGMENTS / 2].1[1] < p[0].1[1]);
    }

    #[test]
    fn the_zoom_draws_indentation_and_surfaces_to_scale() {
        let c = contact();
        // A straight prong along x at y = 0.05 - 1e-3 + 5e-3 (its face 5 mm below the centre line).
        let q: Vec<f64> = (0..5)
            .flat_map(|i| [-0.02 + 0.01 * i as f64, 0.054])
            .collect();
        let o = Obstacle::Circle(Circle {
            center: [0.0, 0.0],
            radius: 0.05,
        });
        let fruit = |p: [f64; 2]| o.query(p).closest;
        let z = zoom(&c, Face::Rod(&q), Some(&fruit));
        // Window: 2.5 a = 10 mm.
        assert!((z.window - 10.0).abs() < 1e-12);
        assert_eq!(z.indentation, [0.0, -1.0]);
        // The undeformed surface passes through the origin, below it at the window's edge by
        // R − √(R² − w²).
        let mid = z.fruit[20];
        assert!(mid[0].abs() < 1e-9 && mid[1].abs() < 1e-9, "{mid:?}");
        let edge = z.fruit[40];
        let drop = 50.0 - (50.0f64.powi(2) - edge[0].powi(2)).sqrt();
        assert!((edge[1] + drop).abs() < 1e-9, "{edge:?}");
        // The face is the centre line 5 mm lower, at −δ under the contact.
        for p in &z.face {
            assert!((p[1] + 1.0).abs() < 1e-9, "{p:?}");
        }
        assert!(z.face.first().unwrap()[0].abs() <= 10.0 + 1e-12);
        assert!(z.centerline.iter().all(|p| (p[1] - 4.0).abs() < 1e-9));
        // The profile is deepest in the middle: p₀ × 0.3 w / max(p₀, threshold) below the
        // face, 2.4 mm; the threshold 3 mm below it.
        let deepest = z
            .profile
            .iter()
            .map(|s| s.0[1][1])
            .fold(f64::INFINITY, f64::min);
        assert!((deepest + 1.0 + 2.4).abs() < 1e-12, "{deepest}");
        let th = z.threshold.unwrap();
        assert!((th[0][1] + 1.0 + 3.0).abs() < 1e-12);
        assert_eq!(z.scale.1, 5.0);
    }

    /// A free fruit's own contact with the table, where the fruit is: a 4 cm disc moved from
    /// its initial place (0, 1) to rest 1 mm deep on the table y = 0. Seen from the fruit, the
    /// table is the face 1 mm from the undeformed surface, which passes through the origin
    /// (the fruit drawn at its pose, not its initial place).
    #[test]
    fn the_zoom_of_a_fruit_on_the_table_draws_both_where_they_are() {
        use crate::obstacle::Plane;
        use crate::world::body::{Placed, Pose};
        let disc = Obstacle::Circle(Circle {
            center: [0.0, 1.0],
            radius: 0.04,
        });
        let table = Obstacle::Plane(Plane::new([0.0, 0.0], [0.0, 1.0]));
        let placed = Placed {
            shape: &disc,
            c0: [0.0, 1.0],
            pose: Pose {
                c: [0.0, 0.039],
                theta: 0.3,
            },
        };
        let c = ContactView {
            rod: usize::MAX,
            node: 0,
            obstacle: 0,
            point: [0.0, -1e-3, 0.0],
            normal: [0.0, 1.0, 0.0],
            ..contact()
        };
        let surface = |p: [f64; 2]| table.query(p).closest;
        let fruit = |p: [f64; 2]| placed.query(p).closest;
        let v = from_the_fruit(&c, surface(xy(c.point)));
        assert_eq!((v.normal, v.point), ([0.0, -1.0, 0.0], [0.0, 0.0, 0.0]));
        let z = zoom(&v, Face::Surface(&surface, "table"), Some(&fruit));
        let mid = z.fruit[20];
        assert!(mid[0].abs() < 1e-9 && mid[1].abs() < 1e-9, "{mid:?}");
        let edge = z.fruit[40];
        let drop = 40.0 - (40.0f64.powi(2) - edge[0].powi(2)).sqrt();
        assert!((edge[1] + drop).abs() < 1e-9, "{edge:?}");
        assert_eq!(z.face.len(), 41);
        assert!(
            z.face.iter().all(|p| (p[1] + 1.0).abs() < 1e-9),
            "{:?}",
            z.face
        );
        assert!(z.centerline.is_empty());
        assert_eq!(z.face_name, "table");
        let labels = z.labels(describe(&c, "\"apple\" on \"table\""));
        assert!(labels.iter().any(|l| l.1 == "table"));
        assert!(labels
            .last()
            .unwrap()
            .1
            .starts_with("\"apple\" on \"table\"\nF 10.0000 N"));
    }

    #[test]
    fn the_most_pressed_contact_is_zoomed() {
        let mut a = contact();
        let mut b = contact();
        b.node = 2;
        b.peak_pressure = 9e4;
        a.half_width = 0.0;
        assert_eq!(most_pressed(&[a, b]).unwrap().node, 2);
        a.half_width = 1e-3;
        a.peak_pressure = 9e4;
        assert_eq!(most_pressed(&[a, b]).unwrap().node, 1);
    }
}
