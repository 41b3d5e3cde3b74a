//! Tests of `.npy` reading and writing, hostile headers included.

use super::*;

/// A version-1 `.npy` with `header` (padded as numpy pads it) and `body`.
fn npy_with(header: &str, body: &[u8]) -> Vec<u8> {
    let header = format!("{header:<117}\n");
    let mut buf = b"\x93NUMPY\x01\x00".to_vec();
    buf.extend((header.len() as u16).to_le_bytes());
    buf.extend(header.as_bytes());
    buf.extend(body);
    buf
}

#[test]
fn round_trip_f32() {
    let mut buf = Vec::new();
    write_npy(&mut buf, &[2, 3], &[1.0f32, 2.0, 3.5, -1.0, f32::NAN, 0.0]).unwrap();
    assert_eq!(buf.len(), 128 + 6 * 4);
    let a = read_npy(&buf[..]).unwrap();
    assert_eq!(a.shape, vec![2, 3]);
    assert_eq!(a.dtype, "<f4");
    assert_eq!(a.data[2], 3.5);
    assert!(a.data[4].is_nan());
}

/// The header is the one `np.save` writes, byte for byte: version 1.0, the dict in numpy's
/// order and spelling, spaces to a multiple of 64 bytes, a newline.
#[test]
fn written_headers_are_numpys() {
    let header = |buf: &[u8]| String::from_utf8(buf[10..128].to_vec()).unwrap();
    let mut buf = Vec::new();
    write_npy(&mut buf, &[120, 160, 3], &vec![0.0f32; 120 * 160 * 3]).unwrap();
    assert_eq!(&buf[..10], b"\x93NUMPY\x01\x00\x76\x00");
    let want = "{'descr': '<f4', 'fortran_order': False, 'shape': (120, 160, 3), }";
    assert_eq!(header(&buf), format!("{want:<117}\n"));
    let mut buf = Vec::new();
    write_npy(&mut buf, &[2], &[1u8, 2]).unwrap();
    let want = "{'descr': '|u1', 'fortran_order': False, 'shape': (2,), }";
    assert_eq!(header(&buf), format!("{want:<117}\n"));
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
    let a = read_npy(&buf[..]).unwrap();
    assert_eq!((a.data, a.dtype.as_str()), (vec![0.5, -1.0], "<f2"));
}

#[test]
fn every_numeric_dtype_reads_in_either_byte_order() {
    let cases: [(&str, Vec<u8>, Vec<f64>); 7] = [
        ("|u1", vec![0, 255], vec![0.0, 255.0]),
        ("|i1", vec![0xFF, 7], vec![-1.0, 7.0]),
        ("|b1", vec![1, 0], vec![1.0, 0.0]),
        (">u2", vec![1, 2, 0, 3], vec![258.0, 3.0]),
        ("<i2", vec![0xFE, 0xFF, 3, 0], vec![-2.0, 3.0]),
        (
            ">f4",
            [1.5f32.to_be_bytes(), (-2.0f32).to_be_bytes()].concat(),
            vec![1.5, -2.0],
        ),
        (
            "<u8",
            [7u64.to_le_bytes(), 9u64.to_le_bytes()].concat(),
            vec![7.0, 9.0],
        ),
    ];
    for (dtype, body, want) in cases {
        let header = format!("{{'descr': '{dtype}', 'fortran_order': False, 'shape': (2,), }}");
        let a = read_npy(&npy_with(&header, &body)[..]).unwrap();
        assert_eq!(a.is_float(), dtype.contains('f'), "{dtype}");
        assert_eq!((a.data, a.dtype.as_str()), (want, dtype));
    }
}

#[test]
fn integers_write_with_their_dtype() {
    for (buf, dtype) in [
        (npy_bytes(&[1u8, 2]), "|u1"),
        (npy_bytes(&[1u16, 2]), "<u2"),
        (npy_bytes(&[1u32, 2]), "<u4"),
        (npy_bytes(&[-1i32, 2]), "<i4"),
        (npy_bytes(&[1.0f64, 2.0]), "<f8"),
    ] {
        let a = read_npy(&buf[..]).unwrap();
        assert_eq!(a.dtype, dtype);
        assert_eq!(a.data[1], 2.0);
    }
}

#[test]
fn data_that_does_not_fill_the_shape_is_not_written() {
    let mut buf = Vec::new();
    let e = write_npy(&mut buf, &[2, 3], &[1.0f32; 5]).unwrap_err();
    assert_eq!(e.kind(), std::io::ErrorKind::InvalidInput);
    assert!(buf.is_empty());
}

fn npy_bytes<T: NpyElement>(data: &[T]) -> Vec<u8> {
    let mut buf = Vec::new();
    write_npy(&mut buf, &[data.len()], data).unwrap();
    buf
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
        Err(NpyError::TooLarge { shape, limit }) => {
            assert_eq!((shape, limit), (vec![3, 4], 11))
        }
        other => panic!("{other:?}"),
    }
    // The header alone is enough: no data behind it.
    buf.truncate(buf.len() - 24);
    assert!(matches!(
        read_npy_within(&buf[..], 11),
        Err(NpyError::TooLarge { .. })
    ));
}

/// A header whose shape overflows when its dimensions (or its bytes) are multiplied: an
/// error, never a short count that a few bytes of data would satisfy, and never a panic.
#[test]
fn overflowing_shapes_are_errors() {
    for (shape, why) in [
        ("(4611686018427387905, 1)", "truncated"),
        ("(4294967296, 4294967296)", "more values than can exist"),
        ("(18446744073709551615, 2)", "more values than can exist"),
        // npyz's strides multiply every dimension but the last in C order.
        ("(4294967296, 4294967296, 0)", "more values than can exist"),
        ("[4294967296, 4294967296]", "more values than can exist"),
    ] {
        let header = format!("{{'descr': '<f4', 'fortran_order': False, 'shape': {shape}, }}");
        let err = read_npy(&npy_with(&header, &1.0f32.to_le_bytes())[..])
            .unwrap_err()
            .to_string();
        assert!(err.contains(why), "{shape}: {err}");
    }
    // A second `shape` key (a dict keeps the last): each one is checked.
    let header = "{'shape': (1,), 'descr': '<f4', 'fortran_order': False, \
                  'shape': (4294967296, 4294967296), }";
    let e = read_npy(&npy_with(header, &[])[..]).unwrap_err();
    assert!(matches!(e, NpyError::ShapeOverflow { .. }), "{e}");
}

/// The preamble is checked before npyz sizes anything from it: a declared header longer than
/// the limit or than the file is refused at once.
#[test]
fn hostile_preambles_are_refused_from_the_bytes() {
    let mut huge = b"\x93NUMPY\x02\x00".to_vec();
    huge.extend(u32::MAX.to_le_bytes());
    let e = read_npy(&huge[..]).unwrap_err();
    assert!(
        matches!(e, NpyError::HeaderTooLong { len, limit: MAX_HEADER_BYTES } if len == u32::MAX as usize),
        "{e}"
    );
    let mut short = b"\x93NUMPY\x01\x00".to_vec();
    short.extend(100u16.to_le_bytes());
    short.extend(b"{'descr'");
    let e = read_npy(&short[..]).unwrap_err();
    assert!(
        matches!(
            e,
            NpyError::TruncatedHeader {
                declared: 100,
                present: 8
            }
        ),
        "{e}"
    );
    let e = read_npy(&b"\x93NUMPY\x09\x00\x10\x00"[..]).unwrap_err();
    assert_eq!(e.to_string(), "unsupported .npy version 9.0");
    let e = read_npy(&b"\x93NUMPY\x02\x00\x10"[..]).unwrap_err();
    assert!(matches!(e, NpyError::TruncatedPreamble { len: 9 }), "{e}");
    assert!(matches!(
        read_npy(&b"\x93NUMPZ\x01\x00\x10\x00"[..]),
        Err(NpyError::BadMagic)
    ));
}

/// A header of nothing but nested brackets, as long as allowed: an error with a short
/// message, on a test thread's ordinary stack.
#[test]
fn deeply_nested_headers_are_errors() {
    let depth = (MAX_HEADER_BYTES - 60) / 2;
    let header = format!(
        "{{'descr': '<f4', 'fortran_order': False, 'shape': {}{}}}",
        "(".repeat(depth),
        ")".repeat(depth)
    );
    let mut buf = b"\x93NUMPY\x01\x00".to_vec();
    buf.extend((header.len() as u16).to_le_bytes());
    buf.extend(header.as_bytes());
    let e = read_npy(&buf[..]).unwrap_err();
    assert!(
        matches!(
            e,
            NpyError::Header {
                reason: HeaderProblem::Literal(_) | HeaderProblem::Npyz(_)
            }
        ),
        "{e}"
    );
    assert!(e.to_string().chars().count() < 300, "{e}");
    let not_text = npy_with("{'descr': '\u{0}\u{ff}'}", &[]);
    let mut not_text = not_text;
    not_text[20] = 0xFF;
    let e = read_npy(&not_text[..]).unwrap_err();
    assert!(
        matches!(
            e,
            NpyError::Header {
                reason: HeaderProblem::NotText(_)
            }
        ),
        "{e}"
    );
    assert_eq!(
        e.to_string(),
        "unreadable .npy header: the header is not UTF-8 text"
    );
}

#[test]
fn fortran_order_and_non_numeric_dtypes_are_refused() {
    let fortran = "{'descr': '<f4', 'fortran_order': True, 'shape': (2, 2), }";
    let e = read_npy(&npy_with(fortran, &[0; 16])[..]).unwrap_err();
    assert!(e.to_string().contains("np.ascontiguousarray"), "{e}");
    for dtype in ["'<c8'", "'<U3'", "'|O'", "'<M8[s]'", "[('a', '<f4')]"] {
        let header = format!("{{'descr': {dtype}, 'fortran_order': False, 'shape': (1,), }}");
        let e = read_npy(&npy_with(&header, &[0; 16])[..]).unwrap_err();
        assert!(
            matches!(&e, NpyError::UnsupportedDtype { .. }) && e.to_string().contains("float32"),
            "{dtype}: {e}"
        );
    }
}
