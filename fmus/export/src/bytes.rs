//! A small, explicit binary format for serialized FMU states (`fmi2SerializeFMUstate`).
//!
//! Little-endian fixed-width numbers, length-prefixed strings. Floats are stored by their
//! bits, so a state replays bit for bit.

/// Appends values to a byte buffer.
#[derive(Debug, Default)]
pub struct ByteWriter {
    bytes: Vec<u8>,
}

impl ByteWriter {
    /// An empty buffer.
    pub fn new() -> Self {
        Self::default()
    }
    /// Appends a `u64`.
    pub fn put_u64(&mut self, v: u64) {
        self.bytes.extend_from_slice(&v.to_le_bytes());
    }
    /// Appends an `f64` by its bits.
    pub fn put_f64(&mut self, v: f64) {
        self.put_u64(v.to_bits());
    }
    /// Appends an `i32`.
    pub fn put_i32(&mut self, v: i32) {
        self.bytes.extend_from_slice(&v.to_le_bytes());
    }
    /// Appends a `bool` as one byte.
    pub fn put_bool(&mut self, v: bool) {
        self.bytes.push(v as u8);
    }
    /// Appends a length-prefixed UTF-8 string.
    pub fn put_str(&mut self, v: &str) {
        self.put_u64(v.len() as u64);
        self.bytes.extend_from_slice(v.as_bytes());
    }
    /// Appends a length-prefixed slice of `f64`.
    pub fn put_f64_slice(&mut self, v: &[f64]) {
        self.put_u64(v.len() as u64);
        for x in v {
            self.put_f64(*x);
        }
    }
    /// Appends a length-prefixed byte string.
    pub fn put_bytes(&mut self, v: &[u8]) {
        self.put_u64(v.len() as u64);
        self.bytes.extend_from_slice(v);
    }
    /// The bytes written so far.
    pub fn into_bytes(self) -> Vec<u8> {
        self.bytes
    }
}

/// Why serialized FMU-state bytes could not be read.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum StateFormatError {
    /// The bytes ended before the value.
    Truncated { needed: usize, left: usize },
    /// A boolean byte other than 0 or 1.
    InvalidBoolean(u8),
    /// A string that is not UTF-8.
    NotUtf8,
    /// A length prefix longer than the bytes left.
    LengthTooLong { length: u64, left: usize },
}

impl std::fmt::Display for StateFormatError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Truncated { needed, left } => write!(
                f,
                "serialized FMU state is truncated: needed {needed} more bytes, {left} left"
            ),
            Self::InvalidBoolean(b) => write!(f, "serialized FMU state: invalid boolean byte {b}"),
            Self::NotUtf8 => write!(f, "serialized FMU state: a string is not UTF-8"),
            Self::LengthTooLong { length, left } => write!(
                f,
                "serialized FMU state: length {length} exceeds the {left} bytes left"
            ),
        }
    }
}

impl std::error::Error for StateFormatError {}

/// Reads values written by [`ByteWriter`], failing cleanly on truncated or foreign input.
#[derive(Debug)]
pub struct ByteReader<'a> {
    bytes: &'a [u8],
}

impl<'a> ByteReader<'a> {
    /// A reader over `bytes`.
    pub fn new(bytes: &'a [u8]) -> Self {
        Self { bytes }
    }
    fn take(&mut self, n: usize) -> Result<&'a [u8], StateFormatError> {
        if self.bytes.len() < n {
            return Err(StateFormatError::Truncated {
                needed: n,
                left: self.bytes.len(),
            });
        }
        let (head, tail) = self.bytes.split_at(n);
        self.bytes = tail;
        Ok(head)
    }
    /// Reads a `u64`.
    pub fn u64(&mut self) -> Result<u64, StateFormatError> {
        let mut b = [0u8; 8];
        b.copy_from_slice(self.take(8)?);
        Ok(u64::from_le_bytes(b))
    }
    /// Reads an `f64`.
    pub fn f64(&mut self) -> Result<f64, StateFormatError> {
        Ok(f64::from_bits(self.u64()?))
    }
    /// Reads an `i32`.
    pub fn i32(&mut self) -> Result<i32, StateFormatError> {
        let mut b = [0u8; 4];
        b.copy_from_slice(self.take(4)?);
        Ok(i32::from_le_bytes(b))
    }
    /// Reads a `bool`.
    pub fn bool(&mut self) -> Result<bool, StateFormatError> {
        match self.take(1)?[0] {
            0 => Ok(false),
            1 => Ok(true),
            b => Err(StateFormatError::InvalidBoolean(b)),
        }
    }
    /// Reads a string.
    pub fn string(&mut self) -> Result<String, StateFormatError> {
        let n = self.len_prefix()?;
        let raw = self.take(n)?;
        String::from_utf8(raw.to_vec()).map_err(|_| StateFormatError::NotUtf8)
    }
    /// Reads a byte string written by [`ByteWriter::put_bytes`].
    pub fn byte_vec(&mut self) -> Result<Vec<u8>, StateFormatError> {
        let n = self.len_prefix()?;
        Ok(self.take(n)?.to_vec())
    }
    /// Reads a slice of `f64`.
    pub fn f64_vec(&mut self) -> Result<Vec<f64>, StateFormatError> {
        let n = self.len_prefix()?;
        (0..n).map(|_| self.f64()).collect()
    }
    fn len_prefix(&mut self) -> Result<usize, StateFormatError> {
        let n = self.u64()?;
        if n > self.bytes.len() as u64 {
            return Err(StateFormatError::LengthTooLong {
                length: n,
                left: self.bytes.len(),
            });
        }
        Ok(n as usize)
    }
    /// Bytes not read yet.
    pub fn remaining(&self) -> usize {
        self.bytes.len()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip() {
        let mut w = ByteWriter::new();
        w.put_f64(-0.1);
        w.put_u64(u64::MAX);
        w.put_i32(-7);
        w.put_bool(true);
        w.put_str("x_hat[1]");
        w.put_f64_slice(&[1.0, f64::MIN_POSITIVE]);
        let bytes = w.into_bytes();
        let mut r = ByteReader::new(&bytes);
        assert_eq!(r.f64().unwrap().to_bits(), (-0.1f64).to_bits());
        assert_eq!(r.u64().unwrap(), u64::MAX);
        assert_eq!(r.i32().unwrap(), -7);
        assert!(r.bool().unwrap());
        assert_eq!(r.string().unwrap(), "x_hat[1]");
        assert_eq!(r.f64_vec().unwrap(), vec![1.0, f64::MIN_POSITIVE]);
        assert_eq!(r.remaining(), 0);
        assert!(r.u64().is_err());
    }

    #[test]
    fn truncated_input_is_an_error() {
        let mut r = ByteReader::new(&[1, 2, 3]);
        assert!(r.f64().unwrap_err().to_string().contains("truncated"));
        let mut w = ByteWriter::new();
        w.put_u64(1 << 40);
        let bytes = w.into_bytes();
        assert!(ByteReader::new(&bytes).string().is_err());
    }
}
