//! Elastic energies of a 3D discrete elastic rod (Bergou et al. 2008, 2010).
//!
//! * Stretching of edge e = x₁ − x₀: E_s = ½ EA l̄ (|e|/l̄ − 1)², gradient and Hessian in closed
//!   form (the planar formula with 3-vectors).
//! * Bending and twisting at an interior node, between edges e (before) and f (after), with
//!   material angles θₑ, θ_f. Each edge carries a reference frame (t, a₁, a₂ = t × a₁) that is
//!   the *time-parallel transport* of the frame it had at the start of the step onto the
//!   current tangent; the material frame is that frame turned by θ about t:
//!   m₁ = cos θ a₁ + sin θ a₂, m₂ = −sin θ a₁ + cos θ a₂.
//!   Curvature binormal κb = 2 tₑ × t_f / (1 + tₑ·t_f), material curvatures
//!   κ₁ = ½ κb·(m₂ₑ + m₂_f), κ₂ = −½ κb·(m₁ₑ + m₁_f), twist m = θ_f − θₑ + m_ref with the
//!   reference twist m_ref the signed angle from the space-parallel transport of a₁ₑ across
//!   the node to a₁_f (kept continuous in time). Energies
//!   E_b = [EI₁ (κ₁ − κ̄₁)² + EI₂ (κ₂ − κ̄₂)²] / (2 Δl),  E_t = GJ (m − m̄)² / (2 Δl),
//!   Δl the mean of the two rest edges (the planar model's Δl). In a plane with θ = 0,
//!   |κb| = 2 tan(φ/2) is the planar curvature measure, so E_b is the planar bending energy.
//!
//! The stencil energy is written once over [`Real`]: its gradient and Hessian with respect to
//! (e, f, θₑ, θ_f) come from [`Dual2`], exact derivatives of the expression itself (including
//! the dependence of the transported frames on the edges), then map linearly to the 11 DOFs
//! (x₀, θₑ, x₁, θ_f, x₂).

use super::dual::{add, cross, dot, lift, mul, sub, vals, Dual2, Real, V3};
use std::f64::consts::PI;

/// Energy, gradient and (optionally) Hessian of one stretching element; DOFs (x₀, x₁).
#[inline]
pub fn stretch(
    x: &[f64; 6],
    ea: f64,
    rest: f64,
    grad: &mut [f64; 6],
    hess: Option<&mut [[f64; 6]; 6]>,
) -> f64 {
    let e = [x[3] - x[0], x[4] - x[1], x[5] - x[2]];
    let l = (e[0] * e[0] + e[1] * e[1] + e[2] * e[2]).sqrt();
    let il = 1.0 / l;
    let strain = l / rest - 1.0;
    let t = [e[0] * il, e[1] * il, e[2] * il];
    let f = ea * strain;
    for k in 0..3 {
        grad[k] = -f * t[k];
        grad[k + 3] = f * t[k];
    }
    if let Some(h) = hess {
        // d²E/de² = EA/l̄ t tᵀ + EA (l/l̄ − 1)/l (I − t tᵀ)
        let (a, b) = (ea / rest, f * il);
        for i in 0..3 {
            for j in 0..3 {
                let id = if i == j { 1.0 } else { 0.0 };
                let k = a * t[i] * t[j] + b * (id - t[i] * t[j]);
                h[i][j] = k;
                h[i + 3][j + 3] = k;
                h[i][j + 3] = -k;
                h[i + 3][j] = -k;
            }
        }
    }
    0.5 * ea * rest * strain * strain
}

/// The reference frame an edge had at the start of the step: unit tangent t and a₁ ⊥ t.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EdgeFrame {
    pub t: [f64; 3],
    pub a1: [f64; 3],
}

/// Parallel transport of the constant vector `a` from the unit tangent `t0` to the unit
/// tangent `t` (the rotation about t0 × t that takes t0 to t):
/// P a = c a + b × a + (b·a)/(1 + c) b with b = t0 × t, c = t0·t.
#[inline]
pub fn transport<T: Real>(a: V3<T>, t0: V3<T>, t: V3<T>) -> V3<T> {
    let b = cross(t0, t);
    let c = dot(t0, t);
    let k = dot(b, a) / (T::cst(1.0) + c);
    add(add(mul(c, a), cross(b, a)), mul(k, b))
}

/// Unit vector and length.
#[inline]
fn unit<T: Real>(e: V3<T>) -> (V3<T>, T) {
    let l = dot(e, e).sqrt();
    let inv = T::cst(1.0) / l;
    (mul(inv, e), l)
}

/// The current reference frame of an edge: tangent and transported a₁.
#[inline]
pub fn frame_of<T: Real>(e: V3<T>, old: &EdgeFrame) -> (V3<T>, V3<T>) {
    let (t, _) = unit(e);
    let a1 = transport(lift(old.a1), lift(old.t), t);
    (t, a1)
}

/// Signed angle of the rotation about the unit `axis` that takes `u` to `v` (both ⊥ axis),
/// taken on the branch nearest `near`.
#[inline]
pub fn signed_angle<T: Real>(u: V3<T>, v: V3<T>, axis: V3<T>, near: f64) -> T {
    let s = dot(cross(u, v), axis);
    let c = dot(u, v);
    // Rotate by the (constant) value of the angle so that atan works near zero: exact
    // derivatives on every branch.
    let a0 = s.val().atan2(c.val());
    let k = ((near - a0) / (2.0 * PI)).round();
    if !T::DERIVATIVES {
        // Plain numbers: the angle itself (the rotation below only serves the derivatives;
        // it gives the same angle to rounding).
        return T::cst(a0 + 2.0 * PI * k);
    }
    let (s0, c0) = a0.sin_cos();
    let x = c.scale(c0) + s.scale(s0);
    let y = s.scale(c0) - c.scale(s0);
    let raw = (y / x).atan() + T::cst(a0);
    raw + T::cst(2.0 * PI * k)
}

/// Rest values and stiffnesses of one interior node.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NodeElastic {
    /// EI₁/Δl, EI₂/Δl, GJ/Δl.
    pub ei1: f64,
    pub ei2: f64,
    pub gj: f64,
    pub kappa_bar: [f64; 2],
    pub twist_bar: f64,
}

/// Material curvatures (κ₁, κ₂), twist m and reference twist m_ref at a node.
/// `ref_twist_old` is the node's reference twist at the start of the step.
#[inline]
pub fn strains<T: Real>(
    e: V3<T>,
    f: V3<T>,
    th: [T; 2],
    old: [&EdgeFrame; 2],
    ref_twist_old: f64,
) -> ([T; 2], T, T) {
    let (te, a1e) = frame_of(e, old[0]);
    let (tf, a1f) = frame_of(f, old[1]);
    let a2e = cross(te, a1e);
    let a2f = cross(tf, a1f);
    let (ce, se) = (th[0].cos(), th[0].sin());
    let (cf, sf) = (th[1].cos(), th[1].sin());
    let m1e = add(mul(ce, a1e), mul(se, a2e));
    let m2e = sub(mul(ce, a2e), mul(se, a1e));
    let m1f = add(mul(cf, a1f), mul(sf, a2f));
    let m2f = sub(mul(cf, a2f), mul(sf, a1f));
    let kb = mul(T::cst(2.0) / (T::cst(1.0) + dot(te, tf)), cross(te, tf));
    let k1 = dot(kb, add(m2e, m2f)).scale(0.5);
    let k2 = -dot(kb, add(m1e, m1f)).scale(0.5);
    let u = transport(a1e, te, tf);
    let mref = signed_angle(u, a1f, tf, ref_twist_old);
    ([k1, k2], th[1] - th[0] + mref, mref)
}

/// Bending and twisting energy of one node: (E_b, E_t).
#[inline]
pub fn bend_twist<T: Real>(
    e: V3<T>,
    f: V3<T>,
    th: [T; 2],
    old: [&EdgeFrame; 2],
    ref_twist_old: f64,
    p: &NodeElastic,
) -> (T, T) {
    let (k, m, _) = strains(e, f, th, old, ref_twist_old);
    let d1 = k[0] - T::cst(p.kappa_bar[0]);
    let d2 = k[1] - T::cst(p.kappa_bar[1]);
    let dm = m - T::cst(p.twist_bar);
    let eb = (d1 * d1).scale(0.5 * p.ei1) + (d2 * d2).scale(0.5 * p.ei2);
    (eb, (dm * dm).scale(0.5 * p.gj))
}

/// Which of the 8 stencil variables (e, f, θₑ, θ_f) each of the 11 DOFs
/// (x₀, θₑ, x₁, θ_f, x₂) feeds, with its sign: e = x₁ − x₀, f = x₂ − x₁.
const MAP: [&[(usize, f64)]; 11] = [
    &[(0, -1.0)],
    &[(1, -1.0)],
    &[(2, -1.0)],
    &[(6, 1.0)],
    &[(0, 1.0), (3, -1.0)],
    &[(1, 1.0), (4, -1.0)],
    &[(2, 1.0), (5, -1.0)],
    &[(7, 1.0)],
    &[(3, 1.0)],
    &[(4, 1.0)],
    &[(5, 1.0)],
];

/// Split the 11 stencil DOFs into the edges and angles.
#[inline]
fn split(x: &[f64; 11]) -> ([f64; 3], [f64; 3], [f64; 2]) {
    (
        [x[4] - x[0], x[5] - x[1], x[6] - x[2]],
        [x[8] - x[4], x[9] - x[5], x[10] - x[6]],
        [x[3], x[7]],
    )
}

/// Energy (bending + twisting) of the stencil with DOFs `x`, no derivatives.
pub fn node_energy(x: &[f64; 11], old: [&EdgeFrame; 2], rt_old: f64, p: &NodeElastic) -> f64 {
    let (e, f, th) = split(x);
    let (eb, et) = bend_twist(e, f, th, old, rt_old, p);
    eb + et
}

/// Energy, gradient and Hessian (bending + twisting) of the stencil with DOFs `x`.
pub fn node_derivatives(
    x: &[f64; 11],
    old: [&EdgeFrame; 2],
    rt_old: f64,
    p: &NodeElastic,
    grad: &mut [f64; 11],
    hess: &mut [[f64; 11]; 11],
) -> f64 {
    let (e, f, th) = split(x);
    let ed: V3<Dual2<8>> = [
        Dual2::var(e[0], 0),
        Dual2::var(e[1], 1),
        Dual2::var(e[2], 2),
    ];
    let fd: V3<Dual2<8>> = [
        Dual2::var(f[0], 3),
        Dual2::var(f[1], 4),
        Dual2::var(f[2], 5),
    ];
    let thd = [Dual2::var(th[0], 6), Dual2::var(th[1], 7)];
    let (eb, et) = bend_twist(ed, fd, thd, old, rt_old, p);
    let en = eb + et;
    for (i, gi) in grad.iter_mut().enumerate() {
        *gi = MAP[i].iter().map(|&(a, s)| s * en.g[a]).sum();
    }
    for i in 0..11 {
        for j in 0..11 {
            let mut v = 0.0;
            for &(a, sa) in MAP[i] {
                for &(b, sb) in MAP[j] {
                    v += sa * sb * en.hess(a, b);
                }
            }
            hess[i][j] = v;
        }
    }
    en.v
}

/// The new frame of an edge after a step: tangent of `e`, a₁ transported from `old`.
pub fn advance_frame(e: [f64; 3], old: &EdgeFrame) -> EdgeFrame {
    let (t, a1) = frame_of::<f64>(e, old);
    EdgeFrame { t, a1 }
}

/// Reference twist at a node given the (already advanced) frames of its two edges.
pub fn reference_twist(fe: &EdgeFrame, ff: &EdgeFrame, near: f64) -> f64 {
    let u = transport(fe.a1, fe.t, ff.t);
    signed_angle(u, ff.a1, ff.t, near)
}

/// Material frame (m₁, m₂) of an edge given its reference frame and angle.
pub fn material_frame(fr: &EdgeFrame, theta: f64) -> ([f64; 3], [f64; 3]) {
    let a2 = cross(fr.t, fr.a1);
    let (s, c) = theta.sin_cos();
    let m1 = add(mul(c, fr.a1), mul(s, a2));
    let m2 = sub(mul(c, a2), mul(s, fr.a1));
    (vals(m1), vals(m2))
}
