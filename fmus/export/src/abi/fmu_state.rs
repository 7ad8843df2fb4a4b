//! The six FMU-state functions of both fronts (`fmi*GetFMUstate` … `fmi*DeSerializeFMUstate`)
//! over the handle: the FMU states an instance created live in its slot until freed, and a
//! pointer it did not create is refused, never dereferenced.

use super::pointers::slice;
use super::slot::{with_slot, Slot};
use crate::instance::{Core, Function};
use crate::model::FmuModel;
use crate::types::Status;
use std::os::raw::c_void;

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
        const STATES: $crate::abi::fmu_state::StateFunctions =
            $crate::abi::fmu_state::StateFunctions {
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

/// Emits, inside a front's export macro, the six FMU-state functions of a front (its
/// handle, FMU-state and byte types; the names in the standard's order) over the `ffi`
/// module in scope.
#[doc(hidden)]
#[macro_export]
macro_rules! fmu_state_entries {
    (
        $handle:ty, $state:ty, $byte:ty;
        $get:ident, $set:ident, $free:ident, $size:ident, $serialize:ident, $deserialize:ident
    ) => {
        #[no_mangle]
        pub unsafe extern "C" fn $get(c: $handle, state: *mut $state) -> ::std::os::raw::c_int {
            unsafe { ffi::get_fmu_state::<M>(c, state) }
        }
        #[no_mangle]
        pub unsafe extern "C" fn $set(c: $handle, state: $state) -> ::std::os::raw::c_int {
            unsafe { ffi::set_fmu_state::<M>(c, state) }
        }
        #[no_mangle]
        pub unsafe extern "C" fn $free(c: $handle, state: *mut $state) -> ::std::os::raw::c_int {
            unsafe { ffi::free_fmu_state::<M>(c, state) }
        }
        #[no_mangle]
        pub unsafe extern "C" fn $size(
            c: $handle,
            state: $state,
            size: *mut usize,
        ) -> ::std::os::raw::c_int {
            unsafe { ffi::serialized_fmu_state_size::<M>(c, state, size) }
        }
        #[no_mangle]
        pub unsafe extern "C" fn $serialize(
            c: $handle,
            state: $state,
            bytes: *mut $byte,
            size: usize,
        ) -> ::std::os::raw::c_int {
            unsafe { ffi::serialize_fmu_state::<M>(c, state, bytes, size) }
        }
        #[no_mangle]
        pub unsafe extern "C" fn $deserialize(
            c: $handle,
            bytes: *const $byte,
            size: usize,
            state: *mut $state,
        ) -> ::std::os::raw::c_int {
            unsafe { ffi::deserialize_fmu_state::<M>(c, bytes, size, state) }
        }
    };
}
