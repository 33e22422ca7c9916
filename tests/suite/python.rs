//! The Python package (python/): its native module, built by this same `cargo test --release`
//! (the workspace member gripsim-py), is assembled with the package's Python files into a
//! temporary folder, and the package's pytest suite (python/tests) runs on it in the test
//! venv (tests/py/setup_venv.py), against the CLI binary of this build.

use crate::common::{venv, ROOT};
use std::path::{Path, PathBuf};
use std::process::Command;

/// The native module of this build: `cargo test` leaves the cdylib in target/<profile>/deps/
/// beside this test binary (`cargo build` also copies it to target/<profile>/).
fn native_module() -> PathBuf {
    let exe = std::env::current_exe().unwrap();
    let deps = exe.parent().unwrap();
    let name = format!(
        "{}gripsim_py{}",
        std::env::consts::DLL_PREFIX,
        std::env::consts::DLL_SUFFIX
    );
    [deps.join(&name), deps.parent().unwrap().join(&name)]
        .into_iter()
        .find(|p| p.exists())
        .unwrap_or_else(|| panic!("no {name} in {}: build the workspace", deps.display()))
}

/// The package `gripsim` in `dir`: python/gripsim's files and the native module as
/// `_gripsim.abi3.so` (what `pip install ./python` installs).
pub fn assemble(dir: &Path) -> PathBuf {
    let pkg = dir.join("gripsim");
    std::fs::create_dir_all(&pkg).unwrap();
    for e in std::fs::read_dir(Path::new(ROOT).join("python/gripsim")).unwrap() {
        let p = e.unwrap().path();
        if matches!(
            p.extension().and_then(|x| x.to_str()),
            Some("py" | "pyi" | "typed")
        ) {
            std::fs::copy(&p, pkg.join(p.file_name().unwrap())).unwrap();
        }
    }
    std::fs::copy(native_module(), pkg.join("_gripsim.abi3.so")).unwrap();
    dir.to_path_buf()
}

#[test]
fn the_python_package_passes_its_pytest_suite() {
    let dir = tempfile::tempdir().unwrap();
    let path = assemble(dir.path());
    let out = Command::new(venv().join("bin/python"))
        .args([
            "-m",
            "pytest",
            "python/tests",
            "-q",
            "-p",
            "no:cacheprovider",
        ])
        .current_dir(ROOT)
        .env("PYTHONPATH", &path)
        .env("GRIPSIM_BIN", env!("CARGO_BIN_EXE_gripsim"))
        .env("PYTHONDONTWRITEBYTECODE", "1")
        .output()
        .expect("the venv's python runs");
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    println!("{text}");
    assert!(out.status.success(), "pytest failed:\n{text}");
    assert!(text.contains(" passed"), "pytest ran nothing:\n{text}");
}
