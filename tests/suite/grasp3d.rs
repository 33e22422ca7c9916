//! A 3D lift gets the planar grasp verdict: held, slipped or dropped, with the friction
//! margin at the lift, in the printed summary and the JSON summary's `grasp`.

use serde_json::Value;

fn run(sets: &[&str]) -> (Value, String) {
    let d = tempfile::tempdir().unwrap();
    let json = d.path().join("s.json");
    let mut cmd = std::process::Command::new(env!("CARGO_BIN_EXE_gripsim"));
    cmd.current_dir(env!("CARGO_MANIFEST_DIR"))
        .args(["run", "scenarios/3d-lift.toml", "--no-record", "--summary"])
        .arg(&json);
    for s in sets {
        cmd.args(["--set", s]);
    }
    let out = cmd.output().unwrap();
    let text = String::from_utf8_lossy(&out.stdout).into_owned();
    assert!(
        out.status.success(),
        "{text}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    (v, text)
}

#[test]
fn a_3d_lift_says_held_or_slipped_with_its_margin() {
    let (v, text) = run(&[]);
    println!("{text}");
    let g = &v["grasp"];
    assert_eq!(g["verdict"], "held", "{g}");
    assert_eq!(g["held"], true);
    let tol = g["hold_tolerance_m"].as_f64().unwrap();
    assert!((tol - 0.005).abs() < 1e-12, "0.1 x the 5 cm radius: {tol}");
    let m = g["safety_margin_at_lift"].as_f64().unwrap();
    assert!(m > 1.0, "held with margin {m}");
    assert!(g["max_slip_m"].as_f64().unwrap() < tol);
    assert!(
        text.contains("fruit           \"fruit\" (0.0524 kg): HELD"),
        "{text}"
    );
    assert!(!text.contains("Some("), "no debug formatting: {text}");
    // The fruit rose with the hand: 3 cm.
    let end = v["grasp"]["final_position_m"][2].as_f64().unwrap();
    assert!((end + 0.06 - 0.03).abs() < 1e-3, "{end}");

    // A fifth of the friction: the margin at the lift falls below 1 and the fingers slide up
    // the fruit, which stays on the table.
    let (v, text) = run(&["friction.mu_s=0.2", "friction.mu_k=0.15"]);
    println!("{text}");
    let g = &v["grasp"];
    assert_eq!(g["verdict"], "slipped", "{g}");
    assert_eq!(g["held"], false);
    let m = g["safety_margin_at_lift"].as_f64().unwrap();
    assert!(m < 1.0, "{m}");
    assert!(g["max_slip_m"].as_f64().unwrap() > 0.025);
    let end = v["grasp"]["final_position_m"][2].as_f64().unwrap();
    assert!((end + 0.06).abs() < 1e-3, "on the table: {end}");
    assert!(text.contains("SLIPPED beyond 5.000e-3 m"), "{text}");
}

/// The planar solve limits hold in 3D: each refused, located, exit 2.
#[test]
fn a_3d_scenario_gets_the_planar_solve_limits() {
    let bin = env!("CARGO_BIN_EXE_gripsim");
    for (set, words) in [
        (
            "solve.dt=1e-12",
            vec!["solve.dt", "is too small", "2.000e10 steps"],
        ),
        ("solve.t_end=1e300", vec!["solve.dt", "is too small"]),
        (
            "solve.gravity=[0,0,-1e308]",
            vec!["solve.gravity", "1.000e308 m/s²", "at most 1e6"],
        ),
        ("solve.dt=1.0", vec!["solve.dt", "larger than t_end"]),
        (
            "solve.max_newton_iterations=4294967296",
            vec!["max_newton_iterations", "at most 100000"],
        ),
        (
            "solve.max_newton_iterations=0",
            vec!["max_newton_iterations", "at least 1"],
        ),
    ] {
        let out = std::process::Command::new(bin)
            .current_dir(env!("CARGO_MANIFEST_DIR"))
            .args([
                "validate",
                "scenarios/3d-lift.toml",
                "--set",
                "solve.t_end=0.02",
                "--set",
                set,
            ])
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{set}: {err}");
        assert!(err.contains("scenarios/3d-lift.toml"), "{err}");
        for w in words {
            assert!(err.contains(w), "{set}: {w:?} in {err}");
        }
    }
}
