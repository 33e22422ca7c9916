//! Unit tests of the actuation model: laws, phases, the state machine.

use super::phase::{DURATION, GRIP_FORCE, GRIP_TORQUE, PROFILE_COMPLETE, TRAVEL, WIDTH};
use super::*;

fn trapezoid_speed() -> Law {
    Law::Trapezoid(Trapezoid::from_speed(0.05, 0.2, 2.0))
}
fn trapezoid_triangle() -> Law {
    Law::Trapezoid(Trapezoid::from_speed(0.01, 0.2, 2.0))
}
fn trapezoid_duration() -> Law {
    Law::Trapezoid(Trapezoid::from_duration(0.05, 0.6))
}
fn s_curve() -> Law {
    Law::SCurve {
        distance: 0.05,
        duration: 0.5,
    }
}
fn table() -> Law {
    Law::Table(Table::new(&[[0.0, 0.0], [0.1, 0.01], [0.25, 0.01], [0.4, -0.02]]).unwrap())
}

fn all_laws() -> Vec<Law> {
    vec![
        Law::ConstantVelocity { speed: 0.3 },
        Law::ConstantAcceleration { acceleration: 9.8 },
        trapezoid_speed(),
        trapezoid_triangle(),
        trapezoid_duration(),
        s_curve(),
        table(),
    ]
}

fn translate(law: Law, end: Ends) -> Phase {
    Phase::new(
        None,
        Movement::Translate {
            direction: [0.6, 0.8],
            law,
        },
        end,
    )
}

fn program(phases: Vec<Phase>, mirror_x: Option<f64>) -> Program {
    Program {
        phases,
        mirror_x,
        force_filter: 0.0,
    }
}

fn norm(a: [f64; 2]) -> f64 {
    (a[0] * a[0] + a[1] * a[1]).sqrt()
}

// ---------------------------------------------------------------------------------------------
// Laws

/// ṡ equals the central difference of s away from the breakpoints (within 1e-6 relative to the
/// law's largest speed), at 400 times over the profile.
#[test]
fn every_law_velocity_matches_finite_differences_of_position() {
    for law in all_laws() {
        let t_end = law.profile_end().unwrap_or(1.0);
        let h = 1e-7 * t_end;
        let vmax = (0..=1000)
            .map(|i| law.eval(t_end * i as f64 / 1000.0).1.abs())
            .fold(0.0, f64::max);
        assert!(vmax > 0.0, "{law:?}");
        let mut checked = 0;
        for i in 1..400 {
            let tau = t_end * (i as f64 + 0.37) / 400.0;
            let (sp, sm) = (law.eval(tau + h).0, law.eval(tau - h).0);
            let fd = (sp - sm) / (2.0 * h);
            // Skip the few samples that straddle a kink of a table or a trapezoid's corner in
            // acceleration (the velocity itself is continuous there except for the table).
            let (v, vp, vm) = (law.eval(tau).1, law.eval(tau + h).1, law.eval(tau - h).1);
            if (vp - vm).abs() > 1e-3 * vmax {
                continue;
            }
            assert!(
                (fd - v).abs() <= 1e-6 * vmax,
                "{}: tau = {tau}: fd {fd} vs v {v}",
                law.name()
            );
            checked += 1;
        }
        assert!(checked >= 390, "{}: only {checked} samples", law.name());
    }
}

#[test]
fn profiles_reach_exactly_their_distance_at_rest() {
    for (law, d) in [
        (trapezoid_speed(), 0.05),
        (trapezoid_triangle(), 0.01),
        (trapezoid_duration(), 0.05),
        (s_curve(), 0.05),
        (table(), -0.02),
    ] {
        let t = law.profile_end().unwrap();
        assert_eq!(law.eval(t), (d, 0.0), "{}", law.name());
        assert_eq!(law.eval(t + 1.0), (d, 0.0), "{}", law.name());
        // Continuous into the end: within 1e-9 of the distance just before it.
        let before = law.eval(t * (1.0 - 1e-9)).0;
        assert!((before - d).abs() < 1e-9, "{}: {before}", law.name());
    }
}

#[test]
fn trapezoid_numbers() {
    // D = 0.05, V = 0.2, A = 2: t_a = 0.1, cruise (0.05 - 0.02)/0.2 = 0.15, T = 0.35.
    let Law::Trapezoid(tr) = trapezoid_speed() else {
        unreachable!()
    };
    assert!((tr.duration - 0.35).abs() < 1e-15);
    assert_eq!(tr.peak_speed, 0.2);
    let law = trapezoid_speed();
    let (s, v) = law.eval(0.05);
    assert!((s - 0.0025).abs() < 1e-17 && (v - 0.1).abs() < 1e-16);
    let (s, v) = law.eval(0.2);
    assert!((s - 0.03).abs() < 1e-16 && v == 0.2, "{s} {v}");
    let (s, v) = law.eval(0.3);
    assert!(
        (s - 0.0475).abs() < 1e-16 && (v - 0.1).abs() < 1e-15,
        "{s} {v}"
    );
    // Triangle: D = 0.01 < V²/A = 0.02: peak √(D A) = √0.02, T = 2 √(D/A).
    let Law::Trapezoid(tri) = trapezoid_triangle() else {
        unreachable!()
    };
    assert!((tri.peak_speed - 0.02f64.sqrt()).abs() < 1e-16);
    assert!((tri.duration - 2.0 * 0.005f64.sqrt()).abs() < 1e-15);
    // Duration form: thirds, V = 1.5 D/T = 0.125, A = 4.5 D/T² = 0.625.
    let Law::Trapezoid(td) = trapezoid_duration() else {
        unreachable!()
    };
    assert!((td.peak_speed - 0.125).abs() < 1e-16);
    assert!((td.acceleration - 0.625).abs() < 1e-15);
}

#[test]
fn s_curve_is_minimum_jerk() {
    let law = s_curve();
    // u = 0.5: s = D/2, v = 1.875 D/T.
    let (s, v) = law.eval(0.25);
    assert!((s - 0.025).abs() < 1e-17, "{s}");
    assert!((v - 1.875 * 0.05 / 0.5).abs() < 1e-16, "{v}");
    // Zero velocity at both ends, and the acceleration starts from zero: near τ = 0,
    // a(τ) = D/T² (60u − …), so v(τ)/τ = 30 D τ/T³ to first order.
    assert_eq!(law.eval(0.0), (0.0, 0.0));
    for tau in [1e-6, 1e-5] {
        let ratio = (law.eval(tau).1 / tau) / (30.0 * 0.05 * tau / 0.125);
        assert!((ratio - 1.0).abs() < 1e-3, "{tau}: {ratio}");
        // And symmetrically it arrives with zero acceleration.
        let end = law.eval(0.5 - tau).1 / tau;
        assert!(
            (end / (30.0 * 0.05 * tau / 0.125) - 1.0).abs() < 1e-3,
            "{end}"
        );
    }
}

#[test]
fn table_is_piecewise_linear_with_its_slope() {
    let law = table();
    let (s, v) = law.eval(0.05);
    assert!((s - 0.005).abs() < 1e-17 && (v - 0.1).abs() < 1e-15);
    assert_eq!(law.eval(0.1), (0.01, 0.0));
    let (s, v) = law.eval(0.3);
    assert!(
        (s - 0.0).abs() < 1e-17 && (v + 0.2).abs() < 1e-15,
        "{s} {v}"
    );
}

#[test]
fn table_validation() {
    let bad = |pts: &[[f64; 2]]| Table::new(pts).unwrap_err();
    assert_eq!(bad(&[[0.0, 1.0]]).index, 0);
    let e = bad(&[[0.1, 0.0], [0.2, 1.0]]);
    assert_eq!(e.index, 0);
    assert!(e.message.contains("first time must be 0"), "{}", e.message);
    let e = bad(&[[0.0, 0.0], [0.2, 1.0], [0.2, 2.0]]);
    assert_eq!(e.index, 2);
    assert!(e.message.contains("increase strictly"), "{}", e.message);
    assert_eq!(bad(&[[0.0, 0.0], [0.2, f64::NAN]]).index, 1);
    let e = bad(&[[0.0, 0.01], [0.2, 1.0]]);
    assert!(
        e.index == 0 && e.message.contains("first value must be 0"),
        "{}",
        e.message
    );
}

#[test]
fn time_to_travel_inverts_every_law() {
    for law in all_laws() {
        for l in [0.001, 0.004, 0.0099, 0.015, 0.03, 0.045] {
            let Some(tau) = law.time_to_travel(l) else {
                // Only when the profile never gets that far.
                let t = law.profile_end().unwrap();
                let max = (0..=4000)
                    .map(|i| law.eval(t * i as f64 / 4000.0).0.abs())
                    .fold(0.0, f64::max);
                assert!(
                    max <= l * (1.0 + 1e-12),
                    "{}: l = {l}, max {max}",
                    law.name()
                );
                continue;
            };
            let s = law.eval(tau).0.abs();
            assert!((s - l).abs() <= 1e-14, "{}: l = {l}: s = {s}", law.name());
            // And not earlier.
            assert!(law.eval(tau * (1.0 - 1e-6)).0.abs() < l, "{}", law.name());
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Phases and analytic ends

#[test]
fn travel_end_lands_exactly_and_the_next_phase_starts_there() {
    let travel = 0.07;
    let ph = translate(
        Law::ConstantVelocity { speed: 0.3 },
        Ends {
            travel: Some(travel),
            ..Ends::default()
        },
    );
    let te = travel / 0.3;
    assert_eq!(ph.analytic_end(), Some((te, TRAVEL)));
    let hold = Phase::new(
        Some("hold".into()),
        Movement::Hold,
        Ends {
            duration: Some(0.1),
            ..Ends::default()
        },
    );
    let mut act = Actuator::new(program(vec![ph, hold], None), [0.0; 2]);
    let at_end = Pose {
        theta: 0.0,
        d: [0.6 * travel, 0.8 * travel],
    };
    // Exactly the travel along the direction, from te on, at rest.
    assert_eq!(act.motion(te), Motion::at_rest(at_end));
    assert_eq!(act.motion(te + 0.05), Motion::at_rest(at_end));
    // Just before: moving at the law's velocity.
    let m = act.motion(te * 0.999);
    assert_eq!(m.v, [0.6 * 0.3, 0.8 * 0.3]);
    // A step that ends past both ends reports both, at their exact times.
    let sw = act.commit(te + 0.1 + 0.01, &Measure::default()).unwrap();
    assert_eq!(
        sw,
        vec![
            PhaseSwitch {
                t: te,
                from: 0,
                to: Some(1),
                reason: TRAVEL
            },
            PhaseSwitch {
                t: te + 0.1,
                from: 1,
                to: None,
                reason: DURATION
            },
        ]
    );
    assert_eq!(act.current_phase(), None);
    assert_eq!(act.motion(5.0), Motion::at_rest(at_end));
}

#[test]
fn duration_end_is_exact_and_motion_is_pure() {
    let ph = |d| {
        translate(
            Law::ConstantAcceleration { acceleration: 2.0 },
            Ends {
                duration: Some(d),
                ..Ends::default()
            },
        )
    };
    let p = program(vec![ph(0.25), ph(0.5)], None);
    let mut act = Actuator::new(p, [0.0; 2]);
    // End of phase 0: s = ½ 2 0.25² = 0.0625 along (0.6, 0.8).
    let s0 = 0.5 * 2.0 * 0.25 * 0.25;
    let p0 = [0.6 * s0, 0.8 * s0];
    assert_eq!(act.motion(0.25).pose.d, p0);
    // In phase 1 at t = 0.25 + 0.1: from p0, s = ½ 2 0.1² more.
    let before = act.motion(0.35);
    let tau = 0.35 - 0.25;
    let s1 = 0.5 * 2.0 * tau * tau;
    assert_eq!(before.pose.d, [p0[0] + 0.6 * s1, p0[1] + 0.8 * s1]);
    assert_eq!(before.v, [0.6 * 2.0 * tau, 0.8 * 2.0 * tau]);
    // Trial calls change nothing; a commit inside phase 0 changes nothing either.
    assert_eq!(act.commit(0.2, &Measure::default()).unwrap(), vec![]);
    assert_eq!(act.motion(0.35), before);
    let sw = act.commit(0.3, &Measure::default()).unwrap();
    assert_eq!(sw.len(), 1);
    assert_eq!((sw[0].t, sw[0].reason), (0.25, DURATION));
    assert_eq!(act.motion(0.35), before);
    assert_eq!(act.next_end_after(0.35), Some(0.75));
}

#[test]
fn profile_completion_ends_a_phase() {
    let ph = translate(s_curve(), Ends::default());
    assert_eq!(ph.analytic_end(), Some((0.5, PROFILE_COMPLETE)));
    let mut act = Actuator::new(program(vec![ph], None), [0.0; 2]);
    let sw = act.commit(0.6, &Measure::default()).unwrap();
    assert_eq!(sw[0].reason, PROFILE_COMPLETE);
    assert_eq!(sw[0].t, 0.5);
    assert_eq!(act.motion(0.6).pose.d, [0.6 * 0.05, 0.8 * 0.05]);
}

#[test]
fn profile_travel_end_lands_exactly_on_the_travel() {
    for law in [trapezoid_speed(), s_curve(), table()] {
        let ph = translate(
            law.clone(),
            Ends {
                travel: Some(0.004),
                ..Ends::default()
            },
        );
        let (te, reason) = ph.analytic_end().unwrap();
        assert_eq!(reason, TRAVEL, "{}", law.name());
        let m = ph.motion(&Pose::IDENTITY, te);
        assert_eq!(m.pose.d, [0.6 * 0.004, 0.8 * 0.004], "{}", law.name());
        assert_eq!(m.v, [0.0; 2]);
    }
}

// ---------------------------------------------------------------------------------------------
// Rotation

fn rotate_program() -> Program {
    // Move 0.02 m along (0.6, 0.8), then turn counter-clockwise by 0.6 rad about the
    // gripper-frame point (0.0, 0.05) with an s-curve.
    let shift = translate(
        Law::ConstantVelocity { speed: 0.1 },
        Ends {
            duration: Some(0.2),
            ..Ends::default()
        },
    );
    let turn = Phase::new(
        Some("turn".into()),
        Movement::Rotate {
            pivot: [0.0, 0.05],
            sense: 1.0,
            law: Law::SCurve {
                distance: 0.6,
                duration: 0.4,
            },
        },
        Ends::default(),
    );
    program(vec![shift, turn], None)
}

#[test]
fn rotation_keeps_points_on_their_arc_about_the_moving_pivot() {
    let act = Actuator::new(rotate_program(), [0.0; 2]);
    // The pivot moved with the gripper: (0, 0.05) + s (0.6, 0.8), s = 0.1 · 0.2.
    let c = act.pivot_world(0.3).unwrap();
    let s = 0.1 * 0.2;
    assert_eq!(c, [0.6 * s, 0.05 + 0.8 * s]);
    assert_eq!(act.pivot_world(0.1), None);
    let law = s_curve_angle();
    let points = [[0.0, 0.0], [0.01, 0.0], [-0.03, 0.12], [0.08, -0.05]];
    for x0 in points {
        let start = act.motion(0.2).position_of(x0, None);
        let r0 = [start[0] - c[0], start[1] - c[1]];
        for i in 0..=50 {
            let t = 0.2 + 0.45 * i as f64 / 50.0;
            let x = act.motion(t).position_of(x0, None);
            let r = [x[0] - c[0], x[1] - c[1]];
            let rel = (norm(r) - norm(r0)).abs() / norm(r0);
            assert!(rel <= 1e-15, "x0 {x0:?} t {t}: relative {rel:e}");
            // Turned by the law's angle.
            let phi = law.eval(t - 0.2).0;
            let turned = (r0[0] * r[1] - r0[1] * r[0]).atan2(r0[0] * r[0] + r0[1] * r[1]);
            assert!((turned - phi).abs() < 1e-14, "t {t}: {turned} vs {phi}");
        }
    }
}

fn s_curve_angle() -> Law {
    Law::SCurve {
        distance: 0.6,
        duration: 0.4,
    }
}

#[test]
fn rotation_velocity_matches_finite_differences() {
    let act = Actuator::new(rotate_program(), [0.0; 2]);
    let h = 1e-7;
    for x0 in [[0.01, 0.0], [-0.03, 0.12]] {
        for mirror in [None, Some(-0.05)] {
            for t in [0.05, 0.27, 0.4, 0.55] {
                let v = act.motion(t).velocity_of(x0, mirror);
                let xp = act.motion(t + h).position_of(x0, mirror);
                let xm = act.motion(t - h).position_of(x0, mirror);
                for a in 0..2 {
                    let fd = (xp[a] - xm[a]) / (2.0 * h);
                    assert!(
                        (fd - v[a]).abs() < 1e-7,
                        "t {t} {mirror:?}: {fd} vs {}",
                        v[a]
                    );
                }
            }
        }
    }
}

#[test]
fn clockwise_rotation_and_grip_torque() {
    let ph = Phase::new(
        None,
        Movement::Rotate {
            pivot: [0.0, 0.0],
            sense: -1.0,
            law: Law::ConstantVelocity { speed: 1.0 },
        },
        Ends {
            grip_torque: Some(0.5),
            travel: Some(1.0),
            ..Ends::default()
        },
    );
    let mut act = Actuator::new(program(vec![ph], None), [0.0; 2]);
    let m = act.motion(0.25);
    assert_eq!(m.pose.theta, -0.25);
    assert_eq!(m.omega, -1.0);
    let x = m.position_of([1.0, 0.0], None);
    assert!((x[0] - 0.25f64.cos()).abs() < 1e-16 && (x[1] + 0.25f64.sin()).abs() < 1e-16);
    // Clockwise: a torque of -0.4 (clockwise) is 0.4 in the rotation's sense: not yet.
    let tq = |t| Measure {
        drive_force: [0.0; 2],
        drive_torque: t,
    };
    assert!(act.commit(0.1, &tq(-0.4)).unwrap().is_empty());
    assert!(act.commit(0.2, &tq(0.6)).unwrap().is_empty());
    let sw = act.commit(0.3, &tq(-0.5)).unwrap();
    assert_eq!((sw[0].t, sw[0].reason), (0.3, GRIP_TORQUE));
    assert_eq!(act.motion(0.5).pose.theta, -0.3);
}

// ---------------------------------------------------------------------------------------------
// Mirror

#[test]
fn mirrored_members_are_exact_mirror_images() {
    // Dyadic numbers: 2c − x is exact, so M(M(x₀)) = x₀ and the velocities are exact
    // mirror images to the bit; positions to the last bit of the coordinates.
    let c = -0.0625;
    let mut p = rotate_program();
    p.mirror_x = Some(c);
    let act = Actuator::new(p, [0.0; 2]);
    for x0 in [[0.25, 0.5], [0.125, -0.375], [-0.5, 0.0]] {
        let xm0 = mirror_point(x0, c);
        for i in 0..=60 {
            let t = 0.7 * i as f64 / 60.0;
            let m = act.motion(t);
            let x = m.position_of(x0, None);
            let xm = m.position_of(xm0, Some(c));
            // Equal up to the rounding of (2c − x₀) − d against 2c − (x₀ + d).
            let want = mirror_point(x, c);
            for a in 0..2 {
                assert!(
                    (xm[a] - want[a]).abs() <= 2.0 * f64::EPSILON,
                    "t {t}: {xm:?} {want:?}"
                );
            }
            let v = m.velocity_of(x0, None);
            assert_eq!(m.velocity_of(xm0, Some(c)), [-v[0], v[1]], "t {t}");
        }
    }
}

#[test]
fn mirrored_translation_matches_the_seed_two_prong_drives_bit_for_bit() {
    // Right prong driven by a = (-9.8, 0); its mirror by a = (+9.8, 0) in the seed.
    let p = Program {
        mirror_x: Some(-0.05),
        ..Program::translation(VectorLaw::Acceleration([-9.8, 0.0]), None, None)
    };
    let left = Program::translation(VectorLaw::Acceleration([9.8, 0.0]), None, None);
    let (act, left) = (Actuator::new(p, [0.0; 2]), Actuator::new(left, [0.0; 2]));
    let x0 = [-0.109, -0.02];
    for i in 0..200 {
        let t = 1e-4 * i as f64 + 3e-7;
        assert_eq!(
            act.motion(t).position_of(x0, Some(-0.05)),
            left.motion(t).position_of(x0, None)
        );
        assert_eq!(
            act.motion(t).velocity_of(x0, Some(-0.05)),
            left.motion(t).velocity_of(x0, None)
        );
    }
}

#[test]
fn mirrored_images_in_general_within_round_off() {
    let c = -0.05;
    let mut p = rotate_program();
    p.mirror_x = Some(c);
    let act = Actuator::new(p, [0.0; 2]);
    let x0 = [0.009, -0.03];
    let xm0 = mirror_point(x0, c);
    for i in 0..=60 {
        let t = 0.7 * i as f64 / 60.0;
        let m = act.motion(t);
        let want = mirror_point(m.position_of(x0, None), c);
        let got = m.position_of(xm0, Some(c));
        for a in 0..2 {
            assert!((got[a] - want[a]).abs() <= 1e-16, "t {t}: {got:?} {want:?}");
        }
    }
}

#[test]
fn measure_add_maps_mirrored_members_and_takes_torque() {
    let mut m = Measure::default();
    let c = -0.05;
    // Right prong node at (0.01, 0) pushed by -x; its mirror image pushed by +x.
    m.add([0.01, 0.0], [-2.0, 0.5], None, Some([0.0, 1.0]));
    m.add(
        mirror_point([0.01, 0.0], c),
        [2.0, 0.5],
        Some(c),
        Some([0.0, 1.0]),
    );
    assert_eq!(m.drive_force, [-4.0, 1.0]);
    // Each: (0.01, -1) × (-2, 0.5) = 0.01·0.5 − (−1)(−2) = −1.995.
    assert!(
        (m.drive_torque + 2.0 * 1.995).abs() < 1e-15,
        "{}",
        m.drive_torque
    );
    let cen = clamp_centroid(
        [
            ([0.01, 0.0], false),
            ([-0.11, 0.02], true),
            ([0.01, 0.02], false),
        ],
        Some(c),
    );
    assert!((cen[0] - 0.01).abs() < 1e-17 && (cen[1] - 0.04 / 3.0).abs() < 1e-17);
}

// ---------------------------------------------------------------------------------------------
// Measured ends

fn force_along(f: f64) -> Measure {
    // Direction (0.6, 0.8): this force has f along it plus a perpendicular part.
    Measure {
        drive_force: [0.6 * f - 0.8 * 3.0, 0.8 * f + 0.6 * 3.0],
        drive_torque: 0.0,
    }
}

fn squeeze_program() -> Program {
    let close = Phase::new(
        Some("squeeze".into()),
        Movement::Translate {
            direction: [0.6, 0.8],
            law: Law::ConstantVelocity { speed: 0.1 },
        },
        Ends {
            grip_force: Some(5.0),
            travel: Some(0.02),
            ..Ends::default()
        },
    );
    let hold = Phase::new(
        Some("hold".into()),
        Movement::Hold,
        Ends {
            duration: Some(0.05),
            ..Ends::default()
        },
    );
    program(vec![close, hold], None)
}

#[test]
fn grip_force_end_switches_at_the_first_commit_that_reaches_it() {
    let mut act = Actuator::new(squeeze_program(), [0.0; 2]);
    for (t, f) in [(0.01, 0.0), (0.05, 3.0), (0.1, 4.999)] {
        assert!(act.commit(t, &force_along(f)).unwrap().is_empty(), "t {t}");
    }
    let pose = act.motion(0.12).pose;
    let sw = act.commit(0.12, &force_along(5.001)).unwrap();
    assert_eq!(
        sw,
        vec![PhaseSwitch {
            t: 0.12,
            from: 0,
            to: Some(1),
            reason: GRIP_FORCE
        }]
    );
    // The hold starts from the pose at 0.12 and keeps it until 0.17.
    assert_eq!(act.motion(0.15), Motion::at_rest(pose));
    assert_eq!(act.next_end_after(0.15), Some(0.12 + 0.05));
    // The same measure does not end the hold early; its duration does.
    assert!(act.commit(0.13, &force_along(50.0)).unwrap().is_empty());
    let sw = act.commit(0.2, &force_along(50.0)).unwrap();
    assert_eq!(
        (sw[0].t, sw[0].to, sw[0].reason),
        (0.12 + 0.05, None, DURATION)
    );
}

#[test]
fn grip_force_met_on_the_step_that_lands_on_the_limit_counts() {
    let mut act = Actuator::new(squeeze_program(), [0.0; 2]);
    let te = 0.02 / 0.1;
    let sw = act.commit(te, &force_along(6.0)).unwrap();
    assert_eq!((sw[0].t, sw[0].reason), (te, GRIP_FORCE));
}

#[test]
fn unreachable_grip_force_names_the_phase_target_and_peak() {
    let mut act = Actuator::new(squeeze_program(), [0.0; 2]);
    for (t, f) in [(0.05, 1.0), (0.1, 3.2), (0.15, 2.0)] {
        act.commit(t, &force_along(f)).unwrap();
    }
    // The travel limit 0.02 m is reached at 0.2 s, inside this step; the measure at 0.21 s
    // belongs to the hold, not to the squeeze.
    let err = act.commit(0.21, &force_along(9.0)).unwrap_err();
    assert_eq!(err.phase, 0);
    assert_eq!(err.name.as_deref(), Some("squeeze"));
    assert_eq!((err.quantity, err.target), (GRIP_FORCE, 5.0));
    assert!((err.peak.unwrap() - 3.2).abs() < 1e-15);
    assert_eq!((err.limit, err.limit_value), (TRAVEL, 0.02));
    assert_eq!(err.t, 0.02 / 0.1);
    let msg = err.to_string();
    assert!(
        msg.starts_with("phase 0 'squeeze' reached its travel limit 0.02 m at t = 0.2")
            && msg.contains("before grip_force = 5 N (peak 3.2"),
        "{msg}"
    );
}

#[test]
fn width_end() {
    // Clamp centroid at x = 0.01, mirror line -0.05: width 0.12 at the start; closing at
    // 0.1 m/s along -x, the width is 0.12 - 0.2 t; width <= 0.1 from t = 0.1.
    let close = Phase::new(
        Some("close".into()),
        Movement::Translate {
            direction: [-1.0, 0.0],
            law: Law::ConstantVelocity { speed: 0.1 },
        },
        Ends {
            width: Some(0.1),
            ..Ends::default()
        },
    );
    let mut act = Actuator::new(program(vec![close], Some(-0.05)), [0.01, -0.02]);
    assert!((act.width(&Pose::IDENTITY).unwrap() - 0.12).abs() < 1e-16);
    assert!(act.commit(0.09, &Measure::default()).unwrap().is_empty());
    let sw = act.commit(0.11, &Measure::default()).unwrap();
    assert_eq!((sw[0].t, sw[0].reason), (0.11, WIDTH));
    let w = act.width(&act.motion(0.2).pose).unwrap();
    assert!((w - (0.12 - 0.2 * 0.11)).abs() < 1e-15, "{w}");
}

#[test]
fn an_empty_program_holds_still() {
    let act = Actuator::new(Program::fixed(), [0.0; 2]);
    let m = act.motion(1.0);
    assert_eq!(m, Motion::at_rest(Pose::IDENTITY));
    assert_eq!(m.position_of([0.1, -0.2], None), [0.1, -0.2]);
    assert_eq!(act.next_end_after(0.0), None);
}

#[test]
fn unreachable_grip_torque_message_in_rotation_units() {
    let ph = Phase::new(
        Some("pinch".into()),
        Movement::Rotate {
            pivot: [0.0, 0.0],
            sense: 1.0,
            law: Law::ConstantVelocity { speed: 2.0 },
        },
        Ends {
            grip_torque: Some(0.25),
            travel: Some(0.5),
            ..Ends::default()
        },
    );
    let mut act = Actuator::new(program(vec![ph], None), [0.0; 2]);
    let tq = |t| Measure {
        drive_force: [0.0; 2],
        drive_torque: t,
    };
    act.commit(0.1, &tq(0.125)).unwrap();
    let err = act.commit(0.3, &tq(0.0)).unwrap_err();
    assert_eq!(err.t, 0.25);
    assert_eq!(
        err.to_string(),
        "phase 0 'pinch' reached its travel limit 0.5 rad at t = 0.25 s before \
         grip_torque = 0.25 N·m (peak 0.125 N·m)"
    );
    // A phase that no step ended inside says so.
    let ph = translate(
        Law::ConstantVelocity { speed: 1.0 },
        Ends {
            grip_force: Some(1.0),
            duration: Some(0.01),
            ..Ends::default()
        },
    );
    let mut act = Actuator::new(program(vec![ph], None), [0.0; 2]);
    let err = act.commit(0.02, &Measure::default()).unwrap_err();
    assert_eq!(err.peak, None);
    assert!(
        err.to_string()
            .ends_with("(no step ended inside the phase)"),
        "{err}"
    );
}

/// `force_filter`: a grip end sees the reaction through a first-order sensor. An impact's
/// reaction (an impulse J over one step, J/Δt) moves the sensor by about J/τ whatever Δt is,
/// so the end does not fire on it at a fine Δt and then on a sustained squeeze it does, after
/// the sensor's lag: y(t) = F (1 − e^(−t/τ)) to round-off.
#[test]
fn a_filtered_grip_end_ignores_an_impact_and_follows_a_squeeze() {
    let tau = 5e-3;
    for dt in [1e-4, 1e-5, 1e-6] {
        let mut p = squeeze_program();
        p.force_filter = tau;
        let mut act = Actuator::new(p, [0.0; 2]);
        let mut t = 0.0;
        assert!(act.commit(t, &force_along(0.0)).unwrap().is_empty());
        // An impulse of 5e-3 N s in one step: 50 N at dt 1e-4, 5000 N at 1e-6 (raw: ends).
        t += dt;
        let sw = act.commit(t, &force_along(5e-3 / dt)).unwrap();
        assert!(sw.is_empty(), "dt {dt}: the impact ended the squeeze");
        // Then a squeeze of 6 N: the sensor reads 5 N a time τ ln 5 later.
        let mut ended = None;
        while ended.is_none() && t < 0.1 {
            t += dt;
            let sw = act.commit(t, &force_along(6.0)).unwrap();
            ended = sw.first().map(|s| s.t);
        }
        let t_end = ended.expect("the squeeze ends the phase");
        // y after the impulse ≈ J/τ (1 N), then 6 − (6 − 1) e^(−(t − dt)/τ) = 5 at t − dt = τ ln 5.
        let expect = dt + tau * 5f64.ln();
        assert!(
            (t_end - expect).abs() < 2.0 * dt + 0.01 * tau,
            "dt {dt}: ended at {t_end}, expected {expect}"
        );
    }
}
