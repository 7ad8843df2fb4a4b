//! Plain-bytes snapshots of model state, for FMU-state serialization without a serialization
//! framework.
//!
//! [`PlainState`] writes a value as little-endian bytes and reads it back; it is implemented
//! for the numbers, `bool`, arrays, `Vec`, `Option`, tuples and the nalgebra matrices, and
//! derived for a struct or enum by listing its fields with [`plain_state!`](crate::plain_state)
//! next to its definition (so private fields are reached and a field cannot be forgotten when
//! the list is kept in the same order as the definition). A snapshot restores a value bit for
//! bit: `read(save(x)) == x`.

use nalgebra::{Complex, DMatrix, Dim, Matrix, RawStorage, SMatrix};

/// Why a snapshot could not be read.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum StateError {
    /// The bytes ended before the value did.
    Truncated { needed: usize, left: usize },
    /// An enum tag, a boolean byte or a length that no value has.
    Invalid { what: &'static str, value: u64 },
}

impl std::fmt::Display for StateError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            StateError::Truncated { needed, left } => write!(
                f,
                "the saved state is truncated: {needed} more bytes expected, {left} left"
            ),
            StateError::Invalid { what, value } => {
                write!(f, "the saved state has an invalid {what} `{value}`")
            }
        }
    }
}

impl std::error::Error for StateError {}

/// A value that can be saved as plain bytes and read back exactly.
pub trait PlainState: Sized {
    /// Appends the value's bytes.
    fn save(&self, out: &mut Vec<u8>);
    /// Reads a value from the front of `input`, advancing it.
    fn read(input: &mut &[u8]) -> Result<Self, StateError>;
}

/// Takes `N` bytes from the front of `input`.
pub fn take<const N: usize>(input: &mut &[u8]) -> Result<[u8; N], StateError> {
    if input.len() < N {
        return Err(StateError::Truncated {
            needed: N,
            left: input.len(),
        });
    }
    let (head, rest) = input.split_at(N);
    *input = rest;
    let mut bytes = [0u8; N];
    bytes.copy_from_slice(head);
    Ok(bytes)
}

macro_rules! numbers {
    ($($t:ty),*) => {$(
        impl PlainState for $t {
            fn save(&self, out: &mut Vec<u8>) {
                out.extend_from_slice(&self.to_le_bytes());
            }
            fn read(input: &mut &[u8]) -> Result<Self, StateError> {
                Ok(<$t>::from_le_bytes(take(input)?))
            }
        }
    )*};
}
numbers!(f64, u64, u32, u8, i64, i32);

impl PlainState for usize {
    fn save(&self, out: &mut Vec<u8>) {
        (*self as u64).save(out);
    }
    fn read(input: &mut &[u8]) -> Result<Self, StateError> {
        let v = u64::read(input)?;
        usize::try_from(v).map_err(|_| StateError::Invalid {
            what: "length",
            value: v,
        })
    }
}

impl PlainState for bool {
    fn save(&self, out: &mut Vec<u8>) {
        out.push(u8::from(*self));
    }
    fn read(input: &mut &[u8]) -> Result<Self, StateError> {
        match u8::read(input)? {
            0 => Ok(false),
            1 => Ok(true),
            v => Err(StateError::Invalid {
                what: "boolean",
                value: u64::from(v),
            }),
        }
    }
}

impl<T: PlainState, const N: usize> PlainState for [T; N] {
    fn save(&self, out: &mut Vec<u8>) {
        self.iter().for_each(|v| v.save(out));
    }
    fn read(input: &mut &[u8]) -> Result<Self, StateError> {
        let items = (0..N)
            .map(|_| T::read(input))
            .collect::<Result<Vec<T>, _>>()?;
        items.try_into().map_err(|_| StateError::Invalid {
            what: "array length",
            value: N as u64,
        })
    }
}

impl<T: PlainState> PlainState for Vec<T> {
    fn save(&self, out: &mut Vec<u8>) {
        self.len().save(out);
        self.iter().for_each(|v| v.save(out));
    }
    fn read(input: &mut &[u8]) -> Result<Self, StateError> {
        let n = usize::read(input)?;
        // Each element takes at least one byte: a corrupt length cannot allocate much.
        if n > input.len() {
            return Err(StateError::Truncated {
                needed: n,
                left: input.len(),
            });
        }
        (0..n).map(|_| T::read(input)).collect()
    }
}

impl<T: PlainState> PlainState for Option<T> {
    fn save(&self, out: &mut Vec<u8>) {
        self.is_some().save(out);
        if let Some(v) = self {
            v.save(out);
        }
    }
    fn read(input: &mut &[u8]) -> Result<Self, StateError> {
        Ok(if bool::read(input)? {
            Some(T::read(input)?)
        } else {
            None
        })
    }
}

impl<A: PlainState, B: PlainState> PlainState for (A, B) {
    fn save(&self, out: &mut Vec<u8>) {
        self.0.save(out);
        self.1.save(out);
    }
    fn read(input: &mut &[u8]) -> Result<Self, StateError> {
        Ok((A::read(input)?, B::read(input)?))
    }
}

impl PlainState for Complex<f64> {
    fn save(&self, out: &mut Vec<u8>) {
        self.re.save(out);
        self.im.save(out);
    }
    fn read(input: &mut &[u8]) -> Result<Self, StateError> {
        Ok(Complex::new(f64::read(input)?, f64::read(input)?))
    }
}

fn save_entries<R: Dim, C: Dim, S: RawStorage<f64, R, C>>(
    m: &Matrix<f64, R, C, S>,
    out: &mut Vec<u8>,
) {
    m.iter().for_each(|v| v.save(out));
}

impl<const R: usize, const C: usize> PlainState for SMatrix<f64, R, C> {
    fn save(&self, out: &mut Vec<u8>) {
        save_entries(self, out);
    }
    fn read(input: &mut &[u8]) -> Result<Self, StateError> {
        let mut m = Self::zeros();
        for v in m.iter_mut() {
            *v = f64::read(input)?;
        }
        Ok(m)
    }
}

impl PlainState for DMatrix<f64> {
    fn save(&self, out: &mut Vec<u8>) {
        self.nrows().save(out);
        self.ncols().save(out);
        save_entries(self, out);
    }
    fn read(input: &mut &[u8]) -> Result<Self, StateError> {
        let (rows, cols) = (usize::read(input)?, usize::read(input)?);
        let n = rows.saturating_mul(cols);
        if n.saturating_mul(8) > input.len() {
            return Err(StateError::Truncated {
                needed: n.saturating_mul(8),
                left: input.len(),
            });
        }
        let entries = (0..n)
            .map(|_| f64::read(input))
            .collect::<Result<Vec<_>, _>>()?;
        Ok(DMatrix::from_vec(rows, cols, entries))
    }
}

impl PlainState for nalgebra::DVector<f64> {
    fn save(&self, out: &mut Vec<u8>) {
        self.len().save(out);
        save_entries(self, out);
    }
    fn read(input: &mut &[u8]) -> Result<Self, StateError> {
        Ok(nalgebra::DVector::from_vec(Vec::<f64>::read(input)?))
    }
}

/// Saves a value into a new byte vector.
pub fn to_bytes<T: PlainState>(value: &T) -> Vec<u8> {
    let mut out = Vec::new();
    value.save(&mut out);
    out
}

/// Reads a whole value from `bytes` (every byte must be used).
pub fn from_bytes<T: PlainState>(mut bytes: &[u8]) -> Result<T, StateError> {
    let value = T::read(&mut bytes)?;
    if bytes.is_empty() {
        Ok(value)
    } else {
        Err(StateError::Invalid {
            what: "trailing length",
            value: bytes.len() as u64,
        })
    }
}

/// Derives [`PlainState`] for a struct by its fields, or for an enum by its variants (a tag
/// byte, then the variant's fields). Write it in the module that defines the type:
///
/// ```
/// #[derive(Debug, PartialEq)]
/// struct Cursor { start: f64, level: Option<f64>, bits: [u64; 2] }
/// spurio::plain_state!(Cursor { start, level, bits });
///
/// #[derive(Debug, PartialEq)]
/// enum Noise { Off, Variance(f64), Snr { db: f64, power: f64 } }
/// spurio::plain_state!(enum Noise { Off, Variance(v), Snr { db, power } });
///
/// use spurio::state::{from_bytes, to_bytes};
/// let c = Cursor { start: 0.5, level: Some(-1.0), bits: [1, u64::MAX] };
/// assert_eq!(from_bytes::<Cursor>(&to_bytes(&c)).unwrap(), c);
/// let n = Noise::Snr { db: 20.0, power: 0.5 };
/// assert_eq!(from_bytes::<Noise>(&to_bytes(&n)).unwrap(), n);
/// assert!(from_bytes::<Noise>(&[7]).is_err());
/// ```
#[macro_export]
macro_rules! plain_state {
    (enum $name:ident { $($variant:ident $({ $($field:ident),* $(,)? })? $(( $($position:ident),* $(,)? ))?),* $(,)? }) => {
        impl $crate::state::PlainState for $name {
            fn save(&self, out: &mut ::std::vec::Vec<u8>) {
                #[allow(dead_code, clippy::enum_variant_names)]
                #[repr(u8)]
                enum Tag { $($variant),* }
                match self {
                    $($name::$variant $({ $($field),* })? $(( $($position),* ))? => {
                        out.push(Tag::$variant as u8);
                        $($($crate::state::PlainState::save($field, out);)*)?
                        $($($crate::state::PlainState::save($position, out);)*)?
                    })*
                }
            }
            fn read(input: &mut &[u8]) -> ::std::result::Result<Self, $crate::state::StateError> {
                #[allow(dead_code, clippy::enum_variant_names)]
                #[repr(u8)]
                enum Tag { $($variant),* }
                let tag = <u8 as $crate::state::PlainState>::read(input)?;
                $(if tag == Tag::$variant as u8 {
                    return Ok($name::$variant
                        $({ $($field: $crate::state::PlainState::read(input)?),* })?
                        $(( $({
                            let $position = $crate::state::PlainState::read(input)?;
                            $position
                        }),* ))?);
                })*
                Err($crate::state::StateError::Invalid {
                    what: concat!(stringify!($name), " variant"),
                    value: u64::from(tag),
                })
            }
        }
    };
    ($name:ident { $($field:ident),* $(,)? }) => {
        impl $crate::state::PlainState for $name {
            fn save(&self, out: &mut ::std::vec::Vec<u8>) {
                $($crate::state::PlainState::save(&self.$field, out);)*
            }
            fn read(input: &mut &[u8]) -> ::std::result::Result<Self, $crate::state::StateError> {
                Ok(Self { $($field: $crate::state::PlainState::read(input)?),* })
            }
        }
    };
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn matrices_options_and_special_floats_round_trip_bit_for_bit() {
        let m = DMatrix::from_row_slice(2, 3, &[1.0, -0.0, f64::NAN, 1e-300, f64::INFINITY, 3.5]);
        let value = (Some(m.clone()), vec![Complex::new(0.5, -0.25)]);
        let bytes = to_bytes(&value);
        let (back, poles): (Option<DMatrix<f64>>, Vec<Complex<f64>>) = from_bytes(&bytes).unwrap();
        let back = back.unwrap();
        assert_eq!((back.nrows(), back.ncols()), (2, 3));
        for (a, b) in back.iter().zip(m.iter()) {
            assert_eq!(a.to_bits(), b.to_bits());
        }
        assert_eq!(poles, vec![Complex::new(0.5, -0.25)]);
        let s = nalgebra::Vector4::new(1.0, 2.0, 3.0, 4.0);
        assert_eq!(
            from_bytes::<nalgebra::Vector4<f64>>(&to_bytes(&s)).unwrap(),
            s
        );
    }

    #[test]
    fn truncated_corrupt_and_overlong_input_is_refused() {
        let bytes = to_bytes(&(1.5f64, true));
        assert_eq!(
            from_bytes::<(f64, bool)>(&bytes[..5]),
            Err(StateError::Truncated { needed: 8, left: 5 })
        );
        let mut bad = bytes.clone();
        bad[8] = 2;
        assert!(matches!(
            from_bytes::<(f64, bool)>(&bad),
            Err(StateError::Invalid {
                what: "boolean",
                value: 2
            })
        ));
        let mut long = bytes;
        long.push(0);
        assert!(from_bytes::<(f64, bool)>(&long).is_err());
        // A corrupt length does not allocate: it is checked against the bytes left.
        let huge = to_bytes(&u64::MAX);
        assert!(from_bytes::<Vec<f64>>(&huge).is_err());
        assert!(from_bytes::<DMatrix<f64>>(&to_bytes(&(1usize << 40, 1usize << 40))).is_err());
    }
}
