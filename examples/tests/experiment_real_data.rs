//! Pins the real-data figures: the hair dryer through the data source and the estimator FMUs
//! (needs `scripts/setup`, which fetches the record into data/slicot/, and the packaged FMUs).
//! Without the record the test fails, saying so: it never skips.

mod common;

use common::run_pinned;
use std::path::PathBuf;

#[test]
fn the_estimators_identify_the_hair_dryer_from_its_record() {
    let record = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../data/slicot/IB01BD.dat.gz");
    assert!(
        record.is_file(),
        "{} is missing: run scripts/setup (it fetches the hair-dryer record from Debian's \
         libslicot-doc)",
        record.display()
    );
    run_pinned("real_data", "realdata", 1);
}
