//! The checks after every model call, on a wide table: the roll-back copy and the non-finite
//! scan cover exactly the variables a model call may write (runs of them, short gaps of
//! parameters joined), a non-finite value in the last element of
//! a long output vector is still found and named, a failed step loses nothing, and the
//! branch-free scan agrees with the former formula (`all(is_finite)`) on random vectors; the
//! harness's audit catches a model that writes a parameter.

use spurio_export::harness::Harness;
use spurio_export::types::Status;
use spurio_export::values::{all_finite, computed_runs, first_non_finite, RUN_GAP};
use spurio_export::{
    ByteReader, ByteWriter, Cause, Config, Context, Failure, FmuModel, ModelInfo, Variable,
};

/// Elements of each output vector.
const K: usize = 50;
/// `u`, the input.
const U: usize = 0;
/// `y[1]` … `y[K]`: `gain · u · i`.
const Y: usize = 1;
/// `gain`, a parameter between the two output vectors.
const GAIN: usize = Y + K;
/// `w[1]` … `w[K]`: `u + i`; `w[K]` is NaN when `u = 7` and +∞ when `u = 8`.
const W: usize = GAIN + 1;
/// `steps`, an Integer output: the steps taken.
const STEPS: usize = W + K;
/// `offset`, a parameter after the last output.
const OFFSET: usize = STEPS + 1;

#[derive(Clone, Debug, Default)]
struct Wide {
    steps: i32,
}

impl Wide {
    fn write(&self, ctx: &mut Context) {
        let (u, gain) = (ctx.values.real(U), ctx.values.real(GAIN));
        for i in 0..K {
            ctx.values.set_real(Y + i, gain * u * (i + 1) as f64);
            ctx.values.set_real(W + i, u + (i + 1) as f64);
        }
        if u == 7.0 {
            ctx.values.set_real(W + K - 1, f64::NAN);
        } else if u == 8.0 {
            ctx.values.set_real(W + K - 1, f64::INFINITY);
        }
        ctx.values.set_integer(STEPS, self.steps);
    }
}

impl FmuModel for Wide {
    fn describe(_config: &Config) -> Result<ModelInfo, Cause> {
        let mut vars = vec![Variable::input("u", 0.0)];
        vars.extend((1..=K).map(|i| Variable::output(&format!("y[{i}]"))));
        vars.push(Variable::parameter("gain", 2.0));
        vars.extend((1..=K).map(|i| Variable::output(&format!("w[{i}]"))));
        let mut steps = Variable::integer_parameter("steps", 0);
        steps.causality = spurio_export::Causality::Output;
        steps.variability = spurio_export::Variability::Discrete;
        steps.initial = Some(spurio_export::Initial::Calculated);
        vars.push(steps);
        vars.push(Variable::parameter("offset", 0.5));
        Ok(ModelInfo::new("Wide", "wide", vars, None, Config::new()))
    }
    fn create(_info: &ModelInfo) -> Result<Self, Cause> {
        Ok(Self::default())
    }
    fn initialize(&mut self, ctx: &mut Context) -> Result<(), Failure> {
        self.write(ctx);
        Ok(())
    }
    fn do_step(&mut self, ctx: &mut Context, _time: f64, _step: f64) -> Result<(), Failure> {
        self.steps += 1;
        self.write(ctx);
        Ok(())
    }
    fn save_state(&self, out: &mut ByteWriter) {
        out.put_i32(self.steps);
    }
    fn load_state(&mut self, input: &mut ByteReader) -> Result<(), Cause> {
        input
            .i32()
            .map(|steps| self.steps = steps)
            .map_err(Into::into)
    }
}

fn all_reals(h: &mut Harness<Wide>) -> Vec<f64> {
    let vrs: Vec<u32> = (0..OFFSET as u32 + 1)
        .filter(|&i| i != STEPS as u32)
        .collect();
    let mut out = vec![0.0; vrs.len()];
    h.get_real(&vrs, &mut out).unwrap();
    out
}

fn last_error(h: &Harness<Wide>) -> String {
    h.log()
        .into_iter()
        .filter(|(s, _, _)| *s >= Status::Error)
        .map(|(_, _, t)| t)
        .next_back()
        .unwrap_or_default()
}

#[test]
fn the_checked_runs_are_the_computed_variables_with_short_gaps_joined() {
    let info = Wide::describe(&Config::new()).unwrap();
    // one parameter between the two vectors: one run
    assert_eq!(computed_runs(&info.variables), vec![Y..STEPS + 1; 1]);
    assert!(computed_runs(&info.variables[..1]).is_empty());
    // a longer gap of parameters: two runs
    let mut vars = vec![Variable::output("a")];
    vars.extend((0..=RUN_GAP).map(|i| Variable::parameter(&format!("p{i}"), 0.0)));
    vars.push(Variable::output("b"));
    vars.push(Variable::input("u", 0.0));
    let b = RUN_GAP + 2;
    assert_eq!(computed_runs(&vars), [0..1, b..b + 1]);
}

#[test]
fn a_non_finite_last_element_of_a_long_vector_is_named_and_the_step_loses_nothing() {
    for (u, shown) in [(7.0, "NaN"), (8.0, "inf")] {
        let mut h = Harness::<Wide>::new(&Config::new()).unwrap();
        h.initialize(0.0).unwrap();
        h.set_real(&[U as u32], &[3.0]).unwrap();
        h.do_step(0.0, 1.0).unwrap();
        let before = all_reals(&mut h);
        assert_eq!(before[Y + K - 1], 2.0 * 3.0 * K as f64);
        assert_eq!(before[W + K - 1], 3.0 + K as f64);

        h.set_real(&[U as u32], &[u]).unwrap();
        assert_eq!(h.do_step(1.0, 1.0), Err(Status::Error));
        let e = last_error(&h);
        let expected = format!(
            "fmi2DoStep: variable `w[{K}]` (value reference {}) came out as {shown}: not published",
            W + K - 1
        );
        assert!(e.contains(&expected), "{e}");
        // every output back to its value after the first step (the inputs as the master set
        // them), the Integer output too
        let after = all_reals(&mut h);
        assert_eq!(after[U], u);
        assert_eq!(after[1..], before[1..]);
        let mut steps = [0];
        h.get_integer(&[STEPS as u32], &mut steps).unwrap();
        assert_eq!(steps, [1]);
        // the instance is in the Error state; fmi2Reset leads on
        assert_eq!(h.do_step(1.0, 1.0), Err(Status::Error));
        assert!(last_error(&h).contains("not allowed in state Error"));
        h.reset().unwrap();
        h.initialize(0.0).unwrap();
        let w_k = W as u32 + K as u32 - 1;
        assert_eq!(h.real(w_k).unwrap(), K as f64);
    }
}

#[test]
fn infinite_and_out_of_range_sets_are_refused_without_bounds_declared() {
    let mut h = Harness::<Wide>::new(&Config::new()).unwrap();
    h.initialize(0.0).unwrap();
    for x in [f64::INFINITY, f64::NEG_INFINITY, f64::NAN] {
        assert_eq!(
            h.set_real(&[U as u32, U as u32], &[1.0, x]),
            Err(Status::Error)
        );
        let e = last_error(&h);
        assert!(
            e.contains("variable `u` (value reference 0)") && e.contains("values must be finite"),
            "{e}"
        );
    }
    // the largest finite values are values
    h.set_real(&[U as u32], &[f64::MAX]).unwrap();
    h.set_real(&[U as u32], &[-f64::MAX]).unwrap();
    assert_eq!(h.real(U as u32).unwrap(), -f64::MAX);
}

/// xorshift64*: a reproducible stream of test numbers without a dependency.
struct Stream(u64);
impl Stream {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_f491_4f6c_dd1d)
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n as u64) as usize
    }
}

#[test]
fn the_branch_free_scan_agrees_with_the_former_formula() {
    let mut rng = Stream(0x9e37_79b9_7f4a_7c15);
    let specials = [
        f64::NAN,
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::MAX,
        -f64::MAX,
        f64::MIN_POSITIVE,
        -0.0,
        5e-324,
    ];
    for case in 0..20_000 {
        let n = rng.below(70);
        let mut xs: Vec<f64> = (0..n)
            .map(|_| f64::from_bits(rng.next()).clamp(-1e300, 1e300))
            .map(|x| if x.is_nan() { 1.0 } else { x })
            .collect();
        // a few specials at random places (none in a quarter of the cases)
        if case % 4 != 0 && n > 0 {
            for _ in 0..1 + rng.below(3) {
                let at = rng.below(n);
                xs[at] = specials[rng.below(specials.len())];
            }
        }
        let former = xs.iter().all(|x| x.is_finite());
        assert_eq!(all_finite(&xs), former, "{xs:?}");
        let first = xs.iter().position(|x| !x.is_finite());
        assert_eq!(first_non_finite(&xs).map(|(i, _)| i), first);
    }
    // the last element of every length up to 70, alone non-finite
    for n in 1..70 {
        let mut xs = vec![1.0; n];
        xs[n - 1] = f64::NAN;
        assert!(!all_finite(&xs), "{n}");
        assert_eq!(first_non_finite(&xs).map(|(i, _)| i), Some(n - 1));
    }
}

/// A model that breaks the contract: it writes one of its parameters in a step.
#[derive(Clone, Debug, Default)]
struct Meddler;

impl FmuModel for Meddler {
    fn describe(_config: &Config) -> Result<ModelInfo, Cause> {
        let vars = vec![Variable::parameter("k", 1.0), Variable::output("y")];
        Ok(ModelInfo::new(
            "Meddler",
            "meddler",
            vars,
            None,
            Config::new(),
        ))
    }
    fn create(_info: &ModelInfo) -> Result<Self, Cause> {
        Ok(Self)
    }
    fn initialize(&mut self, _ctx: &mut Context) -> Result<(), Failure> {
        Ok(())
    }
    fn do_step(&mut self, ctx: &mut Context, _time: f64, _step: f64) -> Result<(), Failure> {
        ctx.values.set_real(0, 2.0);
        Ok(())
    }
    fn save_state(&self, _out: &mut ByteWriter) {}
    fn load_state(&mut self, _input: &mut ByteReader) -> Result<(), Cause> {
        Ok(())
    }
}

#[test]
fn the_audit_catches_a_model_that_writes_a_parameter_and_restores_it() {
    let mut h = Harness::<Meddler>::new(&Config::new()).unwrap();
    h.initialize(0.0).unwrap();
    assert_eq!(h.do_step(0.0, 1.0), Err(Status::Error));
    assert!(
        h.logged(&["fmi2DoStep", "changed variable `k`", "only the master sets"]),
        "{:?}",
        h.log()
    );
    // the parameter as it was (readable in the Error state)
    assert_eq!(h.real(0).unwrap(), 1.0);
}
