//! An experiment run with the FMI 3.0 builds of our FMUs (`build/fmus/fmi3/`) gives the same
//! figures as with the FMI 2.0 builds (`build/fmus/`), bit for bit: the same model code
//! behind either front, and the master moving the same values (FMI 3.0 arrays addressed by
//! the element names the FMI 2.0 FMUs use, so the systems are not edited). The FMUs are
//! built first if they are missing (`packaged_fmus`).

use spurio_experiments::Report;
use spurio_master::fmu::FmiVersion;
use spurio_master::System;
use std::path::{Path, PathBuf};

#[path = "../../master/tests/common/packaged_fmus.rs"]
mod packaged_fmus;

/// `experiment` run from `repo` (its systems under `examples/`, FMUs under `build/fmus/`).
fn run(repo: &Path, experiment: &str, out: &Path, seeds: usize) -> Report {
    let mut reports =
        spurio_experiments::run_all(repo, out, &[experiment.into()], seeds, 0).unwrap();
    reports.remove(0).1
}

/// A copy of the repository's `examples/<experiment>/` in a fresh folder whose
/// `build/fmus` is the FMI 3.0 FMU folder, so the systems' `../../build/fmus/<Id>.fmu` load
/// the FMI 3.0 builds.
fn fmi3_repo(repo: &Path, experiment: &str, root: &Path) -> PathBuf {
    let fmi3 = repo.join("build/fmus/fmi3");
    let examples = root.join("examples").join(experiment);
    std::fs::create_dir_all(&examples).unwrap();
    for entry in std::fs::read_dir(repo.join("examples").join(experiment)).unwrap() {
        let entry = entry.unwrap();
        std::fs::copy(entry.path(), examples.join(entry.file_name())).unwrap();
    }
    std::fs::create_dir_all(root.join("build")).unwrap();
    std::os::unix::fs::symlink(&fmi3, root.join("build/fmus")).unwrap();
    root.to_path_buf()
}

fn same_figures(experiment: &str, seeds: usize) {
    let repo = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..");
    packaged_fmus::packaged_fmus(&repo);
    let tmp = std::env::temp_dir().join(format!(
        "spurio-exp-fmi3-{experiment}-{}",
        std::process::id()
    ));
    let _ = std::fs::remove_dir_all(&tmp);
    let fmi2 = run(&repo, experiment, &tmp.join("out2"), seeds);
    let repo3 = fmi3_repo(&repo, experiment, &tmp.join("repo3"));
    // Every instance of every system of the copy is an FMI 3.0 FMU.
    for entry in std::fs::read_dir(repo3.join("examples").join(experiment)).unwrap() {
        let system = System::from_file(&entry.unwrap().path()).unwrap();
        for instance in system.instances() {
            assert_eq!(instance.fmu.version, FmiVersion::Fmi3, "{}", instance.name);
        }
    }
    let fmi3 = run(&repo3, experiment, &tmp.join("out3"), seeds);
    assert!(!fmi2.figures_of_merit.is_empty());
    assert_eq!(
        fmi3.figures_of_merit,
        fmi2.figures_of_merit,
        "FMI 3.0:\n{}\nFMI 2.0:\n{}",
        fmi3.to_markdown(""),
        fmi2.to_markdown("")
    );
    assert_eq!(fmi3.rows, fmi2.rows);
    let _ = std::fs::remove_dir_all(&tmp);
}

#[test]
fn cosine_outliers_gives_the_same_figures_with_fmi3_fmus() {
    same_figures("cosine_outliers", 3);
}

#[test]
fn distributed_observer_gives_the_same_figures_with_fmi3_fmus() {
    same_figures("distributed_observer", 1);
}
