//! Static mode's stability check: after the last load step, the smallest eigenvalue of each
//! rod's free-DOF Hessian ∇²E (dead loads have none of their own) by inverse iteration on the
//! banded factor. A negative one means the equilibrium found is a saddle of the potential
//! energy — it exists, but the slightest imperfection leaves it ("unstable equilibrium").
//! Rods with fewer than two driven nodes (rigid-body modes), any contact, or a joint (the
//! Hessian of a network is not one rod's) are not checked.

use super::newton::{assemble, RodWork};
use super::Simulation;
use crate::energy::bend::curvature;
use crate::model::Rod;

/// Inverse-iteration sweeps (the buckling mode separates from the next one by a factor of
/// ≈ 9 in its eigenvalue, so a few dozen reach round-off).
const SWEEPS: usize = 60;

impl Simulation {
    /// The smallest Hessian eigenvalue over the checked rods (N/m), None when none is checked.
    pub(super) fn check_stability(&mut self) {
        let mut min: Option<f64> = None;
        for (r, (rod, w)) in self.rods.iter().zip(&mut self.work).enumerate() {
            let driven = rod.clamped.iter().filter(|c| **c).count();
            if rod.n < 3
                || driven < 2
                || w.nfree == 0
                || w.contact.iter().any(|c| c.is_some())
                || self.joints.network_of[r] != usize::MAX
            {
                continue;
            }
            let (lam, v) = smallest_eigenvalue(rod, w);
            min = Some(min.map_or(lam, |m: f64| m.min(lam)));
            w.rhs.fill(0.0);
            if v.len() == w.rhs.len() {
                w.rhs.copy_from_slice(&v);
            }
        }
        self.stats.min_eigenvalue = min;
        // Negative beyond round-off of the Hessian's scale (EA/l̄ dominates its entries).
        let scale = self
            .rods
            .iter()
            .map(|r| r.ea / r.rest_length.iter().copied().fold(f64::INFINITY, f64::min))
            .fold(0.0f64, f64::max);
        self.stats.unstable_equilibrium = min.is_some_and(|m| m < -1e-10 * scale);
    }
}

/// Inverse iteration with shift 0 converges to the eigenvalue of smallest magnitude: at a
/// bifurcation, the one that changes sign. The Rayleigh quotient vᵀHv/vᵀv of the converged
/// vector is returned.
fn smallest_eigenvalue(rod: &Rod, w: &mut RodWork) -> (f64, Vec<f64>) {
    let dim = 2 * w.nfree;
    assemble(rod, &w.free_index, &w.q, &mut w.grad, Some(&mut w.band));
    // Keep H (band rows i−5 … i+5) for the Rayleigh quotient before the factor overwrites it.
    let h: Vec<[f64; 11]> = (0..dim)
        .map(|i| {
            let mut row = [0.0; 11];
            for (d, x) in row.iter_mut().enumerate() {
                if let Some(j) = (i + d).checked_sub(5) {
                    *x = w.band.get(i, j);
                }
            }
            row
        })
        .collect();
    let hv = |v: &[f64], out: &mut [f64]| {
        for i in 0..dim {
            out[i] = (0..11)
                .filter_map(|d| {
                    (i + d)
                        .checked_sub(5)
                        .filter(|&j| j < dim)
                        .map(|j| h[i][d] * v[j])
                })
                .sum();
        }
    };
    if w.band.factor().is_err() {
        // Singular at the shift: an eigenvalue is 0 to round-off.
        return (0.0, Vec::new());
    }
    // A deterministic start with a part along every mode.
    let mut v: Vec<f64> = (0..dim)
        .map(|i| 1.0 + 0.3 * (i as f64 * 0.7).sin())
        .collect();
    for _ in 0..SWEEPS {
        let norm = v.iter().map(|x| x * x).sum::<f64>().sqrt();
        v.iter_mut().for_each(|x| *x /= norm);
        w.band.solve(&mut v);
    }
    let mut hvv = vec![0.0; dim];
    hv(&v, &mut hvv);
    let num: f64 = v.iter().zip(&hvv).map(|(a, b)| a * b).sum();
    let den: f64 = v.iter().map(|x| x * x).sum();
    (num / den, v)
}

/// Static mode with an imperfection, when the equilibrium found is unstable: push the free
/// nodes along the mode of the negative eigenvalue (left in `w.rhs` by the check) by
/// `push` × L, largest component, in direction `sign`.
pub(super) fn push_along_mode(rod: &Rod, w: &mut RodWork, push: f64, sign: f64) {
    let vmax = w.rhs.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    if vmax == 0.0 {
        return;
    }
    let scale = sign * push * rod.length / vmax;
    for i in 0..rod.n {
        let fi = w.free_index[i];
        if fi == usize::MAX {
            continue;
        }
        w.q[2 * i] += scale * w.rhs[2 * fi];
        w.q[2 * i + 1] += scale * w.rhs[2 * fi + 1];
    }
}

/// Static mode's imperfection: move the free nodes off the rest shape by `amplitude` × L ×
/// (s/L)² across the chord (s the arc length from node 0) and make that the stress-free
/// shape (its rest curvatures), so the load ramp follows the stable branch past a
/// bifurcation instead of the symmetric unstable one.
pub(super) fn imperfection(rod: &mut Rod, w: &mut RodWork, amplitude: f64) {
    if rod.n < 3 || amplitude == 0.0 {
        return;
    }
    let (a, b) = (0, rod.n - 1);
    let chord = [w.q[2 * b] - w.q[2 * a], w.q[2 * b + 1] - w.q[2 * a + 1]];
    let len = chord[0].hypot(chord[1]);
    let nrm = [-chord[1] / len, chord[0] / len];
    let mut s = 0.0;
    for i in 0..rod.n {
        if i > 0 {
            s += rod.rest_length[i - 1];
        }
        if rod.clamped[i] {
            continue;
        }
        let d = amplitude * rod.length * (s / rod.length).powi(2);
        w.q[2 * i] += d * nrm[0];
        w.q[2 * i + 1] += d * nrm[1];
    }
    for i in 1..rod.n - 1 {
        let s = 2 * (i - 1);
        let q = &w.q;
        rod.rest_curvature[i] =
            curvature(&[q[s], q[s + 1], q[s + 2], q[s + 3], q[s + 4], q[s + 5]]);
    }
}
