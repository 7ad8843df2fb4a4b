//! `spurio diagnose` on a results CSV: the Grubbs figures of docs/diagnostics.md §3 and the histogram PNG.

use std::process::Command;

fn spurio() -> Command {
    Command::new(env!("CARGO_BIN_EXE_spurio"))
}

#[test]
fn diagnose_reports_grubbs_moments_e_res_and_writes_the_histogram() {
    let dir = std::env::temp_dir().join(format!("spurio-diagnose-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let csv = dir.join("results.csv");
    // 1000 samples of a cosine with three planted outliers; the clean column beside it.
    let mut text = String::from("\"time\",\"y\",\"y_clean\"\n");
    for k in 0..1000 {
        let clean = (2.0 * std::f64::consts::PI * 4.0 * k as f64 / 1000.0).cos();
        let spike = match k {
            100 => 6.0,
            500 => -5.5,
            900 => 5.0,
            _ => 0.0,
        };
        text.push_str(&format!(
            "{},{:?},{:?}\n",
            k as f64 * 0.01,
            clean + spike,
            clean
        ));
    }
    std::fs::write(&csv, text).unwrap();
    let png = dir.join("hist.png");
    let out = spurio()
        .args([
            "diagnose",
            csv.to_str().unwrap(),
            "--column",
            "y",
            "--clean",
            "y_clean",
            "--png",
        ])
        .arg(&png)
        .output()
        .unwrap();
    let report = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{report}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(report.contains("| samples N | 1000 |"), "{report}");
    // docs/diagnostics.md §3: exact two-sided critical value for N = 1000, α = 0.05.
    assert!(report.contains("| 4.0400 |"), "{report}");
    assert!(
        report.contains("| outliers rejected by iterated Grubbs | 3 |"),
        "{report}"
    );
    // E_res = (36 + 30.25 + 25) / 1000
    assert!(report.contains("| 0.091250 |"), "{report}");
    let bytes = std::fs::read(&png).unwrap();
    assert_eq!(&bytes[1..4], b"PNG");
}

#[test]
fn diagnose_names_a_missing_column_and_the_file() {
    let dir = std::env::temp_dir().join(format!("spurio-diagnose-missing-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let csv = dir.join("r.csv");
    std::fs::write(&csv, "\"time\",\"x\"\n0,1\n1,2\n").unwrap();
    let out = spurio()
        .args(["diagnose", csv.to_str().unwrap(), "--column", "theta"])
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("no column `theta`") && err.contains("r.csv"),
        "{err}"
    );
}

#[test]
fn diagnose_reads_what_run_writes_names_with_commas_included() {
    let repo = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..");
    assert!(
        repo.join("build/fmus/DualKalmanFilter.fmu").is_file(),
        "run scripts/build-fmus first"
    );
    let dir = std::env::temp_dir().join(format!("spurio-run-diagnose-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let csv = dir.join("r.csv");
    let run = spurio()
        .arg("run")
        .arg(repo.join("examples/crane_adaptive/dkf.toml"))
        .arg("--out")
        .arg(&csv)
        .output()
        .unwrap();
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let header = std::fs::read_to_string(&csv).unwrap();
    assert!(header.starts_with("\"time\","), "{}", &header[..80]);
    assert!(header.contains("\"est.A_hat[1,1]\""));
    let out = spurio()
        .args([
            "diagnose",
            csv.to_str().unwrap(),
            "--column",
            "est.A_hat[1,1]",
        ])
        .output()
        .unwrap();
    let report = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{report}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    // 40 s at 0.05 s: 801 communication points.
    assert!(report.contains("| samples N | 801 |"), "{report}");
}
