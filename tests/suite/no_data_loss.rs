//! "Nothing lost" (issue 34, items 1, 2, 3, 15, 16): no command writes onto its own inputs or
//! a block device, a command that fails leaves the files that were there before untouched and
//! no half set of new ones, and a scenario is read once (a pipe works). Each test asserts the
//! exit status, the error's key words (the files), and that no file that existed changed
//! (bytes and modification time) and no new file appeared. docs/robustness.md ("Nothing
//! lost") lists them. Parts that need root (mknod, mount) skip with a printed reason without.

use crate::common::{gripsim, scenario};
use std::collections::BTreeMap;
use std::io::Write as _;
use std::os::unix::fs::FileTypeExt;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant, SystemTime};

/// Every file under `dir` (relative path) with its kind, bytes and modification time.
type Snapshot = BTreeMap<PathBuf, (String, Vec<u8>, Option<SystemTime>)>;

fn snapshot(dir: &Path) -> Snapshot {
    fn walk(root: &Path, dir: &Path, out: &mut Snapshot) {
        for e in std::fs::read_dir(dir).unwrap() {
            let p = e.unwrap().path();
            let m = std::fs::symlink_metadata(&p).unwrap();
            let rel = p.strip_prefix(root).unwrap().to_path_buf();
            let ft = m.file_type();
            let (kind, bytes) = if ft.is_symlink() {
                let to = std::fs::read_link(&p).unwrap();
                ("link".to_string(), to.to_string_lossy().as_bytes().to_vec())
            } else if ft.is_dir() {
                walk(root, &p, out);
                ("dir".to_string(), Vec::new())
            } else if ft.is_file() {
                ("file".to_string(), std::fs::read(&p).unwrap())
            } else {
                (format!("{ft:?}"), Vec::new())
            };
            let mtime = (kind == "file").then(|| m.modified().unwrap());
            out.insert(rel, (kind, bytes, mtime));
        }
    }
    let mut out = Snapshot::new();
    walk(dir, dir, &mut out);
    out
}

/// `after` is `before`: same files, same bytes, same modification times.
fn unchanged(before: &Snapshot, after: &Snapshot, what: &str) {
    let names = |s: &Snapshot| s.keys().cloned().collect::<Vec<_>>();
    assert_eq!(
        names(after),
        names(before),
        "{what}: files appeared or went"
    );
    for (k, v) in before {
        let w = &after[k];
        assert!(v.0 == w.0 && v.1 == w.1, "{what}: {} changed", k.display());
        assert_eq!(v.2, w.2, "{what}: {} was rewritten", k.display());
    }
}

fn out_text(o: &Output) -> String {
    format!(
        "exit {:?}\nstdout:\n{}\nstderr:\n{}",
        o.status.code(),
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    )
}

/// Run to the end (a hang guard of `limit`, not a timing: the test fails if it hangs).
fn run_limited(cmd: &mut Command, limit: Duration) -> Output {
    let mut child = cmd
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("gripsim starts");
    let start = Instant::now();
    while child.try_wait().unwrap().is_none() {
        if start.elapsed() > limit {
            let _ = child.kill();
            let o = child.wait_with_output().unwrap();
            panic!("{cmd:?} hung (killed after {limit:?}): {}", out_text(&o));
        }
        std::thread::sleep(Duration::from_millis(5));
    }
    child.wait_with_output().unwrap()
}

const LIMIT: Duration = Duration::from_secs(120);

/// Exit 2 with exactly one `error:` line holding every one of `words`; returns the line.
fn refused(cmd: &mut Command, words: &[&str]) -> String {
    let o = run_limited(cmd, LIMIT);
    assert_eq!(o.status.code(), Some(2), "{cmd:?}: {}", out_text(&o));
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(!stderr.contains("panicked"), "{}", out_text(&o));
    let lines: Vec<&str> = stderr.lines().filter(|l| l.starts_with("error:")).collect();
    assert_eq!(lines.len(), 1, "one error line: {}", out_text(&o));
    for w in words {
        assert!(lines[0].contains(w), "{w:?} missing from: {}", lines[0]);
    }
    lines[0].to_string()
}

fn ok(cmd: &mut Command) -> Output {
    let o = run_limited(cmd, LIMIT);
    assert_eq!(o.status.code(), Some(0), "{cmd:?}: {}", out_text(&o));
    o
}

/// `gripsim` run in `dir`.
fn gs(dir: &Path) -> Command {
    let mut c = gripsim();
    c.current_dir(dir);
    c
}

const SHORT: [&str; 5] = ["-q", "--detail", "step", "--set", "solve.t_end=0.002"];
const SHORT3: [&str; 3] = ["-q", "--set", "solve.t_end=0.002"];

fn is_root() -> bool {
    // SAFETY: a plain query.
    unsafe { libc::geteuid() == 0 }
}

/// A device node made in `dir` (`mknod`; `block` or character), or None (with a printed
/// reason) without root.
fn mknod(dir: &Path, name: &str, block: bool, major: u32, minor: u32) -> Option<PathBuf> {
    let p = dir.join(name);
    let c = std::ffi::CString::new(p.to_str().unwrap()).unwrap();
    let kind = if block { libc::S_IFBLK } else { libc::S_IFCHR };
    // SAFETY: a path we own, a plain mode and device number.
    let r = unsafe { libc::mknod(c.as_ptr(), kind | 0o666, libc::makedev(major, minor)) };
    if r != 0 {
        eprintln!(
            "skipped: cannot mknod {} ({}): needs root",
            p.display(),
            std::io::Error::last_os_error()
        );
        return None;
    }
    Some(p)
}

fn mkfifo(p: &Path) {
    let c = std::ffi::CString::new(p.to_str().unwrap()).unwrap();
    // SAFETY: a valid C string; creates a FIFO in a temporary folder.
    assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o600) }, 0);
}

/// The seed grasp, short, recorded to `dir/name` (planar), and the two-finger sphere (3D).
fn record(dir: &Path, name: &str, three: bool) {
    let mut c = gs(dir);
    if three {
        c.arg("run")
            .arg(scenario("3d-two-finger-sphere"))
            .args(SHORT3)
            .args(["--mcap", name]);
    } else {
        c.arg("run")
            .arg(scenario("seed-grasp-r5"))
            .args(SHORT)
            .args(["--mcap", name]);
    }
    ok(&mut c);
}

// ---------------------------------------------------------------------------------------
// Item 1: replay never writes onto its inputs, nor two outputs onto one file.

#[test]
fn item1_replay_refuses_an_output_that_is_an_input_or_another_output() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    record(d, "a.mcap", false);
    record(d, "b.mcap", false);
    record(d, "c3.mcap", true);
    record(d, "d3.mcap", true);
    std::fs::hard_link(d.join("a.mcap"), d.join("hard.mcap")).unwrap();
    std::os::unix::fs::symlink("b.mcap", d.join("link.mcap")).unwrap();
    let before = snapshot(d);
    let cases: &[(&[&str], &[&str])] = &[
        (
            &["show", "a.mcap", "--rrd", "a.mcap"],
            &["--rrd a.mcap and the run a.mcap (an input)"],
        ),
        (
            &["check", "a.mcap", "--json", "a.mcap"],
            &["--json a.mcap and the run a.mcap (an input)"],
        ),
        (
            &["diff", "a.mcap", "b.mcap", "--json", "b.mcap"],
            &["--json b.mcap and run B b.mcap (an input)"],
        ),
        (
            &["diff", "a.mcap", "b.mcap", "--rrd", "link.mcap"],
            &["--rrd link.mcap and run B b.mcap (an input)"],
        ),
        (
            &["check", "hard.mcap", "--rrd", "a.mcap"],
            &["--rrd a.mcap and the run hard.mcap (an input)"],
        ),
        (
            &["check", "a.mcap", "--json", "o", "--rrd", "o"],
            &["--rrd o and --json o", "same file"],
        ),
        (
            &[
                "check",
                "a.mcap",
                "--json",
                "o.json",
                "--rrd",
                "o.partial.json",
            ],
            &["--rrd o.partial.json and --json o.json"],
        ),
        // 3D recordings, the same rules.
        (
            &["show", "c3.mcap", "--rrd", "c3.mcap"],
            &["--rrd c3.mcap and the run c3.mcap (an input)"],
        ),
        (
            &["check", "c3.mcap", "--json", "./c3.mcap"],
            &["--json ./c3.mcap and the run c3.mcap (an input)"],
        ),
        (
            &["diff", "c3.mcap", "d3.mcap", "--rrd", "d3.mcap"],
            &["--rrd d3.mcap and run B d3.mcap (an input)"],
        ),
    ];
    for (args, words) in cases {
        let e = refused(gs(d).arg("replay").args(*args), words);
        assert!(e.contains("same file"), "{e}");
        unchanged(&before, &snapshot(d), &format!("replay {args:?}"));
    }
}

// ---------------------------------------------------------------------------------------
// Item 2: a file a scenario names (a mesh, a profile table) is an input too.

/// A 3D scenario whose fruit is the OBJ mesh `fruit.obj` beside it, in `d`.
fn mesh_scenario(d: &Path) -> PathBuf {
    let text = std::fs::read_to_string(scenario("3d-two-finger-sphere")).unwrap();
    let from = "shape = { kind = \"sphere\", radius = 0.05 }";
    assert!(text.contains(from));
    let text = text.replace(
        from,
        "shape = { kind = \"mesh\", file = \"fruit.obj\", scale = 0.08 }",
    );
    std::fs::write(d.join("mesh.toml"), text).unwrap();
    std::fs::write(d.join("fruit.obj"), gripsim::obstacle3::mesh::CUBE_OBJ).unwrap();
    d.join("mesh.toml")
}

/// The profiled close with its closing profile in the table file `name` beside it, in `d`.
fn profile_scenario(d: &Path, name: &str) -> PathBuf {
    let text = std::fs::read_to_string(scenario("profiled-close")).unwrap();
    let from =
        "points = [[0.0, 0.0], [0.04, 0.002], [0.08, 0.0048], [0.12, 0.0056], [0.3, 0.0085]]";
    assert!(text.contains(from));
    std::fs::write(
        d.join("prof.toml"),
        text.replace(from, &format!("file = \"{name}\"")),
    )
    .unwrap();
    std::fs::write(
        d.join(name),
        "t, s\n0.0, 0.0\n0.04, 0.002\n0.08, 0.0048\n0.12, 0.0056\n0.3, 0.0085\n",
    )
    .unwrap();
    d.join("prof.toml")
}

#[test]
fn item2_files_a_scenario_names_are_never_outputs() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    mesh_scenario(d);
    profile_scenario(d, "close.csv");
    std::fs::copy(d.join("close.csv"), d.join("other.csv")).unwrap();
    // Both read: the mesh fruit and the profile table.
    ok(gs(d).args(["validate", "mesh.toml"]));
    ok(gs(d).args(["validate", "prof.toml"]));
    let before = snapshot(d);
    for flag in ["--csv", "--summary", "--rrd", "--mcap"] {
        refused(
            gs(d).args(["run", "mesh.toml", "-q", flag, "fruit.obj"]),
            &[&format!(
                "{flag} fruit.obj and the scenario's file fruit.obj (an input)"
            )],
        );
        unchanged(&before, &snapshot(d), &format!("3D {flag} fruit.obj"));
        refused(
            gs(d).args(["run", "prof.toml", "-q", flag, "close.csv"]),
            &[&format!(
                "{flag} close.csv and the scenario's file close.csv (an input)"
            )],
        );
        unchanged(&before, &snapshot(d), &format!("planar {flag} close.csv"));
    }
    // Through --set too: the file named after the overrides is the input.
    refused(
        gs(d).args([
            "run",
            "prof.toml",
            "-q",
            "--set",
            "actuator.0.phase.0.file=\"other.csv\"",
            "--csv",
            "other.csv",
        ]),
        &["--csv other.csv and the scenario's file other.csv (an input)"],
    );
    unchanged(&before, &snapshot(d), "--set file");

    // sweep --out: a profile table named summary.csv beside the scenario, the sweep's table
    // in the same folder; a scenario inside the folder's cases/.
    let s = tempfile::tempdir().unwrap();
    let sd = s.path();
    profile_scenario(sd, "summary.csv");
    std::fs::create_dir_all(sd.join("out/cases/x")).unwrap();
    std::fs::copy(scenario("seed-grasp-r5"), sd.join("out/cases/x/s.toml")).unwrap();
    let before = snapshot(sd);
    let sweep = |scen: &str, out: &str| {
        let mut c = gs(sd);
        c.args([
            "sweep",
            scen,
            "-q",
            "--vary",
            "solve.dt=1e-5,2e-5",
            "--out",
            out,
        ]);
        c
    };
    refused(
        &mut sweep("prof.toml", "."),
        &["--out ./summary.csv and the scenario's file summary.csv (an input)"],
    );
    unchanged(&before, &snapshot(sd), "sweep --out onto a profile");
    refused(
        &mut sweep("out/cases/x/s.toml", "out"),
        &["the scenario out/cases/x/s.toml (an input) is inside --out out/cases"],
    );
    unchanged(&before, &snapshot(sd), "sweep --out around the scenario");
}

// ---------------------------------------------------------------------------------------
// Item 3: a block device is never an output.

#[test]
fn item3_a_block_device_is_refused_as_an_output() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    record(d, "a.mcap", false);
    record(d, "c3.mcap", true);
    let Some(blk) = mknod(d, "blk", true, 7, 200) else {
        return;
    };
    let before = snapshot(d);
    let seed = scenario("seed-grasp-r5");
    let three = scenario("3d-two-finger-sphere");
    for flag in ["--csv", "--summary", "--rrd", "--mcap"] {
        for (sc, args) in [(&seed, &SHORT[..]), (&three, &SHORT3[..])] {
            refused(
                gs(d).arg("run").arg(sc).args(args).args([flag, "blk"]),
                &[&format!("{flag} blk: is a block device")],
            );
            unchanged(&before, &snapshot(d), &format!("run {flag} blk"));
        }
    }
    for run in ["a.mcap", "c3.mcap"] {
        for args in [
            &["show", run, "--rrd", "blk"][..],
            &["check", run, "--json", "blk"][..],
        ] {
            refused(gs(d).arg("replay").args(args), &["blk: is a block device"]);
            unchanged(&before, &snapshot(d), &format!("replay {args:?}"));
        }
    }
    let m = std::fs::symlink_metadata(&blk).unwrap();
    assert!(
        m.file_type().is_block_device(),
        "the node stays a block device"
    );
}

// ---------------------------------------------------------------------------------------
// Item 15: a command that fails leaves what was there and no half set of new files.

/// A read-only folder `d/ro`: a read-only tmpfs as root (root may write into any folder of a
/// writable file system), mode 555 otherwise; None (printed) when neither can be made.
struct ReadOnly {
    path: PathBuf,
    mounted: bool,
}

impl ReadOnly {
    fn new(d: &Path) -> Option<Self> {
        let path = d.join("ro");
        std::fs::create_dir(&path).unwrap();
        if !is_root() {
            use std::os::unix::fs::PermissionsExt;
            std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o555)).unwrap();
            return Some(Self {
                path,
                mounted: false,
            });
        }
        let o = Command::new("mount")
            .args(["-t", "tmpfs", "-o", "ro,size=64k", "tmpfs"])
            .arg(&path)
            .output();
        match o {
            Ok(o) if o.status.success() => Some(Self {
                path,
                mounted: true,
            }),
            other => {
                eprintln!("skipped: cannot mount a read-only tmpfs: {other:?}");
                None
            }
        }
    }
}

impl Drop for ReadOnly {
    fn drop(&mut self) {
        if self.mounted {
            let _ = Command::new("umount").arg(&self.path).status();
        } else {
            use std::os::unix::fs::PermissionsExt;
            let _ = std::fs::set_permissions(&self.path, std::fs::Permissions::from_mode(0o755));
        }
    }
}

#[test]
fn item15_an_output_that_cannot_be_made_is_refused_before_the_run() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // Earlier results, and a file where a folder is wanted.
    std::fs::write(d.join("s.mcap"), b"an earlier recording").unwrap();
    std::fs::write(d.join("s.csv"), b"an earlier table").unwrap();
    std::fs::write(d.join("notadir"), b"a file").unwrap();
    let ro = ReadOnly::new(d);
    let before = snapshot(d);
    let seed = scenario("seed-grasp-r5");
    let three = scenario("3d-two-finger-sphere");
    for (sc, args) in [(&seed, &SHORT[..]), (&three, &SHORT3[..])] {
        refused(
            gs(d).arg("run").arg(sc).args(args).args([
                "--mcap",
                "s.mcap",
                "--csv",
                "s.csv",
                "--summary",
                "notadir/s.json",
            ]),
            &["--summary notadir/s.json", "notadir is not a folder"],
        );
        unchanged(&before, &snapshot(d), "--summary notadir/s.json");
        if ro.is_some() {
            refused(
                gs(d).arg("run").arg(sc).args(args).args([
                    "--mcap",
                    "s.mcap",
                    "--summary",
                    "ro/s.json",
                ]),
                &[
                    "--summary ro/s.json",
                    "cannot create a file in the folder ro",
                ],
            );
            unchanged(&before, &snapshot(d), "--summary ro/s.json");
            refused(
                gs(d).arg("run").arg(sc).args(args).args([
                    "--csv",
                    "s.csv",
                    "--rrd",
                    "ro/sub/s.rrd",
                ]),
                &[
                    "--rrd ro/sub/s.rrd",
                    "cannot create a file in the folder ro",
                ],
            );
            unchanged(&before, &snapshot(d), "--rrd ro/sub/s.rrd");
        }
    }
    // Replay: the .rrd cannot be made, so the report is not written either.
    record(d, "a.mcap", false);
    let before = snapshot(d);
    refused(
        gs(d).args([
            "replay",
            "check",
            "a.mcap",
            "--json",
            "s.json",
            "--rrd",
            "notadir/x.rrd",
        ]),
        &["--rrd notadir/x.rrd", "notadir is not a folder"],
    );
    unchanged(&before, &snapshot(d), "replay check --rrd notadir/x.rrd");
}

#[test]
fn item15_outputs_are_committed_together_and_a_failed_run_keeps_earlier_results() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let seed = scenario("seed-grasp-r5");
    // A good run: its table and summary under their final names.
    ok(gs(d).arg("run").arg(&seed).args(SHORT).args([
        "--csv",
        "results.csv",
        "--summary",
        "results.json",
    ]));
    let good = snapshot(d);
    assert_eq!(
        good.keys().cloned().collect::<Vec<_>>(),
        [PathBuf::from("results.csv"), PathBuf::from("results.json")]
    );
    // A re-run that diverges (a stiff prong, one Newton iteration, no back-off): exit 2, the
    // earlier results untouched, the failed run's files beside them under .partial names.
    let o = run_limited(
        gs(d).arg("run").arg(&seed).args([
            "-q",
            "--detail",
            "step",
            "--set",
            "rod.0.E=1e11",
            "--set",
            "solve.max_newton_iterations=1",
            "--set",
            "solve.max_backoff=0",
            "--csv",
            "results.csv",
            "--summary",
            "results.json",
        ]),
        LIMIT,
    );
    assert_eq!(o.status.code(), Some(2), "{}", out_text(&o));
    assert!(String::from_utf8_lossy(&o.stderr).contains("diverged at step"));
    let after = snapshot(d);
    for k in good.keys() {
        assert_eq!(after[k], good[k], "{} kept", k.display());
    }
    assert_eq!(
        after.keys().cloned().collect::<Vec<_>>(),
        [
            PathBuf::from("results.csv"),
            PathBuf::from("results.json"),
            PathBuf::from("results.partial.csv"),
            PathBuf::from("results.partial.json"),
        ]
    );
    let partial = std::fs::read_to_string(d.join("results.partial.csv")).unwrap();
    assert!(
        partial.lines().count() > 1000,
        "the failed run's rows are kept"
    );
    let summary: serde_json::Value =
        serde_json::from_slice(&std::fs::read(d.join("results.partial.json")).unwrap()).unwrap();
    assert_eq!(summary["completed"], false);

    // 3D: the same (two Newton iterations are not enough where the fingers land).
    let three = scenario("3d-two-finger-sphere");
    ok(gs(d)
        .arg("run")
        .arg(&three)
        .args(SHORT3)
        .args(["--csv", "f.csv"]));
    let good3 = std::fs::read(d.join("f.csv")).unwrap();
    let t3 = std::fs::metadata(d.join("f.csv"))
        .unwrap()
        .modified()
        .unwrap();
    let o = run_limited(
        gs(d).arg("run").arg(&three).args([
            "-q",
            "--set",
            "solve.max_newton_iterations=2",
            "--csv",
            "f.csv",
            "--summary",
            "f.json",
        ]),
        LIMIT,
    );
    assert_eq!(o.status.code(), Some(2), "{}", out_text(&o));
    assert_eq!(std::fs::read(d.join("f.csv")).unwrap(), good3);
    assert_eq!(
        std::fs::metadata(d.join("f.csv"))
            .unwrap()
            .modified()
            .unwrap(),
        t3
    );
    assert!(d.join("f.partial.csv").exists() && !d.join("f.json").exists());

    // A late failure (the summary goes to a device that takes no byte): none of the outputs
    // gets its final name; the earlier ones stay.
    let Some(full) = mknod(d, "full", false, 1, 7) else {
        return;
    };
    let before = snapshot(d);
    for (sc, args) in [(&seed, &SHORT[..]), (&three, &SHORT3[..])] {
        let o = run_limited(
            gs(d)
                .arg("run")
                .arg(sc)
                .args(args)
                .args(["--csv", "results.csv", "--summary", "full"]),
            LIMIT,
        );
        assert_eq!(o.status.code(), Some(2), "{}", out_text(&o));
        let stderr = String::from_utf8_lossy(&o.stderr);
        assert!(
            stderr.contains("full") && stderr.contains("os error 28"),
            "{stderr}"
        );
        let after = snapshot(d);
        for (k, v) in &before {
            if k != Path::new("results.partial.csv") {
                assert_eq!(&after[k], v, "{} kept", k.display());
            }
        }
        assert_eq!(after.len(), before.len(), "no new final file");
    }
    // Replay: the report is not committed when the .rrd fails; nothing of it is left.
    record(d, "a.mcap", false);
    std::fs::write(d.join("check.json"), b"an earlier report").unwrap();
    let before = snapshot(d);
    let o = run_limited(
        gs(d).args([
            "replay",
            "check",
            "a.mcap",
            "--json",
            "check.json",
            "--rrd",
            "full",
        ]),
        LIMIT,
    );
    assert_eq!(o.status.code(), Some(2), "{}", out_text(&o));
    unchanged(&before, &snapshot(d), "replay check --rrd full");
    assert!(full.exists());
}

// ---------------------------------------------------------------------------------------
// Item 16: a scenario is read once; a pipe works, a FIFO nobody writes to does not hang.

fn bash(dir: &Path, script: &str) -> Command {
    let mut c = Command::new("bash");
    c.current_dir(dir)
        .env("GRIPSIM", env!("CARGO_BIN_EXE_gripsim"))
        .env("SEED", scenario("seed-grasp-r5"))
        .env("THREE", scenario("3d-two-finger-sphere"))
        .args(["-c", script]);
    c
}

#[test]
fn item16_a_scenario_from_a_pipe_is_read_once() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // Process substitution: validate, run (planar and 3D) and sweep.
    let o = ok(&mut bash(d, "\"$GRIPSIM\" validate <(cat \"$SEED\")"));
    assert!(String::from_utf8_lossy(&o.stdout).contains("ok (\"seed-grasp-r5\""));
    let o = ok(&mut bash(d, "\"$GRIPSIM\" validate <(cat \"$THREE\")"));
    assert!(String::from_utf8_lossy(&o.stdout).contains("3D"));
    ok(&mut bash(
        d,
        "\"$GRIPSIM\" run <(cat \"$SEED\") -q --set solve.t_end=0.002 --no-record --summary s.json",
    ));
    ok(&mut bash(
        d,
        "\"$GRIPSIM\" run <(cat \"$THREE\") -q --set solve.t_end=0.002 --mcap t.mcap",
    ));
    let s: serde_json::Value =
        serde_json::from_slice(&std::fs::read(d.join("s.json")).unwrap()).unwrap();
    assert_eq!(s["scenario"], "seed-grasp-r5");
    assert!(s["steps"].as_u64().unwrap() > 100);
    // The 3D recording keeps the text read from the pipe: it replays.
    let o = run_limited(gs(d).args(["replay", "check", "t.mcap"]), LIMIT);
    assert!(matches!(o.status.code(), Some(0 | 1)), "{}", out_text(&o));
    ok(&mut bash(
        d,
        "\"$GRIPSIM\" sweep <(cat \"$SEED\") -q --set solve.t_end=0.002 --vary solve.dt=1e-5,2e-5 --no-plots --out sw",
    ));
    assert!(d.join("sw/summary.csv").exists());

    // A named FIFO whose writer comes later.
    let fifo = d.join("s.fifo");
    mkfifo(&fifo);
    let (f2, text) = (
        fifo.clone(),
        std::fs::read(scenario("seed-grasp-r5")).unwrap(),
    );
    let writer = std::thread::spawn(move || {
        std::thread::sleep(Duration::from_millis(300));
        let mut w = std::fs::OpenOptions::new().write(true).open(&f2).unwrap();
        w.write_all(&text).unwrap();
    });
    ok(gs(d).args(["validate", "s.fifo"]));
    writer.join().unwrap();

    // A FIFO nobody writes to: refused after the wait, not a hang.
    let before = snapshot(d);
    refused(
        gs(d).args(["validate", "s.fifo"]),
        &["s.fifo", "a FIFO that nobody wrote to within 5 s"],
    );
    refused(
        gs(d).args(["run", "s.fifo", "--csv", "x.csv"]),
        &["s.fifo", "nobody wrote to"],
    );
    unchanged(&before, &snapshot(d), "a FIFO nobody writes to");

    // A mesh that is /dev/zero or a FIFO: refused at once, nothing read.
    let m = tempfile::tempdir().unwrap();
    let md = m.path();
    let sc = mesh_scenario(md);
    let text = std::fs::read_to_string(&sc).unwrap();
    std::fs::write(&sc, text.replace("\"fruit.obj\"", "\"/dev/zero\"")).unwrap();
    refused(
        gs(md).args(["validate", "mesh.toml"]),
        &[
            "mesh.toml",
            "fruit.shape.file",
            "/dev/zero",
            "not a regular file",
        ],
    );
    mkfifo(&md.join("fifo.obj"));
    std::fs::write(&sc, text.replace("\"fruit.obj\"", "\"fifo.obj\"")).unwrap();
    refused(
        gs(md).args(["run", "mesh.toml", "--csv", "x.csv"]),
        &["mesh.toml", "fifo.obj", "not a regular file"],
    );
    assert!(!md.join("x.csv").exists() && !md.join("x.partial.csv").exists());
}

// ---------------------------------------------------------------------------------------
// sweep --out: a folder holding a summary.csv that no sweep wrote is refused.

#[test]
fn sweep_out_refuses_a_folder_with_a_summary_csv_of_its_own() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::create_dir(d.join("mine")).unwrap();
    std::fs::write(d.join("mine/summary.csv"), b"my own table\n").unwrap();
    let before = snapshot(d);
    let sweep = |out: &str| {
        let mut c = gs(d);
        c.arg("sweep")
            .arg(scenario("seed-grasp-r5"))
            .args([
                "-q",
                "--set",
                "solve.t_end=0.002",
                "--vary",
                "solve.dt=1e-5,2e-5",
            ])
            .args(["--no-plots", "--out", out]);
        c
    };
    refused(
        &mut sweep("mine"),
        &["--out mine", "summary.csv", "no sweep.json"],
    );
    unchanged(&before, &snapshot(d), "sweep --out mine");
    // A sweep folder is resumed as before: its summary.csv is the sweep's.
    ok(&mut sweep("study"));
    let first = snapshot(&d.join("study"));
    assert!(first.contains_key(Path::new("summary.csv")));
    ok(&mut sweep("study"));
    unchanged(&first, &snapshot(&d.join("study")), "a resumed sweep");
}
