//! An FMU archive, as `spurio run` loads one: unpacked within the loader's limits into a
//! temporary folder (which must be gone afterwards), its model description read and checked
//! (FMI 2.0 or 3.0), its binary inspected. Nothing is instantiated.
#![no_main]
use libfuzzer_sys::fuzz_target;
use spurio_fuzz::{assert_nothing_left, input_file, limits, scratch};
use spurio_master::fmu::{FmuFile, LoadOptions};

fuzz_target!(|data: &[u8]| {
    let path = input_file("input.fmu", data);
    let options = LoadOptions {
        limits: limits(),
        temp_dir: Some(scratch().to_path_buf()),
    };
    drop(FmuFile::open_preferring(&path, &options, None));
    assert_nothing_left(&path);
});
