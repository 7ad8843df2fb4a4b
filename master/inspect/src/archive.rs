//! What an FMU archive holds, read without unpacking it: the names of its entries, the text
//! of its `modelDescription.xml` and of the other XML files the standard defines (each at
//! most [`MAX_MODEL_DESCRIPTION`] bytes, counted while inflating, since a declared size can
//! lie).

use crate::InspectError;
use std::io::Read;
use std::path::Path;

/// The largest model description read: 64 MiB, the engine loader's default bound.
pub const MAX_MODEL_DESCRIPTION: u64 = 64 << 20;

/// The entries and the model description of an FMU archive.
pub struct Archive {
    /// Entry names as written (folders end with `/`).
    pub entries: Vec<String>,
    /// The text of `modelDescription.xml`.
    pub model_description: String,
    /// The other XML files of the standard the archive has, (entry name, text):
    /// `terminalsAndIcons/terminalsAndIcons.xml`, `sources/buildDescription.xml` and the
    /// layered standards' `extra/<name>/fmi-ls-manifest.xml`.
    pub documents: Vec<(String, String)>,
}

/// Whether the entry `name` is one of the standard's XML files besides the model
/// description.
fn is_document(name: &str) -> bool {
    name == "terminalsAndIcons/terminalsAndIcons.xml"
        || name == "sources/buildDescription.xml"
        || name
            .strip_prefix("extra/")
            .and_then(|rest| rest.strip_suffix("/fmi-ls-manifest.xml"))
            .is_some_and(|layer| !layer.is_empty() && !layer.contains('/'))
}

/// The text of the entry `name`, at most [`MAX_MODEL_DESCRIPTION`] bytes of UTF-8.
fn text(zip: &mut zip::ZipArchive<std::fs::File>, name: &str) -> Result<String, InspectError> {
    let entry = zip
        .by_name(name)
        .map_err(|e| InspectError::Open(format!("{name}: {e}")))?;
    let mut bytes = Vec::new();
    entry
        .take(MAX_MODEL_DESCRIPTION + 1)
        .read_to_end(&mut bytes)
        .map_err(|e| InspectError::Open(format!("{name}: {e}")))?;
    if bytes.len() as u64 > MAX_MODEL_DESCRIPTION {
        return Err(InspectError::TooLarge(
            name.to_string(),
            MAX_MODEL_DESCRIPTION,
        ));
    }
    String::from_utf8(bytes).map_err(|e| InspectError::IllFormed {
        file: name.to_string(),
        reason: format!("it is not UTF-8: {e}"),
    })
}

impl Archive {
    /// Reads the archive at `path`.
    pub fn read(path: &Path) -> Result<Self, InspectError> {
        let file = std::fs::File::open(path).map_err(|e| InspectError::Open(e.to_string()))?;
        let mut zip =
            zip::ZipArchive::new(file).map_err(|e| InspectError::NotZip(e.to_string()))?;
        let entries = zip
            .file_names()
            .map(|name| name.map(|n| n.into_owned()))
            .collect::<Result<Vec<String>, _>>()
            .map_err(|e| InspectError::NotZip(e.to_string()))?;
        if !entries.iter().any(|e| e == "modelDescription.xml") {
            return Err(InspectError::NoModelDescription);
        }
        let model_description = text(&mut zip, "modelDescription.xml")?;
        let mut documents = Vec::new();
        for name in entries.iter().filter(|e| is_document(e)) {
            documents.push((name.clone(), text(&mut zip, name)?));
        }
        Ok(Self {
            entries,
            model_description,
            documents,
        })
    }

    /// The platform folders under `binaries/` (`linux64`, `x86_64-linux`, …), sorted.
    pub fn platforms(&self) -> Vec<String> {
        let mut platforms: Vec<String> = self
            .entries
            .iter()
            .filter_map(|e| e.strip_prefix("binaries/"))
            .filter_map(|rest| rest.split_once('/'))
            .map(|(platform, _)| platform.to_string())
            .filter(|p| !p.is_empty())
            .collect();
        platforms.sort();
        platforms.dedup();
        platforms
    }

    /// Whether the archive carries the model's C sources (`sources/`).
    pub fn has_sources(&self) -> bool {
        self.entries
            .iter()
            .any(|e| e.starts_with("sources/") && !e.ends_with('/'))
    }

    /// Whether the archive has the file `name`.
    pub fn has(&self, name: &str) -> bool {
        self.entries.iter().any(|e| e == name)
    }
}
