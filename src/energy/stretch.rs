//! Stretching spring on one edge: E_s = ½ EA l̄ (|e|/l̄ − 1)², e = x₁ − x₀.
//! Degrees of freedom (x₀, y₀, x₁, y₁).

/// Energy, gradient and (optionally) Hessian of one stretching element.
#[inline]
pub fn stretch(
    x: &[f64; 4],
    ea: f64,
    rest: f64,
    grad: &mut [f64; 4],
    hess: Option<&mut [[f64; 4]; 4]>,
) -> f64 {
    let e = [x[2] - x[0], x[3] - x[1]];
    let l = (e[0] * e[0] + e[1] * e[1]).sqrt();
    let strain = l / rest - 1.0;
    let energy = 0.5 * ea * rest * strain * strain;
    let t = [e[0] / l, e[1] / l];
    let f = ea * strain; // dE/dl
    grad[0] = -f * t[0];
    grad[1] = -f * t[1];
    grad[2] = f * t[0];
    grad[3] = f * t[1];
    if let Some(h) = hess {
        // d²E/de² = EA/l̄ t tᵀ + EA (l/l̄ − 1)/l (I − t tᵀ)
        let a = ea / rest;
        let b = f / l;
        let mut k = [[0.0; 2]; 2];
        for i in 0..2 {
            for j in 0..2 {
                let id = if i == j { 1.0 } else { 0.0 };
                k[i][j] = a * t[i] * t[j] + b * (id - t[i] * t[j]);
            }
        }
        for i in 0..2 {
            for j in 0..2 {
                h[i][j] = k[i][j];
                h[i + 2][j + 2] = k[i][j];
                h[i][j + 2] = -k[i][j];
                h[i + 2][j] = -k[i][j];
            }
        }
    }
    energy
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::energy::fd::{self, Lcg};

    fn g_of(x: &[f64; 4], ea: f64, rest: f64) -> [f64; 4] {
        let mut g = [0.0; 4];
        stretch(x, ea, rest, &mut g, None);
        g
    }

    #[test]
    fn golden_gradient() {
        let x = [0.0062, -0.0420, 0.0500, -0.0661];
        let g = g_of(&x, 3141.6, 0.05);
        let want = [0.4129, -0.2272, -0.4129, 0.2272];
        for i in 0..4 {
            assert!(
                (g[i] - want[i]).abs() < 5e-4 * 0.4129 + 5e-5,
                "{g:?} vs {want:?}"
            );
        }
    }

    #[test]
    fn gradient_and_hessian_match_finite_differences() {
        let mut r = Lcg(7);
        for _ in 0..200 {
            let x = [
                r.range(-1.0, 1.0),
                r.range(-1.0, 1.0),
                r.range(-1.0, 1.0),
                r.range(-1.0, 1.0),
            ];
            let rest = r.range(0.2, 2.0);
            let ea = r.range(1.0, 100.0);
            let mut g = [0.0; 4];
            let mut h = [[0.0; 4]; 4];
            stretch(&x, ea, rest, &mut g, Some(&mut h));
            let gfd = fd::gradient(|y| stretch(y, ea, rest, &mut [0.0; 4], None), &x, 1e-6);
            assert!(fd::rel_err(&g, &gfd, 1e-8) < 1e-6, "{g:?} {gfd:?}");
            let hfd = fd::jacobian(|y| g_of(y, ea, rest), &x, 1e-6);
            for i in 0..4 {
                assert!(
                    fd::rel_err(
                        &h[i],
                        &hfd[i],
                        h.iter().flatten().fold(0.0f64, |m, v| m.max(v.abs()))
                    ) < 1e-6,
                    "row {i}: {:?} {:?}",
                    h[i],
                    hfd[i]
                );
            }
        }
    }

    #[test]
    fn golden_hessian_matches_fd_of_golden_gradient() {
        let x = [0.0062, -0.0420, 0.0500, -0.0661];
        let mut h = [[0.0; 4]; 4];
        stretch(&x, 3141.6, 0.05, &mut [0.0; 4], Some(&mut h));
        let hfd = fd::jacobian(|y| g_of(y, 3141.6, 0.05), &x, 1e-7);
        let scale = h.iter().flatten().fold(0.0f64, |m, v| m.max(v.abs()));
        for i in 0..4 {
            assert!(fd::rel_err(&h[i], &hfd[i], scale) < 1e-6);
        }
    }
}
