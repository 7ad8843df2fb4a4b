//! A `variant.cfg` (the FMUs' configuration in `resources/`): parsed, the model described
//! for it and, when it is accepted, instantiated, initialised and stepped through the C entry
//! points (the first byte picks sKF, rsKF, DKF or DKF-rsKF).
#![no_main]
use libfuzzer_sys::fuzz_target;
use spurio_export::Config;
use spurio_fuzz::{with_instance, Model};

fuzz_target!(|data: &[u8]| {
    let Some((&selector, text)) = data.split_first() else {
        return;
    };
    let Ok(text) = std::str::from_utf8(text) else {
        return;
    };
    let Ok(config) = Config::parse(text) else {
        return;
    };
    with_instance(Model::of(selector), &config, |i| {
        i.do_step(0.0, 0.01);
    });
});
