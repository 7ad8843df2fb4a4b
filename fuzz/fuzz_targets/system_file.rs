//! A system file (TOML), read as `spurio run` reads one, within a bound on its size.
#![no_main]
use libfuzzer_sys::fuzz_target;
use spurio_fuzz::{assert_nothing_left, input_file};
use spurio_master::SystemDescription;

fuzz_target!(|data: &[u8]| {
    let path = input_file("system.toml", data);
    drop(SystemDescription::read_at_most(&path, 1 << 20));
    assert_nothing_left(&path);
});
