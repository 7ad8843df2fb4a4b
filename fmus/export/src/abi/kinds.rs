//! The value kinds of the typed `fmi*Get*`/`fmi*Set*` functions: Real, Integer and Boolean,
//! each with its C type, its functions and how a value crosses the boundary in each version
//! (`fmi2Boolean` is an `int`, `fmi3Boolean` a C99 `bool`).

use crate::instance::state::{fmi2 as f2, fmi3 as f3, Function};
use crate::variables::VariableType;
use std::os::raw::c_int;

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

// fmi2Real, fmi2Integer, fmi2Boolean (an int); fmi3Float64, fmi3Int32, fmi3Boolean (a bool)
kind! { Fmi2, Real, f64, f2::GET_REAL, f2::SET_REAL, |x| x, |v| v }
kind! { Fmi2, Integer, c_int, f2::GET_INTEGER, f2::SET_INTEGER, |x| x as c_int, f64::from }
kind! { Fmi2, Boolean, c_int, f2::GET_BOOLEAN, f2::SET_BOOLEAN, |x| c_int::from(x != 0.0), |v| f64::from(u8::from(v != 0)) }
kind! { Fmi3, Real, f64, f3::GET_REAL, f3::SET_REAL, |x| x, |v| v }
kind! { Fmi3, Integer, i32, f3::GET_INTEGER, f3::SET_INTEGER, |x| x as i32, f64::from }
kind! { Fmi3, Boolean, u8, f3::GET_BOOLEAN, f3::SET_BOOLEAN, |x| u8::from(x != 0.0), |v| f64::from(u8::from(v != 0)) }

/// Emits, inside a front's value entries, its typed getter and setter symbols: for each pair
/// the two names, the C value type and the two functions they call, over the front's
/// instance, value-reference and status types; `$counted` is `()`, or the name of the count
/// after the values that FMI 3.0 has (`(n_values)`).
#[doc(hidden)]
#[macro_export]
macro_rules! get_set_entries {
    (
        $handle:ty, $vr:ty, $status:ty, $counted:tt;
        $($get:ident, $set:ident, $c:ty => $get_fn:expr, $set_fn:expr;)+
    ) => {
        $(
            $crate::get_set_entries!(@entry $handle, $vr, $status, $counted; $get, *mut $c, $get_fn);
            $crate::get_set_entries!(@entry $handle, $vr, $status, $counted; $set, *const $c, $set_fn);
        )+
    };
    // One symbol: a getter (values `*mut`) or a setter (values `*const`).
    (
        @entry $handle:ty, $vr:ty, $status:ty, ($($count:ident)?);
        $name:ident, $values:ty, $call:expr
    ) => {
        #[no_mangle]
        pub unsafe extern "C" fn $name(
            c: $handle,
            vr: *const $vr,
            nvr: usize,
            values: $values,
            $($count: usize)?
        ) -> $status {
            unsafe { ($call)(c, vr, nvr, values, $($count)?) }
        }
    };
}
