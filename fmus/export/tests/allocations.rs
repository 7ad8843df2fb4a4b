//! The export layer allocates nothing once an instance is initialised: a toy model that
//! itself allocates nothing (Real, Integer and Boolean inputs and outputs, an FMI 3.0 array,
//! direct feedthrough, a tunable parameter set every step, an event logged every step with
//! logging off) driven through the FMI 2.0 and FMI 3.0 C entry points under a counting global
//! allocator: set every input, DoStep, get every output, with zero allocations and frees. The
//! FMUs' own count is `tests/allocations/run`.
#![allow(unsafe_code)]

use spurio_export::fmi3::ffi as ffi3;
use spurio_export::fmi3::types::*;
use spurio_export::types::*;
use spurio_export::{
    ffi, ByteReader, ByteWriter, Causality, Cause, Config, Context, Failure, FmuModel, ModelInfo,
    Variability, Variable,
};
use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::ffi::CString;

/// Counts the allocations and frees of the thread while `COUNTING` is set.
struct Counter;

thread_local! {
    static COUNTING: Cell<bool> = const { Cell::new(false) };
    static EVENTS: Cell<usize> = const { Cell::new(0) };
}

fn note() {
    let _ = COUNTING.try_with(|on| {
        if on.get() {
            let _ = EVENTS.try_with(|n| n.set(n.get() + 1));
        }
    });
}

unsafe impl GlobalAlloc for Counter {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        note();
        unsafe { System.alloc(layout) }
    }
    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        note();
        unsafe { System.alloc_zeroed(layout) }
    }
    unsafe fn realloc(&self, p: *mut u8, layout: Layout, size: usize) -> *mut u8 {
        note();
        unsafe { System.realloc(p, layout, size) }
    }
    unsafe fn dealloc(&self, p: *mut u8, layout: Layout) {
        note();
        unsafe { System.dealloc(p, layout) }
    }
}

#[global_allocator]
static COUNTER: Counter = Counter;

/// The allocations and frees of this thread during `f`.
fn count(f: impl FnOnce()) -> usize {
    EVENTS.with(|n| n.set(0));
    COUNTING.with(|on| on.set(true));
    f();
    COUNTING.with(|on| on.set(false));
    EVENTS.with(|n| n.get())
}

/// u[1], u[2] (Real inputs, an array in FMI 3.0), k (Integer input), b (Boolean input);
/// y[1], y[2] = gain · ∫u; z = u[1] + k (direct feedthrough); n = steps taken; on = b and
/// y[1] > 0; gain a tunable parameter.
#[derive(Clone, Debug, Default)]
struct Toy {
    y: [f64; 2],
    steps: i32,
}

const U: usize = 0;
const K: usize = 2;
const B: usize = 3;
const Y: usize = 4;
const Z: usize = 6;
const N: usize = 7;
const ON: usize = 8;
const GAIN: usize = 9;

impl FmuModel for Toy {
    fn describe(_config: &Config) -> Result<ModelInfo, Cause> {
        let input = |v: Variable| Variable {
            causality: Causality::Input,
            variability: Variability::Discrete,
            initial: None,
            ..v
        };
        let vars = vec![
            Variable::input("u[1]", 0.0),
            Variable::input("u[2]", 0.0),
            input(Variable::integer_parameter("k", 0))
                .min(-5.0)
                .max(5.0),
            input(Variable::boolean_parameter("b", false)),
            Variable::output("y[1]"),
            Variable::output("y[2]"),
            Variable::output("z").depends_on(&[U, K]),
            Variable {
                start: spurio_export::Value::Integer(0),
                ..Variable::discrete_output("n")
            },
            Variable::boolean_output("on"),
            Variable::parameter("gain", 1.0).tunable().min(0.0),
        ];
        Ok(ModelInfo::new("Toy", "toy", vars, None, Config::new()))
    }
    fn create(_info: &ModelInfo) -> Result<Self, Cause> {
        Ok(Self::default())
    }
    fn initialize(&mut self, ctx: &mut Context) -> Result<(), Failure> {
        *self = Self::default();
        self.write(ctx);
        Ok(())
    }
    fn do_step(&mut self, ctx: &mut Context, _time: f64, step: f64) -> Result<(), Failure> {
        for i in 0..2 {
            self.y[i] += step * ctx.values.real(U + i);
        }
        self.steps += 1;
        ctx.log_event("a step taken");
        self.write(ctx);
        Ok(())
    }
    fn update_outputs(&mut self, ctx: &mut Context) -> Result<(), Failure> {
        self.write(ctx);
        Ok(())
    }
    fn parameters_changed(&mut self, ctx: &mut Context) -> Result<(), Failure> {
        self.write(ctx);
        Ok(())
    }
    fn save_state(&self, out: &mut ByteWriter) {
        out.put_f64(self.y[0]);
        out.put_f64(self.y[1]);
        out.put_i32(self.steps);
    }
    fn load_state(&mut self, input: &mut ByteReader) -> Result<(), Cause> {
        self.y = [input.f64()?, input.f64()?];
        self.steps = input.i32()?;
        Ok(())
    }
}

impl Toy {
    fn write(&self, ctx: &mut Context) {
        let gain = ctx.values.real(GAIN);
        ctx.values.set_real(Y, gain * self.y[0]);
        ctx.values.set_real(Y + 1, gain * self.y[1]);
        let z = ctx.values.real(U) + f64::from(ctx.values.integer(K));
        ctx.values.set_real(Z, z);
        ctx.values.set_integer(N, self.steps);
        let on = ctx.values.boolean(B) && self.y[0] > 0.0;
        ctx.values.set_boolean(ON, on);
    }
}

fn token() -> CString {
    CString::new(Toy::describe(&Config::new()).unwrap().guid).unwrap()
}

const STEPS: usize = 100;
const H: f64 = 0.01;

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
    let token = token();
    let c = unsafe {
        ffi::instantiate::<Toy>(
            name.as_ptr(),
            fmi2CoSimulation,
            token.as_ptr(),
            std::ptr::null(),
            &callbacks,
            fmi2False,
            fmi2False,
        )
    };
    assert!(!c.is_null());
    unsafe {
        assert_eq!(ffi::setup_experiment::<Toy>(c, 0, 0.0, 0.0, 0, 0.0), fmi2OK);
        assert_eq!(ffi::enter_initialization_mode::<Toy>(c), fmi2OK);
        assert_eq!(ffi::exit_initialization_mode::<Toy>(c), fmi2OK);
    }
    let (u, k, b) = ([U as u32, U as u32 + 1], [K as u32], [B as u32]);
    let (reals, n, on, gain) = (
        [Y as u32, Y as u32 + 1, Z as u32],
        [N as u32],
        [ON as u32],
        [GAIN as u32],
    );
    let mut y = [0.0; 3];
    let (mut steps, mut positive) = ([0], [0]);
    let mut statuses = Vec::with_capacity(8 * STEPS);
    let allocations = count(|| {
        for i in 0..STEPS {
            let t = i as f64 * H;
            unsafe {
                statuses.push(ffi::set::<Toy, ffi::Real>(
                    c,
                    u.as_ptr(),
                    2,
                    [1.0, -2.0].as_ptr(),
                ));
                statuses.push(ffi::set::<Toy, ffi::Integer>(
                    c,
                    k.as_ptr(),
                    1,
                    [3].as_ptr(),
                ));
                statuses.push(ffi::set::<Toy, ffi::Boolean>(
                    c,
                    b.as_ptr(),
                    1,
                    [fmi2True].as_ptr(),
                ));
                statuses.push(ffi::set::<Toy, ffi::Real>(
                    c,
                    gain.as_ptr(),
                    1,
                    [2.0].as_ptr(),
                ));
                statuses.push(ffi::do_step::<Toy>(c, t, H, fmi2True));
                statuses.push(ffi::get::<Toy, ffi::Real>(
                    c,
                    reals.as_ptr(),
                    3,
                    y.as_mut_ptr(),
                ));
                statuses.push(ffi::get::<Toy, ffi::Integer>(
                    c,
                    n.as_ptr(),
                    1,
                    steps.as_mut_ptr(),
                ));
                statuses.push(ffi::get::<Toy, ffi::Boolean>(
                    c,
                    on.as_ptr(),
                    1,
                    positive.as_mut_ptr(),
                ));
            }
        }
    });
    unsafe { ffi::free_instance::<Toy>(c) };
    assert!(statuses.iter().all(|s| *s == fmi2OK), "{statuses:?}");
    // The model ran: y = gain · Σ h u, z = u[1] + k, every step counted.
    let integral = STEPS as f64 * H;
    assert!((y[0] - 2.0 * integral).abs() < 1e-12, "{y:?}");
    assert!((y[1] + 4.0 * integral).abs() < 1e-12, "{y:?}");
    assert_eq!(y[2], 4.0);
    assert_eq!((steps[0], positive[0]), (STEPS as i32, fmi2True));
    assert_eq!(
        allocations, 0,
        "allocations and frees in {STEPS} FMI 2.0 steps"
    );
}

#[test]
fn fmi3_set_step_get_allocates_nothing() {
    let name = CString::new("toy").unwrap();
    let token = token();
    let c = unsafe {
        ffi3::instantiate_co_simulation::<Toy>(
            name.as_ptr(),
            token.as_ptr(),
            std::ptr::null(),
            fmi3False,
            fmi3False,
            fmi3False,
            0,
            std::ptr::null_mut(),
            None,
        )
    };
    assert!(!c.is_null());
    unsafe {
        assert_eq!(
            ffi3::enter_initialization_mode::<Toy>(c, 0.0, 0, 0.0),
            fmi3OK
        );
        assert_eq!(ffi3::exit_initialization_mode::<Toy>(c), fmi3OK);
    }
    // FMI 3.0 value references: 0 time, 1 u (array of 2), 2 k, 3 b, 4 y (array), 5 z, 6 n,
    // 7 on, 8 gain.
    let (u, k, b, gain) = ([1u32], [2u32], [3u32], [8u32]);
    let (reals, n, on) = ([0u32, 4, 5], [6u32], [7u32]);
    let mut y = [0.0; 4];
    let (mut steps, mut positive) = ([0], [0u8]);
    let mut statuses = Vec::with_capacity(8 * STEPS);
    let allocations = count(|| {
        for i in 0..STEPS {
            let t = i as f64 * H;
            let (mut event, mut terminate, mut early, mut last) = (0, 0, 0, 0.0);
            unsafe {
                statuses.push(ffi3::set::<Toy, ffi3::Float64>(
                    c,
                    u.as_ptr(),
                    1,
                    [1.0, -2.0].as_ptr(),
                    2,
                ));
                statuses.push(ffi3::set::<Toy, ffi3::Int32>(
                    c,
                    k.as_ptr(),
                    1,
                    [3].as_ptr(),
                    1,
                ));
                statuses.push(ffi3::set::<Toy, ffi3::Boolean>(
                    c,
                    b.as_ptr(),
                    1,
                    [fmi3True].as_ptr(),
                    1,
                ));
                statuses.push(ffi3::set::<Toy, ffi3::Float64>(
                    c,
                    gain.as_ptr(),
                    1,
                    [2.0].as_ptr(),
                    1,
                ));
                statuses.push(ffi3::do_step::<Toy>(
                    c,
                    t,
                    H,
                    &mut event,
                    &mut terminate,
                    &mut early,
                    &mut last,
                ));
                statuses.push(ffi3::get::<Toy, ffi3::Float64>(
                    c,
                    reals.as_ptr(),
                    3,
                    y.as_mut_ptr(),
                    4,
                ));
                statuses.push(ffi3::get::<Toy, ffi3::Int32>(
                    c,
                    n.as_ptr(),
                    1,
                    steps.as_mut_ptr(),
                    1,
                ));
                statuses.push(ffi3::get::<Toy, ffi3::Boolean>(
                    c,
                    on.as_ptr(),
                    1,
                    positive.as_mut_ptr(),
                    1,
                ));
            }
        }
    });
    unsafe { ffi3::free_instance::<Toy>(c) };
    assert!(statuses.iter().all(|s| *s == fmi3OK), "{statuses:?}");
    let integral = STEPS as f64 * H;
    assert!((y[0] - STEPS as f64 * H).abs() < 1e-12, "time {y:?}");
    assert!((y[1] - 2.0 * integral).abs() < 1e-12, "{y:?}");
    assert!((y[2] + 4.0 * integral).abs() < 1e-12, "{y:?}");
    assert_eq!(y[3], 4.0);
    assert_eq!((steps[0], positive[0]), (STEPS as i32, fmi3True));
    assert_eq!(
        allocations, 0,
        "allocations and frees in {STEPS} FMI 3.0 steps"
    );
}
