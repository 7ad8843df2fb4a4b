//! An FMU's files in a fresh temporary folder of their own, whether they come from a `.fmu`
//! archive ([`super::archive`], feature `archive`) or from an FMU already unpacked into a
//! folder ([`copy`]): what an FMU carrying another FMU in its `resources/` opens, without
//! linking a zip reader. The copy keeps the archive's rules: plain files and folders only (a
//! symbolic link or any other kind of file is refused), at most [`LoadLimits`] entries and
//! bytes; on any error the temporary folder is removed.

use super::{LoadError, LoadLimits};
use std::path::Path;

/// Name of the model description inside the archive.
pub(super) const MODEL_DESCRIPTION: &str = "modelDescription.xml";

/// An FMU's files in their own temporary folder (removed when dropped).
pub(super) struct Unpacked {
    pub dir: tempfile::TempDir,
    /// Entry names (`/`-separated, relative to the FMU's root), as written in the archive.
    pub names: Vec<String>,
    /// The text of `modelDescription.xml`.
    pub model_description: String,
}

impl Unpacked {
    /// The FMU `path` unpacked into `dir` as the entries `names`, with its model description.
    pub(super) fn read(
        path: &Path,
        dir: tempfile::TempDir,
        names: Vec<String>,
    ) -> Result<Self, LoadError> {
        let model_description = std::fs::read_to_string(dir.path().join(MODEL_DESCRIPTION))
            .map_err(|e| LoadError::ModelDescription {
                file: path.to_path_buf(),
                reason: e.to_string(),
            })?;
        Ok(Self {
            dir,
            names,
            model_description,
        })
    }
}

/// A fresh `spurio-fmu-*` folder under `temp_root` for the FMU `path`.
pub(super) fn temporary(path: &Path, temp_root: &Path) -> Result<tempfile::TempDir, LoadError> {
    tempfile::Builder::new()
        .prefix("spurio-fmu-")
        .tempdir_in(temp_root)
        .map_err(|e| LoadError::TempDir {
            file: path.to_path_buf(),
            folder: temp_root.to_path_buf(),
            reason: e.to_string(),
        })
}

/// Copies the unpacked FMU in the folder `path` into a fresh temporary folder under
/// `temp_root`, within `limits` (entries, bytes in all, bytes of `modelDescription.xml`).
pub(super) fn copy(
    path: &Path,
    limits: &LoadLimits,
    temp_root: &Path,
) -> Result<Unpacked, LoadError> {
    let dir = temporary(path, temp_root)?;
    let mut copying = Copying {
        root: path,
        limits,
        names: Vec::new(),
        bytes: 0,
    };
    copying.folder(path, dir.path(), "")?;
    if !copying.names.iter().any(|n| n == MODEL_DESCRIPTION) {
        return Err(LoadError::NoModelDescription {
            file: path.to_path_buf(),
        });
    }
    Unpacked::read(path, dir, copying.names)
}

/// The state of one copy: the names copied so far and their bytes.
struct Copying<'a> {
    root: &'a Path,
    limits: &'a LoadLimits,
    names: Vec<String>,
    bytes: u64,
}

impl Copying<'_> {
    fn error(&self, entry: &str, reason: impl ToString) -> LoadError {
        LoadError::Unpack {
            file: self.root.to_path_buf(),
            entry: entry.to_string(),
            reason: reason.to_string(),
        }
    }

    /// Copies the folder `from` (entry names prefixed by `prefix`) into `to`, which exists.
    fn folder(&mut self, from: &Path, to: &Path, prefix: &str) -> Result<(), LoadError> {
        let entries = std::fs::read_dir(from).map_err(|e| self.error(prefix, e))?;
        for entry in entries {
            let entry = entry.map_err(|e| self.error(prefix, e))?;
            let file_name = entry.file_name();
            let Some(file_name) = file_name.to_str() else {
                return Err(LoadError::UnsafeEntry {
                    file: self.root.to_path_buf(),
                    entry: format!("{prefix}{}", file_name.to_string_lossy()),
                    reason: "its name is not UTF-8".into(),
                });
            };
            let name = format!("{prefix}{file_name}");
            // `symlink_metadata` does not follow a link: a link is refused, not copied.
            let kind = entry
                .path()
                .symlink_metadata()
                .map_err(|e| self.error(&name, e))?;
            let target = to.join(file_name);
            if kind.is_dir() {
                self.count(&name, 0)?;
                std::fs::create_dir(&target).map_err(|e| self.error(&name, e))?;
                self.folder(&entry.path(), &target, &format!("{name}/"))?;
            } else if kind.is_file() {
                self.count(&name, kind.len())?;
                let copied =
                    std::fs::copy(entry.path(), &target).map_err(|e| self.error(&name, e))?;
                // The file may have grown since its size was read.
                self.bytes = self.bytes.saturating_add(copied.saturating_sub(kind.len()));
                self.check_bytes(&name)?;
            } else {
                return Err(LoadError::UnsafeEntry {
                    file: self.root.to_path_buf(),
                    entry: name,
                    reason: "it is not a plain file or folder (a symbolic link or a device)".into(),
                });
            }
        }
        Ok(())
    }

    /// Notes the entry `name` of `size` bytes, refusing it beyond the limits.
    fn count(&mut self, name: &str, size: u64) -> Result<(), LoadError> {
        let limits = self.limits;
        if self.names.len() >= limits.max_entries {
            return Err(self.too_large(
                format!("the folder has more than {} entries", limits.max_entries),
                format!("at most {} entries (max_entries)", limits.max_entries),
            ));
        }
        if name == MODEL_DESCRIPTION && size > limits.max_model_description {
            return Err(self.too_large(
                format!("{MODEL_DESCRIPTION} has {size} bytes"),
                format!(
                    "at most {} bytes (max_model_description)",
                    limits.max_model_description
                ),
            ));
        }
        self.names.push(name.to_string());
        self.bytes = self.bytes.saturating_add(size);
        self.check_bytes(name)
    }

    fn check_bytes(&self, name: &str) -> Result<(), LoadError> {
        let limit = self.limits.max_unpacked;
        if self.bytes > limit {
            return Err(self.too_large(
                format!("its files hold more than {limit} bytes (reached at `{name}`)"),
                format!("at most {limit} bytes (max_unpacked)"),
            ));
        }
        Ok(())
    }

    fn too_large(&self, what: String, limit: String) -> LoadError {
        LoadError::TooLarge {
            file: self.root.to_path_buf(),
            what,
            limit,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_unpacked_fmu_is_copied_within_the_limits_and_links_are_refused() {
        let source = tempfile::tempdir().unwrap();
        std::fs::write(
            source.path().join(MODEL_DESCRIPTION),
            "<fmiModelDescription/>",
        )
        .unwrap();
        std::fs::create_dir_all(source.path().join("binaries/x86_64-linux")).unwrap();
        std::fs::write(source.path().join("binaries/x86_64-linux/M.so"), [0u8; 100]).unwrap();
        let temp_root = tempfile::tempdir().unwrap();
        let copied = copy(source.path(), &LoadLimits::default(), temp_root.path()).unwrap();
        let mut names = copied.names.clone();
        names.sort();
        assert_eq!(
            names,
            [
                "binaries",
                "binaries/x86_64-linux",
                "binaries/x86_64-linux/M.so",
                MODEL_DESCRIPTION
            ]
        );
        assert_eq!(copied.model_description, "<fmiModelDescription/>");
        assert_eq!(
            std::fs::metadata(copied.dir.path().join("binaries/x86_64-linux/M.so"))
                .unwrap()
                .len(),
            100
        );

        let small = LoadLimits {
            max_unpacked: 120,
            ..LoadLimits::default()
        };
        let e = copy(source.path(), &small, temp_root.path()).err().unwrap();
        assert!(matches!(e, LoadError::TooLarge { .. }), "{e}");
        // The refused copy's folder is gone; the first copy's is still there.
        assert_eq!(std::fs::read_dir(temp_root.path()).unwrap().count(), 1);

        #[cfg(unix)]
        {
            std::os::unix::fs::symlink("/etc/passwd", source.path().join("resources")).unwrap();
            let e = copy(source.path(), &LoadLimits::default(), temp_root.path())
                .err()
                .unwrap();
            assert!(
                matches!(&e, LoadError::UnsafeEntry { entry, .. } if entry == "resources"),
                "{e}"
            );
        }
    }
}
