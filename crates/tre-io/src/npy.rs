//! Minimal NumPy `.npy` (format 1.0) reading and writing for little-endian f32, f64, u8, u16
//! and u32 arrays in C order: enough for depth, normals, roughness and labels.

use std::io::{Read, Write};

use super::IoError;

/// An element type that `.npy` files carry.
pub trait NpyElement: Copy {
    /// The NumPy dtype string, e.g. `<f4`.
    const DESCR: &'static str;
    /// Appends the little-endian bytes of `self`.
    fn write_le(self, out: &mut Vec<u8>);
}

macro_rules! npy_element {
    ($t:ty, $d:expr) => {
        impl NpyElement for $t {
            const DESCR: &'static str = $d;
            fn write_le(self, out: &mut Vec<u8>) {
                out.extend_from_slice(&self.to_le_bytes());
            }
        }
    };
}
npy_element!(f32, "<f4");

/// An IEEE half-precision value stored as its bits (for compact `.npy` files).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct F16(pub u16);

impl F16 {
    /// Rounds an f32 to the nearest half (ties to even); overflow gives ±∞, NaN stays NaN.
    pub fn from_f32(v: f32) -> Self {
        let x = v.to_bits();
        let sign = ((x >> 16) & 0x8000) as u16;
        let exp = ((x >> 23) & 0xFF) as i32;
        let man = x & 0x007F_FFFF;
        if exp == 0xFF {
            return F16(sign | 0x7C00 | if man != 0 { 0x200 } else { 0 });
        }
        let e = exp - 127 + 15;
        if e >= 0x1F {
            return F16(sign | 0x7C00);
        }
        if e <= 0 {
            if e < -10 {
                return F16(sign);
            }
            let m = man | 0x0080_0000;
            let shift = (14 - e) as u32;
            let half = 1u32 << (shift - 1);
            let rest = m & ((1u32 << shift) - 1);
            let mut h = m >> shift;
            if rest > half || (rest == half && h & 1 == 1) {
                h += 1;
            }
            return F16(sign | h as u16);
        }
        let mut h = ((e as u32) << 10) | (man >> 13);
        let rest = man & 0x1FFF;
        if rest > 0x1000 || (rest == 0x1000 && h & 1 == 1) {
            h += 1;
        }
        F16(sign | h as u16)
    }

    /// The value as f64.
    pub fn to_f64(self) -> f64 {
        let (sign, exp, man) = ((self.0 >> 15) & 1, (self.0 >> 10) & 0x1F, self.0 & 0x3FF);
        let s = if sign == 1 { -1.0 } else { 1.0 };
        match exp {
            0 => s * f64::from(man) * 2f64.powi(-24),
            0x1F if man == 0 => s * f64::INFINITY,
            0x1F => f64::NAN,
            e => s * (1.0 + f64::from(man) / 1024.0) * 2f64.powi(i32::from(e) - 15),
        }
    }
}

impl NpyElement for F16 {
    const DESCR: &'static str = "<f2";
    fn write_le(self, out: &mut Vec<u8>) {
        out.extend_from_slice(&self.0.to_le_bytes());
    }
}
npy_element!(f64, "<f8");
npy_element!(u8, "|u1");
npy_element!(u16, "<u2");
npy_element!(u32, "<u4");
npy_element!(i32, "<i4");

/// Writes `data` with `shape` as a `.npy` file.
pub fn write_npy<T: NpyElement>(
    mut w: impl Write,
    shape: &[usize],
    data: &[T],
) -> Result<(), IoError> {
    let dims: Vec<String> = shape.iter().map(|d| d.to_string()).collect();
    let shape_txt = if dims.len() == 1 {
        format!("({},)", dims[0])
    } else {
        format!("({})", dims.join(", "))
    };
    let mut header = format!(
        "{{'descr': '{}', 'fortran_order': False, 'shape': {}, }}",
        T::DESCR,
        shape_txt
    );
    // Magic (6) + version (2) + header length (2) + header + '\n' is a multiple of 64.
    while (10 + header.len() + 1) % 64 != 0 {
        header.push(' ');
    }
    header.push('\n');
    let mut bytes = Vec::with_capacity(10 + header.len() + std::mem::size_of_val(data));
    bytes.extend_from_slice(b"\x93NUMPY\x01\x00");
    bytes.extend_from_slice(&(header.len() as u16).to_le_bytes());
    bytes.extend_from_slice(header.as_bytes());
    for &v in data {
        v.write_le(&mut bytes);
    }
    w.write_all(&bytes).map_err(IoError::from)
}

/// A `.npy` array read into f64, with its shape.
#[derive(Debug, Clone, PartialEq)]
pub struct NpyArray {
    /// Dimensions, C order.
    pub shape: Vec<usize>,
    /// Values, C order, converted to f64.
    pub data: Vec<f64>,
    /// The file's dtype as numpy writes it (`<f4`, `<u2`, `|u1`, …).
    pub dtype: String,
}

impl NpyArray {
    /// Whether the file held floating-point values (float16, float32 or float64).
    pub fn is_float(&self) -> bool {
        matches!(self.dtype.as_str(), "<f2" | "<f4" | "<f8")
    }
}

/// Reads a `.npy` file of any supported numeric dtype into f64.
pub fn read_npy(r: impl Read) -> Result<NpyArray, IoError> {
    read_npy_within(r, usize::MAX)
}

/// [`read_npy`], refusing from the header alone an array of more than `max_values` values, so
/// that a client's file is bounded before it is converted (8 bytes per value, whatever its
/// dtype: a float16 file would otherwise take four times its size).
pub fn read_npy_within(mut r: impl Read, max_values: usize) -> Result<NpyArray, IoError> {
    let mut bytes = Vec::new();
    r.read_to_end(&mut bytes)?;
    let bad = |why: &str| IoError::Npy(why.to_string());
    if bytes.len() < 10 || &bytes[..6] != b"\x93NUMPY" {
        return Err(bad("not a .npy file (bad magic)"));
    }
    let (header_len, start) = match bytes[6] {
        1 => (u16::from_le_bytes([bytes[8], bytes[9]]) as usize, 10),
        2 | 3 if bytes.len() >= 12 => (
            u32::from_le_bytes([bytes[8], bytes[9], bytes[10], bytes[11]]) as usize,
            12,
        ),
        v => return Err(bad(&format!("unsupported .npy version {v}"))),
    };
    let header = bytes
        .get(start..start + header_len)
        .ok_or_else(|| bad("truncated header"))?;
    let header = std::str::from_utf8(header).map_err(|_| bad("header is not text"))?;
    if header.contains("'fortran_order': True") {
        return Err(bad(
            "Fortran-order arrays are not supported; save with np.ascontiguousarray",
        ));
    }
    let descr = field(header, "descr").ok_or_else(|| bad("header has no descr"))?;
    let shape = parse_shape(header).ok_or_else(|| bad("header has no readable shape"))?;
    let count = shape
        .iter()
        .try_fold(1usize, |n, &d| n.checked_mul(d))
        .ok_or_else(|| bad(&format!("shape {shape:?} holds more values than can exist")))?;
    if count > max_values {
        return Err(IoError::NpyTooLarge {
            shape,
            limit: max_values,
        });
    }
    let body = &bytes[start + header_len..];
    let dtype = descr.trim_matches('\'');
    let data = decode(dtype, body, count)?;
    Ok(NpyArray {
        shape,
        data,
        dtype: dtype.to_string(),
    })
}

fn field<'a>(header: &'a str, name: &str) -> Option<&'a str> {
    let at = header.find(&format!("'{name}'"))?;
    let rest = header[at + name.len() + 2..]
        .trim_start()
        .strip_prefix(':')?
        .trim_start();
    let end = rest.find(',')?;
    Some(rest[..end].trim())
}

fn parse_shape(header: &str) -> Option<Vec<usize>> {
    let at = header.find("'shape'")?;
    let open = at + header[at..].find('(')?;
    let close = open + header[open..].find(')')?;
    header[open + 1..close]
        .split(',')
        .map(str::trim)
        .filter(|s| !s.is_empty())
        .map(|s| s.parse().ok())
        .collect()
}

fn decode(descr: &str, body: &[u8], count: usize) -> Result<Vec<f64>, IoError> {
    let size = match descr {
        "<f4" | "<u4" | "<i4" => 4,
        "<f8" | "<i8" | "<u8" => 8,
        "<u2" | "<i2" | "<f2" => 2,
        "|u1" | "|i1" | "|b1" => 1,
        other => {
            return Err(IoError::Npy(format!(
                "unsupported dtype {other}: use float32/float64 or unsigned ints"
            )))
        }
    };
    let needed = count.checked_mul(size).filter(|&n| n <= body.len());
    let Some(needed) = needed else {
        return Err(IoError::Npy(format!(
            "truncated data: {} bytes for {count} values of {size} bytes",
            body.len()
        )));
    };
    let c = body[..needed].chunks_exact(size);
    Ok(match descr {
        "<f4" => c
            .map(|b| f64::from(f32::from_le_bytes([b[0], b[1], b[2], b[3]])))
            .collect(),
        "<f8" => c
            .map(|b| f64::from_le_bytes(b.try_into().expect("8-byte chunk; this is a bug")))
            .collect(),
        "<u4" => c
            .map(|b| f64::from(u32::from_le_bytes([b[0], b[1], b[2], b[3]])))
            .collect(),
        "<i4" => c
            .map(|b| f64::from(i32::from_le_bytes([b[0], b[1], b[2], b[3]])))
            .collect(),
        "<i8" => c
            .map(|b| i64::from_le_bytes(b.try_into().expect("8-byte chunk; this is a bug")) as f64)
            .collect(),
        "<u8" => c
            .map(|b| u64::from_le_bytes(b.try_into().expect("8-byte chunk; this is a bug")) as f64)
            .collect(),
        "<u2" => c
            .map(|b| f64::from(u16::from_le_bytes([b[0], b[1]])))
            .collect(),
        "<i2" => c
            .map(|b| f64::from(i16::from_le_bytes([b[0], b[1]])))
            .collect(),
        "<f2" => c
            .map(|b| F16(u16::from_le_bytes([b[0], b[1]])).to_f64())
            .collect(),
        "|i1" => c.map(|b| f64::from(b[0] as i8)).collect(),
        _ => c.map(|b| f64::from(b[0])).collect(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_f32() {
        let mut buf = Vec::new();
        write_npy(&mut buf, &[2, 3], &[1.0f32, 2.0, 3.5, -1.0, f32::NAN, 0.0]).unwrap();
        assert_eq!(buf.len(), 128 + 6 * 4);
        let a = read_npy(&buf[..]).unwrap();
        assert_eq!(a.shape, vec![2, 3]);
        assert_eq!(a.data[2], 3.5);
        assert!(a.data[4].is_nan());
    }

    #[test]
    fn half_precision_round_trips() {
        for v in [0.0f32, 1.0, -0.5, 0.3333, 65504.0, 1e-5, -2.5e-7, 0.999_99] {
            let h = F16::from_f32(v).to_f64();
            assert!(
                (h - f64::from(v)).abs() <= f64::from(v).abs() * 1e-3 + 6e-8,
                "{v} → {h}"
            );
        }
        assert!(F16::from_f32(f32::NAN).to_f64().is_nan());
        assert_eq!(F16::from_f32(1e6).to_f64(), f64::INFINITY);
        let mut buf = Vec::new();
        write_npy(&mut buf, &[2], &[F16::from_f32(0.5), F16::from_f32(-1.0)]).unwrap();
        assert_eq!(read_npy(&buf[..]).unwrap().data, vec![0.5, -1.0]);
    }

    #[test]
    fn truncated_is_an_error() {
        let mut buf = Vec::new();
        write_npy(&mut buf, &[4], &[1u16, 2, 3, 4]).unwrap();
        buf.truncate(buf.len() - 1);
        assert!(read_npy(&buf[..])
            .unwrap_err()
            .to_string()
            .contains("truncated"));
        assert!(read_npy(&b"hello"[..]).is_err());
    }

    /// A shape beyond the caller's limit is refused from the header, before its values are
    /// read (a float16 file would otherwise take four times its size as f64).
    #[test]
    fn shapes_beyond_the_limit_are_refused_before_reading() {
        let mut buf = Vec::new();
        write_npy(&mut buf, &[3, 4], &[F16::from_f32(1.0); 12]).unwrap();
        assert_eq!(read_npy_within(&buf[..], 12).unwrap().data.len(), 12);
        match read_npy_within(&buf[..], 11) {
            Err(IoError::NpyTooLarge { shape, limit }) => {
                assert_eq!((shape, limit), (vec![3, 4], 11))
            }
            other => panic!("{other:?}"),
        }
        // The header alone is enough: no data behind it.
        buf.truncate(buf.len() - 24);
        assert!(matches!(
            read_npy_within(&buf[..], 11),
            Err(IoError::NpyTooLarge { .. })
        ));
    }

    /// A header whose shape overflows when its dimensions (or its bytes) are multiplied: an
    /// error, never a short count that a few bytes of data would satisfy.
    #[test]
    fn overflowing_shapes_are_errors() {
        for (shape, why) in [
            ("(4611686018427387905, 1)", "truncated"),
            ("(4294967296, 4294967296)", "more values than can exist"),
            ("(18446744073709551615, 2)", "more values than can exist"),
        ] {
            let header = format!("{{'descr': '<f4', 'fortran_order': False, 'shape': {shape}, }}");
            let header = format!("{header:<117}\n");
            let mut buf = b"\x93NUMPY\x01\x00".to_vec();
            buf.extend((header.len() as u16).to_le_bytes());
            buf.extend(header.as_bytes());
            buf.extend(1.0f32.to_le_bytes());
            let err = read_npy(&buf[..]).unwrap_err().to_string();
            assert!(err.contains(why), "{shape}: {err}");
        }
    }
}
