//! Bad scenario input, one class per test: every case runs the built `gripsim` binary on a small
//! scenario (a valid base with one thing broken) and checks that it exits with code 2, prints
//! exactly one `error:` line that names the file, the key path and the offending value, does
//! not panic, and leaves no files behind.

use std::ffi::OsString;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// A valid minimal scenario; every test breaks it in one way.
const BASE: &str = r#"name = "bad-input-base"
description = "a valid minimal scenario that each test breaks in one way"

[solve]
mode = "dynamic"
t_end = 0.002
dt = 0.001
stepping = "fixed"
gravity = [0.0, -9.8]

[[rod]]
name = "prong"
nodes = 5
E = 1e6
density = 1000.0
clamped = [0, 1]
velocity = [0.0, 0.0]
shape = { kind = "straight", start = [0.0, 0.0], end = [0.1, 0.0] }
section = { kind = "rect", b = 0.02, h = 0.01 }
drive = { kind = "constant_velocity", velocity = [0.0, -0.01], stop_time = 0.001 }
loads = [{ node = 4, force = [0.0, -0.1] }]

[[obstacle]]
kind = "circle"
center = [0.05, -0.2]
radius = 0.05

[output]
flush_every = 10
"#;

/// BASE with `from` (which must occur exactly once) replaced by `to`.
fn edit(from: &str, to: &str) -> String {
    edit_text(BASE, from, to)
}

fn edit_text(text: &str, from: &str, to: &str) -> String {
    assert_eq!(
        text.matches(from).count(),
        1,
        "the base scenario should hold {from:?} exactly once"
    );
    text.replacen(from, to, 1)
}

/// BASE with a second obstacle (`obstacle.1`) appended.
fn with_obstacle(body: &str) -> String {
    format!("{BASE}\n[[obstacle]]\n{body}\n")
}

/// A scenario file in a fresh temporary directory, which is also the working directory of the
/// commands run on it (so anything they write would show up there).
struct Case {
    dir: tempfile::TempDir,
    path: PathBuf,
}

impl Case {
    fn new(bytes: &[u8]) -> Case {
        let dir = tempfile::tempdir().expect("temp dir");
        let path = dir.path().join("case.toml");
        std::fs::write(&path, bytes).expect("write scenario");
        Case { dir, path }
    }

    fn run(&self, command: &str, extra: &[&str], sets: &[&str]) -> Output {
        let mut args: Vec<OsString> = vec![command.into(), self.path.clone().into()];
        args.extend(extra.iter().map(OsString::from));
        for s in sets {
            args.push("--set".into());
            args.push(OsString::from(s));
        }
        gripsim(self.dir.path(), &args)
    }

    /// Nothing but the scenario in the directory.
    fn assert_untouched(&self) {
        let names = listing(self.dir.path());
        assert_eq!(names, vec!["case.toml".to_string()], "files left behind");
    }
}

fn gripsim(cwd: &Path, args: &[OsString]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_gripsim"))
        .args(args)
        .current_dir(cwd)
        .output()
        .expect("run gripsim")
}

fn listing(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .expect("list dir")
        .map(|e| {
            e.expect("dir entry")
                .file_name()
                .to_string_lossy()
                .into_owned()
        })
        .collect();
    names.sort();
    names
}

/// Checks a failed command: exit code 2, no panic, one `error:` line naming `file`.
fn failure(out: &Output, file: &str) -> String {
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(!err.contains("panicked"), "gripsim panicked:\n{err}");
    assert_eq!(out.status.code(), Some(2), "exit code; stderr:\n{err}");
    assert!(err.starts_with("error: "), "stderr: {err}");
    assert_eq!(
        err.trim_end().lines().count(),
        1,
        "one line expected:\n{err}"
    );
    assert!(err.contains(file), "stderr does not name {file}: {err}");
    err
}

/// `gripsim validate` on the bytes (with `--set`s) must fail cleanly; returns stderr.
fn reject_bytes(bytes: &[u8], sets: &[&str]) -> String {
    let case = Case::new(bytes);
    let out = case.run("validate", &[], sets);
    let err = failure(&out, &case.path.display().to_string());
    assert!(out.stdout.is_empty(), "stdout on failure: {:?}", out.stdout);
    case.assert_untouched();
    err
}

fn reject(text: &str) -> String {
    reject_bytes(text.as_bytes(), &[])
}

fn reject_set(text: &str, sets: &[&str]) -> String {
    reject_bytes(text.as_bytes(), sets)
}

/// `gripsim run` on the text must fail cleanly without writing anything (not even the
/// requested summary); returns stderr.
fn reject_run(text: &str) -> String {
    let case = Case::new(text.as_bytes());
    let out = case.run("run", &["--summary", "summary.json"], &[]);
    let err = failure(&out, &case.path.display().to_string());
    case.assert_untouched();
    err
}

fn has(err: &str, parts: &[&str]) {
    for p in parts {
        assert!(err.contains(p), "expected {p:?} in:\n{err}");
    }
}

/// "key `path` = value:" as the error line writes it.
fn kv(path: &str, value: &str) -> String {
    format!("key `{path}` = {value}: ")
}

/// "key `path`:" for a key with no value (a missing key).
fn k(path: &str) -> String {
    format!("key `{path}`: ")
}

fn missing(path: &str) -> String {
    format!("key `{path}`: missing required key")
}

fn did_you_mean(key: &str) -> String {
    format!("did you mean `{key}`?")
}

// ---------------------------------------------------------------------------------------------
// The base and the shipped scenarios are valid.

#[test]
fn base_scenario_is_valid() {
    let case = Case::new(BASE.as_bytes());
    let out = case.run("validate", &[], &[]);
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    case.assert_untouched();
}

#[test]
fn every_shipped_scenario_validates_and_leaves_no_files() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios");
    let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)
        .expect("scenarios dir")
        .map(|e| e.expect("entry").path())
        .filter(|p| p.extension().is_some_and(|x| x == "toml"))
        .collect();
    files.sort();
    assert!(
        files.len() >= 5,
        "expected the shipped scenarios, found {files:?}"
    );
    let cwd = tempfile::tempdir().expect("temp dir");
    for f in &files {
        let before = listing(&dir);
        let out = gripsim(cwd.path(), &["validate".into(), f.clone().into()]);
        assert_eq!(
            out.status.code(),
            Some(0),
            "{}: {}",
            f.display(),
            String::from_utf8_lossy(&out.stderr)
        );
        assert!(
            String::from_utf8_lossy(&out.stdout).contains(": ok ("),
            "{}",
            f.display()
        );
        assert!(out.stderr.is_empty(), "{}: stderr not empty", f.display());
        assert!(
            listing(cwd.path()).is_empty(),
            "validate wrote into the cwd"
        );
        assert_eq!(listing(&dir), before, "validate wrote next to the scenario");
    }
}

// ---------------------------------------------------------------------------------------------
// Unknown keys.

#[test]
fn unknown_top_level_key_did_you_mean() {
    let err = reject(&edit(
        "description = ",
        "descripton = \"typo\"\ndescription = ",
    ));
    has(
        &err,
        &[
            &kv("descripton", "\"typo\""),
            "unknown key",
            &did_you_mean("description"),
        ],
    );
}

#[test]
fn unknown_top_level_table_did_you_mean() {
    let err = reject(&edit("[output]", "[outptu]"));
    has(
        &err,
        &[
            "key `outptu` = { flush_every = 10 }",
            "unknown key",
            &did_you_mean("output"),
        ],
    );
}

#[test]
fn misspelt_required_key_is_reported_as_the_typo() {
    // `nmae` instead of `name`: the typo is named, not just "name is missing".
    let err = reject(&edit(
        "name = \"bad-input-base\"",
        "nmae = \"bad-input-base\"",
    ));
    has(
        &err,
        &[
            &kv("nmae", "\"bad-input-base\""),
            "unknown key",
            &did_you_mean("name"),
        ],
    );
}

#[test]
fn unknown_key_in_solve() {
    let err = reject(&edit("dt = 0.001\n", "dt = 0.001\nt_ned = 1.0\n"));
    has(
        &err,
        &[
            &kv("solve.t_ned", "1.0"),
            "unknown key",
            &did_you_mean("t_end"),
        ],
    );
}

#[test]
fn unknown_key_in_rod() {
    let err = reject(&edit(
        "density = 1000.0\n",
        "density = 1000.0\ndenstiy = 5\n",
    ));
    has(
        &err,
        &[
            &kv("rod.0.denstiy", "5"),
            "unknown key",
            &did_you_mean("density"),
        ],
    );
}

#[test]
fn unknown_key_in_shape() {
    let err = reject(&edit(
        "end = [0.1, 0.0] }",
        "end = [0.1, 0.0], lenght = 0.1 }",
    ));
    has(
        &err,
        &[
            &kv("rod.0.shape.lenght", "0.1"),
            "unknown key",
            &did_you_mean("length"),
        ],
    );
}

#[test]
fn shape_key_of_another_kind() {
    // `length` belongs to a parabola, not to a straight shape.
    let err = reject(&edit(
        "end = [0.1, 0.0] }",
        "end = [0.1, 0.0], length = 0.1 }",
    ));
    has(
        &err,
        &[
            &kv("rod.0.shape.length", "0.1"),
            "not used when kind = \"straight\"",
        ],
    );
}

#[test]
fn unknown_key_in_section() {
    let err = reject(&edit("h = 0.01 }", "h = 0.01, hh = 0.01 }"));
    has(
        &err,
        &[
            &kv("rod.0.section.hh", "0.01"),
            "unknown key",
            "did you mean",
        ],
    );
}

#[test]
fn unknown_key_in_drive() {
    let err = reject(&edit("stop_time = 0.001 }", "stop_tim = 0.001 }"));
    has(
        &err,
        &[
            &kv("rod.0.drive.stop_tim", "0.001"),
            "unknown key",
            &did_you_mean("stop_time"),
        ],
    );
}

#[test]
fn drive_key_of_another_kind() {
    // A fixed drive does not stop: stop_time means nothing there.
    let err = reject(&edit(
        "drive = { kind = \"constant_velocity\", velocity = [0.0, -0.01], stop_time = 0.001 }",
        "drive = { kind = \"fixed\", stop_time = 0.001 }",
    ));
    has(
        &err,
        &[
            &kv("rod.0.drive.stop_time", "0.001"),
            "not used when kind = \"fixed\"",
        ],
    );
}

#[test]
fn unknown_key_in_load() {
    let err = reject(&edit(
        "force = [0.0, -0.1] }",
        "force = [0.0, -0.1], torque = 1.0 }",
    ));
    has(&err, &[&kv("rod.0.loads.0.torque", "1.0"), "unknown key"]);
}

#[test]
fn unknown_key_in_output() {
    let err = reject(&edit("flush_every = 10", "flush_every = 10\nflush = 5"));
    has(&err, &[&kv("output.flush", "5"), "unknown key"]);
}

#[test]
fn unknown_key_in_circle_obstacle() {
    let err = reject(&edit("center = [0.05, -0.2]", "centre = [0.05, -0.2]"));
    has(
        &err,
        &[
            &kv("obstacle.0.centre", "[0.05, -0.2]"),
            "unknown key for a circle obstacle",
            &did_you_mean("center"),
        ],
    );
}

#[test]
fn key_of_another_obstacle_kind() {
    let err = reject(&with_obstacle(
        "kind = \"plane\"\npoint = [0.0, -1.0]\nnormal = [0.0, 1.0]\nradius = 0.05",
    ));
    has(
        &err,
        &[
            &kv("obstacle.1.radius", "0.05"),
            "unknown key for a plane obstacle",
            "a plane takes: kind, point, normal",
        ],
    );
}

#[test]
fn unknown_key_in_particle() {
    let text = edit(
        "[[obstacle]]",
        "[[particle]]\nname = \"ball\"\nposition = [0.0, 1.0]\nmass = 0.01\nmas = 0.02\n\n[[obstacle]]",
    );
    let err = reject(&text);
    has(&err, &[&kv("particle.0.mas", "0.02"), "unknown key"]);
}

// ---------------------------------------------------------------------------------------------
// Missing required keys.

#[test]
fn missing_name() {
    let err = reject(&edit("name = \"bad-input-base\"\n", ""));
    has(&err, &[&missing("name")]);
}

#[test]
fn missing_solve() {
    let text = edit(
        "[solve]\nmode = \"dynamic\"\nt_end = 0.002\ndt = 0.001\nstepping = \"fixed\"\ngravity = [0.0, -9.8]\n",
        "",
    );
    let err = reject(&text);
    has(&err, &[&missing("solve")]);
}

#[test]
fn missing_t_end() {
    let err = reject(&edit("t_end = 0.002\n", ""));
    has(&err, &[&missing("solve.t_end")]);
}

#[test]
fn missing_dt() {
    let err = reject(&edit("dt = 0.001\n", ""));
    has(&err, &[&missing("solve.dt")]);
}

#[test]
fn missing_rod() {
    let start = BASE.find("[[rod]]").unwrap();
    let end = BASE.find("[[obstacle]]").unwrap();
    let text = format!("{}{}", &BASE[..start], &BASE[end..]);
    let err = reject(&text);
    has(&err, &[&missing("rod"), "[[rod]]"]);
}

#[test]
fn misspelt_rod_array() {
    let err = reject(&edit("[[rod]]", "[[rods]]"));
    has(
        &err,
        &["key `rods` = [{", "unknown key", &did_you_mean("rod")],
    );
}

#[test]
fn missing_points_of_a_points_shape() {
    let err = reject(&edit(
        "shape = { kind = \"straight\", start = [0.0, 0.0], end = [0.1, 0.0] }",
        "shape = { kind = \"points\", point = [[0.0, 0.0]] }",
    ));
    has(
        &err,
        &[
            &kv("rod.0.shape.point", "[[0.0, 0.0]]"),
            "unknown key",
            &did_you_mean("points"),
        ],
    );
}

#[test]
fn missing_nodes() {
    let err = reject(&edit("nodes = 5\n", ""));
    has(&err, &[&missing("rod.0.nodes")]);
}

#[test]
fn missing_youngs_modulus() {
    let err = reject(&edit("E = 1e6\n", ""));
    has(&err, &[&missing("rod.0.E")]);
}

#[test]
fn missing_density_and_node_mass() {
    let err = reject(&edit("density = 1000.0\n", ""));
    has(&err, &[&missing("rod.0.density"), "node_mass"]);
}

#[test]
fn missing_shape() {
    let err = reject(&edit(
        "shape = { kind = \"straight\", start = [0.0, 0.0], end = [0.1, 0.0] }\n",
        "",
    ));
    has(&err, &[&missing("rod.0.shape")]);
}

#[test]
fn missing_shape_kind() {
    let err = reject(&edit("shape = { kind = \"straight\", ", "shape = { "));
    has(&err, &[&missing("rod.0.shape.kind")]);
}

#[test]
fn missing_section_kind() {
    let err = reject(&edit("section = { kind = \"rect\", ", "section = { "));
    has(&err, &[&missing("rod.0.section.kind")]);
}

#[test]
fn missing_obstacle_radius() {
    let err = reject(&edit("radius = 0.05\n", ""));
    has(&err, &[&missing("obstacle.0.radius")]);
}

#[test]
fn missing_obstacle_kind() {
    let err = reject(&edit("kind = \"circle\"\n", ""));
    has(&err, &[&missing("obstacle.0.kind")]);
}

#[test]
fn missing_drive_velocity() {
    let err = reject(&edit("velocity = [0.0, -0.01], ", ""));
    has(&err, &[&missing("rod.0.drive.velocity")]);
}

#[test]
fn missing_near_distance_with_proximity_stepping() {
    let err = reject(&edit(
        "stepping = \"fixed\"",
        "stepping = \"proximity\"\ndt_near = 0.0001",
    ));
    has(&err, &[&missing("solve.near_distance")]);
}

// ---------------------------------------------------------------------------------------------
// Wrong types.

#[test]
fn string_for_number() {
    let err = reject(&edit("E = 1e6", "E = \"1e6\""));
    has(
        &err,
        &[
            &kv("rod.0.E", "\"1e6\""),
            "expected a number, found a string",
        ],
    );
}

#[test]
fn number_for_string() {
    let err = reject(&edit("name = \"prong\"", "name = 42"));
    has(
        &err,
        &[
            &kv("rod.0.name", "42"),
            "expected a string, found an integer",
        ],
    );
}

#[test]
fn float_for_integer() {
    let err = reject(&edit("nodes = 5", "nodes = 5.5"));
    has(
        &err,
        &[
            &kv("rod.0.nodes", "5.5"),
            "expected an integer, found a float",
        ],
    );
}

#[test]
fn three_components_for_a_2d_vector() {
    let err = reject(&edit("gravity = [0.0, -9.8]", "gravity = [0.0, -9.8, 0.0]"));
    has(
        &err,
        &[
            &kv("solve.gravity", "[0.0, -9.8, 0.0]"),
            "expected a 2D vector [x, y], found 3 elements",
        ],
    );
}

#[test]
fn string_inside_a_2d_vector() {
    let err = reject(&edit("velocity = [0.0, 0.0]", "velocity = [0.0, \"up\"]"));
    has(
        &err,
        &[
            &kv("rod.0.velocity", "[0.0, \"up\"]"),
            "expected a number, found a string",
        ],
    );
}

#[test]
fn table_for_array() {
    let err = reject(&edit("clamped = [0, 1]", "clamped = { first = 0 }"));
    has(
        &err,
        &[
            &kv("rod.0.clamped", "{ first = 0 }"),
            "expected an array, found a table",
        ],
    );
}

#[test]
fn table_for_array_of_rods() {
    let err = reject(&edit("[[rod]]", "[rod]"));
    has(
        &err,
        &["key `rod` = {", "expected an array of [[rod]] tables"],
    );
}

#[test]
fn number_for_table() {
    let err = reject(&edit(
        "section = { kind = \"rect\", b = 0.02, h = 0.01 }",
        "section = 0.01",
    ));
    has(
        &err,
        &[
            &kv("rod.0.section", "0.01"),
            "expected a table, found a float",
        ],
    );
}

#[test]
fn boolean_for_number() {
    let err = reject(&edit("t_end = 0.002", "t_end = true"));
    has(
        &err,
        &[
            &kv("solve.t_end", "true"),
            "expected a number, found a boolean",
        ],
    );
}

// ---------------------------------------------------------------------------------------------
// Non-finite numbers.

#[test]
fn nan_number() {
    let err = reject(&edit("E = 1e6", "E = nan"));
    has(&err, &[&kv("rod.0.E", "nan"), "must be a finite number"]);
}

#[test]
fn infinite_number() {
    let err = reject(&edit("t_end = 0.002", "t_end = inf"));
    has(
        &err,
        &[&kv("solve.t_end", "inf"), "must be a finite number"],
    );
}

#[test]
fn nan_inside_a_vector() {
    let err = reject(&edit("force = [0.0, -0.1]", "force = [nan, -0.1]"));
    has(
        &err,
        &[
            &kv("rod.0.loads.0.force", "[nan, -0.1]"),
            "must be a finite number",
        ],
    );
}

#[test]
fn negative_infinity_in_obstacle() {
    let err = reject(&edit("center = [0.05, -0.2]", "center = [-inf, -0.2]"));
    has(
        &err,
        &[
            &kv("obstacle.0.center", "[-inf, -0.2]"),
            "must be a finite number",
        ],
    );
}

// ---------------------------------------------------------------------------------------------
// Zero or negative where a positive number is needed.

#[test]
fn zero_youngs_modulus() {
    let err = reject(&edit("E = 1e6", "E = 0"));
    has(&err, &[&kv("rod.0.E", "0"), "must be greater than zero"]);
}

#[test]
fn negative_youngs_modulus() {
    let err = reject(&edit("E = 1e6", "E = -2.5e6"));
    has(
        &err,
        &[&kv("rod.0.E", "-2500000.0"), "must be greater than zero"],
    );
}

#[test]
fn zero_density() {
    let err = reject(&edit("density = 1000.0", "density = 0.0"));
    has(
        &err,
        &[&kv("rod.0.density", "0.0"), "must be greater than zero"],
    );
}

#[test]
fn negative_node_mass() {
    let err = reject(&edit("density = 1000.0", "node_mass = -0.01"));
    has(
        &err,
        &[&kv("rod.0.node_mass", "-0.01"), "must be greater than zero"],
    );
}

#[test]
fn zero_dt() {
    let err = reject(&edit("dt = 0.001", "dt = 0"));
    has(&err, &[&kv("solve.dt", "0"), "must be greater than zero"]);
}

#[test]
fn negative_t_end() {
    let err = reject(&edit("t_end = 0.002", "t_end = -1.0"));
    has(
        &err,
        &[&kv("solve.t_end", "-1.0"), "must be greater than zero"],
    );
}

#[test]
fn zero_section_b() {
    let err = reject(&edit("b = 0.02", "b = 0.0"));
    has(
        &err,
        &[&kv("rod.0.section.b", "0.0"), "must be greater than zero"],
    );
}

#[test]
fn negative_section_h() {
    let err = reject(&edit("h = 0.01", "h = -0.01"));
    has(
        &err,
        &[&kv("rod.0.section.h", "-0.01"), "must be greater than zero"],
    );
}

#[test]
fn zero_section_radius() {
    let err = reject(&edit(
        "section = { kind = \"rect\", b = 0.02, h = 0.01 }",
        "section = { kind = \"circle\", radius = 0 }",
    ));
    has(
        &err,
        &[
            &kv("rod.0.section.radius", "0"),
            "must be greater than zero",
        ],
    );
}

#[test]
fn zero_circle_radius() {
    let err = reject(&edit("radius = 0.05", "radius = 0.0"));
    has(
        &err,
        &[&kv("obstacle.0.radius", "0.0"), "must be greater than zero"],
    );
}

#[test]
fn negative_circle_radius() {
    let err = reject(&edit("radius = 0.05", "radius = -0.05"));
    has(
        &err,
        &[
            &kv("obstacle.0.radius", "-0.05"),
            "must be greater than zero",
        ],
    );
}

#[test]
fn zero_shape_length() {
    let err = reject(&edit(
        "shape = { kind = \"straight\", start = [0.0, 0.0], end = [0.1, 0.0] }",
        "shape = { kind = \"parabola\", x0 = 0.0, y0 = 0.0, a = 0.8, length = 0.0 }",
    ));
    has(
        &err,
        &[
            &kv("rod.0.shape.length", "0.0"),
            "must be greater than zero",
        ],
    );
}

#[test]
fn negative_stop_time() {
    let err = reject(&edit("stop_time = 0.001", "stop_time = -0.001"));
    has(
        &err,
        &[
            &kv("rod.0.drive.stop_time", "-0.001"),
            "must be greater than zero",
        ],
    );
}

#[test]
fn zero_flush_every() {
    let err = reject(&edit("flush_every = 10", "flush_every = 0"));
    has(
        &err,
        &[&kv("output.flush_every", "0"), "must be at least 1"],
    );
}

#[test]
fn unknown_precision() {
    let err = reject(&edit(
        "flush_every = 10",
        "flush_every = 10\nprecision = \"f16\"",
    ));
    has(
        &err,
        &[
            &kv("output.precision", "\"f16\""),
            "unknown precision",
            "\"f32\" or \"f64\"",
        ],
    );
}

#[test]
fn solver_limits_out_of_range() {
    let err = reject(&edit(
        "gravity = [0.0, -9.8]",
        "gravity = [0.0, -9.8]\nmax_newton_iterations = 0",
    ));
    has(
        &err,
        &[
            &kv("solve.max_newton_iterations", "0"),
            "must be at least 1",
        ],
    );
    let err = reject(&edit(
        "gravity = [0.0, -9.8]",
        "gravity = [0.0, -9.8]\nmax_backoff = 4294967296",
    ));
    has(
        &err,
        &[&kv("solve.max_backoff", "4294967296"), "unreasonably large"],
    );
    let err = reject(&edit(
        "gravity = [0.0, -9.8]",
        "gravity = [0.0, -9.8]\nload_step = 1.5",
    ));
    has(&err, &[&kv("solve.load_step", "1.5"), "must be in (0, 1]"]);
}

// ---------------------------------------------------------------------------------------------
// Nodes, clamps and loads.

#[test]
fn fewer_than_three_nodes() {
    let err = reject(&edit("nodes = 5", "nodes = 2"));
    has(&err, &[&kv("rod.0.nodes", "2"), "at least 3 nodes"]);
}

#[test]
fn negative_node_count() {
    let err = reject(&edit("nodes = 5", "nodes = -5"));
    has(&err, &[&kv("rod.0.nodes", "-5"), "non-negative integer"]);
}

#[test]
fn clamped_node_out_of_range() {
    let err = reject(&edit("clamped = [0, 1]", "clamped = [0, 5]"));
    has(
        &err,
        &[
            &kv("rod.0.clamped.1", "5"),
            "node index out of range",
            "0..4",
        ],
    );
}

#[test]
fn duplicate_clamped_node() {
    let err = reject(&edit("clamped = [0, 1]", "clamped = [0, 1, 0]"));
    has(&err, &[&kv("rod.0.clamped.2", "0"), "node listed twice"]);
}

#[test]
fn every_node_clamped() {
    let err = reject(&edit("clamped = [0, 1]", "clamped = [0, 1, 2, 3, 4]"));
    has(
        &err,
        &[
            &kv("rod.0.clamped", "[0, 1, 2, 3, 4]"),
            "every node is clamped",
        ],
    );
}

#[test]
fn load_node_out_of_range() {
    let err = reject(&edit("{ node = 4,", "{ node = 9,"));
    has(
        &err,
        &[&kv("rod.0.loads.0.node", "9"), "node index out of range"],
    );
}

#[test]
fn load_on_a_clamped_node() {
    let err = reject(&edit("{ node = 4,", "{ node = 1,"));
    has(
        &err,
        &[&kv("rod.0.loads.0.node", "1"), "a load on a clamped node"],
    );
}

#[test]
fn duplicate_rod_names() {
    let second = &BASE[BASE.find("[[rod]]").unwrap()..BASE.find("[[obstacle]]").unwrap()];
    let text = edit("[[obstacle]]", &format!("{second}[[obstacle]]"));
    let err = reject(&text);
    has(
        &err,
        &[&kv("rod.1.name", "\"prong\""), "duplicate name", "rod.0"],
    );
}

#[test]
fn particle_with_the_name_of_a_rod() {
    let text = edit(
        "[[obstacle]]",
        "[[particle]]\nname = \"prong\"\nposition = [0.0, 1.0]\nmass = 0.01\n\n[[obstacle]]",
    );
    let err = reject(&text);
    has(
        &err,
        &[
            &kv("particle.0.name", "\"prong\""),
            "duplicate name",
            "rod.0",
        ],
    );
}

#[test]
fn points_count_differs_from_nodes() {
    let err = reject(&edit(
        "shape = { kind = \"straight\", start = [0.0, 0.0], end = [0.1, 0.0] }",
        "shape = { kind = \"points\", points = [[0.0, 0.0], [0.05, 0.0], [0.1, 0.0]] }",
    ));
    has(
        &err,
        &[
            &kv(
                "rod.0.shape.points",
                "[[0.0, 0.0], [0.05, 0.0], [0.1, 0.0]]",
            ),
            "has 3 points but the rod has nodes = 5",
        ],
    );
}

#[test]
fn points_shape_with_a_bad_point() {
    let err = reject(&edit(
        "shape = { kind = \"straight\", start = [0.0, 0.0], end = [0.1, 0.0] }",
        "shape = { kind = \"points\", points = [[0.0, 0.0], [0.02, 0.0], [0.04, 0.0, 1.0], [0.06, 0.0], [0.08, 0.0]] }",
    ));
    has(
        &err,
        &[
            &kv("rod.0.shape.points.2", "[0.04, 0.0, 1.0]"),
            "found 3 elements",
        ],
    );
}

#[test]
fn zero_length_edge() {
    let err = reject(&edit("end = [0.1, 0.0]", "end = [0.0, 0.0]"));
    has(
        &err,
        &[
            &kv("rod.0.shape", "[0.0, 0.0]"),
            "nodes 0 and 1 coincide (zero-length edge)",
        ],
    );
}

#[test]
fn rest_shape_folds_back() {
    let err = reject(&edit(
        "shape = { kind = \"straight\", start = [0.0, 0.0], end = [0.1, 0.0] }",
        "shape = { kind = \"points\", points = [[0.0, 0.0], [0.02, 0.0], [0.04, 0.0], [0.02, 0.001], [0.0, 0.002]] }",
    ));
    has(
        &err,
        &[
            &kv("rod.0.shape", "[0.04, 0.0]"),
            "turns by 90° or more at node 2",
        ],
    );
}

#[test]
fn shape_that_overflows() {
    let err = reject(&edit(
        "shape = { kind = \"straight\", start = [0.0, 0.0], end = [0.1, 0.0] }",
        "shape = { kind = \"parabola\", x0 = 0.0, y0 = 0.0, a = 1e300, length = 1e10 }",
    ));
    has(&err, &["key `rod.0.shape` = node 0 at [inf", "not finite"]);
}

// ---------------------------------------------------------------------------------------------
// Time stepping.

#[test]
fn dt_larger_than_t_end() {
    let err = reject(&edit("dt = 0.001", "dt = 0.01"));
    has(
        &err,
        &[&kv("solve.dt", "0.01"), "is larger than t_end = 0.002"],
    );
}

#[test]
fn dt_near_larger_than_dt() {
    let err = reject(&edit(
        "stepping = \"fixed\"",
        "stepping = \"proximity\"\ndt_near = 0.005\nnear_distance = 0.001",
    ));
    has(
        &err,
        &[&kv("solve.dt_near", "0.005"), "is larger than dt = 0.001"],
    );
}

#[test]
fn dt_too_small_for_t_end() {
    // 2e-3 / 1e-15 = 2e12 steps: a run that would never finish.
    let err = reject(&edit("dt = 0.001", "dt = 1e-15"));
    has(
        &err,
        &[&kv("solve.dt", "1e-15"), "is too small", "2.000e12 steps"],
    );
}

#[test]
fn dt_near_too_small_for_t_end() {
    let err = reject(&edit(
        "stepping = \"fixed\"",
        "stepping = \"proximity\"\ndt_near = 1e-15\nnear_distance = 0.001",
    ));
    has(
        &err,
        &[
            &kv("solve.dt_near", "1e-15"),
            "is too small",
            "2.000e12 steps",
        ],
    );
}

#[test]
fn dt_min_larger_than_dt_max() {
    let err = reject(&edit(
        "stepping = \"fixed\"",
        "stepping = \"adaptive\"\ndt_min = 0.0005\ndt_max = 0.0001",
    ));
    has(
        &err,
        &[
            &kv("solve.dt_min", "0.0005"),
            "is larger than dt_max = 0.0001",
        ],
    );
}

#[test]
fn adaptive_first_step_outside_its_bounds() {
    let err = reject(&edit(
        "stepping = \"fixed\"",
        "stepping = \"adaptive\"\ndt_min = 1e-6\ndt_max = 0.0005",
    ));
    has(
        &err,
        &[&kv("solve.dt", "0.001"), "is outside [dt_min, dt_max]"],
    );
}

// ---------------------------------------------------------------------------------------------
// Unknown kinds.

#[test]
fn unknown_mode_did_you_mean() {
    let err = reject(&edit("mode = \"dynamic\"", "mode = \"dinamic\""));
    has(
        &err,
        &[
            &kv("solve.mode", "\"dinamic\""),
            "unknown mode",
            "did you mean \"dynamic\"?",
        ],
    );
}

#[test]
fn unknown_stepping_did_you_mean() {
    let err = reject(&edit("stepping = \"fixed\"", "stepping = \"proximty\""));
    has(
        &err,
        &[
            &kv("solve.stepping", "\"proximty\""),
            "unknown stepping",
            "did you mean \"proximity\"?",
        ],
    );
}

#[test]
fn unknown_stepping_far_from_any() {
    // Nothing is close to "runge-kutta": the hint lists the steppings instead.
    let err = reject(&edit("stepping = \"fixed\"", "stepping = \"runge-kutta\""));
    has(
        &err,
        &[
            &kv("solve.stepping", "\"runge-kutta\""),
            "unknown stepping",
            "(hint: use \"fixed\", ",
        ],
    );
    assert!(!err.contains("did you mean"), "{err}");
}

#[test]
fn unknown_shape_kind_did_you_mean() {
    let err = reject(&edit("kind = \"straight\"", "kind = \"straigth\""));
    has(
        &err,
        &[
            &kv("rod.0.shape.kind", "\"straigth\""),
            "unknown shape kind",
            "did you mean \"straight\"?",
        ],
    );
}

#[test]
fn unknown_section_kind_did_you_mean() {
    let err = reject(&edit("kind = \"rect\"", "kind = \"rec\""));
    has(
        &err,
        &[
            &kv("rod.0.section.kind", "\"rec\""),
            "unknown section kind",
            "did you mean \"rect\"?",
        ],
    );
}

#[test]
fn unknown_drive_kind_did_you_mean() {
    let err = reject(&edit(
        "kind = \"constant_velocity\"",
        "kind = \"constant_velocty\"",
    ));
    has(
        &err,
        &[
            &kv("rod.0.drive.kind", "\"constant_velocty\""),
            "unknown drive kind",
            "did you mean \"constant_velocity\"?",
        ],
    );
}

#[test]
fn unknown_obstacle_kind_did_you_mean() {
    let err = reject(&edit("kind = \"circle\"", "kind = \"circel\""));
    has(
        &err,
        &[
            &kv("obstacle.0.kind", "\"circel\""),
            "unknown obstacle kind",
            "did you mean \"circle\"?",
        ],
    );
}

// ---------------------------------------------------------------------------------------------
// Geometry: rods inside obstacles, degenerate obstacles.

#[test]
fn rod_starts_inside_an_obstacle() {
    // Node 2 of the rod sits at the centre of a 1 cm disc: 1 cm deep.
    let err = reject(&with_obstacle(
        "kind = \"circle\"\ncenter = [0.05, 0.0]\nradius = 0.01",
    ));
    has(
        &err,
        &[
            "key `rod.0.shape` = node 2 at [0.05, 0]",
            "rod \"prong\" node 2's face starts 1.500e-2 m inside obstacle.1 (circle)",
        ],
    );
}

#[test]
fn rod_starts_below_a_sine_surface() {
    // Solid below y = A sin(kx) + c; c = 0.005 puts the whole rod 5 mm under it.
    let err = reject(&with_obstacle(
        "kind = \"sine\"\namplitude = 0.0\nwavenumber = 10.0\noffset = 0.005",
    ));
    has(
        &err,
        &[
            "key `rod.0.shape` = node 0 at [0, 0]",
            "rod \"prong\" node 0's face starts 1.000e-2 m inside obstacle.1 (sine)",
        ],
    );
}

#[test]
fn particle_starts_inside_a_plane() {
    let text = edit(
        "[[obstacle]]",
        "[[particle]]\nname = \"ball\"\nposition = [0.5, -0.5]\nmass = 0.01\n\n[[obstacle]]",
    );
    let text = format!(
        "{text}\n[[obstacle]]\nkind = \"plane\"\npoint = [0.0, -0.4]\nnormal = [0.0, 2.0]\n"
    );
    let err = reject(&text);
    has(
        &err,
        &[
            "key `particle.0.position` = node 0 at [0.5, -0.5]",
            "particle \"ball\" node 0 starts 1.000e-1 m inside obstacle.1 (plane)",
        ],
    );
}

#[test]
fn polygon_with_collinear_vertices() {
    let err = reject(&with_obstacle(
        "kind = \"polygon\"\nvertices = [[0.0, 1.0], [1.0, 1.0], [2.0, 1.0]]",
    ));
    has(
        &err,
        &[
            &kv(
                "obstacle.1.vertices",
                "[[0.0, 1.0], [1.0, 1.0], [2.0, 1.0]]",
            ),
            "degenerate polygon: zero area",
        ],
    );
}

#[test]
fn polygon_that_intersects_itself() {
    let err = reject(&with_obstacle(
        "kind = \"polygon\"\nvertices = [[0.0, 1.0], [2.0, 3.0], [2.0, 1.0], [0.0, 2.0]]",
    ));
    has(
        &err,
        &[
            &kv(
                "obstacle.1.vertices",
                "[[0.0, 1.0], [2.0, 3.0], [2.0, 1.0], [0.0, 2.0]]",
            ),
            "degenerate polygon: edges 0 and 2 cross",
        ],
    );
}

#[test]
fn polygon_touching_itself() {
    // Vertex 3 lies on edge 0: the outline is not simple.
    let err = reject(&with_obstacle(
        "kind = \"polygon\"\nvertices = [[0.0, 1.0], [4.0, 1.0], [4.0, 5.0], [2.0, 1.0], [0.0, 5.0]]",
    ));
    has(
        &err,
        &[
            "key `obstacle.1.vertices` = [[",
            "degenerate polygon",
            "touch",
        ],
    );
}

#[test]
fn polygon_with_fewer_than_three_vertices() {
    let err = reject(&with_obstacle(
        "kind = \"polygon\"\nvertices = [[0.0, 1.0], [1.0, 1.0]]",
    ));
    has(
        &err,
        &[
            &kv("obstacle.1.vertices", "[[0.0, 1.0], [1.0, 1.0]]"),
            "degenerate polygon: 2 vertices (at least 3 are needed)",
        ],
    );
}

#[test]
fn polygon_without_vertices() {
    let err = reject(&with_obstacle("kind = \"polygon\""));
    has(&err, &[&missing("obstacle.1.vertices")]);
}

#[test]
fn ellipse_with_a_zero_axis() {
    let err = reject(&with_obstacle(
        "kind = \"ellipse\"\ncenter = [0.0, 1.0]\na = 0.0\nb = 0.1",
    ));
    has(
        &err,
        &[&kv("obstacle.1.a", "0.0"), "must be greater than zero"],
    );
}

#[test]
fn ellipse_with_extreme_axis_ratio() {
    let err = reject(&with_obstacle(
        "kind = \"ellipse\"\ncenter = [0.0, 1.0]\na = 1.0\nb = 1e-7",
    ));
    has(
        &err,
        &[
            &kv("obstacle.1.b", "1e-7"),
            "degenerate ellipse: axis ratio 1.000e7 exceeds 1e6",
        ],
    );
}

#[test]
fn plane_with_zero_normal() {
    let err = reject(&with_obstacle(
        "kind = \"plane\"\npoint = [0.0, -1.0]\nnormal = [0.0, 0.0]",
    ));
    has(
        &err,
        &[
            &kv("obstacle.1.normal", "[0.0, 0.0]"),
            "the normal is the zero vector",
        ],
    );
}

#[test]
fn sine_with_negative_wavenumber() {
    let err = reject(&with_obstacle(
        "kind = \"sine\"\namplitude = 0.01\nwavenumber = -20.0\noffset = -1.0",
    ));
    has(
        &err,
        &[
            &kv("obstacle.1.wavenumber", "-20.0"),
            "must not be negative",
        ],
    );
}

#[test]
fn obstacle_whose_numbers_overflow() {
    let err = reject(&with_obstacle(
        "kind = \"sine\"\namplitude = 1e300\nwavenumber = 1e300\noffset = -1.0",
    ));
    has(&err, &[&k("obstacle.1"), "cannot be computed"]);
}

// ---------------------------------------------------------------------------------------------
// --set overrides.

#[test]
fn set_path_that_does_not_exist() {
    let err = reject_set(BASE, &["rood.0.E=1e9"]);
    has(
        &err,
        &[
            "(--set rood.0.E=1e9)",
            &kv("rood", "1e9"),
            "this key does not exist",
            &did_you_mean("rod"),
        ],
    );
}

#[test]
fn set_new_key_that_is_unknown() {
    // The last key of a path may be new; the reader then rejects it by name.
    let err = reject_set(BASE, &["solve.dtt=1e-4"]);
    has(
        &err,
        &[
            &kv("solve.dtt", "0.0001"),
            "unknown key",
            &did_you_mean("dt"),
        ],
    );
}

#[test]
fn set_creates_a_table_the_scenario_leaves_out() {
    // BASE has no [contact] table: --set creates it, and the reader checks its keys.
    assert!(!BASE.contains("[contact]"));
    let case = Case::new(BASE.as_bytes());
    let out = case.run("run", &["--no-record", "-q"], &["contact.surface=face"]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let err = reject_set(BASE, &["contact.surfce=face"]);
    has(
        &err,
        &[&kv("contact.surfce", "\"face\""), &did_you_mean("surface")],
    );
    let err = reject_set(BASE, &["contct.surface=face"]);
    has(&err, &["contct", &did_you_mean("contact")]);
}

#[test]
fn set_index_out_of_range() {
    let err = reject_set(BASE, &["obstacle.3.radius=0.04"]);
    has(
        &err,
        &[
            "(--set obstacle.3.radius=0.04)",
            &kv("obstacle.3", "0.04"),
            "index out of range: `obstacle` has 1 entries",
        ],
    );
}

#[test]
fn set_through_a_plain_value() {
    let err = reject_set(BASE, &["rod.0.nodes.count=5"]);
    has(
        &err,
        &[
            &kv("rod.0.nodes.count", "5"),
            "`rod.0.nodes` is a value, not a table or array",
        ],
    );
}

#[test]
fn set_without_equals_sign() {
    let err = reject_set(BASE, &["rod.0.E"]);
    has(&err, &["(--set rod.0.E)", "expected KEY=VALUE"]);
}

#[test]
fn set_a_bad_value() {
    let err = reject_set(BASE, &["rod.0.E=-1"]);
    has(&err, &[&kv("rod.0.E", "-1"), "must be greater than zero"]);
}

#[test]
fn set_a_bad_kind_as_bare_string() {
    let err = reject_set(BASE, &["solve.mode=statc"]);
    has(
        &err,
        &[&kv("solve.mode", "\"statc\""), "did you mean \"static\"?"],
    );
}

// ---------------------------------------------------------------------------------------------
// The file itself.

#[test]
fn nonexistent_file() {
    let dir = tempfile::tempdir().expect("temp dir");
    let path = dir.path().join("no-such-scenario.toml");
    let out = gripsim(dir.path(), &["validate".into(), path.clone().into()]);
    let err = failure(&out, &path.display().to_string());
    has(&err, &["cannot read the file"]);
    assert!(listing(dir.path()).is_empty());
}

#[test]
fn directory_instead_of_file() {
    let dir = tempfile::tempdir().expect("temp dir");
    let out = gripsim(dir.path(), &["validate".into(), dir.path().into()]);
    let err = failure(&out, &dir.path().display().to_string());
    has(&err, &["cannot read the file"]);
}

#[test]
fn non_utf8_file() {
    let mut bytes = b"name = \"caf".to_vec();
    bytes.push(0xE9); // Latin-1 é
    bytes.extend_from_slice(b"\"\n");
    let err = reject_bytes(&bytes, &[]);
    has(&err, &["not UTF-8 text (invalid byte at offset 11)"]);
}

#[test]
fn empty_file() {
    let err = reject("");
    has(&err, &["the file is empty"]);
}

#[test]
fn whitespace_only_file() {
    let err = reject("\n   \n\t\n");
    has(&err, &["the file is empty"]);
}

#[test]
fn toml_syntax_error_gives_line_and_column() {
    let line = BASE.lines().position(|l| l.starts_with("t_end")).unwrap() + 1;
    let err = reject(&edit("t_end = 0.002", "t_end = = 0.002"));
    has(
        &err,
        &[&format!("TOML syntax error at line {line}, column 9")],
    );
}

#[test]
fn toml_syntax_error_after_non_ascii_text() {
    // The column counts characters, not bytes.
    let err = reject(&edit(
        "description = \"a valid",
        "description = \"é\" oops\nx = \"a valid",
    ));
    has(&err, &["TOML syntax error at line 2, column 19"]);
}

#[test]
fn duplicate_toml_key() {
    let line = BASE.lines().position(|l| l.starts_with("E = ")).unwrap() + 2;
    let err = reject(&edit("E = 1e6\n", "E = 1e6\nE = 2e6\n"));
    has(
        &err,
        &[
            &format!("TOML syntax error at line {line}, column 1"),
            "duplicate key `E`",
        ],
    );
}

// ---------------------------------------------------------------------------------------------
// Rules that tie keys together.

#[test]
fn static_mode_with_one_clamped_node() {
    let text = edit("mode = \"dynamic\"", "mode = \"static\"");
    let text = edit_text(&text, "clamped = [0, 1]", "clamped = [0]");
    let err = reject(&text);
    has(
        &err,
        &[&kv("rod.0.clamped", "[0]"), "at least two clamped nodes"],
    );
}

#[test]
fn static_mode_with_a_particle() {
    let text = edit("mode = \"dynamic\"", "mode = \"static\"");
    let text = edit_text(
        &text,
        "[[obstacle]]",
        "[[particle]]\nname = \"ball\"\nposition = [0.0, 1.0]\nmass = 0.01\n\n[[obstacle]]",
    );
    let err = reject(&text);
    has(
        &err,
        &[&kv("particle.0.name", "\"ball\""), "no static equilibrium"],
    );
}

#[test]
fn both_density_and_node_mass() {
    let err = reject(&edit(
        "density = 1000.0",
        "density = 1000.0\nnode_mass = 0.01",
    ));
    has(
        &err,
        &[
            &kv("rod.0.node_mass", "0.01"),
            "both density and node_mass are given",
        ],
    );
}

#[test]
fn drive_on_a_rod_without_clamped_nodes() {
    let text = edit("clamped = [0, 1]\n", "");
    let err = reject(&text);
    has(
        &err,
        &[
            "key `rod.0.drive` = { kind = \"constant_velocity\"",
            "this rod has none",
        ],
    );
}

#[test]
fn scenario_name_with_illegal_characters() {
    let err = reject(&edit(
        "name = \"bad-input-base\"",
        "name = \"bad input/../base\"",
    ));
    has(
        &err,
        &[
            &kv("name", "\"bad input/../base\""),
            "may only hold letters, digits",
        ],
    );
}

#[test]
fn empty_rod_name() {
    let err = reject(&edit("name = \"prong\"", "name = \"  \""));
    has(&err, &[&kv("rod.0.name", "\"  \""), "must not be empty"]);
}

// ---------------------------------------------------------------------------------------------
// `run` rejects the same input, with the same message, before writing anything.

#[test]
fn run_rejects_unknown_key() {
    let err = reject_run(&edit(
        "density = 1000.0\n",
        "density = 1000.0\ndenstiy = 5\n",
    ));
    has(&err, &[&kv("rod.0.denstiy", "5"), &did_you_mean("density")]);
}

#[test]
fn run_rejects_rod_inside_obstacle() {
    let err = reject_run(&with_obstacle(
        "kind = \"circle\"\ncenter = [0.05, 0.0]\nradius = 0.01",
    ));
    has(
        &err,
        &["rod \"prong\" node 2's face starts 1.500e-2 m inside obstacle.1"],
    );
}

#[test]
fn run_rejects_syntax_error() {
    let err = reject_run(&edit("[[rod]]", "[[rod]"));
    has(&err, &["TOML syntax error at line"]);
}

#[test]
fn run_rejects_bad_set() {
    let case = Case::new(BASE.as_bytes());
    let out = case.run("run", &["--summary", "s.json"], &["rod.2.E=1e9"]);
    let err = failure(&out, &case.path.display().to_string());
    has(&err, &[&kv("rod.2", "1e9"), "index out of range"]);
    case.assert_untouched();
}

// ---------------------------------------------------------------------------------------------
// Actuation programs: [[actuator]] tables and the rod keys `actuator`, `mirror`.

const DRIVE_LINE: &str =
    "drive = { kind = \"constant_velocity\", velocity = [0.0, -0.01], stop_time = 0.001 }";

/// A phase that is valid on its own.
const GOOD_PHASE: &str = "[[actuator.phase]]
kind = \"translate\"
direction = [0.0, -1.0]
law = \"constant_velocity\"
speed = 0.01
end = { duration = 0.001 }
";

/// BASE with the rod's drive replaced by `rod_keys` and `actuator` appended.
fn with_actuator(rod_keys: &str, actuator: &str) -> String {
    format!("{}\n{actuator}\n", edit(DRIVE_LINE, rod_keys))
}

/// BASE with the rod moved by actuator "grip" (mirror line x = 0.2) running `phases`.
fn actuator(phases: &str) -> String {
    with_actuator(
        "actuator = \"grip\"",
        &format!("[[actuator]]\nname = \"grip\"\nmirror_x = 0.2\n{phases}"),
    )
}

/// GOOD_PHASE with `from` replaced by `to`.
fn phase(from: &str, to: &str) -> String {
    actuator(&edit_text(GOOD_PHASE, from, to))
}

#[test]
fn actuator_base_is_valid() {
    for text in [
        actuator(GOOD_PHASE),
        with_actuator(
            "actuator = \"grip\"\nmirror = true",
            &format!("[[actuator]]\nname = \"grip\"\nmirror_x = 0.2\n{GOOD_PHASE}"),
        ),
    ] {
        let case = Case::new(text.as_bytes());
        let out = case.run("validate", &[], &[]);
        assert_eq!(
            out.status.code(),
            Some(0),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        case.assert_untouched();
    }
}

#[test]
fn phase_that_never_ends() {
    let err = phase("end = { duration = 0.001 }\n", "");
    has(
        &reject(&err),
        &[
            &k("actuator.0.phase.0.end"),
            "the phase never ends",
            "\"constant_velocity\"",
        ],
    );
    // A hold that is not the last phase must end too (a final one may last forever).
    let hold = format!("[[actuator.phase]]\nkind = \"hold\"\n{GOOD_PHASE}");
    has(
        &reject(&actuator(&hold)),
        &[&k("actuator.0.phase.0.end"), "never ends", "a hold"],
    );
    let last_hold = format!("{GOOD_PHASE}[[actuator.phase]]\nkind = \"hold\"\n");
    let case = Case::new(actuator(&last_hold).as_bytes());
    assert_eq!(case.run("validate", &[], &[]).status.code(), Some(0));
}

#[test]
fn grip_force_without_a_safety_limit() {
    let err = reject(&phase(
        "end = { duration = 0.001 }",
        "end = { grip_force = 5.0 }",
    ));
    has(
        &err,
        &[
            &kv("actuator.0.phase.0.end.grip_force", "5.0"),
            "no safety limit",
            "add duration or travel",
        ],
    );
}

#[test]
fn grip_force_in_a_rotation_and_width_without_mirror_line() {
    let rot = "[[actuator.phase]]\nkind = \"rotate\"\npivot = [0.0, 0.0]\nlaw = \"constant_velocity\"\nspeed = 1.0\nend = { grip_force = 1.0, duration = 0.001 }\n";
    has(
        &reject(&actuator(rot)),
        &[
            &kv("actuator.0.phase.0.end.grip_force", "1.0"),
            "not used in a rotate phase",
            "grip_torque",
        ],
    );
    let no_line = with_actuator(
        "actuator = \"grip\"",
        &format!(
            "[[actuator]]\nname = \"grip\"\n{}",
            edit_text(GOOD_PHASE, "duration = 0.001", "width = 0.01")
        ),
    );
    has(
        &reject(&no_line),
        &[
            &kv("actuator.0.phase.0.end.width", "0.01"),
            "needs the actuator's mirror_x",
        ],
    );
}

#[test]
fn unknown_actuator_name_did_you_mean() {
    let text = edit_text(
        &actuator(GOOD_PHASE),
        "actuator = \"grip\"",
        "actuator = \"gripp\"",
    );
    has(
        &reject(&text),
        &[
            &kv("rod.0.actuator", "\"gripp\""),
            "unknown actuator \"gripp\"",
            "did you mean \"grip\"?",
        ],
    );
}

#[test]
fn drive_and_actuator_together() {
    let text = edit_text(
        &actuator(GOOD_PHASE),
        "actuator = \"grip\"",
        &format!("actuator = \"grip\"\n{DRIVE_LINE}"),
    );
    has(
        &reject(&text),
        &[
            &kv("rod.0.actuator", "\"grip\""),
            "may not also have `drive`",
        ],
    );
}

#[test]
fn mirror_without_mirror_x() {
    let text = with_actuator(
        "actuator = \"grip\"\nmirror = true",
        &format!("[[actuator]]\nname = \"grip\"\n{GOOD_PHASE}"),
    );
    has(
        &reject(&text),
        &[
            &kv("rod.0.mirror", "true"),
            "actuator \"grip\" has no mirror_x",
        ],
    );
    // And mirror without an actuator at all.
    has(
        &reject(&edit(DRIVE_LINE, &format!("{DRIVE_LINE}\nmirror = true"))),
        &[&kv("rod.0.mirror", "true"), "needs `actuator`"],
    );
}

#[test]
fn direction_of_zero_length() {
    let err = reject(&phase("direction = [0.0, -1.0]", "direction = [0.0, 0.0]"));
    has(
        &err,
        &[
            &kv("actuator.0.phase.0.direction", "[0.0, 0.0]"),
            "has zero length",
        ],
    );
    let err = reject(&phase(
        "direction = [0.0, -1.0]\nlaw = \"constant_velocity\"\nspeed = 0.01",
        "law = \"constant_velocity\"\nvelocity = [0.0, 0.0]",
    ));
    has(
        &err,
        &[
            &kv("actuator.0.phase.0.velocity", "[0.0, 0.0]"),
            "has zero length",
        ],
    );
}

#[test]
fn negative_or_non_finite_rates_and_durations() {
    for (from, to, key, value, msg) in [
        (
            "speed = 0.01",
            "speed = -0.01",
            "speed",
            "-0.01",
            "greater than zero",
        ),
        ("speed = 0.01", "speed = nan", "speed", "nan", "finite"),
        ("speed = 0.01", "speed = inf", "speed", "inf", "finite"),
        (
            "law = \"constant_velocity\"\nspeed = 0.01",
            "law = \"constant_acceleration\"\nacceleration = -2.0",
            "acceleration",
            "-2.0",
            "greater than zero",
        ),
        (
            "law = \"constant_velocity\"\nspeed = 0.01",
            "law = \"s_curve\"\ndistance = 0.01\nduration = 0.0",
            "duration",
            "0.0",
            "greater than zero",
        ),
        (
            "duration = 0.001",
            "duration = -0.001",
            "end.duration",
            "-0.001",
            "greater than zero",
        ),
        (
            "duration = 0.001",
            "travel = nan",
            "end.travel",
            "nan",
            "finite",
        ),
    ] {
        let err = reject(&phase(from, to));
        has(
            &err,
            &[&kv(&format!("actuator.0.phase.0.{key}"), value), msg],
        );
    }
}

#[test]
fn table_times_must_start_at_zero_and_increase() {
    let table = |pts: &str| {
        phase(
            "law = \"constant_velocity\"\nspeed = 0.01",
            &format!("law = \"table\"\npoints = {pts}"),
        )
    };
    has(
        &reject(&table("[[0.1, 0.0], [0.2, 0.01]]")),
        &[
            &kv("actuator.0.phase.0.points.0", "[0.1, 0.0]"),
            "the first time must be 0",
        ],
    );
    has(
        &reject(&table("[[0.0, 0.0], [0.2, 0.01], [0.2, 0.02]]")),
        &[
            &kv("actuator.0.phase.0.points.2", "[0.2, 0.02]"),
            "times must increase strictly",
        ],
    );
}

#[test]
fn missing_table_file_is_named() {
    let err = reject(&phase(
        "law = \"constant_velocity\"\nspeed = 0.01",
        "law = \"table\"\nfile = \"no-such-profile.csv\"",
    ));
    has(
        &err,
        &[
            &kv("actuator.0.phase.0.file", "\"no-such-profile.csv\""),
            "cannot read the profile",
            "no-such-profile.csv",
        ],
    );
}

#[test]
fn unknown_law_kind_and_keys_did_you_mean() {
    has(
        &reject(&phase(
            "law = \"constant_velocity\"",
            "law = \"constant_velocty\"",
        )),
        &[
            &kv("actuator.0.phase.0.law", "\"constant_velocty\""),
            "unknown law",
            "did you mean \"constant_velocity\"?",
        ],
    );
    has(
        &reject(&phase("kind = \"translate\"", "kind = \"translat\"")),
        &[
            &kv("actuator.0.phase.0.kind", "\"translat\""),
            "unknown phase kind",
            "did you mean \"translate\"?",
        ],
    );
    has(
        &reject(&phase("speed = 0.01", "speed = 0.01\nsped = 0.02")),
        &[
            &kv("actuator.0.phase.0.sped", "0.02"),
            "unknown key",
            &did_you_mean("speed"),
        ],
    );
    has(
        &reject(&phase("duration = 0.001", "duraton = 0.001")),
        &[
            &kv("actuator.0.phase.0.end.duraton", "0.001"),
            "unknown key",
            &did_you_mean("duration"),
        ],
    );
    // A parameter of another law.
    has(
        &reject(&phase("speed = 0.01", "speed = 0.01\ndistance = 0.02")),
        &[
            &kv("actuator.0.phase.0.distance", "0.02"),
            "not used with law = \"constant_velocity\"",
        ],
    );
}

// ---------------------------------------------------------------------------------------------
// Friction and free bodies (issue 10).

#[test]
fn friction_coefficients_negative_nan_or_kinetic_above_static() {
    has(
        &reject(&format!("{BASE}\n[friction]\nmu_s = -0.2\n")),
        &[&kv("friction.mu_s", "-0.2"), "must not be negative"],
    );
    has(
        &reject(&format!("{BASE}\n[friction]\nmu_s = nan\n")),
        &[&kv("friction.mu_s", "nan"), "finite"],
    );
    has(
        &reject(&format!("{BASE}\n[friction]\nmu_s = 0.3\nmu_k = 0.5\n")),
        &[&kv("friction.mu_k", "0.5"), "exceeds the static one"],
    );
    has(
        &reject(&format!(
            "{BASE}\n[friction]\nmu_s = 0.3\n[[friction.pair]]\nbetween = [\"prong\", \"fruit\"]\nmu_s = 0.4\n"
        )),
        &[&kv("friction.pair.0.between.1", "\"fruit\""), "no rod, particle or obstacle"],
    );
    has(
        &reject(&format!("{BASE}\n[friction]\nmu_s = 0.3\nmu_q = 0.5\n")),
        &[&kv("friction.mu_q", "0.5"), "unknown key"],
    );
}

#[test]
fn free_bodies_need_a_mass_a_closed_shape_and_a_free_start() {
    has(
        &reject(&with_obstacle(
            "kind = \"circle\"\ncenter = [0.3, 0.3]\nradius = 0.04\nfree = true",
        )),
        &[&k("obstacle.1.mass"), "a free body needs a mass"],
    );
    has(
        &reject(&with_obstacle(
            "kind = \"circle\"\ncenter = [0.3, 0.3]\nradius = 0.04\nfree = true\nmass = -1.0",
        )),
        &[&kv("obstacle.1.mass", "-1.0")],
    );
    has(
        &reject(&with_obstacle(
            "kind = \"plane\"\npoint = [0.0, -1.0]\nnormal = [0.0, 1.0]\nfree = true\nmass = 1.0",
        )),
        &[&kv("obstacle.1.free", "true"), "not a closed shape"],
    );
    has(
        &reject(&with_obstacle(
            "kind = \"circle\"\ncenter = [0.3, 0.3]\nradius = 0.04\nfree = true\ndensity = 1000.0",
        )),
        &[&k("obstacle.1.depth")],
    );
    has(
        &reject(&with_obstacle(
            "kind = \"circle\"\ncenter = [0.3, 0.3]\nradius = 0.04\nmass = 1.0",
        )),
        &[&kv("obstacle.1.mass", "1.0"), "only a free obstacle"],
    );
    // A fruit starting inside a prong (the prong's nodes inside the fruit).
    has(
        &reject(&with_obstacle(
            "kind = \"circle\"\ncenter = [0.05, 0.0]\nradius = 0.02\nfree = true\nmass = 0.1",
        )),
        &["rod.0.shape", "starts", "inside obstacle.1"],
    );
    // A fruit starting inside the table.
    has(
        &reject(&format!(
            "{BASE}\n[[obstacle]]\nkind = \"plane\"\npoint = [0.0, -0.5]\nnormal = [0.0, 1.0]\n[[obstacle]]\nkind = \"circle\"\ncenter = [0.3, -0.49]\nradius = 0.04\nfree = true\nmass = 0.1\n"
        )),
        &["obstacle.2", "starts", "inside obstacle.1"],
    );
}

#[test]
fn a_grip_force_that_is_never_reached_is_a_run_time_error_naming_the_phase() {
    let text = edit(
        "drive = { kind = \"constant_velocity\", velocity = [0.0, -0.01], stop_time = 0.001 }",
        "actuator = \"hand\"",
    );
    let text = format!(
        "{text}\n[[actuator]]\nname = \"hand\"\n[[actuator.phase]]\nname = \"squeeze\"\nkind = \"translate\"\ndirection = [0.0, -1.0]\nlaw = \"constant_velocity\"\nspeed = 0.01\nend = {{ grip_force = 50.0, travel = 0.00001 }}\n"
    );
    let case = Case::new(text.as_bytes());
    let out = case.run("run", &["--no-record"], &[]);
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(!err.contains("panicked"), "{err}");
    has(
        &err,
        &[
            "error: actuator \"hand\"",
            "phase 0 'squeeze'",
            "travel limit",
            "before grip_force = 50 N",
        ],
    );
}

/// The recording options a 3D run cannot honour are refused before anything is read or
/// written (exit 2, one line naming the scenario, the option and its value); those that say
/// what a 3D run does anyway are taken.
#[test]
fn planar_recording_options_are_refused_for_a_3d_scenario() {
    let text = std::fs::read(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios/3d-two-finger-sphere.toml"),
    )
    .unwrap();
    let case = Case::new(&text);
    let outputs = ["--rrd", "a.rrd", "--mcap", "a.mcap", "--summary", "s.json"];
    for (option, value) in [
        ("--detail", "iteration"),
        ("--detail", "auto"),
        ("--auto-every", "3"),
        ("--flush-every", "7"),
        ("--precision", "f32"),
        ("--arrows", "log"),
    ] {
        let mut args = vec![option, value];
        args.extend(outputs);
        let out = case.run("run", &args, &[]);
        let err = failure(&out, &case.path.display().to_string());
        has(
            &err,
            &[&format!("{option} {value}"), "planar scenarios only"],
        );
        case.assert_untouched();
    }
    let out = case.run(
        "run",
        &[
            "--detail",
            "step",
            "--precision",
            "f64",
            "--arrows",
            "linear",
            "--no-record",
            "--summary",
            "s.json",
            "-q",
        ],
        &["solve.t_end=0.0005"],
    );
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert_eq!(listing(case.dir.path()), ["case.toml", "s.json"]);
}

// ---------------------------------------------------------------------------------------------
// Joints (`[[joint]]`, issue 36).

/// BASE with a rib from the prong's tip up, rigidly joined there, and `joint` as the joint's
/// body (the valid one when None).
fn with_joint(joint: Option<&str>) -> String {
    let body = joint.unwrap_or("rods = [\"prong\", \"rib\"]\nnodes = [4, 0]\nkind = \"rigid\"");
    format!(
        "{BASE}\n[[rod]]\nname = \"rib\"\nnodes = 4\nE = 1e6\ndensity = 1000.0\n\
         shape = {{ kind = \"straight\", start = [0.1, 0.0], end = [0.1, 0.05] }}\n\
         section = {{ kind = \"rect\", b = 0.02, h = 0.01 }}\n\n[[joint]]\n{body}\n"
    )
}

#[test]
fn a_valid_joint_validates() {
    let case = Case::new(with_joint(None).as_bytes());
    let out = case.run("validate", &[], &[]);
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    case.assert_untouched();
}

#[test]
fn joint_naming_a_missing_rod_or_node() {
    let err = reject(&with_joint(Some(
        "rods = [\"prong\", \"ribb\"]\nnodes = [4, 0]",
    )));
    has(
        &err,
        &[
            &kv("joint.0.rods", "\"ribb\""),
            "no rod is named \"ribb\"",
            "\"rib\"",
        ],
    );
    let err = reject(&with_joint(Some(
        "rods = [\"prong\", \"rib\"]\nnodes = [5, 0]",
    )));
    has(
        &err,
        &[
            &kv("joint.0.nodes", "5"),
            "rod \"prong\" has no node 5",
            "0 to 4",
        ],
    );
    let err = reject(&with_joint(Some("rods = [\"prong\"]\nnodes = [4, 0]")));
    has(&err, &[&kv("joint.0.rods", "[\"prong\"]"), "two entries"]);
}

#[test]
fn joint_joining_a_node_twice_to_the_same_rod() {
    let twice = "rods = [\"prong\", \"rib\"]\nnodes = [4, 0]\n\n[[joint]]\nrods = [\"rib\", \"prong\"]\nnodes = [0, 4]\nkind = \"pin\"";
    let err = reject(&with_joint(Some(twice)));
    has(
        &err,
        &[
            &kv("joint.1.nodes", "[0, 4]"),
            "\"rib\" node 0 is joined to rod \"prong\" twice",
            "joint.0",
        ],
    );
}

#[test]
fn joint_members_that_start_apart() {
    let err = reject(&with_joint(Some(
        "rods = [\"prong\", \"rib\"]\nnodes = [3, 0]",
    )));
    has(
        &err,
        &[
            &kv("joint.0.nodes", "[3, 0]"),
            "the members start apart",
            "2.500e-2 m apart",
        ],
    );
}

#[test]
fn joint_of_an_unknown_kind() {
    let err = reject(&with_joint(Some(
        "rods = [\"prong\", \"rib\"]\nnodes = [4, 0]\nkind = \"welded\"",
    )));
    has(
        &err,
        &[
            &kv("joint.0.kind", "\"welded\""),
            "unknown joint kind",
            "\"rigid\" or \"pin\"",
        ],
    );
    let err = reject(&with_joint(Some(
        "rods = [\"prong\", \"rib\"]\nnodes = [4, 0]\nstiff = true",
    )));
    has(&err, &[&kv("joint.0.stiff", "true"), "unknown key"]);
}
