//! The energy balance of the rods over a run: where the energy put in by the drives and the
//! contacts went (kinetic, elastic, the potential of gravity and dead loads), and what was
//! dissipated — by the material's damping (physics) and by the time integrator (numerics).
//!
//! Per backward Euler step and free node, m (v₁ − v₀)·v₁ = ΔKE + ½ m |v₁ − v₀|² and
//! ∇E(q₁)·Δq = ΔE + B with B = E(q₀) − E(q₁) + ∇E(q₁)·Δq (≥ 0 for a convex energy): so the
//! integrator dissipates ½ m |Δv|² + B per step, each term computed on its own, and
//! ΔKE + ΔE + ΔP + D_damping + D_integrator = W_drive + W_contact up to the Newton residual
//! of the free nodes — the closure. Under BDF2 no such split exists; the integrator term is
//! the remainder (and the closure zero by construction).

/// Cumulative energy terms (J) of all rods.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize, schemars::JsonSchema)]
pub struct Balance {
    /// Kinetic energy of the free nodes now.
    pub kinetic_j: f64,
    /// Elastic (stretch + bend) energy now.
    pub elastic_j: f64,
    /// Potential of gravity and the dead loads, relative to the start.
    pub gravity_j: f64,
    /// Dissipated by material damping so far (≥ 0).
    pub damping_j: f64,
    /// Dissipated by the time integrator so far.
    pub integrator_j: f64,
    /// Work of the drives on the rods (through the driven nodes).
    pub drive_j: f64,
    /// Work of the contact forces (normal and friction) on the rods.
    pub contact_j: f64,
    /// Kinetic + elastic energy at the start.
    pub initial_j: f64,
    /// The integrator term is the remainder of the others (BDF2), not computed on its own.
    pub integrator_is_remainder: bool,
}

impl Balance {
    /// What the balance misses: (kinetic + elastic + gravity + damping + integrator) −
    /// (initial + drive + contact), relative to the largest term (0 when all are zero).
    pub fn closure_rel(&self) -> f64 {
        let terms = [
            self.kinetic_j,
            self.elastic_j,
            self.gravity_j,
            self.damping_j,
            self.integrator_j,
            self.drive_j,
            self.contact_j,
            self.initial_j,
        ];
        let scale = terms.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        let miss =
            self.kinetic_j + self.elastic_j + self.gravity_j + self.damping_j + self.integrator_j
                - self.initial_j
                - self.drive_j
                - self.contact_j;
        if scale > 0.0 {
            miss / scale
        } else {
            0.0
        }
    }
}

/// One rod's terms over one step (J).
#[derive(Debug, Clone, Copy, Default)]
pub struct StepTerms {
    pub kinetic_before: f64,
    pub kinetic_after: f64,
    pub elastic_before: f64,
    pub elastic_after: f64,
    pub gravity: f64,
    pub damping: f64,
    /// Backward Euler's ½ m |Δv|² + B (ignored when the balance takes the remainder).
    pub integrator: f64,
    pub drive: f64,
    pub contact: f64,
}

impl Balance {
    /// Add one rod's step.
    pub fn add(&mut self, s: &StepTerms, remainder: bool) {
        self.kinetic_j += s.kinetic_after - s.kinetic_before;
        self.elastic_j += s.elastic_after - s.elastic_before;
        self.gravity_j += s.gravity;
        self.damping_j += s.damping;
        self.drive_j += s.drive;
        self.contact_j += s.contact;
        self.integrator_j += if remainder {
            s.drive + s.contact
                - (s.kinetic_after - s.kinetic_before)
                - (s.elastic_after - s.elastic_before)
                - s.gravity
                - s.damping
        } else {
            s.integrator
        };
        self.integrator_is_remainder |= remainder;
    }
}
