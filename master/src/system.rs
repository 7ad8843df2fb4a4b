//! A co-simulation system: its description ([`SystemDescription`], TOML or SSP) with every
//! FMU loaded, every start value checked and the rest compiled to an index [`Plan`]; and
//! editing it by name ([`System::set_start_value`], [`System::set_fmu`]).
//!
//! ```toml
//! name = "crane with sensor"
//! start_time = 0.0
//! stop_time = 10.0
//! step_size = 0.05
//! algorithm = "gauss-seidel"     # or "jacobi"
//! connections = ["crane.x -> sensor.u[1]", "crane.theta -> sensor.u[2]"]
//! record = ["crane.x", "sensor.y[1]"]   # default: every output of every instance
//!
//! [[instance]]
//! name = "crane"
//! fmu = "../build/fmus/GantryCrane.fmu"  # relative to this file
//! parameters = { x0 = 0.2 }
//!
//! [[instance]]
//! name = "sensor"
//! fmu = "../build/fmus/Sensor2.fmu"
//! step_multiple = 1                       # multirate: steps every N base steps
//!
//! [[instance]]                            # Model Exchange: the master integrates it
//! name = "filter"                         # (an FMU with Model Exchange only needs no
//! fmu = "../build/fmus/OpAmpFilter.fmu"   # `interface`; one with both runs as
//! interface = "me"                        # Co-Simulation unless it says "me")
//! solver = "dopri5"                       # or "rodas4" (stiff), "rodas3", "shampine4"
//! tolerance = 1e-6                        # relative (default 1e-6)
//! max_step = 0.01                         # seconds (default: none)
//!
//! [[instance]]                            # a table of recorded signals ([`crate::data`]):
//! name = "rig"                            # its columns are outputs (`rig.force`, with
//! data = "rig.csv"                        # `rig.force.valid` and `rig.force.held`)
//! interpolation = "hold"                  # or "linear"
//! ```
//!
//! `start_time = "data"` and `stop_time = "data"` (or omitted) take the times from the data
//! instances: the span every table covers.
//!
//! [`System::resolve`] loads every FMU once and checks every name, type and causality,
//! reporting errors that name the instance, the variable and the file. [`System::from_file`]
//! is the one loader: it reads a TOML system file or an SSP archive, by the file's type.

use crate::algorithm::{self, Algorithm};
use crate::coupling::{
    split_variable, unknown, variable_name, Integration, ResolvedInstance, VarRef,
};
use crate::data::DataTable;
use crate::description::{InstanceDescription, InterfaceName, SystemDescription};
use crate::error::SystemError;
use crate::fmu::{Causality, FmuFile, Interface, LoadOptions, VarType, VariableInfo};
use crate::plan::Plan;
use crate::ssp::SspError;
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// A system with every name resolved. Its instances, its plan and the description they were
/// resolved from change together, only through its methods ([`System::set_start_value`],
/// [`System::set_fmu`], [`System::set_algorithm`], [`System::record_nothing`]); they are
/// read through [`System::instances`], [`System::plan`] and [`System::source_description`].
#[derive(Debug, Clone)]
pub struct System {
    instances: Vec<ResolvedInstance>,
    /// Connections, records and propagation, compiled to indices.
    plan: Plan,
    /// The stepping algorithm the plan was compiled for and the simulation follows.
    algorithm: Arc<dyn Algorithm>,
    /// The description this system was resolved from, FMU paths as loaded; edits by name
    /// ([`System::set_start_value`], [`System::set_fmu`]) keep it in step.
    source: SystemDescription,
    /// What loading had to assume (an SSP's step size source or default), for the user.
    notes: Vec<String>,
    /// The temporary folder an SSP archive was unpacked into, removed with the last clone
    /// of this system.
    unpacked: Option<Arc<tempfile::TempDir>>,
    /// How its FMUs were loaded (limits, temporary folder); [`System::set_fmu`] loads the
    /// same way.
    load: LoadOptions,
}

/// A value given to a parameter or an unconnected input before initialisation, as a system
/// file's `parameters` table gives it: a Real takes a `Real` or an `Integer`, an Integer or
/// Enumeration an `Integer` (that fits 32 bits), a Boolean a `Boolean`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum StartValue {
    Real(f64),
    Integer(i64),
    Boolean(bool),
}

impl From<f64> for StartValue {
    fn from(v: f64) -> Self {
        Self::Real(v)
    }
}

impl From<i64> for StartValue {
    fn from(v: i64) -> Self {
        Self::Integer(v)
    }
}

impl From<i32> for StartValue {
    fn from(v: i32) -> Self {
        Self::Integer(i64::from(v))
    }
}

impl From<u32> for StartValue {
    fn from(v: u32) -> Self {
        Self::Integer(i64::from(v))
    }
}

impl From<bool> for StartValue {
    fn from(v: bool) -> Self {
        Self::Boolean(v)
    }
}

impl From<StartValue> for toml::Value {
    fn from(v: StartValue) -> Self {
        match v {
            StartValue::Real(x) => toml::Value::Float(x),
            StartValue::Integer(i) => toml::Value::Integer(i),
            StartValue::Boolean(b) => toml::Value::Boolean(b),
        }
    }
}

impl System {
    /// Resolves `description`, loading FMUs relative to `base_dir`.
    pub fn resolve(description: &SystemDescription, base_dir: &Path) -> Result<Self, SystemError> {
        Self::resolve_loading(description, base_dir, &LoadOptions::default())
    }

    /// [`System::resolve`], loading the FMUs with `options` (the loader's limits, its
    /// temporary folder).
    pub fn resolve_loading(
        description: &SystemDescription,
        base_dir: &Path,
        options: &LoadOptions,
    ) -> Result<Self, SystemError> {
        let algorithm = algorithm::named(description.algorithm);
        Self::resolve_with(
            description,
            base_dir,
            &mut HashMap::new(),
            options,
            algorithm,
        )
    }

    /// [`System::resolve`], taking FMUs from `loaded` (by path) before loading them.
    fn resolve_with(
        description: &SystemDescription,
        base_dir: &Path,
        loaded: &mut HashMap<(PathBuf, Interface), Arc<FmuFile>>,
        options: &LoadOptions,
        algorithm: Arc<dyn Algorithm>,
    ) -> Result<Self, SystemError> {
        let tables = read_tables(description, base_dir, options.limits.max_unpacked)?;
        let d = &with_times_from_data(description, &tables)?;
        if !(d.step_size.is_finite() && d.step_size > 0.0) {
            return Err(SystemError::Invalid(format!(
                "step_size must be > 0, got {}",
                d.step_size
            )));
        }
        if !(d.stop_time.is_finite() && d.start_time.is_finite() && d.stop_time >= d.start_time) {
            return Err(SystemError::Invalid(format!(
                "stop_time ({}) must be finite and not before start_time ({})",
                d.stop_time, d.start_time
            )));
        }
        if d.instances.is_empty() {
            return Err(SystemError::Invalid("no [[instance]]".into()));
        }
        let mut instances = Vec::new();
        let mut index_of: HashMap<&str, usize> = HashMap::new();
        for (spec, table) in d.instances.iter().zip(tables) {
            if spec.name.is_empty() || spec.name.contains('.') {
                return Err(SystemError::Invalid(format!(
                    "instance name `{}` must be non-empty and contain no '.'",
                    spec.name
                )));
            }
            if index_of
                .insert(spec.name.as_str(), instances.len())
                .is_some()
            {
                return Err(SystemError::Invalid(format!(
                    "two instances are called `{}`",
                    spec.name
                )));
            }
            if spec.step_multiple == 0 {
                return Err(SystemError::Invalid(format!(
                    "instance `{}`: step_multiple must be >= 1",
                    spec.name
                )));
            }
            if let Some(table) = table {
                table.check_range(d.start_time, d.stop_time)?;
                instances.push(ResolvedInstance {
                    name: spec.name.clone(),
                    fmu: Arc::new(FmuFile::table(&table)),
                    start_values: Vec::new(),
                    step_multiple: spec.step_multiple,
                    logging: spec.logging,
                    data: Some(Arc::new(table)),
                    integration: Integration::default(),
                });
                continue;
            }
            let path = base_dir.join(&spec.fmu);
            let asked = spec.interface.map(|i| match i {
                InterfaceName::ModelExchange => Interface::ModelExchange,
                InterfaceName::CoSimulation => Interface::CoSimulation,
            });
            let cached = match asked {
                Some(i) => loaded.get(&(path.clone(), i)),
                None => loaded
                    .get(&(path.clone(), Interface::CoSimulation))
                    .or_else(|| loaded.get(&(path.clone(), Interface::ModelExchange))),
            };
            let fmu = match cached {
                Some(f) => f.clone(),
                None => {
                    let f = Arc::new(FmuFile::open_preferring(&path, options, asked)?);
                    loaded.insert((path.clone(), f.interface), f.clone());
                    f
                }
            };
            let integration = integration(spec, &fmu)?;
            let mut start_values = Vec::new();
            for (name, value) in &spec.parameters {
                let fail = |reason: String| SystemError::Parameter {
                    instance: spec.name.clone(),
                    variable: name.clone(),
                    file: fmu.path.clone(),
                    reason,
                };
                // An FMI 3.0 array named whole takes a TOML array of its elements (row-major,
                // flat or nested).
                if let (None, Some(array)) = (fmu.index_of(name), fmu.array(name)) {
                    let mut values = Vec::new();
                    crate::ssp::flatten(value, &mut values);
                    if values.len() != array.elements.len() {
                        return Err(fail(format!(
                            "is an array of {} elements; give an array of as many values (row-major), or set elements (`{}`)",
                            array.elements.len(),
                            array.elements.first().map_or(name.as_str(), |&e| fmu.variables[e].head.name.as_str())
                        )));
                    }
                    for (&index, v) in array.elements.iter().zip(values) {
                        start_values.push((
                            index,
                            start_number(&fmu.variables[index], &v).map_err(fail)?,
                        ));
                    }
                    continue;
                }
                let Some(index) = fmu.index_of(name) else {
                    return Err(unknown(&spec.name, name, &fmu));
                };
                let number = start_number(&fmu.variables[index], value).map_err(fail)?;
                start_values.push((index, number));
            }
            instances.push(ResolvedInstance {
                name: spec.name.clone(),
                fmu,
                start_values,
                step_multiple: spec.step_multiple,
                logging: spec.logging,
                data: None,
                integration,
            });
        }
        let plan = Plan::compile(d, &instances, algorithm.as_ref())?;
        for inst in &instances {
            for (index, _) in &inst.start_values {
                check_not_connected(&plan, &instances, inst, *index)?;
            }
        }
        let system = Self {
            instances,
            plan,
            algorithm,
            source: SystemDescription {
                instances: d
                    .instances
                    .iter()
                    .map(|i| match &i.data {
                        Some(data) => InstanceDescription {
                            data: Some(base_dir.join(data)),
                            ..i.clone()
                        },
                        None => InstanceDescription {
                            fmu: base_dir.join(&i.fmu),
                            ..i.clone()
                        },
                    })
                    .collect(),
                ..d.clone()
            },
            notes: Vec::new(),
            unpacked: None,
            load: options.clone(),
        };
        Ok(system)
    }

    /// Reads and resolves a system file, by its type: an SSP archive (`.ssp`, SSP 1.0 or 2.0,
    /// whose FMUs are unpacked into a temporary folder removed with the system) or TOML
    /// (anything else; FMU paths relative to the file). What the SSP import had to assume
    /// (where the step size came from) is in [`System::notes`].
    pub fn from_file(path: &Path) -> Result<Self, SystemError> {
        Self::from_file_unpacking(path, None)
    }

    /// [`System::from_file`], unpacking an SSP archive's FMUs into `unpack_to` (kept) instead
    /// of a temporary folder when it is given.
    pub fn from_file_unpacking(path: &Path, unpack_to: Option<&Path>) -> Result<Self, SystemError> {
        Self::from_file_loading(path, unpack_to, &LoadOptions::default())
    }

    /// [`System::from_file_unpacking`], loading the FMUs with `options` (the loader's limits,
    /// its temporary folder). The limits bound the system file and an SSP archive too: the
    /// system file and `SystemStructure.ssd` as `max_model_description` bounds a model
    /// description, the FMUs an SSP holds as `max_unpacked` and `max_entries` bound an FMU
    /// (see [`crate::ssp::import_with`]).
    pub fn from_file_loading(
        path: &Path,
        unpack_to: Option<&Path>,
        options: &LoadOptions,
    ) -> Result<Self, SystemError> {
        if path.extension().is_some_and(|e| e == "ssp") {
            let (dir, temporary) = match unpack_to {
                Some(dir) => (dir.to_path_buf(), None),
                None => {
                    let t = tempfile::Builder::new()
                        .prefix("spurio-ssp-")
                        .tempdir()
                        .map_err(|e| {
                            SystemError::Ssp(crate::ssp::SspError::File {
                                file: path.to_path_buf(),
                                reason: format!("cannot create a temporary folder: {e}"),
                            })
                        })?;
                    (t.path().to_path_buf(), Some(Arc::new(t)))
                }
            };
            let imported = crate::ssp::import_with(path, &dir, &options.limits)?;
            let mut system =
                Self::resolve_loading(&imported.description, &dir, options).map_err(|e| {
                    SystemError::InArchive {
                        ssp: path.to_path_buf(),
                        unpacked: dir.clone(),
                        error: Box::new(e),
                    }
                })?;
            system.notes = imported.notes;
            system.unpacked = temporary;
            return Ok(system);
        }
        let description =
            SystemDescription::read_at_most(path, options.limits.max_model_description)?;
        let base = path.parent().unwrap_or(Path::new("."));
        Self::resolve_loading(&description, base, options)
    }

    /// The description this system was resolved from (FMU paths as loaded, start values as
    /// set by name since).
    pub fn source_description(&self) -> &SystemDescription {
        &self.source
    }

    /// Writes this system as an SSP archive (SSP `version`) with its FMUs (see
    /// [`crate::ssp::export`]).
    pub fn export_ssp(
        &self,
        target: &Path,
        version: crate::ssp::SspVersion,
    ) -> Result<(), SspError> {
        if let Some(data) = self.instances.iter().find(|i| i.data.is_some()) {
            return Err(SspError::File {
                file: target.to_path_buf(),
                reason: format!(
                    "instance `{}` is a data instance ({}): SSP has no element for a table of \
                     recorded signals, so this system cannot be exported; replace it by an FMU",
                    data.name,
                    data.fmu.path.display()
                ),
            });
        }
        let fmus: Vec<&FmuFile> = self.instances.iter().map(|i| i.fmu.as_ref()).collect();
        // An instance integrated by the master is marked so in the SSD, also when its FMU
        // offers Model Exchange only and the system file does not say so.
        let mut source = self.source.clone();
        for (written, inst) in source.instances.iter_mut().zip(&self.instances) {
            if inst.fmu.interface == Interface::ModelExchange {
                written.interface = Some(InterfaceName::ModelExchange);
            }
        }
        crate::ssp::export(&source, &fmus, target, version)
    }

    /// The instance called `name`.
    pub fn instance(&self, name: &str) -> Result<&ResolvedInstance, SystemError> {
        self.instance_index(name).map(|i| &self.instances[i])
    }

    /// The index of the instance called `name`, or an error listing the instances there are.
    fn instance_index(&self, name: &str) -> Result<usize, SystemError> {
        self.instances
            .iter()
            .position(|i| i.name == name)
            .ok_or_else(|| SystemError::UnknownInstance {
                instance: name.to_string(),
                known: self
                    .instances
                    .iter()
                    .map(|i| i.name.as_str())
                    .collect::<Vec<_>>()
                    .join(", "),
            })
    }

    /// The variable called `qualified` (`"instance.variable"`).
    pub fn var_ref(&self, qualified: &str) -> Result<VarRef, SystemError> {
        let Some((instance, variable)) = split_variable(qualified) else {
            return Err(SystemError::Invalid(format!(
                "`{qualified}` is not of the form instance.variable"
            )));
        };
        let i = self.instance_index(instance)?;
        let fmu = &self.instances[i].fmu;
        let v = fmu
            .index_of(variable)
            .ok_or_else(|| unknown(instance, variable, fmu))?;
        Ok((i, v))
    }

    /// What the model description says of `qualified` (`"crane.x"`).
    pub fn variable(&self, qualified: &str) -> Result<&VariableInfo, SystemError> {
        let (i, v) = self.var_ref(qualified)?;
        Ok(&self.instances[i].fmu.variables[v])
    }

    /// The unit of `qualified` (`"crane.x"` → `Some("m")`), if its FMU declares one.
    pub fn unit(&self, qualified: &str) -> Result<Option<&str>, SystemError> {
        Ok(self.variable(qualified)?.unit.as_deref())
    }

    /// The description of `qualified` in its FMU's model description, if any.
    pub fn description(&self, qualified: &str) -> Result<Option<&str>, SystemError> {
        Ok(self.variable(qualified)?.description.as_deref())
    }

    /// The value `qualified` starts with: the one this system sets, else the FMU's start
    /// value (`None` if neither exists).
    pub fn start_value(&self, qualified: &str) -> Result<Option<f64>, SystemError> {
        let (i, v) = self.var_ref(qualified)?;
        let inst = &self.instances[i];
        Ok(inst
            .start_values
            .iter()
            .rev()
            .find(|(index, _)| *index == v)
            .map(|(_, value)| *value)
            .or(inst.fmu.variables[v].start))
    }

    /// Sets `qualified` (`"plant.seed"`) to `value` before initialisation, with the checks of
    /// a `parameters` entry of the system file (a parameter or an input, of a matching type);
    /// replaces a value set before.
    pub fn set_start_value(
        &mut self,
        qualified: &str,
        value: impl Into<StartValue>,
    ) -> Result<(), SystemError> {
        let value = value.into();
        let number = self.check_start_value(qualified, value)?;
        let value = toml::Value::from(value);
        let (i, v) = self.var_ref(qualified)?;
        let inst = &mut self.instances[i];
        let name = inst.fmu.variables[v].head.name.clone();
        inst.start_values.retain(|(index, _)| *index != v);
        inst.start_values.push((v, number));
        if let Some(source) = self.source.instances.get_mut(i) {
            source.parameters.insert(name, value);
        }
        Ok(())
    }

    /// The number the engine would set for `qualified` = `value`, with the checks of
    /// [`System::set_start_value`] (a parameter or an unconnected input, of a matching type),
    /// without setting it.
    pub fn check_start_value(
        &self,
        qualified: &str,
        value: StartValue,
    ) -> Result<f64, SystemError> {
        let (i, v) = self.var_ref(qualified)?;
        let inst = &self.instances[i];
        let variable = &inst.fmu.variables[v];
        let number = start_number(variable, &toml::Value::from(value)).map_err(|reason| {
            SystemError::Parameter {
                instance: inst.name.clone(),
                variable: variable.head.name.clone(),
                file: inst.fmu.path.clone(),
                reason,
            }
        })?;
        check_not_connected(&self.plan, &self.instances, inst, v)?;
        Ok(number)
    }

    /// Runs `instance` from another FMU file (`fmu`, a path as given, not relative to the
    /// system file): its start values, connections and recorded variables are resolved again
    /// by name against the new FMU, with the same checks as when the system was loaded. The
    /// start values are those of the description and of [`System::set_start_value`]. On error
    /// the system is left as it was.
    pub fn set_fmu(&mut self, instance: &str, fmu: &Path) -> Result<(), SystemError> {
        let i = self.instance_index(instance)?;
        let mut description = self.source.clone();
        description.instances[i].fmu = fmu.to_path_buf();
        description.instances[i].data = None;
        description.instances[i].interpolation = None;
        let mut loaded: HashMap<(PathBuf, Interface), Arc<FmuFile>> = self
            .instances
            .iter()
            .map(|inst| {
                (
                    (inst.fmu.path.clone(), inst.fmu.interface),
                    inst.fmu.clone(),
                )
            })
            .collect();
        let mut edited = Self::resolve_with(
            &description,
            Path::new(""),
            &mut loaded,
            &self.load,
            self.algorithm.clone(),
        )?;
        edited.notes = std::mem::take(&mut self.notes);
        edited.unpacked = self.unpacked.take();
        *self = edited;
        Ok(())
    }

    /// Records nothing: after a step the engine reads only the outputs that feed
    /// connections, and an observer receives rows without values (`spurio run
    /// --no-record`). Editing the system by name ([`System::set_fmu`]) records its
    /// variables again.
    pub fn record_nothing(&mut self) -> Result<(), SystemError> {
        self.plan =
            self.plan
                .without_records(&self.source, &self.instances, self.algorithm.as_ref())?;
        Ok(())
    }

    /// Steps with `algorithm` from now on: the plan is compiled again for it (its propagation
    /// order, its records), with the connections and records of the description. On error
    /// the system is left as it was.
    pub fn set_algorithm(&mut self, algorithm: Arc<dyn Algorithm>) -> Result<(), SystemError> {
        self.plan = Plan::compile(&self.source, &self.instances, algorithm.as_ref())?;
        self.algorithm = algorithm;
        Ok(())
    }

    /// `instance.variable`.
    pub fn variable_name(&self, r: VarRef) -> String {
        variable_name(&self.instances, r)
    }

    /// Its name.
    pub fn name(&self) -> &str {
        &self.source.name
    }

    /// The time the simulation starts at.
    pub fn start_time(&self) -> f64 {
        self.source.start_time
    }

    /// The time the simulation stops at.
    pub fn stop_time(&self) -> f64 {
        self.source.stop_time
    }

    /// The base communication step size h.
    pub fn step_size(&self) -> f64 {
        self.source.step_size
    }

    /// The stepping algorithm.
    pub fn algorithm(&self) -> &Arc<dyn Algorithm> {
        &self.algorithm
    }

    /// The instances, in the order of the description, each with its FMU and start values.
    pub fn instances(&self) -> &[ResolvedInstance] {
        &self.instances
    }

    /// Connections, records and propagation, compiled to indices.
    pub fn plan(&self) -> &Plan {
        &self.plan
    }

    /// What loading had to assume (an SSP's step size source or default), for the user.
    pub fn notes(&self) -> &[String] {
        &self.notes
    }
}

/// How instance `spec` of `fmu` is integrated: its `solver`, `tolerance` and `max_step` (the
/// system file checked them), which only a Model Exchange instance takes.
fn integration(spec: &InstanceDescription, fmu: &FmuFile) -> Result<Integration, SystemError> {
    if fmu.interface == Interface::CoSimulation && spec.has_solver_settings() {
        return Err(SystemError::Invalid(format!(
            "instance `{}` ({}) runs as Co-Simulation (its FMU steps itself), so `solver`, \
             `tolerance` and `max_step` do not apply; write `interface = \"me\"` to have the \
             master integrate it as Model Exchange",
            spec.name,
            fmu.path.display()
        )));
    }
    let default = Integration::default();
    Ok(Integration {
        method: spec.solver.unwrap_or(default.method),
        tolerance: spec.tolerance.unwrap_or(default.tolerance),
        max_step: spec.max_step.or(default.max_step),
    })
}

/// The table of every data instance of `d` (`None` for an FMU instance), read relative to
/// `base_dir` (at most `max_bytes` each) and checked whole. An instance names exactly one of `fmu` and `data`; a data
/// instance takes no parameters and no step multiple, and only it takes `interpolation`.
fn read_tables(
    d: &SystemDescription,
    base_dir: &Path,
    max_bytes: u64,
) -> Result<Vec<Option<DataTable>>, SystemError> {
    d.instances
        .iter()
        .map(|spec| {
            let invalid = |reason: &str| {
                Err(SystemError::Invalid(format!(
                    "instance `{}`: {reason}",
                    spec.name
                )))
            };
            let has_fmu = !spec.fmu.as_os_str().is_empty();
            match &spec.data {
                None if !has_fmu => invalid("give `fmu = \"…\"` or `data = \"…\"`"),
                Some(_) if spec.interface.is_some() || spec.has_solver_settings() => invalid(
                    "a data instance is read, not integrated: `interface`, `solver`, `tolerance` and `max_step` do not apply",
                ),
                None if spec.interpolation.is_some() => {
                    invalid("`interpolation` is for a data instance (`data = \"….csv\"`)")
                }
                None => Ok(None),
                Some(_) if has_fmu => invalid("give `fmu` or `data`, not both"),
                Some(_) if !spec.parameters.is_empty() => {
                    invalid("a data instance takes no parameters (its columns are its outputs)")
                }
                Some(_) if spec.step_multiple != 1 => invalid(
                    "a data instance is read at every communication point; step_multiple does not apply",
                ),
                Some(data) => Ok(Some(DataTable::read(
                    &base_dir.join(data),
                    spec.interpolation.unwrap_or_default(),
                    max_bytes,
                )?)),
            }
        })
        .collect()
}

/// `d` with a `start_time` or `stop_time` of `"data"` (NaN) taken from its data tables: the
/// latest first sample, the earliest last sample (the span every table covers).
fn with_times_from_data(
    d: &SystemDescription,
    tables: &[Option<DataTable>],
) -> Result<SystemDescription, SystemError> {
    let mut d = d.clone();
    let given = tables.iter().flatten();
    for (time, what, from) in [
        (
            &mut d.start_time,
            "start_time",
            given.clone().map(DataTable::start).reduce(f64::max),
        ),
        (
            &mut d.stop_time,
            "stop_time",
            given.clone().map(DataTable::end).reduce(f64::min),
        ),
    ] {
        if time.is_nan() {
            *time = from.ok_or_else(|| {
                SystemError::Invalid(format!(
                    "{what} is not given (or is \"data\") and no instance is a data instance to take it from"
                ))
            })?;
        }
    }
    Ok(d)
}

/// A value given to an input that a connection drives would be overwritten at the first
/// communication point: refused, naming the input and the connection.
fn check_not_connected(
    plan: &Plan,
    instances: &[ResolvedInstance],
    inst: &ResolvedInstance,
    index: usize,
) -> Result<(), SystemError> {
    let Some(i) = instances.iter().position(|x| x.name == inst.name) else {
        return Ok(());
    };
    match plan.connections.iter().find(|c| c.to == (i, index)) {
        Some(c) => Err(SystemError::Parameter {
            instance: inst.name.clone(),
            variable: inst.fmu.variables[index].head.name.clone(),
            file: inst.fmu.path.clone(),
            reason: format!(
                "is an input driven by the connection `{} -> {}`, so a value given to it \
                 would be ignored; remove the value or the connection",
                variable_name(instances, c.from),
                variable_name(instances, c.to)
            ),
        }),
        None => Ok(()),
    }
}

/// `value` as the f64 the engine sets for variable `v`, checked as a `parameters` entry is:
/// only parameters and inputs take values, of their own type (a Real or Float32 takes an
/// integer too; an integer type only integers in its range).
fn start_number(v: &VariableInfo, value: &toml::Value) -> Result<f64, String> {
    if !matches!(v.head.causality, Causality::Parameter | Causality::Input) {
        return Err(format!(
            "has causality {:?}: only parameters and inputs can be given values",
            v.head.causality
        ));
    }
    let range = |t: VarType| -> (f64, f64) {
        match t {
            VarType::Int8 => (i8::MIN.into(), i8::MAX.into()),
            VarType::UInt8 => (0.0, u8::MAX.into()),
            VarType::Int16 => (i16::MIN.into(), i16::MAX.into()),
            VarType::UInt16 => (0.0, u16::MAX.into()),
            VarType::UInt32 => (0.0, u32::MAX.into()),
            VarType::UInt64 => (0.0, u64::MAX as f64),
            _ => (i64::MIN as f64, i64::MAX as f64),
        }
    };
    match (v.head.var_type, value.clone()) {
        (VarType::Real | VarType::Float32, toml::Value::Float(x)) => Ok(x),
        (VarType::Real | VarType::Float32, toml::Value::Integer(i)) => Ok(i as f64),
        (VarType::Integer | VarType::Enumeration, toml::Value::Integer(i)) => i32::try_from(i)
            .map(f64::from)
            .map_err(|_| format!("{i} does not fit an Integer")),
        (t, toml::Value::Integer(i)) if t.is_integer() => {
            let (lo, hi) = range(t);
            let x = i as f64;
            if (lo..=hi).contains(&x) {
                Ok(x)
            } else {
                Err(format!("{i} does not fit an {}", t.name_3()))
            }
        }
        (VarType::Boolean, toml::Value::Boolean(b)) => Ok(f64::from(u8::from(b))),
        (VarType::String, v) => Err(format!(
            "is of type String, and only Real, Integer, Enumeration and Boolean variables can \
             be given values (the value was `{v}`)"
        )),
        (t @ (VarType::Binary | VarType::Clock), v) => Err(format!(
            "is of type {}, and only numbers and Booleans can be given values (the value was `{v}`)",
            t.name_3()
        )),
        (t, v) => Err(format!(
            "is of type {t:?}, which takes {}; the value `{v}` is not one",
            match t {
                VarType::Real | VarType::Float32 => "a number (`1.5` or `2`)",
                VarType::Boolean => "`true` or `false`",
                _ => "an integer (`3`)",
            }
        )),
    }
}
