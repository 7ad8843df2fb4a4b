//! The toy model every export-layer suite drives (FMI 2.0 and 3.0, Co-Simulation and Model
//! Exchange), one table for all:
//!
//! | index | variable | what |
//! |---|---|---|
//! | 0, 1 | `u[1]`, `u[2]` | inputs |
//! | 2, 3 | `y[1]`, `y[2]` | outputs and continuous states: `der(y[i]) = u[i]` (CS: Euler per step, exact for constant inputs) |
//! | 4 | `z` | `u[1] + u[2]` (direct feedthrough) |
//! | 5–8 | `P[1,1]` … `P[2,2]` | a 2×2 parameter (≤ 100), read back only |
//! | 9 | `N` | Integer parameter (≥ 1) |
//! | 10 | `positive` | `y[1] > 0` |
//! | 11 | `y0` | start of `y[1]` (−10 … 10) |
//! | 12, 13 | `der(y)[1]`, `der(y)[2]` | the derivatives (Model Exchange) |
//! | 14 | `to_wrap` | event indicator `y_max − y[1]` (Model Exchange) |
//! | 15 | `y_max` | tunable: at the event `y[1]` is reset to 0 (Model Exchange only) |
//!
//! It panics when `u[1] = 13` (in a step or an evaluation), fails when `u[1] < −100`, refuses
//! steps longer than 1000 s, and lets `y` overflow to ±∞ when `u · h` does.
#![allow(dead_code)]

use spurio_export::{
    ByteReader, ByteWriter, Cause, Config, Context, EventUpdate, Failure, FmuModel, ModelExchange,
    ModelInfo, Variable,
};

/// The toy (the CS state `y`; Model Exchange keeps its states in the variables).
#[derive(Clone, Debug, Default)]
pub struct Toy {
    y: [f64; 2],
}

pub const U: usize = 0; // u[1], u[2]
pub const Y: usize = 2; // y[1], y[2]
pub const Z: usize = 4;
pub const P: usize = 5; // P[1,1] … P[2,2]
pub const N: usize = 9;
pub const POSITIVE: usize = 10;
pub const Y0: usize = 11;
pub const DER_Y: usize = 12; // der(y)[1], der(y)[2]
pub const TO_WRAP: usize = 14;
pub const Y_MAX: usize = 15;

impl FmuModel for Toy {
    fn describe(_config: &Config) -> Result<ModelInfo, Cause> {
        let mut vars = vec![Variable::input("u[1]", 0.0), Variable::input("u[2]", 0.0)];
        for i in 0..2 {
            vars.push(
                Variable::output(&format!("y[{}]", i + 1))
                    .state()
                    .nominal(2.0)
                    .depends_on(&[Y + i]),
            );
        }
        vars.push(Variable::output("z").depends_on(&[U, U + 1]));
        for (i, j) in [(1, 1), (1, 2), (2, 1), (2, 2)] {
            vars.push(Variable::parameter(&format!("P[{i},{j}]"), (10 * i + j) as f64).max(100.0));
        }
        vars.push(Variable::integer_parameter("N", 3).min(1.0));
        vars.push(Variable::boolean_output("positive"));
        vars.push(Variable::parameter("y0", 0.0).min(-10.0).max(10.0));
        for i in 0..2 {
            vars.push(
                Variable::derivative(&format!("der(y)[{}]", i + 1), Y + i).depends_on(&[U + i]),
            );
        }
        vars.push(Variable::event_indicator("to_wrap"));
        vars.push(Variable::parameter("y_max", 1e6).tunable().min(0.0));
        Ok(ModelInfo::new("Toy", "toy", vars, None, Config::new()).with_model_exchange()?)
    }
    fn create(_info: &ModelInfo) -> Result<Self, Cause> {
        Ok(Self::default())
    }
    fn initialize(&mut self, ctx: &mut Context) -> Result<(), Failure> {
        self.y = [ctx.values.real(Y0), 0.0];
        ctx.values.set_real(Y, self.y[0]);
        ctx.values.set_real(Y + 1, self.y[1]);
        self.update_outputs(ctx)
    }
    fn check_step(&self, _ctx: &Context, _time: f64, step: f64) -> Result<(), Cause> {
        if step > 1000.0 {
            return Err(format!("a step of {step} s is longer than 1000 s").into());
        }
        Ok(())
    }
    fn do_step(&mut self, ctx: &mut Context, _time: f64, step: f64) -> Result<(), Failure> {
        check_input(ctx)?;
        for i in 0..2 {
            self.y[i] += step * ctx.values.real(U + i);
            ctx.values.set_real(Y + i, self.y[i]);
        }
        self.update_outputs(ctx)
    }
    fn update_outputs(&mut self, ctx: &mut Context) -> Result<(), Failure> {
        let z = ctx.values.real(U) + ctx.values.real(U + 1);
        ctx.values.set_real(Z, z);
        let positive = ctx.values.real(Y) > 0.0;
        ctx.values.set_boolean(POSITIVE, positive);
        Ok(())
    }
    fn save_state(&self, out: &mut ByteWriter) {
        out.put_f64(self.y[0]);
        out.put_f64(self.y[1]);
    }
    fn load_state(&mut self, input: &mut ByteReader) -> Result<(), Cause> {
        let y = [input.f64()?, input.f64()?];
        if let Some(bad) = y.iter().find(|y| !y.is_finite()) {
            return Err(format!("the toy's state {bad} is not finite").into());
        }
        self.y = y;
        Ok(())
    }
}

/// The panic and the failure the toy's inputs trigger.
fn check_input(ctx: &Context) -> Result<(), Failure> {
    let u = ctx.values.real(U);
    if u == 13.0 {
        panic!("unlucky input");
    }
    if u < -100.0 {
        return Err(Failure::error("u below -100 is not integrable"));
    }
    Ok(())
}

impl ModelExchange for Toy {
    fn evaluate(&mut self, ctx: &mut Context) -> Result<(), Failure> {
        check_input(ctx)?;
        for i in 0..2 {
            let u = ctx.values.real(U + i);
            ctx.values.set_real(DER_Y + i, u);
        }
        self.update_outputs(ctx)
    }
    fn event_indicators(&mut self, ctx: &mut Context, z: &mut [f64]) -> Result<(), Failure> {
        z[0] = ctx.values.real(Y_MAX) - ctx.values.real(Y);
        Ok(())
    }
    fn update_discrete_states(&mut self, ctx: &mut Context) -> Result<EventUpdate, Failure> {
        let mut update = EventUpdate::default();
        if ctx.values.real(Y) >= ctx.values.real(Y_MAX) {
            ctx.values.set_real(Y, 0.0);
            let time = ctx.time();
            ctx.log_event(|| format!("y[1] wrapped to 0 at t = {}", time));
            update.states_changed = true;
        }
        Ok(update)
    }

    type Jacobian = ();

    fn jacobian(&mut self, _ctx: &Context) -> Result<(), Failure> {
        Ok(())
    }

    /// ∂der(y[i])/∂u[i] = 1, ∂y[i]/∂y[i] = 1, ∂z/∂u[j] = 1; everything else 0.
    fn partial(&self, _: &(), unknown: usize, known: usize) -> Result<f64, Failure> {
        Ok(match unknown {
            DER_Y | 13 if known == U + unknown - DER_Y => 1.0,
            Y | 3 if known == unknown => 1.0,
            Z if known == U || known == U + 1 => 1.0,
            _ => 0.0,
        })
    }
}
