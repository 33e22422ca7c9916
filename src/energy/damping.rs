//! Kelvin–Voigt material damping of a discrete elastic rod: beside each element's elastic
//! force k s ∇s (s the element's strain — stretch ε or curvature κ — and k its stiffness,
//! E = ½ k (s − s̄)²) acts the viscous force τ k ṡ ∇s with ṡ = ∇s · v. The retardation time τ
//! is a material property: a loss factor tan δ at a frequency f gives τ = tan δ / (2π f).
//! The force is linear in the node velocities, so its work over a backward Euler step,
//! τ k dt ṡ², is never negative.

use crate::energy::bend::curvature_derivatives;
use crate::model::Rod;

/// The strain gradient of the stretch element (x₀, y₀, x₁, y₁) with rest length `rest`:
/// ∇ε = (−t, t)/l̄, t the unit edge.
#[inline]
pub fn stretch_strain_gradient(x: &[f64; 4], rest: f64) -> [f64; 4] {
    let e = [x[2] - x[0], x[3] - x[1]];
    let l = (e[0] * e[0] + e[1] * e[1]).sqrt();
    let t = [e[0] / (l * rest), e[1] / (l * rest)];
    [-t[0], -t[1], t[0], t[1]]
}

/// One element's viscous force `f` = τ k (g·v) g for strain gradient `g` and velocities `v`,
/// and when asked its Jacobian with respect to the step's displacement, τ k g gᵀ scaled per
/// column node by dv/dΔq (`vfac`, one per node of the element).
#[inline]
pub fn viscous<const N: usize>(
    g: &[f64; N],
    v: &[f64; N],
    tau_k: f64,
    vfac: &[f64],
    f: &mut [f64; N],
    jac: Option<&mut [[f64; N]; N]>,
) {
    let rate: f64 = g.iter().zip(v).map(|(a, b)| a * b).sum();
    for a in 0..N {
        f[a] = tau_k * rate * g[a];
    }
    if let Some(h) = jac {
        for a in 0..N {
            for c in 0..N {
                h[a][c] = tau_k * g[a] * g[c] * vfac[c / 2];
            }
        }
    }
}

/// One element's Jacobian of its viscous force ([`rod_viscous`]): a stretch element's
/// (nodes e, e + 1) or a bending element's (nodes i − 1, i, i + 1).
pub enum ElementJacobian<'a> {
    Stretch(&'a [[f64; 4]; 4]),
    Bend(&'a [[f64; 6]; 6]),
}

/// The Kelvin–Voigt forces of every element of `rod` at positions `q` and node velocities `v`
/// (interleaved), added into `fd`: the force the material resists with (it enters eq. 2's
/// residual beside ∇E, and the force on the nodes is −fd). With `vfac` (dv/dΔq per node)
/// each element's Jacobian goes to `jacobian` with the element's first node. A rod without
/// a retardation time has none.
pub fn rod_viscous(
    rod: &Rod,
    q: &[f64],
    v: &[f64],
    fd: &mut [f64],
    vfac: Option<&[f64]>,
    mut jacobian: impl FnMut(usize, ElementJacobian<'_>),
) {
    let (tau, n) = (rod.damping_time, rod.n);
    let no_vfac: &[f64] = &[];
    let (mut f4, mut h4) = ([0.0; 4], [[0.0; 4]; 4]);
    for e in 0..n.saturating_sub(1) {
        let s = 2 * e;
        let x = [q[s], q[s + 1], q[s + 2], q[s + 3]];
        let ve = [v[s], v[s + 1], v[s + 2], v[s + 3]];
        let g = stretch_strain_gradient(&x, rod.rest_length[e]);
        let k = rod.ea * rod.rest_length[e];
        let vf = vfac.map_or(no_vfac, |f| &f[e..e + 2]);
        viscous(&g, &ve, tau * k, vf, &mut f4, vfac.map(|_| &mut h4));
        for a in 0..4 {
            fd[s + a] += f4[a];
        }
        if vfac.is_some() {
            jacobian(e, ElementJacobian::Stretch(&h4));
        }
    }
    let (mut f6, mut h6, mut g6) = ([0.0; 6], [[0.0; 6]; 6], [0.0; 6]);
    for i in 1..n.saturating_sub(1) {
        let s = 2 * (i - 1);
        let x = [q[s], q[s + 1], q[s + 2], q[s + 3], q[s + 4], q[s + 5]];
        let ve = [v[s], v[s + 1], v[s + 2], v[s + 3], v[s + 4], v[s + 5]];
        curvature_derivatives(&x, &mut g6, None);
        let k = rod.ei / rod.bend_length(i);
        let vf = vfac.map_or(no_vfac, |f| &f[i - 1..i + 2]);
        viscous(&g6, &ve, tau * k, vf, &mut f6, vfac.map(|_| &mut h6));
        for a in 0..6 {
            fd[s + a] += f6[a];
        }
        if vfac.is_some() {
            jacobian(i - 1, ElementJacobian::Bend(&h6));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::energy::stretch::stretch;

    /// ∇ε is the stretch gradient divided by dE/dε = EA l̄ ε.
    #[test]
    fn strain_gradient_matches_the_energy_gradient() {
        let x = [0.01, -0.02, 0.07, 0.03];
        let (ea, rest) = (2.0, 0.05);
        let mut g = [0.0; 4];
        stretch(&x, ea, rest, &mut g, None);
        let l = ((x[2] - x[0]).powi(2) + (x[3] - x[1]).powi(2)).sqrt();
        let eps = l / rest - 1.0;
        let ge = stretch_strain_gradient(&x, rest);
        for a in 0..4 {
            assert!(
                (g[a] - ea * rest * eps * ge[a]).abs() < 1e-12,
                "{g:?} {ge:?}"
            );
        }
    }

    /// The force does work τ k (g·v)² ≥ 0 at velocity v and its Jacobian is τ k g gᵀ / dt.
    #[test]
    fn viscous_force_dissipates() {
        let g = [0.3, -0.1, -0.3, 0.1];
        let v = [1.0, 2.0, -0.5, 0.25];
        let mut f = [0.0; 4];
        let mut h = [[0.0; 4]; 4];
        viscous(&g, &v, 2.0, &[10.0, 10.0], &mut f, Some(&mut h));
        let rate: f64 = 0.3 - 0.2 + 0.15 + 0.025;
        let work: f64 = f.iter().zip(&v).map(|(a, b)| a * b).sum();
        assert!((work - 2.0 * rate * rate).abs() < 1e-14);
        assert!((h[0][2] - 2.0 * 0.3 * -0.3 * 10.0).abs() < 1e-14);
    }
}
