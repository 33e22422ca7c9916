//! Issue 36: the Fin Ray finger generator (`shape = { kind = "fin_ray", ... }`). The generated
//! finger equals the hand-built one of `joints.rs` (same nodes, same joints, same response),
//! shows the Fin Ray effect, mirrors as a parallel pair, and refuses bad input with exit 2.

use crate::joints::{fin_ray_with, node, run};
use gripsim::events::NullObserver;
use gripsim::scenario::geometry::shape_points;
use gripsim::{Scenario, Simulation};
use std::process::Command;

/// The generated counterpart of `fin_ray_with(ribs, kind, p, false, 0.04, rib_h)`: front
/// flank (0, 0) → (0, 0.1), back flank from (0.04, 0), `6 (ribs + 1) + 1` nodes per flank,
/// ribs of 7 nodes, the load `p` at the front flank's mid node.
fn generated(ribs: usize, kind: &str, p: f64, rib_h: f64) -> String {
    let nf = (ribs + 1) * 6 + 1;
    let mid = (nf - 1) / 2;
    format!(
        "name = \"fin-ray\"\n[solve]\nmode = \"static\"\ngravity = [0.0, 0.0]\nforce_tol = 1e-12\n\n\
         [[rod]]\nname = \"finger\"\nnodes = {nf}\n\
         shape = {{ kind = \"fin_ray\", length = 0.1, base_width = 0.04, ribs = {ribs}, \
         rib_angle = 0.0, rib_joint = \"{kind}\", rib_section = {{ kind = \"rect\", b = 0.02, h = {rib_h:e} }} }}\n\
         E = 1e6\nsection = {{ kind = \"rect\", b = 0.02, h = 0.002 }}\ndensity = 1000.0\n\
         loads = [{{ node = {mid}, force = [{p:e}, 0.0] }}]\n"
    )
}

fn scenario(text: &str) -> Scenario {
    Scenario::from_str(text, "test.toml", &[]).unwrap_or_else(|e| panic!("{e}"))
}

/// Largest node distance between two finished runs, rod by rod.
fn max_difference(a: &Simulation, b: &Simulation) -> f64 {
    assert_eq!(a.rods.len(), b.rods.len());
    let mut worst = 0.0f64;
    for r in 0..a.rods.len() {
        let (qa, qb) = (a.positions(r), b.positions(r));
        assert_eq!(qa.len(), qb.len(), "rod {r}");
        for (x, y) in qa.iter().zip(qb) {
            worst = worst.max((x - y).abs());
        }
    }
    worst
}

/// The generator lays out exactly the hand-built finger (rod order front, back, rib1 …; the
/// same joints; node positions equal to 1e-15 m) and the static response under the Fin Ray
/// test's loads is the same to 1e-12 m, pinned and rigid ribs.
#[test]
fn generated_fin_ray_equals_the_hand_built_finger() {
    for (ribs, kind, p, rib_h) in [(5, "pin", 0.2, 0.002), (4, "rigid", 1e-3, 0.001)] {
        let hand_text = fin_ray_with(ribs, kind, p, false, 0.04, rib_h);
        let gen_text = generated(ribs, kind, p, rib_h);
        let (hand, gen) = (scenario(&hand_text), scenario(&gen_text));
        let names: Vec<&str> = gen.rods.iter().map(|r| r.name.as_str()).collect();
        let mut want = vec!["finger.front".to_string(), "finger.back".to_string()];
        want.extend((1..=ribs).map(|k| format!("finger.rib{k}")));
        assert_eq!(names, want);
        assert_eq!(gen.joints, hand.joints, "{ribs} ribs, {kind}");
        assert_eq!(gen.rods.len(), hand.rods.len());
        for (g, h) in gen.rods.iter().zip(&hand.rods) {
            assert_eq!((g.nodes, &g.clamped), (h.nodes, &h.clamped), "{}", g.name);
            assert_eq!(g.section.inertia(), h.section.inertia(), "{}", g.name);
            let (pg, ph) = (
                shape_points(&g.shape, g.nodes),
                shape_points(&h.shape, h.nodes),
            );
            for (a, b) in pg.iter().zip(&ph) {
                let d = (a[0] - b[0]).abs().max((a[1] - b[1]).abs());
                assert!(d <= 1e-15, "{} node at {a:?} against {b:?}", g.name);
            }
        }
        let (sh, sg) = (run(&hand_text), run(&gen_text));
        let d = max_difference(&sh, &sg);
        let n = sg.rods[0].n;
        println!(
            "{ribs} {kind} ribs, P = {p} N: tip dx {:.6e} m (hand-built {:.6e} m), largest node \
             difference {d:.2e} m",
            node(&sg, 0, n - 1)[0],
            node(&sh, 0, n - 1)[0]
        );
        assert!(d <= 1e-12, "{ribs} {kind}: {d}");
    }
}

/// The Fin Ray effect from the generator: 5 pinned ribs, P = 0.2 N at the front flank's mid
/// node push the flank in and turn the tip toward the load (−x).
#[test]
fn generated_fin_ray_wraps_toward_a_mid_flank_push() {
    let sim = run(&generated(5, "pin", 0.2, 0.002));
    let n = sim.rods[0].n;
    let (tip, mid) = (node(&sim, 0, n - 1)[0], node(&sim, 0, (n - 1) / 2)[0]);
    println!("generated fin ray, 5 pinned ribs, P = 0.2 N: tip dx {tip:.4e} m, mid dx {mid:.4e} m");
    assert!(mid > 0.03, "the flank is pushed in: {mid}");
    assert!(tip < -2e-3, "the tip turns toward the load: {tip}");
}

/// A parallel pair: two generated fingers, the right one `mirror = true` with its back flank
/// on the left of its direction, driven by one actuator. Every member and joint is there
/// (the second finger's joints count its own rods) and the pair stays mirror images.
#[test]
fn a_mirrored_pair_of_generated_fingers_moves_as_mirror_images() {
    let finger = |name: &str, x: f64, side: &str, mirror: bool| {
        format!(
            "[[rod]]\nname = \"{name}\"\nnodes = 19\n\
             shape = {{ kind = \"fin_ray\", length = 0.06, base_width = 0.02, ribs = 2, \
             rib_angle = 10.0, base = [{x}, 0.1], direction = [0.0, -1.0], side = \"{side}\" }}\n\
             E = 1e6\nsection = {{ kind = \"rect\", b = 0.02, h = 0.002 }}\ndensity = 1000.0\n\
             actuator = \"gripper\"\nmirror = {mirror}\n\n"
        )
    };
    let text = format!(
        "name = \"pair\"\n[solve]\nt_end = 0.08\ndt = 1e-3\n\n{}{}\
         [[actuator]]\nname = \"gripper\"\nmirror_x = 0.0\n[[actuator.phase]]\nname = \"close\"\n\
         kind = \"translate\"\ndirection = [1.0, 0.0]\nlaw = \"constant_velocity\"\nspeed = 0.2\n\
         end = {{ travel = 0.01 }}\n[[actuator.phase]]\nname = \"hold\"\nkind = \"hold\"\n",
        finger("left", -0.05, "right", false),
        finger("right", 0.05, "left", true)
    );
    let sc = scenario(&text);
    let names: Vec<&str> = sc.rods.iter().map(|r| r.name.as_str()).collect();
    assert_eq!(
        names,
        [
            "left.front",
            "left.back",
            "left.rib1",
            "left.rib2",
            "right.front",
            "right.back",
            "right.rib1",
            "right.rib2"
        ]
    );
    assert_eq!(sc.joints.len(), 10);
    assert!(sc.joints[5..]
        .iter()
        .all(|j| j.rods.iter().all(|&r| r >= 4)));
    let mut sim = Simulation::new(&sc);
    sim.run(&mut NullObserver).unwrap_or_else(|e| panic!("{e}"));
    let mut worst = 0.0f64;
    for r in 0..4 {
        let (a, b) = (sim.positions(r), sim.positions(r + 4));
        for i in 0..a.len() / 2 {
            worst = worst
                .max((a[2 * i] + b[2 * i]).abs())
                .max((a[2 * i + 1] - b[2 * i + 1]).abs());
        }
    }
    let base = sim.positions(0)[0];
    println!("mirrored pair: left front base x {base:.6} m, mirror mismatch {worst:.2e} m");
    assert!(
        (base - (-0.04)).abs() < 1e-9,
        "the left finger closed 10 mm: {base}"
    );
    assert!(worst < 1e-12, "{worst}");
}

/// Bad generator input: exit 2, one line naming the file, the key and the value.
#[test]
fn bad_fin_ray_input_is_located_with_exit_2() {
    let base = |shape: &str, nodes: usize, extra: &str| {
        format!(
            "name = \"bad\"\n[solve]\nmode = \"static\"\n[[rod]]\nname = \"finger\"\nnodes = {nodes}\n\
             shape = {{ kind = \"fin_ray\", {shape} }}\nE = 1e6\n\
             section = {{ kind = \"rect\", b = 0.02, h = 0.002 }}\ndensity = 1000.0\n{extra}"
        )
    };
    let ok = "length = 0.1, base_width = 0.04";
    let cases = [
        (
            base(&format!("{ok}, ribs = 0"), 37, ""),
            "rod.0.shape.ribs",
            "0",
        ),
        (
            base(&format!("{ok}, ribs = 3, rib_angle = 90.0"), 37, ""),
            "rod.0.shape.rib_angle",
            "90.0",
        ),
        (
            base(&format!("{ok}, ribs = 3, rib_angle = -90.0"), 37, ""),
            "rod.0.shape.rib_angle",
            "-90.0",
        ),
        (
            base("length = 0.1, base_width = 0.0, ribs = 3", 37, ""),
            "rod.0.shape.base_width",
            "0.0",
        ),
        (
            base("length = 0.1, base_width = 0.1, ribs = 3", 37, ""),
            "rod.0.shape.base_width",
            "0.1",
        ),
        (base(&format!("{ok}, ribs = 5"), 9, ""), "rod.0.nodes", "9"),
        (
            base(&format!("{ok}, ribs = 3, rib_angle = -80.0"), 37, ""),
            "rod.0.shape.rib_angle",
            "-80.0",
        ),
        (
            base(&format!("{ok}, ribs = 3, rib_joint = \"glued\""), 37, ""),
            "rod.0.shape.rib_joint",
            "\"glued\"",
        ),
        (
            base(&format!("{ok}, ribs = 3"), 37, "clamped = [0, 1]\n"),
            "rod.0.clamped",
            "[0, 1]",
        ),
    ];
    let twice =
        "[[joint]]\nrods = [\"finger.front\", \"finger.rib1\"]\nnodes = [9, 0]\nkind = \"pin\"\n";
    let same_name = "[[rod]]\nname = \"finger.back\"\nnodes = 3\n\
                     shape = { kind = \"straight\", start = [0.2, 0.0], end = [0.3, 0.0] }\n\
                     E = 1e6\nsection = { kind = \"rect\", b = 0.02, h = 0.002 }\n\
                     density = 1000.0\nclamped = [0, 1]\n";
    let more = [
        (
            base(&format!("{ok}, ribs = 3"), 37, twice),
            "joint.0.nodes",
            "[9, 0]",
            "joins them already",
        ),
        (
            base(&format!("{ok}, ribs = 3"), 37, same_name),
            "rod.1.name",
            "\"finger.back\"",
            "rod.0",
        ),
    ];
    for (text, key, value, says) in more {
        let e = Scenario::from_str(&text, "case.toml", &[]).expect_err(key);
        println!("{key} = {value}: {e}");
        assert_eq!((e.key.as_str(), e.value.as_str()), (key, value), "{e}");
        assert!(e.to_string().contains(says), "{e}");
    }
    let dir = tempfile::tempdir().expect("temp dir");
    for (text, key, value) in cases {
        let e = Scenario::from_str(&text, "case.toml", &[]).expect_err(key);
        assert_eq!((e.key.as_str(), e.value.as_str()), (key, value), "{e}");
        let path = dir.path().join("case.toml");
        std::fs::write(&path, &text).expect("write case");
        let out = Command::new(env!("CARGO_BIN_EXE_gripsim"))
            .arg("run")
            .arg(&path)
            .current_dir(dir.path())
            .output()
            .expect("run gripsim");
        let err = String::from_utf8_lossy(&out.stderr);
        println!("{key} = {value}: {}", err.trim_end());
        assert_eq!(out.status.code(), Some(2), "{err}");
        assert!(err.contains("case.toml") && err.contains(key), "{err}");
        assert!(!err.contains("panicked"), "{err}");
        let left: Vec<_> = std::fs::read_dir(dir.path()).expect("list").collect();
        assert_eq!(left.len(), 1, "nothing written beside the scenario");
    }
}

/// scenarios/fin-ray-push.toml: the figures its comment block states (tip x of the front
/// flank −3.0 mm; welded ribs +1.4 mm; ribs at 20°, −8.9 mm).
#[test]
fn the_shipped_fin_ray_push_turns_its_tip_toward_the_load() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios/fin-ray-push.toml");
    for (set, want) in [
        (None, -3.0e-3),
        (Some("rod.0.shape.rib_joint=\"rigid\""), 1.4e-3),
        (Some("rod.0.shape.rib_angle=20"), -8.9e-3),
    ] {
        let sets: Vec<String> = set.into_iter().map(str::to_string).collect();
        let sc = Scenario::load(&path, &sets).unwrap_or_else(|e| panic!("{e}"));
        let mut sim = Simulation::new(&sc);
        sim.run(&mut NullObserver).unwrap_or_else(|e| panic!("{e}"));
        let n = sim.rods[0].n;
        let tip = node(&sim, 0, n - 1)[0];
        println!("fin-ray-push {set:?}: tip x {tip:.4e} m");
        assert!((tip - want).abs() < 0.05e-3, "{set:?}: {tip}");
    }
}

/// A sweep over `ribs` changes the rods a case has: its per-rod columns (named after the
/// first case's rods) are matched by name, so a second finger's columns hold that finger's
/// numbers in every case (by position they would hold the first finger's extra rib).
#[test]
fn a_sweep_over_ribs_keeps_each_finger_in_its_own_columns() {
    let finger = |name: &str, x: f64, load: &str| {
        format!(
            "[[rod]]\nname = \"{name}\"\nnodes = 25\n\
             shape = {{ kind = \"fin_ray\", length = 0.1, base_width = 0.04, ribs = 2, base = [{x}, 0.0] }}\n\
             E = 1e6\nsection = {{ kind = \"rect\", b = 0.02, h = 0.002 }}\ndensity = 1000.0\n{load}\n"
        )
    };
    let text = format!(
        "name = \"pair-sweep\"\n[solve]\nmode = \"static\"\ngravity = [0.0, 0.0]\n\n{}{}",
        finger("left", 0.0, "loads = [{ node = 12, force = [0.05, 0.0] }]"),
        finger("right", 0.2, "")
    );
    let dir = tempfile::tempdir().expect("temp dir");
    let path = dir.path().join("pair.toml");
    std::fs::write(&path, text).expect("write");
    let out = Command::new(env!("CARGO_BIN_EXE_gripsim"))
        .args([
            "sweep",
            "--vary",
            "rod.*.shape.ribs=2,3",
            "-j",
            "1",
            "--out",
            "sw",
        ])
        .arg(&path)
        .current_dir(dir.path())
        .output()
        .expect("run gripsim");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let csv = std::fs::read_to_string(dir.path().join("sw/summary.csv")).expect("summary.csv");
    let mut lines = csv.lines();
    let header: Vec<&str> = lines.next().expect("header").split(',').collect();
    let col = |name: &str| header.iter().position(|h| *h == name).expect(name);
    let (left, right) = (
        col("max_tip_deflection_m:left.front"),
        col("max_tip_deflection_m:right.front"),
    );
    let right_cols: Vec<usize> = (0..header.len())
        .filter(|&i| header[i].starts_with("max_tip_deflection_m:right."))
        .collect();
    assert_eq!(right_cols.len(), 4, "{header:?}");
    let rows: Vec<Vec<&str>> = lines.map(|l| l.split(',').collect()).collect();
    assert_eq!(rows.len(), 2);
    for row in &rows {
        let l: f64 = row[left].parse().expect("left");
        println!(
            "ribs {}: left tip deflection {l:.4e} m, right {}",
            row[2], row[right]
        );
        assert!(l > 1e-3, "the loaded finger deflects: {l}");
        for &c in &right_cols {
            assert_eq!(row[c].parse::<f64>().expect("right"), 0.0, "{}", header[c]);
        }
    }
}
