//! What the CLI tests share: running the `spurio` binary, its output on success and on
//! failure, the repository and its packaged FMUs, fresh scratch folders.

#![allow(dead_code)]

use std::ffi::OsStr;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// The repository root.
pub fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// Asserts that each of `fmus` (e.g. `"GantryCrane"`) is packaged in `build/fmus`, built
/// first if the FMUs are missing (`master/tests/common/packaged_fmus.rs`, which every test
/// crate that includes this file names `crate::packaged_fmus`: included by path, or, where
/// the engine's test helpers are included too, theirs).
pub fn require_fmus(fmus: &[&str]) {
    let dir = crate::packaged_fmus::packaged_fmus(&repo());
    for fmu in fmus {
        let path = dir.join(format!("{fmu}.fmu"));
        assert!(path.is_file(), "no {}", path.display());
    }
}

/// Runs `spurio` with `args`.
pub fn spurio<S: AsRef<OsStr>>(args: impl IntoIterator<Item = S>) -> Output {
    Command::new(env!("CARGO_BIN_EXE_spurio"))
        .args(args)
        .output()
        .unwrap()
}

/// The standard output of a command that must succeed.
pub fn ok(out: Output) -> String {
    let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
    assert!(
        out.status.success(),
        "{stdout}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    stdout
}

/// The standard error of a command that must fail.
pub fn failed(out: Output) -> String {
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(
        !out.status.success(),
        "expected a failure\n{}\n{stderr}",
        String::from_utf8_lossy(&out.stdout)
    );
    stderr
}

/// A fresh, empty folder `<tmp>/spurio-<name>-<pid>/`.
pub fn temp(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("spurio-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// `p` as a command-line argument.
pub fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}
