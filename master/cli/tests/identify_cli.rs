//! `spurio identify`: Dahlquist's k (ẋ = −k x, x = e^{−kt}) from its exact solution plus
//! seeded noise and 5 % outliers, offline and online, and the messages for bad names and an
//! FMU without Model Exchange, given before anything runs.

mod common;
#[path = "../../tests/common/packaged_fmus.rs"]
mod packaged_fmus;

use common::{failed, ok, s, spurio, temp};
use std::io::{Read, Write};
use std::path::{Path, PathBuf};

const K: f64 = 1.5;

fn dahlquist() -> PathBuf {
    common::repo().join("tests/third_party/reference-fmus/fmi2/Dahlquist.fmu")
}

/// x(t) = e^{−K t} every 0.05 s to 5 s, plus N(0, 0.005²) (SplitMix64, Box–Muller) and, on
/// 5 % of the samples, ±0.1 (20 σ); one missing sample.
fn write_data(path: &Path) {
    let mut state: u64 = 28;
    let mut uniform = move || {
        state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = state;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
        ((z >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    };
    let mut text = String::from("time,level\n");
    for k in 0..=100 {
        let t = k as f64 * 0.05;
        let (a, b) = (uniform(), uniform());
        let noise = 0.005 * (-2.0 * a.ln()).sqrt() * (2.0 * std::f64::consts::PI * b).cos();
        let outlier = if uniform() < 0.05 { 0.1 } else { 0.0 };
        let y = (-K * t).exp() + noise + outlier;
        if k == 50 {
            text += &format!("{t},\n");
        } else {
            text += &format!("{t},{y}\n");
        }
    }
    std::fs::write(path, text).unwrap();
}

/// The estimate of `k` in `dir/estimates.csv` and its standard error.
fn estimate(dir: &Path) -> (f64, f64) {
    let text = std::fs::read_to_string(dir.join("estimates.csv")).unwrap();
    let mut lines = text.lines();
    assert_eq!(
        lines.next(),
        Some("parameter,estimate,standard_error,start")
    );
    let row: Vec<&str> = lines.next().unwrap().split(',').collect();
    assert_eq!(row[0], "k");
    assert_eq!(
        row[3].parse::<f64>().unwrap(),
        1.0,
        "the start is the FMU's"
    );
    (row[1].parse().unwrap(), row[2].parse().unwrap())
}

fn identify(dir: &Path, data: &Path, method: &str, robust: &str) -> (f64, f64) {
    let out = dir.join(format!("{method}-{robust}"));
    let text = ok(spurio([
        "identify",
        s(&dahlquist()),
        "--data",
        s(data),
        "--output",
        "x=level",
        "--free",
        "k",
        "--method",
        method,
        "--robust",
        robust,
        "--noise",
        "2.5e-5",
        "--validate",
        "0.3",
        "--out",
        s(&out),
    ]));
    assert!(
        text.contains("| `k` |") && text.contains("one-step fit"),
        "{text}"
    );
    let report = std::fs::read_to_string(out.join("report.md")).unwrap();
    assert!(report.contains("## Outliers"), "{report}");
    estimate(&out)
}

#[test]
fn dahlquist_k_offline_and_online_robust_beats_plain() {
    let dir = temp("identify-dahlquist");
    let data = dir.join("data.csv");
    write_data(&data);
    let (ml, se) = identify(&dir, &data, "ml", "huber");
    let (ml_plain, _) = identify(&dir, &data, "ml", "none");
    let (ukf, sd) = identify(&dir, &data, "ukf", "huber");
    let (ukf_plain, _) = identify(&dir, &data, "ukf", "none");
    let (ekf, ekf_sd) = identify(&dir, &data, "ekf", "huber");
    println!(
        "k: ml huber {ml} ± {se}, none {ml_plain}; ukf huber {ukf} ± {sd}, none {ukf_plain}; ekf huber {ekf} ± {ekf_sd}; ratios {:.1}, {:.1}",
        (ml_plain - K).abs() / (ml - K).abs(),
        (ukf_plain - K).abs() / (ukf - K).abs()
    );
    assert!(
        (ml - K).abs() < 0.01 * K && se > 0.0 && se < 0.01,
        "{ml} ± {se}"
    );
    assert!((ukf - K).abs() < 2.0 * sd, "{ukf} ± {sd}");
    assert!((ekf - K).abs() < 2.0 * ekf_sd, "{ekf} ± {ekf_sd}");
    assert!(
        (ml_plain - K).abs() > 2.0 * (ml - K).abs(),
        "{ml_plain} vs {ml}"
    );
    assert!(dir.join("ukf-huber/trajectory.csv").is_file());
    assert!(dir.join("ekf-huber/trajectory.csv").is_file());
    let _ = std::fs::remove_dir_all(&dir);
}

/// `source` rewritten with its model description passed through `edit`.
fn edited_copy(source: &Path, path: &Path, edit: impl Fn(&str) -> String) {
    let mut archive = zip::ZipArchive::new(std::fs::File::open(source).unwrap()).unwrap();
    let mut zip = zip::ZipWriter::new(std::fs::File::create(path).unwrap());
    let options = zip::write::SimpleFileOptions::default();
    for i in 0..archive.len() {
        let mut entry = archive.by_index(i).unwrap();
        if entry.is_dir() {
            continue;
        }
        let name = entry.name().unwrap().to_string();
        let mut data = Vec::new();
        entry.read_to_end(&mut data).unwrap();
        if name == "modelDescription.xml" {
            data = edit(&String::from_utf8(data).unwrap()).into_bytes();
        }
        zip.start_file(name, options).unwrap();
        zip.write_all(&data).unwrap();
    }
    zip.finish().unwrap();
}

#[test]
fn bad_names_and_an_fmu_without_model_exchange_are_refused_before_anything_runs() {
    let dir = temp("identify-names");
    // No data file: the FMU and its names are checked first.
    let missing = dir.join("absent.csv");
    let run = |fmu: &Path, output: &str, free: &str| {
        failed(spurio([
            "identify",
            s(fmu),
            "--data",
            s(&missing),
            "--output",
            output,
            "--free",
            free,
        ]))
    };
    let said = run(&dahlquist(), "x", "x");
    assert!(
        said.contains("`x` cannot be estimated") && said.contains("parameters are k"),
        "{said}"
    );
    let said = run(&dahlquist(), "y", "k");
    assert!(said.contains("`y` is not a variable"), "{said}");
    // A value set for the experiment must be a parameter of the FMU, checked as early; a
    // start must be a number.
    let with = |flag: &str, value: &str| {
        failed(spurio([
            "identify",
            s(&dahlquist()),
            "--data",
            s(&missing),
            "--output",
            "x",
            "--free",
            "k",
            flag,
            value,
        ]))
    };
    let said = with("--set", "x=2");
    assert!(
        said.contains("`x` cannot be set") && said.contains("an output"),
        "{said}"
    );
    let said = with("--start", "k=fast");
    assert!(said.contains("`fast` is not a number"), "{said}");
    let cs_only = dir.join("DahlquistCS.fmu");
    edited_copy(&dahlquist(), &cs_only, |text| {
        let start = text.find("<ModelExchange").unwrap();
        let end =
            start + text[start..].find("</ModelExchange>").unwrap() + "</ModelExchange>".len();
        format!("{}{}", &text[..start], &text[end..])
    });
    let said = run(&cs_only, "x", "k");
    assert!(said.to_lowercase().contains("model exchange"), "{said}");
    let _ = std::fs::remove_dir_all(&dir);
}
