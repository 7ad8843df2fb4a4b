//! A serialised FMU state, as `fmi2DeSerializeFMUstate` accepts it, for a real model type
//! (the first byte picks sKF, rsKF, DKF or DKF-rsKF, crane dimensions): deserialised into an
//! initialised instance through the C entry points; when accepted, set and stepped.
//!
//! `SPURIO_FUZZ_SEEDS=DIR` writes seeds instead: the states real instances serialise after
//! initialisation and after a few steps.
#![no_main]
use libfuzzer_sys::fuzz_target;
use spurio_fuzz::{with_instance, Model};

fn write_seeds(dir: &std::path::Path) {
    std::fs::create_dir_all(dir).expect("the seed folder");
    for model in Model::ALL {
        for steps in [0usize, 5] {
            let state = with_instance(model, &model.config(), |i| {
                for k in 0..steps {
                    i.do_step(k as f64 * 0.01, 0.01);
                }
                i.serialized_state()
            })
            .flatten()
            .expect("a state of a real instance");
            let mut seed = vec![model.byte()];
            seed.extend_from_slice(&state);
            std::fs::write(dir.join(format!("{model:?}-{steps}")), seed).expect("a seed");
        }
    }
}

fuzz_target!(
    init: {
        if let Some(dir) = std::env::var_os("SPURIO_FUZZ_SEEDS") {
            write_seeds(std::path::Path::new(&dir));
            std::process::exit(0);
        }
    },
    |data: &[u8]| {
        let Some((&selector, bytes)) = data.split_first() else {
            return;
        };
        let model = Model::of(selector);
        with_instance(model, &model.config(), |i| {
            if i.restore_state(bytes) {
                i.do_step(0.0, 0.01);
            }
        });
    }
);
