//! Hand-derived gradient and Hessian of the bending and twisting energy of one node (the
//! fast path of the assembly; [`super::energy::node_derivatives`], by dual numbers, is the
//! reference the tests hold it to).
//!
//! Variables of the stencil: the edges e, f, their material angles θₑ, θ_f (local layout
//! e = 0..3, f = 3..6, θₑ = 6, θ_f = 7), mapped to the 11 DOFs (x₀, θₑ, x₁, θ_f, x₂) at the end.
//!
//! **Strains.** With unit tangents tₑ, t_f, χ = 1 + tₑ·t_f and κb = 2 tₑ × t_f / χ, the
//! material curvatures of [`super::energy`] are
//! κ₁ = ½ κb·(m₂ₑ + m₂_f) = (t_f·m₁ₑ − tₑ·m₁_f)/χ,  κ₂ = −½ κb·(m₁ₑ + m₁_f) = (t_f·m₂ₑ − tₑ·m₂_f)/χ,
//! so each is a difference of two products w·u (a tangent with the other edge's director)
//! over χ, and the twist is m = θ_f − θₑ + m_ref.
//!
//! **How a director moves.** The reference frame of an edge is the time-parallel transport of
//! its frame at the start of the step, so under a change δe of the edge the frame turns with
//! the angular velocity Ω = t × δt + δψ t: the bending part of Bergou et al. plus a twist
//! δψ = v·δe, v = (t × t⁰)/((1 + t⁰·t) |e|), the holonomy of the transport from the old
//! tangent t⁰ (zero at t = t⁰, where the usual formulas hold exactly). Hence
//! ∂m₁/∂e = −t m₁ᵀ/|e| + m₂ vᵀ, ∂m₂/∂e = −t m₂ᵀ/|e| − m₁ vᵀ, ∂m₁/∂θ = m₂, ∂m₂/∂θ = −m₁.
//! The reference twist moves with the holonomy of the space-parallel transport across the
//! node (Bergou 2010): ∂m_ref/∂e = κb/(2|e|) − vₑ, ∂m_ref/∂f = κb/(2|f|) + v_f.
//!
//! **Second derivatives.** For S = w·u (u a director of one edge, w the other edge's
//! tangent) differentiating the director formulas once more gives the own-edge block
//! −(w uᵀ)/|e|² + w·t (2 t uᵀ + u tᵀ)/|e|² − w·t (v u⊥ᵀ + u⊥ vᵀ)/|e| + (w·u⊥) ∂v/∂eᵀ − (w·u) v vᵀ
//! (u⊥ = ∂u/∂θ), whose antisymmetric parts cancel (the curvature of the frame's twist
//! against that of v): its symmetric part is the exact block. The cross blocks are
//! P_w ∂u/∂e with P_w = (I − w wᵀ)/|f|, the other-edge block is u contracted with
//! ∂²t/∂f². The reference twist's blocks are ∂(κb/2|e|)/∂(e, f) ∓ ∂v/∂e with
//! ∂κb/∂e = (−2[t_f]× − κb (tₑ + t_f)ᵀ)/(χ|e|), ∂κb/∂f = (2[tₑ]× − κb (tₑ + t_f)ᵀ)/(χ|f|).
//! Everything is linear in (u, u⊥), so the weighted sum of the four director products
//! of a node is one evaluation per side.

use super::dual::{add, cross, dot, mul, sub};
use super::energy::{signed_angle, transport, EdgeFrame, NodeElastic};

type V = [f64; 3];
type G8 = [f64; 8];
type H8 = [[f64; 8]; 8];

/// Offsets of the local variables.
const E: usize = 0;
const F: usize = 3;
const TE: usize = 6;
const TF: usize = 7;

/// One edge of a stencil at the current iterate: its frame and the derivatives of its
/// reference twist. Each edge belongs to two stencils; the assembly computes it once.
#[derive(Debug, Clone, Copy)]
pub struct Edge {
    t: V,
    /// 1/|e| (multiplications instead of divisions in the derivatives).
    il: f64,
    a1: V,
    m1: V,
    m2: V,
    /// Gradient of the twist ψ of the time-parallel reference frame w.r.t. the edge vector.
    v: V,
    /// Its Jacobian, jv[i][j] = ∂vᵢ/∂eⱼ.
    jv: [[f64; 3]; 3],
}

fn unit(j: usize) -> V {
    let mut u = [0.0; 3];
    u[j] = 1.0;
    u
}

/// Edge vector `e` with material angle `theta`, its reference frame transported from `old`;
/// with `jv` also ∂v/∂e (Hessians only).
pub fn edge(e: V, old: &EdgeFrame, theta: f64, jv: bool) -> Edge {
    let want_jv = jv;
    let l = dot(e, e).sqrt();
    let il = 1.0 / l;
    let t = mul(il, e);
    let a1 = transport(old.a1, old.t, t);
    let a2 = cross(t, a1);
    let (s, c) = theta.sin_cos();
    let m1 = add(mul(c, a1), mul(s, a2));
    let m2 = sub(mul(c, a2), mul(s, a1));
    let t0 = old.t;
    let b = cross(t, t0);
    let ch = 1.0 + dot(t0, t);
    let v = mul(1.0 / (ch * l), b);
    // ∂v/∂e = −[t⁰]× P/(ch l) − b (P t⁰)ᵀ/(ch² l) − b tᵀ/(ch l²), P = (I − t tᵀ)/l, where
    // column j of [t⁰]× P is (t⁰ × êⱼ + b tⱼ)/l.
    let mut jv = [[0.0; 3]; 3];
    let (d1, d2) = (il * il / ch, il / (ch * ch));
    for (j, _) in t.iter().enumerate().filter(|_| want_jv) {
        let x = cross(t0, unit(j));
        let pt0 = (t0[j] - (ch - 1.0) * t[j]) * il;
        for i in 0..3 {
            jv[i][j] = -(x[i] + 2.0 * b[i] * t[j]) * d1 - b[i] * pt0 * d2;
        }
    }
    Edge {
        t,
        il,
        a1,
        m1,
        m2,
        v,
        jv,
    }
}

/// Adds s ∇(w·u), u a director of `own` (variables at `o`, angle at `th`, u⊥ = ∂u/∂θ) and
/// w the tangent of `oth` (variables at `oo`).
#[allow(clippy::too_many_arguments)]
fn dot_grad(
    own: &Edge,
    o: usize,
    th: usize,
    u: V,
    up: V,
    oth: &Edge,
    oo: usize,
    s: f64,
    g: &mut G8,
) {
    let w = oth.t;
    let (wt, wu, wp) = (dot(w, own.t), dot(w, u), dot(w, up));
    for j in 0..3 {
        g[o + j] += s * (-wt * u[j] * own.il + wp * own.v[j]);
        g[oo + j] += s * (u[j] - wu * w[j]) * oth.il;
    }
    g[th] += s * wp;
}

/// Adds s ∇²(w·u) (symmetric: its lower triangle only, row ≥ column), same arguments as
/// [`dot_grad`]. The angle `th` comes after both edges' variables.
#[allow(clippy::too_many_arguments)]
fn dot_hess(
    own: &Edge,
    o: usize,
    th: usize,
    u: V,
    up: V,
    oth: &Edge,
    oo: usize,
    s: f64,
    h: &mut H8,
) {
    let (w, t, v, il, io) = (oth.t, own.t, own.v, own.il, oth.il);
    let (wt, wu, wp) = (dot(w, t), dot(w, u), dot(w, up));
    let (il2, io2) = (s * il * il, s * io * io);
    debug_assert!(th > o && th > oo);
    for i in 0..3 {
        for j in 0..=i {
            let own_ij = il2
                * (-0.5 * (w[i] * u[j] + w[j] * u[i]) + 1.5 * wt * (t[i] * u[j] + t[j] * u[i]))
                + s * (-wt * (v[i] * up[j] + v[j] * up[i]) * il
                    + 0.5 * wp * (own.jv[i][j] + own.jv[j][i])
                    - wu * v[i] * v[j]);
            h[o + i][o + j] += own_ij;
            let d = if i == j { 1.0 } else { 0.0 };
            h[oo + i][oo + j] -= io2 * (w[i] * u[j] + w[j] * u[i] + wu * (d - 3.0 * w[i] * w[j]));
        }
        for j in 0..3 {
            // ∂/∂w_i of the own gradient: P_w ∂u/∂e_j (into the lower of its two places).
            let pt = (t[i] - w[i] * wt) * io;
            let pp = (up[i] - w[i] * wp) * io;
            let c = s * (-pt * u[j] * il + pp * v[j]);
            if oo > o {
                h[oo + i][o + j] += c;
            } else {
                h[o + j][oo + i] += c;
            }
        }
        h[th][oo + i] += s * (up[i] - w[i] * wp) * io;
        h[th][o + i] += s * (-wt * up[i] * il - wu * v[i]);
    }
    h[th][th] -= s * wu;
}

/// Gradient of χ = 1 + tₑ·t_f.
fn chi_grad(a: &Edge, b: &Edge) -> G8 {
    let c = dot(a.t, b.t);
    let mut g = [0.0; 8];
    for k in 0..3 {
        g[E + k] = (b.t[k] - c * a.t[k]) * a.il;
        g[F + k] = (a.t[k] - c * b.t[k]) * b.il;
    }
    g
}

/// Adds s ∇²χ (lower triangle).
fn chi_hess(a: &Edge, b: &Edge, s: f64, h: &mut H8) {
    let c = dot(a.t, b.t);
    let (x, y) = (a.t, b.t);
    let (sa, sb, sab) = (s * a.il * a.il, s * b.il * b.il, s * a.il * b.il);
    for i in 0..3 {
        for j in 0..3 {
            let d = if i == j { 1.0 } else { 0.0 };
            if j <= i {
                h[E + i][E + j] -= sa * (x[i] * y[j] + x[j] * y[i] + c * (d - 3.0 * x[i] * x[j]));
                h[F + i][F + j] -= sb * (x[i] * y[j] + x[j] * y[i] + c * (d - 3.0 * y[i] * y[j]));
            }
            h[F + j][E + i] += sab * (d - x[i] * x[j] - y[i] * y[j] + c * x[i] * y[j]);
        }
    }
}

/// Gradient of the twist m = θ_f − θₑ + m_ref.
fn twist_grad(a: &Edge, b: &Edge, kb: V) -> G8 {
    let mut g = [0.0; 8];
    for k in 0..3 {
        g[E + k] = 0.5 * kb[k] * a.il - a.v[k];
        g[F + k] = 0.5 * kb[k] * b.il + b.v[k];
    }
    g[TE] = -1.0;
    g[TF] = 1.0;
    g
}

/// Adds s ∇²m (only the reference twist has a second derivative; lower triangle).
fn twist_hess(a: &Edge, b: &Edge, kb: V, chi: f64, s: f64, h: &mut H8) {
    let sum = add(a.t, b.t);
    let x = a.t;
    let ichi = 1.0 / chi;
    let (ia2, ib2) = (0.25 * a.il * a.il, 0.25 * b.il * b.il);
    let (cee, cff, cef) = (ichi * ia2, ichi * ib2, 0.5 * ichi * a.il * b.il);
    // [tₑ]×, row i column j.
    let tx = [[0.0, -x[2], x[1]], [x[2], 0.0, -x[0]], [-x[1], x[0], 0.0]];
    for i in 0..3 {
        for j in 0..3 {
            if j <= i {
                let ks = kb[i] * sum[j] + sum[i] * kb[j];
                let ee = -ks * cee
                    - (kb[i] * a.t[j] + a.t[i] * kb[j]) * ia2
                    - 0.5 * (a.jv[i][j] + a.jv[j][i]);
                let ff = -ks * cff - (kb[i] * b.t[j] + b.t[i] * kb[j]) * ib2
                    + 0.5 * (b.jv[i][j] + b.jv[j][i]);
                h[E + i][E + j] += s * ee;
                h[F + i][F + j] += s * ff;
            }
            h[F + j][E + i] += s * ((2.0 * tx[i][j] - kb[i] * sum[j]) * cef);
        }
    }
}

/// The curvatures of a node and the gradients of its strains over the local variables.
struct Strains {
    chi: f64,
    kb: V,
    k1: f64,
    k2: f64,
    /// ∇χ, ∇κ₁, ∇κ₂, ∇m.
    gc: G8,
    g1: G8,
    g2: G8,
    gm: G8,
}

fn strains(a: &Edge, b: &Edge) -> Strains {
    let chi = 1.0 + dot(a.t, b.t);
    let ichi = 1.0 / chi;
    let kb = mul(2.0 * ichi, cross(a.t, b.t));
    let k1 = (dot(b.t, a.m1) - dot(a.t, b.m1)) * ichi;
    let k2 = (dot(b.t, a.m2) - dot(a.t, b.m2)) * ichi;
    let gc = chi_grad(a, b);
    // ∇κᵢ = (∇Nᵢ − κᵢ ∇χ)/χ, Nᵢ = t_f·mᵢₑ − tₑ·mᵢ_f.
    let (mut g1, mut g2) = ([0.0; 8], [0.0; 8]);
    let nm1 = [-a.m1[0], -a.m1[1], -a.m1[2]];
    let nb1 = [-b.m1[0], -b.m1[1], -b.m1[2]];
    dot_grad(a, E, TE, a.m1, a.m2, b, F, 1.0, &mut g1);
    dot_grad(b, F, TF, b.m1, b.m2, a, E, -1.0, &mut g1);
    dot_grad(a, E, TE, a.m2, nm1, b, F, 1.0, &mut g2);
    dot_grad(b, F, TF, b.m2, nb1, a, E, -1.0, &mut g2);
    for k in 0..8 {
        g1[k] = (g1[k] - k1 * gc[k]) * ichi;
        g2[k] = (g2[k] - k2 * gc[k]) * ichi;
    }
    let gm = twist_grad(a, b, kb);
    Strains {
        chi,
        kb,
        k1,
        k2,
        gc,
        g1,
        g2,
        gm,
    }
}

/// The gradients of the strains κ₁, κ₂ and m of the stencil with DOFs `x` (x₀, θₑ, x₁, θ_f,
/// x₂) over those DOFs: the strain rates of material damping are ∇s·v.
pub fn strain_gradients(x: &[f64; 11], old: [&EdgeFrame; 2]) -> [[f64; 11]; 3] {
    let e = [x[4] - x[0], x[5] - x[1], x[6] - x[2]];
    let f = [x[8] - x[4], x[9] - x[5], x[10] - x[6]];
    let s = strains(&edge(e, old[0], x[3], false), &edge(f, old[1], x[7], false));
    let mut out = [[0.0; 11]; 3];
    for (o, g) in out.iter_mut().zip([&s.g1, &s.g2, &s.gm]) {
        map_to_dofs(g, o);
    }
    out
}

/// Energy, gradient and Hessian of one node over the local variables (e, f, θₑ, θ_f).
#[allow(clippy::too_many_arguments)]
pub fn local(
    e: V,
    f: V,
    th: [f64; 2],
    old: [&EdgeFrame; 2],
    rt_old: f64,
    p: &NodeElastic,
    g: &mut G8,
    h: Option<&mut H8>,
) -> f64 {
    let want_h = h.is_some();
    let a = edge(e, old[0], th[0], want_h);
    let b = edge(f, old[1], th[1], want_h);
    stencil(&a, &b, th, rt_old, p, g, h)
}

/// [`local`] from the stencil's two edges ([`edge`], with ∂v/∂e when `h` is wanted) and
/// their material angles.
pub fn stencil(
    a: &Edge,
    b: &Edge,
    th: [f64; 2],
    rt_old: f64,
    p: &NodeElastic,
    g: &mut G8,
    h: Option<&mut H8>,
) -> f64 {
    let Strains {
        chi,
        kb,
        k1,
        k2,
        gc,
        g1,
        g2,
        gm,
    } = strains(a, b);
    let mref = signed_angle(transport(a.a1, a.t, b.t), b.a1, b.t, rt_old);
    let m = th[1] - th[0] + mref;
    let (d1, d2, dm) = (k1 - p.kappa_bar[0], k2 - p.kappa_bar[1], m - p.twist_bar);
    let (w1, w2, wm) = (p.ei1 * d1, p.ei2 * d2, p.gj * dm);
    for k in 0..8 {
        g[k] = w1 * g1[k] + w2 * g2[k] + wm * gm[k];
    }
    let energy = 0.5 * (w1 * d1 + w2 * d2 + wm * dm);
    let Some(h) = h else {
        return energy;
    };
    // Σ wᵢ ∇²κᵢ = [Σ wᵢ ∇²Nᵢ − (Σ wᵢ κᵢ) ∇²χ − (∇χ cᵀ + c ∇χᵀ)]/χ, c = Σ wᵢ ∇κᵢ. The
    // outer products k₁ ∇κ₁∇κ₁ᵀ + k₂ ∇κ₂∇κ₂ᵀ + k_m ∇m∇mᵀ and the last term in one pass.
    // The Hessian is symmetric: every term below fills its lower triangle (row ≥ column),
    // the upper one is copied from it at the end.
    let ichi = 1.0 / chi;
    let c: G8 = std::array::from_fn(|i| (w1 * g1[i] + w2 * g2[i]) * ichi);
    for i in 0..8 {
        let (a1, a2, am) = (p.ei1 * g1[i], p.ei2 * g2[i], p.gj * gm[i]);
        for j in 0..=i {
            h[i][j] = a1 * g1[j] + a2 * g2[j] + am * gm[j] - (gc[i] * c[j] + c[i] * gc[j]);
        }
    }
    let ua = add(mul(w1, a.m1), mul(w2, a.m2));
    let upa = sub(mul(w1, a.m2), mul(w2, a.m1));
    let ub = add(mul(w1, b.m1), mul(w2, b.m2));
    let upb = sub(mul(w1, b.m2), mul(w2, b.m1));
    dot_hess(a, E, TE, ua, upa, b, F, ichi, h);
    dot_hess(b, F, TF, ub, upb, a, E, -ichi, h);
    chi_hess(a, b, -(w1 * k1 + w2 * k2) * ichi, h);
    twist_hess(a, b, kb, chi, wm, h);
    for i in 0..8 {
        for j in i + 1..8 {
            h[i][j] = h[j][i];
        }
    }
    energy
}

/// Energy, gradient and (with `hess`) Hessian over the DOFs (x₀, θₑ, x₁, θ_f, x₂) of the
/// stencil of edges `a`, `b` with material angles `th`: [`node_derivatives`] /
/// [`node_gradient`] with the edges computed by the caller.
pub fn stencil_dofs(
    a: &Edge,
    b: &Edge,
    th: [f64; 2],
    rt_old: f64,
    p: &NodeElastic,
    grad: &mut [f64; 11],
    hess: Option<&mut [[f64; 11]; 11]>,
) -> f64 {
    let mut g = [0.0; 8];
    match hess {
        Some(hess) => {
            let mut h = [[0.0; 8]; 8];
            let en = stencil(a, b, th, rt_old, p, &mut g, Some(&mut h));
            to_dofs(&g, &h, grad, hess);
            en
        }
        None => {
            let en = stencil(a, b, th, rt_old, p, &mut g, None);
            map_to_dofs(&g, grad);
            en
        }
    }
}

/// Energy, gradient and Hessian (bending + twisting) of the stencil with DOFs `x`
/// (x₀, θₑ, x₁, θ_f, x₂): the same contract as [`super::energy::node_derivatives`].
pub fn node_derivatives(
    x: &[f64; 11],
    old: [&EdgeFrame; 2],
    rt_old: f64,
    p: &NodeElastic,
    grad: &mut [f64; 11],
    hess: &mut [[f64; 11]; 11],
) -> f64 {
    let e = [x[4] - x[0], x[5] - x[1], x[6] - x[2]];
    let f = [x[8] - x[4], x[9] - x[5], x[10] - x[6]];
    let (mut g, mut h) = ([0.0; 8], [[0.0; 8]; 8]);
    let en = local(e, f, [x[3], x[7]], old, rt_old, p, &mut g, Some(&mut h));
    to_dofs(&g, &h, grad, hess);
    en
}

/// Energy and gradient only (the residual of a convergence test): [`node_derivatives`]
/// without the Hessian, the same numbers for the gradient.
pub fn node_gradient(
    x: &[f64; 11],
    old: [&EdgeFrame; 2],
    rt_old: f64,
    p: &NodeElastic,
    grad: &mut [f64; 11],
) -> f64 {
    let e = [x[4] - x[0], x[5] - x[1], x[6] - x[2]];
    let f = [x[8] - x[4], x[9] - x[5], x[10] - x[6]];
    let mut g = [0.0; 8];
    let en = local(e, f, [x[3], x[7]], old, rt_old, p, &mut g, None);
    map_to_dofs(&g, grad);
    en
}

/// A local (e, f, θₑ, θ_f) gradient over the DOFs (x₀, θₑ, x₁, θ_f, x₂).
fn map_to_dofs(r: &[f64; 8], out: &mut [f64; 11]) {
    for k in 0..3 {
        out[k] = -r[E + k];
        out[4 + k] = r[E + k] - r[F + k];
        out[8 + k] = r[F + k];
    }
    out[3] = r[TE];
    out[7] = r[TF];
}

/// Map local (e, f, θₑ, θ_f) derivatives to the DOFs (x₀, θₑ, x₁, θ_f, x₂), e = x₁ − x₀,
/// f = x₂ − x₁: rows first, then columns.
pub fn to_dofs(g: &G8, h: &H8, grad: &mut [f64; 11], hess: &mut [[f64; 11]; 11]) {
    let map = map_to_dofs;
    map(g, grad);
    // Rows: r[i] = the local row map of column i.
    let mut rows = [[0.0; 11]; 8];
    for i in 0..8 {
        map(&h[i], &mut rows[i]);
    }
    for j in 0..11 {
        let col: [f64; 8] = std::array::from_fn(|i| rows[i][j]);
        let mut out = [0.0; 11];
        map(&col, &mut out);
        for i in 0..11 {
            hess[i][j] = out[i];
        }
    }
}
