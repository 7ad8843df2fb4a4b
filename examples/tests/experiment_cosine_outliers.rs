//! Pins the cosine-with-outliers figures of papers 000 and 001 (needs `scripts/build-fmus`).

mod common;

use common::{close, run_experiment};

#[test]
fn rskf_beats_skf_and_reaches_both_papers_figures() {
    let (report, out) = run_experiment("cosine_outliers", "cosine", 100);
    let report = &report;
    assert!(report.all_goals_met(), "{}", report.to_markdown(""));
    // Paper 000: literal filters (an independent numpy run: 0.179, 0.0121).
    close(report, "e_res_skf_000", 0.1735, 0.01);
    close(report, "e_res_rskf_000", 0.01213, 2e-4);
    assert!(report.value("e_res_rskf_000").unwrap() <= 0.0124);
    close(report, "outliers_000", 48.7, 1.0);
    // Paper 001: outliers in the first half; the start-up transient and its removal.
    close(report, "e_res_skf_001", 0.1785, 0.01);
    close(report, "e_res_rskf_001_literal", 0.0124, 4e-4);
    close(report, "e_res_rskf_001", 0.0065, 4e-4);
    close(report, "e_res_rskf_001_no_outliers", 0.0113, 4e-4);
    close(report, "outliers_001", 50.0, 1.0);
    close(report, "kurtosis_rskf_001_segments", -0.87, 0.1);
    close(report, "kurtosis_skf_001_segments", 2.97, 0.5);
    // Grubbs: the exact critical value and the paper's ≈ 10 rejections of one pass.
    close(report, "grubbs_critical", 4.0400, 5e-5);
    close(report, "grubbs_single_pass", 10.4, 0.8);
    // The recorded clean value is the cosine at the row's own time (the Sensor's y_clean
    // feeds no connection: the master re-reads it after setting the Sensor's input).
    let csv = std::fs::read_to_string(out.join("cosine_outliers/paper000_seed1.csv")).unwrap();
    let header: Vec<&str> = csv.lines().next().unwrap().split(',').collect();
    let clean = header
        .iter()
        .position(|h| *h == "\"sensor.y_clean[1]\"")
        .unwrap();
    for line in csv.lines().skip(1).take(300) {
        let fields: Vec<f64> = line.split(',').map(|f| f.parse().unwrap()).collect();
        let expected = (2.0 * std::f64::consts::PI * fields[0] / 25.0).cos();
        assert!((fields[clean] - expected).abs() < 1e-9, "{line}");
    }
    for file in [
        "paper000_signals.png",
        "paper000_histogram.png",
        "paper001_signals.png",
        "paper000_seed1.csv",
        "paper001_seed1.csv",
    ] {
        assert!(out.join("cosine_outliers").join(file).is_file(), "{file}");
    }
}
