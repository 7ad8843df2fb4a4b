//! A Model Exchange model with one state and twelve event indicators (`z_k = x − k`, more
//! than any fixed-size buffer of the layer) that counts its calls: what the lazy event
//! indicators are checked with (`lazy_indicators.rs`: call counts; `allocations.rs`: no
//! allocation). Included by `#[path]` where needed.
#![allow(dead_code)]

use spurio_export::abi::model_exchange::{self as me, Array};
use spurio_export::fmi2::functions;
use spurio_export::harness::Harness;
use spurio_export::types::*;
use spurio_export::{
    ByteReader, ByteWriter, Cause, Config, Context, EventUpdate, Failure, FmuModel, ModelExchange,
    ModelInfo, Variable,
};
use std::cell::Cell;

thread_local! {
    /// The model's `evaluate` and `event_indicators` calls on this thread.
    static CALLS: Cell<(usize, usize)> = const { Cell::new((0, 0)) };
}

/// The model calls (evaluations, indicator computations) since the last look.
pub fn calls() -> (usize, usize) {
    CALLS.with(|c| c.replace((0, 0)))
}

pub const N: usize = 12;
pub const X: usize = 0;
pub const DER_X: usize = 1;
pub const U: usize = 2;
pub const Z0: usize = 3;

/// `der(x) = u`, `z_k = x − k` for k = 0…11; `x = 7.5` makes `z_7` NaN.
#[derive(Clone, Debug, Default)]
pub struct Ramp;

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

pub struct Me(pub Harness<Ramp>);

impl Me {
    /// An instance in Continuous-Time Mode, the call counts reset.
    pub fn new() -> Self {
        let hooks = spurio_export::model::hooks::<Ramp>();
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
    pub fn set(&self, t: f64, x: f64) {
        let c = self.0.component();
        let f = &functions::SET_TIME;
        assert_eq!(unsafe { me::set_time::<Ramp, ()>(c, f, t) }, fmi2OK);
        let f = &functions::SET_CONTINUOUS_STATES;
        let s = unsafe { me::set_continuous_states::<Ramp, ()>(c, f, &x, 1) };
        assert_eq!(s, fmi2OK);
    }
    pub fn derivative(&self) -> f64 {
        let mut out = f64::NAN;
        let (f, which) = (&functions::GET_DERIVATIVES, Array::Derivatives);
        let s = unsafe { me::get_array::<Ramp, ()>(self.0.component(), f, which, &mut out, 1) };
        assert_eq!(s, fmi2OK);
        out
    }
    pub fn indicators(&self, out: &mut [f64; N]) -> fmi2Status {
        let (f, which) = (&functions::GET_EVENT_INDICATORS, Array::EventIndicators);
        let c = self.0.component();
        unsafe { me::get_array::<Ramp, ()>(c, f, which, out.as_mut_ptr(), N) }
    }
}

/// The indicators at `x`.
pub fn expected(x: f64) -> [f64; N] {
    std::array::from_fn(|k| x - k as f64)
}
