//! The Newton system of one 3D step with contacts: every rod's banded Jacobian in the local
//! contact bases of its contact nodes, the prescribed coordinates eliminated (identity rows),
//! and the free bodies' unknowns ΔX coupled in by a bordered solve (Schur complement):
//!
//! [A_r  B_r] [y_r]   [f_r]      A_r banded (one per rod), B_r the columns of the prescribed
//! [C_r  S  ] [δX ] = [f_b]      coordinates that follow a body (δu_j = P_j δX), C_r the rows
//!                                Gᵀ Qᵀ of the nodes touching a body (the reaction on the body).
//!
//! δX = (S − Σ C_r A_r⁻¹ B_r)⁻¹ (f_b − Σ C_r A_r⁻¹ f_r), then y_r = A_r⁻¹ (f_r − B_r δX).
//! A body's contacts with fixed obstacles add Lagrange multipliers to the small dense system.
//! A_r is symmetric but for the kinetic friction rows of sliding nodes ([`KineticRow`]): its
//! symmetric part is factored by banded Cholesky and the rows enter by the Woodbury identity.

use super::symband::SymBand;
use crate::solver::banded::BandLu;
use nalgebra::{DMatrix, DVector};

/// The rows around `k` that can couple with it (the band of a node block).
#[inline]
pub fn band_range(n: usize, k: usize) -> std::ops::RangeInclusive<usize> {
    let k0 = k - k % 4;
    k0.saturating_sub(8)..=(k0 + 10).min(n - 1)
}

/// A kinetic friction row of a sliding node: the node's t₁ row `row` of the rod's equations
/// becomes t₁·R + μ_k n·R, i.e. gains μ × `n`, the node's normal row of the Jacobian on the
/// free columns (its prescribed columns are in the border already). The only unsymmetric
/// part of a rod block: it stays out of the banded matrix, which keeps its Cholesky factor,
/// and enters as a low-rank update (Woodbury).
#[derive(Debug, Clone, Default)]
pub struct KineticRow {
    pub row: usize,
    pub mu: f64,
    pub n: Vec<(usize, f64)>,
}

/// The factors of one rod block, storage kept from call to call.
#[derive(Debug, Clone)]
pub struct BlockFactor {
    chol: SymBand,
    lu: BandLu,
    use_lu: bool,
    /// Y = S⁻¹ U for the kinetic rows (U's columns μ e_row, S the symmetric part) and the LU
    /// of the capacitance matrix I + Vᵀ Y (V's columns the rows' `n`).
    y: Vec<Vec<f64>>,
    cap: Option<nalgebra::LU<f64, nalgebra::Dyn, nalgebra::Dyn>>,
}

impl BlockFactor {
    /// Storage for a rod block of dimension n (half-bandwidth 10).
    pub fn new(n: usize) -> BlockFactor {
        BlockFactor {
            chol: SymBand::new(n, 10),
            lu: BandLu::new(n, 10, 10),
            use_lu: false,
            y: Vec::new(),
            cap: None,
        }
    }
}

/// One rod's part of the bordered system.
pub struct RodBlock<'a> {
    /// The symmetric part S of the rod's matrix A (lower band).
    pub a: &'a SymBand,
    /// A's kinetic rows: A = S + Σ μ e_row nᵀ.
    pub kinetic: &'a [KineticRow],
    pub factor: &'a mut BlockFactor,
    pub rhs: &'a mut [f64],
    pub border: &'a [Vec<f64>],
    /// Storage for Z = A⁻¹ B (one column per body unknown), kept between calls.
    pub z: &'a mut Vec<Vec<f64>>,
    /// Rows of the body equations: (body row 0..6nb, column, value).
    pub rows: &'a [(usize, usize, f64)],
}

impl RodBlock<'_> {
    /// Factor A: S by banded Cholesky (about a quarter of the work of LU), the kinetic rows
    /// by the Woodbury identity (one solve each); LU of the whole of A when S is not
    /// positive definite.
    fn factor(&mut self) -> Result<(), &'static str> {
        let f = &mut *self.factor;
        f.use_lu = false;
        f.cap = None;
        f.chol.copy_from(self.a);
        if f.chol.factor().is_err() {
            return self.factor_lu();
        }
        let m = self.kinetic.len();
        if m == 0 {
            return Ok(());
        }
        f.y.resize_with(m, Vec::new);
        for (y, k) in f.y.iter_mut().zip(self.kinetic) {
            y.clear();
            y.resize(self.a.dim(), 0.0);
            y[k.row] = k.mu;
            f.chol.solve(y);
        }
        let cap = DMatrix::from_fn(m, m, |i, j| {
            let vy: f64 = self.kinetic[i].n.iter().map(|&(l, v)| v * f.y[j][l]).sum();
            vy + if i == j { 1.0 } else { 0.0 }
        })
        .lu();
        if !cap.is_invertible() {
            return self.factor_lu();
        }
        f.cap = Some(cap);
        Ok(())
    }

    /// The whole of A (S and the kinetic rows) by LU with pivoting.
    fn factor_lu(&mut self) -> Result<(), &'static str> {
        let f = &mut *self.factor;
        self.a.expand_into(&mut f.lu);
        for k in self.kinetic {
            for &(l, v) in &k.n {
                f.lu.add(k.row, l, k.mu * v);
            }
        }
        f.lu.factor().map_err(|_| "singular Jacobian")?;
        f.use_lu = true;
        f.cap = None;
        Ok(())
    }

    /// Solve A x = b in place with the factor.
    fn solve_in(&self, b: &mut [f64]) {
        if self.factor.use_lu {
            self.factor.lu.solve(b);
            return;
        }
        self.factor.chol.solve(b);
        self.woodbury(b);
    }

    /// Several columns at once (rows before `first` zero in all of them).
    fn solve_many(&self, cols: &mut [&mut [f64]], first: usize) {
        if self.factor.use_lu {
            cols.iter_mut().for_each(|b| self.factor.lu.solve(b));
            return;
        }
        self.factor.chol.solve_many(cols, first);
        cols.iter_mut().for_each(|b| self.woodbury(b));
    }

    /// From x = S⁻¹b to A⁻¹b: (S + U Vᵀ)⁻¹ b = S⁻¹b − Y (I + Vᵀ Y)⁻¹ Vᵀ S⁻¹b.
    fn woodbury(&self, b: &mut [f64]) {
        let f = &*self.factor;
        let Some(cap) = &f.cap else { return };
        let vb = DVector::from_iterator(
            self.kinetic.len(),
            self.kinetic
                .iter()
                .map(|k| k.n.iter().map(|&(l, v)| v * b[l]).sum::<f64>()),
        );
        let w = cap.solve(&vb).expect("invertible capacitance");
        for (y, wi) in f.y.iter().zip(w.iter()) {
            for (bj, yj) in b.iter_mut().zip(y) {
                *bj -= wi * yj;
            }
        }
    }
}

/// Solve the bordered system. `s` and `fb` are the bodies' block (with the D terms already in);
/// `kkt` are extra constraint rows on ΔX with their force columns: (row J, column K, value):
/// S δX + Σ K λ = f_b, J δX = v. Returns δX and λ; each rod's `rhs` becomes its y.
pub fn solve_bordered(
    rods: &mut [RodBlock<'_>],
    s: &DMatrix<f64>,
    fb: &DVector<f64>,
    kkt: &[(Vec<f64>, Vec<f64>, f64)],
) -> Result<(DVector<f64>, DVector<f64>), &'static str> {
    let nx = fb.len();
    for r in rods.iter_mut() {
        r.factor()?;
        let rhs = std::mem::take(&mut r.rhs);
        r.solve_in(rhs);
        r.rhs = rhs;
    }
    if nx == 0 {
        return Ok((DVector::zeros(0), DVector::zeros(0)));
    }
    let nk = kkt.len();
    let mut m = DMatrix::zeros(nx + nk, nx + nk);
    let mut f = DVector::zeros(nx + nk);
    m.view_mut((0, 0), (nx, nx)).copy_from(s);
    f.rows_mut(0, nx).copy_from(fb);
    for r in rods.iter_mut() {
        let n = r.rhs.len();
        // Z = A⁻¹ B, column by column (into storage kept from step to step).
        // The nonzero columns solved together, from their first nonzero row.
        let mut zr = std::mem::take(&mut *r.z);
        zr.resize_with(nx, Vec::new);
        // The border row by row (one pass over its rows), each column's first nonzero row.
        let mut top = vec![n; nx];
        zr.iter_mut().for_each(|col| col.resize(n, 0.0));
        for (l, row) in r.border.iter().enumerate() {
            for (c, &v) in row.iter().enumerate().take(nx) {
                zr[c][l] = v;
                if v != 0.0 && top[c] == n {
                    top[c] = l;
                }
            }
        }
        let first = top.iter().copied().min().unwrap_or(n);
        let mut active: Vec<&mut [f64]> = zr
            .iter_mut()
            .zip(&top)
            .filter(|(_, &t)| t < n)
            .map(|(col, _)| col.as_mut_slice())
            .collect();
        r.solve_many(&mut active, first);
        drop(active);
        // C Z: row l of Z gathered once for the consecutive entries of a column l.
        let (mrows, ms) = (m.nrows(), m.as_mut_slice());
        let mut zl = vec![0.0; nx];
        let mut last = usize::MAX;
        for &(row, l, v) in r.rows {
            f[row] -= v * r.rhs[l];
            if l != last {
                zl.iter_mut().zip(&zr).for_each(|(z, col)| *z = col[l]);
                last = l;
            }
            for (c, z) in zl.iter().enumerate() {
                ms[c * mrows + row] -= v * z;
            }
        }
        *r.z = zr;
    }
    for (i, (jrow, kcol, v)) in kkt.iter().enumerate() {
        for c in 0..nx {
            m[(nx + i, c)] = jrow[c];
            m[(c, nx + i)] = kcol[c];
        }
        f[nx + i] = *v;
    }
    let sol = m.lu().solve(&f).ok_or("singular body system")?;
    let dx = sol.rows(0, nx).into_owned();
    for r in rods.iter_mut() {
        for (c, col) in r.z.iter().enumerate() {
            if dx[c] != 0.0 {
                for (y, zc) in r.rhs.iter_mut().zip(col) {
                    *y -= zc * dx[c];
                }
            }
        }
    }
    Ok((dx, sol.rows(nx, nk).into_owned()))
}
