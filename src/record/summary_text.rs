//! The printed summary of a run (`gripsim run` without `-q`), for both dimensions: one line
//! per figure, vectors as `(x, y[, z])` with six decimals, every lift ending in HELD, SLIPPED
//! or DROPPED.

use super::grasp::{GraspSummary, Verdict};
use super::summary::{PressureSummary, Summary};
use std::fmt::Write as _;

/// `(x, y[, z])` with six decimals; a coordinate below the printed precision prints as 0
/// (not `-0.000000`).
pub fn vector(v: &[f64]) -> String {
    let parts: Vec<String> = v
        .iter()
        .map(|x| format!("{:.6}", if x.abs() < 5e-7 { 0.0 } else { *x }))
        .collect();
    format!("({})", parts.join(", "))
}

impl Summary {
    /// The printed summary, one line per figure, ending in a newline.
    pub fn to_text(&self) -> String {
        let mut o = String::new();
        self.head(&mut o);
        if let Some(g) = &self.grasp {
            grasp(&mut o, g, self.dimension);
        }
        if self.dimension == 3 {
            let forces: Vec<String> = self
                .rods
                .iter()
                .map(|r| format!("{:.4}", r.final_contact_force_n))
                .collect();
            let _ = writeln!(
                o,
                "finger forces   {} N (contact normal forces at the end)",
                forces.join(", ")
            );
        }
        if let Some(p) = &self.contact_pressure {
            pressure(&mut o, p);
        }
        let _ = if self.contact_onset_time_s.is_none() && self.max_penetration_m == 0.0 {
            writeln!(o, "penetration     none (no contact)")
        } else {
            writeln!(
                o,
                "penetration     {:.3e} m max after the corrector",
                self.max_penetration_m
            )
        };
        if let Some(n) = &self.max_bending_stress_node {
            let _ = writeln!(
                o,
                "bending stress  {:.4e} Pa max at rod {:?} node {}",
                self.max_bending_stress_pa, n.rod, n.node
            );
        }
        if let Some(t) = self.max_twist_rad {
            let _ = writeln!(o, "twist           {t:.3e} rad max");
        }
        for r in &self.rods {
            let tip = r.final_positions.last().map_or(&[][..], |p| p);
            let busiest = r
                .contact_steps_per_node
                .iter()
                .enumerate()
                .max_by_key(|(i, c)| (**c, std::cmp::Reverse(*i)))
                .filter(|(_, c)| **c > 0);
            let _ = write!(
                o,
                "rod {:<11} tip at {} m",
                format!("{:?}", r.name),
                vector(tip)
            );
            if let Some((i, c)) = busiest {
                let _ = write!(o, ", most contact steps: node {i} ({c})");
            }
            o.push('\n');
        }
        o
    }

    /// Scenario, steps, times, the peak reaction and the first contact.
    fn head(&self, o: &mut String) {
        let dim = if self.dimension == 3 { " (3D)" } else { "" };
        let _ = writeln!(o, "scenario        {}{dim}", self.scenario);
        let _ = writeln!(
            o,
            "steps           {} ({} Newton iterations, {} corrector passes, {} dt back-offs)",
            self.steps, self.newton_iterations, self.contact_passes, self.dt_backoffs
        );
        let load = if self.mode == "static" {
            " (load factor)"
        } else {
            ""
        };
        let _ = writeln!(o, "simulated       {:.6} s{load}", self.simulated_time_s);
        let _ = writeln!(o, "wall time       {:.3} s", self.wall_time_s);
        let at = self.peak_reaction_time_s.unwrap_or(0.0);
        let _ = match &self.peak_reaction_node {
            Some(n) if self.mode == "static" => writeln!(
                o,
                "peak reaction   {:.4} N at rod {:?} node {} (load factor {at:.6}; the equilibrium contact force)",
                self.peak_reaction_force_n, n.rod, n.node
            ),
            Some(n) => writeln!(
                o,
                "peak reaction   {:.4} N at rod {:?} node {} (t = {at:.6} s; eq. 2, the seed's figure)",
                self.peak_reaction_force_n, n.rod, n.node
            ),
            None => writeln!(o, "peak reaction   none (no contact)"),
        };
        if let Some(t) = self.contact_onset_time_s {
            let _ = writeln!(o, "first contact   t = {t:.6} s");
        }
    }
}

/// The fruit's verdict, grip force, safety margin and slip.
fn grasp(o: &mut String, g: &GraspSummary, dimension: u8) {
    let verdict = match g.verdict {
        Verdict::Slipped => format!("SLIPPED beyond {:.3e} m", g.hold_tolerance_m),
        v => v.word().to_string(),
    };
    let _ = writeln!(
        o,
        "fruit           {:?} ({:.4} kg): {verdict}",
        g.fruit, g.fruit_mass_kg
    );
    let _ = writeln!(
        o,
        "grip force      {:.4} N peak per prong, {:.4} N peak total",
        g.peak_grip_force_n, g.peak_total_grip_force_n
    );
    let opt = |x: Option<f64>| x.map_or("-".to_string(), |m| format!("{m:.4}"));
    let _ = writeln!(
        o,
        "safety margin   {} at lift, {} min during the lift (mu_s * sum N / m g)",
        opt(g.safety_margin_at_lift),
        opt(g.min_safety_margin)
    );
    if dimension == 3 {
        // The 3D run does not report stick ↔ slip switches yet: no first slip.
        let _ = writeln!(
            o,
            "slip            {:.3e} m max relative to the gripper during the lift",
            g.max_slip_m
        );
        let _ = writeln!(
            o,
            "fruit moved     from {} to {} m",
            vector(&g.initial_position_m),
            vector(&g.final_position_m)
        );
    } else {
        let _ = writeln!(
            o,
            "slip            {:.3e} m max relative to the gripper, first slip {}",
            g.max_slip_m,
            g.first_slip_time_s
                .map_or("never".to_string(), |t| format!("at t = {t:.6} s"))
        );
    }
}

/// A compliant fruit's contact: force of the contact law, Hertz pressure, bruise verdict.
fn pressure(o: &mut String, p: &PressureSummary) {
    let _ = writeln!(
        o,
        "fruit contact   peak force {:.4} N (the contact law's), peak pressure {:.4e} Pa at rod {:?} node {} (t = {:.6} s, half-width {:.3e} m), deepest indentation {:.3e} m",
        p.peak_contact_force_n,
        p.max_pressure_pa,
        p.max_pressure_node.rod,
        p.max_pressure_node.node,
        p.max_pressure_time_s,
        p.half_width_at_max_m,
        p.max_indentation_m
    );
    let above = if p.bruised {
        format!(
            ", up to {:.3e} m of the contact above it",
            p.max_bruise_width_m
        )
    } else {
        String::new()
    };
    let _ = writeln!(
        o,
        "bruise          {}: peak pressure {:.3} x the bruise pressure {:.4e} Pa{above}",
        if p.bruised { "BRUISED" } else { "not bruised" },
        p.bruise_ratio,
        p.bruise_pressure_pa,
    );
}

#[cfg(test)]
mod tests {
    use super::vector;

    #[test]
    fn vectors_print_with_six_decimals_and_no_negative_zero() {
        assert_eq!(vector(&[0.0085, -0.08]), "(0.008500, -0.080000)");
        assert_eq!(
            vector(&[1.0, -2e-7, 3.25]),
            "(1.000000, 0.000000, 3.250000)"
        );
    }
}
