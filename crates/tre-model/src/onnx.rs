//! The operator-set versions an ONNX file imports, read straight from its protobuf bytes.
//!
//! An ONNX file is a serialised `ModelProto`; its field 8, `opset_import`, repeats
//! `OperatorSetIdProto { domain = 1 (string), version = 2 (int64) }`. Only the top-level fields
//! and those small messages are walked (varint, 64-bit, length-delimited and 32-bit wire types),
//! so no protobuf compiler or generated code is needed; the graph itself is skipped unread.

/// `ModelProto.opset_import`.
const MODEL_OPSET_IMPORT: u64 = 8;
/// `OperatorSetIdProto.domain`.
const OPSET_DOMAIN: u64 = 1;
/// `OperatorSetIdProto.version`.
const OPSET_VERSION: u64 = 2;

/// One `opset_import` entry: an operator domain (`""` is the default ONNX domain) and its version.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) struct OpsetImport {
    /// Operator domain; `""` (or `"ai.onnx"`) is the default ONNX operator set.
    pub(crate) domain: String,
    /// Operator-set version.
    pub(crate) version: i64,
}

/// What is wrong with bytes that should be an ONNX `ModelProto`.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("not a valid ONNX model: {reason} at byte {offset}")]
pub struct OnnxParseError {
    /// Where the walk stopped.
    pub offset: usize,
    /// What it found there.
    pub reason: &'static str,
}

/// Every `opset_import` entry of a serialised `ModelProto`, in file order (unit test
/// `the_smallest_model_imports_opset_17`).
pub(crate) fn opset_imports(bytes: &[u8]) -> Result<Vec<OpsetImport>, OnnxParseError> {
    let mut reader = Reader { bytes, at: 0 };
    let mut imports = Vec::new();
    while !reader.done() {
        let (field, value) = reader.field()?;
        if let (MODEL_OPSET_IMPORT, Value::Bytes(start, body)) = (field, value) {
            imports.push(opset_entry(body, start)?);
        }
    }
    Ok(imports)
}

/// The version of the default ONNX operator set (domain `""` or `"ai.onnx"`), if imported.
pub(crate) fn default_opset(imports: &[OpsetImport]) -> Option<i64> {
    imports
        .iter()
        .find(|i| i.domain.is_empty() || i.domain == "ai.onnx")
        .map(|i| i.version)
}

/// Parses one `OperatorSetIdProto` that starts at byte `base` of the file.
fn opset_entry(bytes: &[u8], base: usize) -> Result<OpsetImport, OnnxParseError> {
    let mut reader = Reader { bytes, at: 0 };
    let mut entry = OpsetImport {
        domain: String::new(),
        version: 0,
    };
    while !reader.done() {
        let at = base + reader.at;
        match reader.field()? {
            (OPSET_DOMAIN, Value::Bytes(_, text)) => {
                entry.domain = std::str::from_utf8(text)
                    .map_err(|_| OnnxParseError {
                        offset: at,
                        reason: "opset domain is not UTF-8",
                    })?
                    .to_owned();
            }
            // int64 on the wire: two's complement in a 64-bit varint.
            (OPSET_VERSION, Value::Varint(v)) => entry.version = v as i64,
            _ => {}
        }
    }
    Ok(entry)
}

/// A decoded field value; length-delimited bodies keep their file offset.
enum Value<'a> {
    Varint(u64),
    Fixed,
    Bytes(usize, &'a [u8]),
}

/// A cursor over protobuf bytes.
struct Reader<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl<'a> Reader<'a> {
    fn done(&self) -> bool {
        self.at >= self.bytes.len()
    }

    fn fail(&self, reason: &'static str) -> OnnxParseError {
        OnnxParseError {
            offset: self.at,
            reason,
        }
    }

    /// The next field: its number and value.
    fn field(&mut self) -> Result<(u64, Value<'a>), OnnxParseError> {
        let key = self.varint()?;
        let (field, wire) = (key >> 3, key & 7);
        if field == 0 {
            return Err(self.fail("field number 0"));
        }
        let value = match wire {
            0 => Value::Varint(self.varint()?),
            1 => self.skip(8).map(|_| Value::Fixed)?,
            2 => {
                let len = usize::try_from(self.varint()?).map_err(|_| self.fail("huge length"))?;
                let start = self.at;
                Value::Bytes(start, self.skip(len)?)
            }
            5 => self.skip(4).map(|_| Value::Fixed)?,
            _ => return Err(self.fail("unsupported wire type")),
        };
        Ok((field, value))
    }

    /// Consumes `len` bytes.
    fn skip(&mut self, len: usize) -> Result<&'a [u8], OnnxParseError> {
        let end = self
            .at
            .checked_add(len)
            .filter(|&end| end <= self.bytes.len())
            .ok_or_else(|| self.fail("field runs past the end"))?;
        let body = &self.bytes[self.at..end];
        self.at = end;
        Ok(body)
    }

    /// A base-128 varint of at most 10 bytes.
    fn varint(&mut self) -> Result<u64, OnnxParseError> {
        let mut value = 0u64;
        for shift in (0..64).step_by(7) {
            let Some(&byte) = self.bytes.get(self.at) else {
                return Err(self.fail("varint runs past the end"));
            };
            self.at += 1;
            value |= u64::from(byte & 0x7f) << shift;
            if byte & 0x80 == 0 {
                return Ok(value);
            }
        }
        Err(self.fail("varint longer than 10 bytes"))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_smallest_model_imports_opset_17() {
        // ModelProto { ir_version: 8, opset_import: [{ domain: "", version: 17 }] }
        let bytes = [0x08, 8, 0x42, 2, 0x10, 17];
        let imports = opset_imports(&bytes).unwrap();
        assert_eq!(imports[0].version, 17);
        assert_eq!(default_opset(&imports), Some(17));
    }

    #[test]
    fn reads_domains_and_multi_byte_versions_and_skips_other_wire_types() {
        let bytes = [
            0x08, 0x09, // ir_version = 9
            0x11, 1, 2, 3, 4, 5, 6, 7, 8, // field 2, fixed64
            0x3a, 3, b'a', b'b', b'c', // field 7 (graph), bytes
            0x42, 0x0c, 0x0a, 0x08, b'a', b'i', b'.', b'o', b'n', b'n', b'x', b'2', 0x10,
            0x01, // { "ai.onnx2", 1 }
            0x1d, 0, 0, 0, 0, // field 3, fixed32
            0x42, 0x03, 0x10, 0xac, 0x02, // { "", 300 }
        ];
        let imports = opset_imports(&bytes).expect("valid bytes");
        assert_eq!(imports.len(), 2);
        assert_eq!(imports[0].domain, "ai.onnx2");
        assert_eq!(imports[0].version, 1);
        assert_eq!(imports[1].version, 300);
        assert_eq!(default_opset(&imports), Some(300));
    }

    #[test]
    fn truncated_or_garbage_bytes_are_errors_not_panics() {
        assert!(opset_imports(&[0x42, 5, 0x10]).is_err());
        assert!(opset_imports(&[0x80]).is_err());
        assert!(opset_imports(&[0x0b]).is_err());
        assert!(opset_imports(&[0x00, 0x01]).is_err());
        assert_eq!(opset_imports(&[]), Ok(vec![]));
    }
}
