//! What every FMI front (FMI 2.0 [`crate::ffi`], FMI 3.0 [`crate::fmi3::ffi`]) shares below
//! its C entry points: the slot an instance pointer points to, the guarded call on it (null
//! check, panic catch, allowed-state mask), the value kinds of the typed get/set functions,
//! the FMU-state handling and its serialization, the string conversions and the reading of
//! the variant configuration. A front only maps its C signatures and names onto these.
//!
//! Both versions' status codes are the same integers (`fmi2OK` = `fmi3OK` = 0 … `Fatal` =
//! 4: [`Status::code`]), and their instance and FMU-state handles are both `void*`, so one
//! path serves them.

use crate::description::{Config, ModelInfo, CONFIG_FILE};
use crate::ffi::{guarded, guarded_call, slice, string_arg, CallMarker};
use crate::fmi3::arrays::Layout;
use crate::instance::{Access, Core, Function, Instance};
use crate::model::{Cause, FmuModel};
use crate::types::Status;
use crate::variables::{computed_runs, Value, VariableType};
use std::any::TypeId;
use std::ffi::CString;
use std::os::raw::{c_char, c_int, c_void};
use std::path::Path;
use std::sync::{Arc, Mutex};

/// What every instance of one configuration of a model shares, built once per configuration
/// ([`interface`]): the model description, the access table that get/set calls check values
/// against (value reference = index), the variables a model call may change, and the FMI
/// 3.0 arrays over the table.
#[derive(Debug)]
pub struct Interface {
    /// The model description.
    pub info: ModelInfo,
    /// How each variable may be accessed, by value reference.
    pub access: Vec<Access>,
    /// The variables a model call may write, as runs of indices
    /// ([`crate::variables::computed_runs`]): what is copied before the call and checked for
    /// non-finite values after it (a `memcpy` and a branch-free scan a run). Parameters and
    /// inputs a run spans are copied and scanned too: the model does not change them
    /// (checked in debug builds), and what the master sets is finite.
    pub computed: Vec<std::ops::Range<usize>>,
    /// Whether a String is in a run (the texts are then copied too).
    pub computed_texts: bool,
    /// When the model computes one run of at most [`WINDOW`] values (a scalar filter's
    /// outputs): the [`WINDOW`] consecutive values that hold it, copied and scanned as a fixed
    /// block instead of the run.
    pub window: Option<Window>,
    /// The FMI 3.0 variables (arrays) over the table.
    pub layout: Layout,
    /// By FMI 3.0 value reference: the scalars it names, for the get/set fast path.
    pub spans: Vec<Span>,
}

/// The number of values of a [`Window`].
pub const WINDOW: usize = 4;

/// [`WINDOW`] consecutive values from `start` that hold the one run of computed values:
/// `lanes[k]` says whether value `start + k` is in the run (the others, parameters or inputs,
/// are copied with it and otherwise ignored).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Window {
    /// The index of the first value.
    pub start: usize,
    /// Which of the values belong to the run.
    pub lanes: [bool; WINDOW],
    /// The lanes as bit masks (all ones in the run, zero outside), for the branch-free scan.
    pub(crate) keep: [u64; WINDOW],
}

impl Window {
    /// The window of `computed` in a table of `len` values: `Some` when `computed` is one
    /// run of at most [`WINDOW`] values and the table holds at least [`WINDOW`].
    pub fn of(computed: &[std::ops::Range<usize>], len: usize) -> Option<Self> {
        let [run] = computed else { return None };
        if run.is_empty() || run.len() > WINDOW || len < WINDOW || run.end > len {
            return None;
        }
        let start = run.start.min(len - WINDOW);
        let lanes = std::array::from_fn(|k| run.contains(&(start + k)));
        Some(Self {
            start,
            lanes,
            keep: lanes.map(|lane| if lane { u64::MAX } else { 0 }),
        })
    }
}

/// The scalars an FMI 3.0 value reference names: `len` consecutive table entries from
/// `first`, of the type whose [`Access::type_bit`] is `type_bit`; value reference 0, `time`,
/// has `len` 0 (read and set apart).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Span {
    /// The table index of the first scalar.
    pub first: u32,
    /// The number of scalars (0 for `time`).
    pub len: u32,
    /// The scalars' type, as its bit.
    pub type_bit: u32,
}

impl Interface {
    /// The interface of `info`.
    pub fn new(info: ModelInfo) -> Self {
        let access: Vec<Access> = info.variables.iter().map(Access::of).collect();
        let layout = Layout::of(&info.variables);
        let computed = computed_runs(&info.variables);
        let computed_texts = computed
            .iter()
            .flat_map(|run| &info.variables[run.clone()])
            .any(|v| v.variable_type() == VariableType::String);
        let time = Span {
            first: 0,
            len: 0,
            type_bit: Access::type_bit(VariableType::Real),
        };
        let spans = std::iter::once(time)
            .chain(layout.variables().iter().map(|v| Span {
                first: v.first as u32,
                len: v.len() as u32,
                type_bit: Access::type_bit(access[v.first].variable_type),
            }))
            .collect();
        Self {
            window: Window::of(&computed, info.variables.len()),
            info,
            access,
            computed,
            computed_texts,
            layout,
            spans,
        }
    }

    /// The number of values the runs of [`Interface::computed`] hold.
    pub fn computed_len(&self) -> usize {
        self.computed.iter().map(|run| run.len()).sum()
    }
}

/// Interfaces built so far in this process, by model type and configuration. Bounded: a
/// process that instantiates more configurations than this rebuilds the oldest.
static INTERFACES: Mutex<Vec<(TypeId, Config, Arc<Interface>)>> = Mutex::new(Vec::new());
const INTERFACES_KEPT: usize = 64;

/// The interface of model `M` for `config`: built by [`FmuModel::describe`] on first use,
/// then shared by every instance of that configuration in the process (so an instance
/// carries no copy of its description, and instantiating needs no XML hashing).
pub fn interface<M: FmuModel>(config: &Config) -> Result<Arc<Interface>, Cause> {
    let key = TypeId::of::<M>();
    let find = |cache: &[(TypeId, Config, Arc<Interface>)]| {
        cache
            .iter()
            .find(|(t, c, _)| *t == key && c == config)
            .map(|(_, _, i)| Arc::clone(i))
    };
    if let Some(found) = find(&INTERFACES.lock().unwrap_or_else(|e| e.into_inner())) {
        return Ok(found);
    }
    // Described outside the lock: a model's `describe` may take a while.
    let built = Arc::new(Interface::new(M::describe(config)?));
    let mut cache = INTERFACES.lock().unwrap_or_else(|e| e.into_inner());
    if let Some(found) = find(&cache) {
        return Ok(found);
    }
    if cache.len() >= INTERFACES_KEPT {
        cache.remove(0);
    }
    cache.push((key, config.clone(), Arc::clone(&built)));
    Ok(built)
}

/// What an instance handle (`fmi2Component`, `fmi3Instance`) points to: the instance, the
/// front's own data `X` (the FMI 3.0 array layout), the FMU states it created and the
/// strings it last returned.
pub struct Slot<M: FmuModel, X = ()> {
    pub(crate) instance: Instance<M>,
    pub(crate) extra: X,
    /// FMU states created by this instance and not freed yet.
    states: Vec<*mut Core<M>>,
    /// Keeps the strings returned by `fmi*GetString` alive until the next call.
    strings: Vec<CString>,
    /// Which thread runs a call on the slot, for the panic hook ([`crate::ffi`]).
    marker: Arc<CallMarker>,
}

impl<M: FmuModel, X> Slot<M, X> {
    /// A slot for `instance` with the front's data.
    pub fn new(instance: Instance<M>, extra: X) -> Self {
        Self {
            instance,
            extra,
            states: Vec::new(),
            strings: Vec::new(),
            marker: CallMarker::registered(),
        }
    }

    /// The front's own data.
    pub fn extra(&self) -> &X {
        &self.extra
    }

    /// The instance.
    pub fn instance(&self) -> &Instance<M> {
        &self.instance
    }

    /// Boxes the slot as an instance handle (and installs the panic hook the calls on it
    /// rely on: [`crate::ffi::guarded_call`]).
    pub fn into_handle(self) -> *mut c_void {
        crate::ffi::install_panic_hook();
        Box::into_raw(Box::new(self)) as *mut c_void
    }

    /// Keeps `texts` as C strings until the next call and writes pointers to them into
    /// `out`.
    ///
    /// # Safety
    /// `out` points to at least `texts.len()` writable slots.
    pub(crate) unsafe fn return_strings(&mut self, texts: &[String], out: *mut *const c_char) {
        self.strings = texts
            .iter()
            .map(|text| CString::new(text.replace('\0', " ")).unwrap_or_default())
            .collect();
        for (i, cs) in self.strings.iter().enumerate() {
            // SAFETY: `out` holds the slots (caller); the strings live in the slot until the
            // next get-string call.
            unsafe { *out.add(i) = cs.as_ptr() };
        }
    }
}

impl<M: FmuModel, X> Drop for Slot<M, X> {
    fn drop(&mut self) {
        CallMarker::unregister(&self.marker);
        for p in self.states.drain(..) {
            // SAFETY: every pointer in `states` came from `Box::into_raw` and is removed from the
            // list when freed, so each is freed exactly once.
            drop(unsafe { Box::from_raw(p) });
        }
    }
}

/// Frees a slot boxed by [`Slot::into_handle`] (`fmi*FreeInstance`).
///
/// # Safety
/// `c` must be NULL or a handle of a `Slot<M, X>` not freed yet.
pub unsafe fn free_slot<M: FmuModel, X>(c: *mut c_void) {
    if c.is_null() {
        return;
    }
    let _ = guarded(|| {
        // SAFETY: `c` came from `Box::into_raw` in `Slot::into_handle`.
        drop(unsafe { Box::from_raw(c as *mut Slot<M, X>) });
    });
}

/// Runs `body` on the slot behind `c` after the null and state checks, catching panics (the
/// instance is then `Fatal`); the status as its C code. Inlined into every entry point: the
/// fixed cost of a call is the null check, the call marker (two stores), the state mask test.
///
/// # Safety
/// `c` must be NULL or a live handle of a `Slot<M, X>` (the master's obligation).
#[inline(always)]
pub unsafe fn with_slot<M: FmuModel, X>(
    c: *mut c_void,
    f: &Function,
    body: impl FnOnce(&mut Slot<M, X>) -> Status,
) -> std::os::raw::c_int {
    if c.is_null() {
        return Status::Error.code();
    }
    let slot = c as *mut Slot<M, X>;
    // SAFETY: `c` is non-null and a live slot (the caller's obligation); the marker lives in
    // its own allocation (the slot's `Arc`), outside the memory the call borrows mutably, as
    // long as the slot, which outlives the call.
    let marker: &CallMarker = unsafe { &*Arc::as_ptr(&(*slot).marker) };
    let result = guarded_call(marker, || {
        // SAFETY: `c` is non-null and a live slot (the caller's obligation); no other reference
        // to the slot is alive during the call.
        let slot = unsafe { &mut *slot };
        if !slot.instance.allows(f) {
            return Status::Error;
        }
        body(slot)
    });
    match result {
        Ok(status) => status.code(),
        // SAFETY: as above; the closure that panicked no longer borrows the slot.
        Err(payload) => unsafe { fatal(slot, f, payload) },
    }
}

/// After a panic in a call `f` on the slot: the instance is `Fatal`, the panic logged.
///
/// # Safety
/// `slot` is a live slot no reference points into.
#[cold]
#[inline(never)]
unsafe fn fatal<M: FmuModel, X>(
    slot: *mut Slot<M, X>,
    f: &Function,
    payload: crate::ffi::Payload,
) -> std::os::raw::c_int {
    let message = crate::ffi::panic_text(payload.as_ref());
    let _ = guarded(|| {
        // SAFETY: the caller's obligation.
        unsafe { &mut *slot }.instance.set_fatal(f, &message)
    });
    Status::Fatal.code()
}

/// The FMI versions, for the functions a [`Kind`] has in each.
pub trait Version {}
/// FMI 2.0.
pub struct Fmi2;
impl Version for Fmi2 {}
/// FMI 3.0.
pub struct Fmi3;
impl Version for Fmi3 {}

/// A kind of value exchanged through the typed `fmi*Get*`/`fmi*Set*` functions of FMI version
/// `V`: its C type, its functions and how a value crosses the boundary.
pub trait Kind<V: Version> {
    /// The C type of one value.
    type C: Copy;
    /// The variables' type.
    const TYPE: VariableType;
    /// The get function (`fmi2GetReal`, `fmi3GetFloat64`, …).
    const GET: &'static Function;
    /// The set function.
    const SET: &'static Function;
    /// A value of this kind (as [`crate::Values::number`] stores it) as the master reads it.
    fn to_c(number: f64) -> Self::C;
    /// A value the master sets, as a number (see [`crate::Values::numbers`]).
    fn to_number(value: Self::C) -> f64;
}

/// Declares the [`Kind`] of the marker type of `Value::$name` in one FMI version: its C type,
/// its functions (paths to the `Function` constants), how a stored number becomes a C value
/// and how a C value becomes a stored number.
macro_rules! kind {
    ($version:ty, $name:ident, $c:ty, $get:path, $set:path, $to_c:expr, $to_number:expr) => {
        impl Kind<$version> for $name {
            type C = $c;
            const TYPE: VariableType = VariableType::$name;
            const GET: &'static Function = &$get;
            const SET: &'static Function = &$set;
            #[inline]
            fn to_c(number: f64) -> $c {
                let to_c: fn(f64) -> $c = $to_c;
                to_c(number)
            }
            #[inline]
            fn to_number(value: $c) -> f64 {
                let to_number: fn($c) -> f64 = $to_number;
                to_number(value)
            }
        }
    };
}

/// Real values: `fmi2Real`, `fmi3Float64`.
pub struct Real;
/// Integer values: `fmi2Integer`, `fmi3Int32`.
pub struct Integer;
/// Boolean values: `fmi2Boolean` (an `int`), `fmi3Boolean` (a C99 `bool`).
pub struct Boolean;

mod kinds {
    use super::*;
    use crate::fmi3::functions as f3;
    use crate::instance::functions as f2;

    // fmi2Real, fmi2Integer, fmi2Boolean (an int); fmi3Float64, fmi3Int32, fmi3Boolean (a bool)
    kind! { Fmi2, Real, f64, f2::GET_REAL, f2::SET_REAL, |x| x, |v| v }
    kind! { Fmi2, Integer, c_int, f2::GET_INTEGER, f2::SET_INTEGER, |x| x as c_int, f64::from }
    kind! { Fmi2, Boolean, c_int, f2::GET_BOOLEAN, f2::SET_BOOLEAN, |x| c_int::from(x != 0.0), |v| f64::from(u8::from(v != 0)) }
    kind! { Fmi3, Real, f64, f3::GET_REAL, f3::SET_REAL, |x| x, |v| v }
    kind! { Fmi3, Integer, i32, f3::GET_INTEGER, f3::SET_INTEGER, |x| x as i32, f64::from }
    kind! { Fmi3, Boolean, u8, f3::GET_BOOLEAN, f3::SET_BOOLEAN, |x| u8::from(x != 0.0), |v| f64::from(u8::from(v != 0)) }
}

/// Reads the C strings of a set-string call as values; `Err` with the rejection's status
/// if one is NULL.
///
/// # Safety
/// Every pointer in `raw` is NULL or a NUL-terminated string.
pub(crate) unsafe fn string_values<M: FmuModel, X>(
    slot: &Slot<M, X>,
    f: &Function,
    raw: &[*const c_char],
) -> Result<Vec<Value>, Status> {
    raw.iter()
        // SAFETY: the caller's obligation.
        .map(|p| match unsafe { string_arg(*p) } {
            Some(t) => Ok(Value::String(t)),
            None => Err(slot.instance.reject(f, "a string value is NULL")),
        })
        .collect()
}

/// What the resources directory holds of a variant configuration.
pub(crate) enum ConfigFile {
    /// `variant.cfg`, parsed.
    Found(Config),
    /// No `variant.cfg` (the error that says so).
    Missing(std::io::Error),
}

/// The variant configuration in the resources directory `dir`; `Err` with the message if it
/// cannot be read or parsed.
pub(crate) fn read_config(dir: &Path) -> Result<ConfigFile, String> {
    let path = dir.join(CONFIG_FILE);
    match std::fs::read_to_string(&path) {
        Ok(text) => Config::parse(&text)
            .map(ConfigFile::Found)
            .map_err(|e| format!("cannot read {}: {e}", path.display())),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(ConfigFile::Missing(e)),
        Err(e) => Err(format!(
            "cannot read the variant configuration {}: {e}",
            path.display()
        )),
    }
}

/// The FMU-state functions of one front: their `Function`s and how the front spells an FMU
/// state in its messages (`FMUstate`, `FMUState`).
pub struct StateFunctions {
    /// `fmi*GetFMUstate`.
    pub get: &'static Function,
    /// `fmi*SetFMUstate`.
    pub set: &'static Function,
    /// `fmi*FreeFMUstate`.
    pub free: &'static Function,
    /// `fmi*SerializedFMUstateSize`.
    pub size: &'static Function,
    /// `fmi*SerializeFMUstate`.
    pub serialize: &'static Function,
    /// `fmi*DeSerializeFMUstate`.
    pub deserialize: &'static Function,
    /// `FMUstate` or `FMUState`.
    pub noun: &'static str,
}

impl StateFunctions {
    fn unknown(&self) -> String {
        format!(
            "unknown {}: it was not created by this instance or was already freed",
            self.noun
        )
    }
}

/// Emits, in a front's `ffi` module, its six FMU-state functions (`get_fmu_state`,
/// `set_fmu_state`, `free_fmu_state`, `serialized_fmu_state_size`, `serialize_fmu_state`,
/// `deserialize_fmu_state`) over the front's handle, state and byte types and slot data, as
/// the [`StateFunctions`] `STATES` of the `functions` module in scope (every front names its
/// FMU-state `Function`s alike) and `$noun`, the front's spelling of an FMU state.
macro_rules! state_functions {
    ($handle:ty, $state:ty, $byte:ty, $extra:ty, $noun:literal) => {
        /// The FMU-state functions of this front.
        const STATES: $crate::front::StateFunctions = $crate::front::StateFunctions {
            get: &functions::GET_FMU_STATE,
            set: &functions::SET_FMU_STATE,
            free: &functions::FREE_FMU_STATE,
            size: &functions::SERIALIZED_FMU_STATE_SIZE,
            serialize: &functions::SERIALIZE_FMU_STATE,
            deserialize: &functions::DESERIALIZE_FMU_STATE,
            noun: $noun,
        };

        /// `fmi*GetFMUstate`: a new state, or the given one overwritten.
        ///
        /// # Safety
        /// FMI pointer contract.
        pub unsafe fn get_fmu_state<M: FmuModel>(
            c: $handle,
            state: *mut $state,
        ) -> std::os::raw::c_int {
            unsafe { STATES.get::<M, $extra>(c, state) }
        }

        /// `fmi*SetFMUstate`.
        ///
        /// # Safety
        /// FMI pointer contract.
        pub unsafe fn set_fmu_state<M: FmuModel>(c: $handle, state: $state) -> std::os::raw::c_int {
            unsafe { STATES.set::<M, $extra>(c, state) }
        }

        /// `fmi*FreeFMUstate`.
        ///
        /// # Safety
        /// FMI pointer contract.
        pub unsafe fn free_fmu_state<M: FmuModel>(
            c: $handle,
            state: *mut $state,
        ) -> std::os::raw::c_int {
            unsafe { STATES.free::<M, $extra>(c, state) }
        }

        /// `fmi*SerializedFMUstateSize`.
        ///
        /// # Safety
        /// FMI pointer contract.
        pub unsafe fn serialized_fmu_state_size<M: FmuModel>(
            c: $handle,
            state: $state,
            size: *mut usize,
        ) -> std::os::raw::c_int {
            unsafe { STATES.size::<M, $extra>(c, state, size) }
        }

        /// `fmi*SerializeFMUstate`.
        ///
        /// # Safety
        /// FMI pointer contract.
        pub unsafe fn serialize_fmu_state<M: FmuModel>(
            c: $handle,
            state: $state,
            bytes: *mut $byte,
            size: usize,
        ) -> std::os::raw::c_int {
            unsafe { STATES.serialize::<M, $extra>(c, state, bytes as *mut u8, size) }
        }

        /// `fmi*DeSerializeFMUstate`.
        ///
        /// # Safety
        /// FMI pointer contract.
        pub unsafe fn deserialize_fmu_state<M: FmuModel>(
            c: $handle,
            bytes: *const $byte,
            size: usize,
            state: *mut $state,
        ) -> std::os::raw::c_int {
            unsafe { STATES.deserialize::<M, $extra>(c, bytes as *const u8, size, state) }
        }
    };
}
pub(crate) use state_functions;

unsafe fn known_state<'a, M: FmuModel, X>(
    s: &Slot<M, X>,
    state: *mut c_void,
) -> Option<&'a Core<M>> {
    let p = state as *mut Core<M>;
    // SAFETY: only pointers this instance created and has not freed are dereferenced.
    (!p.is_null() && s.states.contains(&p)).then(|| unsafe { &*p })
}

impl StateFunctions {
    /// `fmi*GetFMUstate`: a new state, or the given one overwritten.
    ///
    /// # Safety
    /// FMI pointer contract.
    pub unsafe fn get<M: FmuModel, X>(
        &self,
        c: *mut c_void,
        state: *mut *mut c_void,
    ) -> std::os::raw::c_int {
        let f = self.get;
        unsafe {
            with_slot::<M, X>(c, f, |s| {
                if state.is_null() {
                    return s.instance.reject(f, &format!("{} is NULL", self.noun));
                }
                let existing = *state as *mut Core<M>;
                let snapshot = s.instance.get_state();
                if !existing.is_null() && s.states.contains(&existing) {
                    *existing = *snapshot;
                } else {
                    let p = Box::into_raw(snapshot);
                    s.states.push(p);
                    *state = p as *mut c_void;
                }
                Status::Ok
            })
        }
    }

    /// `fmi*SetFMUstate`.
    ///
    /// # Safety
    /// FMI pointer contract.
    pub unsafe fn set<M: FmuModel, X>(
        &self,
        c: *mut c_void,
        state: *mut c_void,
    ) -> std::os::raw::c_int {
        let f = self.set;
        unsafe {
            with_slot::<M, X>(c, f, |s| match known_state(s, state) {
                Some(core) => {
                    s.instance.set_state(core);
                    Status::Ok
                }
                None => s.instance.reject(f, &self.unknown()),
            })
        }
    }

    /// `fmi*FreeFMUstate`.
    ///
    /// # Safety
    /// FMI pointer contract.
    pub unsafe fn free<M: FmuModel, X>(
        &self,
        c: *mut c_void,
        state: *mut *mut c_void,
    ) -> std::os::raw::c_int {
        let f = self.free;
        unsafe {
            with_slot::<M, X>(c, f, |s| {
                if state.is_null() || (*state).is_null() {
                    return Status::Ok;
                }
                let p = *state as *mut Core<M>;
                match s.states.iter().position(|q| *q == p) {
                    Some(i) => {
                        s.states.swap_remove(i);
                        drop(Box::from_raw(p));
                        *state = std::ptr::null_mut();
                        Status::Ok
                    }
                    None => s.instance.reject(f, &self.unknown()),
                }
            })
        }
    }

    /// `fmi*SerializedFMUstateSize`.
    ///
    /// # Safety
    /// FMI pointer contract.
    pub unsafe fn size<M: FmuModel, X>(
        &self,
        c: *mut c_void,
        state: *mut c_void,
        size: *mut usize,
    ) -> std::os::raw::c_int {
        let f = self.size;
        unsafe {
            with_slot::<M, X>(c, f, |s| match (known_state(s, state), size.is_null()) {
                (Some(core), false) => {
                    *size = s.instance.serialize(core).len();
                    Status::Ok
                }
                (None, _) => s.instance.reject(f, &self.unknown()),
                (_, true) => s.instance.reject(f, "size is NULL"),
            })
        }
    }

    /// `fmi*SerializeFMUstate`.
    ///
    /// # Safety
    /// FMI pointer contract.
    pub unsafe fn serialize<M: FmuModel, X>(
        &self,
        c: *mut c_void,
        state: *mut c_void,
        bytes: *mut u8,
        size: usize,
    ) -> std::os::raw::c_int {
        let f = self.serialize;
        unsafe {
            with_slot::<M, X>(c, f, |s| {
                let Some(core) = known_state(s, state) else {
                    return s.instance.reject(f, &self.unknown());
                };
                let data = s.instance.serialize(core);
                if bytes.is_null() || size < data.len() {
                    return s.instance.reject(
                        f,
                        &format!(
                            "the buffer holds {size} bytes, the state needs {}",
                            data.len()
                        ),
                    );
                }
                std::ptr::copy_nonoverlapping(data.as_ptr(), bytes, data.len());
                Status::Ok
            })
        }
    }

    /// `fmi*DeSerializeFMUstate`.
    ///
    /// # Safety
    /// FMI pointer contract.
    pub unsafe fn deserialize<M: FmuModel, X>(
        &self,
        c: *mut c_void,
        bytes: *const u8,
        size: usize,
        state: *mut *mut c_void,
    ) -> std::os::raw::c_int {
        let f = self.deserialize;
        unsafe {
            with_slot::<M, X>(c, f, |s| {
                let Some(data) = slice(bytes, size) else {
                    return s.instance.reject(f, "serializedState is NULL");
                };
                if state.is_null() {
                    return s.instance.reject(f, &format!("{} is NULL", self.noun));
                }
                match s.instance.deserialize(data) {
                    Ok(core) => {
                        let p = Box::into_raw(core);
                        s.states.push(p);
                        *state = p as *mut c_void;
                        Status::Ok
                    }
                    Err(e) => s.instance.reject(f, &e.to_string()),
                }
            })
        }
    }
}

/// Writes what `answer` says of the instance behind `c` into the one value behind `out`
/// (rejected when NULL, naming the argument `what`): the size and status queries.
///
/// # Safety
/// `c` as for [`with_slot`]; `out` is NULL or points to one writable `T`.
pub unsafe fn write_out<M: FmuModel, X, T>(
    c: *mut c_void,
    f: &Function,
    (out, what): (*mut T, &str),
    answer: impl FnOnce(&Slot<M, X>) -> T,
) -> std::os::raw::c_int {
    unsafe {
        with_slot::<M, X>(c, f, |s| {
            if out.is_null() {
                return s.instance.reject(f, &format!("{what} is NULL"));
            }
            // SAFETY: checked non-NULL; the caller's obligation otherwise.
            *out = answer(s);
            Status::Ok
        })
    }
}
