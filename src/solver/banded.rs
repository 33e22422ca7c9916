//! Banded LU factorisation with partial pivoting (the LAPACK `gbtf2`/`gbtrs` algorithm) in
//! column-major band storage. The rod Jacobian couples each node with its two neighbours on
//! either side (bending spans three nodes), so with two DOFs per node its half-bandwidth is 5
//! and a factorisation costs O(n). Storage is allocated once per rod and reused every step:
//! there is no symbolic analysis to redo because the band pattern never changes.

#[derive(Debug, Clone)]
pub struct BandLu {
    n: usize,
    kl: usize,
    ku: usize,
    ldab: usize,
    ab: Vec<f64>,
    ipiv: Vec<usize>,
}

impl BandLu {
    pub fn new(n: usize, kl: usize, ku: usize) -> Self {
        let ldab = 2 * kl + ku + 1;
        Self {
            n,
            kl,
            ku,
            ldab,
            ab: vec![0.0; ldab * n.max(1)],
            ipiv: vec![0; n],
        }
    }

    pub fn dim(&self) -> usize {
        self.n
    }

    pub fn clear(&mut self) {
        self.ab.fill(0.0);
    }

    #[inline(always)]
    fn idx(&self, i: usize, j: usize) -> usize {
        // Row i, column j lives at ab[kl + ku + i − j, j].
        j * self.ldab + self.kl + self.ku + i - j
    }

    /// Add `v` to A[i][j]; (i, j) must lie inside the band.
    #[inline(always)]
    pub fn add(&mut self, i: usize, j: usize, v: f64) {
        debug_assert!(
            i <= j + self.kl && j <= i + self.ku,
            "({i},{j}) outside the band"
        );
        let k = self.idx(i, j);
        self.ab[k] += v;
    }

    #[inline(always)]
    pub fn get(&self, i: usize, j: usize) -> f64 {
        if i > j + self.kl || j > i + self.ku || i >= self.n || j >= self.n {
            return 0.0;
        }
        self.ab[self.idx(i, j)]
    }

    #[inline(always)]
    fn set(&mut self, i: usize, j: usize, v: f64) {
        let k = self.idx(i, j);
        self.ab[k] = v;
    }

    /// Filter the node whose two DOFs start at `a` with P = I − n nᵀ on both sides and put
    /// `s · n nᵀ` on its diagonal block: the modified-mass system P J P + s (I − P), whose
    /// solution has no component along n at that node. Must be called for every constrained
    /// node before [`BandLu::factor`]; rows first, then columns, so the result is P J P.
    pub fn filter_rows(&mut self, a: usize, nrm: [f64; 2]) {
        let lo = a.saturating_sub(self.kl.min(4));
        let hi = (a + 5).min(self.n - 1);
        for c in lo..=hi {
            let (x, y) = (self.get(a, c), self.get(a + 1, c));
            let d = nrm[0] * x + nrm[1] * y;
            if a <= c + self.kl && c <= a + self.ku {
                self.set(a, c, x - nrm[0] * d);
            }
            if a < c + self.kl && c <= a + 1 + self.ku {
                self.set(a + 1, c, y - nrm[1] * d);
            }
        }
    }

    /// Replace rows `a`, `a + 1` (one node) by `L` times them: the node's equations become
    /// L r = 0 (a kinetic-friction row, see `contact::friction`).
    pub fn transform_rows(&mut self, a: usize, l: [[f64; 2]; 2]) {
        let lo = a.saturating_sub(self.kl.min(4));
        let hi = (a + 5).min(self.n - 1);
        for c in lo..=hi {
            let (x, y) = (self.get(a, c), self.get(a + 1, c));
            if a <= c + self.kl && c <= a + self.ku {
                self.set(a, c, l[0][0] * x + l[0][1] * y);
            }
            if a < c + self.kl && c <= a + 1 + self.ku {
                self.set(a + 1, c, l[1][0] * x + l[1][1] * y);
            }
        }
    }

    pub fn filter_cols(&mut self, a: usize, nrm: [f64; 2], s: f64) {
        let lo = a.saturating_sub(self.ku.min(4));
        let hi = (a + 5).min(self.n - 1);
        for r in lo..=hi {
            let (x, y) = (self.get(r, a), self.get(r, a + 1));
            let d = nrm[0] * x + nrm[1] * y;
            if r <= a + self.kl && a <= r + self.ku {
                self.set(r, a, x - nrm[0] * d);
            }
            if r <= a + 1 + self.kl && a < r + self.ku {
                self.set(r, a + 1, y - nrm[1] * d);
            }
        }
        for i in 0..2 {
            for j in 0..2 {
                self.add(a + i, a + j, s * nrm[i] * nrm[j]);
            }
        }
    }

    /// LU with partial pivoting in place. Returns the column of a zero pivot on failure.
    pub fn factor(&mut self) -> Result<(), usize> {
        let (n, kl, ku) = (self.n, self.kl, self.ku);
        let kv = kl + ku;
        // Zero the fill-in rows above the original band.
        for j in 0..n {
            for r in 0..kl {
                self.ab[j * self.ldab + r] = 0.0;
            }
        }
        let mut ju = 0usize;
        for j in 0..n {
            let km = kl.min(n - 1 - j);
            let base = j * self.ldab + kv;
            let mut jp = 0;
            let mut best = self.ab[base].abs();
            for r in 1..=km {
                let v = self.ab[base + r].abs();
                if v > best {
                    best = v;
                    jp = r;
                }
            }
            self.ipiv[j] = j + jp;
            if best == 0.0 || !best.is_finite() {
                return Err(j);
            }
            ju = ju.max((j + ku + jp).min(n - 1));
            if jp != 0 {
                for c in j..=ju {
                    let i1 = self.idx(j, c);
                    let i2 = self.idx(j + jp, c);
                    self.ab.swap(i1, i2);
                }
            }
            let piv = self.ab[base];
            let inv = 1.0 / piv;
            for r in 1..=km {
                self.ab[base + r] *= inv;
            }
            for c in j + 1..=ju {
                let t = self.ab[self.idx(j, c)];
                if t != 0.0 {
                    let cb = self.idx(j, c);
                    for r in 1..=km {
                        let l = self.ab[base + r];
                        self.ab[cb + r] -= l * t;
                    }
                }
            }
        }
        Ok(())
    }

    /// Solve A x = b in place after [`BandLu::factor`].
    pub fn solve(&self, b: &mut [f64]) {
        let (n, kl, ku) = (self.n, self.kl, self.ku);
        let kv = kl + ku;
        for j in 0..n {
            let lm = kl.min(n - 1 - j);
            let p = self.ipiv[j];
            if p != j {
                b.swap(j, p);
            }
            let bj = b[j];
            if bj != 0.0 {
                let base = j * self.ldab + kv;
                for r in 1..=lm {
                    b[j + r] -= self.ab[base + r] * bj;
                }
            }
        }
        for j in (0..n).rev() {
            let base = j * self.ldab + kv;
            b[j] /= self.ab[base];
            let bj = b[j];
            if bj != 0.0 {
                let top = j.saturating_sub(kv);
                for i in top..j {
                    b[i] -= self.ab[self.idx(i, j)] * bj;
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::energy::fd::Lcg;

    fn dense_mul(a: &[Vec<f64>], x: &[f64]) -> Vec<f64> {
        a.iter()
            .map(|r| r.iter().zip(x).map(|(p, q)| p * q).sum())
            .collect()
    }

    #[test]
    fn solves_random_banded_systems_including_indefinite() {
        let mut rng = Lcg(5);
        for &n in &[1usize, 2, 5, 6, 11, 40, 101] {
            for trial in 0..5 {
                let (kl, ku) = (5, 5);
                let mut dense = vec![vec![0.0; n]; n];
                let mut b = BandLu::new(n, kl, ku);
                for i in 0..n {
                    for j in i.saturating_sub(kl)..(i + ku + 1).min(n) {
                        let mut v = rng.range(-1.0, 1.0);
                        // Some trials have a zero diagonal to force pivoting.
                        if i == j && trial % 2 == 1 {
                            v = 0.0;
                        }
                        if i == j && trial % 2 == 0 {
                            v += 8.0;
                        }
                        dense[i][j] = v;
                        b.add(i, j, v);
                    }
                }
                let x: Vec<f64> = (0..n).map(|i| (i as f64 * 0.37).sin()).collect();
                let mut rhs = dense_mul(&dense, &x);
                if b.factor().is_err() {
                    continue;
                }
                b.solve(&mut rhs);
                for i in 0..n {
                    assert!(
                        (rhs[i] - x[i]).abs() < 1e-8,
                        "n={n} trial={trial} i={i}: {} vs {}",
                        rhs[i],
                        x[i]
                    );
                }
            }
        }
    }

    #[test]
    fn filter_keeps_solution_off_the_normal() {
        // A rod-like matrix: symmetric, two DOFs per node, nodes coupled to two neighbours
        // on either side.
        let n = 12;
        let mut rng = Lcg(9);
        let mut b = BandLu::new(n, 5, 5);
        let mut dense = vec![vec![0.0; n]; n];
        for i in 0..n {
            for j in i..n {
                if (i / 2).abs_diff(j / 2) <= 2 {
                    let v = if i == j {
                        10.0
                    } else {
                        0.3 * rng.range(-1.0, 1.0)
                    };
                    dense[i][j] = v;
                    dense[j][i] = v;
                }
            }
        }
        for i in 0..n {
            for j in 0..n {
                if dense[i][j] != 0.0 {
                    b.add(i, j, dense[i][j]);
                }
            }
        }
        let nrm = [0.6, 0.8];
        b.filter_rows(4, nrm);
        b.filter_cols(4, nrm, 10.0);
        let mut rhs: Vec<f64> = (0..n).map(|i| (i as f64).cos()).collect();
        // Project the right-hand side too.
        let d = nrm[0] * rhs[4] + nrm[1] * rhs[5];
        rhs[4] -= nrm[0] * d;
        rhs[5] -= nrm[1] * d;
        b.factor().unwrap();
        b.solve(&mut rhs);
        assert!((nrm[0] * rhs[4] + nrm[1] * rhs[5]).abs() < 1e-14);
    }
}
