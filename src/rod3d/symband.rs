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
use nalgebra::Matrix3;

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
    /// After [`SymBand::factor`]: the reciprocals of L's diagonal (multiplications instead
    /// of divisions in the factorisation and the solves).
    inv: Vec<f64>,
}

impl SymBand {
    pub fn new(n: usize, k: usize) -> SymBand {
        SymBand {
            n,
            k,
            a: vec![0.0; n * (k + 1)],
            inv: vec![0.0; n],
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

    /// Copy `other` (same dimension and bandwidth) into this storage.
    pub fn copy_from(&mut self, other: &SymBand) {
        debug_assert!(self.n == other.n && self.k == other.k);
        self.a.copy_from_slice(&other.a);
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

    /// Set A[i][j] = A[j][i] = v (inside the band).
    #[inline(always)]
    fn set(&mut self, i: usize, j: usize, v: f64) {
        let (i, j) = if i >= j { (i, j) } else { (j, i) };
        debug_assert!(i - j <= self.k, "({i},{j}) outside the band");
        let at = self.at(i, j);
        self.a[at] = v;
    }

    /// Rotate the position block `k0..k0+3` of a node into the basis whose rows are `q`
    /// (A ← Q A Qᵀ on that block row and column). A node couples only with columns
    /// k0 − 8 … k0 + 10 (three-node stencils, four DOFs per node), inside the band.
    pub fn rotate_node(&mut self, k0: usize, q: &Matrix3<f64>) {
        let (lo, hi) = (k0.saturating_sub(8), (k0 + 10).min(self.n - 1));
        for l in (lo..=hi).filter(|l| !(k0..k0 + 3).contains(l)) {
            let old = [self.get(k0, l), self.get(k0 + 1, l), self.get(k0 + 2, l)];
            for r in 0..3 {
                let v = q[(r, 0)] * old[0] + q[(r, 1)] * old[1] + q[(r, 2)] * old[2];
                self.set(k0 + r, l, v);
            }
        }
        let b: [[f64; 3]; 3] =
            std::array::from_fn(|i| std::array::from_fn(|j| self.get(k0 + i, k0 + j)));
        for r in 0..3 {
            for c in 0..=r {
                let mut v = 0.0;
                for s in 0..3 {
                    for t in 0..3 {
                        v += q[(r, s)] * b[s][t] * q[(c, t)];
                    }
                }
                self.set(k0 + r, k0 + c, v);
            }
        }
    }

    /// Make coordinate j prescribed: its column (= row) leaves the matrix, the rows `l` not in
    /// `elim` adding A[l][j] to the border column `border` when j follows a body, and its
    /// diagonal becomes 1. `rows` are the rows that can couple with j.
    pub fn eliminate(
        &mut self,
        j: usize,
        rows: std::ops::RangeInclusive<usize>,
        mut border: Option<&mut [f64]>,
        elim: &[bool],
    ) {
        for l in rows.filter(|&l| l != j) {
            let v = self.get(l, j);
            if v == 0.0 {
                continue;
            }
            if let Some(col) = border.as_deref_mut() {
                if !elim[l] {
                    col[l] += v;
                }
            }
            self.set(l, j, 0.0);
        }
        self.set(j, j, 1.0);
    }

    /// The full (both triangles) matrix into `lu`, cleared first: the general band for an LU
    /// factorisation when this one is not positive definite.
    pub fn expand_into(&self, lu: &mut BandLu) {
        lu.clear();
        for i in 0..self.n {
            for j in i.saturating_sub(self.k)..=i {
                let v = self.a[self.at(i, j)];
                lu.add(i, j, v);
                if i != j {
                    lu.add(j, i, v);
                }
            }
        }
    }

    /// Factorise A = L Lᵀ in place. Err(i) if the pivot of row i is not positive (A is not
    /// positive definite); the storage is then spoilt and must be reassembled.
    pub fn factor(&mut self) -> Result<(), usize> {
        if self.k == K {
            return self.factor_by_columns();
        }
        let (n, k, w) = (self.n, self.k, self.k + 1);
        for i in 0..n {
            let lo = i.saturating_sub(k);
            let ri = i * w + k - i; // row i's storage origin: (i, j) at ri + j
            for j in lo..=i {
                let rj = j * w + k - j;
                let (li, lj) = (&self.a[ri + lo..ri + j], &self.a[rj + lo..rj + j]);
                let s = self.a[ri + j] - dot(li, lj);
                self.set_factor_entry(i, j, ri + j, s)?;
            }
        }
        Ok(())
    }

    /// [`SymBand::factor`] at the rods' bandwidth K, column by column (right-looking): column
    /// j of L is A's column scaled by its pivot, then the K × K triangle after it loses
    /// L[·][j] L[·][j]ᵀ. Row by row each entry of L waits for the one before it (a chain of
    /// dependent dot products, latency-bound); here the 55 updates of a column are
    /// independent. A column that is zero below its pivot (a fixed or eliminated DOF) updates
    /// nothing.
    fn factor_by_columns(&mut self) -> Result<(), usize> {
        let n = self.n;
        let a = &mut self.a;
        for j in 0..n {
            let s = a[j * W + K];
            if s.is_nan() || s <= 0.0 {
                return Err(j);
            }
            let d = s.sqrt();
            let inv = 1.0 / d;
            a[j * W + K] = d;
            self.inv[j] = inv;
            // L[j + 1 + t][j] at (j + 1 + t)·W + K − (t + 1).
            let m = K.min(n - 1 - j);
            let mut col = [0.0; K];
            let mut any = false;
            for (t, c) in col.iter_mut().enumerate().take(m) {
                let at = (j + 1 + t) * W + K - (t + 1);
                let v = a[at] * inv;
                a[at] = v;
                *c = v;
                any |= v != 0.0;
            }
            if !any {
                continue;
            }
            for (t, &lij) in col.iter().enumerate().take(m) {
                if lij == 0.0 {
                    continue;
                }
                // Row j + 1 + t, columns j + 1 … j + 1 + t.
                let base = (j + 1 + t) * W + K - t;
                for (x, c) in a[base..=base + t].iter_mut().zip(&col) {
                    *x -= lij * c;
                }
            }
        }
        Ok(())
    }

    /// L[i][j] from s = A[i][j] − Σ L[i][c] L[j][c] (storage index `at`); on the diagonal
    /// the pivot must be positive.
    #[inline(always)]
    fn set_factor_entry(&mut self, i: usize, j: usize, at: usize, s: f64) -> Result<(), usize> {
        if j < i {
            self.a[at] = s * self.inv[j];
            return Ok(());
        }
        if s.is_nan() || s <= 0.0 {
            return Err(i);
        }
        let d = s.sqrt();
        self.a[at] = d;
        self.inv[i] = 1.0 / d;
        Ok(())
    }

    /// Solve A x = b with the factor, in place.
    pub fn solve(&self, b: &mut [f64]) {
        let (n, k, w) = (self.n, self.k, self.k + 1);
        let start = if k == K { n.min(K) } else { n };
        for i in 0..start {
            let lo = i.saturating_sub(k);
            let ri = i * w + k - i;
            let s = b[i] - dot(&self.a[ri + lo..ri + i], &b[lo..i]);
            b[i] = s * self.inv[i];
        }
        for i in start..n {
            // b[i − 1] was found just before: its product last, so that the older terms'
            // sum does not wait for it (the substitution is a chain of dependent rows).
            let row = &self.a[i * W..i * W + K];
            let s = b[i] - dotn::<{ K - 1 }>(row, &b[i - K..]);
            b[i] = (s - row[K - 1] * b[i - 1]) * self.inv[i];
        }
        for i in (0..n).rev() {
            b[i] *= self.inv[i];
            self.axpy_row(i, b);
        }
    }

    /// b[j] −= L[i][j] b[i] for the columns j < i of row i (the backward substitution's
    /// column of Lᵀ).
    #[inline(always)]
    fn axpy_row(&self, i: usize, b: &mut [f64]) {
        let bi = b[i];
        if self.k == K && i >= K {
            let row: &[f64; K] = self.a[i * W..i * W + K].try_into().unwrap();
            let x: &mut [f64; K] = (&mut b[i - K..i]).try_into().unwrap();
            for (x, l) in x.iter_mut().zip(row) {
                *x -= l * bi;
            }
            return;
        }
        let (k, w) = (self.k, self.k + 1);
        let ri = i * w + k - i;
        let lo = i.saturating_sub(k);
        for (x, l) in b[lo..i].iter_mut().zip(&self.a[ri + lo..ri + i]) {
            *x -= l * bi;
        }
    }

    /// Solve A X = B for several right-hand sides in one pass over the factor, in place.
    /// Rows before `first` must be zero in every column (the forward pass starts there).
    pub fn solve_many<C: AsMut<[f64]>>(&self, cols: &mut [C], first: usize) {
        let (n, k, w) = (self.n, self.k, self.k + 1);
        for i in first..n {
            let lo = i.saturating_sub(k).max(first);
            let ri = i * w + k - i;
            let row = &self.a[ri + lo..ri + i];
            if k == K && lo + K == i {
                for b in cols.iter_mut() {
                    let b = b.as_mut();
                    let s = b[i] - dotn::<K>(row, &b[lo..]);
                    b[i] = s * self.inv[i];
                }
                continue;
            }
            for b in cols.iter_mut() {
                let b = b.as_mut();
                let s = b[i] - dot(row, &b[lo..i]);
                b[i] = s * self.inv[i];
            }
        }
        for i in (0..n).rev() {
            for b in cols.iter_mut() {
                let b = b.as_mut();
                b[i] *= self.inv[i];
                self.axpy_row(i, b);
            }
        }
    }
}

/// The half-bandwidth of the rods' matrices (three-node stencils, four DOFs a node), which
/// the factorisation and the solves unroll, and its row width.
const K: usize = 10;
const W: usize = K + 1;

/// x·y of two short slices of equal length, in four independent sums (the band's dot
/// products are at most k long: one chain of dependent additions would be latency-bound).
#[inline(always)]
fn dot(x: &[f64], y: &[f64]) -> f64 {
    let n = x.len().min(y.len());
    let (x, y) = (&x[..n], &y[..n]);
    let mut acc = [0.0; 4];
    let mut i = 0;
    while i + 4 <= n {
        for (a, c) in acc.iter_mut().enumerate() {
            *c += x[i + a] * y[i + a];
        }
        i += 4;
    }
    while i < n {
        acc[0] += x[i] * y[i];
        i += 1;
    }
    (acc[0] + acc[1]) + (acc[2] + acc[3])
}

/// [`dot`] of the first N entries, N known at compile time (unrolled; the same sums in the
/// same order, so the same result to the bit).
#[inline(always)]
fn dotn<const N: usize>(x: &[f64], y: &[f64]) -> f64 {
    let x: &[f64; N] = x[..N].try_into().unwrap();
    let y: &[f64; N] = y[..N].try_into().unwrap();
    let mut acc = [0.0; 4];
    for i in 0..N {
        acc[if i < N / 4 * 4 { i % 4 } else { 0 }] += x[i] * y[i];
    }
    (acc[0] + acc[1]) + (acc[2] + acc[3])
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
