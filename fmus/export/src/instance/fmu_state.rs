//! FMU states: a copy of an instance's [`Core`] (`fmi*GetFMUstate`, `fmi*SetFMUstate`) and
//! its bytes (`fmi*SerializeFMUstate`, `fmi*DeSerializeFMUstate`).
//!
//! **A serialized state is checked before it is accepted**: format version, model identifier,
//! GUID, value count and types, a state-machine state that a saved state can carry
//! ([`ModelState::can_be_saved`]), finite time and stop time, finite Reals within their declared
//! bounds, then the model's own part ([`crate::model::FmuModel::load_state`] validates what it
//! reads).

use super::common::{Core, Instance};
use super::state::{bits::ME_MODES, ModelState};
use crate::bytes::{ByteReader, ByteWriter, StateFormatError};
use crate::model::{Cause, FmuModel};
use crate::values::Values;
use crate::variables::VariableType;

const STATE_MAGIC: &str = "spurio-fmu-state/2";

impl<M: FmuModel> Instance<M> {
    /// `fmi2GetFMUstate`: a copy of everything that determines the future of the instance.
    pub fn get_state(&self) -> Box<Core<M>> {
        Box::new(self.core.clone())
    }

    /// `fmi2SetFMUstate`.
    pub fn set_state(&mut self, core: &Core<M>) {
        self.core = core.clone();
        self.indicators.invalidate();
        self.jacobian.forget();
    }

    /// `fmi2SerializeFMUstate`: the bytes of a state.
    pub fn serialize(&self, core: &Core<M>) -> Vec<u8> {
        let mut w = ByteWriter::new();
        w.put_str(STATE_MAGIC);
        w.put_str(&self.interface.info.model_identifier);
        w.put_str(&self.interface.info.guid);
        w.put_u64(
            ModelState::ALL
                .iter()
                .position(|s| *s == core.state)
                .unwrap_or(0) as u64,
        );
        w.put_f64(core.time);
        w.put_bool(core.stop_time.is_some());
        w.put_f64(core.stop_time.unwrap_or(0.0));
        w.put_bool(core.inputs_changed);
        w.put_u64(core.values.len() as u64);
        core.values.save(&mut w);
        core.model.save_state(&mut w);
        w.into_bytes()
    }

    /// `fmi2DeSerializeFMUstate`: a state from bytes written by [`Instance::serialize`] of an
    /// instance of the same FMU.
    pub fn deserialize(&self, bytes: &[u8]) -> Result<Box<Core<M>>, StateError> {
        let mut r = ByteReader::new(bytes);
        match r.string() {
            Ok(magic) if magic == STATE_MAGIC => {}
            Ok(magic) if magic.starts_with("spurio-fmu-state/") => {
                return Err(StateError::Version {
                    saved: magic,
                    this: STATE_MAGIC,
                })
            }
            _ => return Err(StateError::NotAState),
        }
        let model = r.string()?;
        if model != self.interface.info.model_identifier {
            return Err(StateError::OtherModel {
                saved: model,
                this: self.interface.info.model_identifier.clone(),
            });
        }
        let guid = r.string()?;
        if guid != self.interface.info.guid {
            return Err(StateError::OtherFmu {
                saved: guid,
                this: self.interface.info.guid.clone(),
            });
        }
        let index = r.u64()?;
        let state = ModelState::from_bits_index(index)
            .filter(|s| s.can_be_saved())
            .filter(|s| {
                let me_only = s.bit() & ME_MODES != 0;
                let cs_only = *s == ModelState::StepComplete;
                !(me_only && !self.model_exchange || cs_only && self.model_exchange)
            })
            .ok_or(StateError::MachineState(index))?;
        let time = r.f64()?;
        if !time.is_finite() {
            return Err(StateError::Time("time", time));
        }
        let has_stop = r.bool()?;
        let stop = r.f64()?;
        if has_stop && (!stop.is_finite() || stop < time - 1e-9 * time.abs().max(1.0)) {
            return Err(StateError::Time("stop time", stop));
        }
        let inputs_changed = r.bool()?;
        let n = r.u64()?;
        if n != self.interface.info.variables.len() as u64 {
            return Err(StateError::ValueCount {
                saved: n,
                variables: self.interface.info.variables.len(),
            });
        }
        let mut values = Values::from_start(&self.interface.info.variables);
        values.load(&mut r)?;
        for (i, v) in self.interface.info.variables.iter().enumerate() {
            let x = match values.variable_type(i) {
                Some(VariableType::Real | VariableType::Integer) => values.number(i),
                _ => continue,
            };
            if !x.is_finite()
                || v.min.is_some_and(|min| x < min)
                || v.max.is_some_and(|max| x > max)
            {
                return Err(StateError::Value {
                    name: v.name.clone(),
                    value: x,
                });
            }
        }
        let mut model = self.core.model.clone();
        model.load_state(&mut r).map_err(StateError::Model)?;
        if r.remaining() != 0 {
            return Err(StateError::LeftOver(r.remaining()));
        }
        Ok(Box::new(Core {
            model,
            values,
            time,
            state,
            stop_time: has_stop.then_some(stop),
            inputs_changed,
        }))
    }
}

/// Why serialized bytes are not a state of this FMU (`fmi2DeSerializeFMUstate`).
#[derive(Debug)]
pub enum StateError {
    /// The bytes do not start with the spurio state header.
    NotAState,
    /// The state was written by another version of the state format.
    Version { saved: String, this: &'static str },
    /// The state belongs to another model.
    OtherModel { saved: String, this: String },
    /// The state belongs to an FMU with another GUID.
    OtherFmu { saved: String, this: String },
    /// The saved state-machine state (its index) is unknown or one no saved state can carry.
    MachineState(u64),
    /// The saved time or stop time is not finite (or the stop time is before the time).
    Time(&'static str, f64),
    /// A saved value is not finite or outside its variable's declared bounds.
    Value { name: String, value: f64 },
    /// The number of saved values is not the number of variables.
    ValueCount { saved: u64, variables: usize },
    /// The bytes are malformed.
    Format(StateFormatError),
    /// The model could not read its part.
    Model(Cause),
    /// Bytes remain after the state.
    LeftOver(usize),
}

impl std::fmt::Display for StateError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::NotAState => write!(f, "the bytes are not a serialized spurio FMU state"),
            Self::Version { saved, this } => write!(
                f,
                "serialized FMU state of format {saved}, this FMU reads {this}"
            ),
            Self::OtherModel { saved, this } => write!(
                f,
                "the state was serialized by model {saved}, this FMU is {this}"
            ),
            Self::OtherFmu { saved, this } => write!(
                f,
                "the state was serialized by an FMU with GUID {saved}, this one is {this}"
            ),
            Self::MachineState(index) => write!(
                f,
                "serialized FMU state: state machine state {index} is not one a saved state can carry ({})",
                ModelState::ALL
                    .iter()
                    .filter(|s| s.can_be_saved())
                    .map(|s| s.to_string())
                    .collect::<Vec<_>>()
                    .join(", ")
            ),
            Self::Time(what, value) => {
                write!(f, "serialized FMU state: its {what} {value} is not valid")
            }
            Self::Value { name, value } => write!(
                f,
                "serialized FMU state: variable `{name}` = {value} is not finite or outside its declared bounds"
            ),
            Self::ValueCount { saved, variables } => write!(
                f,
                "serialized FMU state has {saved} values, the FMU has {variables} variables"
            ),
            Self::Format(e) => write!(f, "{e}"),
            Self::Model(e) => write!(f, "{e}"),
            Self::LeftOver(n) => write!(f, "serialized FMU state has {n} bytes left over"),
        }
    }
}

impl std::error::Error for StateError {}

impl From<StateFormatError> for StateError {
    fn from(e: StateFormatError) -> Self {
        StateError::Format(e)
    }
}
