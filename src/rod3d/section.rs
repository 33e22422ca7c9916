//! Cross-sections of a 3D rod. The material frame (m₁, m₂) is attached to the section: for a
//! rectangle, `h` is its extent along m₁ and `b` its extent along m₂, so a rod whose m₁ lies in
//! a plane bends in that plane with I₁ = b h³/12, exactly the planar model's `rect` section
//! (b out of the plane, h in it), and out of it with I₂ = h b³/12.

use std::f64::consts::PI;

#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Section3 {
    Rect { b: f64, h: f64 },
    Circle { r: f64 },
}

impl Section3 {
    pub fn area(&self) -> f64 {
        match *self {
            Section3::Rect { b, h } => b * h,
            Section3::Circle { r } => PI * r * r,
        }
    }

    /// Second moment for curvature κ₁ (bending about m₂, the section deflecting along m₁).
    pub fn i1(&self) -> f64 {
        match *self {
            Section3::Rect { b, h } => b * h * h * h / 12.0,
            Section3::Circle { r } => 0.25 * PI * r.powi(4),
        }
    }

    /// Second moment for curvature κ₂ (bending about m₁, the section deflecting along m₂).
    pub fn i2(&self) -> f64 {
        match *self {
            Section3::Rect { b, h } => h * b * b * b / 12.0,
            Section3::Circle { r } => 0.25 * PI * r.powi(4),
        }
    }

    /// Polar second moment I₁ + I₂ (the rotary inertia of the twist angle is ρ (I₁ + I₂) l).
    pub fn polar(&self) -> f64 {
        self.i1() + self.i2()
    }

    /// Saint-Venant torsion constant J. For a rectangle with long side a and short side c the
    /// standard series (Timoshenko & Goodier, Theory of Elasticity, §109):
    /// J = (a c³/3) [1 − (192/π⁵)(c/a) Σ_{n = 1, 3, 5, …} tanh(nπa/(2c))/n⁵],
    /// summed until a term no longer changes the sum. A circle has J = π r⁴/2.
    pub fn torsion_constant(&self) -> f64 {
        match *self {
            Section3::Rect { b, h } => {
                let (a, c) = if b >= h { (b, h) } else { (h, b) };
                let mut sum = 0.0;
                let mut n = 1.0f64;
                loop {
                    let term = (n * PI * a / (2.0 * c)).tanh() / n.powi(5);
                    if sum + term == sum {
                        break;
                    }
                    sum += term;
                    n += 2.0;
                }
                a * c * c * c / 3.0 * (1.0 - 192.0 / PI.powi(5) * (c / a) * sum)
            }
            Section3::Circle { r } => 0.5 * PI * r.powi(4),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn torsion_constant_of_a_square_and_of_a_thin_strip() {
        // Square: J = 0.1406 a⁴ (Timoshenko & Goodier's table: β = 0.141 for a/c = 1).
        let j = Section3::Rect { b: 2.0, h: 2.0 }.torsion_constant();
        assert!((j / 16.0 - 0.140577).abs() < 2e-6, "J/a⁴ = {}", j / 16.0);
        // a/c = 2: β = 0.229 (same table).
        let j2 = Section3::Rect { b: 1.0, h: 2.0 }.torsion_constant();
        assert!((j2 / 2.0 - 0.2287).abs() < 1e-4, "β = {}", j2 / 2.0);
        // A thin strip tends to a c³/3 (1 − 0.630 c/a).
        let s = Section3::Rect { b: 100.0, h: 1.0 }.torsion_constant();
        let want = 100.0 / 3.0 * (1.0 - 0.630249 / 100.0);
        assert!((s - want).abs() / want < 1e-6, "{s} vs {want}");
    }

    #[test]
    fn second_moments_swap_with_the_sides() {
        let s = Section3::Rect { b: 0.02, h: 0.01 };
        assert!((s.i1() - 0.02 * 1e-6 / 12.0).abs() < 1e-20);
        assert!((s.i2() - 0.01 * 8e-6 / 12.0).abs() < 1e-20);
    }
}
