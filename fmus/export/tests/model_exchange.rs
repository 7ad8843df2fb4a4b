//! The FMI 2.0 Model Exchange front driven through its C entry points (in-process harness)
//! with the shared toy model ([`common::toy`]): the state machine's masks, states,
//! derivatives and nominals, event indicators and event iteration, directional derivatives
//! (Model Exchange and Co-Simulation), FMU states, non-finite values, panics and misuse.
#![allow(unsafe_code)]

mod common;

use common::toy::{Toy, DER_Y, TO_WRAP, U, Y, Y0, Y_MAX, Z};
use spurio_export::abi::model_exchange::{self as me, Array};
use spurio_export::fmi2::functions;
use spurio_export::fmi2::model_exchange::{self as me2, fmi2EventInfo};
use spurio_export::harness::Harness;
use spurio_export::instance::Function;
use spurio_export::types::*;
use spurio_export::{Config, FmuModel};

fn hooks() -> spurio_export::model::Hooks<Toy> {
    spurio_export::model::hooks::<Toy>()
}

fn last_error<M: FmuModel>(h: &Harness<M>) -> String {
    h.log()
        .into_iter()
        .rev()
        .find(|(s, _, _)| *s >= Status::Error)
        .map(|(_, _, t)| t)
        .unwrap_or_default()
}

/// A Model Exchange instance of the toy and the calls the harness does not wrap.
struct Me(Harness<Toy>);

impl Me {
    fn new() -> Self {
        Self(Harness::model_exchange(&Config::new(), hooks()).unwrap())
    }
    fn c(&self) -> fmi2Component {
        self.0.component()
    }
    fn set_time(&self, t: f64) -> fmi2Status {
        unsafe { me::set_time::<Toy, ()>(self.c(), &functions::SET_TIME, t) }
    }
    fn set_states(&self, x: &[f64]) -> fmi2Status {
        unsafe {
            let f = &functions::SET_CONTINUOUS_STATES;
            me::set_continuous_states::<Toy, ()>(self.c(), f, x.as_ptr(), x.len())
        }
    }
    fn states(&self, n: usize) -> Result<Vec<f64>, fmi2Status> {
        self.array(
            n,
            &functions::GET_CONTINUOUS_STATES,
            Array::ContinuousStates,
        )
    }
    fn derivatives(&self, n: usize) -> Result<Vec<f64>, fmi2Status> {
        self.array(n, &functions::GET_DERIVATIVES, Array::Derivatives)
    }
    fn indicators(&self, n: usize) -> Result<Vec<f64>, fmi2Status> {
        self.array(n, &functions::GET_EVENT_INDICATORS, Array::EventIndicators)
    }
    fn nominals(&self, n: usize) -> Result<Vec<f64>, fmi2Status> {
        self.array(
            n,
            &functions::GET_NOMINALS_OF_CONTINUOUS_STATES,
            Array::Nominals,
        )
    }
    fn array(&self, n: usize, f: &Function, which: Array) -> Result<Vec<f64>, fmi2Status> {
        let mut out = vec![f64::NAN; n];
        let s = unsafe { me::get_array::<Toy, ()>(self.c(), f, which, out.as_mut_ptr(), n) };
        if s == fmi2OK {
            Ok(out)
        } else {
            Err(s)
        }
    }
    fn enter_event_mode(&self) -> fmi2Status {
        unsafe { me::enter_mode::<Toy, ()>(self.c(), &functions::ENTER_EVENT_MODE, true) }
    }
    fn enter_continuous_time_mode(&self) -> fmi2Status {
        unsafe {
            let f = &functions::ENTER_CONTINUOUS_TIME_MODE;
            me::enter_mode::<Toy, ()>(self.c(), f, false)
        }
    }
    fn new_discrete_states(&self) -> Result<fmi2EventInfo, fmi2Status> {
        let mut info = fmi2EventInfo {
            newDiscreteStatesNeeded: 7,
            ..Default::default()
        };
        let s = unsafe { me2::new_discrete_states::<Toy>(self.c(), &mut info) };
        if s == fmi2OK {
            Ok(info)
        } else {
            Err(s)
        }
    }
    fn completed_integrator_step(&self) -> (fmi2Status, fmi2Boolean, fmi2Boolean) {
        let (mut event, mut terminate) = (7, 7);
        let s = unsafe {
            {
                let f = &functions::COMPLETED_INTEGRATOR_STEP;
                me::completed_integrator_step::<Toy, (), _>(self.c(), f, &mut event, &mut terminate)
            }
        };
        (s, event, terminate)
    }
    /// Initialization, the first event iteration, then Continuous-Time Mode.
    fn start(&mut self) {
        self.0.initialize(0.0).unwrap();
        let info = self.new_discrete_states().unwrap();
        assert_eq!(info.newDiscreteStatesNeeded, fmi2False);
        assert_eq!(self.enter_continuous_time_mode(), fmi2OK);
    }
}

fn directional(
    c: fmi2Component,
    unknowns: &[usize],
    knowns: &[usize],
    seed: &[f64],
) -> Result<Vec<f64>, fmi2Status> {
    directional_of::<Toy>(c, unknowns, knowns, seed)
}

/// `fmi2GetDirectionalDerivative` of an instance of `M`.
fn directional_of<M: FmuModel>(
    c: fmi2Component,
    unknowns: &[usize],
    knowns: &[usize],
    seed: &[f64],
) -> Result<Vec<f64>, fmi2Status> {
    let u: Vec<u32> = unknowns.iter().map(|&i| i as u32).collect();
    let k: Vec<u32> = knowns.iter().map(|&i| i as u32).collect();
    let mut out = vec![f64::NAN; u.len()];
    let s = unsafe {
        let (u, k) = ((u.as_ptr(), u.len()), (k.as_ptr(), k.len()));
        me2::get_directional_derivative::<M>(c, u, k, seed.as_ptr(), out.as_mut_ptr())
    };
    if s == fmi2OK {
        Ok(out)
    } else {
        Err(s)
    }
}

#[test]
fn the_state_machine_follows_the_model_exchange_masks() {
    let mut m = Me::new();
    // Instantiated: no time, states or event mode yet
    assert_eq!(m.set_time(0.5), fmi2Error);
    assert!(last_error(&m.0).contains("fmi2SetTime: illegal call sequence: not allowed in state Instantiated (allowed in: EventMode, ContinuousTimeMode)"));
    assert_eq!(m.enter_event_mode(), fmi2Error);
    // nominals are known from instantiation on
    assert_eq!(m.nominals(2).unwrap(), [2.0, 2.0]);
    m.0.set_real(&[Y0 as u32], &[1.5]).unwrap();
    m.0.setup_experiment(0.0, None).unwrap();
    m.0.enter_initialization_mode().unwrap();
    // derivatives and states in Initialization Mode, from the initial values
    m.0.set_real(&[U as u32], &[2.0]).unwrap();
    assert_eq!(m.derivatives(2).unwrap(), [2.0, 0.0]);
    assert_eq!(m.states(2).unwrap(), [1.5, 0.0]);
    assert_eq!(m.set_states(&[1.0, 1.0]), fmi2Error);
    m.0.exit_initialization_mode().unwrap();
    // Event Mode: no states set, no integrator step, no Co-Simulation step
    assert_eq!(m.set_states(&[1.0, 1.0]), fmi2Error);
    assert!(last_error(&m.0).contains("not allowed in state EventMode"));
    assert_eq!(m.completed_integrator_step().0, fmi2Error);
    assert_eq!(m.0.do_step(0.0, 0.1), Err(Status::Error));
    assert!(last_error(&m.0).contains("fmi2DoStep: illegal call sequence"));
    assert!(m.new_discrete_states().is_ok());
    assert_eq!(m.enter_continuous_time_mode(), fmi2OK);
    // Continuous-Time Mode
    assert_eq!(m.enter_continuous_time_mode(), fmi2Error);
    assert_eq!(m.new_discrete_states().unwrap_err(), fmi2Error);
    assert_eq!(m.set_time(0.25), fmi2OK);
    assert_eq!(m.set_states(&[0.5, -0.5]), fmi2OK);
    assert_eq!(
        m.completed_integrator_step(),
        (fmi2OK, fmi2False, fmi2False)
    );
    // a fixed parameter cannot be set any more, an input can
    assert_eq!(m.0.set_real(&[Y0 as u32], &[1.0]), Err(Status::Error));
    assert_eq!(m.0.set_real(&[U as u32], &[-1.0]), Ok(Status::Ok));
    assert_eq!(m.derivatives(2).unwrap(), [-1.0, 0.0]);
    // the tunable y_max only in Event Mode
    assert_eq!(m.0.set_real(&[Y_MAX as u32], &[5.0]), Err(Status::Error));
    assert_eq!(m.enter_event_mode(), fmi2OK);
    assert_eq!(m.0.set_real(&[Y_MAX as u32], &[5.0]), Ok(Status::Ok));
    assert_eq!(m.indicators(1).unwrap(), [4.5]);
    // terminate from Event Mode; the results stay readable
    assert_eq!(
        unsafe { spurio_export::fmi2::ffi::terminate::<Toy>(m.c()) },
        fmi2OK
    );
    assert_eq!(m.states(2).unwrap(), [0.5, -0.5]);
    assert_eq!(m.set_time(1.0), fmi2Error);
    // reset leads back to Instantiated, still Model Exchange
    m.0.reset().unwrap();
    m.start();
    assert_eq!(m.states(2).unwrap(), [0.0, 0.0]);
}

#[test]
fn states_inputs_and_time_determine_the_derivatives_and_outputs() {
    let mut m = Me::new();
    m.start();
    assert_eq!(m.set_states(&[0.5, 3.0]), fmi2OK);
    m.0.set_real(&[U as u32, U as u32 + 1], &[2.0, -1.0])
        .unwrap();
    assert_eq!(m.derivatives(2).unwrap(), [2.0, -1.0]);
    let mut v = [0.0; 4];
    m.0.get_real(
        &[Y as u32, Y as u32 + 1, Z as u32, DER_Y as u32 + 1],
        &mut v,
    )
    .unwrap();
    assert_eq!(v, [0.5, 3.0, 1.0, -1.0]);
    // the event indicator is written into its variable too
    assert_eq!(m.indicators(1).unwrap(), [1e6 - 0.5]);
    assert_eq!(m.0.real(TO_WRAP as u32).unwrap(), 1e6 - 0.5);
    // counts, NULL and non-finite states are rejected and change nothing
    assert_eq!(m.derivatives(3).unwrap_err(), fmi2Error);
    assert!(last_error(&m.0).contains("fmi2GetDerivatives: nx = 3, but Toy has 2"));
    assert_eq!(m.indicators(2).unwrap_err(), fmi2Error);
    assert!(last_error(&m.0).contains("fmi2GetEventIndicators: ni = 2, but Toy has 1"));
    assert_eq!(m.set_states(&[1.0, f64::NAN]), fmi2Error);
    assert!(last_error(&m.0).contains("state `y[2]`: NaN rejected"));
    let f = &functions::SET_CONTINUOUS_STATES;
    let s = unsafe { me::set_continuous_states::<Toy, ()>(m.c(), f, std::ptr::null(), 2) };
    assert_eq!(s, fmi2Error);
    let (f, which) = (&functions::GET_DERIVATIVES, Array::Derivatives);
    let s = unsafe { me::get_array::<Toy, ()>(m.c(), f, which, std::ptr::null_mut(), 2) };
    assert_eq!(s, fmi2Error);
    assert_eq!(m.set_time(f64::INFINITY), fmi2Error);
    assert_eq!(m.states(2).unwrap(), [0.5, 3.0]);
}

#[test]
fn a_state_event_is_handled_in_event_mode() {
    let mut m = Me::new();
    m.0.set_real(&[Y_MAX as u32], &[1.0]).unwrap();
    m.start();
    m.0.set_real(&[U as u32], &[1.0]).unwrap();
    // the solver integrates past y_max: the indicator changes sign
    assert_eq!(m.set_time(0.9), fmi2OK);
    assert_eq!(m.set_states(&[0.9, 0.0]), fmi2OK);
    assert!((m.indicators(1).unwrap()[0] - 0.1).abs() < 1e-15);
    assert_eq!(m.set_time(1.0), fmi2OK);
    assert_eq!(m.set_states(&[1.0, 0.0]), fmi2OK);
    assert_eq!(m.indicators(1).unwrap(), [0.0]);
    assert_eq!(m.enter_event_mode(), fmi2OK);
    let info = m.new_discrete_states().unwrap();
    assert_eq!(info.valuesOfContinuousStatesChanged, fmi2True);
    assert_eq!(info.newDiscreteStatesNeeded, fmi2False);
    assert_eq!(info.terminateSimulation, fmi2False);
    assert_eq!(info.nextEventTimeDefined, fmi2False);
    assert_eq!(m.states(2).unwrap(), [0.0, 0.0]);
    assert_eq!(m.indicators(1).unwrap(), [1.0]);
    // a second iteration changes nothing
    let info = m.new_discrete_states().unwrap();
    assert_eq!(info.valuesOfContinuousStatesChanged, fmi2False);
    assert!(m.0.logged(&["y[1] wrapped to 0 at t = 1"]));
    let s = unsafe { me2::new_discrete_states::<Toy>(m.c(), std::ptr::null_mut()) };
    assert_eq!(s, fmi2Error);
}

#[test]
fn directional_derivatives_are_exact_and_checked() {
    let mut m = Me::new();
    m.start();
    assert_eq!(m.set_states(&[0.3, -0.7]), fmi2OK);
    let unknowns = [DER_Y, DER_Y + 1, Z, Y];
    let knowns = [Y, Y + 1, U, U + 1];
    let seed = [1.0, 2.0, 3.0, 4.0];
    assert_eq!(
        directional(m.c(), &unknowns, &knowns, &seed).unwrap(),
        [3.0, 4.0, 7.0, 1.0]
    );
    // the Jacobian column by column equals the seeded product
    let mut product = [0.0; 4];
    for (j, s) in seed.iter().enumerate() {
        let column = directional(m.c(), &unknowns, &knowns[j..=j], &[1.0]).unwrap();
        for (p, c) in product.iter_mut().zip(column) {
            *p += c * s;
        }
    }
    assert_eq!(product, [3.0, 4.0, 7.0, 1.0]);
    // an input is no unknown, a derivative no known, 99 no variable, NaN no seed
    assert_eq!(directional(m.c(), &[U], &[Y], &[1.0]), Err(fmi2Error));
    assert!(
        last_error(&m.0).contains("`u[1]`: an unknown must be a Real output or state derivative")
    );
    assert_eq!(directional(m.c(), &[Z], &[DER_Y], &[1.0]), Err(fmi2Error));
    assert!(
        last_error(&m.0).contains("`der(y)[1]`: a known must be a Real input or continuous state")
    );
    assert_eq!(directional(m.c(), &[99], &[U], &[1.0]), Err(fmi2Error));
    assert!(last_error(&m.0).contains("unknown value reference 99"));
    assert_eq!(directional(m.c(), &[Z], &[U], &[f64::NAN]), Err(fmi2Error));
    // a Co-Simulation instance without the model's functions has none
    let mut cs = Harness::<Toy>::new(&Config::new()).unwrap();
    let c = cs.component();
    assert_eq!(
        directional(c, &[Z], &[U, U + 1], &[1.0, 1.0]),
        Err(fmi2Error)
    );
    assert!(last_error(&cs).contains("illegal call sequence"));
    cs.initialize(0.0).unwrap();
    assert_eq!(
        directional(c, &[Z], &[U, U + 1], &[1.0, 1.0]),
        Err(fmi2Error)
    );
    let e = last_error(&cs);
    assert!(e.contains("providesDirectionalDerivative=\"false\""), "{e}");
}

#[test]
fn a_co_simulation_instance_with_the_functions_offers_directional_derivatives_only() {
    // as export_fmu!(Toy, model_exchange) instantiates for fmi2CoSimulation
    let info = Toy::describe(&Config::new()).unwrap();
    // no logger, no memory functions, no environment: all NULL
    let callbacks: fmi2CallbackFunctions = unsafe { std::mem::zeroed() };
    let name = c"cs";
    let guid = std::ffi::CString::new(info.guid).unwrap();
    let instantiate = |kind, hooks| unsafe {
        spurio_export::fmi2::ffi::instantiate::<Toy>(
            name.as_ptr(),
            kind,
            guid.as_ptr(),
            std::ptr::null(),
            &callbacks,
            fmi2False,
            fmi2False,
            hooks,
        )
    };
    // without the functions, Model Exchange is refused; an unknown type always
    assert!(instantiate(fmi2ModelExchange, None).is_null());
    assert!(instantiate(7, Some(hooks())).is_null());
    let me = instantiate(fmi2ModelExchange, Some(hooks()));
    assert!(!me.is_null());
    unsafe { spurio_export::fmi2::ffi::free_instance::<Toy>(me) };
    let c = instantiate(fmi2CoSimulation, Some(hooks()));
    assert!(!c.is_null());
    unsafe {
        assert_eq!(
            spurio_export::fmi2::ffi::setup_experiment::<Toy>(c, 0, 0.0, 0.0, 0, 0.0),
            fmi2OK
        );
        assert_eq!(
            spurio_export::fmi2::ffi::enter_initialization_mode::<Toy>(c),
            fmi2OK
        );
        assert_eq!(
            spurio_export::fmi2::ffi::exit_initialization_mode::<Toy>(c),
            fmi2OK
        );
        let u = [2.0, 0.0];
        let vr = [U as u32, U as u32 + 1];
        assert_eq!(
            spurio_export::fmi2::values::set::<Toy, spurio_export::fmi2::values::Real>(
                c,
                vr.as_ptr(),
                2,
                u.as_ptr()
            ),
            fmi2OK
        );
        assert_eq!(
            spurio_export::fmi2::ffi::do_step::<Toy>(c, 0.0, 0.5, fmi2True),
            fmi2OK
        );
        assert_eq!(
            directional(c, &[Y, Z], &[Y, U], &[1.0, 10.0]).unwrap(),
            [1.0, 10.0]
        );
        // but not the Model Exchange functions
        assert_eq!(
            me::set_time::<Toy, ()>(c, &functions::SET_TIME, 1.0),
            fmi2Error
        );
        let mut x = [0.0; 2];
        let (f, which) = (&functions::GET_CONTINUOUS_STATES, Array::ContinuousStates);
        assert_eq!(
            me::get_array::<Toy, ()>(c, f, which, x.as_mut_ptr(), 2),
            fmi2Error
        );
        spurio_export::fmi2::ffi::free_instance::<Toy>(c);
    }
}

#[test]
fn fmu_states_carry_the_continuous_states() {
    let mut m = Me::new();
    m.start();
    assert_eq!(m.set_time(0.5), fmi2OK);
    assert_eq!(m.set_states(&[0.25, 0.75]), fmi2OK);
    let saved = m.0.serialized_state().unwrap();
    assert_eq!(m.set_time(0.6), fmi2OK);
    assert_eq!(m.set_states(&[9.0, 9.0]), fmi2OK);
    m.0.restore_state(&saved).unwrap();
    assert_eq!(m.states(2).unwrap(), [0.25, 0.75]);
    // still in Continuous-Time Mode
    assert_eq!(m.set_states(&[0.5, 0.5]), fmi2OK);
    assert_eq!(m.completed_integrator_step().0, fmi2OK);
    // a Model Exchange state does not fit a Co-Simulation instance
    let mut cs = Harness::<Toy>::new(&Config::new()).unwrap();
    assert_eq!(cs.restore_state(&saved), Err(Status::Error));
    assert!(
        last_error(&cs).contains("state machine state 11"),
        "{}",
        last_error(&cs)
    );
}

#[test]
fn non_finite_results_and_panics_are_errors() {
    let mut m = Me::new();
    m.start();
    // z = u[1] + u[2] overflows: not published, the instance is in Error
    m.0.set_real(&[U as u32, U as u32 + 1], &[1e308, 1e308])
        .unwrap();
    assert_eq!(m.derivatives(2).unwrap_err(), fmi2Error);
    let e = last_error(&m.0);
    assert!(
        e.contains(
            "fmi2GetDerivatives: variable `z` (value reference 4) came out as inf: not published"
        ),
        "{e}"
    );
    assert_eq!(m.set_time(1.0), fmi2Error);
    m.0.reset().unwrap();
    m.start();
    m.0.set_real(&[U as u32], &[13.0]).unwrap();
    assert_eq!(m.derivatives(2).unwrap_err(), fmi2Fatal);
    assert!(m
        .0
        .logged(&["fmi2GetDerivatives: internal error: unlucky input"]));
    assert_eq!(m.set_time(1.0), fmi2Error);
}

/// Run by [`a_panic_in_an_evaluation_prints_nothing_on_stderr`] in a child process.
#[test]
fn panicking_evaluation_child() {
    if std::env::var_os("SPURIO_PANIC_CHILD").is_none() {
        return;
    }
    let mut m = Me::new();
    m.start();
    m.0.set_real(&[U as u32], &[13.0]).unwrap();
    assert_eq!(m.indicators(1).unwrap_err(), fmi2Fatal);
    assert!(m
        .0
        .logged(&["fmi2GetEventIndicators: internal error: unlucky input (at "]));
    eprintln!("child done");
}

#[test]
fn a_panic_in_an_evaluation_prints_nothing_on_stderr() {
    common::assert_child_prints_only_its_line("panicking_evaluation_child");
}

#[test]
fn a_count_other_than_the_models_is_refused_before_the_array_becomes_a_slice() {
    let mut m = Me::new();
    m.start();
    assert_eq!(m.set_states(&[0.5, 3.0]), fmi2OK);
    // a huge count with a two-element array: refused from the count alone, the array untouched
    // (a slice of that length would exceed isize::MAX bytes: undefined behaviour to form)
    let huge = usize::MAX / 4;
    let mut out = [f64::NAN; 2];
    let arrays = [
        (
            &functions::GET_CONTINUOUS_STATES,
            Array::ContinuousStates,
            "fmi2GetContinuousStates: nx",
            2,
        ),
        (
            &functions::GET_DERIVATIVES,
            Array::Derivatives,
            "fmi2GetDerivatives: nx",
            2,
        ),
        (
            &functions::GET_EVENT_INDICATORS,
            Array::EventIndicators,
            "fmi2GetEventIndicators: ni",
            1,
        ),
        (
            &functions::GET_NOMINALS_OF_CONTINUOUS_STATES,
            Array::Nominals,
            "fmi2GetNominalsOfContinuousStates: nx",
            2,
        ),
    ];
    for (f, which, what, has) in arrays {
        let s = unsafe { me::get_array::<Toy, ()>(m.c(), f, which, out.as_mut_ptr(), huge) };
        assert_eq!(s, fmi2Error);
        assert!(last_error(&m.0).contains(&format!("{what} = {huge}, but Toy has {has}")));
    }
    assert!(out.iter().all(|x| x.is_nan()));
    let f = &functions::SET_CONTINUOUS_STATES;
    let x = [1.0, 2.0];
    let s = unsafe { me::set_continuous_states::<Toy, ()>(m.c(), f, x.as_ptr(), huge) };
    assert_eq!(s, fmi2Error);
    assert!(last_error(&m.0).contains(&format!(
        "fmi2SetContinuousStates: nx = {huge}, but Toy has 2"
    )));
    assert_eq!(m.states(2).unwrap(), [0.5, 3.0]);
}

/// A decay `der(x) = −k·x + d` with a tunable rate `k` and a discrete input `d`: what a
/// master may set in Event Mode and in Continuous-Time Mode, and what the derivatives then
/// read.
#[derive(Clone, Debug, Default)]
struct Decay;

const K: usize = 0;
const X: usize = 1;
const DER_X: usize = 2;
const D: usize = 3;

impl FmuModel for Decay {
    fn describe(_config: &Config) -> Result<spurio_export::ModelInfo, spurio_export::Cause> {
        let mut d = spurio_export::Variable::input("d", 0.0);
        d.variability = spurio_export::Variability::Discrete;
        let vars = vec![
            spurio_export::Variable::parameter("k", 1.0).tunable(),
            spurio_export::Variable::output("x")
                .state()
                .depends_on(&[X]),
            spurio_export::Variable::derivative("der(x)", X).depends_on(&[X, D]),
            d,
        ];
        Ok(
            spurio_export::ModelInfo::new("Decay", "decay", vars, None, Config::new())
                .with_model_exchange()?,
        )
    }
    fn create(_info: &spurio_export::ModelInfo) -> Result<Self, spurio_export::Cause> {
        Ok(Self)
    }
    fn initialize(
        &mut self,
        ctx: &mut spurio_export::Context,
    ) -> Result<(), spurio_export::Failure> {
        ctx.values.set_real(X, 2.0);
        Ok(())
    }
    fn do_step(
        &mut self,
        _ctx: &mut spurio_export::Context,
        _time: f64,
        _step: f64,
    ) -> Result<(), spurio_export::Failure> {
        Ok(())
    }
    fn save_state(&self, _out: &mut spurio_export::ByteWriter) {}
    fn load_state(
        &mut self,
        _input: &mut spurio_export::ByteReader,
    ) -> Result<(), spurio_export::Cause> {
        Ok(())
    }
}

impl spurio_export::ModelExchange for Decay {
    fn evaluate(&mut self, ctx: &mut spurio_export::Context) -> Result<(), spurio_export::Failure> {
        let der = -ctx.values.real(K) * ctx.values.real(X) + ctx.values.real(D);
        ctx.values.set_real(DER_X, der);
        Ok(())
    }
    fn event_indicators(
        &mut self,
        _ctx: &mut spurio_export::Context,
        _z: &mut [f64],
    ) -> Result<(), spurio_export::Failure> {
        Ok(())
    }
    fn update_discrete_states(
        &mut self,
        _ctx: &mut spurio_export::Context,
    ) -> Result<spurio_export::EventUpdate, spurio_export::Failure> {
        Ok(spurio_export::EventUpdate::default())
    }
    /// `∂der(x)/∂x = −k` (the layer keeps it between directional derivatives).
    type Jacobian = f64;
    fn jacobian(&mut self, ctx: &spurio_export::Context) -> Result<f64, spurio_export::Failure> {
        Ok(-ctx.values.real(K))
    }
    fn partial(
        &self,
        slope: &f64,
        unknown: usize,
        known: usize,
    ) -> Result<f64, spurio_export::Failure> {
        Ok(match (unknown, known) {
            (DER_X, X) => *slope,
            (DER_X, D) => 1.0,
            _ => 0.0,
        })
    }
}

/// A Model Exchange instance of `Decay`, initialised (`x = 2`, `k = 1`, `d = 0`), in
/// Continuous-Time Mode.
fn decay_in_continuous_time_mode() -> Harness<Decay> {
    let hooks = spurio_export::model::hooks::<Decay>();
    let mut h = Harness::model_exchange(&Config::new(), hooks).unwrap();
    h.initialize(0.0).unwrap();
    decay_mode(&h, false);
    h
}

/// `∂der(x)/∂x` of `Decay` through `fmi2GetDirectionalDerivative`.
fn decay_slope(h: &Harness<Decay>) -> f64 {
    directional_of::<Decay>(h.component(), &[DER_X], &[X], &[1.0]).unwrap()[0]
}

/// The layer keeps the Jacobian between directional derivatives at the same values (an
/// importer asks for it column by column) and forms it again after anything that may change
/// it: a parameter set in Event Mode, an FMU state restored.
#[test]
fn the_jacobian_kept_between_directional_derivatives_follows_the_values() {
    let mut h = decay_in_continuous_time_mode();
    assert_eq!(decay_slope(&h), -1.0);
    assert_eq!(decay_slope(&h), -1.0);
    let seeded = directional_of::<Decay>(h.component(), &[DER_X], &[X, D], &[2.0, 1.0]);
    assert_eq!(seeded, Ok(vec![-1.0]));
    let before = h.serialized_state().unwrap();
    decay_mode(&h, true);
    assert_eq!(h.set_real(&[K as u32], &[3.0]), Ok(Status::Ok));
    assert_eq!(decay_slope(&h), -3.0);
    assert_eq!(h.set_real(&[K as u32], &[5.0]), Ok(Status::Ok));
    assert_eq!(decay_slope(&h), -5.0);
    assert_eq!(h.restore_state(&before), Ok(Status::Ok));
    assert_eq!(decay_slope(&h), -1.0);
}

/// The derivative of `Decay` through `fmi2GetDerivatives`.
fn decay_derivative(h: &Harness<Decay>) -> f64 {
    let mut out = [f64::NAN];
    let (f, which) = (&functions::GET_DERIVATIVES, Array::Derivatives);
    let s = unsafe { me::get_array::<Decay, ()>(h.component(), f, which, out.as_mut_ptr(), 1) };
    assert_eq!(s, fmi2OK);
    out[0]
}

fn decay_mode(h: &Harness<Decay>, event: bool) {
    let f = if event {
        &functions::ENTER_EVENT_MODE
    } else {
        &functions::ENTER_CONTINUOUS_TIME_MODE
    };
    assert_eq!(
        unsafe { me::enter_mode::<Decay, ()>(h.component(), f, event) },
        fmi2OK
    );
}

/// FMI 2.0.4 §3.2.3 (FMI 3.0.2 §3.2.1 likewise): in Event Mode a master may set inputs and
/// tunable parameters, and every value read afterwards is computed from them; in
/// Continuous-Time Mode it may set continuous-time inputs only (a discrete input changes at
/// events alone).
#[test]
fn tunable_parameters_and_discrete_inputs_are_set_in_event_mode_only_and_read_back() {
    let mut h = decay_in_continuous_time_mode();
    assert_eq!(decay_derivative(&h), -2.0);
    // Continuous-Time Mode: neither the discrete input nor the tunable parameter
    assert_eq!(h.set_real(&[D as u32], &[1.0]), Err(Status::Error));
    assert!(
        last_error(&h).contains("variable `d`"),
        "{}",
        last_error(&h)
    );
    assert_eq!(h.set_real(&[K as u32], &[3.0]), Err(Status::Error));
    assert_eq!(decay_derivative(&h), -2.0);
    // Event Mode: both, and the derivative follows the new rate at once
    decay_mode(&h, true);
    assert_eq!(h.set_real(&[K as u32], &[3.0]), Ok(Status::Ok));
    assert_eq!(decay_derivative(&h), -6.0);
    assert_eq!(h.real(DER_X as u32), Ok(-6.0));
    assert_eq!(h.set_real(&[D as u32], &[1.0]), Ok(Status::Ok));
    assert_eq!(decay_derivative(&h), -5.0);
}

/// FMI 2.0.4 §3.2.3: `fmi2GetReal` returns every variable consistent with the states, time
/// and inputs last set, the event indicators' local variables too (without a call of
/// `fmi2GetEventIndicators` first).
#[test]
fn the_event_indicator_variables_follow_the_states() {
    let mut m = Me::new();
    m.start();
    assert_eq!(m.set_states(&[0.5, 0.0]), fmi2OK);
    assert_eq!(m.0.real(TO_WRAP as u32), Ok(1e6 - 0.5));
    assert_eq!(m.set_states(&[2.5, 0.0]), fmi2OK);
    assert_eq!(m.0.real(TO_WRAP as u32), Ok(1e6 - 2.5));
    assert_eq!(m.indicators(1).unwrap(), [1e6 - 2.5]);
}
