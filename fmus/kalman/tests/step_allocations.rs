//! No heap allocation per step in the estimators: the estimator FMUs after initialisation,
//! driven through the C entry points (`fmi2SetReal` of every input, `fmi2DoStep`, `fmi2GetReal`
//! of every real output), with a counting global allocator over `fmi2DoStep` and
//! `fmi2GetReal` (`fmi2SetReal` is the export layer's alone and is counted by its own test).

use spurio_counting_allocator::{count, CountingAllocator};
use spurio_export::harness::Harness;
use spurio_export::{Causality, Config, FmuModel, VariableType};
use spurio_fmu_kalman::{
    dims_config, DkfRsKfFmu, DualKalmanFilterFmu, KalmanFilterFmu, RobustKalmanFilterFmu,
};

#[global_allocator]
static ALLOCATOR: CountingAllocator = CountingAllocator;

/// Allocations in `fmi2DoStep` + `fmi2GetReal` over 50 steps after 5 warm-up steps, every
/// input set (missing samples among them) and every real output read; `set` and `flags` are parameters set before
/// initialisation.
fn allocations<M: FmuModel>(config: &Config, set: &[(&str, f64)], flags: &[(&str, bool)]) -> u64 {
    let info = M::describe(config).expect("describe");
    let references = |causality: Causality, kind: VariableType| -> Vec<u32> {
        let variables = info.variables.iter().enumerate();
        variables
            .filter(|(_, v)| v.causality == causality && v.variable_type() == kind)
            .map(|(k, _)| k as u32)
            .collect()
    };
    let inputs = references(Causality::Input, VariableType::Real);
    // The Boolean inputs `y_valid[j]`: a pattern of missing samples (one channel, every
    // channel, none) runs through the counted steps too.
    let valid = references(Causality::Input, VariableType::Boolean);
    assert!(!valid.is_empty(), "y_valid inputs");
    let outputs = references(Causality::Output, VariableType::Real);
    let mut h = Harness::<M>::new(config).expect("instantiate");
    h.setup_experiment(0.0, None).expect("setup");
    h.enter_initialization_mode().expect("enter");
    for (name, value) in set {
        let vr = info.index_of(name).expect("variable") as u32;
        h.set_real(&[vr], &[*value]).expect("set");
    }
    for (name, value) in flags {
        let vr = info.index_of(name).expect("variable") as u32;
        h.set_boolean(&[vr], &[*value]).expect("set");
    }
    h.exit_initialization_mode().expect("exit");
    let mut values = vec![0.0; inputs.len()];
    let mut out = vec![0.0; outputs.len()];
    let step = 0.05;
    let mut counted = 0;
    for k in 0..55u64 {
        for (i, v) in values.iter_mut().enumerate() {
            let outlier = if (k + i as u64).is_multiple_of(13) {
                3.0
            } else {
                0.0
            };
            *v = (k as f64 * 0.05 * (i + 1) as f64).sin() + outlier;
        }
        h.set_real(&inputs, &values).expect("set");
        let present: Vec<bool> = (0..valid.len())
            .map(|j| match k % 4 {
                1 => j != 0,
                2 => false,
                _ => true,
            })
            .collect();
        h.set_boolean(&valid, &present).expect("set");
        let ((stepped, got), counts) = count(|| {
            let stepped = h.do_step(k as f64 * step, step);
            (stepped, h.get_real(&outputs, &mut out))
        });
        stepped.expect("step");
        got.expect("get");
        if k >= 5 {
            counted += counts.allocations;
        }
    }
    counted
}

#[test]
fn estimator_steps_do_not_allocate() {
    let kf = |n, m, p| allocations::<KalmanFilterFmu>(&dims_config(n, m, p), &[], &[]);
    let rkf = |n, m, p| allocations::<RobustKalmanFilterFmu>(&dims_config(n, m, p), &[], &[]);
    let dkf = |n, m, p, set: &[(&str, f64)], flags: &[(&str, bool)]| {
        allocations::<DualKalmanFilterFmu>(&dims_config(n, m, p), set, flags)
    };
    let dkf_rskf = |n, m, p| allocations::<DkfRsKfFmu>(&dims_config(n, m, p), &[], &[]);
    let cases = [
        ("KalmanFilter 1,0,1", kf(1, 0, 1)),
        ("KalmanFilter 3,1,2", kf(3, 1, 2)),
        ("KalmanFilter 8,2,2", kf(8, 2, 2)),
        ("RobustKalmanFilter 1,0,1", rkf(1, 0, 1)),
        ("RobustKalmanFilter 2,1,2", rkf(2, 1, 2)),
        ("DualKalmanFilter 2,1,1", dkf(2, 1, 1, &[], &[])),
        (
            "DualKalmanFilter 4,1,2, C and D free",
            dkf(4, 1, 2, &[], &[("fix_output_matrices", false)]),
        ),
        (
            "DualKalmanFilter 4,1,2, output error, bounded variance",
            dkf(4, 1, 2, &[("pmax_theta", 2.0)], &[("output_error", true)]),
        ),
        (
            "DualKalmanFilter 4,1,2, excitation gate",
            dkf(4, 1, 2, &[("excitation_min", 1e-6)], &[]),
        ),
        ("DkfRsKf 4,1,2", dkf_rskf(4, 1, 2)),
        ("DkfRsKf 8,2,2 (DkfRsKfGenerator)", dkf_rskf(8, 2, 2)),
    ];
    for (name, count) in &cases {
        eprintln!("{name}: {count} allocations in 50 steps");
    }
    assert!(cases.iter().all(|(_, c)| *c == 0), "{cases:?}");
}
