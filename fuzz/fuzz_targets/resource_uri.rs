//! A resource location (`fmuResourceLocation` of `fmi2Instantiate`, `resourcePath`'s URI
//! form): turned into a local path, POSIX and Windows spellings.
#![no_main]
use libfuzzer_sys::fuzz_target;
use spurio_export::uri::{local_path, resource_path, PathStyle};

fuzz_target!(|data: &[u8]| {
    let Ok(uri) = std::str::from_utf8(data) else {
        return;
    };
    if let Ok(path) = resource_path(uri) {
        assert!(
            path.is_absolute(),
            "`{uri}` gives the relative path {}",
            path.display()
        );
    }
    drop(local_path(uri, PathStyle::Posix));
    drop(local_path(uri, PathStyle::Windows));
});
