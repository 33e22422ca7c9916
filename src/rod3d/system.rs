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
use nalgebra::{DMatrix, DVector, RowVector6, Vector6};

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

/// What a border column multiplies: the six unknowns of body `b` with weights `p` (a
/// prescribed coordinate that follows the body, δu = p·δX_b), or one unknown of the dense
/// system (an edge contact's multiplier; a body unknown's own column).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Weight {
    Body(usize, Vector6<f64>),
    Unknown(usize),
}

impl Weight {
    /// w·δX.
    #[inline]
    fn dot(&self, dx: &[f64]) -> f64 {
        match *self {
            Weight::Body(b, p) => p.dot(&Vector6::from_column_slice(&dx[6 * b..6 * b + 6])),
            Weight::Unknown(c) => dx[c],
        }
    }
}

/// The border B of a rod block as a sum of outer products, B = Σ_k v_k w_kᵀ: one column v_k
/// (over the rod's coordinates) per prescribed coordinate that follows a body and per edge
/// contact unknown. A sliding contact node on a body is one column, not the body's six:
/// Z = A⁻¹ B needs one solve per column. Storage kept from call to call.
#[derive(Debug, Clone, Default)]
pub struct Border {
    cols: Vec<Vec<f64>>,
    w: Vec<Weight>,
    n: usize,
}

impl Border {
    /// An empty border of a rod block of dimension n.
    pub fn new(n: usize) -> Border {
        Border {
            cols: Vec::new(),
            w: Vec::new(),
            n,
        }
    }

    pub fn clear(&mut self) {
        self.w.clear();
    }

    pub fn len(&self) -> usize {
        self.w.len()
    }

    pub fn is_empty(&self) -> bool {
        self.w.is_empty()
    }

    /// A new zero column with weight `w`; returns its index.
    pub fn push(&mut self, w: Weight) -> usize {
        let k = self.w.len();
        if k == self.cols.len() {
            self.cols.push(vec![0.0; self.n]);
        } else {
            self.cols[k].fill(0.0);
        }
        self.w.push(w);
        k
    }

    /// Column k, to add to.
    pub fn col_mut(&mut self, k: usize) -> &mut [f64] {
        &mut self.cols[k]
    }

    /// Column k and its weight.
    pub fn col(&self, k: usize) -> (&[f64], Weight) {
        (&self.cols[k], self.w[k])
    }
}

/// The bodies' contacts' constraint rows on ΔX with their force columns (row J, column K,
/// right-hand side v: S δX + Σ K λ = f_b, J δX = v), each nonzero on one body's six unknowns
/// only; storage kept from call to call.
#[derive(Debug, Clone, Default)]
pub struct Kkt {
    rows: Vec<(usize, RowVector6<f64>, RowVector6<f64>, f64)>,
}

impl Kkt {
    pub fn clear(&mut self) {
        self.rows.clear();
    }

    pub fn len(&self) -> usize {
        self.rows.len()
    }

    pub fn is_empty(&self) -> bool {
        self.rows.is_empty()
    }

    /// A row J (entries `j` on the unknowns `at .. at + 6`), its force column K (`k` there)
    /// and its right-hand side.
    pub fn push(&mut self, at: usize, j: RowVector6<f64>, k: RowVector6<f64>, v: f64) {
        self.rows.push((at, j, k, v));
    }
}

/// The factors of one rod block, storage kept from call to call.
#[derive(Debug, Clone)]
pub struct BlockFactor {
    chol: SymBand,
    lu: BandLu,
    use_lu: bool,
    /// Y = S⁻¹ U for the kinetic rows (U's columns μ e_row, S the symmetric part) and the LU
    /// of the capacitance matrix I + Vᵀ Y (V's columns the rows' `n`), column-major.
    y: Vec<Vec<f64>>,
    cap: Vec<f64>,
    cap_piv: Vec<usize>,
    /// Vᵀ x of one solve (scratch).
    vb: Vec<f64>,
}

impl BlockFactor {
    /// Storage for a rod block of dimension n (half-bandwidth 10).
    pub fn new(n: usize) -> BlockFactor {
        BlockFactor {
            chol: SymBand::new(n, 10),
            lu: BandLu::new(n, 10, 10),
            use_lu: false,
            y: Vec::new(),
            cap: Vec::new(),
            cap_piv: Vec::new(),
            vb: Vec::new(),
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
    pub border: &'a Border,
    /// Storage for Z = A⁻¹ B, kept between calls: its columns z_k (A⁻¹ of the border's
    /// columns, or of a body's six combined columns) and their weights, Z = Σ z_k w_kᵀ.
    pub z: &'a mut Vec<Vec<f64>>,
    pub zw: &'a mut Vec<Weight>,
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
        f.cap.clear();
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
        f.cap.resize(m * m, 0.0);
        for j in 0..m {
            for i in 0..m {
                let vy: f64 = self.kinetic[i].n.iter().map(|&(l, v)| v * f.y[j][l]).sum();
                f.cap[j * m + i] = vy + if i == j { 1.0 } else { 0.0 };
            }
        }
        if lu_factor(&mut f.cap, m, &mut f.cap_piv).is_err() {
            return self.factor_lu();
        }
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
        f.cap.clear();
        Ok(())
    }

    /// Solve A x = b in place with the factor.
    fn solve_in(&mut self, b: &mut [f64]) {
        if self.factor.use_lu {
            self.factor.lu.solve(b);
            return;
        }
        self.factor.chol.solve(b);
        self.woodbury(b);
    }

    /// Z's columns at once (rows before `first` zero in all of them).
    fn solve_z(&mut self, first: usize) {
        let cols = &mut self.z[..self.zw.len()];
        let f = &mut *self.factor;
        if f.use_lu {
            cols.iter_mut().for_each(|b| f.lu.solve(b));
            return;
        }
        f.chol.solve_many(cols, first);
        for b in cols.iter_mut() {
            woodbury(f, self.kinetic, b);
        }
    }

    fn woodbury(&mut self, b: &mut [f64]) {
        woodbury(self.factor, self.kinetic, b);
    }

    /// Z = A⁻¹ B: the border's columns, or a body's six combined columns Σ v_k p_kᵀ where
    /// it has more than six (fewer solves either way); zero columns left out. Returns the
    /// first row any of them is nonzero in.
    fn load_z(&mut self) -> usize {
        let n = self.rhs.len();
        let (border, z, zw) = (self.border, &mut *self.z, &mut *self.zw);
        zw.clear();
        let mut first = n;
        // A column of Z's storage for weight w.
        let take = |z: &mut Vec<Vec<f64>>, zw: &mut Vec<Weight>, w: Weight| {
            let k = zw.len();
            if k == z.len() {
                z.push(vec![0.0; n]);
            }
            zw.push(w);
            k
        };
        for k in 0..border.len() {
            let (v, w) = border.col(k);
            let combine = match w {
                Weight::Body(b, _) => {
                    let same = |x: &Weight| matches!(x, Weight::Body(b2, _) if *b2 == b);
                    (0..border.len())
                        .filter(|&i| same(&border.col(i).1))
                        .count()
                        > 6
                }
                Weight::Unknown(_) => false,
            };
            let Some(top) = v.iter().position(|&x| x != 0.0) else {
                continue;
            };
            first = first.min(top);
            match (combine, w) {
                (true, Weight::Body(b, p)) => {
                    let base = match zw.iter().position(|x| *x == Weight::Unknown(6 * b)) {
                        Some(at) => at,
                        None => {
                            let at = zw.len();
                            for c in 0..6 {
                                let i = take(z, zw, Weight::Unknown(6 * b + c));
                                z[i].fill(0.0);
                            }
                            at
                        }
                    };
                    for c in 0..6 {
                        for (x, &vl) in z[base + c].iter_mut().zip(v) {
                            *x += vl * p[c];
                        }
                    }
                }
                _ => {
                    let i = take(z, zw, w);
                    z[i].copy_from_slice(v);
                }
            }
        }
        first
    }

    /// This rod's part of the dense system: Z, then −C Z into `m` (column-major, leading
    /// dimension `ld`) and −C A⁻¹ f into `f` (`u`: scratch).
    fn schur(&mut self, nx: usize, m: &mut [f64], ld: usize, f: &mut [f64], u: &mut Vec<f64>) {
        let first = self.load_z();
        let nz = self.zw.len();
        if nz > 0 {
            self.solve_z(first);
        }
        // C Z column by column (u_k = C z_k), then −Σ u_k w_kᵀ.
        u.clear();
        u.resize(nz * nx, 0.0);
        for &(row, l, v) in self.rows {
            f[row] -= v * self.rhs[l];
            for (k, z) in self.z[..nz].iter().enumerate() {
                u[k * nx + row] += v * z[l];
            }
        }
        for (k, w) in self.zw.iter().enumerate() {
            let uk = &u[k * nx..(k + 1) * nx];
            match *w {
                Weight::Body(b, p) => {
                    for (c, pc) in p.iter().enumerate() {
                        let col = &mut m[(6 * b + c) * ld..(6 * b + c) * ld + nx];
                        col.iter_mut().zip(uk).for_each(|(x, u)| *x -= u * pc);
                    }
                }
                Weight::Unknown(c) => {
                    let col = &mut m[c * ld..c * ld + nx];
                    col.iter_mut().zip(uk).for_each(|(x, u)| *x -= u);
                }
            }
        }
    }
}

/// From x = S⁻¹b to A⁻¹b: (S + U Vᵀ)⁻¹ b = S⁻¹b − Y (I + Vᵀ Y)⁻¹ Vᵀ S⁻¹b.
fn woodbury(f: &mut BlockFactor, kinetic: &[KineticRow], b: &mut [f64]) {
    if f.cap.is_empty() {
        return;
    }
    let m = kinetic.len();
    f.vb.clear();
    f.vb.extend(
        kinetic
            .iter()
            .map(|k| k.n.iter().map(|&(l, v)| v * b[l]).sum::<f64>()),
    );
    lu_solve(&f.cap, m, &f.cap_piv, &mut f.vb);
    for (y, wi) in f.y.iter().zip(&f.vb) {
        for (bj, yj) in b.iter_mut().zip(y) {
            *bj -= wi * yj;
        }
    }
}

/// LU with partial pivoting of the n × n column-major `a` in place (unit lower L below the
/// diagonal, U on and above it; row k was swapped with row `piv[k]`). Err if a pivot is zero.
fn lu_factor(a: &mut [f64], n: usize, piv: &mut Vec<usize>) -> Result<(), ()> {
    piv.clear();
    for k in 0..n {
        let mut p = k;
        for i in k + 1..n {
            if a[k * n + i].abs() > a[k * n + p].abs() {
                p = i;
            }
        }
        piv.push(p);
        if a[k * n + p] == 0.0 {
            return Err(());
        }
        if p != k {
            for c in 0..n {
                a.swap(c * n + k, c * n + p);
            }
        }
        let inv = 1.0 / a[k * n + k];
        for i in k + 1..n {
            a[k * n + i] *= inv;
        }
        for c in k + 1..n {
            let akc = a[c * n + k];
            if akc != 0.0 {
                for i in k + 1..n {
                    a[c * n + i] -= a[k * n + i] * akc;
                }
            }
        }
    }
    Ok(())
}

/// Solve with [`lu_factor`]'s factors, b in place.
fn lu_solve(a: &[f64], n: usize, piv: &[usize], b: &mut [f64]) {
    for (k, &p) in piv.iter().enumerate() {
        b.swap(k, p);
    }
    for k in 0..n {
        let bk = b[k];
        for i in k + 1..n {
            b[i] -= a[k * n + i] * bk;
        }
    }
    for k in (0..n).rev() {
        b[k] /= a[k * n + k];
        let bk = b[k];
        for i in 0..k {
            b[i] -= a[k * n + i] * bk;
        }
    }
}

/// Relative compliance of a body's contact row: ε = this × J S⁻¹ K (diagonal estimate).
pub const REDUNDANCY_COMPLIANCE: f64 = 1e-10;

/// A body's contact rows may be linearly dependent: a box's four corners on a plane give four
/// normal rows (twelve when stuck) on the three (six) motions they can restrain, and a plane
/// given twice doubles every row. The bordered matrix [S K; J 0] is then singular although
/// the motion is determined. Each row gets a compliance ε λ (J δX + ε λ = v) of
/// [`REDUNDANCY_COMPLIANCE`] times its own scale Σ |j_c k_c| / S_cc: the matrix is regular,
/// the forces on the body balance exactly (its rows of S δX + K λ = f are untouched), the
/// redundant rows share their load by the least-squares rule, and a row's constraint is missed
/// by ε λ (about 1e-10 × dt² × the acceleration the force gives the body: below 1e-16 m).
fn redundancy_compliance(kkt: &Kkt, nx: usize, dim: usize, m: &mut [f64]) {
    for (i, (at, j, k, _)) in kkt.rows.iter().enumerate() {
        let scale: f64 = (0..6)
            .map(|c| {
                let s = m[(at + c) * dim + at + c].abs();
                if s > 0.0 {
                    (j[c] * k[c]).abs() / s
                } else {
                    0.0
                }
            })
            .sum();
        m[(nx + i) * dim + nx + i] = REDUNDANCY_COMPLIANCE * scale;
    }
}

/// The dense system of the bodies' unknowns and their contacts' multipliers, kept from call
/// to call: after [`solve_bordered`], `sol` holds δX then λ.
#[derive(Debug, Clone, Default)]
pub struct Dense {
    m: Vec<f64>,
    piv: Vec<usize>,
    u: Vec<f64>,
    pub sol: Vec<f64>,
}

/// Solve the bordered system. `s` and `fb` are the bodies' block (with the D terms already in);
/// `kkt` are extra constraint rows on ΔX with their force columns: S δX + Σ K λ = f_b,
/// J δX = v. Leaves δX and λ in `d.sol`; each rod's `rhs` becomes its y.
pub fn solve_bordered(
    rods: &mut [RodBlock<'_>],
    s: &DMatrix<f64>,
    fb: &DVector<f64>,
    kkt: &Kkt,
    d: &mut Dense,
) -> Result<(), &'static str> {
    let nx = fb.len();
    for r in rods.iter_mut() {
        r.factor()?;
        let rhs = std::mem::take(&mut r.rhs);
        r.solve_in(rhs);
        r.rhs = rhs;
    }
    let nk = kkt.len();
    let dim = nx + nk;
    d.sol.clear();
    d.sol.resize(dim, 0.0);
    if nx == 0 {
        return Ok(());
    }
    d.m.clear();
    d.m.resize(dim * dim, 0.0);
    for c in 0..nx {
        d.m[c * dim..c * dim + nx].copy_from_slice(&s.as_slice()[c * nx..(c + 1) * nx]);
    }
    d.sol[..nx].copy_from_slice(fb.as_slice());
    for r in rods.iter_mut() {
        r.schur(nx, &mut d.m, dim, &mut d.sol, &mut d.u);
    }
    for (i, (at, j, k, v)) in kkt.rows.iter().enumerate() {
        for c in 0..6 {
            d.m[(at + c) * dim + nx + i] = j[c];
            d.m[(nx + i) * dim + at + c] = k[c];
        }
        d.sol[nx + i] = *v;
    }
    redundancy_compliance(kkt, nx, dim, &mut d.m);
    lu_factor(&mut d.m, dim, &mut d.piv).map_err(|_| "singular body system")?;
    lu_solve(&d.m, dim, &d.piv, &mut d.sol);
    let dx = &d.sol[..nx];
    for r in rods.iter_mut() {
        for (z, w) in r.z.iter().zip(r.zw.iter()) {
            let a = w.dot(dx);
            if a != 0.0 {
                for (y, zc) in r.rhs.iter_mut().zip(z) {
                    *y -= zc * a;
                }
            }
        }
    }
    Ok(())
}
