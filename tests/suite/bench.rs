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
    // 3 bdf2+adaptive+toi + 3 tr_bdf2+adaptive+toi) rungs; the point mass and the cantilever
    // have 2 rungs of each fixed-dt strategy.
    assert_eq!(lines.len(), 1 + 2 * 21 + 2 * 18, "{csv}");
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
    // The second figure of each line: fixed backward Euler's steps at exactly 1 %, between
    // its rungs dt = 1e-4 (600 steps, 2.6 %) and 3e-5 (2 000 steps, 0.84 %).
    for l in targets.lines() {
        let tail = l.split("same way): fixed ").nth(1).expect(l);
        let n: f64 = tail.split_whitespace().next().unwrap().parse().expect(l);
        assert!(n > 600.0 && n < 2000.0, "{l}");
        // TR-BDF2's figure at exactly 1 %, between its rungs rtol 1e-5 (88 steps, 2.1 %) and
        // 1e-6 (147 steps, 0.37 %): below BDF2's (between 116 and 247).
        let tr = l.split("tr_bdf2+adaptive+toi ").last().expect(l);
        let m: f64 = tr.split_whitespace().next().unwrap().parse().expect(l);
        assert!(m > 88.0 && m < 147.0, "{l}");
    }
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

#[test]
fn steps_at_the_limit_are_interpolated_log_log_between_the_bracketing_rungs() {
    use gripsim::bench::steps_at_limit;
    let close = |a: Option<f64>, b: f64| a.is_some_and(|a| (a - b).abs() < 1e-9 * b);
    // Error ∝ 1/steps: halfway in log is 200 steps at 2 %.
    assert!(close(
        steps_at_limit(&[(100, 0.04), (400, 0.01)], 0.02),
        200.0
    ));
    // Error ∝ 1/steps²: 100 √2 steps at 2 %, whatever the order of the rungs and a rung
    // further down.
    let second = [(800, 0.002), (200, 0.01), (100, 0.04)];
    assert!(close(steps_at_limit(&second, 0.02), 100.0 * 2f64.sqrt()));
    // A rung exactly at the limit is its own answer.
    let exact = [(100, 0.04), (250, 0.02), (400, 0.01)];
    assert!(close(steps_at_limit(&exact, 0.02), 250.0));
    // Not monotone: three crossings, the fewest steps win (100 · 1.5^(ln 3 / ln(0.03/0.009))).
    let wobbly = [(100, 0.03), (150, 0.009), (200, 0.012), (300, 0.005)];
    assert!(close(steps_at_limit(&wobbly, 0.01), 144.770_937_851_11));
    // Nothing brackets the limit.
    assert_eq!(steps_at_limit(&[(100, 0.005), (200, 0.001)], 0.01), None);
    assert_eq!(steps_at_limit(&[(100, 0.05), (200, 0.02)], 0.01), None);
    assert_eq!(steps_at_limit(&[(100, 0.05)], 0.01), None);
}

#[test]
fn a_short_run_is_timed_in_back_to_back_batches_of_at_least_the_minimum_sample() {
    use gripsim::bench::{runs_per_sample, MIN_SAMPLE_S};
    // A run as long as the minimum, or longer, is timed alone.
    assert_eq!(runs_per_sample(MIN_SAMPLE_S), 1);
    assert_eq!(runs_per_sample(0.5), 1);
    // A 1 ms run: 20 runs make a 20 ms sample; a 3 ms run: 7 (21 ms).
    assert_eq!(runs_per_sample(0.001), 20);
    assert_eq!(runs_per_sample(0.003), 7);
    for wall in [3e-4, 7e-4, 2.9e-3, 0.011, 0.019] {
        let k = runs_per_sample(wall);
        assert!(k as f64 * wall >= MIN_SAMPLE_S, "{wall}: {k}");
        assert!((k - 1) as f64 * wall < MIN_SAMPLE_S, "{wall}: {k}");
    }
    // A run too short to measure is capped, not repeated without end.
    assert_eq!(runs_per_sample(0.0), 100);
    assert_eq!(runs_per_sample(f64::NAN), 1);
}
