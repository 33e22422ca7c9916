//! A compliant fruit in 3D: the Hertz point (elliptical) contact of a prong on a sphere or an
//! ellipsoid ([`PointContact`], Johnson 1985 §4.2) inside the one implicit Newton step.
//!
//! A contact on a compliant surface keeps its local basis (n, t₁, t₂) and its linearised
//! surface (n·x = target + a·ΔX, a = Gᵀ n on a body) but its normal coordinate is free: the
//! node carries the law's force F(δ) n at the indentation δ = target + a·ΔX − n·x, with
//! ∂F/∂x = −F′ nᵀ and ∂F/∂ΔX = F′ aᵀ in the Jacobian (the band and, on a body, one border
//! column). Stuck, its tangential coordinates are held at the anchor (their reaction is the
//! friction, decided against μ_s F by [`crate::contact::friction::decide_cone`]); sliding, it
//! carries −μ_k F t₁ (an unsymmetric kinetic row −μ_k F′ on its normal column). The body
//! feels the opposite of the node's whole contact force through the rows of the node's
//! elastic residual, as on a rigid body (src/rod3d/world/newton3.rs), so momentum is
//! exchanged exactly.

use super::*;
use crate::contact::compliant::PointContact;
use crate::rod3d::symband::BandSink;

/// One compliant contact at the end of a step: the law's force and the Hertz contact.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pressed3 {
    pub rod: usize,
    pub node: usize,
    pub surface: Surface3,
    /// The law's normal force F (N) and the indentation δ (m).
    pub force: f64,
    pub indentation: f64,
    /// The contact ellipse's semi-axes a ≥ b (m) and the peak pressure p₀ (Pa).
    pub radii: (f64, f64),
    pub pressure: f64,
    /// The surface point under the node (world).
    pub point: V3,
}

/// The indentation of a compliant contact at node position x and body displacement dx.
#[inline]
fn indentation(c: &Contact3, x: &V3, dx: &Vector6<f64>) -> f64 {
    let a = lever_map(&c.lever).transpose() * c.normal;
    c.target + a.dot(dx) - c.normal.dot(x)
}

/// The compliant contacts' forces and stiffnesses into rod r's rows (after its contact bases,
/// body rows and rigid kinetic rows; before the eliminations).
pub(super) fn law_rows(w: &mut Work3, contacts: &[Option<Contact3>], bodies: &[Body3], jac: bool) {
    for bi in 0..w.bases.len() {
        let i = w.bases[bi].0;
        let c = contacts[i].as_ref().unwrap();
        let Some(law) = c.law else { continue };
        let dx = match c.surface {
            Surface3::Body(b) => bodies[b].dx,
            Surface3::Obstacle(_) => Vector6::zeros(),
        };
        let k0 = pos(i);
        let x = World3::node(&w.qn, i);
        let (f, k) = law.force(indentation(c, &x, &dx));
        let mu = c.kinetic();
        // r_n = r_el − F, r_t₁ = r_el,t₁ + μ_k F (rhs = −r).
        w.rhs[k0] += f;
        w.rhs[k0 + 1] -= mu * f;
        if !jac {
            continue;
        }
        BandSink::add(&mut w.band, k0, k0, k);
        if mu > 0.0 && k > 0.0 {
            let mut n = w.kinetic_pool.pop().unwrap_or_default();
            n.clear();
            n.push((k0, -k));
            w.kinetic.push(KineticRow { row: k0 + 1, mu, n });
        }
        if let (Surface3::Body(b), true) = (c.surface, k > 0.0) {
            let a = lever_map(&c.lever).transpose() * c.normal;
            let col = w.border.push(Weight::Body(b, a));
            let col = w.border.col_mut(col);
            col[k0] = -k;
            col[k0 + 1] = mu * k;
        }
    }
}

/// A compliant body contact's part of the bodies' system: the law's force on the body,
/// f = F(δ) (n − μ_k d) (d the slip direction of a sliding contact, else 0), into the
/// right-hand side (Gᵀ f) and its stiffness Gᵀ (n − μ_k d) F′ nᵀ G into S (δ = gap − n·G ΔX);
/// stuck, the two tangential rows t·(G ΔX) = 0 with their force columns, as a rigid stuck
/// contact's (their last force into `forces`).
pub(super) fn body_law_rows(
    bc: &BodyContact3,
    dx: &Vector6<f64>,
    s: &mut DMatrix<f64>,
    fb: &mut DVector<f64>,
    forces: &mut DVector<f64>,
    kkt: &mut crate::rod3d::system::Kkt,
) {
    let law = bc.law.expect("a compliant body contact");
    let g = lever_map(&bc.lever);
    let (f, k) = law.force(bc.indentation(dx));
    let dir = if bc.stuck.is_some() {
        V3::zeros()
    } else {
        bc.dir
    };
    let fdir = bc.normal - dir * bc.coulomb.mu_k;
    let gf = g.transpose() * fdir;
    let gn = g.transpose() * bc.normal;
    let at = 6 * bc.body;
    for e in 0..6 {
        fb[at + e] += f * gf[e];
        for c in 0..6 {
            s[(at + e, at + c)] += k * gf[e] * gn[c];
        }
    }
    if bc.stuck.is_some() {
        // The held friction's last force, for the convergence test (as a rigid contact's).
        let ft = bc.force - bc.normal * bc.normal.dot(&bc.force);
        let gt = g.transpose() * ft;
        for e in 0..6 {
            forces[at + e] += gt[e];
        }
        let now = g * dx;
        for t in bc.tangents() {
            let j = t.transpose() * g;
            kkt.push(at, j, -j, -t.dot(&now));
        }
    }
}

impl World3 {
    /// The compliant material of a surface, if any.
    pub fn material(&self, s: Surface3) -> Option<&Material> {
        match s {
            Surface3::Obstacle(k) => self.materials.get(k).and_then(Option::as_ref),
            Surface3::Body(b) => self.bodies[b].material.as_ref(),
        }
    }

    /// The Hertz law of rod r's node i on surface `s` where `prox` sees it (None: rigid):
    /// the fruit's principal curvatures there plus the prong's (a round section is a
    /// cylinder along the rod, a rectangular one a flat face), E* of both materials.
    pub(super) fn law_at(
        &self,
        r: usize,
        i: usize,
        s: Surface3,
        prox: &Proximity3,
    ) -> Option<PointContact> {
        let m = self.material(s)?;
        let prong = self.prong_compliance.get(r).copied().unwrap_or(0.0);
        let e_star = 1.0 / (prong + m.compliance());
        let n = prox.normal;
        let pick = if n.x.abs() < 0.9 { V3::x() } else { V3::y() };
        let t1 = (pick - n * n.dot(&pick)).normalize();
        let t = [t1, n.cross(&t1)];
        let fruit = surface_curvature(self.surface(s), &prox.closest, &t);
        let mut face = [[0.0; 2]; 2];
        if let Section3::Circle { r: radius } = self.sections[r] {
            let q = &self.rods[r].q;
            let (a, b) = (i.saturating_sub(1), (i + 1).min(self.rods[r].rod.n - 1));
            let axis = Self::node(q, b) - Self::node(q, a);
            let u = V3::new(axis.dot(&t[0]), axis.dot(&t[1]), 0.0);
            if u.norm() > 0.0 {
                let u = u / u.norm();
                // Curvature 1/r across the axis, 0 along it.
                let across = [-u.y, u.x];
                for (p, row) in face.iter_mut().enumerate() {
                    for (q, v) in row.iter_mut().enumerate() {
                        *v = across[p] * across[q] / radius;
                    }
                }
            }
        }
        Some(PointContact::of_curvatures(fruit, face, e_star))
    }

    /// Every compliant contact at the end of the last step.
    pub fn pressed(&self) -> Vec<Pressed3> {
        let mut out = Vec::new();
        for (r, cs) in self.contacts.iter().enumerate() {
            for (i, c) in cs.iter().enumerate() {
                let Some((c, law)) = c.and_then(|c| c.law.map(|l| (c, l))) else {
                    continue;
                };
                let x = Self::node(&self.rods[r].q, i);
                let d = indentation(&c, &x, &self.body_dx(c.surface)).max(0.0);
                out.push(Pressed3 {
                    rod: r,
                    node: i,
                    surface: c.surface,
                    force: law.force(d).0,
                    indentation: d,
                    radii: law.radii(d),
                    pressure: law.peak_pressure(d),
                    point: x + c.normal * (d - c.offset),
                });
            }
        }
        out
    }

    /// The Hertz law of compliant body b on fixed obstacle k at the body's surface point `p`
    /// (outward normal of the obstacle `n`; None: a rigid body). The obstacle is rigid: E* is
    /// the fruit's; its curvature (a sphere's or an ellipsoid's, a plane's 0) adds to the
    /// fruit's.
    pub(super) fn table_law(&self, b: usize, k: usize, p: &V3, n: &V3) -> Option<PointContact> {
        let m = self.bodies[b].material.as_ref()?;
        let pick = if n.x.abs() < 0.9 { V3::x() } else { V3::y() };
        let t1 = (pick - n * n.dot(&pick)).normalize();
        let t = [t1, n.cross(&t1)];
        let fruit = surface_curvature(&self.bodies[b].obstacle, p, &t);
        let table = surface_curvature(&self.obstacles[k], p, &t);
        Some(PointContact::of_curvatures(
            fruit,
            table,
            1.0 / m.compliance(),
        ))
    }

    /// The compliant fruit's contacts with fixed obstacles (the table) at the end of the last
    /// step, as [`Pressed3`] with `surface` the obstacle and `rod`, `node` 0.
    pub fn pressed_on_obstacles(&self) -> Vec<Pressed3> {
        let mut out = Vec::new();
        for bc in &self.body_contacts {
            let Some(law) = bc.law else { continue };
            let body = &self.bodies[bc.body];
            let d = bc.indentation(&body.dx).max(0.0);
            out.push(Pressed3 {
                rod: 0,
                node: 0,
                surface: Surface3::Obstacle(bc.obstacle),
                force: law.force(d).0,
                indentation: d,
                radii: law.radii(d),
                pressure: law.peak_pressure(d),
                point: body.centre() + bc.lever,
            });
        }
        out
    }

    /// Whether a compliant contact's law force has gone (its indentation is ≤ 0).
    pub(super) fn law_released(&self, r: usize, i: usize, c: &Contact3) -> bool {
        let x = Self::node(&self.work[r].qn, i);
        c.law.is_some() && indentation(c, &x, &self.body_dx(c.surface)) <= 0.0
    }
}

/// The curvature tensor of a sphere or an ellipsoid at its surface point `p` in the tangent
/// basis `t` (positive: convex). Other shapes are flat (they carry no material).
fn surface_curvature(o: &Obstacle3, p: &V3, t: &[V3; 2]) -> [[f64; 2]; 2] {
    use crate::obstacle3::Shape3;
    let mut k = [[0.0; 2]; 2];
    match &o.shape {
        Shape3::Sphere { radius } => {
            k[0][0] = 1.0 / radius;
            k[1][1] = 1.0 / radius;
        }
        Shape3::Ellipsoid { semi_axes } => {
            // F = xᵀ D x − 1: the normal curvature along a unit tangent v is vᵀ D v / |D x|.
            let rot = o.pose.rotation;
            let local = rot.inverse() * (p - o.pose.position);
            let d = V3::new(
                1.0 / (semi_axes[0] * semi_axes[0]),
                1.0 / (semi_axes[1] * semi_axes[1]),
                1.0 / (semi_axes[2] * semi_axes[2]),
            );
            let g = d.component_mul(&local).norm();
            let tl = [rot.inverse() * t[0], rot.inverse() * t[1]];
            for a in 0..2 {
                for b in 0..2 {
                    k[a][b] = tl[a].component_mul(&d).dot(&tl[b]) / g;
                }
            }
        }
        _ => {}
    }
    k
}
