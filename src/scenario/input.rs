//! Reading a scenario and the files it names: each read exactly once, bounded in size, and
//! never blocking forever.
//!
//! - A scenario path may be a regular file, a pipe or FIFO (process substitution,
//!   `gripsim run <(sed … s.toml)`), or a device; it is read once, up to
//!   [`MAX_SCENARIO_BYTES`] + 1 bytes, and parsed from that buffer. A FIFO nobody opens for
//!   writing is given [`FIFO_WAIT`] for a writer to appear, then refused; a FIFO with a writer
//!   is read to its end however long the writer takes (as `cat` would).
//! - A file a scenario names (a 3D fruit's `mesh` file, an actuation profile's `file`) must be
//!   a regular file of at most [`MAX_REFERENCED_BYTES`]: a FIFO, device or folder is refused
//!   without blocking.
//! - [`referenced_files`] lists those files (every `file = "…"` value of the scenario, after
//!   its `--set` overrides), so that a command can refuse to write an output onto one.

use super::ScenarioError;
use std::io::Read as _;
use std::path::{Path, PathBuf};
use std::time::Duration;

/// The largest scenario file read (16 MiB; a 100 000-vertex polygon takes about 4 MiB). A
/// longer input (`/dev/zero`, a recording given by mistake) is refused after reading one byte
/// more than this, before it is parsed.
pub const MAX_SCENARIO_BYTES: u64 = 16 << 20;

/// The largest file a scenario names (a mesh, a profile table): 64 MiB.
pub const MAX_REFERENCED_BYTES: u64 = 64 << 20;

/// How long a scenario FIFO that no process has opened for writing is waited for.
pub const FIFO_WAIT: Duration = Duration::from_secs(5);

/// Open `path` for reading without blocking on a FIFO that has no writer yet (`O_NONBLOCK`),
/// with its metadata.
fn open_nonblocking(path: &Path) -> std::io::Result<(std::fs::File, std::fs::Metadata)> {
    use std::os::unix::fs::OpenOptionsExt;
    let file = std::fs::OpenOptions::new()
        .read(true)
        .custom_flags(libc::O_NONBLOCK)
        .open(path)?;
    let meta = file.metadata()?;
    Ok((file, meta))
}

/// Clear `O_NONBLOCK` on `file` (reads block again, as on any file).
fn set_blocking(file: &std::fs::File) {
    use std::os::fd::AsRawFd;
    // SAFETY: fcntl on a descriptor we own, with flags read from it.
    unsafe {
        let fd = file.as_raw_fd();
        let flags = libc::fcntl(fd, libc::F_GETFL);
        if flags >= 0 {
            libc::fcntl(fd, libc::F_SETFL, flags & !libc::O_NONBLOCK);
        }
    }
}

/// Wait until `file` (a pipe) has data or its writer left, at most `ms` ms (-1: no limit).
/// Returns whether the writer hung up.
fn poll_in(file: &std::fs::File, ms: i32) -> bool {
    use std::os::fd::AsRawFd;
    let mut p = libc::pollfd {
        fd: file.as_raw_fd(),
        events: libc::POLLIN,
        revents: 0,
    };
    // SAFETY: one pollfd we own, for the duration of the call.
    let n = unsafe { libc::poll(&mut p, 1, ms) };
    n > 0 && p.revents & libc::POLLHUP != 0
}

/// Read a FIFO or pipe opened with `O_NONBLOCK` to its end, at most `cap` + 1 bytes.
///
/// A read of 0 bytes means no writer is there: the end when a writer was seen (it wrote, or
/// hung up), else a writer is waited for until [`FIFO_WAIT`] has passed. `EAGAIN` means a
/// writer is there with nothing written yet: waited for without a limit.
fn read_fifo(file: &std::fs::File, cap: u64) -> std::io::Result<Vec<u8>> {
    let start = std::time::Instant::now();
    let mut bytes = Vec::new();
    let mut buf = vec![0u8; 64 << 10];
    let mut writer_seen = false;
    loop {
        match (&*file).read(&mut buf) {
            Ok(0) if writer_seen || !bytes.is_empty() => return Ok(bytes),
            Ok(0) => {
                let left = FIFO_WAIT.saturating_sub(start.elapsed());
                if left.is_zero() {
                    return Err(std::io::Error::new(
                        std::io::ErrorKind::TimedOut,
                        format!(
                            "a FIFO that nobody wrote to within {} s",
                            FIFO_WAIT.as_secs()
                        ),
                    ));
                }
                writer_seen = poll_in(file, left.as_millis().clamp(1, 1000) as i32);
            }
            Ok(n) => {
                bytes.extend_from_slice(&buf[..n]);
                if bytes.len() as u64 > cap {
                    bytes.truncate(cap as usize + 1);
                    return Ok(bytes);
                }
            }
            Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => {
                writer_seen = true;
                poll_in(file, -1);
            }
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
}

/// Read at most [`MAX_SCENARIO_BYTES`] + 1 bytes of `path` (so a longer one is detected), in
/// one pass: a regular file, a device, or a pipe/FIFO (read to its writer's end; one nobody
/// writes to is refused after [`FIFO_WAIT`]).
pub fn read_capped(path: &Path) -> std::io::Result<Vec<u8>> {
    let (file, meta) = open_nonblocking(path)?;
    if meta.file_type().is_dir() {
        return Err(std::io::Error::from_raw_os_error(libc::EISDIR));
    }
    use std::os::unix::fs::FileTypeExt;
    if meta.file_type().is_fifo() {
        return read_fifo(&file, MAX_SCENARIO_BYTES);
    }
    set_blocking(&file);
    let mut bytes = Vec::new();
    file.take(MAX_SCENARIO_BYTES + 1).read_to_end(&mut bytes)?;
    Ok(bytes)
}

/// A scenario file's text, read once ([`read_capped`]): the error names the file and says
/// why (missing, a folder, over 16 MiB, not UTF-8), with a hint.
pub fn read_text(path: &Path) -> Result<String, ScenarioError> {
    let file = path.display().to_string();
    let fail = |message: String, hint: Option<String>| ScenarioError {
        file: file.clone(),
        key: String::new(),
        value: String::new(),
        message,
        hint,
    };
    let bytes = read_capped(path).map_err(|e| {
        fail(
            format!("cannot read the file: {e}"),
            Some(super::missing_file_hint(path, &e)),
        )
    })?;
    if bytes.len() as u64 > MAX_SCENARIO_BYTES {
        return Err(fail(
            format!(
                "larger than {} MiB: not a scenario file (reading stopped there)",
                MAX_SCENARIO_BYTES >> 20
            ),
            Some("a scenario is a short TOML text; check the path".into()),
        ));
    }
    String::from_utf8(bytes).map_err(|e| {
        fail(
            format!(
                "not UTF-8 text (invalid byte at offset {})",
                e.utf8_error().valid_up_to()
            ),
            Some("scenario files are TOML text in UTF-8".into()),
        )
    })
}

/// The text of a file a scenario names (`what`: "mesh", "profile"): a regular file of at most
/// [`MAX_REFERENCED_BYTES`], opened without blocking (a FIFO, device or folder is refused).
/// The error names the path.
pub fn read_referenced(path: &Path, what: &str) -> Result<String, String> {
    let cannot = |e: String| format!("cannot read the {what} {}: {e}", path.display());
    let (file, meta) = open_nonblocking(path).map_err(|e| cannot(e.to_string()))?;
    if !meta.is_file() {
        return Err(cannot(
            "not a regular file (a folder, device or FIFO): give the path of a file".into(),
        ));
    }
    if meta.len() > MAX_REFERENCED_BYTES {
        return Err(cannot(format!(
            "{} bytes, over the {} MiB a {what} may have",
            meta.len(),
            MAX_REFERENCED_BYTES >> 20
        )));
    }
    set_blocking(&file);
    let mut bytes = Vec::new();
    file.take(MAX_REFERENCED_BYTES + 1)
        .read_to_end(&mut bytes)
        .map_err(|e| cannot(e.to_string()))?;
    if bytes.len() as u64 > MAX_REFERENCED_BYTES {
        return Err(cannot(format!(
            "over the {} MiB a {what} may have",
            MAX_REFERENCED_BYTES >> 20
        )));
    }
    String::from_utf8(bytes).map_err(|e| {
        cannot(format!(
            "not UTF-8 text (invalid byte at offset {})",
            e.utf8_error().valid_up_to()
        ))
    })
}

/// Every file the scenario `text` (with the `--set` overrides `sets` applied) names: each
/// string value of a key `file` (a 3D `mesh` shape's, an actuation `table` profile's), joined
/// to `dir` (the folder of the scenario file) as the readers join it. A text that does not
/// parse names none (it is refused by its reader anyway).
pub fn referenced_files(text: &str, sets: &[String], dir: &Path) -> Vec<PathBuf> {
    let Ok(mut root) = text.parse::<toml::Table>() else {
        return Vec::new();
    };
    if super::apply_sets(&mut root, sets, "").is_err() {
        root = text.parse::<toml::Table>().unwrap_or_default();
    }
    fn walk(v: &toml::Value, dir: &Path, out: &mut Vec<PathBuf>) {
        match v {
            toml::Value::Table(t) => {
                for (k, v) in t {
                    match v {
                        toml::Value::String(s) if k == "file" => out.push(dir.join(s)),
                        _ => walk(v, dir, out),
                    }
                }
            }
            toml::Value::Array(a) => a.iter().for_each(|v| walk(v, dir, out)),
            _ => {}
        }
    }
    let mut out = Vec::new();
    walk(&toml::Value::Table(root), dir, &mut out);
    out.sort();
    out.dedup();
    out
}

/// The folder a scenario at `path` names its files relative to.
pub fn scenario_dir(path: &Path) -> &Path {
    path.parent().unwrap_or(Path::new(""))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn referenced_files_are_every_file_key_after_the_overrides() {
        let text = "name = \"x\"\n[[obstacle]]\nshape = { kind = \"mesh\", file = \"fruit.obj\" }\n\
                    [[actuator]]\nname = \"a\"\n[[actuator.phase]]\nlaw = \"table\"\nfile = \"p.csv\"\n";
        let got = referenced_files(text, &[], Path::new("d"));
        assert_eq!(
            got,
            [PathBuf::from("d/fruit.obj"), PathBuf::from("d/p.csv")]
        );
        let got = referenced_files(
            text,
            &["actuator.0.phase.0.file=\"q.csv\"".to_string()],
            Path::new(""),
        );
        assert_eq!(got, [PathBuf::from("fruit.obj"), PathBuf::from("q.csv")]);
        assert!(referenced_files("not = = toml", &[], Path::new("")).is_empty());
    }

    #[test]
    fn a_referenced_file_must_be_a_regular_file() {
        let dir = tempfile::tempdir().unwrap();
        let e = read_referenced(dir.path(), "mesh").unwrap_err();
        assert!(e.contains("not a regular file"), "{e}");
        let e = read_referenced(Path::new("/dev/zero"), "mesh").unwrap_err();
        assert!(
            e.contains("/dev/zero") && e.contains("not a regular file"),
            "{e}"
        );
        let f = dir.path().join("m.obj");
        std::fs::write(&f, "v 0 0 0\n").unwrap();
        assert_eq!(read_referenced(&f, "mesh").unwrap(), "v 0 0 0\n");
    }
}
