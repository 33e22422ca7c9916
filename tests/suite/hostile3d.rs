//! Issue 34: 3D holds up to hostile input. Each test runs the built binary (or the library)
//! and asserts the exit code, the message's key words and that no file was left behind.

use crate::common::{gripsim, text, ROOT};
use std::path::{Path, PathBuf};

/// The shipped two-finger 3D scenario copied into a fresh folder (the outputs land there).
fn base(dir: &Path) -> PathBuf {
    let p = dir.join("s.toml");
    std::fs::copy(
        Path::new(ROOT).join("scenarios/3d-two-finger-sphere.toml"),
        &p,
    )
    .unwrap();
    p
}

fn files(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

/// `gripsim <args> s.toml --set …` in a fresh folder: exit 2, one `error:` line holding every
/// word, and the folder as it was.
fn refused(args: &[&str], sets: &[&str], words: &[&str]) {
    let d = tempfile::tempdir().unwrap();
    let s = base(d.path());
    let before = files(d.path());
    let mut c = gripsim();
    c.current_dir(d.path()).args(args).arg(&s);
    for set in sets {
        c.args(["--set", set]);
    }
    let out = c.output().unwrap();
    let all = text(&out);
    assert_eq!(out.status.code(), Some(2), "{args:?} {sets:?}: {all}");
    let err = String::from_utf8_lossy(&out.stderr);
    let line = err
        .lines()
        .find(|l| l.starts_with("error:"))
        .unwrap_or_else(|| panic!("no error line: {all}"));
    for w in words {
        assert!(line.contains(w), "{sets:?}: {w:?} missing in {line}");
    }
    assert!(!err.contains("panicked"), "{all}");
    assert_eq!(files(d.path()), before, "{sets:?}: a file was left: {all}");
}

fn validate_refuses(sets: &[&str], words: &[&str]) {
    refused(&["validate"], sets, words);
    refused(&["run", "--csv", "o.csv"], sets, words);
}

/// Item 9: nodes per prong, fingers and nodes in all are bounded before anything is built.
#[test]
fn sizes_in_3d_are_bounded_before_allocating() {
    validate_refuses(
        &["prong.nodes=10000000"],
        &["prong.nodes", "10000000", "at most 1000000 nodes per prong"],
    );
    validate_refuses(
        &["gripper.kind=\"radial\"", "gripper.fingers=1000000000000"],
        &["gripper.fingers", "1000000000000", "at most 1000 fingers"],
    );
    validate_refuses(
        &[
            "gripper.kind=\"radial\"",
            "gripper.fingers=4",
            "prong.nodes=300000",
        ],
        &[
            "prong.nodes",
            "1200000 nodes over 4 fingers",
            "at most 1000000 in all",
        ],
    );
}

/// Item 17: names that would name a folder, break a CSV row or repeat another object's.
#[test]
fn names_in_3d_are_checked() {
    validate_refuses(&["name=\".\""], &["key `name`", "letter or digit"]);
    validate_refuses(&["name=\"a\\nb\""], &["key `name`", "may only hold"]);
    validate_refuses(
        &["fruit.name=\"finger1\""],
        &["fruit.name", "duplicate name \"finger1\"", "finger"],
    );
    validate_refuses(
        &["fruit.name=\"table\""],
        &["obstacle.0.name", "duplicate name \"table\"", "fruit.name"],
    );
    validate_refuses(
        &["obstacle.0.name=\"ta\\u0000ble\""],
        &["obstacle.0.name", "must not hold the character '\\0'"],
    );
    validate_refuses(
        &["fruit.name=\"a,b\""],
        &["fruit.name", "must not hold the character ','"],
    );
}

/// `dimension = 2` is the planar default said aloud: a planar scenario that says it reads as
/// one that does not.
#[test]
fn a_planar_scenario_may_say_dimension_2() {
    let d = tempfile::tempdir().unwrap();
    let s = d.path().join("jaw.toml");
    let t = std::fs::read_to_string(Path::new(ROOT).join("scenarios/jaw-grasp-hold.toml")).unwrap();
    std::fs::write(&s, format!("dimension = 2\n{t}")).unwrap();
    let out = gripsim().arg("validate").arg(&s).output().unwrap();
    assert_eq!(out.status.code(), Some(0), "{}", text(&out));
    std::fs::write(&s, format!("dimension = 2.0\n{t}")).unwrap();
    let out = gripsim().arg("validate").arg(&s).output().unwrap();
    assert_eq!(out.status.code(), Some(2), "{}", text(&out));
}

/// Item 18: `dimension` of another type is a type error of the 3D reader, not planar noise.
#[test]
fn a_dimension_of_another_type_says_so() {
    for (written, words) in [
        (
            "dimension = 3.0",
            vec![
                "key `dimension` = 3.0",
                "expected the integer 3, found a float 3.0",
            ],
        ),
        (
            "dimension = \"3\"",
            vec!["key `dimension` = \"3\"", "found a string \"3\""],
        ),
        (
            "dimension = 4",
            vec!["key `dimension` = 4", "a planar one dimension = 2"],
        ),
    ] {
        let d = tempfile::tempdir().unwrap();
        let s = base(d.path());
        let t = std::fs::read_to_string(&s).unwrap();
        std::fs::write(&s, t.replace("dimension = 3", written)).unwrap();
        let out = gripsim().arg("validate").arg(&s).output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{}", text(&out));
        for w in &words {
            assert!(err.contains(w), "{written}: {w:?} missing in {err}");
        }
        assert!(
            !err.contains("2D vector") && !err.contains("t_end"),
            "{err}"
        );
    }
}

/// Item 18: what 3D does not have yet is refused as such, with nothing written. (A sweep
/// runs 3D files: tests/suite/study3d.rs.)
#[test]
fn perturb_on_a_3d_file_is_not_yet_available() {
    refused(
        &["run", "--perturb", "--csv", "o.csv"],
        &[],
        &["--perturb", "not yet available in 3D"],
    );
}

/// A closed bipyramid of `2 n` triangles (counter-clockwise from outside), 2 cm across.
fn bipyramid(n: usize) -> String {
    let mut s = String::new();
    for k in 0..n {
        let a = 2.0 * std::f64::consts::PI * k as f64 / n as f64;
        s += &format!("v {} {} 0\n", 0.01 * a.cos(), 0.01 * a.sin());
    }
    s += "v 0 0 0.01\nv 0 0 -0.01\n";
    for k in 0..n {
        let (a, b) = (k + 1, (k + 1) % n + 1);
        s += &format!("f {a} {b} {}\nf {b} {a} {}\n", n + 1, n + 2);
    }
    s
}

/// Items 8 and 18: a mesh's scale is range-checked, a mesh's size is bounded, a large one
/// runs with a warning of its cost.
#[test]
fn meshes_are_bounded_and_large_ones_are_announced() {
    let mesh = "fruit.shape={kind=\"mesh\",file=\"m.obj\",scale=1e200}";
    let d = tempfile::tempdir().unwrap();
    let s = base(d.path());
    std::fs::write(d.path().join("m.obj"), bipyramid(8)).unwrap();
    let out = gripsim()
        .arg("validate")
        .arg(&s)
        .args(["--set", mesh])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{}", text(&out));
    assert!(
        err.contains("fruit.shape.scale") && err.contains("too large (at most 1e6)"),
        "{err}"
    );
    // 100 002 triangles: accepted, with the cost said.
    std::fs::write(d.path().join("m.obj"), bipyramid(50_001)).unwrap();
    let out = gripsim()
        .arg("validate")
        .arg(&s)
        .args(["--set", &mesh.replace("scale=1e200", "scale=1.0")])
        .args(["--set", "fruit.centre=[0,0,-0.09]"])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{}", text(&out));
    assert!(
        err.contains("warning:") && err.contains("fruit.shape: the mesh has 100002 triangles"),
        "{err}"
    );
    // Over the limit: refused before its triangles are stored.
    let lim = gripsim::rod3d::limits::check_mesh_faces(1_000_001).unwrap_err();
    assert!(lim.contains("1000001 triangles"), "{lim}");
}

/// Item 8: a mesh that is a FIFO, a folder or a device is refused at once (never opened for a
/// blocking read), in `run`, `validate` and `scenarios --dir`.
#[test]
fn a_mesh_that_is_not_a_regular_file_is_refused_without_blocking() {
    let d = tempfile::tempdir().unwrap();
    let s = base(d.path());
    let fifo = d.path().join("fifo.obj");
    assert!(std::process::Command::new("mkfifo")
        .arg(&fifo)
        .status()
        .unwrap()
        .success());
    std::fs::create_dir(d.path().join("dir.obj")).unwrap();
    std::os::unix::fs::symlink("/dev/zero", d.path().join("zero.obj")).unwrap();
    for f in ["fifo.obj", "dir.obj", "zero.obj"] {
        let set = format!("fruit.shape={{kind=\"mesh\",file=\"{f}\"}}");
        for args in [vec!["validate"], vec!["run", "--no-record"]] {
            let out = gripsim()
                .args(&args)
                .arg(&s)
                .args(["--set", &set])
                .output()
                .unwrap();
            let err = String::from_utf8_lossy(&out.stderr);
            assert_eq!(out.status.code(), Some(2), "{f}: {}", text(&out));
            assert!(
                err.contains("fruit.shape.file") && err.contains("not a regular file"),
                "{f}: {err}"
            );
        }
        let t = std::fs::read_to_string(&s).unwrap().replace(
            "shape = { kind = \"sphere\", radius = 0.05 }",
            &format!("shape = {{ kind = \"mesh\", file = \"{f}\" }}"),
        );
        std::fs::write(d.path().join("bad.toml"), t).unwrap();
        let out = gripsim()
            .args(["scenarios", "--dir"])
            .arg(d.path())
            .output()
            .unwrap();
        let all = text(&out);
        assert!(all.contains("not a regular file"), "{f}: {all}");
        std::fs::remove_file(d.path().join("bad.toml")).unwrap();
    }
}

/// Item 10: nothing starts inside anything: the fruit in the table, a prong's face in the
/// fruit or an obstacle, coincident prong points.
#[test]
fn start_up_geometry_is_checked_in_3d() {
    validate_refuses(
        &["fruit.centre=[0,0,-0.1]"],
        &[
            "fruit.centre",
            "the fruit \"fruit\" starts 4.000e-2 m inside obstacle \"table\"",
        ],
    );
    validate_refuses(
        &["gripper.radius=0.03"],
        &[
            "fruit.centre",
            "finger0 node",
            "'s face",
            "m inside the fruit \"fruit\"",
        ],
    );
    validate_refuses(
        &[
            "obstacle.0.at=[0,0,-0.07]",
            "fruit.centre=[0,0,-0.02]",
            "fruit.shape={kind=\"sphere\",radius=0.01}",
        ],
        &[
            "obstacle.0.at",
            "finger0 node 7's face",
            "starts 7.955e-3 m inside obstacle \"table\"",
        ],
    );
    // Points given in the file (a --set cannot remove `nodes` and `shape`).
    let d = tempfile::tempdir().unwrap();
    let s = base(d.path());
    let t = std::fs::read_to_string(&s).unwrap().replace(
        "nodes = 10\nshape = { kind = \"parabola\", a = 0.8, length = 0.1 }",
        "points = [[0, 0, 0], [0, 0, -0.05], [0, 0, -0.05], [0, 0, -0.1]]",
    );
    assert!(t.contains("points = "));
    std::fs::write(&s, t).unwrap();
    let out = gripsim().arg("validate").arg(&s).output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{}", text(&out));
    assert!(
        err.contains("prong.points") && err.contains("nodes 1 and 2 coincide"),
        "{err}"
    );
}

/// Item 18: a 3D run with no fruit and no obstacle says so, never "-inf".
#[test]
fn a_3d_run_without_surfaces_prints_no_contact() {
    let d = tempfile::tempdir().unwrap();
    let s = base(d.path());
    let t = std::fs::read_to_string(&s).unwrap();
    let (a, b) = (t.find("[fruit]").unwrap(), t.find("[[move]]").unwrap());
    std::fs::write(&s, format!("{}{}", &t[..a], &t[b..])).unwrap();
    let out = gripsim()
        .arg("run")
        .arg(&s)
        .args(["--no-record", "--set", "solve.t_end=0.002"])
        .output()
        .unwrap();
    let all = text(&out);
    assert!(out.status.success(), "{all}");
    assert!(all.contains("penetration     none (no contact"), "{all}");
    assert!(!all.contains("inf"), "{all}");
}

/// Item 13: the 3D CSV's rows are written as the planar CSV's: every page boundary of the
/// file falls at the end of a row, so a process killed inside a write leaves whole rows.
#[test]
fn the_3d_csv_ends_every_page_at_a_row_end() {
    use std::io::Write;
    let mut w = gripsim::record::csv::PagedRows::new(Vec::new());
    let mut expect = String::new();
    for step in 0..3000u32 {
        let row = format!("{step},{:e},finger0,{}\n", step as f64 * 1e-4, step % 17);
        expect += &row;
        w.write_all(row.as_bytes()).unwrap();
        if step % 3 == 0 {
            w.rows_end().unwrap();
        }
    }
    w.flush().unwrap();
    let bytes = w.into_inner();
    assert!(bytes.len() > 10 * 4096);
    for page in (4096..bytes.len()).step_by(4096) {
        assert_eq!(bytes[page - 1], b'\n', "page boundary {page} inside a row");
    }
    // Padding is leading zeros of `step`: the same numbers.
    let read: Vec<String> = String::from_utf8(bytes)
        .unwrap()
        .lines()
        .map(|l| {
            let (s, rest) = l.split_once(',').unwrap();
            format!("{},{rest}", s.parse::<u32>().unwrap())
        })
        .collect();
    let want: Vec<&str> = expect.lines().collect();
    assert_eq!(read, want);
}

/// Item 14: a full disk in 3D is exit 2, with no file left (planar: faults.rs).
#[test]
fn a_full_disk_in_3d_is_exit_2_and_leaves_nothing() {
    let d = tempfile::tempdir().unwrap();
    let s = base(d.path());
    for opt in ["--csv", "--rrd", "--mcap", "--summary"] {
        let link = d.path().join(format!("o{}", opt.replace("--", ".")));
        std::os::unix::fs::symlink("/dev/full", &link).unwrap();
        let mut c = gripsim();
        c.current_dir(d.path()).args(["run"]).arg(&s);
        if opt == "--summary" {
            c.arg("--no-record");
        }
        let out = c
            .arg(opt)
            .arg(&link)
            .args(["--set", "solve.t_end=0.01"])
            .output()
            .unwrap();
        let all = text(&out);
        assert_eq!(out.status.code(), Some(2), "{opt}: {all}");
        assert!(!all.contains("panicked"), "{all}");
        std::fs::remove_file(&link).unwrap();
        let left: Vec<String> = files(d.path())
            .into_iter()
            .filter(|f| f != "s.toml")
            .collect();
        assert!(left.is_empty(), "{opt}: {left:?}: {all}");
    }
}

/// Item 11: a box resting on a table (four corners on a plane: dependent contact rows), and on
/// a table given twice, rests for 1 s: the table carries m g, the box neither sinks nor drifts.
#[test]
fn a_box_rests_on_a_plane_and_on_a_plane_given_twice() {
    use gripsim::obstacle3::{Obstacle3, Pose3, Shape3};
    use gripsim::rod3d::body3::Body3;
    use gripsim::rod3d::World3;
    let g = 9.81;
    for (planes, mu) in [(1, 0.0), (1, 0.5), (2, 0.0), (2, 0.5)] {
        let mut w = World3::new([0.0, 0.0, -g]);
        w.friction.default.mu_s = mu;
        w.friction.default.mu_k = mu;
        let half = [0.03, 0.02, 0.01];
        let body = Body3::new("box", Shape3::Box { half }, 800.0, [0.0, 0.0, 0.01]).unwrap();
        let m = body.mass;
        w.bodies.push(body);
        for k in 0..planes {
            w.obstacles.push(Obstacle3::new(
                &format!("table{k}"),
                Shape3::Plane,
                Pose3::facing([0.0; 3], [0.0, 0.0, 1.0]),
            ));
        }
        let dt = 1e-3;
        let (mut worst_force, mut worst_drift): (f64, f64) = (0.0, 0.0);
        for step in 1..=1000 {
            w.step(dt)
                .unwrap_or_else(|e| panic!("{planes} plane(s), mu {mu}: step {step}: {e}"));
            let f: f64 = w.body_contacts.iter().map(|c| c.force.z).sum();
            if step > 1 {
                worst_force = worst_force.max((f - m * g).abs() / (m * g));
            }
            let c = w.bodies[0].centre();
            worst_drift = worst_drift.max((c - gripsim::obstacle3::V3::new(0.0, 0.0, 0.01)).norm());
        }
        let spin = w.bodies[0].obstacle.pose.rotation.angle();
        println!(
            "{planes} plane(s), mu {mu}: {} contacts, force error {worst_force:e}, drift \
             {worst_drift:e} m, rotation {spin:e} rad",
            w.body_contacts.len()
        );
        assert!(w.body_contacts.len() >= 4 * planes);
        assert!(
            worst_force < 1e-6,
            "{planes} plane(s), mu {mu}: {worst_force:e}"
        );
        assert!(
            worst_drift < 1e-9,
            "{planes} plane(s), mu {mu}: {worst_drift:e}"
        );
        assert!(spin < 1e-9, "{spin:e}");
    }
}

/// Item 8: a replay reads the mesh the scenario names beside the recording; a different mesh
/// there is refused (the recording keeps the mesh's hash), the same one replays.
#[test]
fn a_replay_refuses_a_different_mesh_beside_the_recording() {
    let d = tempfile::tempdir().unwrap();
    let s = base(d.path());
    std::fs::write(d.path().join("m.obj"), bipyramid(12)).unwrap();
    let out = gripsim()
        .current_dir(d.path())
        .arg("run")
        .arg(&s)
        .args(["--mcap", "r.mcap", "--set", "solve.t_end=0.002"])
        .args(["--set", "fruit.shape={kind=\"mesh\",file=\"m.obj\"}"])
        .args(["--set", "fruit.centre=[0,0,-0.1]"])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", text(&out));
    let check = || {
        gripsim()
            .current_dir(d.path())
            .args(["replay", "check", "r.mcap"])
            .output()
            .unwrap()
    };
    let same = check();
    assert!(
        !String::from_utf8_lossy(&same.stderr).contains("not the mesh the run used"),
        "{}",
        text(&same)
    );
    assert_ne!(same.status.code(), Some(2), "{}", text(&same));
    std::fs::write(d.path().join("m.obj"), bipyramid(16)).unwrap();
    let other = check();
    let err = String::from_utf8_lossy(&other.stderr);
    assert_eq!(other.status.code(), Some(2), "{}", text(&other));
    assert!(
        err.contains("r.mcap")
            && err.contains("the mesh of \"fruit\" found beside the recording (32 triangles")
            && err.contains("is not the mesh the run used"),
        "{err}"
    );
}

/// Item 18: a 3D run that does not converge names the finger and the node, as planar does.
#[test]
fn a_3d_divergence_names_the_finger_and_node() {
    let out = gripsim()
        .args(["run", "scenarios/3d-lift.toml", "--no-record", "-q"])
        .args(["--set", "solve.max_newton_iterations=1"])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{}", text(&out));
    assert!(
        err.contains("step 1 ")
            && err.contains("rod \"finger")
            && err.contains(" node ")
            && err.contains("Newton did not converge"),
        "{err}"
    );
}
