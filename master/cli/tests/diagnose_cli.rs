//! `spurio diagnose` on a results CSV: the Grubbs figures of docs/diagnostics.md §3 and the histogram PNG.

mod common;
#[path = "../../tests/common/packaged_fmus.rs"]
mod packaged_fmus;

use common::{failed, ok, repo, require_fmus, s, spurio, temp};

#[test]
fn diagnose_reports_grubbs_moments_e_res_and_writes_the_histogram() {
    let dir = temp("diagnose");
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
    let report = ok(spurio([
        "diagnose",
        s(&csv),
        "--column",
        "y",
        "--clean",
        "y_clean",
        "--png",
        s(&png),
    ]));
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
    let csv = temp("diagnose-missing").join("r.csv");
    std::fs::write(&csv, "\"time\",\"x\"\n0,1\n1,2\n").unwrap();
    let err = failed(spurio(["diagnose", s(&csv), "--column", "theta"]));
    assert!(
        err.contains("no column `theta`") && err.contains("r.csv"),
        "{err}"
    );
}

#[test]
fn diagnose_reads_what_run_writes_names_with_commas_included() {
    require_fmus(&["DualKalmanFilter"]);
    let csv = temp("run-diagnose").join("r.csv");
    let system = repo().join("examples/crane_adaptive/dkf.toml");
    ok(spurio(["run", s(&system), "--out", s(&csv)]));
    let header = std::fs::read_to_string(&csv).unwrap();
    assert!(header.starts_with("\"time\","), "{}", &header[..80]);
    assert!(header.contains("\"est.A_hat[1,1]\""));
    let report = ok(spurio(["diagnose", s(&csv), "--column", "est.A_hat[1,1]"]));
    // 40 s at 0.05 s: 801 communication points.
    assert!(report.contains("| samples N | 801 |"), "{report}");
}
