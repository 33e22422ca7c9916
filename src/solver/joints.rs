//! Joints between rods (`[[joint]]`), solved exactly inside the implicit step.
//!
//! A joint holds node i of member a and node j of member b at one point: the constraint
//! c = x_a,i − x_b,j = 0 (two equations) with a multiplier Λ, the force member a exerts on
//! member b (r_a,i += Λ, r_b,j −= Λ in the residuals r = M/Δt² (Δq − s) + ∇E − F). A rigid joint
//! also keeps the angle between the members' edges at the joint: one bending spring per pair
//! of arms (an edge of a at node i, an edge of b at node j), E = ½ k ψ², ψ the turning-angle
//! measure of the DER bending element (2 tan(φ/2), src/energy/bend.rs) of the three points
//! (x_a,p, x_a,i, x_a,i + R(−φ̄)(x_b,q − x_a,i)) — the arm of b rotated back by its rest angle
//! φ̄, so ψ = 2 tan((φ − φ̄)/2) and a straight joint is the DER's own element. Its stiffness is
//! that of the two half edges in series, k = 1 / (l_a/(2 EI_a) + l_b/(2 EI_b)) (EI/Δl of the
//! DER when the members are alike), shared equally by the pairs (a rib ending on a flank's
//! interior node has two pairs). A clamped–jointed–free beam is then the one-rod beam.
//!
//! The joined rods of a network are solved together, Newton on all of them at once. Each rod
//! keeps its banded, filtered Jacobian Ã_r (src/solver/newton.rs; contact filters as on any
//! rod); the joints' unknowns are bordered on: z, the updates of the border nodes (every free
//! node a joint's constraint or spring touches), and ΔΛ. With U selecting the border DOFs, W
//! the springs' Hessian on them, G the constraints' rows and Z v = P Ã_r⁻¹ L v (one banded
//! solve per border DOF; P, L the node filters),
//!
//! ```text
//! (I + X (W − ρ I)) z + X Gᵀ ΔΛ = Uᵀ Z(−r),   X = Uᵀ Z U   (block diagonal by rod)
//! G z = −c
//! ```
//!
//! a small dense system, then δ = Z(−r − U y), y = (W − ρ I) z + Gᵀ ΔΛ. The bands carry ρ I on
//! the border DOFs (ρ = EA / shortest edge) and the border takes it back: a member held only
//! by its joints (singular alone in a static solve) factorises, and the step is unchanged.
//! Cost per iteration: O(N) for the bands, one banded solve per border DOF, and a dense solve
//! of the border (two DOFs per border node, two per joint).

use super::coupled::dense_solve;
use super::newton::{self, IterationReport, NewtonFailure, NewtonOptions, RodWork};
use crate::energy::bend::{bend, curvature};
use crate::model::Rod;
use crate::scenario::joint::{components, JointKind, JointSpec};

/// One bending spring of a rigid joint: the arm from node `p` of member a into the joint and
/// the arm from the joint to node `q` of member b; (cos, sin) of the rest turning angle φ̄.
#[derive(Debug, Clone, Copy)]
struct Spring {
    p: usize,
    q: usize,
    cos: f64,
    sin: f64,
    k: f64,
}

/// A joint and what it carried at the last solve.
#[derive(Debug, Clone)]
pub struct Joint {
    pub rods: [usize; 2],
    pub nodes: [usize; 2],
    pub kind: JointKind,
    springs: Vec<Spring>,
    /// The force member a exerts on member b at the joint (N): the constraint's force plus
    /// the springs' forces on b's arm nodes.
    pub force: [f64; 2],
    /// The constraint's multiplier Λ: the force on b's joint node (N).
    lambda: [f64; 2],
    /// The bending moment the joint's springs carry (N·m; 0 for a pin), positive when member
    /// b is turned counter-clockwise from its rest angle to member a.
    pub moment: f64,
}

/// A set of joined rods and its border scratch (allocated once).
#[derive(Debug, Clone, Default)]
pub struct Network {
    pub rods: Vec<usize>,
    pub joints: Vec<usize>,
    /// Border nodes (rod, node, free index) and, per rod of the scenario, each node's slot.
    pub(super) border: Vec<(usize, usize, usize)>,
    pub(super) slot: Vec<Vec<usize>>,
    /// One banded solve Ã⁻¹ L e per border DOF (the rod's free DOFs long).
    pub(super) cols: Vec<Vec<f64>>,
    /// W − ρ I on the border DOFs (row-major).
    pub(super) w: Vec<f64>,
    /// X = Uᵀ P Ã⁻¹ L U (row-major).
    pub(super) x: Vec<f64>,
    dense: Vec<f64>,
    /// The border's solution: z, then ΔΛ.
    pub(super) rhs: Vec<f64>,
    y: Vec<f64>,
    /// The border nodes' residuals before the joints' terms (rods with edge contacts).
    r_old: Vec<f64>,
}

/// Every joint of a scenario and the networks they make.
#[derive(Debug, Clone, Default)]
pub struct Joints {
    pub joints: Vec<Joint>,
    pub networks: Vec<Network>,
    /// Per rod: its network (`usize::MAX` when it is joined to nothing).
    pub network_of: Vec<usize>,
    /// Per rod: the joints' constraint forces on each DOF (N; the springs' are in ∇E).
    pub force: Vec<Vec<f64>>,
}

impl Joints {
    pub fn new(specs: &[JointSpec], rods: &[Rod], works: &[RodWork]) -> Joints {
        let joints: Vec<Joint> = specs.iter().map(|s| joint(s, rods)).collect();
        let comp = components(rods.len(), specs);
        let mut network_of = vec![usize::MAX; rods.len()];
        let mut networks: Vec<Network> = Vec::new();
        for (k, j) in joints.iter().enumerate() {
            let c = comp[j.rods[0]];
            let id = match networks.iter().position(|n| comp[n.rods[0]] == c) {
                Some(id) => id,
                None => {
                    let members: Vec<usize> = (0..rods.len()).filter(|&r| comp[r] == c).collect();
                    for &r in &members {
                        network_of[r] = networks.len();
                    }
                    networks.push(Network {
                        rods: members,
                        ..Network::default()
                    });
                    networks.len() - 1
                }
            };
            networks[id].joints.push(k);
        }
        for n in &mut networks {
            n.allocate(&joints, rods, works);
        }
        Joints {
            joints,
            networks,
            network_of,
            force: rods.iter().map(|r| vec![0.0; 2 * r.n]).collect(),
        }
    }

    pub fn is_empty(&self) -> bool {
        self.joints.is_empty()
    }
}

/// A joint's springs from the rest shapes (none for a pin).
fn joint(s: &JointSpec, rods: &[Rod]) -> Joint {
    let (ra, rb) = (&rods[s.rods[0]], &rods[s.rods[1]]);
    let (i, j) = (s.nodes[0], s.nodes[1]);
    let mut springs = Vec::new();
    if s.kind == JointKind::Rigid {
        let arms = |r: &Rod, i: usize| {
            let mut v = Vec::new();
            if i > 0 {
                v.push((i - 1, r.rest_length[i - 1]));
            }
            if i + 1 < r.n {
                v.push((i + 1, r.rest_length[i]));
            }
            v
        };
        let (aa, ab) = (arms(ra, i), arms(rb, j));
        let pairs = (aa.len() * ab.len()) as f64;
        let pt = |r: &Rod, k: usize| [r.q0[2 * k], r.q0[2 * k + 1]];
        let c = pt(ra, i);
        for &(p, la) in &aa {
            for &(q, lb) in &ab {
                let (xp, xq) = (pt(ra, p), pt(rb, q));
                let e1 = [c[0] - xp[0], c[1] - xp[1]];
                let e2 = [xq[0] - c[0], xq[1] - c[1]];
                let phi = (e1[0] * e2[1] - e1[1] * e2[0]).atan2(e1[0] * e2[0] + e1[1] * e2[1]);
                let k = 1.0 / (0.5 * la / ra.ei + 0.5 * lb / rb.ei) / pairs;
                springs.push(Spring {
                    p,
                    q,
                    cos: phi.cos(),
                    sin: phi.sin(),
                    k,
                });
            }
        }
    }
    Joint {
        rods: s.rods,
        nodes: s.nodes,
        kind: s.kind,
        springs,
        force: [0.0; 2],
        lambda: [0.0; 2],
        moment: 0.0,
    }
}

impl Network {
    fn allocate(&mut self, joints: &[Joint], rods: &[Rod], works: &[RodWork]) {
        self.slot = rods.iter().map(|r| vec![usize::MAX; r.n]).collect();
        for &k in &self.joints {
            let j = &joints[k];
            let mut nodes = vec![(j.rods[0], j.nodes[0]), (j.rods[1], j.nodes[1])];
            for s in &j.springs {
                nodes.push((j.rods[0], s.p));
                nodes.push((j.rods[1], s.q));
            }
            for (r, i) in nodes {
                let fi = works[r].free_index[i];
                if fi != usize::MAX && self.slot[r][i] == usize::MAX {
                    self.slot[r][i] = self.border.len();
                    self.border.push((r, i, fi));
                }
            }
        }
        let k = 2 * self.border.len();
        let m = 2 * self.joints.len();
        self.cols = (0..k)
            .map(|d| vec![0.0; 2 * works[self.border[d / 2].0].nfree])
            .collect();
        self.w = vec![0.0; k * k];
        self.x = vec![0.0; k * k];
        self.dense = vec![0.0; (k + m) * (k + m)];
        self.rhs = vec![0.0; k + m];
        self.y = vec![0.0; k];
        self.r_old = vec![0.0; k];
    }

    /// The DOF of the border that (rod, node, direction) is, if any.
    #[inline]
    pub(super) fn dof(&self, r: usize, i: usize, a: usize) -> Option<usize> {
        let s = self.slot[r][i];
        (s != usize::MAX).then_some(2 * s + a)
    }
}

/// The regularisation ρ of a rod's border DOFs (N/m).
fn rho(rod: &Rod) -> f64 {
    let shortest = rod
        .rest_length
        .iter()
        .cloned()
        .fold(f64::INFINITY, f64::min);
    if rod.n > 1 && rod.ea > 0.0 && shortest > 0.0 {
        rod.ea / shortest
    } else {
        1.0
    }
}

/// The points of a spring: (x_a,p, x_a,i, x_a,i + R(−φ̄)(x_b,q − x_a,i)).
fn spring_points(s: &Spring, a: &[f64], b: &[f64], i: usize) -> [f64; 6] {
    let c = [a[2 * i], a[2 * i + 1]];
    let d = [b[2 * s.q] - c[0], b[2 * s.q + 1] - c[1]];
    [
        a[2 * s.p],
        a[2 * s.p + 1],
        c[0],
        c[1],
        c[0] + s.cos * d[0] + s.sin * d[1],
        c[1] - s.sin * d[0] + s.cos * d[1],
    ]
}

/// T: d(spring points)/d(x_a,p, x_a,i, x_b,q), 6 × 6.
fn spring_map(s: &Spring) -> [[f64; 6]; 6] {
    let r = [[s.cos, s.sin], [-s.sin, s.cos]];
    let mut t = [[0.0; 6]; 6];
    for a in 0..2 {
        t[a][a] = 1.0;
        t[2 + a][2 + a] = 1.0;
        for b in 0..2 {
            t[4 + a][2 + b] = if a == b { 1.0 } else { 0.0 } - r[a][b];
            t[4 + a][4 + b] = r[a][b];
        }
    }
    t
}

/// The joints' forces of the current iterates into the rods' ∇E, residuals, energies and
/// right-hand sides; with `hessian` the springs' Hessian into `net.w` (less ρ, which goes
/// onto the bands). Returns the largest joint violation |c| (m).
pub fn add_joint_terms(
    joints: &mut Joints,
    id: usize,
    rods: &[Rod],
    works: &mut [RodWork],
    hessian: bool,
) -> f64 {
    let Joints {
        joints: list,
        networks,
        force,
        ..
    } = joints;
    let net = &mut networks[id];
    if hessian {
        net.w.fill(0.0);
    }
    for &r in &net.rods {
        force[r].fill(0.0);
    }
    let k = 2 * net.border.len();
    for (s, &(r, i, _)) in net.border.iter().enumerate() {
        net.r_old[2 * s] = works[r].r[2 * i];
        net.r_old[2 * s + 1] = works[r].r[2 * i + 1];
    }
    let mut violation = 0.0f64;
    for &jk in &net.joints {
        let j = &mut list[jk];
        let ([ra, rb], [i, jn]) = (j.rods, j.nodes);
        j.moment = 0.0;
        j.force = j.lambda;
        for sk in 0..j.springs.len() {
            add_spring(j, sk, (&net.slot, &mut net.w), works, hessian);
        }
        for a in 0..2 {
            let lam = j.lambda[a];
            works[ra].r[2 * i + a] += lam;
            works[rb].r[2 * jn + a] -= lam;
            force[ra][2 * i + a] -= lam;
            force[rb][2 * jn + a] += lam;
            let c = works[ra].qn[2 * i + a] - works[rb].qn[2 * jn + a];
            violation = violation.max(c.abs());
        }
    }
    for (s, &(r, i, fi)) in net.border.iter().enumerate() {
        let w = &mut works[r];
        if w.edges.is_empty() {
            let (rx, ry) = newton::rows(w.r[2 * i], w.r[2 * i + 1], w.contact[i]);
            w.rhs[2 * fi] = -rx;
            w.rhs[2 * fi + 1] = -ry;
        } else {
            // The right-hand side keeps the edge contacts' forces (`w.r` does not): add the
            // joints' part alone.
            let d = [
                w.r[2 * i] - net.r_old[2 * s],
                w.r[2 * i + 1] - net.r_old[2 * s + 1],
            ];
            let (rx, ry) = newton::rows(d[0], d[1], w.contact[i]);
            w.rhs[2 * fi] -= rx;
            w.rhs[2 * fi + 1] -= ry;
        }
        if hessian {
            let p = rho(&rods[r]);
            let d = net.dof(r, i, 0).unwrap_or(0);
            for a in 0..2 {
                w.band.add(2 * fi + a, 2 * fi + a, p);
                net.w[(d + a) * k + d + a] -= p;
            }
        }
    }
    violation
}

/// Spring `sk` of joint `j`: its energy, its forces (into ∇E and r of its three nodes; the
/// force on b's arm into the joint's force), its moment, and its Hessian into `net.w`.
fn add_spring(
    j: &mut Joint,
    sk: usize,
    (slot, wmat): (&[Vec<usize>], &mut [f64]),
    works: &mut [RodWork],
    hessian: bool,
) {
    let s = j.springs[sk];
    let ([ra, rb], i) = (j.rods, j.nodes[0]);
    let x = spring_points(&s, &works[ra].qn, &works[rb].qn, i);
    let (mut g6, mut h6) = ([0.0; 6], [[0.0; 6]; 6]);
    works[ra].energy += bend(&x, s.k, 0.0, &mut g6, hessian.then_some(&mut h6));
    let psi = curvature(&x);
    j.moment += s.k * psi * (1.0 + 0.25 * psi * psi);
    let t = spring_map(&s);
    let nodes = [(ra, s.p), (ra, i), (rb, s.q)];
    for (c, &(r, n)) in nodes.iter().enumerate() {
        for a in 0..2 {
            let g: f64 = (0..6).map(|m| t[m][2 * c + a] * g6[m]).sum();
            works[r].grad[2 * n + a] += g;
            works[r].r[2 * n + a] += g;
            if c == 2 {
                j.force[a] -= g;
            }
        }
    }
    if !hessian {
        return;
    }
    // Tᵀ H T on the border DOFs (driven ones have no update).
    let k = wmat.len().isqrt();
    let dof = |r: usize, i: usize, a: usize| {
        let s = slot[r][i];
        (s != usize::MAX).then_some(2 * s + a)
    };
    let mut th = [[0.0; 6]; 6];
    for m in 0..6 {
        for c in 0..6 {
            th[m][c] = (0..6).map(|l| h6[m][l] * t[l][c]).sum();
        }
    }
    for (c1, &(r1, n1)) in nodes.iter().enumerate() {
        for (c2, &(r2, n2)) in nodes.iter().enumerate() {
            for a in 0..2 {
                for b in 0..2 {
                    let (Some(u), Some(v)) = (dof(r1, n1, a), dof(r2, n2, b)) else {
                        continue;
                    };
                    wmat[u * k + v] += (0..6)
                        .map(|m| t[m][2 * c1 + a] * th[m][2 * c2 + b])
                        .sum::<f64>();
                }
            }
        }
    }
}

/// The largest filtered residual of a rod (its free rows), and the node where it is.
pub(super) fn rod_residual(rod: &Rod, w: &RodWork) -> (f64, usize) {
    let mut res = 0.0f64;
    let mut worst = 0;
    for i in 0..rod.n {
        let fi = w.free_index[i];
        if fi == usize::MAX {
            continue;
        }
        let v = w.rhs[2 * fi].abs().max(w.rhs[2 * fi + 1].abs());
        if v > res || v.is_nan() {
            res = v;
            worst = i;
        }
    }
    (res, worst)
}

/// A failure of a network's solve: the rod it names and the Newton failure.
pub type NetworkFailure = (usize, NewtonFailure);

/// An observer of a network's iterations: (rod, its iterate).
pub type OnIteration<'a> = Option<&'a mut dyn FnMut(usize, IterationReport<'_>)>;

/// The worst residual of a network: (rod, node, residual in N).
type Worst = (usize, usize, f64);

/// Solve network `id`'s step with its current constraint sets, starting from the rods' Δq.
/// `on_iter` gets (rod, iteration) after every update.
pub fn solve_network(
    joints: &mut Joints,
    id: usize,
    rods: &[Rod],
    works: &mut [RodWork],
    opt: &NewtonOptions,
    mut on_iter: OnIteration<'_>,
) -> Result<u32, NetworkFailure> {
    for &r in &joints.networks[id].rods {
        newton::place_on_targets(&rods[r], &mut works[r], &[]);
        works[r].stage_factor = false;
    }
    let stol = joints.networks[id]
        .rods
        .iter()
        .map(|&r| opt.step_tol * works[r].length_scale)
        .fold(f64::INFINITY, f64::min);
    let mut iterations = 0u32;
    loop {
        let (ratio, worst, violation) = network_residual(joints, id, rods, works, opt, iterations)?;
        if ratio <= 1.0 && violation <= stol {
            return finite(&joints.networks[id].rods, works, iterations);
        }
        if iterations >= opt.max_iterations {
            return Err((
                worst.0,
                NewtonFailure {
                    node: worst.1,
                    residual: worst.2,
                    reason: "Newton did not converge",
                    iterations,
                },
            ));
        }
        for &r in &joints.networks[id].rods {
            let w = &mut works[r];
            newton::jacobian(&rods[r], w, opt);
            newton::factor(w, worst.2, iterations).map_err(|f| (r, f))?;
            w.factorizations += 1;
        }
        border_solve(joints, id, works, worst, iterations)?;
        let scale = damping(&joints.networks[id].rods, rods, works, worst.2, iterations)?;
        iterations += 1;
        let upd = apply_update(
            joints,
            id,
            rods,
            works,
            scale,
            worst.2,
            iterations,
            &mut on_iter,
        )?;
        if upd <= stol {
            for &r in &joints.networks[id].rods {
                newton::finish_residual(&rods[r], &mut works[r], opt);
            }
            add_joint_terms(joints, id, rods, works, false);
            return finite(&joints.networks[id].rods, works, iterations);
        }
    }
}

fn finite(members: &[usize], works: &[RodWork], iterations: u32) -> Result<u32, NetworkFailure> {
    for &r in members {
        newton::all_finite(&works[r], 0.0, iterations).map_err(|f| (r, f))?;
    }
    Ok(iterations)
}

/// Residuals of every member (with the Hessians) and the joints' terms. Returns the largest
/// residual relative to its rod's force tolerance, the worst (rod, node, residual) and the
/// joints' largest violation.
fn network_residual(
    joints: &mut Joints,
    id: usize,
    rods: &[Rod],
    works: &mut [RodWork],
    opt: &NewtonOptions,
    iterations: u32,
) -> Result<(f64, Worst, f64), NetworkFailure> {
    let members = &joints.networks[id].rods;
    for &r in members {
        newton::residual(&rods[r], &mut works[r], opt, true, iterations).map_err(|f| (r, f))?;
    }
    let violation = add_joint_terms(joints, id, rods, works, true);
    let mut ratio = 0.0f64;
    let mut worst = (joints.networks[id].rods[0], 0, 0.0);
    for &r in &joints.networks[id].rods {
        let (res, node) = rod_residual(&rods[r], &works[r]);
        let q = res / (opt.force_tol * works[r].force_scale);
        if !q.is_finite() {
            return Err((
                r,
                NewtonFailure {
                    node,
                    residual: res,
                    reason: "non-finite residual",
                    iterations,
                },
            ));
        }
        if q > ratio {
            ratio = q;
            worst = (r, node, res);
        }
    }
    Ok((ratio, worst, violation))
}

/// The border's dense system; on return each member's `rhs` holds its (unfiltered) update and
/// `net.rhs[k..]` the multipliers' increments.
fn border_solve(
    joints: &mut Joints,
    id: usize,
    works: &mut [RodWork],
    worst: Worst,
    iterations: u32,
) -> Result<(), NetworkFailure> {
    let Joints {
        joints: list,
        networks,
        ..
    } = joints;
    let net = &mut networks[id];
    let k = 2 * net.border.len();
    let m = 2 * net.joints.len();
    let nd = k + m;
    columns(net, works);
    // δ̃₀ = Ã⁻¹(−L r) in place; b₀ = Uᵀ P δ̃₀.
    for &r in &net.rods {
        let w = &mut works[r];
        w.band.solve(&mut w.rhs);
    }
    for (s, &(r, i, fi)) in net.border.iter().enumerate() {
        let w = &works[r];
        let (x, y) = newton::tangential(w.rhs[2 * fi], w.rhs[2 * fi + 1], w.contact[i]);
        net.rhs[2 * s] = x;
        net.rhs[2 * s + 1] = y;
    }
    let d = &mut net.dense;
    d.fill(0.0);
    for t in 0..k {
        d[t * nd + t] = 1.0;
        for v in 0..k {
            let xtv = net.x[t * k + v];
            if xtv == 0.0 {
                continue;
            }
            for u in 0..k {
                d[t * nd + u] += xtv * net.w[v * k + u];
            }
        }
    }
    for (e, &jk) in net.joints.iter().enumerate() {
        let j = &list[jk];
        for a in 0..2 {
            let row = k + 2 * e + a;
            let c =
                works[j.rods[0]].qn[2 * j.nodes[0] + a] - works[j.rods[1]].qn[2 * j.nodes[1] + a];
            net.rhs[row] = -c;
            for (side, sign) in [(0usize, 1.0), (1, -1.0)] {
                let sl = net.slot[j.rods[side]][j.nodes[side]];
                if sl == usize::MAX {
                    continue;
                }
                let v = 2 * sl + a;
                d[row * nd + v] = sign;
                for t in 0..k {
                    d[t * nd + row] += net.x[t * k + v] * sign;
                }
            }
        }
    }
    if !dense_solve(d, &mut net.rhs, nd) {
        return Err((
            worst.0,
            NewtonFailure {
                node: worst.1,
                residual: worst.2,
                reason: "singular joint system",
                iterations,
            },
        ));
    }
    corrections(net, list, works);
    Ok(())
}

/// Ã⁻¹ L e for every border DOF, and X = Uᵀ P (those) (zero between rods).
pub(super) fn columns(net: &mut Network, works: &[RodWork]) {
    let k = 2 * net.border.len();
    net.x.fill(0.0);
    for col in 0..k {
        let (r, i, fi) = net.border[col / 2];
        let w = &works[r];
        let v = &mut net.cols[col];
        v.fill(0.0);
        let e = if col % 2 == 0 { (1.0, 0.0) } else { (0.0, 1.0) };
        let (ux, uy) = newton::rows(e.0, e.1, w.contact[i]);
        v[2 * fi] = ux;
        v[2 * fi + 1] = uy;
        super::edges::solve_k(w, v);
        for (s, &(rt, it, ft)) in net.border.iter().enumerate() {
            if rt != r {
                continue;
            }
            let (x, y) = newton::tangential(v[2 * ft], v[2 * ft + 1], w.contact[it]);
            net.x[(2 * s) * k + col] = x;
            net.x[(2 * s + 1) * k + col] = y;
        }
    }
}

/// y = (W − ρ I) z + Gᵀ ΔΛ, and each member's update δ̃ = δ̃₀ − Σ y_s Ã⁻¹ L e_s.
pub(super) fn corrections(net: &mut Network, list: &[Joint], works: &mut [RodWork]) {
    let k = 2 * net.border.len();
    for u in 0..k {
        net.y[u] = (0..k).map(|v| net.w[u * k + v] * net.rhs[v]).sum();
    }
    for (e, &jk) in net.joints.iter().enumerate() {
        let j = &list[jk];
        for a in 0..2 {
            let lam = net.rhs[k + 2 * e + a];
            if let Some(v) = net.dof(j.rods[0], j.nodes[0], a) {
                net.y[v] += lam;
            }
            if let Some(v) = net.dof(j.rods[1], j.nodes[1], a) {
                net.y[v] -= lam;
            }
        }
    }
    for col in 0..k {
        let r = net.border[col / 2].0;
        let ys = net.y[col];
        if ys == 0.0 {
            continue;
        }
        for (x, c) in works[r].rhs.iter_mut().zip(&net.cols[col]) {
            *x -= ys * c;
        }
    }
}

/// The multipliers' and the members' updates, damped by `scale`; tells the observer. Returns
/// the largest update (m).
#[allow(clippy::too_many_arguments)]
fn apply_update(
    joints: &mut Joints,
    id: usize,
    rods: &[Rod],
    works: &mut [RodWork],
    scale: f64,
    res: f64,
    iterations: u32,
    on_iter: &mut OnIteration<'_>,
) -> Result<f64, NetworkFailure> {
    let net = &joints.networks[id];
    let n = 2 * net.border.len();
    for (e, &jk) in net.joints.iter().enumerate() {
        for a in 0..2 {
            joints.joints[jk].lambda[a] += scale * net.rhs[n + 2 * e + a];
        }
    }
    let mut upd = 0.0f64;
    for &r in &net.rods {
        let w = &mut works[r];
        let u =
            newton::update(&rods[r], w, Some(scale), &[], res, iterations).map_err(|f| (r, f))?;
        upd = upd.max(u);
        if let Some(cb) = on_iter.as_deref_mut() {
            for k in 0..2 * rods[r].n {
                w.qn[k] = w.q[k] + w.dq[k];
            }
            let report = IterationReport {
                iteration: iterations,
                residual: res,
                update: u,
                q: &w.qn,
            };
            cb(r, report);
        }
    }
    Ok(upd)
}

/// One damping factor for the whole network: no node moves more than its rod allows.
fn damping(
    members: &[usize],
    rods: &[Rod],
    works: &[RodWork],
    res: f64,
    iterations: u32,
) -> Result<f64, NetworkFailure> {
    let mut scale = 1.0f64;
    for &r in members {
        let w = &works[r];
        let full = newton::largest_update(&rods[r], w, &[], res, iterations).map_err(|f| (r, f))?;
        if w.max_update > 0.0 && full > w.max_update {
            scale = scale.min(w.max_update / full);
        }
    }
    Ok(scale)
}

/// The multipliers of network `id` take the border's increments ΔΛ (`net.rhs[k..]`), damped
/// by `scale` (a network solved with free bodies or edge contacts: src/solver/coupled.rs).
pub(super) fn take_multipliers(joints: &mut Joints, id: usize, scale: f64) {
    let net = &joints.networks[id];
    let n = 2 * net.border.len();
    for (e, &jk) in net.joints.iter().enumerate() {
        for a in 0..2 {
            joints.joints[jk].lambda[a] += scale * net.rhs[n + 2 * e + a];
        }
    }
}
