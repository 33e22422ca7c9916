//! A command's files, planned before it writes any: [`OutputPlan`].
//!
//! Every command that writes files (`run` planar and 3D, `replay check|diff|show`, `sweep`)
//! lists its inputs (the scenario and every file it names, the recordings it reads) and its
//! outputs first. [`OutputPlan::check`] then refuses, before anything is created:
//!
//! - an output that is an input or another output: the same file through `./`, `..`,
//!   symlinks or hard links (device and inode where the file exists, the canonical path
//!   otherwise), or one output's `.partial` file; one character device (`/dev/null`) may take
//!   several outputs;
//! - an output that cannot take a file: a directory, a socket, a block device, a dangling
//!   symlink, a path whose folder is a file, or a folder that cannot be written (read-only,
//!   no permission); the folders it needs are made only when the command writes;
//! - an input inside a folder the command fills (`sweep --out DIR`'s `cases/`, `plots/`).
//!
//! [`OutputPlan::hold`] then makes the outputs wait for each other: a completed file stays
//! under its `.partial` name ([`super::OutputFile::settle`]) until [`Held::commit`] renames
//! them all, once every one of them was written. A command that fails therefore leaves the
//! files that existed before untouched (the older final file of every output stays, beside
//! the failed run's `.partial` files) and never a half set of new final files.

use super::{error_reason, OutputFile, Target};
use std::path::{Path, PathBuf};
use std::sync::Mutex;

/// The partial files (absolute) of the outputs held by a [`Held`] of this process.
static HELD: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

fn key(partial: &Path) -> PathBuf {
    normalize(&std::path::absolute(partial).unwrap_or_else(|_| partial.to_path_buf()))
}

fn held_list() -> std::sync::MutexGuard<'static, Vec<PathBuf>> {
    HELD.lock().unwrap_or_else(|e| e.into_inner())
}

/// Whether a [`Held`] of this process holds the output written as `partial`.
pub(crate) fn is_held(partial: &Path) -> bool {
    let k = key(partial);
    held_list().contains(&k)
}

/// Whether the output `path` is held by a [`Held`] (its rename is [`Held::commit`]'s).
pub fn holds(path: &Path) -> bool {
    let out = OutputFile::new(path);
    out.target == Target::File && is_held(&out.partial)
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Kind {
    Input,
    File,
    Folder,
}

#[derive(Debug, Clone)]
struct Entry {
    what: String,
    path: PathBuf,
    kind: Kind,
}

/// The inputs and outputs of one command, checked before it writes anything (see the module
/// documentation).
#[derive(Debug, Clone, Default)]
pub struct OutputPlan {
    entries: Vec<Entry>,
}

impl OutputPlan {
    pub fn new() -> Self {
        Self::default()
    }

    fn push(&mut self, what: &str, path: &Path, kind: Kind) -> &mut Self {
        self.entries.push(Entry {
            what: what.to_string(),
            path: path.to_path_buf(),
            kind,
        });
        self
    }

    /// A file the command reads (`what`: "the scenario", "the run", …).
    pub fn input(&mut self, what: &str, path: &Path) -> &mut Self {
        self.push(what, path, Kind::Input)
    }

    /// A scenario file and every file its text (with the `--set` overrides `sets`) names
    /// ([`crate::scenario::input::referenced_files`]: meshes, profile tables).
    pub fn scenario(&mut self, path: &Path, text: &str, sets: &[String]) -> &mut Self {
        self.input("the scenario", path);
        let dir = crate::scenario::input::scenario_dir(path);
        for f in crate::scenario::input::referenced_files(text, sets, dir) {
            self.input("the scenario's file", &f);
        }
        self
    }

    /// A file the command writes (`what`: the option, e.g. "--mcap").
    pub fn output(&mut self, what: &str, path: &Path) -> &mut Self {
        self.push(what, path, Kind::File)
    }

    /// A folder the command writes into (everything under it may be replaced).
    pub fn folder(&mut self, what: &str, path: &Path) -> &mut Self {
        self.push(what, path, Kind::Folder)
    }

    /// Refuse, before anything is written, an output that cannot take a file or that is an
    /// input or another output; the error is one line naming both paths (or the path and
    /// why).
    pub fn check(&self) -> Result<(), String> {
        for e in &self.entries {
            match e.kind {
                Kind::File => check_file(e)?,
                Kind::Folder => check_folder(e)?,
                Kind::Input => {}
            }
        }
        self.check_distinct()?;
        self.check_folders()
    }

    /// Hold the outputs (after [`OutputPlan::check`]): their completed files wait under their
    /// `.partial` names for [`Held::commit`].
    pub fn hold(&self) -> Held {
        let mut outputs = Vec::new();
        for e in self.entries.iter().filter(|e| e.kind == Kind::File) {
            let out = OutputFile::new(&e.path);
            if out.target == Target::File {
                outputs.push((e.what.clone(), out));
            }
        }
        let keys: Vec<PathBuf> = outputs.iter().map(|(_, o)| key(&o.partial)).collect();
        held_list().extend(keys.iter().cloned());
        Held { outputs, keys }
    }

    /// Every input and output file its own (an input may be read by several).
    fn check_distinct(&self) -> Result<(), String> {
        let files: Vec<(&Entry, Vec<PathId>)> = self
            .entries
            .iter()
            .filter(|e| e.kind != Kind::Folder)
            .map(|e| (e, ids(e)))
            .collect();
        for (j, (b, b_ids)) in files.iter().enumerate() {
            for (a, a_ids) in &files[..j] {
                let outputs = a.kind == Kind::File && b.kind == Kind::File;
                if a.kind == Kind::Input && b.kind == Kind::Input {
                    continue;
                }
                let clash = a_ids.iter().any(|x| {
                    b_ids.iter().any(|y| {
                        let same =
                            x.canonical == y.canonical || (x.inode.is_some() && x.inode == y.inode);
                        same && !(x.char_device && y.char_device && outputs)
                    })
                });
                if clash {
                    // The output first, then what it clashes with.
                    let (o, other) = if b.kind == Kind::File { (b, a) } else { (a, b) };
                    let role = if other.kind == Kind::Input {
                        " (an input)"
                    } else {
                        ""
                    };
                    return Err(format!(
                        "{} {} and {} {}{role} are the same file (or one is the other's .partial file): give each output its own path",
                        o.what,
                        o.path.display(),
                        other.what,
                        other.path.display()
                    ));
                }
            }
        }
        Ok(())
    }

    /// No input inside a folder the command fills.
    fn check_folders(&self) -> Result<(), String> {
        for f in self.entries.iter().filter(|e| e.kind == Kind::Folder) {
            let dir = path_id(&f.path).canonical;
            for i in self.entries.iter().filter(|e| e.kind == Kind::Input) {
                if path_id(&i.path).canonical.starts_with(&dir) {
                    return Err(format!(
                        "{} {} (an input) is inside {} {}, which the command writes: move it or give another folder",
                        i.what,
                        i.path.display(),
                        f.what,
                        f.path.display()
                    ));
                }
            }
        }
        Ok(())
    }
}

/// The identities of an entry: an output's own path, the regular file it stands for and its
/// `.partial` file.
fn ids(e: &Entry) -> Vec<PathId> {
    let mut v = vec![path_id(&e.path)];
    if e.kind == Kind::File {
        let out = OutputFile::new(&e.path);
        if !out.is_through() {
            v.push(path_id(&out.final_path));
            v.push(path_id(&out.partial));
        }
    }
    v
}

/// An output file's path can take the file: not a directory, socket, block device or
/// dangling symlink, in a folder that exists (or can be made) and can be written, with no
/// directory at its `.partial` name.
fn check_file(e: &Entry) -> Result<(), String> {
    let out = OutputFile::new(&e.path);
    let fail = |why: String| format!("{} {}: {why}", e.what, e.path.display());
    out.check().map_err(|err| fail(error_reason(&err)))?;
    if out.is_through() {
        return Ok(());
    }
    let folder = out
        .final_path
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    writable_folder(folder).map_err(fail)?;
    if std::fs::symlink_metadata(&out.partial).is_ok_and(|m| m.is_dir()) {
        return Err(fail(format!(
            "its partial file {} is a directory",
            out.partial.display()
        )));
    }
    Ok(())
}

/// An output folder is a folder (or can be made) and can be written.
fn check_folder(e: &Entry) -> Result<(), String> {
    let fail = |why: String| format!("{} {}: {why}", e.what, e.path.display());
    match std::fs::metadata(&e.path) {
        Ok(m) if !m.is_dir() => Err(fail("is not a folder".into())),
        _ => writable_folder(&e.path).map_err(fail),
    }
}

/// `dir`, or the nearest of its ancestors that exists (where the missing ones would be made),
/// is a folder this process may create files in.
fn writable_folder(dir: &Path) -> Result<(), String> {
    let mut d = dir.to_path_buf();
    loop {
        match std::fs::metadata(&d) {
            Ok(m) if m.is_dir() => return may_write(&d),
            Ok(_) => return Err(format!("{} is not a folder", d.display())),
            // Missing, or under a file (ENOTDIR): the file is found further up.
            Err(e)
                if e.kind() == std::io::ErrorKind::NotFound
                    || e.raw_os_error() == Some(libc::ENOTDIR) =>
            {
                d = match d.parent() {
                    Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
                    _ => PathBuf::from("."),
                };
            }
            Err(e) => return Err(format!("cannot reach the folder {}: {e}", d.display())),
        }
    }
}

/// Whether this process may create files in the folder `d` (write and search permission, a
/// writable file system).
fn may_write(d: &Path) -> Result<(), String> {
    use std::os::unix::ffi::OsStrExt as _;
    let c = std::ffi::CString::new(d.as_os_str().as_bytes())
        .map_err(|_| format!("{}: a path with a NUL byte", d.display()))?;
    // SAFETY: a valid C string; faccessat only reads it.
    let r = unsafe {
        libc::faccessat(
            libc::AT_FDCWD,
            c.as_ptr(),
            libc::W_OK | libc::X_OK,
            libc::AT_EACCESS,
        )
    };
    if r == 0 {
        Ok(())
    } else {
        Err(format!(
            "cannot create a file in the folder {}: {}",
            d.display(),
            std::io::Error::last_os_error()
        ))
    }
}

/// The outputs of an [`OutputPlan`] waiting for each other: each completed one stays under
/// its `.partial` name until [`Held::commit`]. Dropped without a commit, it leaves the
/// partial files where they are (a run that failed keeps them, as documented).
#[derive(Debug)]
pub struct Held {
    outputs: Vec<(String, OutputFile)>,
    keys: Vec<PathBuf>,
}

impl Held {
    /// Give every output its final name, once all of them were written (their `.partial`
    /// files are there): else none is renamed and the error names the one missing. Devices
    /// are not held (written through).
    pub fn commit(self) -> Result<(), String> {
        for (what, out) in &self.outputs {
            if std::fs::symlink_metadata(&out.partial).is_err() {
                return Err(format!(
                    "{what} {} was not written (no {}): no output was given its final name",
                    out.path.display(),
                    out.partial.display()
                ));
            }
        }
        for (what, out) in &self.outputs {
            std::fs::rename(&out.partial, &out.final_path).map_err(|e| {
                format!(
                    "{what} {}: cannot rename {} to its final name: {e}",
                    out.path.display(),
                    out.partial.display()
                )
            })?;
        }
        Ok(())
    }

    /// Remove the outputs' `.partial` files (a command whose partial results are of no use,
    /// e.g. a replay that failed).
    pub fn discard(self) {
        for (_, out) in &self.outputs {
            out.discard();
        }
    }
}

impl Drop for Held {
    fn drop(&mut self) {
        let mut list = held_list();
        for k in &self.keys {
            if let Some(i) = list.iter().position(|x| x == k) {
                list.swap_remove(i);
            }
        }
    }
}

/// The identity of a path for [`OutputPlan::check`]: its device and inode when it exists, and
/// its absolute path with symlinks resolved as far as they exist.
#[derive(Debug, Clone, PartialEq, Eq)]
struct PathId {
    inode: Option<(u64, u64)>,
    char_device: bool,
    canonical: PathBuf,
}

fn path_id(p: &Path) -> PathId {
    use std::os::unix::fs::{FileTypeExt, MetadataExt};
    let meta = std::fs::metadata(p).ok();
    let canonical = std::fs::canonicalize(p).unwrap_or_else(|_| {
        // Not there yet: resolve the folder, keep the name.
        let abs = std::path::absolute(p).unwrap_or_else(|_| p.to_path_buf());
        let mut parts: Vec<std::ffi::OsString> = Vec::new();
        let mut dir = abs.as_path();
        loop {
            if let Ok(c) = std::fs::canonicalize(dir) {
                let mut out = c;
                for part in parts.iter().rev() {
                    out.push(part);
                }
                return normalize(&out);
            }
            match (dir.file_name(), dir.parent()) {
                (Some(name), Some(parent)) => {
                    parts.push(name.to_os_string());
                    dir = parent;
                }
                _ => return normalize(&abs),
            }
        }
    });
    PathId {
        inode: meta.as_ref().map(|m| (m.dev(), m.ino())),
        char_device: meta.is_some_and(|m| m.file_type().is_char_device()),
        canonical,
    }
}

/// `a/./b/../c` → `a/c` (lexically; only for paths that do not exist yet).
fn normalize(p: &Path) -> PathBuf {
    use std::path::Component;
    let mut out = PathBuf::new();
    for c in p.components() {
        match c {
            Component::CurDir => {}
            Component::ParentDir => {
                out.pop();
            }
            other => out.push(other.as_os_str()),
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Held outputs wait under their `.partial` names and get their final names together;
    /// an older final file stays until then, and a plan whose output is missing commits none.
    #[test]
    fn held_outputs_are_renamed_together() {
        let dir = tempfile::tempdir().unwrap();
        let (a, b) = (dir.path().join("a.json"), dir.path().join("b.csv"));
        std::fs::write(&a, b"earlier").unwrap();
        let mut plan = OutputPlan::new();
        plan.output("--summary", &a).output("--csv", &b);
        plan.check().unwrap();
        let held = plan.hold();
        assert!(holds(&a) && holds(&b));
        crate::record::write_atomic(&a, b"new a").unwrap();
        assert_eq!(std::fs::read(&a).unwrap(), b"earlier", "not renamed yet");
        assert_eq!(
            std::fs::read(dir.path().join("a.partial.json")).unwrap(),
            b"new a"
        );
        // b was not written: nothing is committed.
        let e = held.commit().unwrap_err();
        assert!(e.contains("--csv") && e.contains("was not written"), "{e}");
        assert_eq!(std::fs::read(&a).unwrap(), b"earlier");
        assert!(!holds(&a), "released when dropped");

        let held = plan.hold();
        crate::record::write_atomic(&a, b"new a").unwrap();
        crate::record::write_atomic(&b, b"new b").unwrap();
        held.commit().unwrap();
        assert_eq!(std::fs::read(&a).unwrap(), b"new a");
        assert_eq!(std::fs::read(&b).unwrap(), b"new b");
        let mut left: Vec<_> = std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        left.sort();
        assert_eq!(left, ["a.json", "b.csv"]);
    }

    #[test]
    fn inputs_inside_an_output_folder_and_unwritable_paths_are_refused() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        std::fs::create_dir_all(d.join("out/cases")).unwrap();
        std::fs::write(d.join("out/cases/s.toml"), b"x").unwrap();
        std::fs::write(d.join("file"), b"x").unwrap();
        let mut plan = OutputPlan::new();
        plan.input("the scenario", &d.join("out/cases/s.toml"))
            .folder("--out", &d.join("out/./cases"));
        let e = plan.check().unwrap_err();
        assert!(e.contains("(an input) is inside --out"), "{e}");
        let mut plan = OutputPlan::new();
        plan.output("--csv", &d.join("file/sub/x.csv"));
        let e = plan.check().unwrap_err();
        assert!(e.contains("file is not a folder"), "{e}");
        let mut plan = OutputPlan::new();
        plan.folder("--out", &d.join("file"));
        assert!(plan.check().unwrap_err().contains("is not a folder"));
        // Inputs may be read twice; outputs may not clash with them.
        let mut plan = OutputPlan::new();
        plan.input("run A", &d.join("file"))
            .input("run B", &d.join("file"));
        plan.check().unwrap();
        plan.output("--json", &d.join("./file"));
        let e = plan.check().unwrap_err();
        assert!(
            e.contains("--json") && e.contains("run A") && e.contains("(an input)"),
            "{e}"
        );
    }
}
