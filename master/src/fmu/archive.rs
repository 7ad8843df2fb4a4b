//! Unpacking an FMU archive into a fresh temporary folder, refusing whatever could reach
//! outside it or exhaust the machine: absolute or `..` entry names, symbolic links and any
//! entry that is neither a plain file nor a folder, more entries or more bytes than the
//! [`LoadLimits`] allow. Sizes are checked twice: as declared in the archive, then counted
//! while inflating (a declared size can lie). On any error the folder is removed.

use super::folder::{Unpacked, MODEL_DESCRIPTION};
use super::{LoadError, LoadLimits};
use std::io::{Read, Write};
use std::path::{Component, Path, PathBuf};

fn archive_error(file: &Path, reason: impl ToString) -> LoadError {
    LoadError::Archive {
        file: file.to_path_buf(),
        reason: reason.to_string(),
    }
}

fn unsafe_entry(file: &Path, entry: &str, reason: &str) -> LoadError {
    LoadError::UnsafeEntry {
        file: file.to_path_buf(),
        entry: entry.to_string(),
        reason: reason.to_string(),
    }
}

/// Why the entry name `name` cannot be unpacked as it stands, if it cannot: an absolute
/// path (`/x`, `\x`, `C:x`) or one with a `..` component. Zip names use `/`; a `\` is
/// treated as a separator too, so a name cannot hide a `..` behind it.
fn name_problem(name: &str) -> Option<&'static str> {
    if name.starts_with('/') || name.starts_with('\\') {
        return Some("it is an absolute path");
    }
    let bytes = name.as_bytes();
    if bytes.len() >= 2 && bytes[1] == b':' && bytes[0].is_ascii_alphabetic() {
        return Some("it is an absolute path");
    }
    if name.contains('\0') {
        return Some("it contains a NUL character");
    }
    if name.split(['/', '\\']).any(|c| c == "..") {
        return Some("it has a `..` component");
    }
    None
}

/// File type bits of a Unix mode.
const S_IFMT: u32 = 0o170_000;
const S_IFREG: u32 = 0o100_000;
const S_IFDIR: u32 = 0o040_000;

/// Opens `path` as a zip archive, checks every entry and unpacks it under `temp_root`.
pub(super) fn unpack(
    path: &Path,
    limits: &LoadLimits,
    temp_root: &Path,
) -> Result<Unpacked, LoadError> {
    let file = std::fs::File::open(path).map_err(|e| archive_error(path, e))?;
    let mut archive = zip::ZipArchive::new(file).map_err(|e| LoadError::NotZip {
        file: path.to_path_buf(),
        reason: e.to_string(),
    })?;
    if archive.len() > limits.max_entries {
        return Err(LoadError::TooLarge {
            file: path.to_path_buf(),
            what: format!("the archive has {} entries", archive.len()),
            limit: format!("at most {} entries (max_entries)", limits.max_entries),
        });
    }

    // First pass: names, kinds and declared sizes, before anything is written.
    let mut names = Vec::with_capacity(archive.len());
    let mut declared_total: u64 = 0;
    let mut has_description = false;
    for i in 0..archive.len() {
        let entry = archive
            .by_index_raw(i)
            .map_err(|e| archive_error(path, e))?;
        let name = entry
            .name()
            .map_err(|e| archive_error(path, e))?
            .to_string();
        if let Some(reason) = name_problem(&name) {
            return Err(unsafe_entry(path, &name, reason));
        }
        if entry.enclosed_name().is_none() {
            return Err(unsafe_entry(
                path,
                &name,
                "it would unpack outside the FMU's folder",
            ));
        }
        if entry.is_symlink() {
            return Err(unsafe_entry(path, &name, "it is a symbolic link"));
        }
        if let Some(mode) = entry.unix_mode() {
            let kind = mode & S_IFMT;
            if kind != 0 && kind != S_IFREG && kind != S_IFDIR {
                return Err(unsafe_entry(
                    path,
                    &name,
                    &format!("it is not a plain file or folder (Unix mode {mode:o})"),
                ));
            }
        }
        if name == MODEL_DESCRIPTION {
            has_description = true;
            if entry.size() > limits.max_model_description {
                return Err(LoadError::TooLarge {
                    file: path.to_path_buf(),
                    what: format!("{MODEL_DESCRIPTION} declares {} bytes", entry.size()),
                    limit: format!(
                        "at most {} bytes (max_model_description)",
                        limits.max_model_description
                    ),
                });
            }
        }
        declared_total = declared_total.saturating_add(entry.size());
        if declared_total > limits.max_unpacked {
            return Err(LoadError::TooLarge {
                file: path.to_path_buf(),
                what: format!(
                    "its entries declare more than {} bytes unpacked (reached at `{name}`)",
                    limits.max_unpacked
                ),
                limit: format!("at most {} bytes (max_unpacked)", limits.max_unpacked),
            });
        }
        names.push(name);
    }
    if !has_description {
        return Err(LoadError::NoModelDescription {
            file: path.to_path_buf(),
        });
    }

    // Second pass: unpack, counting the bytes actually inflated.
    let dir = super::folder::temporary(path, temp_root)?;
    let mut written: u64 = 0;
    for (i, name) in names.iter().enumerate() {
        let mut entry = archive.by_index(i).map_err(|e| archive_error(path, e))?;
        let relative = match relative_path(name) {
            Some(r) => r,
            // A folder entry naming the root itself (`./`) creates nothing.
            None if entry.is_dir() => continue,
            None => return Err(unsafe_entry(path, name, "it names no file")),
        };
        let target = dir.path().join(&relative);
        let io_error = |e: std::io::Error| LoadError::Unpack {
            file: path.to_path_buf(),
            entry: name.clone(),
            reason: e.to_string(),
        };
        if entry.is_dir() {
            std::fs::create_dir_all(&target).map_err(io_error)?;
            continue;
        }
        if let Some(parent) = target.parent() {
            std::fs::create_dir_all(parent).map_err(io_error)?;
        }
        // `create_new` never follows or replaces what is there: a duplicated entry is an error.
        let mut out = std::fs::OpenOptions::new()
            .write(true)
            .create_new(true)
            .open(&target)
            .map_err(io_error)?;
        let entry_limit = if name == MODEL_DESCRIPTION {
            limits.max_model_description
        } else {
            u64::MAX
        };
        let mut entry_bytes: u64 = 0;
        let mut buffer = vec![0u8; 64 * 1024];
        loop {
            let n = entry.read(&mut buffer).map_err(|e| LoadError::Unpack {
                file: path.to_path_buf(),
                entry: name.clone(),
                reason: e.to_string(),
            })?;
            if n == 0 {
                break;
            }
            entry_bytes += n as u64;
            written += n as u64;
            if entry_bytes > entry_limit {
                return Err(LoadError::TooLarge {
                    file: path.to_path_buf(),
                    what: format!("{MODEL_DESCRIPTION} inflates to more than {entry_limit} bytes"),
                    limit: format!("at most {entry_limit} bytes (max_model_description)"),
                });
            }
            if written > limits.max_unpacked {
                return Err(LoadError::TooLarge {
                    file: path.to_path_buf(),
                    what: format!(
                        "its entries inflate to more than {} bytes (reached in `{name}`, which declared {} bytes)",
                        limits.max_unpacked,
                        entry.size()
                    ),
                    limit: format!("at most {} bytes (max_unpacked)", limits.max_unpacked),
                });
            }
            out.write_all(&buffer[..n]).map_err(io_error)?;
        }
    }
    Unpacked::read(path, dir, names)
}

/// The relative path an already checked entry name unpacks to (normal components only).
fn relative_path(name: &str) -> Option<PathBuf> {
    let mut out = PathBuf::new();
    for part in name.split(['/', '\\']) {
        if part.is_empty() || part == "." {
            continue;
        }
        match Path::new(part).components().next() {
            Some(Component::Normal(c)) if Path::new(part).components().count() == 1 => out.push(c),
            _ => return None,
        }
    }
    (!out.as_os_str().is_empty()).then_some(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_that_leave_the_folder_are_refused() {
        assert_eq!(name_problem("/etc/passwd"), Some("it is an absolute path"));
        assert_eq!(name_problem("\\x.so"), Some("it is an absolute path"));
        assert_eq!(name_problem("C:/x.so"), Some("it is an absolute path"));
        assert_eq!(name_problem("a/../../b"), Some("it has a `..` component"));
        assert_eq!(name_problem("a\\..\\b"), Some("it has a `..` component"));
        assert_eq!(name_problem("binaries/linux64/M.so"), None);
        assert_eq!(name_problem("resources/a..b.txt"), None);
    }

    #[test]
    fn relative_paths_keep_normal_components_only() {
        assert_eq!(
            relative_path("binaries/linux64/M.so"),
            Some(PathBuf::from("binaries/linux64/M.so"))
        );
        assert_eq!(relative_path("./a//b/"), Some(PathBuf::from("a/b")));
        assert_eq!(relative_path("./"), None);
    }
}
