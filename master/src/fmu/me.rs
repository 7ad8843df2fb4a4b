//! Model Exchange instances of FMI 2.0 and 3.0 behind [`ModelExchangeCalls`], and what the
//! Model Exchange driver needs from the model description: the number of states and event
//! indicators, the value references of the derivatives and states (for directional
//! derivatives), and the `DefaultExperiment`.
//!
//! Directional derivatives: FMI 2.0 FMUs that declare `providesDirectionalDerivative` give
//! `∂ẋ/∂x · v` by `fmi2GetDirectionalDerivative` (unknowns: the derivatives, knowns: the
//! states). rust-fmi 0.8 has no safe `fmi3GetDirectionalDerivative`, so FMI 3.0 FMUs are
//! differentiated by finite differences in the solver.

use super::instance::{get2, get3, set2, set3, Scratch};
use super::{
    CallError, Experiment, FmiVersion, FmuFile, Import, Interface, LoadError, VarType, Versioned,
};
use crate::logging::LogKey;
use crate::model_exchange::{EventUpdate, ModelExchangeCalls};
use crate::xml::{attribute, tags, Tag};
use fmi::fmi2::instance::{Common as _, ModelExchange as _};
use fmi::fmi3::{Common as _, Fmi3Model as _, ModelExchange as _};
use fmi::traits::FmiImport;
use fmi::EventFlags;

/// A model description's `DefaultExperiment` (each attribute if given).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct DefaultExperiment {
    pub start_time: Option<f64>,
    pub stop_time: Option<f64>,
    pub tolerance: Option<f64>,
    pub step_size: Option<f64>,
}

/// What the Model Exchange driver takes from the model description.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct MeDescription {
    /// FMI 2.0: the states, one per `<Derivatives><Unknown>` (FMI 3.0: asked of the instance).
    pub states: usize,
    /// FMI 2.0: `numberOfEventIndicators` (FMI 3.0: asked of the instance).
    pub event_indicators: usize,
    /// The value references of the derivatives, in the order of the states (FMI 2.0).
    pub derivatives: Vec<u32>,
    /// The value references of the states (FMI 2.0).
    pub state_references: Vec<u32>,
    /// `providesDirectionalDerivative(s)` of `<ModelExchange>`.
    pub directional_derivatives: bool,
    pub default_experiment: DefaultExperiment,
}

/// Reads the `DefaultExperiment` and the Model Exchange layout of a loaded FMU from its
/// `modelDescription.xml`.
pub fn read_description(fmu: &FmuFile) -> Result<MeDescription, LoadError> {
    let dir = match &fmu.import {
        Import::Fmi2(i) => i.archive_path().to_path_buf(),
        Import::Fmi3(i) => i.archive_path().to_path_buf(),
        Import::Table => {
            return Err(LoadError::ModelDescription {
                file: fmu.path.clone(),
                reason: "a data instance's table has no model description".into(),
            })
        }
    };
    let text = std::fs::read_to_string(dir.join("modelDescription.xml")).map_err(|e| {
        LoadError::ModelDescription {
            file: fmu.path.clone(),
            reason: e.to_string(),
        }
    })?;
    parse(&text, fmu.version).map_err(|reason| LoadError::ModelDescription {
        file: fmu.path.clone(),
        reason,
    })
}

/// An attribute parsed as a number (`None` when absent; an error naming it when malformed).
fn number<T: std::str::FromStr>(
    e: &quick_xml::events::BytesStart,
    key: &str,
) -> Result<Option<T>, String> {
    match attribute(e, key) {
        None => Ok(None),
        Some(v) => v
            .trim()
            .parse()
            .map(Some)
            .map_err(|_| format!("`{key}=\"{v}\"` of <{}> is not a number", e.name().as_ref())),
    }
}

/// Reads the model description `text` of FMI `version`.
fn parse(text: &str, version: FmiVersion) -> Result<MeDescription, String> {
    let mut d = MeDescription::default();
    // FMI 2.0: (value reference, `derivative` index) of each ScalarVariable, 1-based order.
    let mut scalars: Vec<(u32, Option<usize>)> = Vec::new();
    let mut derivative_indices: Vec<usize> = Vec::new();
    let (mut in_derivatives, mut in_variables) = (false, false);
    for tag in tags(text) {
        let (e, empty) = match tag? {
            Tag::Start { element, empty } => (element, empty),
            // Leaving a list ends it (the lists here do not nest).
            Tag::End(end) => {
                let name = end.name();
                in_derivatives &= name.as_ref() != "Derivatives";
                in_variables &= name.as_ref() != "ModelVariables";
                continue;
            }
        };
        match e.name().as_ref() {
            "fmiModelDescription" if version == FmiVersion::Fmi2 => {
                d.event_indicators = number(&e, "numberOfEventIndicators")?.unwrap_or(0);
            }
            "ModelExchange" => {
                let key = match version {
                    FmiVersion::Fmi2 => "providesDirectionalDerivative",
                    FmiVersion::Fmi3 => "providesDirectionalDerivatives",
                };
                d.directional_derivatives = attribute(&e, key).as_deref() == Some("true");
            }
            "DefaultExperiment" => {
                d.default_experiment = DefaultExperiment {
                    start_time: number(&e, "startTime")?,
                    stop_time: number(&e, "stopTime")?,
                    tolerance: number(&e, "tolerance")?,
                    step_size: number(&e, "stepSize")?,
                };
            }
            "ModelVariables" => in_variables = !empty,
            "ScalarVariable" if in_variables => {
                let vr = number(&e, "valueReference")?.unwrap_or(0);
                scalars.push((vr, None));
            }
            "Real" if in_variables && version == FmiVersion::Fmi2 => {
                if let (Some(last), Some(k)) = (scalars.last_mut(), number(&e, "derivative")?) {
                    last.1 = Some(k);
                }
            }
            "Derivatives" => in_derivatives = !empty,
            "Unknown" if in_derivatives => {
                derivative_indices.push(number(&e, "index")?.unwrap_or(0));
            }
            _ => {}
        }
    }
    if version == FmiVersion::Fmi2 {
        d.states = derivative_indices.len();
        for index in derivative_indices {
            let variable = index
                .checked_sub(1)
                .and_then(|i| scalars.get(i))
                .ok_or_else(|| {
                    format!("<Derivatives> names variable {index}, which does not exist")
                })?;
            let state = variable
                .1
                .and_then(|k| k.checked_sub(1))
                .and_then(|k| scalars.get(k))
                .ok_or_else(|| {
                    format!("variable {index} in <Derivatives> has no valid `derivative` attribute")
                })?;
            d.derivatives.push(variable.0);
            d.state_references.push(state.0);
        }
    }
    Ok(d)
}

/// A rust-fmi Model Exchange instance of either version.
type Inner = Versioned<fmi::fmi2::instance::InstanceME, fmi::fmi3::instance::InstanceME>;

/// One Model Exchange instance with what its calls need.
pub struct MeInstance {
    /// The layout from the model description (and, FMI 3.0, the instance).
    description: MeDescription,
    /// The rust-fmi instance.
    inner: Inner,
    /// Where its log messages are kept.
    log: LogKey,
    /// The FMU's file and the instance, for messages.
    name: String,
    /// The conversion buffers of the FMI 3.0 typed calls, and of FMI 2.0 Integers/Booleans.
    scratch: Scratch,
    ints: Vec<i32>,
}

impl std::fmt::Debug for MeInstance {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "MeInstance({})", self.name)
    }
}

impl FmuFile {
    /// A Model Exchange instance called `instance` of an FMU loaded for Model Exchange
    /// ([`FmuFile::open_for`]), with its layout read from the model description (FMI 3.0: the
    /// numbers of states and event indicators asked of the instance).
    pub fn instantiate_model_exchange(
        &self,
        instance: &str,
        logging_on: bool,
    ) -> Result<MeInstance, LoadError> {
        let mut description = read_description(self)?;
        let key = LogKey::new(instance);
        let name = format!("{} (instance `{instance}`)", self.path.display());
        let failed = |call: &'static str, reason: String| LoadError::Instantiate {
            instance: instance.to_string(),
            file: self.path.clone(),
            call,
            log: reason,
        };
        if self.interface != Interface::ModelExchange {
            return Err(failed(
                "fmi2Instantiate",
                ": the FMU was loaded for Co-Simulation, not Model Exchange".into(),
            ));
        }
        let inner = match &self.import {
            Import::Fmi2(import) => import
                .instantiate_me(key.instance_name(), false, logging_on)
                .map(|i| Inner::Fmi2(Box::new(i)))
                .map_err(|e| failed("fmi2Instantiate", key.failed_call(e)))?,
            Import::Fmi3(import) => {
                let mut i = crate::logging::speaking(&key, || {
                    import.instantiate_me(key.instance_name(), false, logging_on)
                })
                .map_err(|e| failed("fmi3InstantiateModelExchange", key.failed_call(e)))?;
                description.states = i
                    .get_number_of_continuous_states()
                    .map_err(|e| failed("fmi3GetNumberOfContinuousStates", format!(" ({e})")))?;
                description.event_indicators = i
                    .get_number_of_event_indicators()
                    .map_err(|e| failed("fmi3GetNumberOfEventIndicators", format!(" ({e})")))?;
                Inner::Fmi3(Box::new(i))
            }
            Import::Table => {
                return Err(failed(
                    "fmi2Instantiate",
                    " (a data table is read by the engine, not instantiated)".into(),
                ))
            }
        };
        Ok(MeInstance {
            inner,
            log: key,
            name,
            scratch: Scratch::default(),
            ints: Vec::new(),
            description,
        })
    }
}

impl MeInstance {
    /// Where this instance's log messages are kept.
    pub fn log(&self) -> &LogKey {
        &self.log
    }

    /// The FMI version of the instance.
    pub fn version(&self) -> FmiVersion {
        match self.inner {
            Inner::Fmi2(_) => FmiVersion::Fmi2,
            Inner::Fmi3(_) => FmiVersion::Fmi3,
        }
    }

    /// The layout read from the model description (and, FMI 3.0, the instance).
    pub fn description(&self) -> &MeDescription {
        &self.description
    }

    /// The driver's layout for this instance of `fmu`: its states and event indicators, its
    /// outputs recorded (by name, in the model description's order), and `start_values`
    /// (by variable name) set before initialisation. An unknown name, or one that is not a
    /// number, is an error naming it.
    pub fn layout(
        &self,
        fmu: &FmuFile,
        start_values: &[(String, f64)],
    ) -> Result<crate::model_exchange::Layout, String> {
        let recorded = fmu
            .variables
            .iter()
            .filter(|v| {
                v.head.causality == super::Causality::Output && v.head.var_type.is_numeric()
            })
            .map(|v| (v.head.name.clone(), v.head.var_type, v.head.value_reference))
            .collect();
        let start_values = start_values
            .iter()
            .map(|(name, value)| {
                let v = fmu
                    .variable(name)
                    .ok_or_else(|| format!("{} has no variable `{name}`", fmu.path.display()))?;
                if let Some((array, _)) = v.element {
                    return Err(format!(
                        "`{name}` is an element of the FMI 3.0 array `{}` of {}: set the array's elements in a system file (a single-FMU run sets scalars)",
                        fmu.arrays[array].head.name,
                        fmu.path.display()
                    ));
                }
                if !v.head.var_type.is_numeric() {
                    return Err(format!(
                        "`{name}` of {} is a {}, not a number",
                        fmu.path.display(),
                        v.head.var_type.name()
                    ));
                }
                Ok((v.head.var_type, v.head.value_reference, *value))
            })
            .collect::<Result<_, String>>()?;
        Ok(crate::model_exchange::Layout {
            states: self.description.states,
            event_indicators: self.description.event_indicators,
            recorded,
            start_values,
        })
    }
}

/// The error of a failed call, with what the instance logged (its recent messages the user
/// has not seen, [`LogKey::failure_note`]): a plant's own reason reaches the error report
/// even where its log is not printed (inside an estimator FMU).
#[cold]
fn quoting_log(log: &LogKey, e: CallError) -> CallError {
    match log.failure_note() {
        Some(note) => CallError(format!("{} ({note})", e.0)),
        None => e,
    }
}

/// Runs the FMI 2.0 call `$fmi2` or the FMI 3.0 call `$fmi3` on `$self`'s instance (bound to
/// `$i`; an FMI 3.0 instance's log messages heard under its key), for its success.
macro_rules! me_call {
    ($self:expr, |$i:ident| $fmi2:expr, |$j:ident| $fmi3:expr) => {
        match &mut $self.inner {
            Inner::Fmi2($i) => {
                let $i = $i.as_mut();
                $fmi2
                    .map(|_| ())
                    .map_err(|e| quoting_log(&$self.log, CallError::from(e)))
            }
            Inner::Fmi3($j) => {
                let $j = $j.as_mut();
                crate::logging::speaking(&$self.log, || $fmi3)
                    .map(|_| ())
                    .map_err(|e| quoting_log(&$self.log, CallError::from(e)))
            }
        }
    };
}

/// A call of the same name and arguments in both versions.
macro_rules! me_same {
    ($self:expr, |$i:ident| $call:expr) => {
        me_call!($self, |$i| $call, |$i| $call)
    };
}

/// An error for a call that reported success with `false` (event indicators not computed).
fn discarded(call: &str) -> CallError {
    CallError(format!(
        "{call} returned Discard (the indicators could not be computed)"
    ))
}

impl MeInstance {
    /// `fmi2Reset` / `fmi3Reset`: the instance back to the state right after instantiation
    /// (FMI 2.0 §2.1.6, FMI 3.0 §2.3.1), so that fixed parameters can be set again before a
    /// new initialisation.
    pub fn reset(&mut self) -> Result<(), CallError> {
        me_call!(self, |i| fmi::fmi2::instance::Common::reset(i), |i| {
            fmi::fmi3::Common::reset(i)
        })
    }
}

impl ModelExchangeCalls for MeInstance {
    fn name(&self) -> String {
        self.name.clone()
    }

    fn is_fmi3(&self) -> bool {
        matches!(self.inner, Inner::Fmi3(_))
    }

    fn setup_experiment(&mut self, e: Experiment) -> Result<(), CallError> {
        me_call!(
            self,
            |i| i.setup_experiment(e.tolerance, e.start, e.stop),
            |i| {
                let _ = i;
                Ok::<(), fmi::fmi3::Fmi3Error>(())
            }
        )
    }

    fn set(&mut self, t: VarType, vrs: &[u32], values: &[f64]) -> Result<(), CallError> {
        me_call!(self, |i| set2(i, t, vrs, values, &mut self.ints), |i| set3(
            i,
            t,
            vrs,
            values,
            &mut self.scratch
        ))
    }

    fn get(&mut self, t: VarType, vrs: &[u32], out: &mut [f64]) -> Result<(), CallError> {
        me_call!(self, |i| get2(i, t, vrs, out, &mut self.ints), |i| get3(
            i,
            t,
            vrs,
            out,
            &mut self.scratch
        ))
    }

    fn enter_initialization_mode(&mut self, e: Experiment) -> Result<(), CallError> {
        me_call!(self, |i| i.enter_initialization_mode(), |i| i
            .enter_initialization_mode(e.tolerance, e.start, e.stop))
    }

    fn exit_initialization_mode(&mut self) -> Result<(), CallError> {
        me_call!(self, |i| i.exit_initialization_mode(), |i| i
            .exit_initialization_mode())
    }

    fn enter_event_mode(&mut self) -> Result<(), CallError> {
        me_same!(self, |i| i.enter_event_mode())
    }

    fn update_discrete_states(&mut self) -> Result<EventUpdate, CallError> {
        let mut flags = EventFlags::default();
        me_call!(self, |i| i.new_discrete_states(&mut flags), |i| {
            fmi::fmi3::Common::update_discrete_states(i, &mut flags)
        })?;
        Ok(EventUpdate {
            discrete_states_need_update: flags.discrete_states_need_update,
            terminate_simulation: flags.terminate_simulation,
            nominals_changed: flags.nominals_of_continuous_states_changed,
            values_changed: flags.values_of_continuous_states_changed,
            next_event_time: flags.next_event_time,
        })
    }

    fn enter_continuous_time_mode(&mut self) -> Result<(), CallError> {
        me_same!(self, |i| i.enter_continuous_time_mode())
    }

    fn completed_integrator_step(&mut self) -> Result<(bool, bool), CallError> {
        let (mut enter, mut terminate) = (false, false);
        me_same!(self, |i| i.completed_integrator_step(
            true,
            &mut enter,
            &mut terminate
        ))?;
        Ok((enter, terminate))
    }

    fn set_time(&mut self, time: f64) -> Result<(), CallError> {
        me_same!(self, |i| i.set_time(time))
    }

    fn set_continuous_states(&mut self, x: &[f64]) -> Result<(), CallError> {
        me_same!(self, |i| i.set_continuous_states(x))
    }

    fn get_continuous_states(&mut self, x: &mut [f64]) -> Result<(), CallError> {
        me_same!(self, |i| i.get_continuous_states(x))
    }

    fn get_nominals(&mut self, nominals: &mut [f64]) -> Result<(), CallError> {
        me_same!(self, |i| i.get_nominals_of_continuous_states(nominals))
    }

    fn get_derivatives(&mut self, dx: &mut [f64]) -> Result<(), CallError> {
        me_call!(
            self,
            |i| fmi::fmi2::instance::ModelExchange::get_derivatives(i, dx),
            |i| fmi::fmi3::ModelExchange::get_continuous_state_derivatives(i, dx)
        )
    }

    fn get_event_indicators(&mut self, z: &mut [f64]) -> Result<(), CallError> {
        let fmi3 = self.is_fmi3();
        let mut computed = true;
        me_call!(
            self,
            |i| {
                fmi::fmi2::instance::ModelExchange::get_event_indicators(i, z).map(|c| computed = c)
            },
            |i| fmi::fmi3::ModelExchange::get_event_indicators(i, z).map(|c| computed = c)
        )?;
        if computed {
            Ok(())
        } else {
            Err(discarded(if fmi3 {
                "fmi3GetEventIndicators"
            } else {
                "fmi2GetEventIndicators"
            }))
        }
    }

    fn directional_derivative(&mut self, seed: &[f64], out: &mut [f64]) -> Result<bool, CallError> {
        let d = &self.description;
        if !d.directional_derivatives || d.derivatives.len() != seed.len() {
            return Ok(false);
        }
        match &mut self.inner {
            Inner::Fmi2(i) => {
                fmi::fmi2::instance::Common::get_directional_derivative(
                    i.as_ref(),
                    &d.derivatives,
                    &d.state_references,
                    seed,
                    out,
                )?;
                Ok(true)
            }
            Inner::Fmi3(_) => Ok(false),
        }
    }

    fn terminate(&mut self) -> Result<(), CallError> {
        me_call!(self, |i| fmi::fmi2::instance::Common::terminate(i), |i| {
            fmi::fmi3::Common::terminate(i)
        })
    }
}
