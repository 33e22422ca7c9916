//! What the test modules share: the CLI under test, the shipped scenarios and the Python venv
//! that holds the independent readers (rerun-sdk, mcap).

use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::sync::OnceLock;

/// The repository root.
pub const ROOT: &str = env!("CARGO_MANIFEST_DIR");

/// The `gripsim` binary, run from the repository root.
pub fn gripsim() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_gripsim"));
    c.current_dir(ROOT);
    c
}

/// A scenario's path: a shipped one (scenarios/) or a golden guard's (recordings/golden/).
pub fn scenario(name: &str) -> PathBuf {
    let file = format!("{name}.toml");
    let shipped = Path::new(ROOT).join("scenarios").join(&file);
    if shipped.exists() {
        shipped
    } else {
        Path::new(ROOT).join("recordings/golden").join(file)
    }
}

/// The test venv of tests/py/setup_venv.py (created once per machine; the script takes a lock,
/// so concurrent test processes are safe too).
pub fn venv() -> &'static Path {
    static VENV: OnceLock<PathBuf> = OnceLock::new();
    VENV.get_or_init(|| {
        let out = Command::new("python3")
            .arg(Path::new(ROOT).join("tests/py/setup_venv.py"))
            .stderr(Stdio::inherit())
            .output()
            .expect("python3 runs tests/py/setup_venv.py");
        assert!(out.status.success(), "setting up the test venv failed");
        PathBuf::from(String::from_utf8(out.stdout).unwrap().trim())
    })
}

/// A message of a gripsim MCAP in its JSON form, whatever its encoding (format 2 writes
/// `/sim/step` and `/sim/iteration` as protobuf, the rest and format 1 as JSON).
pub fn message_json(m: &mcap::Message) -> serde_json::Value {
    let schema = m.channel.schema.as_ref().expect("a schema");
    gripsim::record::proto::decode_json(&schema.name, &m.channel.message_encoding, &m.data)
        .unwrap_or_else(|| panic!("{}: a message that does not decode", m.channel.topic))
}

/// A finished command's status, stdout and stderr, for messages.
pub fn text(out: &Output) -> String {
    format!(
        "status {}\nstdout:\n{}\nstderr:\n{}",
        out.status,
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    )
}

/// Run, expect exit `code`, never a panic.
pub fn expect(cmd: &mut Command, code: i32) -> Output {
    let out = cmd.output().expect("gripsim starts");
    assert_eq!(out.status.code(), Some(code), "{cmd:?}\n{}", text(&out));
    assert!(
        !String::from_utf8_lossy(&out.stderr).contains("panicked"),
        "{cmd:?} panicked:\n{}",
        text(&out)
    );
    out
}

/// Run, expect success.
pub fn run_ok(cmd: &mut Command) -> Output {
    let out = cmd.output().expect("gripsim starts");
    assert!(
        out.status.success(),
        "{cmd:?} failed with {}:\n{}\n{}",
        out.status,
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    out
}
