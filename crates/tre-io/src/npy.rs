//! NumPy `.npy` files: any numeric dtype (either byte order, header version 1, 2 or 3) read
//! into f64 through the `npyz` crate, f16/f32/f64 and unsigned or signed integers written as
//! numpy writes them; enough for depth, normals, roughness and labels.
//!
//! The server reads `.npy` depth that clients send, so reading is guarded: the bytes pass
//! [`check_header`] before `npyz` sees them, and the shape is bounded before any value is
//! read. Measured on npyz 0.9.1 (debug build, as the tests run), without the guard:
//! - a 12-byte version-2 file that declares a 4 GiB header made npyz allocate 4,294,967,295
//!   bytes before failing (it sizes its buffer from the declared length);
//! - a shape such as `(4294967296, 4294967296)` panicked with "attempt to multiply with
//!   overflow" in `NpyHeader::from_reader` (a release build wraps the count instead);
//! - its Python-literal header parser takes about 3 µs per header byte (31 ms for 10 kB of
//!   nested parentheses, 60 µs for a plain header).
//!
//! So the header must be at most [`MAX_HEADER_BYTES`] and lie within the file, and its shape
//! (every `shape` entry, parsed with the same Python-literal parser `npyz` uses) must not
//! overflow when multiplied out; only then does `npyz` parse it and read the values.
//!
//! Writing stays a block of bytes behind the header numpy writes, with the dtype named by npyz:
//! npyz's per-value writer took 45–115 ms for 2048×2048 float32 values (release build, three
//! runs on a busy 2-core machine) where one block takes 17–42 ms, and the server writes `.npy`
//! answers of up to that size; and npyz's header differs from numpy's (`(12, 16, 3,)`, padding
//! to 16 bytes), which would change the bytes of every file written (the generator's recorded
//! output among them). Reading through npyz took 44–70 ms against 34–41 ms for a plain
//! conversion loop: kept, for its handling of every dtype, byte order and header version.

use std::io::{Read, Write};

use npyz::{DType, TypeChar};
use py_literal::Value;

use tre_core::geometry::GeometryError;

/// The longest header read, bytes: a numeric array's header is a few hundred bytes (numpy's own
/// reader stops at 10,000), and parsing costs about 3 µs per byte.
pub const MAX_HEADER_BYTES: usize = 4096;

/// Longest part of the parser's message shown in [`NpyError::Header`], characters.
const MAX_REASON_CHARS: usize = 200;

/// An IEEE half-precision value (for compact `.npy` files).
pub type F16 = npyz::half::f16;

/// Errors of reading or checking a `.npy` array.
#[derive(Debug, thiserror::Error)]
pub enum NpyError {
    /// The bytes could not be read, or a value in them could not be decoded.
    #[error("reading .npy: {0}")]
    Read(#[from] std::io::Error),
    /// The file does not start with the `.npy` magic string.
    #[error("not a .npy file (bad magic)")]
    BadMagic,
    /// A format version other than 1.0, 2.0 or 3.0.
    #[error("unsupported .npy version {major}.{minor}")]
    Version {
        /// Major version byte.
        major: u8,
        /// Minor version byte.
        minor: u8,
    },
    /// A file that ends before its header length.
    #[error("truncated .npy: {len} bytes, too few for the magic, version and header length")]
    TruncatedPreamble {
        /// Bytes in the file.
        len: usize,
    },
    /// The header is declared longer than the bytes that follow.
    #[error("truncated .npy header: {declared} bytes declared, {present} present")]
    TruncatedHeader {
        /// Header length the file declares.
        declared: usize,
        /// Bytes present after the length field.
        present: usize,
    },
    /// The header is longer than [`MAX_HEADER_BYTES`].
    #[error(".npy header of {len} bytes is longer than the limit of {limit}")]
    HeaderTooLong {
        /// Header length the file declares.
        len: usize,
        /// The most allowed.
        limit: usize,
    },
    /// The header is not the Python dict literal it should be.
    // The reason is in the message, not a `source`: a report that prints the chain would say
    // it twice.
    #[error("unreadable .npy header: {reason}")]
    Header {
        /// What is wrong: text that is not UTF-8, or what the parser said (its message cut to
        /// 200 characters).
        reason: HeaderProblem,
    },
    /// Values stored in Fortran (column-major) order.
    #[error("Fortran-order arrays are not supported; save with np.ascontiguousarray")]
    FortranOrder,
    /// A dtype that is not a number (strings, records, objects, complex, dates).
    #[error("unsupported .npy dtype {dtype}: use float32/float64 or unsigned ints")]
    UnsupportedDtype {
        /// The dtype as the header gives it.
        dtype: String,
    },
    /// A shape whose dimensions multiply to more than 2⁶⁴.
    #[error("shape {shape:?} holds more values than can exist")]
    ShapeOverflow {
        /// The declared shape.
        shape: Vec<u64>,
    },
    /// A shape of more values than the caller allows (checked before reading them).
    #[error(".npy shape {shape:?} holds more values than the limit of {limit}")]
    TooLarge {
        /// The declared shape.
        shape: Vec<usize>,
        /// The most values allowed.
        limit: usize,
    },
    /// Fewer data bytes than the shape and dtype need.
    #[error("truncated .npy data: {present} bytes for {count} values of {value_bytes} bytes")]
    TruncatedData {
        /// Data bytes present.
        present: usize,
        /// Values the shape declares.
        count: usize,
        /// Bytes per value.
        value_bytes: usize,
    },
    /// An array of another shape than the map needs.
    #[error("expected {expected}, got shape {got:?}")]
    Shape {
        /// The shape needed, in words.
        expected: &'static str,
        /// The array's shape.
        got: Vec<usize>,
    },
    /// Depth given as integers: their unit cannot be known.
    #[error(
        "depth .npy must hold float metres (float16, float32 or float64), got dtype {dtype}: \
         for integer depth send a 16-bit PNG with its depth_scale"
    )]
    DepthNotFloat {
        /// The array's dtype.
        dtype: String,
    },
    /// Labels given as floats, which would be truncated.
    #[error("labels must be an integer .npy (class ids, 0 = void), got dtype {dtype}")]
    LabelsNotInteger {
        /// The array's dtype.
        dtype: String,
    },
    /// The array does not make a grid (e.g. a dimension of 0).
    #[error(transparent)]
    Grid(#[from] GeometryError),
}

/// Why a `.npy` header does not read ([`NpyError::Header`]). A parser's message is shown cut
/// to 200 characters: it may quote the header, which a client wrote.
#[derive(Debug, thiserror::Error)]
pub enum HeaderProblem {
    /// Header bytes that are not UTF-8 text.
    #[error("the header is not UTF-8 text")]
    NotText(#[source] std::str::Utf8Error),
    /// Text that the Python-literal parser refused.
    #[error("{}", Cut(.0))]
    Literal(py_literal::ParseError),
    /// A header that `npyz` refused.
    #[error("{}", Cut(.0))]
    Npyz(std::io::Error),
}

/// A message shown cut to [`MAX_REASON_CHARS`] characters, with `…` where it was cut.
struct Cut<'a, E>(&'a E);

impl<E: std::fmt::Display> std::fmt::Display for Cut<'_, E> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let text = self.0.to_string();
        match text.char_indices().nth(MAX_REASON_CHARS) {
            Some((cut, _)) => write!(f, "{}…", &text[..cut]),
            None => f.write_str(&text),
        }
    }
}

/// An element type that `.npy` files carry and [`write_npy`] writes.
pub trait NpyElement: npyz::AutoSerialize + Copy {
    /// Appends the value's bytes in the machine's byte order, the order of npyz's default dtype
    /// for it.
    fn extend_ne(self, out: &mut Vec<u8>);
}

macro_rules! npy_element {
    ($($t:ty),*) => {$(
        impl NpyElement for $t {
            fn extend_ne(self, out: &mut Vec<u8>) {
                out.extend_from_slice(&self.to_ne_bytes());
            }
        }
    )*};
}
npy_element!(f32, f64, F16, u8, u16, u32, i32);

/// Writes `data` with `shape` (C order) as a `.npy` file in the machine's byte order, with the
/// header numpy's `np.save` writes (the dtype named by npyz).
pub fn write_npy<T: NpyElement>(
    mut w: impl Write,
    shape: &[usize],
    data: &[T],
) -> std::io::Result<()> {
    if shape.iter().try_fold(1usize, |n, &d| n.checked_mul(d)) != Some(data.len()) {
        return Err(std::io::Error::new(
            std::io::ErrorKind::InvalidInput,
            format!("{} values do not fill shape {shape:?}", data.len()),
        ));
    }
    let header = numpy_header(&dtype_name(&T::default_dtype()), shape);
    let mut out = Vec::with_capacity(header.len() + std::mem::size_of_val(data));
    out.extend_from_slice(&header);
    for &v in data {
        v.extend_ne(&mut out);
    }
    w.write_all(&out)
}

/// The magic string, version 1.0, header length and header of a C-order array, padded with
/// spaces to a multiple of 64 bytes as numpy pads it.
fn numpy_header(descr: &str, shape: &[usize]) -> Vec<u8> {
    let dims: Vec<String> = shape.iter().map(|d| d.to_string()).collect();
    let shape = match &dims[..] {
        [one] => format!("({one},)"),
        dims => format!("({})", dims.join(", ")),
    };
    let mut text = format!("{{'descr': '{descr}', 'fortran_order': False, 'shape': {shape}, }}");
    // Magic (6) + version (2) + length (2) + text + '\n' is a multiple of 64.
    let padded = (10 + text.len() + 1).div_ceil(64) * 64 - 10;
    text.extend(std::iter::repeat_n(' ', padded - 1 - text.len()));
    text.push('\n');
    let mut out = b"\x93NUMPY\x01\x00".to_vec();
    out.extend_from_slice(&(text.len() as u16).to_le_bytes());
    out.extend_from_slice(text.as_bytes());
    out
}

/// A `.npy` array read into f64, with its shape.
#[derive(Debug, Clone, PartialEq)]
pub struct NpyArray {
    /// Dimensions, C order.
    pub shape: Vec<usize>,
    /// Values, C order, converted to f64.
    pub data: Vec<f64>,
    /// The file's dtype as numpy writes it (`<f4`, `>u2`, `|u1`, …).
    pub dtype: String,
}

impl NpyArray {
    /// Whether the file held floating-point values (float16, float32 or float64).
    pub fn is_float(&self) -> bool {
        self.dtype.get(1..2) == Some("f")
    }
}

/// Reads a `.npy` file of any supported numeric dtype into f64.
pub fn read_npy(r: impl Read) -> Result<NpyArray, NpyError> {
    read_npy_within(r, usize::MAX)
}

/// [`read_npy`], refusing from the header alone an array of more than `max_values` values, so
/// that a client's file is bounded before it is converted (8 bytes per value, whatever its
/// dtype: a float16 file would otherwise take four times its size).
pub fn read_npy_within(mut r: impl Read, max_values: usize) -> Result<NpyArray, NpyError> {
    let mut bytes = Vec::new();
    r.read_to_end(&mut bytes)?;
    let data_start = check_header(&bytes)?;
    let file = npyz::NpyFile::new(&bytes[..]).map_err(|e| NpyError::Header {
        reason: HeaderProblem::Npyz(e),
    })?;
    if file.order() == npyz::Order::Fortran {
        return Err(NpyError::FortranOrder);
    }
    let shape = to_usize(file.shape())?;
    let count = shape.iter().try_fold(1usize, |n, &d| n.checked_mul(d));
    let count = count.ok_or_else(|| NpyError::ShapeOverflow {
        shape: file.shape().to_vec(),
    })?;
    if count > max_values {
        return Err(NpyError::TooLarge {
            shape,
            limit: max_values,
        });
    }
    let (dtype, value_bytes) = numeric_dtype(&file.dtype())?;
    let present = bytes.len() - data_start;
    if count.checked_mul(value_bytes).is_none_or(|n| n > present) {
        return Err(NpyError::TruncatedData {
            present,
            count,
            value_bytes,
        });
    }
    let data = read_values(file, &dtype, count)?;
    Ok(NpyArray {
        shape,
        data,
        dtype: dtype.to_string(),
    })
}

/// Where the data of a `.npy` file starts, once its preamble and header are checked: the
/// magic string, a known version, a header within the bytes and within [`MAX_HEADER_BYTES`],
/// and a header whose `shape` entries do not overflow when multiplied out (see the module
/// docs for why `npyz` must not see the others).
pub fn check_header(bytes: &[u8]) -> Result<usize, NpyError> {
    if bytes.len() < 8 || &bytes[..6] != b"\x93NUMPY" {
        return Err(NpyError::BadMagic);
    }
    let start = match (bytes[6], bytes[7]) {
        (1, 0) => 10,
        (2 | 3, 0) => 12,
        (major, minor) => return Err(NpyError::Version { major, minor }),
    };
    let Some(length) = bytes.get(8..start) else {
        return Err(NpyError::TruncatedPreamble { len: bytes.len() });
    };
    // Little-endian, 2 or 4 bytes.
    let declared = length
        .iter()
        .rev()
        .fold(0usize, |n, &b| n << 8 | usize::from(b));
    let present = bytes.len().saturating_sub(start);
    if declared > MAX_HEADER_BYTES {
        return Err(NpyError::HeaderTooLong {
            len: declared,
            limit: MAX_HEADER_BYTES,
        });
    }
    if declared > present {
        return Err(NpyError::TruncatedHeader { declared, present });
    }
    check_shapes(&bytes[start..start + declared])?;
    Ok(start + declared)
}

/// Refuses a header any of whose `shape` entries multiply out beyond `u64`, counting every
/// prefix product `npyz` forms (dimensions of 0 left out, since the strides skip none).
fn check_shapes(header: &[u8]) -> Result<(), NpyError> {
    let header_error = |reason| NpyError::Header { reason };
    let text = std::str::from_utf8(header.strip_suffix(b"\n").unwrap_or(header))
        .map_err(|e| header_error(HeaderProblem::NotText(e)))?;
    let value: Value = text
        .parse()
        .map_err(|e| header_error(HeaderProblem::Literal(e)))?;
    let Value::Dict(entries) = value else {
        return Ok(()); // npyz says what is wrong.
    };
    for (key, shape) in &entries {
        let (Value::String(key), Value::Tuple(dims) | Value::List(dims)) = (key, shape) else {
            continue;
        };
        if key != "shape" {
            continue;
        }
        // Dimensions that are not integers within u64 are npyz's to refuse.
        let dims: Vec<u64> = dims
            .iter()
            .filter_map(|d| match d {
                Value::Integer(i) => u64::try_from(i).ok(),
                _ => None,
            })
            .collect();
        let mut nonzero = dims.iter().filter(|&&d| d != 0);
        if nonzero.try_fold(1u64, |n, &d| n.checked_mul(d)).is_none() {
            return Err(NpyError::ShapeOverflow { shape: dims });
        }
    }
    Ok(())
}

/// The shape as `usize`s.
fn to_usize(shape: &[u64]) -> Result<Vec<usize>, NpyError> {
    shape
        .iter()
        .map(|&d| usize::try_from(d))
        .collect::<Result<_, _>>()
        .map_err(|_| NpyError::ShapeOverflow {
            shape: shape.to_vec(),
        })
}

/// The dtype's type string and bytes per value, if it is a number this module reads.
fn numeric_dtype(dtype: &DType) -> Result<(npyz::TypeStr, usize), NpyError> {
    let unsupported = || NpyError::UnsupportedDtype {
        dtype: dtype_name(dtype),
    };
    let DType::Plain(ts) = dtype else {
        return Err(unsupported());
    };
    let size = ts.size_field();
    let ok = match ts.type_char() {
        TypeChar::Float => matches!(size, 2 | 4 | 8),
        TypeChar::Uint | TypeChar::Int => matches!(size, 1 | 2 | 4 | 8),
        TypeChar::Bool => size == 1,
        _ => false,
    };
    if !ok || ts.time_units().is_some() {
        return Err(unsupported());
    }
    Ok((ts.clone(), size as usize))
}

/// The dtype as numpy writes it: `<f4`, `|u1`, or a record's list.
fn dtype_name(dtype: &DType) -> String {
    match dtype {
        DType::Plain(ts) => ts.to_string(),
        other => other.descr(),
    }
}

/// Reads `count` values of the (checked) numeric `dtype` as f64.
fn read_values(
    file: npyz::NpyFile<&[u8]>,
    dtype: &npyz::TypeStr,
    count: usize,
) -> Result<Vec<f64>, NpyError> {
    fn all<T: npyz::Deserialize>(
        file: npyz::NpyFile<&[u8]>,
        count: usize,
        to_f64: impl Fn(T) -> f64,
    ) -> Result<Vec<f64>, NpyError> {
        let dtype = file.dtype();
        let reader = file.data::<T>().map_err(|_| NpyError::UnsupportedDtype {
            dtype: dtype_name(&dtype),
        })?;
        let mut out = Vec::with_capacity(count);
        for v in reader {
            out.push(to_f64(v?));
        }
        Ok(out)
    }
    match (dtype.type_char(), dtype.size_field()) {
        (TypeChar::Float, 2) => all(file, count, |v: F16| v.to_f64()),
        (TypeChar::Float, 4) => all(file, count, |v: f32| f64::from(v)),
        (TypeChar::Float, _) => all(file, count, |v: f64| v),
        (TypeChar::Uint, 1) => all(file, count, |v: u8| f64::from(v)),
        (TypeChar::Uint, 2) => all(file, count, |v: u16| f64::from(v)),
        (TypeChar::Uint, 4) => all(file, count, |v: u32| f64::from(v)),
        (TypeChar::Uint, _) => all(file, count, |v: u64| v as f64),
        (TypeChar::Int, 1) => all(file, count, |v: i8| f64::from(v)),
        (TypeChar::Int, 2) => all(file, count, |v: i16| f64::from(v)),
        (TypeChar::Int, 4) => all(file, count, |v: i32| f64::from(v)),
        (TypeChar::Int, _) => all(file, count, |v: i64| v as f64),
        _ => all(file, count, |v: bool| f64::from(u8::from(v))),
    }
}

#[cfg(test)]
mod tests;
