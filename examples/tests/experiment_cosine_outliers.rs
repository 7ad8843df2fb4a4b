//! Pins the cosine-with-outliers figures of papers 000 and 001 (needs `scripts/build-fmus`).

mod common;

use common::run_pinned;

#[test]
fn rskf_beats_skf_and_reaches_both_papers_figures() {
    let (_, out) = run_pinned("cosine_outliers", "cosine", 100);
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
}
