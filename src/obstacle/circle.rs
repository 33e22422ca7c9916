use super::{norm, Proximity};

/// A rigid disc: the seed's fruit.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Circle {
    pub center: [f64; 2],
    pub radius: f64,
}

impl Circle {
    pub fn new(center: [f64; 2], radius: f64) -> Self {
        Self { center, radius }
    }

    #[inline]
    pub fn query(&self, p: [f64; 2]) -> Proximity {
        let d = [p[0] - self.center[0], p[1] - self.center[1]];
        let len = norm(d);
        // At the exact centre every direction is closest; pick +x deterministically.
        let n = if len > 0.0 {
            [d[0] / len, d[1] / len]
        } else {
            [1.0, 0.0]
        };
        Proximity {
            distance: len - self.radius,
            closest: [
                self.center[0] + self.radius * n[0],
                self.center[1] + self.radius * n[1],
            ],
            normal: n,
        }
    }

    pub fn outline(&self) -> Vec<[f64; 2]> {
        let n = 180;
        (0..=n)
            .map(|i| {
                let a = std::f64::consts::TAU * i as f64 / n as f64;
                [
                    self.center[0] + self.radius * a.cos(),
                    self.center[1] + self.radius * a.sin(),
                ]
            })
            .collect()
    }
}
