//! Model Exchange event indicators are computed when they are read, not at every evaluation:
//! a model with one state and twelve indicators (`z_k = x − k`, more than any fixed-size
//! buffer of the layer) that counts its calls, driven through the FMI 2.0 C entry points
//! (in-process harness) under a counting global allocator. An integration loop that reads
//! derivatives alone makes one model call per evaluation; `fmi2GetEventIndicators` and a
//! getter of an indicator's variable see indicators consistent with the states last set;
//! neither allocates; a restored FMU state and a non-finite indicator behave as before.
#![allow(unsafe_code)]

use spurio_export::harness::Harness;
use spurio_export::instance::functions;
use spurio_export::me::ffi::{self as me, Array};
use spurio_export::types::*;
use spurio_export::{
    ByteReader, ByteWriter, Cause, Config, Context, EventUpdate, Failure, FmuModel, ModelExchange,
    ModelInfo, Variable,
};
use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;

/// Counts the allocations and frees of the thread while `COUNTING` is set.
struct Counter;

thread_local! {
    static COUNTING: Cell<bool> = const { Cell::new(false) };
    static ALLOCATIONS: Cell<usize> = const { Cell::new(0) };
    /// The model's `evaluate` and `event_indicators` calls on this thread.
    static CALLS: Cell<(usize, usize)> = const { Cell::new((0, 0)) };
}

fn note() {
    let _ = COUNTING.try_with(|on| {
        if on.get() {
            let _ = ALLOCATIONS.try_with(|n| n.set(n.get() + 1));
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
fn allocations(f: impl FnOnce()) -> usize {
    ALLOCATIONS.with(|n| n.set(0));
    COUNTING.with(|on| on.set(true));
    f();
    COUNTING.with(|on| on.set(false));
    ALLOCATIONS.with(|n| n.get())
}

/// The model calls (evaluations, indicator computations) since the last look.
fn calls() -> (usize, usize) {
    CALLS.with(|c| c.replace((0, 0)))
}

const N: usize = 12;
const X: usize = 0;
const DER_X: usize = 1;
const U: usize = 2;
const Z0: usize = 3;

/// `der(x) = u`, `z_k = x − k` for k = 0…11; `x = 7.5` makes `z_7` NaN.
#[derive(Clone, Debug, Default)]
struct Ramp;

impl FmuModel for Ramp {
    fn describe(_config: &Config) -> Result<ModelInfo, Cause> {
        let mut vars = vec![
            Variable::output("x").state().depends_on(&[X]),
            Variable::derivative("der(x)", X).depends_on(&[U]),
            Variable::input("u", 1.0),
        ];
        vars.extend((0..N).map(|k| Variable::event_indicator(&format!("z{k}"))));
        Ok(ModelInfo::new("Ramp", "ramp", vars, None, Config::new()).with_model_exchange()?)
    }
    fn create(_info: &ModelInfo) -> Result<Self, Cause> {
        Ok(Self)
    }
    fn initialize(&mut self, _ctx: &mut Context) -> Result<(), Failure> {
        Ok(())
    }
    fn do_step(&mut self, _ctx: &mut Context, _time: f64, _step: f64) -> Result<(), Failure> {
        Ok(())
    }
    fn save_state(&self, _out: &mut ByteWriter) {}
    fn load_state(&mut self, _input: &mut ByteReader) -> Result<(), Cause> {
        Ok(())
    }
}

impl ModelExchange for Ramp {
    fn evaluate(&mut self, ctx: &mut Context) -> Result<(), Failure> {
        CALLS.with(|c| c.set((c.get().0 + 1, c.get().1)));
        ctx.values.set_real(DER_X, ctx.values.real(U));
        Ok(())
    }
    fn event_indicators(&mut self, ctx: &mut Context, z: &mut [f64]) -> Result<(), Failure> {
        CALLS.with(|c| c.set((c.get().0, c.get().1 + 1)));
        let x = ctx.values.real(X);
        for (k, z) in z.iter_mut().enumerate() {
            *z = if x == 7.5 && k == 7 {
                f64::NAN
            } else {
                x - k as f64
            };
        }
        Ok(())
    }
    fn update_discrete_states(&mut self, _ctx: &mut Context) -> Result<EventUpdate, Failure> {
        Ok(EventUpdate::default())
    }
    type Jacobian = ();
    fn jacobian(&mut self, _ctx: &Context) -> Result<(), Failure> {
        Ok(())
    }
    fn partial(&self, _: &(), _unknown: usize, _known: usize) -> Result<f64, Failure> {
        Ok(0.0)
    }
}

struct Me(Harness<Ramp>);

impl Me {
    /// An instance in Continuous-Time Mode, the call counts reset.
    fn new() -> Self {
        let hooks = spurio_export::me::hooks::<Ramp>();
        let mut h = Harness::model_exchange(&Config::new(), hooks).unwrap();
        h.initialize(0.0).unwrap();
        let f = &functions::ENTER_CONTINUOUS_TIME_MODE;
        assert_eq!(
            unsafe { me::enter_mode::<Ramp, ()>(h.component(), f, false) },
            fmi2OK
        );
        calls();
        Self(h)
    }
    fn set(&self, t: f64, x: f64) {
        let c = self.0.component();
        let f = &functions::SET_TIME;
        assert_eq!(unsafe { me::set_time::<Ramp, ()>(c, f, t) }, fmi2OK);
        let f = &functions::SET_CONTINUOUS_STATES;
        let s = unsafe { me::set_continuous_states::<Ramp, ()>(c, f, &x, 1) };
        assert_eq!(s, fmi2OK);
    }
    fn derivative(&self) -> f64 {
        let mut out = f64::NAN;
        let (f, which) = (&functions::GET_DERIVATIVES, Array::Derivatives);
        let s = unsafe { me::get_array::<Ramp, ()>(self.0.component(), f, which, &mut out, 1) };
        assert_eq!(s, fmi2OK);
        out
    }
    fn indicators(&self, out: &mut [f64; N]) -> fmi2Status {
        let (f, which) = (&functions::GET_EVENT_INDICATORS, Array::EventIndicators);
        let c = self.0.component();
        unsafe { me::get_array::<Ramp, ()>(c, f, which, out.as_mut_ptr(), N) }
    }
}

fn expected(x: f64) -> [f64; N] {
    std::array::from_fn(|k| x - k as f64)
}

#[test]
fn an_integration_loop_reading_derivatives_makes_one_model_call_an_evaluation() {
    let m = Me::new();
    for k in 0..1000 {
        m.set(k as f64 * 1e-3, k as f64);
        assert_eq!(m.derivative(), 1.0);
    }
    assert_eq!(calls(), (1000, 0));
    // the indicators, when asked for: computed once for the states last set
    let mut z = [f64::NAN; N];
    assert_eq!(m.indicators(&mut z), fmi2OK);
    assert_eq!(z, expected(999.0));
    assert_eq!(m.indicators(&mut z), fmi2OK);
    assert_eq!(calls(), (0, 1));
    // a new state: evaluated and computed again when read
    m.set(1.0, 3.0);
    assert_eq!(m.indicators(&mut z), fmi2OK);
    assert_eq!(z, expected(3.0));
    assert_eq!(calls(), (1, 1));
}

#[test]
fn a_getter_of_an_indicator_variable_computes_them_and_one_of_other_variables_does_not() {
    let mut m = Me::new();
    m.set(0.0, 4.0);
    assert_eq!(m.0.real(DER_X as u32), Ok(1.0));
    assert_eq!(m.0.real(X as u32), Ok(4.0));
    assert_eq!(calls(), (1, 0));
    assert_eq!(m.0.real((Z0 + 3) as u32), Ok(1.0));
    assert_eq!(m.0.real((Z0 + 11) as u32), Ok(-7.0));
    assert_eq!(calls(), (0, 1));
    // an input changes the derivative; the indicators are stale until read
    m.0.set_real(&[U as u32], &[2.0]).unwrap();
    assert_eq!(m.derivative(), 2.0);
    m.set(0.5, 5.0);
    let mut out = [0.0; 3];
    m.0.get_real(&[X as u32, (Z0 + 1) as u32, DER_X as u32], &mut out)
        .unwrap();
    assert_eq!(out, [5.0, 4.0, 2.0]);
    assert_eq!(calls(), (2, 1));
}

#[test]
fn evaluations_and_indicators_allocate_nothing_at_twelve_indicators() {
    let mut m = Me::new();
    let mut z = [0.0; N];
    m.set(0.0, 1.0);
    assert_eq!(m.indicators(&mut z), fmi2OK);
    let n = allocations(|| {
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

#[test]
fn a_restored_state_reads_its_own_indicators() {
    let mut m = Me::new();
    m.set(0.0, 2.0);
    assert_eq!(m.derivative(), 1.0);
    // saved with the indicators stale (never read at x = 2)
    let saved = m.0.serialized_state().unwrap();
    m.set(0.1, 9.0);
    let mut z = [0.0; N];
    assert_eq!(m.indicators(&mut z), fmi2OK);
    assert_eq!(z, expected(9.0));
    assert_eq!(m.0.restore_state(&saved), Ok(Status::Ok));
    assert_eq!(m.indicators(&mut z), fmi2OK);
    assert_eq!(z, expected(2.0));
    assert_eq!(m.0.real((Z0 + 1) as u32), Ok(1.0));
}

#[test]
fn a_non_finite_indicator_is_an_error_naming_it_when_read() {
    let m = Me::new();
    m.set(0.0, 7.5);
    // the derivatives do not need the indicators
    assert_eq!(m.derivative(), 1.0);
    let mut z = [-1.0; N];
    assert_eq!(m.indicators(&mut z), fmi2Error);
    assert_eq!(z, [-1.0; N], "nothing published");
    assert!(m.0.logged(&[
        "fmi2GetEventIndicators",
        "event indicator 8 came out as NaN: not published"
    ]));
    // the instance is in state Error
    let f = &functions::SET_TIME;
    assert_eq!(
        unsafe { me::set_time::<Ramp, ()>(m.0.component(), f, 1.0) },
        fmi2Error
    );
}
