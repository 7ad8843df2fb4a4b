//! Asks a built FMU library (`lib<Id>.so`, `<Id>.dll`) for its bundled variants and its model
//! description, through the query symbols every spurio FMU exports beside the `fmi2*` ones
//! (see `spurio_export::query`). The packager finds the FMUs this way, with no list of them.
//!
//! Loading a shared library and calling its C functions cannot be done without `unsafe`;
//! this module is that one place (to be merged with the engine's FMU loader), and it exposes
//! only safe functions.
#![allow(unsafe_code)]

use spurio_export::query::{
    parse_variants, Variant, DESCRIBE3_SYMBOL, DESCRIBE_SYMBOL, VARIANTS_SYMBOL,
};
use spurio_export::Config;
use std::ffi::CString;
use std::os::raw::c_char;
use std::path::{Path, PathBuf};

/// Why a library could not be asked.
#[derive(Debug, thiserror::Error)]
pub enum QueryError {
    #[error("{path}: cannot load the library: {error}")]
    Load {
        path: PathBuf,
        error: libloading::Error,
    },
    #[error("{path}: no `{symbol}` symbol (not a spurio FMU library, or built before it had one)")]
    Symbol { path: PathBuf, symbol: &'static str },
    #[error("{path}: {message}")]
    Answer { path: PathBuf, message: String },
}

type VariantsFn = unsafe extern "C" fn(*mut u8, usize) -> usize;
type DescribeFn = unsafe extern "C" fn(*const c_char, *mut u8, usize) -> isize;

/// A loaded FMU library.
pub struct FmuLibrary {
    path: PathBuf,
    library: libloading::Library,
}

/// Calls `ask(buffer, capacity)` until the buffer holds the whole answer.
fn answer(mut ask: impl FnMut(*mut u8, usize) -> usize) -> Vec<u8> {
    let mut buffer = vec![0u8; 64 * 1024];
    loop {
        let length = ask(buffer.as_mut_ptr(), buffer.len());
        if length <= buffer.len() {
            buffer.truncate(length);
            return buffer;
        }
        buffer = vec![0u8; length];
    }
}

impl FmuLibrary {
    /// Loads the library at `path`.
    pub fn open(path: &Path) -> Result<Self, QueryError> {
        // SAFETY: loading runs the library's initialisers; our FMU libraries have none beyond
        // the Rust runtime's. The packager only loads libraries built from this repository.
        let library =
            unsafe { libloading::Library::new(path) }.map_err(|error| QueryError::Load {
                path: path.to_path_buf(),
                error,
            })?;
        Ok(Self {
            path: path.to_path_buf(),
            library,
        })
    }

    fn symbol<T: Copy>(&self, name: &'static str) -> Result<T, QueryError> {
        // SAFETY: `T` is the function type the export layer declares for `name`.
        unsafe { self.library.get::<T>(name.as_bytes()) }
            .map(|s| *s)
            .map_err(|_| QueryError::Symbol {
                path: self.path.clone(),
                symbol: name,
            })
    }

    /// The bundled variants: (file stem, configuration).
    pub fn variants(&self) -> Result<Vec<Variant>, QueryError> {
        let f: VariantsFn = self.symbol(VARIANTS_SYMBOL)?;
        // SAFETY: the function writes at most `capacity` bytes into the buffer it is given.
        let bytes = answer(|out, capacity| unsafe { f(out, capacity) });
        parse_variants(&String::from_utf8_lossy(&bytes)).map_err(|e| QueryError::Answer {
            path: self.path.clone(),
            message: e.to_string(),
        })
    }

    /// The model description for `config`, or the library's message why not.
    pub fn describe(&self, config: &Config) -> Result<String, QueryError> {
        self.describe_with(DESCRIBE_SYMBOL, config)
    }

    /// The FMI 3.0 model description for `config`, or the library's message why not.
    pub fn describe3(&self, config: &Config) -> Result<String, QueryError> {
        self.describe_with(DESCRIBE3_SYMBOL, config)
    }

    fn describe_with(&self, symbol: &'static str, config: &Config) -> Result<String, QueryError> {
        let f: DescribeFn = self.symbol(symbol)?;
        let text = CString::new(config.to_text()).map_err(|_| QueryError::Answer {
            path: self.path.clone(),
            message: "the configuration contains a NUL byte".into(),
        })?;
        let mut failed = false;
        let bytes = answer(|out, capacity| {
            // SAFETY: `text` is NUL-terminated and outlives the call; the function writes at
            // most `capacity` bytes into `out`.
            let length = unsafe { f(text.as_ptr(), out, capacity) };
            failed = length < 0;
            length.unsigned_abs()
        });
        let text = String::from_utf8_lossy(&bytes).into_owned();
        if failed {
            Err(QueryError::Answer {
                path: self.path.clone(),
                message: text,
            })
        } else {
            Ok(text)
        }
    }
}
