//! Elastic energies of a planar discrete elastic rod. Each element gives its energy, gradient
//! and Hessian in closed form; the tests beside each check them against finite differences
//! and against the golden values in `references.md`.

pub mod balance;
pub mod bend;
pub mod damping;
pub mod stretch;

#[cfg(test)]
pub(crate) mod fd {
    /// Central finite-difference gradient of `f` at `x`.
    pub fn gradient<const N: usize>(
        f: impl Fn(&[f64; N]) -> f64,
        x: &[f64; N],
        h: f64,
    ) -> [f64; N] {
        let mut g = [0.0; N];
        for i in 0..N {
            let mut xp = *x;
            let mut xm = *x;
            xp[i] += h;
            xm[i] -= h;
            g[i] = (f(&xp) - f(&xm)) / (2.0 * h);
        }
        g
    }

    /// Central finite-difference Jacobian of a gradient function.
    pub fn jacobian<const N: usize>(
        g: impl Fn(&[f64; N]) -> [f64; N],
        x: &[f64; N],
        h: f64,
    ) -> [[f64; N]; N] {
        let mut j = [[0.0; N]; N];
        for c in 0..N {
            let mut xp = *x;
            let mut xm = *x;
            xp[c] += h;
            xm[c] -= h;
            let (gp, gm) = (g(&xp), g(&xm));
            for r in 0..N {
                j[r][c] = (gp[r] - gm[r]) / (2.0 * h);
            }
        }
        j
    }

    /// A small deterministic pseudo-random generator for test configurations.
    pub struct Lcg(pub u64);
    impl Lcg {
        pub fn next(&mut self) -> f64 {
            self.0 = self
                .0
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((self.0 >> 11) as f64) / ((1u64 << 53) as f64)
        }
        pub fn range(&mut self, a: f64, b: f64) -> f64 {
            a + (b - a) * self.next()
        }
    }

    /// max |a − b| / max(|b|_∞, floor)
    pub fn rel_err(a: &[f64], b: &[f64], floor: f64) -> f64 {
        let scale = b.iter().fold(floor, |m, v| m.max(v.abs()));
        a.iter()
            .zip(b)
            .map(|(x, y)| (x - y).abs())
            .fold(0.0, f64::max)
            / scale
    }
}
