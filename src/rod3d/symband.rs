//! Symmetric banded matrices for the 3D rod: assembly straight into the band and a banded
//! Cholesky factorisation.
//!
//! The Jacobian of a dynamic 3D rod step without contact, c M + ∇²E with identity rows and
//! columns on fixed DOFs, is symmetric and (for a stable step) positive definite. A banded
//! Cholesky factor with half-bandwidth k = 10 costs about k²/2 multiply-adds per DOF, against
//! about k (2k) for LU with partial pivoting in LAPACK band storage (which also keeps room for
//! the pivoting fill): roughly 4× less. When the matrix is not positive definite (a static
//! solve past a buckling load, a huge step) [`SymBand::factor`] says so and the caller falls
//! back to [`BandLu`].

use crate::solver::banded::BandLu;

/// Something the assembly can add Hessian entries to.
pub trait BandSink {
    /// Add `v` to A[i][j].
    fn add(&mut self, i: usize, j: usize, v: f64);
    /// Add the dense block `h` at rows and columns `base .. base + N` (all inside the band).
    fn add_block<const N: usize>(&mut self, base: usize, h: &[[f64; N]; N]);
}

impl BandSink for BandLu {
    #[inline(always)]
    fn add(&mut self, i: usize, j: usize, v: f64) {
        BandLu::add(self, i, j, v);
    }
    #[inline]
    fn add_block<const N: usize>(&mut self, base: usize, h: &[[f64; N]; N]) {
        for (i, row) in h.iter().enumerate() {
            for (j, v) in row.iter().enumerate() {
                BandLu::add(self, base + i, base + j, *v);
            }
        }
    }
}

/// A symmetric band matrix of half-bandwidth `k`, lower triangle stored by rows
/// (row i holds columns i − k … i), factorised in place as L Lᵀ.
#[derive(Debug, Clone)]
pub struct SymBand {
    n: usize,
    k: usize,
    a: Vec<f64>,
}

impl SymBand {
    pub fn new(n: usize, k: usize) -> SymBand {
        SymBand {
            n,
            k,
            a: vec![0.0; n * (k + 1)],
        }
    }

    pub fn dim(&self) -> usize {
        self.n
    }

    pub fn clear(&mut self) {
        self.a.fill(0.0);
    }

    /// Storage index of (i, j), j ≤ i ≤ j + k.
    #[inline(always)]
    fn at(&self, i: usize, j: usize) -> usize {
        i * (self.k + 1) + self.k + j - i
    }

    /// A[i][j] (symmetric; zero outside the band). Before [`SymBand::factor`] only.
    pub fn get(&self, i: usize, j: usize) -> f64 {
        let (i, j) = if i >= j { (i, j) } else { (j, i) };
        if i - j > self.k || i >= self.n {
            return 0.0;
        }
        self.a[self.at(i, j)]
    }

    /// Load the lower band of `a` (before its factorisation), a symmetric matrix of the same
    /// dimension and half-bandwidth at most `k`.
    pub fn copy_lower(&mut self, a: &BandLu) {
        debug_assert_eq!(a.dim(), self.n);
        for i in 0..self.n {
            for j in i.saturating_sub(self.k)..=i {
                let at = self.at(i, j);
                self.a[at] = a.get(i, j);
            }
        }
    }

    /// Factorise A = L Lᵀ in place. Err(i) if the pivot of row i is not positive (A is not
    /// positive definite); the storage is then spoilt and must be reassembled.
    pub fn factor(&mut self) -> Result<(), usize> {
        let (n, k, w) = (self.n, self.k, self.k + 1);
        for i in 0..n {
            let lo = i.saturating_sub(k);
            let ri = i * w + k - i; // row i's storage origin: (i, j) at ri + j
            for j in lo..=i {
                let rj = j * w + k - j;
                let mut s = self.a[ri + j];
                let (li, lj) = (&self.a[ri + lo..ri + j], &self.a[rj + lo..rj + j]);
                for (x, y) in li.iter().zip(lj) {
                    s -= x * y;
                }
                if j < i {
                    self.a[ri + j] = s / self.a[rj + j];
                } else {
                    if s.is_nan() || s <= 0.0 {
                        return Err(i);
                    }
                    self.a[ri + i] = s.sqrt();
                }
            }
        }
        Ok(())
    }

    /// Solve A x = b with the factor, in place.
    pub fn solve(&self, b: &mut [f64]) {
        let (n, k, w) = (self.n, self.k, self.k + 1);
        for i in 0..n {
            let lo = i.saturating_sub(k);
            let ri = i * w + k - i;
            let mut s = b[i];
            for j in lo..i {
                s -= self.a[ri + j] * b[j];
            }
            b[i] = s / self.a[ri + i];
        }
        for i in (0..n).rev() {
            let ri = i * w + k - i;
            b[i] /= self.a[ri + i];
            let bi = b[i];
            for j in i.saturating_sub(k)..i {
                b[j] -= self.a[ri + j] * bi;
            }
        }
    }
}

impl BandSink for SymBand {
    /// Only the lower triangle is kept: entries above the diagonal are dropped (the
    /// assembly adds both of a symmetric pair).
    #[inline(always)]
    fn add(&mut self, i: usize, j: usize, v: f64) {
        if j <= i {
            debug_assert!(i - j <= self.k, "({i},{j}) outside the band");
            let at = self.at(i, j);
            self.a[at] += v;
        }
    }
    #[inline]
    fn add_block<const N: usize>(&mut self, base: usize, h: &[[f64; N]; N]) {
        debug_assert!(N <= self.k + 1 && base + N <= self.n);
        for (i, row) in h.iter().enumerate() {
            let r = self.at(base + i, base);
            for (j, v) in row[..=i].iter().enumerate() {
                self.a[r + j] += v;
            }
        }
    }
}
