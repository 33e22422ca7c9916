//! The file layer under faults (issue 15): outputs at devices, symlinks and shared paths, a
//! full disk, memory over long runs, oversized inputs, signals and a killed run. Each test
//! names the item it covers; docs/robustness.md ("The file layer under faults") lists
//! them. Tests that need root powers (mknod, mount) skip with a printed reason without them.

use crate::common::{gripsim, scenario};
use std::io::Read as _;
use std::os::unix::fs::FileTypeExt;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// What a finished child did: exit code (None when a signal ended it), stdout, stderr and its
/// peak resident memory (VmHWM of /proc/PID/status, read every few ms while it runs; the
/// kernel keeps the high-water mark, so only a peak in its last few ms could be missed.
/// wait4's ru_maxrss would count the forked copy of this test process before exec).
struct Ran {
    code: Option<i32>,
    stdout: String,
    stderr: String,
    peak_mb: f64,
}

impl std::fmt::Debug for Ran {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "exit {:?}, peak {:.1} MB\nstdout:\n{}\nstderr:\n{}",
            self.code, self.peak_mb, self.stdout, self.stderr
        )
    }
}

/// Run `cmd` to its end, or kill it after `limit` (a hang guard, not a timing: the test then
/// fails because the process hung). The child is reaped by `waitpid` below, not `Child::wait`.
#[allow(clippy::zombie_processes)]
fn run(cmd: &mut Command, limit: Duration) -> Ran {
    let mut child = cmd
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("gripsim starts");
    let pid = child.id() as libc::pid_t;
    let mut out = child.stdout.take().unwrap();
    let mut err = child.stderr.take().unwrap();
    let o = std::thread::spawn(move || {
        let mut s = String::new();
        let _ = out.read_to_string(&mut s);
        s
    });
    let e = std::thread::spawn(move || {
        let mut s = String::new();
        let _ = err.read_to_string(&mut s);
        s
    });
    let start = Instant::now();
    let mut status = 0;
    let mut hung = false;
    let mut peak_kb = 0u64;
    loop {
        if let Ok(s) = std::fs::read_to_string(format!("/proc/{pid}/status")) {
            // Only once the child runs gripsim (before exec it is a copy of this process).
            if s.lines()
                .any(|l| l.split_whitespace().eq(["Name:", "gripsim"]))
            {
                let hwm = s
                    .lines()
                    .find_map(|l| l.strip_prefix("VmHWM:"))
                    .and_then(|v| v.split_whitespace().next()?.parse::<u64>().ok());
                peak_kb = peak_kb.max(hwm.unwrap_or(0));
            }
        }
        // SAFETY: waitpid on our own child's pid.
        let r = unsafe { libc::waitpid(pid, &mut status, libc::WNOHANG) };
        if r == pid {
            break;
        }
        assert!(r == 0, "waitpid failed");
        if start.elapsed() > limit && !hung {
            hung = true;
            unsafe { libc::kill(pid, libc::SIGKILL) };
        }
        std::thread::sleep(Duration::from_millis(3));
    }
    let ran = Ran {
        code: libc::WIFEXITED(status).then(|| libc::WEXITSTATUS(status)),
        stdout: o.join().unwrap(),
        stderr: e.join().unwrap(),
        peak_mb: peak_kb as f64 / 1024.0,
    };
    assert!(
        !hung,
        "{cmd:?} did not end within {limit:?} (hung): {ran:?}"
    );
    ran
}

const LIMIT: Duration = Duration::from_secs(120);

/// A character device made in `dir` (`mknod`), or None with a printed reason.
fn mknod(dir: &Path, name: &str, major: u32, minor: u32) -> Option<PathBuf> {
    let p = dir.join(name);
    let c = std::ffi::CString::new(p.to_str().unwrap()).unwrap();
    // SAFETY: a path we own, a plain mode and device number.
    let r = unsafe {
        libc::mknod(
            c.as_ptr(),
            libc::S_IFCHR | 0o666,
            libc::makedev(major, minor),
        )
    };
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

fn is_char_device(p: &Path) -> bool {
    std::fs::symlink_metadata(p).is_ok_and(|m| m.file_type().is_char_device())
}

/// The single `error:` line of a failed command.
fn error_line(r: &Ran) -> String {
    let lines: Vec<&str> = r
        .stderr
        .lines()
        .filter(|l| l.starts_with("error:"))
        .collect();
    assert_eq!(lines.len(), 1, "one error line expected: {r:?}");
    lines[0].to_string()
}

fn files_in(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

/// Seed grasp, short.
fn short_run() -> Command {
    let mut c = gripsim();
    c.arg("run").arg(scenario("seed-grasp-r5")).args([
        "-q",
        "--detail",
        "step",
        "--set",
        "solve.t_end=0.002",
    ]);
    c
}

// ---------------------------------------------------------------------------------------
// Item 1: outputs are written through devices and symlinks, never renamed over them.

#[test]
fn item1_a_device_at_an_output_path_is_written_through_not_replaced() {
    let dir = tempfile::tempdir().unwrap();
    let Some(null) = mknod(dir.path(), "null", 1, 3) else {
        return;
    };
    // Every output of `run` at the device (one character device may take several).
    let r = run(
        short_run()
            .arg("--rrd")
            .arg(&null)
            .arg("--mcap")
            .arg(&null)
            .arg("--csv")
            .arg(&null)
            .arg("--summary")
            .arg(&null),
        LIMIT,
    );
    assert_eq!(r.code, Some(0), "{r:?}");
    assert!(is_char_device(&null), "the device was replaced");
    assert_eq!(files_in(dir.path()), ["null"], "no .partial file left");

    // `replay show --rrd` and `replay check --json` at the device (write_atomic and the
    // .rrd sink of replay go through the same OutputFile).
    let mcap = dir.path().join("r.mcap");
    let r = run(short_run().arg("--mcap").arg(&mcap), LIMIT);
    assert_eq!(r.code, Some(0), "{r:?}");
    let r = run(
        gripsim()
            .args(["replay", "show"])
            .arg(&mcap)
            .arg("--rrd")
            .arg(&null),
        LIMIT,
    );
    assert_eq!(r.code, Some(0), "{r:?}");
    assert!(is_char_device(&null), "replay show replaced the device");
    let r = run(
        gripsim()
            .args(["replay", "check"])
            .arg(&mcap)
            .arg("--json")
            .arg(&null),
        LIMIT,
    );
    assert!(matches!(r.code, Some(0 | 1)), "{r:?}");
    assert!(
        is_char_device(&null),
        "replay check --json replaced the device"
    );
    assert_eq!(files_in(dir.path()), ["null", "r.mcap"]);
}

#[test]
fn item1_a_symlink_at_an_output_path_stays_a_symlink_to_the_new_file() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let real = d.join("real.mcap");
    std::fs::write(&real, b"old contents").unwrap();
    let link = d.join("link.mcap");
    std::os::unix::fs::symlink(&real, &link).unwrap();
    let r = run(short_run().arg("--mcap").arg(&link), LIMIT);
    assert_eq!(r.code, Some(0), "{r:?}");
    assert!(
        std::fs::symlink_metadata(&link)
            .unwrap()
            .file_type()
            .is_symlink(),
        "the symlink was replaced"
    );
    let bytes = std::fs::read(&real).unwrap();
    assert_eq!(
        &bytes[..8],
        b"\x89MCAP0\r\n",
        "the linked file holds the new run"
    );
    assert_eq!(files_in(d), ["link.mcap", "real.mcap"]);

    // A symlink that leads nowhere is refused before the run (writing through it would
    // create a file somewhere else).
    let dangling = d.join("dangling.csv");
    std::os::unix::fs::symlink(d.join("nowhere/x.csv"), &dangling).unwrap();
    let r = run(short_run().arg("--csv").arg(&dangling), LIMIT);
    assert_eq!(r.code, Some(2), "{r:?}");
    assert!(
        error_line(&r).contains("symlink that leads nowhere"),
        "{r:?}"
    );
}

#[test]
fn item1_writing_to_a_full_device_fails_with_exit_2() {
    let dir = tempfile::tempdir().unwrap();
    let Some(full) = mknod(dir.path(), "full", 1, 7) else {
        return;
    };
    for flag in ["--rrd", "--mcap", "--csv", "--summary"] {
        let r = run(short_run().arg(flag).arg(&full), LIMIT);
        assert_eq!(r.code, Some(2), "{flag}: {r:?}");
        let e = error_line(&r);
        assert!(
            e.contains(&*full.to_string_lossy()),
            "{flag}: names the file: {e}"
        );
        assert!(
            e.contains("No space left on device") || e.contains("os error 28"),
            "{flag}: says why: {e}"
        );
        assert!(is_char_device(&full), "{flag}: the device was replaced");
    }
    assert_eq!(files_in(dir.path()), ["full"]);
}

// ---------------------------------------------------------------------------------------
// Item 2: a full disk ends the run with an error, never a hang.

/// A 300 kB tmpfs mounted on a fresh folder, unmounted on drop; None (with a printed reason)
/// where mounting is not permitted.
struct SmallDisk {
    dir: tempfile::TempDir,
}

impl SmallDisk {
    fn new() -> Option<Self> {
        let dir = tempfile::tempdir().ok()?;
        let out = Command::new("mount")
            .args(["-t", "tmpfs", "-o", "size=300k", "tmpfs"])
            .arg(dir.path())
            .output();
        match out {
            Ok(o) if o.status.success() => Some(Self { dir }),
            Ok(o) => {
                eprintln!(
                    "skipped: cannot mount a small tmpfs: {}",
                    String::from_utf8_lossy(&o.stderr).trim()
                );
                None
            }
            Err(e) => {
                eprintln!("skipped: cannot run mount: {e}");
                None
            }
        }
    }

    fn path(&self) -> &Path {
        self.dir.path()
    }
}

impl Drop for SmallDisk {
    fn drop(&mut self) {
        let _ = Command::new("umount").arg(self.dir.path()).status();
    }
}

#[test]
fn item2_a_full_disk_ends_the_run_with_an_error_and_closes_the_rest() {
    let Some(disk) = SmallDisk::new() else {
        return;
    };
    let side = tempfile::tempdir().unwrap();
    // 30 000 steps write MBs: the 300 kB disk fills early in the run.
    for (k, flag) in ["--rrd", "--rrd", "--rrd", "--mcap", "--csv"]
        .iter()
        .enumerate()
    {
        let ext = &flag[2..];
        let full = disk.path().join(format!("run{k}.{ext}"));
        let ok = side.path().join(format!("other{k}.mcap"));
        let other = if *flag == "--mcap" { "--csv" } else { "--mcap" };
        let ok = if *flag == "--mcap" {
            ok.with_extension("csv")
        } else {
            ok
        };
        let r = run(
            gripsim()
                .arg("run")
                .arg(scenario("seed-grasp-r5"))
                .args([
                    "-q",
                    "--detail",
                    "step",
                    "--set",
                    "solve.t_end=0.3",
                    "--flush-every",
                    "20",
                ])
                .arg(flag)
                .arg(&full)
                .arg(other)
                .arg(&ok),
            LIMIT,
        );
        assert_eq!(r.code, Some(2), "{flag}: {r:?}");
        let e = error_line(&r);
        assert!(e.contains(&format!("run{k}.partial.{ext}")), "{flag}: {e}");
        // The other output was closed properly (it keeps its .partial name: the run stopped).
        let partial = side.path().join(format!(
            "other{k}.partial.{}",
            ok.extension().unwrap().to_string_lossy()
        ));
        let bytes = std::fs::read(&partial).unwrap_or_else(|e| panic!("{flag}: {e}: {r:?}"));
        if other == "--mcap" {
            assert_eq!(
                &bytes[bytes.len() - 8..],
                b"\x89MCAP0\r\n",
                "{flag}: mcap closed"
            );
        } else {
            assert_eq!(
                bytes.last(),
                Some(&b'\n'),
                "{flag}: csv ends with a whole row"
            );
        }
        let _ = std::fs::remove_file(disk.path().join(format!("run{k}.partial.{ext}")));
    }
}

// ---------------------------------------------------------------------------------------
// Item 3: the .rrd writer's memory does not grow with the run.

#[test]
fn item3_memory_stays_flat_over_a_long_run() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let peak = |steps: u64| {
        let t_end = format!("solve.t_end={}", steps as f64 * 1e-5);
        let r = run(
            gripsim()
                .arg("run")
                .arg(scenario("seed-grasp-r5"))
                .args(["-q", "--detail", "step", "--set", &t_end, "--rrd"])
                .arg(d.join(format!("{steps}.rrd")))
                .arg("--mcap")
                .arg(d.join(format!("{steps}.mcap")))
                .arg("--csv")
                .arg(d.join(format!("{steps}.csv"))),
            LIMIT,
        );
        assert_eq!(r.code, Some(0), "{r:?}");
        let rrd = std::fs::metadata(d.join(format!("{steps}.rrd")))
            .unwrap()
            .len();
        eprintln!(
            "{steps} steps: peak {:.1} MB, .rrd {:.1} MB",
            r.peak_mb,
            rrd as f64 / 1e6
        );
        r.peak_mb
    };
    let short = peak(3_000);
    let long = peak(30_000);
    // Before: 25 MB at 6 000 steps, 105 MB at 60 000 (the .rrd footer index grew with every
    // chunk: ~60 MB at 30 000 steps). Now the index is dropped past FOOTER_CHUNKS (2 048
    // chunks, ~16 000 steps since the columnar logging: 16.6 MB at 3 000 steps, 19.8 MB at
    // 30 000; with 8 192 chunks the index grew to 45 MB at 60 000 steps).
    assert!(long < 45.0, "peak memory {long:.1} MB at 30 000 steps");
    assert!(
        long - short < 15.0,
        "peak memory grew from {short:.1} MB to {long:.1} MB"
    );
}

// ---------------------------------------------------------------------------------------
// Item 4: two outputs on one path, or an output on an input, are refused before the run.

#[test]
fn item4_outputs_on_one_path_or_on_an_input_are_refused_before_the_run() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let sc = d.join("scen.toml");
    std::fs::copy(scenario("seed-grasp-r5"), &sc).unwrap();
    let text = std::fs::read(&sc).unwrap();
    std::fs::hard_link(&sc, d.join("hard.toml")).unwrap();
    std::os::unix::fs::symlink(d.join("a.mcap"), d.join("link.mcap")).unwrap();
    let cases: &[(&[&str], &str)] = &[
        (
            &["--rrd", "same.out", "--mcap", "same.out"],
            "--mcap same.out and --rrd same.out",
        ),
        (
            &["--mcap", "a.mcap", "--csv", "./a.mcap"],
            "--csv ./a.mcap and --mcap a.mcap",
        ),
        (
            &["--mcap", "a.mcap", "--csv", "sub/../a.mcap"],
            "--csv sub/../a.mcap and --mcap a.mcap",
        ),
        (
            &["--mcap", "a.mcap", "--csv", "link.mcap"],
            "--csv link.mcap and --mcap a.mcap",
        ),
        (&["--csv", "X", "--summary", "X"], "--summary X and --csv X"),
        (
            &["--csv", "scen.toml"],
            "--csv scen.toml and the scenario scen.toml (an input)",
        ),
        (
            &["--csv", "hard.toml"],
            "--csv hard.toml and the scenario scen.toml (an input)",
        ),
        // One output's .partial file is another's final name.
        (
            &["--rrd", "x.rrd", "--mcap", "x.partial.rrd"],
            "--mcap x.partial.rrd and --rrd x.rrd",
        ),
    ];
    std::fs::create_dir(d.join("sub")).unwrap();
    for (args, names) in cases {
        let r = run(
            gripsim()
                .current_dir(d)
                .args(["run", "scen.toml", "-q"])
                .args(*args),
            LIMIT,
        );
        assert_eq!(r.code, Some(2), "{args:?}: {r:?}");
        let e = error_line(&r);
        assert!(e.contains(names), "{args:?}: {e}");
        assert!(e.contains("same file"), "{args:?}: {e}");
        assert_eq!(
            files_in(d),
            ["hard.toml", "link.mcap", "scen.toml", "sub"],
            "{args:?}: nothing written"
        );
        assert_eq!(
            std::fs::read(&sc).unwrap(),
            text,
            "the scenario is untouched"
        );
    }
}

// ---------------------------------------------------------------------------------------
// Item 5: an output at a directory is refused, nothing is left behind.

#[test]
fn item5_summary_at_a_directory_is_refused_and_leaves_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::create_dir(d.join("DIR")).unwrap();
    for flag in ["--summary", "--rrd", "--mcap", "--csv"] {
        let r = run(short_run().arg(flag).arg(d.join("DIR")), LIMIT);
        assert_eq!(r.code, Some(2), "{flag}: {r:?}");
        assert!(error_line(&r).contains("is a directory"), "{flag}: {r:?}");
        assert_eq!(files_in(d), ["DIR"], "{flag}: nothing left behind");
        assert!(files_in(&d.join("DIR")).is_empty());
    }
}

// ---------------------------------------------------------------------------------------
// Item 7: inputs are capped before they are read or built.

#[test]
fn item7_an_endless_scenario_file_is_refused_after_16_mib() {
    for cmd in ["validate", "run"] {
        let r = run(gripsim().args([cmd, "/dev/zero"]), LIMIT);
        assert_eq!(r.code, Some(2), "{r:?}");
        let e = error_line(&r);
        assert!(
            e.contains("/dev/zero") && e.contains("larger than 16 MiB"),
            "{e}"
        );
        // Before: 5.4 GB in 8 s and growing.
        assert!(r.peak_mb < 100.0, "read {:.1} MB", r.peak_mb);
    }
    let dir = tempfile::tempdir().unwrap();
    let r = run(
        gripsim()
            .args([
                "sweep",
                "/dev/zero",
                "--vary",
                "solve.dt=1e-5,2e-5",
                "--out",
            ])
            .arg(dir.path().join("s")),
        LIMIT,
    );
    assert_eq!(r.code, Some(2), "{r:?}");
    assert!(error_line(&r).contains("larger than 16 MiB"), "{r:?}");
}

#[test]
fn item7_a_huge_sweep_grid_is_refused_before_it_is_built() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("s");
    // 1e4 x 1e4 = 1e8 cases (before: 1.9 GB before a word).
    let r = run(
        gripsim()
            .arg("sweep")
            .arg(scenario("seed-grasp-r5"))
            .args([
                "--vary",
                "obstacle.0.radius=0.01:0.05:10000",
                "--vary",
                "rod.0.E=1e5:1e7:10000",
                "--out",
            ])
            .arg(&out),
        LIMIT,
    );
    assert_eq!(r.code, Some(2), "{r:?}");
    let e = error_line(&r);
    assert!(e.contains("10000 x 10000 = 1.000e8 cases"), "{e}");
    assert!(r.peak_mb < 100.0, "{:.1} MB", r.peak_mb);
    assert!(!out.exists());
    // One range of 1e8 values: refused while the arguments are read.
    let r = run(
        gripsim()
            .arg("sweep")
            .arg(scenario("seed-grasp-r5"))
            .args(["--vary", "rod.0.E=1e5:1e7:100000000", "--out"])
            .arg(&out),
        LIMIT,
    );
    assert_eq!(r.code, Some(2), "{r:?}");
    assert!(
        r.stderr
            .contains("COUNT 100000000 is more than a sweep takes"),
        "{r:?}"
    );
    assert!(r.peak_mb < 100.0, "{:.1} MB", r.peak_mb);
}

#[test]
fn item7_a_large_grid_is_checked_with_progress_and_stops_on_sigterm() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("s");
    // 1e5 cases: checking them all takes minutes; SIGTERM must stop it at once.
    let mut child = gripsim()
        .arg("sweep")
        .arg(scenario("seed-grasp-r5"))
        .args([
            "--vary",
            "obstacle.0.radius=0.01:0.05:1000",
            "--vary",
            "rod.0.E=1e5:1e7:100",
            "--out",
        ])
        .arg(&out)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // Wait for the first progress line (after 2 s of checking), then SIGTERM.
    let mut err = child.stderr.take().unwrap();
    let mut seen = Vec::new();
    let mut buf = [0u8; 256];
    while !String::from_utf8_lossy(&seen).contains("checking the grid") {
        let n = err.read(&mut buf).unwrap();
        assert!(
            n > 0,
            "no progress line: {}",
            String::from_utf8_lossy(&seen)
        );
        seen.extend_from_slice(&buf[..n]);
    }
    unsafe { libc::kill(child.id() as libc::pid_t, libc::SIGTERM) };
    let start = Instant::now();
    let status = loop {
        if let Some(s) = child.try_wait().unwrap() {
            break s;
        }
        // A hang guard (it ignored SIGTERM for 213 s before), not a timing.
        assert!(start.elapsed() < Duration::from_secs(60), "SIGTERM ignored");
        std::thread::sleep(Duration::from_millis(20));
    };
    let _ = err.read_to_end(&mut seen);
    let stderr = String::from_utf8_lossy(&seen);
    assert_eq!(status.code(), Some(143), "{stderr}");
    assert!(stderr.contains("interrupted by SIGTERM"), "{stderr}");
    assert!(
        !out.join("sweep.json").exists(),
        "nothing written before the grid was checked"
    );
}

// ---------------------------------------------------------------------------------------
// Item 8: the smaller ones.

fn validate(args: &[&str]) -> Ran {
    run(
        gripsim()
            .arg("validate")
            .arg(scenario("seed-grasp-r5"))
            .args(args),
        LIMIT,
    )
}

fn refused(args: &[&str], wants: &[&str]) {
    let r = validate(args);
    assert_eq!(r.code, Some(2), "{args:?}: {r:?}");
    let e = error_line(&r);
    for w in wants {
        assert!(e.contains(w), "{args:?}: wants {w:?}: {e}");
    }
}

#[test]
fn item8_misspelt_mass_keys_are_named() {
    let dir = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(scenario("seed-grasp-r5")).unwrap();
    for (typo, right) in [
        ("densty = 1000.0", "density"),
        ("node_mas = 0.01", "node_mass"),
    ] {
        let p = dir.path().join("t.toml");
        std::fs::write(&p, text.replace("node_mass = 0.01", typo)).unwrap();
        let r = run(gripsim().arg("validate").arg(&p), LIMIT);
        assert_eq!(r.code, Some(2), "{r:?}");
        let e = error_line(&r);
        let key = typo.split(' ').next().unwrap();
        assert!(e.contains(&format!("key `rod.0.{key}`")), "{e}");
        assert!(e.contains("unknown key"), "{e}");
        assert!(e.contains(&format!("did you mean `{right}`")), "{e}");
    }
}

#[test]
fn item8_multi_line_set_values_and_datetimes() {
    refused(
        &["--set", "solve.t_end=0.01\nsolve.dt=1"],
        &["--set solve.t_end=0.01\\nsolve.dt=1", "must be on one line"],
    );
    refused(
        &["--set", "solve.t_end=1979-05-27T07:32:00Z"],
        &[
            "= 1979-05-27T07:32:00Z",
            "expected a number, found a datetime",
        ],
    );
    let r = validate(&["--set", "solve.gravity=[1979-05-27, 0.0]"]);
    assert!(!r.stderr.contains("toml_private"), "{r:?}");
    assert!(r.stderr.contains("[1979-05-27, 0.0]"), "{r:?}");
}

#[test]
fn item8_solve_checks_with_any_stepping() {
    // dt_near is checked with fixed stepping too (the scenario has stepping = "fixed").
    refused(
        &["--set", "solve.dt_near=1e-4"],
        &["solve.dt_near", "larger than dt"],
    );
    refused(
        &["--set", "solve.dt_near=1e-20"],
        &["solve.dt_near", "too small"],
    );
    // Adaptive stepping has a step-count limit through dt_min.
    refused(
        &[
            "--set",
            "solve.stepping=adaptive",
            "--set",
            "solve.dt_min=1e-300",
        ],
        &["solve.dt_min", "too small: t_end / dt_min"],
    );
    // Non-physical magnitudes.
    refused(
        &["--set", "solve.gravity=[0.0, -1e308]"],
        &["solve.gravity", "not physical"],
    );
    refused(
        &["--set", "rod.0.drive.acceleration=[1e308, 0.0]"],
        &["rod.0.drive.acceleration", "not physical"],
    );
    refused(
        &["--set", "rod.0.loads=[{ node = 5, force = [0.0, 1e308] }]"],
        &["rod.0.loads.0.force", "not physical"],
    );
    // Names that are only dots.
    refused(&["--set", "name=."], &["key `name`", "letter or digit"]);
    refused(&["--set", "name=.."], &["key `name`", "letter or digit"]);
}

/// A scenario that runs as long as we like (stopped by a signal).
fn long_scenario(dir: &Path) -> PathBuf {
    let p = dir.join("long.toml");
    let text = std::fs::read_to_string(scenario("seed-grasp-r5"))
        .unwrap()
        .replace("t_end = 0.06", "t_end = 100.0");
    std::fs::write(&p, text).unwrap();
    p
}

fn wait_for_size(path: &Path, bytes: u64, child: &mut std::process::Child) {
    let start = Instant::now();
    while std::fs::metadata(path).map(|m| m.len()).unwrap_or(0) < bytes {
        if let Some(s) = child.try_wait().unwrap() {
            panic!("the run ended ({s}) before {} grew", path.display());
        }
        assert!(
            start.elapsed() < Duration::from_secs(60),
            "{} did not grow",
            path.display()
        );
        std::thread::sleep(Duration::from_millis(5));
    }
}

#[test]
fn item8_sighup_closes_the_files_like_sigterm() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let sc = long_scenario(d);
    let mut child = gripsim()
        .arg("run")
        .arg(&sc)
        .args(["-q", "--detail", "step", "--mcap"])
        .arg(d.join("h.mcap"))
        .arg("--csv")
        .arg(d.join("h.csv"))
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    wait_for_size(&d.join("h.partial.mcap"), 200_000, &mut child);
    unsafe { libc::kill(child.id() as libc::pid_t, libc::SIGHUP) };
    let out = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(129), "{stderr}");
    assert!(stderr.contains("by SIGHUP"), "{stderr}");
    let mcap = std::fs::read(d.join("h.partial.mcap")).unwrap();
    assert_eq!(
        &mcap[mcap.len() - 8..],
        b"\x89MCAP0\r\n",
        "the MCAP was closed"
    );
    let csv = std::fs::read(d.join("h.partial.csv")).unwrap();
    assert_eq!(csv.last(), Some(&b'\n'));
}

#[test]
fn item8_a_killed_run_leaves_whole_csv_rows() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let sc = long_scenario(d);
    for (k, size) in [300_000u64, 1_100_000, 2_500_000].into_iter().enumerate() {
        let csv = d.join(format!("k{k}.csv"));
        let mut child = gripsim()
            .arg("run")
            .arg(&sc)
            .args(["-q", "--detail", "step", "--flush-every", "7", "--csv"])
            .arg(&csv)
            .stdout(Stdio::null())
            .spawn()
            .unwrap();
        let partial = d.join(format!("k{k}.partial.csv"));
        wait_for_size(&partial, size, &mut child);
        child.kill().unwrap(); // SIGKILL
        child.wait().unwrap();
        let text = std::fs::read_to_string(&partial).unwrap();
        assert!(
            text.ends_with('\n'),
            "the last row is cut: {:?}",
            &text[text.len() - 80..]
        );
        let header = text.lines().next().unwrap().split(',').count();
        // 19 columns, 4 of a compliant contact (indentation, half-width, peak pressure,
        // bruise half-width) and the obstacle of the row's contact.
        assert_eq!(header, 24);
        // Whole rows, each with every column; steps in order with one row per node (10
        // nodes), the last step possibly incomplete (the kill may come between two rows).
        assert!(text.lines().all(|l| l.split(',').count() == header));
        let steps: Vec<u64> = text
            .lines()
            .skip(1)
            .map(|l| l.split(',').next().unwrap().parse().unwrap())
            .collect();
        assert!(steps.len() > 10);
        for (k, s) in steps.iter().enumerate() {
            assert_eq!(*s, (k / 10) as u64, "row {k}");
        }
    }
}

/// A 3D run (`dimension = 3`) follows the planar file rules: every output at a device is
/// written through (the device stays), a symlinked output stays a symlink to the new file,
/// and a run that fails keeps its files under their `.partial` names with the error as the
/// run's end (exit 2): `replay check` reads it, says the run failed and exits 3.
#[test]
fn item1_3d_runs_follow_the_same_file_rules() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let run3 = |sets: &[&str]| {
        let mut c = gripsim();
        c.arg("run").arg(scenario("3d-two-finger-sphere")).arg("-q");
        for s in sets {
            c.args(["--set", s]);
        }
        c
    };
    if let Some(null) = mknod(d, "null", 1, 3) {
        let mut c = run3(&["solve.t_end=0.002"]);
        for flag in ["--rrd", "--mcap", "--csv", "--summary"] {
            c.arg(flag).arg(&null);
        }
        let r = run(&mut c, LIMIT);
        assert_eq!(r.code, Some(0), "{r:?}");
        assert!(is_char_device(&null), "the device was replaced");
        assert_eq!(files_in(d), ["null"], "no .partial file left");
        std::fs::remove_file(&null).unwrap();
    }
    let real = d.join("real.mcap");
    std::fs::write(&real, b"old contents").unwrap();
    let link = d.join("link.mcap");
    std::os::unix::fs::symlink(&real, &link).unwrap();
    let r = run(run3(&["solve.t_end=0.002"]).arg("--mcap").arg(&link), LIMIT);
    assert_eq!(r.code, Some(0), "{r:?}");
    assert!(std::fs::symlink_metadata(&link)
        .unwrap()
        .file_type()
        .is_symlink());
    assert_eq!(&std::fs::read(&real).unwrap()[..8], b"\x89MCAP0\r\n");
    assert_eq!(files_in(d), ["link.mcap", "real.mcap"]);

    // Two Newton iterations are not enough where the fingers land.
    let mut c = run3(&["solve.max_newton_iterations=2"]);
    for (flag, name) in [("--rrd", "f.rrd"), ("--mcap", "f.mcap"), ("--csv", "f.csv")] {
        c.arg(flag).arg(d.join(name));
    }
    let r = run(&mut c, LIMIT);
    assert_eq!(r.code, Some(2), "{r:?}");
    let e = error_line(&r);
    println!("{e}");
    assert!(e.contains("Newton did not converge"), "{e}");
    assert!(
        e.contains("f.partial.mcap") && e.contains("f.partial.rrd"),
        "{e}"
    );
    assert_eq!(
        files_in(d),
        [
            "f.partial.csv",
            "f.partial.mcap",
            "f.partial.rrd",
            "link.mcap",
            "real.mcap"
        ]
    );
    // The failing step is the one after the last recorded.
    let failed: u64 = e
        .split("step ")
        .nth(1)
        .and_then(|x| x.split_whitespace().next())
        .and_then(|x| x.parse().ok())
        .expect("the error names the step");
    let report = d.join("check.json");
    let r = run(
        gripsim()
            .args(["replay", "check"])
            .arg(d.join("f.partial.mcap"))
            .arg("--json")
            .arg(&report),
        LIMIT,
    );
    assert_eq!(r.code, Some(3), "{r:?}");
    assert!(r.stdout.contains("the run ended early: step"), "{r:?}");
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    assert_eq!(v["completed"], false);
    assert_eq!(v["steps"].as_u64(), Some(failed - 1));
    assert!(v["run_error"]
        .as_str()
        .is_some_and(|x| x.contains("Newton did not converge")));
    let csv = std::fs::read_to_string(d.join("f.partial.csv")).unwrap();
    let last = csv.lines().last().unwrap();
    assert!(last.starts_with(&format!("{},", failed - 1)), "{last}");
}

/// SIGTERM stops a 3D run after the current step as it does a planar one: exit 143, the
/// files closed under their `.partial` names (the MCAP with its footer and a run end that
/// says "interrupted at step N"), `replay check` reads them and exits 3.
#[test]
fn item8_sigterm_closes_a_3d_runs_files() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let mut child = gripsim()
        .arg("run")
        .arg(scenario("3d-lift"))
        .args(["-q", "--mcap"])
        .arg(d.join("l.mcap"))
        .arg("--csv")
        .arg(d.join("l.csv"))
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    wait_for_size(&d.join("l.partial.mcap"), 200_000, &mut child);
    unsafe { libc::kill(child.id() as libc::pid_t, libc::SIGTERM) };
    let out = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(143), "{stderr}");
    assert!(stderr.contains("by SIGTERM"), "{stderr}");
    let mcap = std::fs::read(d.join("l.partial.mcap")).unwrap();
    assert_eq!(
        &mcap[mcap.len() - 8..],
        b"\x89MCAP0\r\n",
        "the MCAP was closed"
    );
    let csv = std::fs::read(d.join("l.partial.csv")).unwrap();
    assert_eq!(csv.last(), Some(&b'\n'));
    let r = run(
        gripsim()
            .args(["replay", "check"])
            .arg(d.join("l.partial.mcap")),
        LIMIT,
    );
    assert_eq!(r.code, Some(3), "{r:?}");
    assert!(r.stdout.contains("interrupted at step"), "{r:?}");
}
