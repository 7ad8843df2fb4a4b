//! The values one FMI call moves ([`Batch`]: a [`Transfer`] of the plan as the value
//! references of one get or set) and the running instance it moves them from or to
//! ([`Unit`]: a Co-Simulation instance, or a Model Exchange instance that the master
//! integrates).

use crate::fmu::me::MeInstance;
use crate::fmu::{CallError, Experiment, FmiVersion, FmuFile, Instance, VarType};
use crate::logging::LogKey;
use crate::model_exchange::ModelExchangeCalls;
use crate::plan::Transfer;

/// A running FMU instance: Co-Simulation (it steps itself) or Model Exchange (the master
/// integrates it, [`crate::model_exchange::Stepper`]).
pub(crate) enum Unit {
    Cs(Instance),
    Me(MeInstance),
}

impl Unit {
    /// Reads the values of `vrs` (all of type `t`) into `out`.
    #[inline]
    pub(crate) fn get(
        &mut self,
        t: VarType,
        vrs: &[u32],
        out: &mut [f64],
    ) -> Result<(), CallError> {
        match self {
            Self::Cs(i) => i.get(t, vrs, out),
            Self::Me(i) => i.get(t, vrs, out),
        }
    }

    /// Sets `vrs` (all of type `t`) from `values`.
    #[inline]
    pub(crate) fn set(&mut self, t: VarType, vrs: &[u32], values: &[f64]) -> Result<(), CallError> {
        match self {
            Self::Cs(i) => i.set(t, vrs, values),
            Self::Me(i) => i.set(t, vrs, values),
        }
    }

    pub(crate) fn version(&self) -> FmiVersion {
        match self {
            Self::Cs(i) => i.version(),
            Self::Me(i) => i.version(),
        }
    }

    /// Where its log messages are kept.
    pub(crate) fn log(&self) -> &LogKey {
        match self {
            Self::Cs(i) => i.log(),
            Self::Me(i) => i.log(),
        }
    }

    pub(crate) fn setup_experiment(&mut self, e: Experiment) -> Result<(), CallError> {
        match self {
            Self::Cs(i) => i.setup_experiment(e),
            Self::Me(i) => i.setup_experiment(e),
        }
    }

    pub(crate) fn enter_initialization_mode(&mut self, e: Experiment) -> Result<(), CallError> {
        match self {
            Self::Cs(i) => i.enter_initialization_mode(e),
            Self::Me(i) => i.enter_initialization_mode(e),
        }
    }

    pub(crate) fn exit_initialization_mode(&mut self) -> Result<(), CallError> {
        match self {
            Self::Cs(i) => i.exit_initialization_mode(),
            Self::Me(i) => i.exit_initialization_mode(),
        }
    }

    pub(crate) fn terminate(&mut self) -> Result<(), CallError> {
        match self {
            Self::Cs(i) => i.terminate(),
            Self::Me(i) => ModelExchangeCalls::terminate(i),
        }
    }
}

/// One value of a [`Batch`]: its buffer slot, its position among the call's values and,
/// for an FMI 3.0 array element, (array, position in the array).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Entry {
    slot: usize,
    position: usize,
    element: Option<(usize, usize)>,
}

/// A [`Transfer`] of the plan as one FMI call: the value references of the call (an FMI 3.0
/// array once, with all its values), where each value goes, and the scratch space.
#[derive(Debug, Clone)]
pub(crate) struct Batch {
    var_type: VarType,
    /// The member (position among the running instances) it moves values of.
    pub(crate) member: usize,
    vrs: Vec<u32>,
    entries: Vec<Entry>,
    /// (array, first position) of every array moved whole by the call.
    arrays: Vec<(usize, usize)>,
    values: Vec<f64>,
}

impl Batch {
    pub(crate) fn new(t: &Transfer, fmu: &FmuFile) -> Self {
        let mut vrs = Vec::with_capacity(t.vrs.len());
        let mut entries = Vec::with_capacity(t.vrs.len());
        let mut arrays: Vec<(usize, usize)> = Vec::new();
        let mut count = 0;
        for ((&vr, &slot), &var) in t.vrs.iter().zip(&t.slots).zip(&t.vars) {
            let element = fmu.variables.get(var).and_then(|v| v.element);
            let position = match element {
                None => {
                    vrs.push(vr);
                    count += 1;
                    count - 1
                }
                Some((array, k)) => match arrays.iter().find(|(a, _)| *a == array) {
                    Some(&(_, first)) => first + k,
                    None => {
                        let first = count;
                        vrs.push(vr);
                        count += fmu.arrays.get(array).map_or(0, |a| a.elements.len());
                        arrays.push((array, first));
                        first + k
                    }
                },
            };
            entries.push(Entry {
                slot,
                position,
                element,
            });
        }
        Self {
            var_type: t.var_type,
            member: t.member,
            vrs,
            entries,
            arrays,
            values: vec![0.0; count],
        }
    }

    #[inline]
    pub(crate) fn get(&mut self, inst: &mut Unit, buffer: &mut [f64]) -> Result<(), CallError> {
        inst.get(self.var_type, &self.vrs, &mut self.values)?;
        for e in &self.entries {
            buffer[e.slot] = self.values[e.position];
        }
        Ok(())
    }

    /// Sets the values from the buffer; the elements of an array this batch does not set
    /// keep the values last given to them (`held`, per array of the instance's FMU).
    #[inline]
    pub(crate) fn set(
        &mut self,
        inst: &mut Unit,
        buffer: &[f64],
        held: &mut [Vec<f64>],
    ) -> Result<(), CallError> {
        for e in &self.entries {
            let v = buffer[e.slot];
            self.values[e.position] = v;
            if let Some((array, k)) = e.element {
                if let Some(x) = held.get_mut(array).and_then(|a| a.get_mut(k)) {
                    *x = v;
                }
            }
        }
        for &(array, first) in &self.arrays {
            if let Some(a) = held.get(array) {
                self.values[first..first + a.len()].copy_from_slice(a);
            }
        }
        inst.set(self.var_type, &self.vrs, &self.values)
    }
}
