//! Bending spring at an interior node: E_b = ½ EI (κ − κ̄)² / Δl, with
//! κ = 2 tan(φ/2) = 2 (e₁ × e₂) / (|e₁||e₂| + e₁·e₂) the signed turning angle measure between
//! e₁ = x₁ − x₀ and e₂ = x₂ − x₁. Degrees of freedom (x₀, y₀, x₁, y₁, x₂, y₂).
//!
//! Derivatives go through the turning angle φ = θ(e₂) − θ(e₁), θ(e) = atan2(e_y, e_x):
//! ∂θ/∂e = e⊥/|e|², ∂²θ/∂e² = (J − 2 (J e) eᵀ/|e|²)/|e|², J the 90° rotation; then
//! dκ/dφ = 1 + κ²/4, d²κ/dφ² = (κ/2)(1 + κ²/4).

/// The curvature measure κ of three points.
#[inline]
pub fn curvature(x: &[f64; 6]) -> f64 {
    let e1 = [x[2] - x[0], x[3] - x[1]];
    let e2 = [x[4] - x[2], x[5] - x[3]];
    let cross = e1[0] * e2[1] - e1[1] * e2[0];
    let dot = e1[0] * e2[0] + e1[1] * e2[1];
    let l1 = (e1[0] * e1[0] + e1[1] * e1[1]).sqrt();
    let l2 = (e2[0] * e2[0] + e2[1] * e2[1]).sqrt();
    2.0 * cross / (l1 * l2 + dot)
}

/// κ, its gradient and (optionally) its Hessian.
#[inline]
pub fn curvature_derivatives(
    x: &[f64; 6],
    grad: &mut [f64; 6],
    hess: Option<&mut [[f64; 6]; 6]>,
) -> f64 {
    let e1 = [x[2] - x[0], x[3] - x[1]];
    let e2 = [x[4] - x[2], x[5] - x[3]];
    let k = curvature(x);
    let n1 = e1[0] * e1[0] + e1[1] * e1[1];
    let n2 = e2[0] * e2[0] + e2[1] * e2[1];
    // e⊥ = J e = (−e_y, e_x)
    let p1 = [-e1[1] / n1, e1[0] / n1];
    let p2 = [-e2[1] / n2, e2[0] / n2];
    // ∇φ over (x0, x1, x2): (+p1, −p1 − p2, +p2)
    let gphi = [p1[0], p1[1], -p1[0] - p2[0], -p1[1] - p2[1], p2[0], p2[1]];
    let dk = 1.0 + 0.25 * k * k;
    for i in 0..6 {
        grad[i] = dk * gphi[i];
    }
    if let Some(h) = hess {
        let m = |e: [f64; 2], n: f64| -> [[f64; 2]; 2] {
            let je = [-e[1], e[0]];
            let j = [[0.0, -1.0], [1.0, 0.0]];
            let mut r = [[0.0; 2]; 2];
            for a in 0..2 {
                for b in 0..2 {
                    r[a][b] = (j[a][b] - 2.0 * je[a] * e[b] / n) / n;
                }
            }
            r
        };
        let m1 = m(e1, n1);
        let m2 = m(e2, n2);
        // Hφ = B₂ᵀ M₂ B₂ − B₁ᵀ M₁ B₁ with B₁ = [−I, I, 0], B₂ = [0, −I, I].
        let b1 = [-1.0, 1.0, 0.0];
        let b2 = [0.0, -1.0, 1.0];
        let d2k = 0.5 * k * dk;
        for bi in 0..3 {
            for bj in 0..3 {
                for a in 0..2 {
                    for b in 0..2 {
                        let hphi = b2[bi] * b2[bj] * m2[a][b] - b1[bi] * b1[bj] * m1[a][b];
                        let (r, c) = (2 * bi + a, 2 * bj + b);
                        h[r][c] = d2k * gphi[r] * gphi[c] + dk * hphi;
                    }
                }
            }
        }
    }
    k
}

/// Energy, gradient and (optionally) Hessian of one bending element.
/// `eil` is EI/Δl (N·m), `kbar` the rest curvature measure.
#[inline]
pub fn bend(
    x: &[f64; 6],
    eil: f64,
    kbar: f64,
    grad: &mut [f64; 6],
    hess: Option<&mut [[f64; 6]; 6]>,
) -> f64 {
    let mut gk = [0.0; 6];
    match hess {
        None => {
            let k = curvature_derivatives(x, &mut gk, None);
            let d = k - kbar;
            for i in 0..6 {
                grad[i] = eil * d * gk[i];
            }
            0.5 * eil * d * d
        }
        Some(h) => {
            let mut hk = [[0.0; 6]; 6];
            let k = curvature_derivatives(x, &mut gk, Some(&mut hk));
            let d = k - kbar;
            for i in 0..6 {
                grad[i] = eil * d * gk[i];
                for j in 0..6 {
                    h[i][j] = eil * (gk[i] * gk[j] + d * hk[i][j]);
                }
            }
            0.5 * eil * d * d
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::energy::fd::{self, Lcg};

    fn g_of(x: &[f64; 6], eil: f64, kbar: f64) -> [f64; 6] {
        let mut g = [0.0; 6];
        bend(x, eil, kbar, &mut g, None);
        g
    }

    #[test]
    fn golden_gradient() {
        let x = [0.0062, -0.0420, 0.0500, -0.0661, 0.0938, -0.0420];
        let g = g_of(&x, 7.854e-4 / 0.05, 0.0);
        let want = [0.2172, 0.3947, 0.0, -0.7893, -0.2172, 0.3947];
        for i in 0..6 {
            assert!((g[i] - want[i]).abs() < 1e-3 * 0.7893, "{g:?} vs {want:?}");
        }
    }

    #[test]
    fn curvature_is_two_tan_half_angle() {
        let mut r = Lcg(3);
        for _ in 0..100 {
            let phi: f64 = r.range(-2.5, 2.5);
            let (l1, l2) = (r.range(0.1, 2.0), r.range(0.1, 2.0));
            let th = r.range(-3.0, 3.0);
            let x0 = [r.range(-1.0, 1.0), r.range(-1.0, 1.0)];
            let x1 = [x0[0] + l1 * th.cos(), x0[1] + l1 * th.sin()];
            let x2 = [x1[0] + l2 * (th + phi).cos(), x1[1] + l2 * (th + phi).sin()];
            let k = curvature(&[x0[0], x0[1], x1[0], x1[1], x2[0], x2[1]]);
            assert!((k - 2.0 * (phi / 2.0).tan()).abs() < 1e-10 * (1.0 + k.abs()));
        }
    }

    #[test]
    fn gradient_and_hessian_match_finite_differences() {
        let mut r = Lcg(11);
        for case in 0..300 {
            // Random, moderately bent configurations with curved rest shapes.
            let phi: f64 = r.range(-2.0, 2.0);
            let (l1, l2) = (r.range(0.2, 1.5), r.range(0.2, 1.5));
            let th = r.range(-3.0, 3.0);
            let x0 = [r.range(-1.0, 1.0), r.range(-1.0, 1.0)];
            let x1 = [x0[0] + l1 * th.cos(), x0[1] + l1 * th.sin()];
            let x2 = [x1[0] + l2 * (th + phi).cos(), x1[1] + l2 * (th + phi).sin()];
            let x = [x0[0], x0[1], x1[0], x1[1], x2[0], x2[1]];
            let eil = r.range(0.5, 5.0);
            let kbar = if case % 3 == 0 {
                0.0
            } else {
                r.range(-1.5, 1.5)
            };
            let mut g = [0.0; 6];
            let mut h = [[0.0; 6]; 6];
            bend(&x, eil, kbar, &mut g, Some(&mut h));
            let gfd = fd::gradient(|y| bend(y, eil, kbar, &mut [0.0; 6], None), &x, 1e-6);
            assert!(
                fd::rel_err(&g, &gfd, 1e-6) < 1e-6,
                "case {case}: {g:?} {gfd:?}"
            );
            let hfd = fd::jacobian(|y| g_of(y, eil, kbar), &x, 1e-6);
            let scale = h.iter().flatten().fold(1e-6f64, |m, v| m.max(v.abs()));
            for i in 0..6 {
                assert!(
                    fd::rel_err(&h[i], &hfd[i], scale) < 1e-6,
                    "case {case} row {i}: {:?} {:?}",
                    h[i],
                    hfd[i]
                );
                for j in 0..6 {
                    assert!((h[i][j] - h[j][i]).abs() <= 1e-12 * scale, "symmetry");
                }
            }
        }
    }

    #[test]
    fn golden_hessian_matches_fd_of_golden_gradient() {
        let x = [0.0062, -0.0420, 0.0500, -0.0661, 0.0938, -0.0420];
        let eil = 7.854e-4 / 0.05;
        let mut h = [[0.0; 6]; 6];
        bend(&x, eil, 0.0, &mut [0.0; 6], Some(&mut h));
        let hfd = fd::jacobian(|y| g_of(y, eil, 0.0), &x, 1e-7);
        let scale = h.iter().flatten().fold(0.0f64, |m, v| m.max(v.abs()));
        for i in 0..6 {
            assert!(fd::rel_err(&h[i], &hfd[i], scale) < 1e-6, "row {i}");
        }
    }
}
