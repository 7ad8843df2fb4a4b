//! What the fuzz targets share: a scratch folder per process for the parsers that read files
//! (an input is written there, parsed, and nothing else may remain), the limits an archive is
//! loaded with (small, so a bomb is refused at once and a blow-up past them is a finding), and
//! the FMU models whose serialised states and variant configurations are fuzzed.

use spurio_export::harness::Harness;
use spurio_export::types::Status;
use spurio_export::{Config, FmuModel};
use spurio_fmu_kalman::{
    dims_config, DkfRsKfFmu, DualKalmanFilterFmu, KalmanFilterFmu, RobustKalmanFilterFmu,
};
use spurio_master::fmu::LoadLimits;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

/// The limits archives are loaded with: a few MiB, far below the defaults, so the fuzzer
/// meets them often (an input is at most 1 MiB: `scripts/fuzz` sets `-max_len`).
pub fn limits() -> LoadLimits {
    LoadLimits {
        max_unpacked: 8 << 20,
        max_model_description: 2 << 20,
        max_entries: 256,
    }
}

/// This process's scratch folder (removed at exit by nobody: libFuzzer ends with `exit`, so
/// it lives under `SPURIO_FUZZ_SCRATCH`, which `scripts/fuzz` creates and removes).
pub fn scratch() -> &'static Path {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    DIR.get_or_init(|| {
        let root = std::env::var_os("SPURIO_FUZZ_SCRATCH")
            .map(PathBuf::from)
            .unwrap_or_else(std::env::temp_dir);
        let dir = root.join(format!("scratch-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("the fuzz scratch folder");
        dir
    })
}

/// Writes `data` to `name` in the scratch folder, returning its path.
pub fn input_file(name: &str, data: &[u8]) -> PathBuf {
    let path = scratch().join(name);
    std::fs::write(&path, data).expect("writing the fuzz input");
    path
}

/// Panics (a finding) when the scratch folder holds anything but `input`: a parser left a
/// temporary folder or file behind.
pub fn assert_nothing_left(input: &Path) {
    for entry in std::fs::read_dir(scratch()).expect("the fuzz scratch folder") {
        let path = entry.expect("a scratch entry").path();
        assert!(path == input, "left behind: {}", path.display());
    }
}

/// The model types of the FMUs whose states and configurations are fuzzed: the Kalman
/// family (sKF, rsKF, DKF, DKF-rsKF), whose dimensions come from `variant.cfg`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Model {
    Kalman,
    RobustKalman,
    DualKalman,
    DkfRsKf,
}

impl Model {
    pub const ALL: [Model; 4] = [
        Model::Kalman,
        Model::RobustKalman,
        Model::DualKalman,
        Model::DkfRsKf,
    ];

    /// The model a selector byte picks.
    pub fn of(byte: u8) -> Model {
        Self::ALL[usize::from(byte) % Self::ALL.len()]
    }

    /// The selector byte of this model.
    pub fn byte(self) -> u8 {
        Self::ALL.iter().position(|&m| m == self).unwrap_or(0) as u8
    }

    /// The configuration its states are fuzzed with: the crane's dimensions (n = 4, m = 1,
    /// p = 2), as the bundled `DualKalmanFilter` and `DkfRsKf`.
    pub fn config(self) -> Config {
        dims_config(4, 1, 2)
    }
}

/// Runs `f` with a fresh, initialised instance of `model` for `config` (`None` when the
/// configuration is refused at instantiation or initialisation, as an importer would be told).
pub fn with_instance<R>(
    model: Model,
    config: &Config,
    f: impl FnOnce(&mut dyn Driven) -> R,
) -> Option<R> {
    fn go<M: FmuModel, R>(config: &Config, f: impl FnOnce(&mut dyn Driven) -> R) -> Option<R> {
        let mut h = Harness::<M>::new(config).ok()?;
        let initialized = h.initialize(0.0);
        succeeded(&h, initialized).then_some(())?;
        Some(f(&mut h))
    }
    match model {
        Model::Kalman => go::<KalmanFilterFmu, R>(config, f),
        Model::RobustKalman => go::<RobustKalmanFilterFmu, R>(config, f),
        Model::DualKalman => go::<DualKalmanFilterFmu, R>(config, f),
        Model::DkfRsKf => go::<DkfRsKfFmu, R>(config, f),
    }
}

/// The calls the targets make on an instance, whatever its model type.
pub trait Driven {
    fn serialized_state(&mut self) -> Option<Vec<u8>>;
    /// `fmi2DeSerializeFMUstate` + `fmi2SetFMUstate`: whether the state was accepted.
    fn restore_state(&mut self, bytes: &[u8]) -> bool;
    /// `fmi2DoStep(time, step)`: whether it succeeded.
    fn do_step(&mut self, time: f64, step: f64) -> bool;
}

impl<M: FmuModel> Driven for Harness<M> {
    fn serialized_state(&mut self) -> Option<Vec<u8>> {
        match Harness::serialized_state(self) {
            Ok(bytes) => Some(bytes),
            Err(status) => {
                succeeded(self, Err(status));
                None
            }
        }
    }
    fn restore_state(&mut self, bytes: &[u8]) -> bool {
        let result = Harness::restore_state(self, bytes);
        succeeded(self, result)
    }
    fn do_step(&mut self, time: f64, step: f64) -> bool {
        let result = Harness::do_step(self, time, step);
        succeeded(self, result)
    }
}

/// Whether a call succeeded; panics (a finding) when it ended `Fatal`: the export layer
/// answers a panic inside the FMU with `fmi2Fatal` (and logs it) instead of unwinding
/// across the C ABI, so a panic would otherwise pass unseen.
fn succeeded<M: FmuModel>(h: &Harness<M>, result: Result<Status, Status>) -> bool {
    if result == Err(Status::Fatal) {
        panic!("an FMU call ended Fatal; its log: {:?}", h.log());
    }
    result.is_ok()
}
