//! First contact: what a new user sees first — the help of every command (each shows an
//! example), and errors that say how to fix them.

use crate::common::gripsim;
use std::path::Path;
use std::process::Output;

fn text(out: &Output) -> (String, String) {
    (
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// The subcommands listed under "Commands:" in a help text (without `help`).
fn subcommands(help: &str) -> Vec<String> {
    help.lines()
        .skip_while(|l| l.trim() != "Commands:")
        .skip(1)
        .take_while(|l| !l.trim().is_empty())
        .filter_map(|l| l.split_whitespace().next())
        .filter(|c| *c != "help")
        .map(str::to_string)
        .collect()
}

/// `gripsim --help` and the help of every subcommand, at every level (found by reading the
/// "Commands:" lists, so a new command is checked without touching this test), show an
/// example, with both `--help` and `-h`.
#[test]
fn every_command_help_shows_an_example() {
    let mut todo: Vec<Vec<String>> = vec![vec![]];
    let mut seen = Vec::new();
    while let Some(path) = todo.pop() {
        for flag in ["--help", "-h"] {
            let out = gripsim().args(&path).arg(flag).output().unwrap();
            let (stdout, stderr) = text(&out);
            assert!(
                out.status.success(),
                "gripsim {} {flag}: {}\n{stderr}",
                path.join(" "),
                out.status
            );
            assert!(
                stdout.contains("Example"),
                "gripsim {} {flag} shows no example:\n{stdout}",
                path.join(" ")
            );
            if flag == "--help" {
                for c in subcommands(&stdout) {
                    let mut next = path.clone();
                    next.push(c);
                    todo.push(next);
                }
            }
        }
        seen.push(path.join(" "));
    }
    for c in ["run", "validate", "scenarios", "bench"] {
        assert!(seen.iter().any(|s| s == c), "{c} not found in {seen:?}");
    }
}

/// A bare `gripsim` or a command without its file says what to type.
#[test]
fn missing_arguments_point_to_the_help() {
    for args in [&[][..], &["run"][..], &["validate"][..]] {
        let out = gripsim().args(args).output().unwrap();
        let (_, stderr) = text(&out);
        assert_eq!(out.status.code(), Some(2), "gripsim {args:?}");
        assert!(
            stderr.contains("Usage:") && stderr.contains("--help"),
            "gripsim {args:?}:\n{stderr}"
        );
    }
}

/// A mistyped scenario path or a run from the wrong folder names the file and the fix.
#[test]
fn common_first_mistakes_suggest_the_fix() {
    let out = gripsim()
        .args(["run", "scenarios/seed-grasp-r6.toml", "--no-record"])
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .unwrap();
    let (_, stderr) = text(&out);
    assert_eq!(out.status.code(), Some(2));
    assert!(
        stderr.contains("scenarios/seed-grasp-r6.toml")
            && stderr.contains("hint: did you mean scenarios/seed-grasp-r")
            && stderr.contains("gripsim scenarios"),
        "{stderr}"
    );
    // A bare name: without the folder and without .toml.
    let out = gripsim()
        .args(["validate", "seed-grasp-r5"])
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .unwrap();
    let (_, stderr) = text(&out);
    assert_eq!(out.status.code(), Some(2));
    assert!(
        stderr.contains("did you mean scenarios/seed-grasp-r5.toml?"),
        "{stderr}"
    );

    let dir = tempfile::tempdir().unwrap();
    let out = gripsim()
        .arg("scenarios")
        .current_dir(dir.path())
        .output()
        .unwrap();
    let (_, stderr) = text(&out);
    assert_eq!(out.status.code(), Some(2));
    assert!(stderr.contains("--dir"), "{stderr}");

    // The listing works from anywhere with --dir.
    let out = gripsim()
        .arg("scenarios")
        .arg("--dir")
        .arg(Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios"))
        .current_dir(dir.path())
        .output()
        .unwrap();
    let (stdout, _) = text(&out);
    assert!(out.status.success());
    assert!(stdout.contains("seed-grasp-r5.toml"), "{stdout}");
}

/// `gripsim run ... | head -2` (or `gripsim scenarios | head`): the reader goes away before the
/// summary is printed. That panicked ("failed printing to stdout: Broken pipe", exit 101); the
/// output is now simply cut, and the exit status is the run's.
#[test]
fn a_closed_stdout_is_not_a_panic() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    for args in [
        vec![
            "run".to_string(),
            root.join("scenarios/seed-grasp-r5.toml")
                .display()
                .to_string(),
            "--no-record".to_string(),
        ],
        vec![
            "scenarios".to_string(),
            "--dir".to_string(),
            root.join("scenarios").display().to_string(),
        ],
    ] {
        let mut child = gripsim()
            .args(&args)
            .stdout(std::process::Stdio::piped())
            .stderr(std::process::Stdio::piped())
            .spawn()
            .unwrap();
        // Close the reading end before anything is printed.
        drop(child.stdout.take());
        let out = child.wait_with_output().unwrap();
        let (_, stderr) = text(&out);
        assert!(!stderr.contains("panicked"), "gripsim {args:?}:\n{stderr}");
        assert_eq!(out.status.code(), Some(0), "gripsim {args:?}:\n{stderr}");
    }
}
