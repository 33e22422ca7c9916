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
    let end = v["fruit_end"][2].as_f64().unwrap();
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
    let end = v["fruit_end"][2].as_f64().unwrap();
    assert!((end + 0.06).abs() < 1e-3, "on the table: {end}");
    assert!(text.contains("SLIPPED beyond 5.000e-3 m"), "{text}");
}
