//! Missing samples through the FMUs of the Kalman family (docs/estimators.md, "Missing
//! samples"): `y_valid[j]` = false is the missing sample of the library's filters (a NaN
//! y_j), through `fmi2SetBoolean` and `fmi2DoStep`: the sKF and rsKF FMUs give the library
//! filter's numbers bit for bit, the dual filters hold Θ̂ over a gap, every output finite.

use nalgebra::{DMatrix, DVector};
use spurio::estimation::StateEstimator;
use spurio::estimation::{GaussianModel, InfluenceFunction, KalmanFilter, RobustKalmanFilter};
use spurio::state_space::StateSpace;
use spurio_export::harness::Harness;
use spurio_export::FmuModel;
use spurio_fmu_kalman::{
    dims_config, DkfRsKfFmu, DualKalmanFilterFmu, KalmanFilterFmu, RobustKalmanFilterFmu,
};

/// The FMU `M` for (n, m, p), initialised with `P0` = 0.5 I, and its value references.
fn instance<M: FmuModel>(n: usize, m: usize, p: usize) -> (Harness<M>, impl Fn(&str) -> u32) {
    let config = dims_config(n, m, p);
    let info = M::describe(&config).unwrap();
    let vr = move |name: &str| info.index_of(name).unwrap() as u32;
    let mut h = Harness::<M>::new(&config).unwrap();
    h.setup_experiment(0.0, None).unwrap();
    h.enter_initialization_mode().unwrap();
    for i in 1..=n {
        h.set_real(&[vr(&format!("P0[{i},{i}]"))], &[0.5]).unwrap();
    }
    h.exit_initialization_mode().unwrap();
    (h, vr)
}

/// The FMUs' defaults (A = I, B = 0, C = [I 0], D = 0, Q = R = 1e-4 I, x̂₀ = 0) with P₀ = 0.5 I.
fn default_model(n: usize, m: usize, p: usize) -> GaussianModel {
    let mut c = DMatrix::zeros(p, n);
    for j in 0..p.min(n) {
        c[(j, j)] = 1.0;
    }
    GaussianModel {
        system: StateSpace {
            a: DMatrix::identity(n, n),
            b: DMatrix::zeros(n, m),
            c,
            d: DMatrix::zeros(p, m),
            q: DMatrix::identity(n, n) * 1e-4,
            r: DMatrix::identity(p, p) * 1e-4,
        },
        x0: DVector::zeros(n),
        p0: DMatrix::identity(n, n) * 0.5,
    }
}

/// Which channels of sample k are present: gaps of one channel, of every channel (a run of
/// 20 samples), none.
fn present(k: usize, p: usize) -> Vec<bool> {
    (0..p)
        .map(|j| match k {
            40..60 => false,
            _ if k % 7 == 3 => j != 0,
            _ if k % 11 == 5 => j != p - 1,
            _ => true,
        })
        .collect()
}

/// Runs the FMU and the library filter side by side; every output equal bit for bit.
fn fmu_equals_library<M: FmuModel, F: StateEstimator>(n: usize, m: usize, p: usize, mut f: F) {
    let (mut h, vr) = instance::<M>(n, m, p);
    let names = |prefix: &str, len: usize| -> Vec<u32> {
        (1..=len).map(|i| vr(&format!("{prefix}[{i}]"))).collect()
    };
    let (u_vr, y_vr, valid_vr) = (names("u", m), names("y", p), names("y_valid", p));
    let (x_vr, e_vr) = (names("x_hat", n), names("innovation", p));
    let (mut x_out, mut e_out) = (vec![0.0; n], vec![0.0; p]);
    for k in 0..100 {
        let t = k as f64 * 0.05;
        let u: Vec<f64> = (0..m).map(|i| (t * (i + 1) as f64).sin()).collect();
        let y: Vec<f64> = (0..p)
            .map(|j| (t + j as f64).cos() + 0.01 * (k % 3) as f64)
            .collect();
        let present = present(k, p);
        h.set_real(&u_vr, &u).unwrap();
        h.set_real(&y_vr, &y).unwrap();
        h.set_boolean(&valid_vr, &present).unwrap();
        h.do_step(t, 0.05).unwrap();
        let y_lib = DVector::from_iterator(
            p,
            y.iter()
                .zip(&present)
                .map(|(y, ok)| if *ok { *y } else { f64::NAN }),
        );
        f.step(&DVector::from_vec(u), &y_lib).unwrap();
        h.get_real(&x_vr, &mut x_out).unwrap();
        h.get_real(&e_vr, &mut e_out).unwrap();
        assert_eq!(x_out.as_slice(), f.state().as_slice(), "x̂ at step {k}");
        assert_eq!(e_out.as_slice(), f.innovation().as_slice(), "e at step {k}");
        for (e, ok) in e_out.iter().zip(&present) {
            assert!(*ok || *e == 0.0, "the innovation of a missing sample is 0");
        }
    }
}

#[test]
fn kalman_filter_fmus_on_missing_samples_equal_the_library_filter() {
    for (n, m, p) in [(1, 0, 1), (1, 1, 1), (2, 1, 2), (3, 1, 2)] {
        let kf = KalmanFilter::new(default_model(n, m, p)).unwrap();
        fmu_equals_library::<KalmanFilterFmu, _>(n, m, p, kf);
        let psi = InfluenceFunction::huber();
        let rkf = RobustKalmanFilter::new(default_model(n, m, p), psi).unwrap();
        fmu_equals_library::<RobustKalmanFilterFmu, _>(n, m, p, rkf);
    }
}

#[test]
fn robust_filter_fmu_reports_weight_zero_for_a_missing_sample() {
    let (mut h, vr) = instance::<RobustKalmanFilterFmu>(2, 0, 2);
    h.set_real(&[vr("y[1]"), vr("y[2]")], &[1.0, 2.0]).unwrap();
    h.set_boolean(&[vr("y_valid[2]")], &[false]).unwrap();
    h.do_step(0.0, 0.1).unwrap();
    assert_eq!(h.real(vr("w[2]")).unwrap(), 0.0);
    assert!(h.real(vr("w[1]")).unwrap() > 0.0);
}

/// The dual filters over a gap of 30 samples: Θ̂ (every `A_hat`, `B_hat`) held exactly,
/// x̂ and ŷ finite, and the DKF-rsKF's weights 0; learning resumes after the gap.
#[test]
fn dual_filter_fmus_hold_theta_over_a_gap() {
    fn run<M: FmuModel>(cleaned: bool) {
        let (n, m, p) = (4, 1, 2);
        let (mut h, vr) = instance::<M>(n, m, p);
        let theta: Vec<u32> = (1..=n)
            .flat_map(|i| (1..=n).map(move |k| (i, k)))
            .map(|(i, k)| vr(&format!("A_hat[{i},{k}]")))
            .chain((1..=n).map(|i| vr(&format!("B_hat[{i},1]"))))
            .collect();
        let outputs = [
            vr("x_hat[1]"),
            vr("x_hat[4]"),
            vr("y_hat[1]"),
            vr("y_hat[2]"),
        ];
        let (mut held, mut now, mut out) =
            (vec![0.0; theta.len()], vec![0.0; theta.len()], [0.0; 4]);
        let valid = [vr("y_valid[1]"), vr("y_valid[2]")];
        for k in 0..120 {
            let t = k as f64 * 0.05;
            h.set_real(
                &[vr("u[1]"), vr("y[1]"), vr("y[2]")],
                &[t.sin(), t.cos(), 0.3 * t.sin()],
            )
            .unwrap();
            let gap = (50..80).contains(&k);
            h.set_boolean(&valid, &[!gap, !gap]).unwrap();
            h.do_step(t, 0.05).unwrap();
            h.get_real(&theta, &mut now).unwrap();
            h.get_real(&outputs, &mut out).unwrap();
            assert!(out.iter().chain(&now).all(|v| v.is_finite()), "step {k}");
            if gap {
                assert_eq!(now, held, "Θ̂ held at step {k}");
                if cleaned {
                    assert_eq!(h.real(vr("w[1]")).unwrap(), 0.0);
                }
            }
            if k == 49 {
                held.clone_from(&now);
            }
        }
        assert_ne!(now, held, "learning resumed after the gap");
    }
    run::<DualKalmanFilterFmu>(false);
    run::<DkfRsKfFmu>(true);
}

/// An FMU state saved right after a missing sample (the DKF keeps y_{k−1} as missing) and
/// restored continues bit for bit.
#[test]
fn a_state_saved_after_a_missing_sample_continues_bit_for_bit() {
    let (mut h, vr) = instance::<DkfRsKfFmu>(4, 1, 2);
    let inputs = [vr("u[1]"), vr("y[1]"), vr("y[2]")];
    let valid = [vr("y_valid[1]"), vr("y_valid[2]")];
    let outputs = [
        vr("x_hat[1]"),
        vr("A_hat[1,1]"),
        vr("y_clean[2]"),
        vr("w[1]"),
    ];
    let sample = |h: &mut Harness<DkfRsKfFmu>, k: usize, present: [bool; 2]| {
        let t = k as f64 * 0.05;
        h.set_real(&inputs, &[t.sin(), t.cos(), 0.3 * t.sin()])
            .unwrap();
        h.set_boolean(&valid, &present).unwrap();
        h.do_step(t, 0.05).unwrap();
        let mut out = [0.0; 4];
        h.get_real(&outputs, &mut out).unwrap();
        out
    };
    for k in 0..30 {
        sample(&mut h, k, [true, true]);
    }
    sample(&mut h, 30, [false, true]);
    let saved = h.serialized_state().unwrap();
    let mut runs = Vec::new();
    for restore in [false, true] {
        if restore {
            h.restore_state(&saved).unwrap();
        }
        let outputs: Vec<[f64; 4]> = (31..60)
            .map(|k| sample(&mut h, k, [k % 5 != 0, true]))
            .collect();
        runs.push(outputs);
    }
    let (first, second) = (&runs[0], &runs[1]);
    assert_eq!(first, second);
    assert!(first.iter().flatten().all(|v| v.is_finite()));
}
