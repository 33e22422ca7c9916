//! Second-order forward-mode dual numbers: a value with its exact gradient and Hessian with
//! respect to `N` seeded variables. The 3D bending and twisting energies are written once,
//! generically over [`Real`], and evaluated with `f64` for the energy alone and with
//! [`Dual2`] for energy, gradient and Hessian; the derivatives are those of the very
//! expression that gives the energy (no finite differences, no truncation error), and the
//! tests still check them against finite differences.

use std::ops::{Add, Div, Mul, Neg, Sub};

/// The arithmetic the rod energies need.
pub trait Real:
    Copy
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
{
    /// A constant.
    fn cst(v: f64) -> Self;
    /// The value.
    fn val(&self) -> f64;
    fn sqrt(self) -> Self;
    fn sin(self) -> Self;
    fn cos(self) -> Self;
    fn atan(self) -> Self;
    /// Multiply by a plain number.
    fn scale(self, s: f64) -> Self;
    /// Whether the type carries derivatives (false for plain numbers).
    const DERIVATIVES: bool = true;
}

impl Real for f64 {
    const DERIVATIVES: bool = false;
    #[inline(always)]
    fn cst(v: f64) -> Self {
        v
    }
    #[inline(always)]
    fn val(&self) -> f64 {
        *self
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        f64::sqrt(self)
    }
    #[inline(always)]
    fn sin(self) -> Self {
        f64::sin(self)
    }
    #[inline(always)]
    fn cos(self) -> Self {
        f64::cos(self)
    }
    #[inline(always)]
    fn atan(self) -> Self {
        f64::atan(self)
    }
    #[inline(always)]
    fn scale(self, s: f64) -> Self {
        self * s
    }
}

/// A value with its gradient `g` and Hessian `h`. The Hessian is symmetric and only its upper
/// triangle (j ≥ i) is computed: read it with [`Dual2::hess`].
#[derive(Clone, Copy, Debug)]
pub struct Dual2<const N: usize> {
    pub v: f64,
    pub g: [f64; N],
    pub h: [[f64; N]; N],
}

impl<const N: usize> Dual2<N> {
    /// The independent variable number `i` with value `v`.
    pub fn var(v: f64, i: usize) -> Self {
        let mut d = Self::cst(v);
        d.g[i] = 1.0;
        d
    }

    /// Hessian entry (i, j), from the upper triangle.
    #[inline(always)]
    pub fn hess(&self, i: usize, j: usize) -> f64 {
        if i <= j {
            self.h[i][j]
        } else {
            self.h[j][i]
        }
    }

    /// f(self) given f, f' and f'' at the value.
    #[inline]
    fn chain(self, f: f64, d1: f64, d2: f64) -> Self {
        let mut r = Self::cst(f);
        for i in 0..N {
            r.g[i] = d1 * self.g[i];
        }
        for i in 0..N {
            let gi = d2 * self.g[i];
            for j in i..N {
                r.h[i][j] = d1 * self.h[i][j] + gi * self.g[j];
            }
        }
        r
    }

    #[inline]
    fn recip(self) -> Self {
        let r = 1.0 / self.v;
        self.chain(r, -r * r, 2.0 * r * r * r)
    }
}

impl<const N: usize> Add for Dual2<N> {
    type Output = Self;
    #[inline]
    fn add(mut self, o: Self) -> Self {
        self.v += o.v;
        for i in 0..N {
            self.g[i] += o.g[i];
            for j in i..N {
                self.h[i][j] += o.h[i][j];
            }
        }
        self
    }
}

impl<const N: usize> Sub for Dual2<N> {
    type Output = Self;
    #[inline]
    fn sub(mut self, o: Self) -> Self {
        self.v -= o.v;
        for i in 0..N {
            self.g[i] -= o.g[i];
            for j in i..N {
                self.h[i][j] -= o.h[i][j];
            }
        }
        self
    }
}

impl<const N: usize> Neg for Dual2<N> {
    type Output = Self;
    #[inline]
    fn neg(self) -> Self {
        self.scale(-1.0)
    }
}

impl<const N: usize> Mul for Dual2<N> {
    type Output = Self;
    #[inline]
    fn mul(self, o: Self) -> Self {
        let mut r = Self::cst(self.v * o.v);
        for i in 0..N {
            r.g[i] = self.v * o.g[i] + o.v * self.g[i];
        }
        for i in 0..N {
            for j in i..N {
                r.h[i][j] = self.v * o.h[i][j]
                    + o.v * self.h[i][j]
                    + self.g[i] * o.g[j]
                    + o.g[i] * self.g[j];
            }
        }
        r
    }
}

impl<const N: usize> Div for Dual2<N> {
    type Output = Self;
    /// a / b = a · (1/b), the reciprocal carrying its own second-order chain rule.
    #[inline]
    #[allow(clippy::suspicious_arithmetic_impl)]
    fn div(self, o: Self) -> Self {
        self * o.recip()
    }
}

impl<const N: usize> Real for Dual2<N> {
    #[inline]
    fn cst(v: f64) -> Self {
        Self {
            v,
            g: [0.0; N],
            h: [[0.0; N]; N],
        }
    }
    #[inline(always)]
    fn val(&self) -> f64 {
        self.v
    }
    #[inline]
    fn sqrt(self) -> Self {
        let s = self.v.sqrt();
        self.chain(s, 0.5 / s, -0.25 / (s * self.v))
    }
    #[inline]
    fn sin(self) -> Self {
        let (s, c) = self.v.sin_cos();
        self.chain(s, c, -s)
    }
    #[inline]
    fn cos(self) -> Self {
        let (s, c) = self.v.sin_cos();
        self.chain(c, -s, -c)
    }
    #[inline]
    fn atan(self) -> Self {
        let d = 1.0 / (1.0 + self.v * self.v);
        self.chain(self.v.atan(), d, -2.0 * self.v * d * d)
    }
    #[inline]
    fn scale(mut self, s: f64) -> Self {
        self.v *= s;
        for i in 0..N {
            self.g[i] *= s;
            for j in i..N {
                self.h[i][j] *= s;
            }
        }
        self
    }
}

/// Three-vectors over any [`Real`].
pub type V3<T> = [T; 3];

#[inline]
pub fn add<T: Real>(a: V3<T>, b: V3<T>) -> V3<T> {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}
#[inline]
pub fn sub<T: Real>(a: V3<T>, b: V3<T>) -> V3<T> {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
#[inline]
pub fn dot<T: Real>(a: V3<T>, b: V3<T>) -> T {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
#[inline]
pub fn cross<T: Real>(a: V3<T>, b: V3<T>) -> V3<T> {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}
#[inline]
pub fn mul<T: Real>(s: T, a: V3<T>) -> V3<T> {
    [s * a[0], s * a[1], s * a[2]]
}
#[inline]
pub fn lift<T: Real>(a: [f64; 3]) -> V3<T> {
    [T::cst(a[0]), T::cst(a[1]), T::cst(a[2])]
}
#[inline]
pub fn vals<T: Real>(a: V3<T>) -> [f64; 3] {
    [a[0].val(), a[1].val(), a[2].val()]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn derivatives_of_a_composite_expression_are_exact() {
        // f(x, y) = sin(x y) / sqrt(1 + x²) + atan(y), at (0.7, -1.3).
        let f =
            |x: Dual2<2>, y: Dual2<2>| (x * y).sin() / (Dual2::cst(1.0) + x * x).sqrt() + y.atan();
        let (x, y) = (0.7, -1.3);
        let d = f(Dual2::var(x, 0), Dual2::var(y, 1));
        let s = (1.0f64 + x * x).sqrt();
        let (sn, cs) = (x * y).sin_cos();
        let fx = y * cs / s - sn * x / (s * s * s);
        let fy = x * cs / s + 1.0 / (1.0 + y * y);
        let fyy = -x * x * sn / s - 2.0 * y / ((1.0 + y * y) * (1.0 + y * y));
        assert!((d.g[0] - fx).abs() < 1e-14, "{} {}", d.g[0], fx);
        assert!((d.g[1] - fy).abs() < 1e-14);
        assert!((d.hess(1, 1) - fyy).abs() < 1e-14);
        let fxy = cs / s - x * y * sn / s - x * x * cs / (s * s * s);
        assert!(
            (d.hess(1, 0) - fxy).abs() < 1e-14,
            "{} {}",
            d.hess(1, 0),
            fxy
        );
    }
}
