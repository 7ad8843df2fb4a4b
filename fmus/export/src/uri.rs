//! The `fmuResourceLocation` of `fmi2Instantiate` (FMI 2.0.4 §2.1.5): a `file` URI (RFC 8089)
//! turned into a local path, on Windows as well as on POSIX systems.
//!
//! Accepted forms: `file:///abs/path`, `file:/abs/path`, `file://localhost/abs/path`, on
//! Windows `file:///C:/dir` → `C:\dir` and `file://server/share/dir` → `\\server\share\dir`
//! (UNC). The path is percent-decoded (`%20` → space, `%C3%A9` → `é`); a malformed escape or a
//! path that does not decode to UTF-8 is an error, never a silently different path. `?` and
//! `#` are kept as part of the path (masters do not put queries or fragments in this URI, and a
//! folder name may contain them).

use std::fmt;
use std::path::PathBuf;

/// Why a resource location is not a usable local path.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum UriError {
    /// The string is empty.
    Empty,
    /// The scheme is not `file:`.
    NotFileUri(String),
    /// `%` not followed by two hexadecimal digits, at this byte offset of the URI.
    InvalidEscape(usize),
    /// The decoded path is not UTF-8.
    NotUtf8,
    /// The decoded path contains a NUL character.
    Nul,
    /// `file://host/…` with a host other than `localhost`, which only Windows (UNC) can reach.
    RemoteHost(String),
    /// The URI has no path (`file://host` alone) or a relative one.
    NoPath,
}

impl fmt::Display for UriError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            UriError::Empty => write!(f, "the resource location is empty"),
            UriError::NotFileUri(uri) => write!(f, "`{uri}` is not a file:// URI"),
            UriError::InvalidEscape(at) => write!(
                f,
                "invalid percent escape at byte {at} (expected % and two hexadecimal digits)"
            ),
            UriError::NotUtf8 => write!(f, "the percent-decoded path is not UTF-8"),
            UriError::Nul => write!(f, "the percent-decoded path contains a NUL character"),
            UriError::RemoteHost(host) => write!(
                f,
                "host `{host}` names a remote file system, which only Windows (UNC paths) can open"
            ),
            UriError::NoPath => write!(f, "the URI has no absolute path"),
        }
    }
}

impl std::error::Error for UriError {}

/// How the local file system spells paths.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PathStyle {
    /// `/` separators, one root.
    Posix,
    /// Drive letters, `\` separators, UNC `\\server\share`.
    Windows,
}

impl PathStyle {
    /// The style of the platform this binary runs on.
    pub const HOST: PathStyle = if cfg!(windows) {
        PathStyle::Windows
    } else {
        PathStyle::Posix
    };
}

/// The local path of a resource-location URI on this platform.
pub fn resource_path(uri: &str) -> Result<PathBuf, UriError> {
    local_path(uri, PathStyle::HOST).map(PathBuf::from)
}

/// The local path of a `file` URI, spelled in `style`.
pub fn local_path(uri: &str, style: PathStyle) -> Result<String, UriError> {
    if uri.is_empty() {
        return Err(UriError::Empty);
    }
    let rest = match uri.get(..5) {
        Some(scheme) if scheme.eq_ignore_ascii_case("file:") => &uri[5..],
        _ => return Err(UriError::NotFileUri(uri.to_string())),
    };
    // Splits `//authority/path` into host and path; `/path` has no authority.
    let (host, path) = match rest.strip_prefix("//") {
        Some(after) => match after.find('/') {
            Some(i) => (&after[..i], &after[i..]),
            None => return Err(UriError::NoPath),
        },
        None => ("", rest),
    };
    if !path.starts_with('/') {
        return Err(UriError::NoPath);
    }
    let offset = uri.len() - path.len();
    let decoded = percent_decode(path, offset)?;
    let host = if host.eq_ignore_ascii_case("localhost") {
        ""
    } else {
        host
    };
    match style {
        PathStyle::Posix => {
            if !host.is_empty() {
                return Err(UriError::RemoteHost(host.to_string()));
            }
            Ok(decoded)
        }
        PathStyle::Windows => {
            let backslashed = decoded.replace('/', "\\");
            if !host.is_empty() {
                return Ok(format!("\\\\{}{backslashed}", percent_decode(host, 0)?));
            }
            // `/C:/dir` (or the legacy `/C|/dir`) is a drive path; `/dir` stays rooted on the
            // current drive.
            let b = decoded.as_bytes();
            if b.len() >= 3 && b[1].is_ascii_alphabetic() && (b[2] == b':' || b[2] == b'|') {
                let drive = b[1] as char;
                return Ok(format!("{drive}:{}", &backslashed[3..]));
            }
            Ok(backslashed)
        }
    }
}

/// Decodes `%XX` escapes; `offset` is where `s` starts in the URI (for error positions).
fn percent_decode(s: &str, offset: usize) -> Result<String, UriError> {
    let bytes = s.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        if bytes[i] == b'%' {
            let value = bytes
                .get(i + 1..i + 3)
                .and_then(|h| std::str::from_utf8(h).ok())
                .filter(|h| h.bytes().all(|c| c.is_ascii_hexdigit()))
                .and_then(|h| u8::from_str_radix(h, 16).ok())
                .ok_or(UriError::InvalidEscape(offset + i))?;
            out.push(value);
            i += 3;
        } else {
            out.push(bytes[i]);
            i += 1;
        }
    }
    let text = String::from_utf8(out).map_err(|_| UriError::NotUtf8)?;
    if text.contains('\0') {
        return Err(UriError::Nul);
    }
    Ok(text)
}

#[cfg(test)]
mod tests {
    use super::*;
    use PathStyle::{Posix, Windows};

    /// Each URI, read in its path style, gives its local path.
    fn assert_paths(cases: &[(&str, PathStyle, &str)]) {
        for &(uri, style, path) in cases {
            assert_eq!(
                local_path(uri, style).as_deref(),
                Ok(path),
                "{uri} ({style:?})"
            );
        }
    }

    /// Each URI, read in its path style, is refused with its error.
    fn assert_errors(cases: &[(&str, PathStyle, UriError)]) {
        for (uri, style, error) in cases {
            assert_eq!(
                local_path(uri, *style).as_ref(),
                Err(error),
                "{uri} ({style:?})"
            );
        }
    }

    #[test]
    fn windows_drive_paths_lose_the_leading_slash() {
        assert_paths(&[
            ("file:///C:/x%20y/res", Windows, r"C:\x y\res"),
            ("file:/d:/fmu/res/", Windows, r"d:\fmu\res\"),
            ("file:///C|/legacy", Windows, r"C:\legacy"),
            ("file://localhost/Z:/tmp/a", Windows, r"Z:\tmp\a"),
            // The same URI on a POSIX system is taken literally.
            ("file:///C:/x%20y/res", Posix, "/C:/x y/res"),
        ]);
    }

    #[test]
    fn posix_forms() {
        assert_paths(&[
            ("file:///home/u/res/", Posix, "/home/u/res/"),
            ("file:/home/u/res", Posix, "/home/u/res"),
            ("file://localhost/home/u/res", Posix, "/home/u/res"),
            ("FILE://LocalHost/home/u", Posix, "/home/u"),
            ("file:///", Posix, "/"),
        ]);
    }

    #[test]
    fn unc_paths_on_windows_only() {
        assert_paths(&[
            ("file://server/share/res", Windows, r"\\server\share\res"),
            (
                "file://server/share/my%20fmu/res",
                Windows,
                r"\\server\share\my fmu\res",
            ),
        ]);
        assert_eq!(
            local_path("file://server/share/res", Posix),
            Err(UriError::RemoteHost("server".into()))
        );
    }

    #[test]
    fn percent_decoding_including_utf8() {
        assert_paths(&[
            (
                "file:///tmp/caf%C3%A9/%E6%97%A5%20%25/res",
                Posix,
                "/tmp/café/日 %/res",
            ),
            // Unencoded non-ASCII text passes through unchanged, as do `?` and `#`.
            ("file:///tmp/Ünïcode/a#b?c", Posix, "/tmp/Ünïcode/a#b?c"),
            (
                "file:///C:/Users/J%C3%BCrgen/res",
                Windows,
                r"C:\Users\Jürgen\res",
            ),
            // Lower-case hexadecimal digits.
            ("file:///a%2fb%3a", Posix, "/a/b:"),
        ]);
    }

    #[test]
    fn invalid_escapes_are_errors_with_their_position() {
        assert_errors(&[
            ("file:///tmp/a%zzb", Posix, UriError::InvalidEscape(13)),
            ("file:///tmp/a%4", Posix, UriError::InvalidEscape(13)),
            ("file:///tmp/a%", Posix, UriError::InvalidEscape(13)),
            // `%+1` must not pass as hexadecimal through from_str_radix's sign handling.
            ("file:///a%+1", Posix, UriError::InvalidEscape(9)),
            ("file:///tmp/%C3%28", Posix, UriError::NotUtf8),
            ("file:///tmp/%00", Posix, UriError::Nul),
        ]);
    }

    #[test]
    fn not_a_file_uri() {
        assert_errors(&[
            ("", Posix, UriError::Empty),
            (
                "http://x/res",
                Posix,
                UriError::NotFileUri("http://x/res".into()),
            ),
            (
                "/home/u/res",
                Posix,
                UriError::NotFileUri("/home/u/res".into()),
            ),
            (
                r"C:\fmu\res",
                Windows,
                UriError::NotFileUri(r"C:\fmu\res".into()),
            ),
            ("file://server", Windows, UriError::NoPath),
            ("file:relative/res", Posix, UriError::NoPath),
            ("fil", Posix, UriError::NotFileUri("fil".into())),
        ]);
    }

    #[test]
    fn host_style_matches_the_platform() {
        let path = resource_path("file:///C:/fmu/res").unwrap();
        if cfg!(windows) {
            assert_eq!(path, PathBuf::from(r"C:\fmu\res"));
        } else {
            assert_eq!(path, PathBuf::from("/C:/fmu/res"));
        }
    }
}
