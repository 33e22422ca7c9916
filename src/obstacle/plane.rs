use super::Proximity;

/// A half-plane: solid on the side opposite to the (unit) outward normal.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Plane {
    pub point: [f64; 2],
    pub normal: [f64; 2],
}

impl Plane {
    pub fn new(point: [f64; 2], normal: [f64; 2]) -> Self {
        Self { point, normal }
    }

    #[inline]
    pub fn query(&self, p: [f64; 2]) -> Proximity {
        let n = self.normal;
        let d = (p[0] - self.point[0]) * n[0] + (p[1] - self.point[1]) * n[1];
        Proximity {
            distance: d,
            closest: [p[0] - d * n[0], p[1] - d * n[1]],
            normal: n,
        }
    }

    /// The line clipped to a box around the scene.
    pub fn outline(&self, min: [f64; 2], max: [f64; 2]) -> Vec<[f64; 2]> {
        let t = [-self.normal[1], self.normal[0]];
        let half = ((max[0] - min[0]).powi(2) + (max[1] - min[1]).powi(2))
            .sqrt()
            .max(1e-3);
        let c = [0.5 * (min[0] + max[0]), 0.5 * (min[1] + max[1])];
        // Foot of the box centre on the line.
        let d = (c[0] - self.point[0]) * self.normal[0] + (c[1] - self.point[1]) * self.normal[1];
        let f = [c[0] - d * self.normal[0], c[1] - d * self.normal[1]];
        vec![
            [f[0] - half * t[0], f[1] - half * t[1]],
            [f[0] + half * t[0], f[1] + half * t[1]],
        ]
    }
}
