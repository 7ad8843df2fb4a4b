//! `spurio sweep` in shards and `spurio sweep-merge`: the merged table is the one-machine
//! sweep's table, byte for byte; the staged Slurm scripts, run as array tasks would run them,
//! give the same table. Uses the FMUs of `scripts/build-fmus`.

mod common;
#[path = "../../tests/common/packaged_fmus.rs"]
mod packaged_fmus;

use common::{failed, ok, repo, require_fmus, s, spurio, temp};
use std::path::PathBuf;
use std::process::Command;

const VARY: &str = "sensor.seed=1..12";
const METRICS: [&str; 2] = ["rms(sensor.y[1])", "e_res(sensor.y[2], crane.theta)"];

fn sweep_args<'a>(system: &'a str, extra: &[&'a str]) -> Vec<&'a str> {
    let mut args = vec!["sweep", system, "--vary", VARY, "--threads", "2"];
    for m in METRICS {
        args.extend(["--metric", m]);
    }
    args.extend(extra);
    args
}

/// The one-machine sweep the shards must reproduce, run into a fresh folder.
struct Local {
    /// The crane-sensor system swept.
    system: PathBuf,
    /// The fresh folder `<tmp>/spurio-<name>-<pid>/`.
    dir: PathBuf,
    /// Its runs table (`--out`), `local.csv` in `dir`.
    csv: PathBuf,
    /// The table it printed.
    table: String,
}

fn local_sweep(name: &str) -> Local {
    require_fmus(&["GantryCrane", "Sensor2"]);
    let system = repo().join("examples/systems/crane_sensor.toml");
    let dir = temp(name);
    let csv = dir.join("local.csv");
    let table = ok(spurio(sweep_args(s(&system), &["--out", s(&csv)])));
    Local {
        system,
        dir,
        csv,
        table,
    }
}

#[test]
fn shards_merge_into_the_one_machine_table_byte_for_byte() {
    let Local {
        system,
        dir,
        csv: local_csv,
        table: local,
    } = local_sweep("sweep-shards");
    let local_rows = std::fs::read_to_string(&local_csv).unwrap();
    // A real table: 12 runs, the seed varies the noise, so rows differ.
    assert!(local.contains("| rms(sensor.y[1]) | "), "{local}");
    assert!(local.contains(" | 12/12 |"), "{local}");
    let lines: Vec<&str> = local_rows.lines().collect();
    assert_eq!(
        lines[0],
        "\"sensor.seed\",\"rms(sensor.y[1])\",\"e_res(sensor.y[2];crane.theta)\""
    );
    assert_eq!(lines.len(), 13);
    assert!(lines[1].starts_with("1.0,") && lines[12].starts_with("12.0,"));
    assert_ne!(lines[1][4..], lines[2][4..]);

    // Five shards of 12 runs, run out of order, one of them on a single thread.
    let shards = dir.join("shards");
    std::fs::create_dir_all(&shards).unwrap();
    for i in [3, 0, 4, 1, 2] {
        let spec = format!("{i}/5");
        let out = ok(spurio(sweep_args(
            s(&system),
            &["--shard", &spec, "--shard-out", s(&shards)],
        )));
        assert!(out.contains(&format!("shard {i}/5: runs ")), "{out}");
    }
    let merged_csv = dir.join("merged.csv");
    let merged = ok(spurio(["sweep-merge", s(&shards), "--out", s(&merged_csv)]));
    assert_eq!(merged, local);
    assert_eq!(std::fs::read_to_string(&merged_csv).unwrap(), local_rows);

    // Shard 1 lost: the merge names it and the command that reruns it.
    let lost = shards.join("shard-1.toml");
    let kept = std::fs::read(&lost).unwrap();
    std::fs::remove_file(&lost).unwrap();
    let err = failed(spurio(["sweep-merge", s(&shards), "--out", s(&merged_csv)]));
    assert!(err.contains("1 of 5 shards missing"), "{err}");
    assert!(err.contains("shard 1/5 (runs 3..6)"), "{err}");
    assert!(err.contains("--shard 1/5 --shard-out "), "{err}");
    assert!(
        err.contains("--vary sensor.seed=1..12 --metric 'rms(sensor.y[1])'"),
        "{err}"
    );
    // Progress: 4 of 5 shards, the running table over their 9 runs.
    let progress = ok(spurio(["sweep-merge", "--progress", s(&shards)]));
    assert!(
        progress.starts_with("4/5 shards done (9/12 runs); missing: 1\n"),
        "{progress}"
    );
    assert!(progress.contains(" | 9/9 |"), "{progress}");
    // Rerun and a duplicate under another name.
    std::fs::write(&lost, &kept).unwrap();
    std::fs::write(shards.join("again.toml"), &kept).unwrap();
    let err = failed(spurio(["sweep-merge", s(&shards)]));
    assert!(err.contains("shard 1 appears more than once"), "{err}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn staged_slurm_scripts_run_as_array_tasks_give_the_local_table() {
    let Local {
        system,
        dir,
        csv: local_csv,
        table: local,
    } = local_sweep("sweep-slurm");
    let stage = dir.join("stage");
    let out = ok(spurio(sweep_args(
        s(&system),
        &["--slurm", s(&stage), "--shards", "4", "--time", "00:05:00"],
    )));
    assert!(
        out.contains("staged a sweep of 12 runs in 4 shards"),
        "{out}"
    );
    for f in [
        "sweep.sbatch",
        "merge.sbatch",
        "sweep.toml",
        "system.toml",
        "bin/spurio",
        "fmus/GantryCrane.fmu",
        "fmus/Sensor2.fmu",
    ] {
        assert!(stage.join(f).is_file(), "{f} not staged");
    }
    let script = std::fs::read_to_string(stage.join("sweep.sbatch")).unwrap();
    assert!(
        script.contains("#SBATCH --array=0-3\n#SBATCH --requeue\n"),
        "{script}"
    );
    assert!(script.contains("#SBATCH --time=00:05:00\n"), "{script}");

    // Nothing ran yet.
    let progress = ok(spurio(["sweep-merge", "--progress", s(&stage)]));
    assert_eq!(progress, "0/4 shards done (0/12 runs); missing: all\n");

    let task = |i: usize, restarts: &str| {
        Command::new("bash")
            .arg(stage.join("sweep.sbatch"))
            .env("SLURM_ARRAY_TASK_ID", i.to_string())
            .env("SLURM_ARRAY_JOB_ID", "1")
            .env("SLURM_RESTART_COUNT", restarts)
            .env("SLURM_CPUS_PER_TASK", "1")
            .output()
            .unwrap()
    };
    // The test hook: task 2 fails once (its last allowed attempt here, so it gives up
    // rather than call scontrol), and removes the marker.
    std::fs::create_dir_all(stage.join("inject-failure")).unwrap();
    std::fs::write(stage.join("inject-failure/2"), "").unwrap();
    let attempt = task(2, "2");
    assert_eq!(attempt.status.code(), Some(75));
    assert!(String::from_utf8_lossy(&attempt.stderr).contains("injected failure"));
    assert!(!stage.join("inject-failure/2").exists());
    assert!(!stage.join("shards/shard-2.toml").exists());
    for i in [0, 1, 3] {
        ok(task(i, "0"));
    }
    let progress = ok(spurio(["sweep-merge", "--progress", s(&stage)]));
    assert!(
        progress.starts_with("3/4 shards done (9/12 runs); missing: 2\n"),
        "{progress}"
    );
    let err = failed(spurio(["sweep-merge", s(&stage)]));
    assert!(
        err.contains(&format!(
            "or on Slurm: sbatch --array=2 {}",
            stage.join("sweep.sbatch").canonicalize().unwrap().display()
        )),
        "{err}"
    );
    ok(task(2, "1"));
    let merge = Command::new("bash")
        .arg(stage.join("merge.sbatch"))
        .output()
        .unwrap();
    ok(merge);
    assert_eq!(
        std::fs::read_to_string(stage.join("table.md")).unwrap(),
        local
    );
    assert_eq!(
        std::fs::read(stage.join("runs.csv")).unwrap(),
        std::fs::read(&local_csv).unwrap()
    );
    // A shard of another sweep (another metric) is refused by the staged folder.
    let foreign = dir.join("foreign");
    std::fs::create_dir_all(&foreign).unwrap();
    let mut args = vec!["sweep", s(&system), "--vary", VARY];
    args.extend(["--metric", METRICS[0], "--metric", "final(crane.x)"]);
    args.extend(["--shard", "0/4", "--shard-out", s(&foreign)]);
    ok(spurio(&args));
    std::fs::copy(
        foreign.join("shard-0.toml"),
        stage.join("shards/shard-0.toml"),
    )
    .unwrap();
    let err = failed(spurio(["sweep-merge", s(&stage)]));
    assert!(
        err.contains("belong to another sweep than sha256:"),
        "{err}"
    );
    // Staging again into a folder with shards is refused.
    let err = failed(spurio(sweep_args(s(&system), &["--slurm", s(&stage)])));
    assert!(
        err.contains("holds shard files of an earlier sweep"),
        "{err}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}
