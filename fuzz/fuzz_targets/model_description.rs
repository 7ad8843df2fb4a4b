//! A model description (FMI 2.0 or 3.0 XML), read and checked by the FMU loader: the input
//! is packed alone as `modelDescription.xml` into an archive the loader opens (the same path
//! as `fmu_archive`, past the unpacking).
#![no_main]
use libfuzzer_sys::fuzz_target;
use spurio_fuzz::{assert_nothing_left, input_file, limits, scratch};
use spurio_master::fmu::{FmuFile, LoadOptions};
use std::io::Write;

fuzz_target!(|data: &[u8]| {
    let mut zip = zip::ZipWriter::new(std::io::Cursor::new(Vec::new()));
    let stored =
        zip::write::SimpleFileOptions::default().compression_method(zip::CompressionMethod::Stored);
    zip.start_file("modelDescription.xml", stored)
        .expect("a zip entry in memory");
    zip.write_all(data).expect("a zip entry in memory");
    let archive = zip.finish().expect("a zip in memory").into_inner();
    let path = input_file("input.fmu", &archive);
    let options = LoadOptions {
        limits: limits(),
        temp_dir: Some(scratch().to_path_buf()),
    };
    drop(FmuFile::open_preferring(&path, &options, None));
    assert_nothing_left(&path);
});
