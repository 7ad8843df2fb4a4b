//! The packaged FMUs that the integration tests run (`build/fmus/<stem>.fmu`, FMI 2.0, and
//! `build/fmus/fmi3/<stem>.fmu`), built on first use, so that `cargo test` passes on a fresh
//! clone.
//!
//! The first test that needs them runs `scripts/build-fmus --host-only` (the workspace built
//! with `cargo build --release`, every FMU packaged for linux64 by `spurio package`) under a
//! file lock, `build/.build-fmus.lock`; the tests running beside it, in this process or in the
//! other test binaries, wait on the lock and then find the FMUs built. FMUs already there (for
//! example from a full `scripts/build-fmus`, with the win64 and aarch64-linux binaries) are
//! used as they are: remove `build/fmus` to have them built again.
//!
//! One file for every crate whose tests run packaged FMUs: the engine's and the CLI's tests
//! and the experiments' include it by path.

use std::path::{Path, PathBuf};
use std::process::Command;

/// `build/fmus` of the repository `repo`, its FMUs built first if they are missing.
pub fn packaged_fmus(repo: &Path) -> PathBuf {
    let dir = repo.join("build/fmus");
    if is_built(repo, &dir) {
        return dir;
    }
    let build = repo.join("build");
    std::fs::create_dir_all(&build)
        .unwrap_or_else(|e| panic!("cannot create {}: {e}", build.display()));
    let lock_path = build.join(".build-fmus.lock");
    let lock = std::fs::OpenOptions::new()
        .create(true)
        .truncate(false)
        .write(true)
        .open(&lock_path)
        .unwrap_or_else(|e| panic!("cannot open {}: {e}", lock_path.display()));
    lock.lock()
        .unwrap_or_else(|e| panic!("cannot lock {}: {e}", lock_path.display()));
    if !is_built(repo, &dir) {
        let script = repo.join("scripts/build-fmus");
        let out = Command::new(&script)
            .arg("--host-only")
            .current_dir(repo)
            .output()
            .unwrap_or_else(|e| panic!("cannot run {}: {e}", script.display()));
        assert!(
            out.status.success() && is_built(repo, &dir),
            "`scripts/build-fmus --host-only` failed ({}):\n{}\n{}",
            out.status,
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr)
        );
    }
    dir
}

/// Whether `dir` holds every bundled FMU: one FMI 2.0 archive for each committed model
/// description (`modelDescription/<stem>.xml`) and one FMI 3.0 archive for each
/// `modelDescription/fmi3/<stem>.xml` (a build stopped half-way is not taken for a whole one).
fn is_built(repo: &Path, dir: &Path) -> bool {
    [
        ("modelDescription", dir.to_path_buf()),
        ("modelDescription/fmi3", dir.join("fmi3")),
    ]
    .iter()
    .all(|(committed, out)| {
        std::fs::read_dir(repo.join(committed)).is_ok_and(|entries| {
            entries.filter_map(Result::ok).all(|entry| {
                let path = entry.path();
                match (path.extension(), path.file_stem()) {
                    (Some(ext), Some(stem)) if ext == "xml" => {
                        out.join(stem).with_extension("fmu").is_file()
                    }
                    _ => true,
                }
            })
        })
    })
}
