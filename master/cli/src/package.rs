//! Packaging: turns a compiled FMU library and its catalogue entry into a `.fmu` archive.
//!
//! Layout (FMI 2.0 §2.3): `modelDescription.xml` (generated from the Rust variable table),
//! `binaries/linux64/<modelIdentifier>.so` (Cargo's `lib<modelIdentifier>.so` renamed),
//! `documentation/index.html` (the FMU's page, rendered from `docs/fmus/<id>.md`) and, for
//! variants of dimension-generic FMUs, `resources/variant.cfg`, which the binary reads in
//! `fmi2Instantiate`.

use anyhow::{bail, Context, Result};
use spurio_fmi2::description::CONFIG_FILE;
use spurio_fmi2::Config;
use spurio_fmus::CatalogueEntry;
use std::fs::File;
use std::io::Write;
use std::path::{Path, PathBuf};
use zip::write::SimpleFileOptions;

/// Renders the FMU's Markdown page as a standalone HTML document.
pub fn documentation_html(title: &str, markdown: &str) -> String {
    let parser = pulldown_cmark::Parser::new_ext(markdown, pulldown_cmark::Options::ENABLE_TABLES);
    let mut body = String::new();
    pulldown_cmark::html::push_html(&mut body, parser);
    format!(
        "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n<title>{title}</title>\n<style>body{{font-family:sans-serif;max-width:60em;margin:2em auto;line-height:1.4}}table{{border-collapse:collapse}}td,th{{border:1px solid #ccc;padding:.2em .5em}}code,pre{{background:#f4f4f4}}</style>\n</head>\n<body>\n{body}</body>\n</html>\n"
    )
}

/// Writes `<out_dir>/<stem>.fmu` for one variant of `entry`, taking the binary from `lib_dir`.
pub fn package_variant(
    entry: &CatalogueEntry,
    stem: &str,
    config: &Config,
    lib_dir: &Path,
    out_dir: &Path,
) -> Result<PathBuf> {
    let info = (entry.describe)(config)
        .map_err(|e| anyhow::anyhow!("{}: invalid configuration: {e}", entry.model_identifier))?;
    let library = lib_dir.join(format!("lib{}.so", entry.model_identifier));
    if !library.is_file() {
        bail!(
            "{}: the compiled library {} is missing (build it with `cargo build --release --workspace`)",
            entry.model_identifier,
            library.display()
        );
    }
    let binary =
        std::fs::read(&library).with_context(|| format!("reading {}", library.display()))?;
    std::fs::create_dir_all(out_dir).with_context(|| format!("creating {}", out_dir.display()))?;
    let path = out_dir.join(format!("{stem}.fmu"));
    let file = File::create(&path).with_context(|| format!("creating {}", path.display()))?;
    let mut zip = zip::ZipWriter::new(file);
    let options = SimpleFileOptions::default().compression_method(zip::CompressionMethod::Deflated);
    let mut add = |name: &str, data: &[u8]| -> Result<()> {
        zip.start_file(name, options)?;
        zip.write_all(data)?;
        Ok(())
    };
    add("modelDescription.xml", info.to_xml().as_bytes())?;
    add(
        &format!("binaries/linux64/{}.so", entry.model_identifier),
        &binary,
    )?;
    let page = entry.documentation.replace("](img/", "](");
    add(
        "documentation/index.html",
        documentation_html(&info.model_name, &page).as_bytes(),
    )?;
    for (file_name, bytes) in entry.images {
        add(&format!("documentation/{file_name}"), bytes)?;
    }
    if !config.is_empty() {
        add(
            &format!("resources/{CONFIG_FILE}"),
            config.to_text().as_bytes(),
        )?;
    }
    zip.finish()?;
    Ok(path)
}

/// The committed model description file of a variant.
pub fn committed_model_description(repo: &Path, stem: &str) -> PathBuf {
    repo.join("modelDescription").join(format!("{stem}.xml"))
}
