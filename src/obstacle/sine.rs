use super::Proximity;

/// The surface y = A sin(k x) + c, solid below it.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Sine {
    pub amplitude: f64,
    pub wavenumber: f64,
    pub offset: f64,
}

impl Sine {
    pub fn new(amplitude: f64, wavenumber: f64, offset: f64) -> Self {
        Self {
            amplitude,
            wavenumber,
            offset,
        }
    }

    #[inline]
    fn f(&self, x: f64) -> (f64, f64, f64) {
        let (s, c) = (self.wavenumber * x).sin_cos();
        let a = self.amplitude;
        let k = self.wavenumber;
        (a * s + self.offset, a * k * c, -a * k * k * s)
    }

    /// Closest point by a safeguarded Newton iteration on d/dx |p − (x, f(x))|² = 0, started
    /// at the point's own x. Exact for the nodes near the surface that contact cares about.
    pub fn query(&self, p: [f64; 2]) -> Proximity {
        let (fy, _, _) = self.f(p[0]);
        let above = p[1] >= fy;
        let mut x = p[0];
        let k = self.wavenumber.max(1e-300);
        let max_step = 0.25 / k;
        for _ in 0..50 {
            let (y, d1, d2) = self.f(x);
            let g = (x - p[0]) + (y - p[1]) * d1;
            let h = 1.0 + d1 * d1 + (y - p[1]) * d2;
            let mut step = if h > 1e-12 { -g / h } else { -g };
            if step.abs() > max_step {
                step = max_step * step.signum();
            }
            x += step;
            if step.abs() <= 1e-15 * (1.0 + x.abs()) {
                break;
            }
        }
        let (y, d1, _) = self.f(x);
        let s = (1.0 + d1 * d1).sqrt();
        let n = [-d1 / s, 1.0 / s];
        let dist = ((p[0] - x).powi(2) + (p[1] - y).powi(2)).sqrt();
        let distance = if above { dist } else { -dist };
        Proximity {
            distance,
            closest: [x, y],
            normal: n,
        }
    }

    /// y − (c + |A|) never exceeds the signed distance.
    #[inline]
    pub fn lower_bound(&self, p: [f64; 2]) -> f64 {
        p[1] - (self.offset + self.amplitude.abs())
    }

    pub fn outline(&self, min: [f64; 2], max: [f64; 2]) -> Vec<[f64; 2]> {
        let (x0, x1) = (min[0], max[0].max(min[0] + 1e-6));
        let wavelength = if self.wavenumber > 0.0 {
            std::f64::consts::TAU / self.wavenumber
        } else {
            x1 - x0
        };
        let n = (((x1 - x0) / wavelength * 40.0).ceil() as usize).clamp(64, 20_000);
        (0..=n)
            .map(|i| {
                let x = x0 + (x1 - x0) * i as f64 / n as f64;
                [x, self.f(x).0]
            })
            .collect()
    }
}
