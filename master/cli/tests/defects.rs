//! `spurio validate` on hand-made defects, one test each: the cases are data,
//! `tests/defects/defects.toml` (what to break in which valid FMU, and the report lines that
//! must name it). Each case copies the FMU with its model description edited (and entries
//! added), runs `spurio validate` on it and checks the exit code and the lines.

#[path = "../../tests/common/mod.rs"]
mod engine;

use libtest_mimic::{Arguments, Failed, Trial};
use serde::Deserialize;
use std::path::{Path, PathBuf};

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct Cases {
    defect: Vec<Defect>,
}

#[derive(Deserialize, Clone)]
#[serde(deny_unknown_fields)]
struct Defect {
    name: String,
    fmu: String,
    #[serde(default)]
    edit: Vec<Edit>,
    #[serde(default)]
    add: Vec<Entry>,
    #[serde(default = "one")]
    exit: i32,
    expect: Vec<String>,
}

fn one() -> i32 {
    1
}

/// `replace` → `with`: every occurrence, or the first `count`; only after `after`.
#[derive(Deserialize, Clone)]
#[serde(deny_unknown_fields)]
struct Edit {
    replace: String,
    with: String,
    count: Option<usize>,
    after: Option<String>,
}

#[derive(Deserialize, Clone)]
#[serde(deny_unknown_fields)]
struct Entry {
    entry: String,
    text: String,
}

/// The FMU a case names: `reference/<version>/<Model>` or `ours/[fmi3/]<Model>`.
fn source(name: &str) -> PathBuf {
    if let Some(rest) = name.strip_prefix("reference/") {
        let (version, model) = rest.split_once('/').expect("reference/<version>/<Model>");
        return engine::reference(version, model);
    }
    let ours = name.strip_prefix("ours/").expect("reference/… or ours/…");
    engine::fmus().join(format!("{ours}.fmu"))
}

fn edited(text: &str, edits: &[Edit]) -> Result<String, Failed> {
    let mut text = text.to_string();
    for e in edits {
        let at = match &e.after {
            Some(marker) => text.find(marker.as_str()).ok_or(format!("no `{marker}`"))?,
            None => 0,
        };
        let (head, tail) = text.split_at(at);
        let tail = match e.count {
            Some(n) => tail.replacen(&e.replace, &e.with, n),
            None => tail.replace(&e.replace, &e.with),
        };
        let changed = format!("{head}{tail}");
        if changed == text {
            return Err(format!("the edit `{}` changes nothing", e.replace).into());
        }
        text = changed;
    }
    Ok(text)
}

fn check(case: &Defect, folder: &Path) -> Result<(), Failed> {
    let extra: Vec<(&str, &[u8], u32)> = case
        .add
        .iter()
        .map(|a| (a.entry.as_str(), a.text.as_bytes(), 0o644))
        .collect();
    let failure = std::cell::RefCell::new(None);
    let bytes = engine::rewrite(
        &source(&case.fmu),
        |name, data| {
            if name != "modelDescription.xml" {
                return Some(data);
            }
            match edited(&String::from_utf8_lossy(&data), &case.edit) {
                Ok(text) => Some(text.into_bytes()),
                Err(e) => {
                    *failure.borrow_mut() = Some(e);
                    Some(data)
                }
            }
        },
        &extra,
    );
    if let Some(e) = failure.into_inner() {
        return Err(e);
    }
    std::fs::create_dir_all(folder)?;
    let fmu = folder.join(format!("{}.fmu", case.name));
    std::fs::write(&fmu, bytes)?;
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_spurio"))
        .arg("validate")
        .arg(&fmu)
        .output()?;
    let report = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    if out.status.code() != Some(case.exit) {
        return Err(format!(
            "exit {:?}, expected {}:\n{report}{stderr}",
            out.status.code(),
            case.exit
        )
        .into());
    }
    let lines: Vec<&str> = report.lines().collect();
    for expected in &case.expect {
        if !lines.iter().any(|l| l.contains(expected.as_str())) {
            return Err(format!("no line `{expected}` in:\n{report}").into());
        }
    }
    Ok(())
}

fn main() {
    let arguments = Arguments::from_args();
    let file = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/defects/defects.toml");
    let text = std::fs::read_to_string(&file).expect("tests/defects/defects.toml");
    let cases: Cases = toml::from_str(&text).expect("tests/defects/defects.toml");
    let root = std::env::temp_dir().join(format!("spurio-defects-{}", std::process::id()));
    let trials = cases
        .defect
        .into_iter()
        .map(|case| {
            let folder = root.join(&case.name);
            Trial::test(case.name.clone(), move || {
                let result = check(&case, &folder);
                let _ = std::fs::remove_dir_all(&folder);
                result
            })
        })
        .collect();
    let conclusion = libtest_mimic::run(&arguments, trials);
    let _ = std::fs::remove_dir_all(&root);
    conclusion.exit();
}
