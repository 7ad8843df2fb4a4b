//! The model of the `PanicTest` FMU (shared by the library and the `describe` binary).

use spurio_export::{
    ByteReader, ByteWriter, Cause, Config, Context, Failure, FmuModel, ModelInfo, Variable,
};

/// The test model.
#[derive(Clone, Debug, Default)]
pub struct PanicTest {
    state: f64,
}

const U: usize = 0;
const Y: usize = 1;

impl FmuModel for PanicTest {
    fn describe(_config: &Config) -> Result<ModelInfo, Cause> {
        Ok(ModelInfo::new(
            "PanicTest",
            "test model that fails on purpose",
            vec![Variable::input("u", 0.0), Variable::output("y")],
            None,
            Config::new(),
        ))
    }
    fn create(_info: &ModelInfo) -> Result<Self, Cause> {
        Ok(Self::default())
    }
    fn initialize(&mut self, ctx: &mut Context) -> Result<(), Failure> {
        ctx.values.set_real(Y, self.state);
        Ok(())
    }
    fn do_step(&mut self, ctx: &mut Context, _time: f64, step: f64) -> Result<(), Failure> {
        let u = ctx.values.real(U);
        if u == 13.0 {
            panic!("unlucky input 13");
        }
        if u < -100.0 {
            return Err(Failure::error(format!("u = {u} is below -100")));
        }
        self.state += step * u;
        ctx.values.set_real(Y, self.state);
        Ok(())
    }
    fn save_state(&self, out: &mut ByteWriter) {
        out.put_f64(self.state);
    }
    fn load_state(&mut self, input: &mut ByteReader) -> Result<(), Cause> {
        self.state = input.f64()?;
        Ok(())
    }
}
