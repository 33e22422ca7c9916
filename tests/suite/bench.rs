//! `gripsim bench --quick` and `--stress --quick` as smoke tests: they run, and write their
//! tables and figures. No timing is asserted here; speed is measured by the bench itself.

use std::process::Command;

fn bench(args: &[&str]) -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_gripsim"))
        .arg("bench")
        .args(args)
        .arg("--out")
        .arg(dir.path())
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "bench {args:?} failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    dir
}

#[test]
fn quick_work_precision_and_scaling_write_tables_and_figures() {
    let dir = bench(&["--quick"]);
    let csv = std::fs::read_to_string(dir.path().join("work-precision.csv")).unwrap();
    let lines: Vec<&str> = csv.lines().collect();
    // The two grasps × (3 fixed + 3 proximity + 3 adaptive + 3 adaptive+toi + 3 bdf2 +
    // 3 bdf2+adaptive+toi) rungs; the point mass and the cantilever have 2 rungs of each
    // fixed-dt strategy.
    assert_eq!(lines.len(), 1 + 2 * 18 + 2 * 15, "{csv}");
    assert!(lines[0].starts_with("case,strategy,parameter,value,steps"));
    for l in &lines[1..] {
        let f: Vec<&str> = l.split(',').collect();
        let steps: u64 = f[4].parse().unwrap();
        assert!(steps > 0, "{l}");
        let pos: f64 = f[7].parse().unwrap();
        assert!(pos.is_finite() && pos >= 0.0, "{l}");
    }
    // Refining the fixed step reduces the seed grasp's position error.
    let seed: Vec<f64> = lines
        .iter()
        .filter(|l| l.starts_with("seed-grasp-r5,fixed,"))
        .map(|l| l.split(',').nth(7).unwrap().parse().unwrap())
        .collect();
    assert!(
        seed.len() == 3 && seed[2] < seed[1] && seed[1] < seed[0],
        "{seed:?}"
    );
    // The issue 13 comparison at 1 % impulse error, one line per grasp case (and the
    // cantilever, whose impulse is zero, is left out).
    let targets = std::fs::read_to_string(dir.path().join("work-precision-targets.txt")).unwrap();
    let cases: Vec<&str> = targets
        .lines()
        .map(|l| l.split_whitespace().nth(1).unwrap())
        .collect();
    assert_eq!(cases, ["seed-grasp-r5", "two-prong-grasp"], "{targets}");
    for (f, min) in [
        ("work-precision.png", 10_000),
        ("work-precision.svg", 10_000),
        ("scaling.png", 5_000),
        ("scaling.svg", 5_000),
        ("scaling.csv", 60),
    ] {
        let m = std::fs::metadata(dir.path().join(f)).unwrap_or_else(|_| panic!("{f} missing"));
        assert!(m.len() > min, "{f} is too small ({} bytes)", m.len());
    }
    let scaling = std::fs::read_to_string(dir.path().join("scaling.csv")).unwrap();
    assert_eq!(scaling.lines().count(), 1 + 3, "{scaling}");
}

#[test]
fn quick_stress_map_has_no_non_finite_value_and_no_penetration_in_ok_cells() {
    let dir = bench(&["--stress", "--quick"]);
    let csv = std::fs::read_to_string(dir.path().join("stress.csv")).unwrap();
    let mut rows = csv.lines();
    let header: Vec<&str> = rows.next().unwrap().split(',').collect();
    let col = |name: &str| header.iter().position(|h| *h == name).unwrap();
    let mut n = 0;
    for l in rows {
        let f: Vec<&str> = l.split(',').collect();
        n += 1;
        assert_eq!(f[col("non_finite")], "false", "{l}");
        if f[col("status")] == "ok" {
            let pen: f64 = f[col("max_penetration_m")].parse().unwrap();
            assert!(pen <= 1e-9, "{l}");
        }
    }
    assert_eq!(n, 16);
    assert!(dir.path().join("stress.png").exists() && dir.path().join("stress.svg").exists());
}
