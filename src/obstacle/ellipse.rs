use super::{norm, Proximity};

/// A rigid ellipse with semi-axes `a` (along the rotated x axis) and `b`, rotated by `angle` (rad).
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Ellipse {
    pub center: [f64; 2],
    pub a: f64,
    pub b: f64,
    pub angle: f64,
}

impl Ellipse {
    pub fn new(center: [f64; 2], a: f64, b: f64, angle: f64) -> Self {
        Self {
            center,
            a,
            b,
            angle,
        }
    }

    pub fn lower_bound(&self, p: [f64; 2]) -> f64 {
        norm([p[0] - self.center[0], p[1] - self.center[1]]) - self.a.max(self.b)
    }

    /// Closest point by Eberly's robust bisection ("Distance from a point to an ellipse"),
    /// in the ellipse's frame, first quadrant, major axis first.
    pub fn query(&self, p: [f64; 2]) -> Proximity {
        let (s, c) = self.angle.sin_cos();
        let d = [p[0] - self.center[0], p[1] - self.center[1]];
        let local = [c * d[0] + s * d[1], -s * d[0] + c * d[1]];
        let swap = self.a < self.b;
        let (e0, e1) = if swap {
            (self.b, self.a)
        } else {
            (self.a, self.b)
        };
        let (y0, y1) = if swap {
            (local[1], local[0])
        } else {
            (local[0], local[1])
        };
        let (sx, sy) = (y0.signum(), y1.signum());
        let (x0, x1) = closest_first_quadrant(e0, e1, y0.abs(), y1.abs());
        let (x0, x1) = (x0 * sx, x1 * sy);
        // Outward normal ∝ (x0/e0², x1/e1²).
        let g = [x0 / (e0 * e0), x1 / (e1 * e1)];
        let gl = norm(g);
        let nl = [g[0] / gl, g[1] / gl];
        let inside = (y0 / e0).powi(2) + (y1 / e1).powi(2) < 1.0;
        let dist = ((x0 - y0).powi(2) + (x1 - y1).powi(2)).sqrt();
        let (cl, nl) = if swap {
            ([x1, x0], [nl[1], nl[0]])
        } else {
            ([x0, x1], nl)
        };
        let to_world = |v: [f64; 2]| [c * v[0] - s * v[1], s * v[0] + c * v[1]];
        let cw = to_world(cl);
        Proximity {
            distance: if inside { -dist } else { dist },
            closest: [cw[0] + self.center[0], cw[1] + self.center[1]],
            normal: to_world(nl),
        }
    }

    pub fn outline(&self) -> Vec<[f64; 2]> {
        let (s, c) = self.angle.sin_cos();
        let n = 180;
        (0..=n)
            .map(|i| {
                let t = std::f64::consts::TAU * i as f64 / n as f64;
                let (x, y) = (self.a * t.cos(), self.b * t.sin());
                [
                    self.center[0] + c * x - s * y,
                    self.center[1] + s * x + c * y,
                ]
            })
            .collect()
    }
}

fn closest_first_quadrant(e0: f64, e1: f64, y0: f64, y1: f64) -> (f64, f64) {
    if y1 > 0.0 {
        if y0 > 0.0 {
            let z0 = y0 / e0;
            let z1 = y1 / e1;
            let g = z0 * z0 + z1 * z1 - 1.0;
            if g != 0.0 {
                let r0 = (e0 / e1).powi(2);
                let sbar = root(r0, z0, z1, g);
                (r0 * y0 / (sbar + r0), y1 / (sbar + 1.0))
            } else {
                (y0, y1)
            }
        } else {
            (0.0, e1)
        }
    } else {
        let numer0 = e0 * y0;
        let denom0 = e0 * e0 - e1 * e1;
        if numer0 < denom0 {
            let xde0 = numer0 / denom0;
            (e0 * xde0, e1 * (1.0 - xde0 * xde0).max(0.0).sqrt())
        } else {
            (e0, 0.0)
        }
    }
}

fn root(r0: f64, z0: f64, z1: f64, g: f64) -> f64 {
    let n0 = r0 * z0;
    let mut s0 = z1 - 1.0;
    let mut s1 = if g < 0.0 {
        0.0
    } else {
        (n0 * n0 + z1 * z1).sqrt() - 1.0
    };
    let mut s = 0.0;
    for _ in 0..1100 {
        s = 0.5 * (s0 + s1);
        if s == s0 || s == s1 {
            break;
        }
        let ratio0 = n0 / (s + r0);
        let ratio1 = z1 / (s + 1.0);
        let gs = ratio0 * ratio0 + ratio1 * ratio1 - 1.0;
        if gs > 0.0 {
            s0 = s;
        } else if gs < 0.0 {
            s1 = s;
        } else {
            break;
        }
    }
    s
}
