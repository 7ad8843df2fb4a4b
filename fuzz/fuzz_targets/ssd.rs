//! A `SystemStructure.ssd` (SSP 1.0 or 2.0 XML), read from memory.
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(text) = std::str::from_utf8(data) {
        drop(spurio_master::ssp::parse_ssd(text));
    }
});
