//! The roll-back window: a model whose computed values are one short run is checked in a
//! fixed block of the table ([`Window`]), and a step that makes one of them NaN publishes
//! nothing: every output reads as before the step, the log names the variable.

use spurio_export::harness::Harness;
use spurio_export::instance::{Window, WINDOW};
use spurio_export::types::Status;
use spurio_export::values::computed_runs;
use spurio_export::{ByteReader, ByteWriter, Cause, Config, Context, Failure, FmuModel, ModelInfo};
use spurio_export::{Variable, VariableType};

/// Outputs `y[k] = gain · u + k` at the variables the configuration `names` puts them
/// (`u`, `gain`, `y1`…); `y[last]` comes out NaN when `u = 7`.
#[derive(Debug, Clone)]
struct Short {
    u: usize,
    gain: usize,
    y: Vec<usize>,
}

fn layout(config: &Config) -> Vec<String> {
    config
        .get("names")
        .unwrap_or("u gain y y y")
        .split(' ')
        .map(str::to_string)
        .collect()
}

impl FmuModel for Short {
    fn describe(config: &Config) -> Result<ModelInfo, Cause> {
        let variables = layout(config)
            .iter()
            .enumerate()
            .map(|(k, name)| match name.as_str() {
                "u" => Variable::input("u", 0.0),
                "y" => Variable::output(&format!("y{k}")),
                other => Variable::parameter(&format!("{other}{k}"), 2.0),
            })
            .collect();
        Ok(ModelInfo::new(
            "Short",
            "short",
            variables,
            None,
            config.clone(),
        ))
    }
    fn create(info: &ModelInfo) -> Result<Self, Cause> {
        let names = layout(&info.config);
        let at = |n: &str| names.iter().position(|m| m == n).unwrap_or(0);
        Ok(Self {
            u: at("u"),
            gain: at("gain"),
            y: (0..names.len()).filter(|&k| names[k] == "y").collect(),
        })
    }
    fn initialize(&mut self, ctx: &mut Context) -> Result<(), Failure> {
        self.do_step(ctx, 0.0, 0.0)
    }
    fn do_step(&mut self, ctx: &mut Context, _: f64, _: f64) -> Result<(), Failure> {
        let (u, gain) = (ctx.values.real(self.u), ctx.values.real(self.gain));
        for (k, &y) in self.y.iter().enumerate() {
            let last = k + 1 == self.y.len();
            let v = if last && u == 7.0 {
                f64::NAN
            } else {
                gain * u + k as f64
            };
            ctx.values.set_real(y, v);
        }
        Ok(())
    }
    fn save_state(&self, out: &mut ByteWriter) {
        out.put_u64(self.y.len() as u64);
    }
    fn load_state(&mut self, input: &mut ByteReader) -> Result<(), Cause> {
        match input.u64()? {
            n if n == self.y.len() as u64 => Ok(()),
            n => Err(format!("{n} outputs saved, {} here", self.y.len()).into()),
        }
    }
}

#[test]
fn a_short_run_is_checked_in_its_window_and_a_failed_step_loses_nothing() {
    for (names, window) in [
        ("u gain y y y", Some((1, [false, true, true, true]))),
        ("y u gain", None),
        ("u y gain gain", Some((0, [false, true, false, false]))),
        (
            "gain gain u gain y y",
            Some((2, [false, false, true, true])),
        ),
        ("gain y y y y u", Some((1, [true, true, true, true]))),
        ("u y y y y y", None),
    ] {
        let mut config = Config::new();
        config.set("names", names);
        let info = Short::describe(&config).unwrap();
        let runs = computed_runs(&info.variables);
        let found = Window::of(&runs, info.variables.len());
        assert_eq!(found.map(|w| (w.start, w.lanes)), window, "{names}");
        if let Some(w) = found {
            // the lanes are exactly the run
            let lanes: Vec<usize> = (0..WINDOW)
                .filter(|&k| w.lanes[k])
                .map(|k| w.start + k)
                .collect();
            assert_eq!(lanes, runs[0].clone().collect::<Vec<_>>(), "{names}");
        }
        let mut h = Harness::<Short>::new(&config).unwrap();
        let u = info.index_of("u").unwrap() as u32;
        h.initialize(0.0).unwrap();
        h.set_real(&[u], &[1.5]).unwrap();
        h.do_step(0.0, 1.0).unwrap();
        let reals: Vec<u32> = (0..info.variables.len() as u32).collect();
        let read = |h: &mut Harness<Short>| {
            let mut out = vec![0.0; reals.len()];
            h.get_real(&reals, &mut out).unwrap();
            out
        };
        let before = read(&mut h);
        assert!(before.iter().all(|v| v.is_finite()));
        h.set_real(&[u], &[7.0]).unwrap();
        assert_eq!(h.do_step(1.0, 1.0), Err(Status::Error), "{names}");
        let mut after = read(&mut h);
        after[u as usize] = 1.5;
        assert_eq!(after, before, "{names}: the outputs as they were");
        let last_y = info
            .variables
            .iter()
            .rposition(|v| v.name.starts_with('y'))
            .unwrap();
        let (_, _, text) = h.log().pop().unwrap();
        assert!(
            text.contains(&format!(
                "variable `y{last_y}` (value reference {last_y}) came out as NaN"
            )),
            "{names}: {text}"
        );
        assert!(info
            .variables
            .iter()
            .all(|v| v.variable_type() == VariableType::Real));
    }
}
