//! Builds the table of the standard's schema files into the library: for each folder of
//! `schema/` (`fmi2`, `fmi3`, `fmi-ls-ref`), `$OUT_DIR/<folder>.rs` holds `&[(file name,
//! text)]` of its `.xsd` files, sorted, each `include_str!`ed, so the folder is the one list
//! of them.

use std::path::Path;

fn main() {
    let manifest = std::env::var("CARGO_MANIFEST_DIR").expect("cargo sets CARGO_MANIFEST_DIR");
    let out = std::env::var("OUT_DIR").expect("cargo sets OUT_DIR");
    for version in ["fmi2", "fmi3", "fmi-ls-ref"] {
        let folder = Path::new(&manifest).join("schema").join(version);
        println!("cargo:rerun-if-changed={}", folder.display());
        let mut files: Vec<_> = std::fs::read_dir(&folder)
            .unwrap_or_else(|e| panic!("{}: {e}", folder.display()))
            .map(|entry| entry.expect("a readable folder entry").path())
            .filter(|path| path.extension().is_some_and(|e| e == "xsd"))
            .collect();
        files.sort();
        let entries: Vec<String> = files
            .iter()
            .map(|path| {
                let name = path.file_name().expect("a file name").to_string_lossy();
                format!("({name:?}, include_str!({:?}))", path.display().to_string())
            })
            .collect();
        let table = format!("&[{}]\n", entries.join(", "));
        std::fs::write(Path::new(&out).join(format!("{version}.rs")), table)
            .unwrap_or_else(|e| panic!("cannot write {version}.rs: {e}"));
    }
}
