//! The native module is built by the root's `cargo test --release` (this test makes cargo
//! build the package's cdylib beside the suite, which runs the pytest suite with it:
//! tests/suite/python.rs), and it is the module `gripsim._gripsim` Python imports.

#[test]
fn the_cdylib_is_built_and_exports_the_module_init() {
    let exe = std::env::current_exe().unwrap();
    // target/<profile>/deps/module-<hash>: `cargo test` leaves the cdylib beside it (only
    // `cargo build` copies it up to target/<profile>/).
    let dir = exe.parent().unwrap();
    let lib = dir.join(format!(
        "{}gripsim_py{}",
        std::env::consts::DLL_PREFIX,
        std::env::consts::DLL_SUFFIX
    ));
    let bytes = std::fs::read(&lib).unwrap_or_else(|e| panic!("{}: {e}", lib.display()));
    let init = b"PyInit__gripsim";
    assert!(
        bytes.windows(init.len()).any(|w| w == init),
        "{} exports no PyInit__gripsim",
        lib.display()
    );
}
