//! The export layer allocates nothing once an instance is initialised: a toy model that
//! itself allocates nothing (Real, Integer and Boolean inputs and outputs, an FMI 3.0 array,
//! direct feedthrough, a tunable parameter set every step, an event logged every step with
//! logging off) driven through the FMI 2.0 and FMI 3.0 C entry points under a counting global
//! allocator: set every input, DoStep, get every output, with zero allocations and frees; and
//! a Model Exchange loop with twelve event indicators, and an importer's restart of a Model
//! Exchange instance (reset, initialisation, nominals). The FMUs' own count is
//! `tests/allocations/run`.
#![allow(unsafe_code)]

use spurio_counting_allocator::CountingAllocator;
use spurio_export::abi::model_exchange::{self as me, Array};
use spurio_export::fmi2::{ffi, functions as me2_functions, values};
use spurio_export::fmi3::ffi as ffi3;
use spurio_export::fmi3::types::*;
use spurio_export::fmi3::values as values3;
use spurio_export::types::*;
use spurio_export::{
    ByteReader, ByteWriter, Causality, Cause, Config, Context, Failure, FmuModel, ModelInfo, Value,
    Variability, Variable,
};
use std::ffi::CString;

#[path = "common/ramp.rs"]
mod ramp;

use ramp::{expected, Me, N, Z0};

#[global_allocator]
static ALLOCATOR: CountingAllocator = CountingAllocator;

/// The allocations and frees of this thread during `f`.
fn count(f: impl FnOnce()) -> u64 {
    spurio_counting_allocator::count(f).1.events()
}

/// An input of another type than Real: discrete, no `initial`.
fn input(v: Variable) -> Variable {
    Variable {
        causality: Causality::Input,
        variability: Variability::Discrete,
        initial: None,
        ..v
    }
}

spurio_export::declare_variables! {
    /// u (Real inputs, an array in FMI 3.0), k (Integer input), b (Boolean input);
    /// y = gain · ∫u; z = u[1] + k (direct feedthrough); n = steps taken; on = b and
    /// y[1] > 0; gain a tunable parameter.
    fn variables() {
        table: [
            U[2] = ["u[1]", "u[2]"].map(|n| Variable::input(n, 0.0)),
            K = input(Variable::integer_parameter("k", 0)).min(-5.0).max(5.0),
            B = input(Variable::boolean_parameter("b", false)),
            Y[2] = ["y[1]", "y[2]"].map(Variable::output),
            Z = Variable::output("z").depends_on(&[vr::U, vr::K]),
            N = Variable { start: Value::Integer(0), ..Variable::discrete_output("n") },
            ON = Variable::boolean_output("on"),
            GAIN = Variable::parameter("gain", 1.0).tunable().min(0.0),
        ]
    }
}

/// The toy: its state is ∫u[1], ∫u[2] and the number of steps.
#[derive(Clone, Debug, Default)]
struct Toy([f64; 3]);

impl FmuModel for Toy {
    fn describe(config: &Config) -> Result<ModelInfo, Cause> {
        let info = ModelInfo::new("Toy", "toy", variables(), None, config.clone());
        Ok(info)
    }
    fn create(_info: &ModelInfo) -> Result<Self, Cause> {
        Ok(Toy([0.0; 3]))
    }
    fn initialize(&mut self, ctx: &mut Context) -> Result<(), Failure> {
        *self = Self::default();
        self.write(ctx)
    }
    fn do_step(&mut self, ctx: &mut Context, _time: f64, step: f64) -> Result<(), Failure> {
        self.0[0] += step * ctx.values.real(vr::U);
        self.0[1] += step * ctx.values.real(vr::U + 1);
        self.0[2] += 1.0;
        ctx.log_event(|| "a step taken".into());
        self.write(ctx)
    }
    fn update_outputs(&mut self, ctx: &mut Context) -> Result<(), Failure> {
        self.write(ctx)
    }
    fn parameters_changed(&mut self, ctx: &mut Context) -> Result<(), Failure> {
        self.write(ctx)
    }
    fn save_state(&self, out: &mut ByteWriter) {
        self.0.iter().for_each(|x| out.put_f64(*x));
    }
    fn load_state(&mut self, input: &mut ByteReader) -> Result<(), Cause> {
        for x in &mut self.0 {
            *x = input.f64()?;
        }
        Ok(())
    }
}

impl Toy {
    fn write(&self, ctx: &mut Context) -> Result<(), Failure> {
        let v = &mut *ctx.values;
        let gain = v.real(vr::GAIN);
        v.set_real(vr::Y, gain * self.0[0]);
        v.set_real(vr::Y + 1, gain * self.0[1]);
        v.set_real(vr::Z, v.real(vr::U) + f64::from(v.integer(vr::K)));
        v.set_integer(vr::N, self.0[2] as i32);
        v.set_boolean(vr::ON, v.boolean(vr::B) && self.0[0] > 0.0);
        Ok(())
    }
}

fn token() -> CString {
    CString::new(Toy::describe(&Config::new()).unwrap().guid).unwrap()
}

const STEPS: usize = 100;
const H: f64 = 0.01;
/// Every step sets u = (1, −2), k = 3, b = true, gain = 2.
const INPUTS: ([f64; 2], i32, f64) = ([1.0, -2.0], 3, 2.0);

/// Runs `STEPS` exchanges under the counter: `exchange(t)` sets the inputs, steps from `t`
/// and reads the outputs, returning its calls' statuses and y[1], y[2], z, n, on. Checks
/// that every call succeeded, the outputs, and that nothing was allocated or freed.
fn check(version: &str, mut exchange: impl FnMut(f64) -> ([i32; 8], [f64; 5])) {
    let mut statuses = Vec::with_capacity(STEPS);
    let mut outputs = [f64::NAN; 5];
    let allocations = count(|| {
        for i in 0..STEPS {
            let (status, read) = exchange(i as f64 * H);
            statuses.push(status);
            outputs = read;
        }
    });
    assert!(
        statuses.iter().flatten().all(|s| *s == 0),
        "{version}: {statuses:?}"
    );
    // y = gain · Σ h u, z = u[1] + k, every step counted, on = b and y[1] > 0.
    let integral = INPUTS.2 * STEPS as f64 * H;
    let expected = [integral, -2.0 * integral, 4.0, STEPS as f64, 1.0];
    for (got, want) in outputs.iter().zip(expected) {
        assert!(
            (got - want).abs() < 1e-12,
            "{version}: {outputs:?}, not {expected:?}"
        );
    }
    assert_eq!(
        allocations, 0,
        "{version}: allocations and frees in {STEPS} steps"
    );
}

#[test]
fn fmi2_set_step_get_allocates_nothing() {
    let name = CString::new("toy").unwrap();
    let callbacks = fmi2CallbackFunctions {
        logger: None,
        allocateMemory: None,
        freeMemory: None,
        stepFinished: None,
        componentEnvironment: std::ptr::null_mut(),
    };
    let (token, null) = (token(), std::ptr::null());
    let (cs, off) = (fmi2CoSimulation, fmi2False);
    let c = unsafe {
        ffi::instantiate::<Toy>(
            name.as_ptr(),
            cs,
            token.as_ptr(),
            null,
            &callbacks,
            off,
            off,
            None,
        )
    };
    assert!(!c.is_null());
    unsafe {
        assert_eq!(ffi::setup_experiment::<Toy>(c, 0, 0.0, 0.0, 0, 0.0), fmi2OK);
        assert_eq!(ffi::enter_initialization_mode::<Toy>(c), fmi2OK);
        assert_eq!(ffi::exit_initialization_mode::<Toy>(c), fmi2OK);
    }
    let [u1, u2, k, b, gain, y1, y2, z, n, on] = [
        vr::U,
        vr::U + 1,
        vr::K,
        vr::B,
        vr::GAIN,
        vr::Y,
        vr::Y + 1,
        vr::Z,
        vr::N,
        vr::ON,
    ]
    .map(|i| i as u32);
    let (u, (reals, integers, booleans)) = ([u1, u2], ([y1, y2, z], [k, n], [b, on]));
    let (k_value, gain_value) = (INPUTS.1, INPUTS.2);
    check("FMI 2.0", |t| unsafe {
        let (mut y, mut ints, mut bools) = ([0.0; 3], [0; 2], [0; 2]);
        let status = [
            values::set::<Toy, values::Real>(c, u.as_ptr(), 2, INPUTS.0.as_ptr()),
            values::set::<Toy, values::Integer>(c, &k, 1, &k_value),
            values::set::<Toy, values::Boolean>(c, &b, 1, &fmi2True),
            values::set::<Toy, values::Real>(c, &gain, 1, &gain_value),
            ffi::do_step::<Toy>(c, t, H, fmi2True),
            values::get::<Toy, values::Real>(c, reals.as_ptr(), 3, y.as_mut_ptr()),
            values::get::<Toy, values::Integer>(c, integers.as_ptr(), 2, ints.as_mut_ptr()),
            values::get::<Toy, values::Boolean>(c, booleans.as_ptr(), 2, bools.as_mut_ptr()),
        ];
        (
            status,
            [y[0], y[1], y[2], f64::from(ints[1]), f64::from(bools[1])],
        )
    });
    unsafe { ffi::free_instance::<Toy>(c) };
}

#[test]
fn fmi3_set_step_get_allocates_nothing() {
    let name = CString::new("toy").unwrap();
    let (token, off) = (token(), fmi3False);
    let env = std::ptr::null_mut();
    let c = unsafe {
        let args = ffi3::Instantiation(
            name.as_ptr(),
            token.as_ptr(),
            std::ptr::null(),
            off,
            env,
            None,
        );
        ffi3::instantiate_co_simulation::<Toy>(args, off, off, 0, None)
    };
    assert!(!c.is_null());
    unsafe {
        assert_eq!(
            ffi3::enter_initialization_mode::<Toy>(c, 0.0, 0, 0.0),
            fmi3OK
        );
        assert_eq!(ffi3::exit_initialization_mode::<Toy>(c), fmi3OK);
    }
    // FMI 3.0 value references: 0 time, 1 u (array of 2), 2 k, 3 b, 4 y (array of 2), 5 z,
    // 6 n, 7 on, 8 gain.
    let (u, k, b, gain) = (1u32, 2u32, 3u32, 8u32);
    let (reals, integers, booleans) = ([4u32, 5], [2u32, 6], [3u32, 7]);
    let (k_value, gain_value) = (INPUTS.1, INPUTS.2);
    check("FMI 3.0", |t| unsafe {
        let (mut y, mut ints, mut bools) = ([0.0; 3], [0; 2], [0u8; 2]);
        let (mut event, mut terminate, mut early, mut last) = (0, 0, 0, 0.0);
        let status = [
            values3::set::<Toy, values3::Float64>(c, &u, 1, INPUTS.0.as_ptr(), 2),
            values3::set::<Toy, values3::Int32>(c, &k, 1, &k_value, 1),
            values3::set::<Toy, values3::Boolean>(c, &b, 1, &fmi3True, 1),
            values3::set::<Toy, values3::Float64>(c, &gain, 1, &gain_value, 1),
            ffi3::do_step::<Toy>(c, t, H, &mut event, &mut terminate, &mut early, &mut last),
            values3::get::<Toy, values3::Float64>(c, reals.as_ptr(), 2, y.as_mut_ptr(), 3),
            values3::get::<Toy, values3::Int32>(c, integers.as_ptr(), 2, ints.as_mut_ptr(), 2),
            values3::get::<Toy, values3::Boolean>(c, booleans.as_ptr(), 2, bools.as_mut_ptr(), 2),
        ];
        (
            status,
            [y[0], y[1], y[2], f64::from(ints[1]), f64::from(bools[1])],
        )
    });
    unsafe { ffi3::free_instance::<Toy>(c) };
}

/// Model Exchange: evaluations (time and states set, derivatives read) and the event
/// indicators computed when read (twelve of them, through `fmi2GetEventIndicators` and a
/// getter of an indicator's variable) allocate nothing (`common/ramp.rs`).
#[test]
fn evaluations_and_indicators_allocate_nothing_at_twelve_indicators() {
    let mut m = Me::new();
    let mut z = [0.0; N];
    m.set(0.0, 1.0);
    assert_eq!(m.indicators(&mut z), fmi2OK);
    let n = count(|| {
        for k in 0..100 {
            m.set(k as f64, k as f64 + 0.25);
            assert_eq!(m.derivative(), 1.0);
            assert_eq!(m.indicators(&mut z), fmi2OK);
            let mut one = [0.0];
            m.0.get_real(&[(Z0 + 2) as u32], &mut one).unwrap();
            assert_eq!(one[0], k as f64 - 1.75);
        }
    });
    assert_eq!(z, expected(99.25));
    assert_eq!(n, 0, "allocations and frees in 100 evaluations");
}

/// What an importer does at every restart of a Model Exchange plant, as the estimator FMU
/// (PlantEstimator) does once per sigma point and step: `fmi2Reset`, the input set,
/// initialisation, Continuous-Time Mode, the state nominals read, states and derivatives.
/// It allocates nothing after the first cycle: the reset refills the values in place and the
/// nominals are written into the caller's buffer (each allocated before, 11,958 allocations
/// in 200 steps of the GantryCrane's estimator through the C driver).
#[test]
fn reset_initialise_and_nominals_allocate_nothing() {
    let mut m = Me::new();
    let mut restart = |u: f64| {
        let h = &mut m.0;
        assert_eq!(h.reset(), Ok(Status::Ok));
        assert_eq!(h.set_real(&[ramp::U as u32], &[u]), Ok(Status::Ok));
        assert_eq!(h.initialize(0.0), Ok(Status::Ok));
        let (c, f) = (h.component(), &me2_functions::ENTER_CONTINUOUS_TIME_MODE);
        assert_eq!(
            unsafe { me::enter_mode::<ramp::Ramp, ()>(c, f, false) },
            fmi2OK
        );
        let mut nominal = f64::NAN;
        let (f, which) = (
            &me2_functions::GET_NOMINALS_OF_CONTINUOUS_STATES,
            Array::Nominals,
        );
        let s = unsafe { me::get_array::<ramp::Ramp, ()>(c, f, which, &mut nominal, 1) };
        assert_eq!((s, nominal), (fmi2OK, 1.0));
        m.set(0.5, 2.0);
        assert_eq!(m.derivative(), u);
    };
    restart(3.0);
    let n = count(|| {
        for k in 0..100 {
            restart(k as f64 - 50.0);
        }
    });
    assert_eq!(n, 0, "allocations and frees in 100 restarts");
}
