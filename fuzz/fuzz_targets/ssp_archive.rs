//! An SSP archive, as `spurio run` / `ssp-import` read one: its entries within the loader's
//! limits, its `SystemStructure.ssd`, the FMUs it names extracted into a folder (removed after
//! each input).
#![no_main]
use libfuzzer_sys::fuzz_target;
use spurio_fuzz::{assert_nothing_left, input_file, limits, scratch};
use spurio_master::ssp;

fuzz_target!(|data: &[u8]| {
    let path = input_file("input.ssp", data);
    let out = tempfile::Builder::new()
        .prefix("ssp-out-")
        .tempdir_in(scratch())
        .expect("an output folder");
    drop(ssp::import_with(&path, out.path(), &limits()));
    drop(out);
    assert_nothing_left(&path);
});
