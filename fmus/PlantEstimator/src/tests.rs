//! The estimator FMU through the export layer's harness on the Reference FMU VanDerPol
//! (unpacked as a packaged estimator carries it): the same outputs as
//! `spurio_identify::estimator::Estimator` sample by sample (bit for bit), missing samples,
//! the refusals at instantiation, no heap allocation per DoStep after the first, the
//! serialized FMU state restored bit for bit (and refused truncated, garbled or of another
//! configuration).

use super::*;
use spurio_export::harness::Harness;
use spurio_export::types::Status;
use spurio_identify::online::{Method, Robust};
use std::path::PathBuf;

#[global_allocator]
static ALLOCATOR: spurio_counting_allocator::CountingAllocator =
    spurio_counting_allocator::CountingAllocator;

/// A `resources/` folder holding VanDerPol unpacked in `plant/` (removed on drop).
struct Resources(PathBuf);

impl Drop for Resources {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

fn resources(tag: &str) -> Resources {
    let reference_fmus = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../tests/third_party/reference-fmus"
    );
    let dir = std::env::temp_dir().join(format!(
        "spurio-plant-estimator-{}-{tag}",
        std::process::id()
    ));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let status = std::process::Command::new("unzip")
        .arg("-q")
        .arg(format!("{reference_fmus}/fmi2/VanDerPol.fmu"))
        .arg("-d")
        .arg(dir.join(PLANT_FOLDER))
        .status()
        .expect("unzip runs");
    assert!(status.success());
    Resources(dir)
}

/// μ of VanDerPol estimated from x0, as `spurio package-estimator VanDerPol.fmu --free mu
/// --output x0 --noise x0=1e-4 --start mu=1.2` declares it.
fn declared(method: Method) -> EstimatorDeclaration {
    let named = |name: &str| Named {
        name: name.into(),
        unit: None,
    };
    EstimatorDeclaration {
        name: "VanDerPolEstimator".into(),
        plant: "van der Pol oscillator".into(),
        method,
        robust: Robust::Huber,
        tolerance: 1e-8,
        inputs: Vec::new(),
        outputs: vec![Measured {
            variable: named("x0"),
            noise: 1e-4,
        }],
        states: vec![named("x0"), named("x1")],
        free: vec![Free {
            parameter: named("mu"),
            start: 1.2,
        }],
        set: Vec::new(),
    }
}

fn config_of(d: &EstimatorDeclaration) -> Config {
    let mut config = Config::new();
    for (key, value) in d.entries() {
        config.set(&key, value);
    }
    config
}

/// x0 of VanDerPol at t = 0.1 k (μ = 1.5), from its own initial state, 2 at k = 0.
fn measurements(dir: &Path) -> Vec<f64> {
    let spec = declared(Method::Ukf).plant_spec();
    let mut plant = FmuPlant::open(dir, &spec, integration(0.0, 1e-8)).unwrap();
    let times: Vec<f64> = (0..=30).map(|k| 0.1 * k as f64).collect();
    let rows = spurio_identify::online::simulate(&mut plant, &[1.5], &times, &[]).unwrap();
    std::iter::once(2.0)
        .chain(rows.iter().map(|y| y[0]))
        .collect()
}

/// The reference: the library's estimator with the filter `spurio identify` sets up.
fn reference(dir: &Path, d: &EstimatorDeclaration) -> Estimator {
    let plant = open_plant(dir, d, 0.0).unwrap();
    let plant = Rc::new(RefCell::new(plant));
    let x0 = plant.borrow_mut().initial_states(&d.starts()).unwrap();
    let filter = joint_filter(
        &plant,
        &d.starts(),
        &x0,
        &d.noise(),
        d.robust.influence(),
        d.method.linearisation(),
    )
    .unwrap();
    Estimator::new(filter, 0)
}

/// The value reference of the `i`-th variable of `block`.
fn vr(layout: &Layout, block: Block, i: usize) -> u32 {
    (layout.block(block).start + i) as u32
}

#[test]
fn the_fmu_gives_the_library_estimator_sample_by_sample_bit_for_bit() {
    for method in [Method::Ukf, Method::Ekf] {
        let res = resources(method.name());
        let d = declared(method);
        let layout = Layout::of(&d);
        let y = measurements(&res.0.join(PLANT_FOLDER));
        let mut h = Harness::<PlantEstimatorFmu>::with_resources(&config_of(&d), &res.0)
            .unwrap_or_else(|e| panic!("{e}"));
        h.initialize(0.0).unwrap();
        // Before the first sample: x̂₀ = VanDerPol's start (2, 0), μ̂₀ = 1.2 ± 0.24.
        assert_eq!(h.real(vr(&layout, Block::Outputs, 0)).unwrap(), 2.0);
        assert_eq!(h.real(vr(&layout, Block::Outputs, 2)).unwrap(), 1.2);
        assert!((h.real(vr(&layout, Block::Outputs, 5)).unwrap() - 0.24).abs() < 1e-12);
        let mut library = reference(&res.0.join(PLANT_FOLDER), &d);
        let mut allocations = Vec::new();
        for (k, yk) in y.iter().enumerate() {
            // Sample 12 is missing (its value garbage, its flag false).
            let missing = k == 12;
            let value = if missing { 1e6 } else { *yk };
            h.set_real(&[vr(&layout, Block::Measured, 0)], &[value])
                .unwrap();
            h.set_boolean(&[vr(&layout, Block::Valid, 0)], &[!missing])
                .unwrap();
            let (stepped, counts) =
                spurio_counting_allocator::count(|| h.do_step(0.1 * k as f64, 0.1));
            assert_eq!(stepped, Ok(Status::Ok), "sample {k}: {:?}", h.log());
            allocations.push(counts.allocations);
            let measured = if missing { f64::NAN } else { *yk };
            let expected = library
                .step(0.1 * k as f64, &[], &[measured])
                .unwrap()
                .to_vec();
            let mut fmu = vec![0.0; expected.len()];
            let all: Vec<u32> = layout.block(Block::Outputs).map(|v| v as u32).collect();
            h.get_real(&all, &mut fmu).unwrap();
            assert_eq!(fmu, expected, "{method:?}, sample {k}");
            if missing {
                assert_eq!(&fmu[6..9], &[0.0, 0.0, 0.0]);
            } else {
                assert!(fmu[8] > 0.0, "a present sample's weight: {fmu:?}");
            }
        }
        // μ̂ from 1.2 ± 0.24 to the truth 1.5 within 1 % after 3 s.
        let mu = h.real(vr(&layout, Block::Outputs, 2)).unwrap();
        let sd = h.real(vr(&layout, Block::Outputs, 5)).unwrap();
        assert!(
            (mu - 1.5).abs() < 0.015 && sd < 0.03,
            "{method:?}: μ̂ = {mu} ± {sd}"
        );
        println!("{method:?}: heap allocations per DoStep (one sample each): {allocations:?}");
        // The first sample sizes the filter's buffers; none after it allocates, missing or not.
        assert!(
            allocations[1..].iter().all(|&n| n == 0),
            "{method:?}: allocations per DoStep {allocations:?}"
        );
    }
}

#[test]
fn a_step_of_half_the_period_holds_and_a_double_step_takes_two_samples() {
    let res = resources("clock");
    let d = declared(Method::Ukf);
    let layout = Layout::of(&d);
    let y = measurements(&res.0.join(PLANT_FOLDER));
    let mut h = Harness::<PlantEstimatorFmu>::with_resources(&config_of(&d), &res.0).unwrap();
    h.set_real(&[layout.sample_period() as u32], &[0.1])
        .unwrap();
    h.initialize(0.0).unwrap();
    let mut library = reference(&res.0.join(PLANT_FOLDER), &d);
    let mu = vr(&layout, Block::Outputs, 2);
    h.set_real(&[vr(&layout, Block::Measured, 0)], &[y[0]])
        .unwrap();
    // [0, 0.05) holds sample 0; [0.05, 0.1) holds none.
    h.do_step(0.0, 0.05).unwrap();
    let after_first = library.step(0.0, &[], &[y[0]]).unwrap()[2];
    assert_eq!(h.real(mu).unwrap(), after_first);
    h.do_step(0.05, 0.05).unwrap();
    assert_eq!(h.real(mu).unwrap(), after_first);
    // [0.1, 0.3) holds samples 1 and 2, both with the inputs set before the step.
    h.set_real(&[vr(&layout, Block::Measured, 0)], &[y[1]])
        .unwrap();
    h.do_step(0.1, 0.2).unwrap();
    library.step(0.1, &[], &[y[1]]).unwrap();
    let two = library.step(0.2, &[], &[y[1]]).unwrap()[2];
    assert_eq!(h.real(mu).unwrap(), two);
}

/// The message with which instantiating `d` on `resources` is refused.
fn refusal(d: &EstimatorDeclaration, resources: &Path) -> String {
    match Harness::<PlantEstimatorFmu>::with_resources(&config_of(d), resources) {
        Ok(_) => panic!("{} on {} was not refused", d.name, resources.display()),
        Err(e) => e.to_string(),
    }
}

#[test]
fn a_missing_or_garbled_plant_fails_instantiation_naming_the_file() {
    let d = declared(Method::Ukf);
    let empty = std::env::temp_dir().join(format!(
        "spurio-plant-estimator-{}-none",
        std::process::id()
    ));
    std::fs::create_dir_all(&empty).unwrap();
    let guard = Resources(empty);
    let e = refusal(&d, &guard.0);
    assert!(e.contains("resources/plant"), "{e}");
    let res = resources("garbled");
    std::fs::write(
        res.0.join("plant/modelDescription.xml"),
        "<fmiModelDescription",
    )
    .unwrap();
    let e = refusal(&d, &res.0);
    assert!(
        e.contains("resources/plant") && e.contains("modelDescription"),
        "{e}"
    );
    // A plant of another shape than declared: the state count is compared.
    let res = resources("shape");
    let mut three = declared(Method::Ukf);
    three.states.push(Named {
        name: "x2".into(),
        unit: None,
    });
    let e = refusal(&three, &res.0);
    assert!(
        e.contains("2 continuous states") && e.contains("declares 3"),
        "{e}"
    );
    // A declared name the plant lacks.
    let mut unknown = declared(Method::Ukf);
    unknown.free[0].parameter.name = "nu".into();
    let e = refusal(&unknown, &res.0);
    assert!(e.contains("`nu`"), "{e}");
}

#[test]
fn the_library_bundles_no_variant_and_says_why() {
    assert!(bundled_variants().is_empty());
    // The table is laid out as its layout says: the first output and `sample_period`.
    let d = declared(Method::Ukf);
    let (variables, layout) = (variables(&d), Layout::of(&d));
    assert_eq!(
        variables[layout.block(Block::Outputs).start].name,
        "x_hat.x0"
    );
    assert_eq!(variables[layout.sample_period()].name, "sample_period");
    assert_eq!(variables.len(), layout.sample_period() + 1);
    let e = PlantEstimatorFmu::describe(&Config::new())
        .err()
        .unwrap()
        .to_string();
    assert!(e.contains("spurio package-estimator"), "{e}");
}

#[test]
fn a_bad_variance_fails_initialisation_naming_it() {
    let res = resources("variance");
    let d = declared(Method::Ukf);
    let layout = Layout::of(&d);
    let mut h = Harness::<PlantEstimatorFmu>::with_resources(&config_of(&d), &res.0).unwrap();
    h.set_real(&[vr(&layout, Block::Noise, 0)], &[0.0]).unwrap();
    assert_eq!(h.initialize(0.0), Err(Status::Error));
    assert!(h.logged(&["noise.x0", "> 0"]), "{:?}", h.log());
}

/// Steps `h` over samples `range` of `y` (0.1 s each) and gives every output after each.
fn outputs_over(
    h: &mut Harness<PlantEstimatorFmu>,
    layout: &Layout,
    y: &[f64],
    range: Range<usize>,
) -> Vec<Vec<f64>> {
    let all: Vec<u32> = layout.block(Block::Outputs).map(|v| v as u32).collect();
    range
        .map(|k| {
            h.set_real(&[vr(layout, Block::Measured, 0)], &[y[k]])
                .unwrap();
            assert_eq!(
                h.do_step(0.1 * k as f64, 0.1),
                Ok(Status::Ok),
                "{:?}",
                h.log()
            );
            let mut out = vec![0.0; all.len()];
            h.get_real(&all, &mut out).unwrap();
            out
        })
        .collect()
}

#[test]
fn a_serialized_state_restores_the_filter_bit_for_bit_here_and_in_a_fresh_instance() {
    const N: usize = 8;
    const M: usize = 10;
    for method in [Method::Ukf, Method::Ekf] {
        let res = resources(&format!("state-{}", method.name()));
        let d = declared(method);
        let layout = Layout::of(&d);
        let y = measurements(&res.0.join(PLANT_FOLDER));
        let mut h = Harness::<PlantEstimatorFmu>::with_resources(&config_of(&d), &res.0).unwrap();
        h.initialize(0.0).unwrap();
        outputs_over(&mut h, &layout, &y, 0..N);
        let bytes = h.serialized_state().unwrap();
        let first = outputs_over(&mut h, &layout, &y, N..N + M);
        // Back to sample N in the same instance: the same M samples again, bit for bit.
        assert_eq!(h.restore_state(&bytes), Ok(Status::Ok), "{:?}", h.log());
        assert_eq!(
            outputs_over(&mut h, &layout, &y, N..N + M),
            first,
            "{method:?}"
        );
        // In a fresh instance of the FMU, never initialised: the same.
        let mut fresh =
            Harness::<PlantEstimatorFmu>::with_resources(&config_of(&d), &res.0).unwrap();
        assert_eq!(
            fresh.restore_state(&bytes),
            Ok(Status::Ok),
            "{:?}",
            fresh.log()
        );
        assert_eq!(
            outputs_over(&mut fresh, &layout, &y, N..N + M),
            first,
            "{method:?}"
        );
        // The filter moved between N and N + M (the check compares something).
        assert_ne!(first[0][2], first[M - 1][2]);
        // A truncated state, and one with a garbled flag byte, are refused.
        let mut h = Harness::<PlantEstimatorFmu>::with_resources(&config_of(&d), &res.0).unwrap();
        for cut in [1, 9, model_part_length() / 2] {
            assert_eq!(
                h.restore_state(&bytes[..bytes.len() - cut]),
                Err(Status::Error)
            );
            assert!(h.logged(&["serialized FMU state", "left"]), "{:?}", h.log());
        }
        let mut garbled = bytes.clone();
        // The byte after the start time and the parameters (θ₀, R: 2 values) is the flag
        // "the filter was initialised": 7 is no boolean.
        let flag = garbled.len() - model_part_length() + 8 + 8 + 2 * 8;
        assert_eq!(garbled[flag], 1);
        garbled[flag] = 7;
        assert_eq!(h.restore_state(&garbled), Err(Status::Error));
        assert!(h.logged(&["invalid boolean"]), "{:?}", h.log());
    }
}

/// The length of the estimator's own part at the end of a serialized state of an initialised
/// `declared(…)` (L = 3, p = 1, q = 1, no input, no set parameter), from what
/// [`PlantEstimatorFmu::save_state`] writes: a vector is its length then its values.
fn model_part_length() -> usize {
    let (l, p, q) = (3, 1, 1);
    let vector = |n: usize| 8 + 8 * n;
    let mut clock = ByteWriter::new();
    clock::save(&SampleClock::new(Rule::Step, 0.0, 0.0).unwrap(), &mut clock);
    8 + vector(q + p)
        + 1
        + vector(l)
        + vector(l * l)
        + 1
        + 8
        + vector(0)
        + 8
        + vector(2 * l + 3 * p)
        + clock.into_bytes().len()
}

#[test]
fn a_state_of_another_configuration_is_refused_naming_the_counts() {
    let res = resources("other");
    let d = declared(Method::Ukf);
    let mut h = Harness::<PlantEstimatorFmu>::with_resources(&config_of(&d), &res.0).unwrap();
    h.initialize(0.0).unwrap();
    let bytes = h.serialized_state().unwrap();
    // The same model, another configuration (a set parameter more): the export layer's
    // check of the variable count refuses it, and so does the estimator's own of the
    // parameter count when handed the model part.
    let mut other = declared(Method::Ukf);
    other.set.push(("x1".into(), 0.0));
    let mut h = Harness::<PlantEstimatorFmu>::with_resources(&config_of(&other), &res.0).unwrap();
    assert_eq!(h.restore_state(&bytes), Err(Status::Error));
    let info = PlantEstimatorFmu::describe(&config_of(&other)).unwrap();
    let mut model = PlantEstimatorFmu::create_with_resources(&info, Some(&res.0)).unwrap();
    let mut w = ByteWriter::new();
    w.put_f64(0.0);
    w.put_f64_slice(&[1.2, 1e-4]);
    w.put_bool(false);
    let bytes = w.into_bytes();
    let e = model.load_state(&mut ByteReader::new(&bytes)).unwrap_err();
    assert!(
        e.to_string().contains("2 parameters") && e.to_string().contains("has 3"),
        "{e}"
    );
}
