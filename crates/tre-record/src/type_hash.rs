//! ROS 2 type hashes (REP 2016, `RIHS01_` and 64 hex digits), computed from the `.msg`
//! definitions of [`RosMessage`]: the SHA-256 of the type description (the type's fields and
//! those of every type it uses, without constants and default values) written as the
//! canonical JSON of `rosidl_generator_type_description`. Recordings carry the hash in each
//! channel's `topic_type_hash` metadata, where rosbag2's MCAP storage reads it.

use sha2::{Digest, Sha256};

use crate::msgs::RosMessage;

/// A `.msg` definition whose type hash cannot be computed.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum TypeHashError {
    /// A line that is neither a field nor a constant.
    #[error("{type_name}: line {line:?}")]
    Line {
        /// The type whose section holds it.
        type_name: String,
        /// The line, comment removed.
        line: String,
    },
    /// An array type without its closing `]`.
    #[error("array type {field_type:?}")]
    Array {
        /// The type as written.
        field_type: String,
    },
    /// An array bound that is not a whole number.
    #[error("{field_type:?}: {source}")]
    Bound {
        /// The type as written.
        field_type: String,
        /// Why the bound does not parse.
        #[source]
        source: std::num::ParseIntError,
    },
    /// A definition without a type.
    #[error("no type")]
    NoType,
    /// A type used whose definition the text does not hold.
    #[error("{type_name}: no definition of {used}")]
    Undefined {
        /// The type hashed.
        type_name: String,
        /// The type it uses (`pkg/msg/Name`).
        used: String,
    },
}

/// The `RIHS01_…` hash of `M`.
///
/// # Errors
///
/// A line of its definition that is not a field or a constant, or a type it uses whose
/// definition is missing.
pub fn rihs01_of<M: RosMessage>() -> Result<String, TypeHashError> {
    rihs01(&M::schema_name(), &M::definition())
}

/// A field's type in a type description (`type_description_interfaces/msg/FieldType`).
#[derive(Debug, Clone, PartialEq, Eq)]
struct FieldType {
    type_id: u32,
    capacity: u64,
    string_capacity: u64,
    nested: String,
}

/// One type's name and fields.
#[derive(Debug, Clone)]
struct Individual {
    name: String,
    fields: Vec<(String, FieldType)>,
}

/// `pkg/Name` or `pkg/msg/Name` (or `Name` in `package`, `Header` in std_msgs) as
/// `pkg/msg/Name`.
fn full_name(t: &str, package: &str) -> String {
    match t.split('/').collect::<Vec<_>>()[..] {
        [pkg, name] => format!("{pkg}/msg/{name}"),
        [_, _, _] => t.to_owned(),
        _ if t == "Header" => "std_msgs/msg/Header".to_owned(),
        _ => format!("{package}/msg/{t}"),
    }
}

/// The id of a scalar type (1 for a nested type), and a bounded string's capacity.
fn base_id(t: &str) -> (u32, u64) {
    if let Some(n) = t.strip_prefix("string<=") {
        return (21, n.parse().unwrap_or(0));
    }
    if let Some(n) = t.strip_prefix("wstring<=") {
        return (22, n.parse().unwrap_or(0));
    }
    let id = match t {
        "int8" => 2,
        // rosidl maps `char` to uint8.
        "uint8" | "char" => 3,
        "int16" => 4,
        "uint16" => 5,
        "int32" => 6,
        "uint32" => 7,
        "int64" => 8,
        "uint64" => 9,
        "float32" => 10,
        "float64" => 11,
        "bool" => 15,
        "byte" => 16,
        "string" => 17,
        "wstring" => 18,
        _ => 1,
    };
    (id, 0)
}

/// A field's type as written in a `.msg` line (`float64[9]`, `uint8[]`, `pkg/T[<=4]`).
fn field_type(t: &str, package: &str) -> Result<FieldType, TypeHashError> {
    let (base, offset, capacity) = match t.split_once('[') {
        None => (t, 0, 0),
        Some((base, rest)) => {
            let inner = rest.strip_suffix(']').ok_or_else(|| TypeHashError::Array {
                field_type: t.to_owned(),
            })?;
            let number = |s: &str| {
                s.parse::<u64>().map_err(|source| TypeHashError::Bound {
                    field_type: t.to_owned(),
                    source,
                })
            };
            match inner.strip_prefix("<=") {
                _ if inner.is_empty() => (base, 144, 0),
                Some(n) => (base, 96, number(n)?),
                None => (base, 48, number(inner)?),
            }
        }
    };
    let (id, string_capacity) = base_id(base);
    Ok(FieldType {
        type_id: id + offset,
        capacity,
        string_capacity,
        nested: if id == 1 {
            full_name(base, package)
        } else {
            String::new()
        },
    })
}

/// The fields of one `.msg` text (constants, comments and default values left out).
fn parse(name: &str, text: &str) -> Result<Individual, TypeHashError> {
    let package = name.split('/').next().unwrap_or_default();
    let mut fields = Vec::new();
    for line in text.lines() {
        let line = line.split('#').next().unwrap_or_default().trim();
        let mut words = line.split_whitespace();
        let (Some(t), Some(field)) = (words.next(), words.next()) else {
            if line.is_empty() {
                continue;
            }
            return Err(TypeHashError::Line {
                type_name: name.to_owned(),
                line: line.to_owned(),
            });
        };
        if field.contains('=') || words.next() == Some("=") {
            continue; // a constant
        }
        fields.push((field.to_owned(), field_type(t, package)?));
    }
    Ok(Individual {
        name: name.to_owned(),
        fields,
    })
}

/// The `.msg` sections of a definition: the main type's, then each `MSG: pkg/Name`.
fn sections(name: &str, definition: &str) -> Result<Vec<Individual>, TypeHashError> {
    let mut out = Vec::new();
    let mut current = (name.to_owned(), String::new());
    for line in definition.lines() {
        if line.starts_with("=====") {
            continue;
        }
        if let Some(next) = line.strip_prefix("MSG: ") {
            out.push(parse(&current.0, &current.1)?);
            current = (full_name(next.trim(), ""), String::new());
        } else {
            current.1.push_str(line);
            current.1.push('\n');
        }
    }
    out.push(parse(&current.0, &current.1)?);
    Ok(out)
}

/// `s` as a JSON string, as Python's `json.dumps` writes it (ASCII only).
fn json_string(s: &str, out: &mut String) {
    out.push('"');
    for c in s.chars() {
        match c {
            '"' => out.push_str("\\\""),
            '\\' => out.push_str("\\\\"),
            '\n' => out.push_str("\\n"),
            '\r' => out.push_str("\\r"),
            '\t' => out.push_str("\\t"),
            c if c.is_ascii() && (c as u32) >= 0x20 => out.push(c),
            c => {
                let mut buf = [0u16; 2];
                for unit in c.encode_utf16(&mut buf) {
                    out.push_str(&format!("\\u{unit:04x}"));
                }
            }
        }
    }
    out.push('"');
}

fn json_individual(t: &Individual, out: &mut String) {
    out.push_str("{\"type_name\": ");
    json_string(&t.name, out);
    out.push_str(", \"fields\": [");
    for (i, (name, ft)) in t.fields.iter().enumerate() {
        if i > 0 {
            out.push_str(", ");
        }
        out.push_str("{\"name\": ");
        json_string(name, out);
        out.push_str(&format!(
            ", \"type\": {{\"type_id\": {}, \"capacity\": {}, \"string_capacity\": {}, \
             \"nested_type_name\": ",
            ft.type_id, ft.capacity, ft.string_capacity
        ));
        json_string(&ft.nested, out);
        out.push_str("}}");
    }
    out.push_str("]}");
}

/// The hash of the type `name` (`pkg/msg/Name`) of `definition` (its `.msg` text, then a
/// `MSG: pkg/Name` section per type it uses).
///
/// # Errors
///
/// As [`rihs01_of`].
pub fn rihs01(name: &str, definition: &str) -> Result<String, TypeHashError> {
    let all = sections(name, definition)?;
    let (main, rest) = all.split_first().ok_or(TypeHashError::NoType)?;
    // The types `main` uses, directly or not, sorted by name.
    let mut used: Vec<&Individual> = Vec::new();
    let mut todo: Vec<&str> = main.fields.iter().map(|f| f.1.nested.as_str()).collect();
    while let Some(n) = todo.pop() {
        if n.is_empty() || used.iter().any(|u| u.name == n) {
            continue;
        }
        let t = rest
            .iter()
            .find(|t| t.name == n)
            .ok_or_else(|| TypeHashError::Undefined {
                type_name: name.to_owned(),
                used: n.to_owned(),
            })?;
        used.push(t);
        todo.extend(t.fields.iter().map(|f| f.1.nested.as_str()));
    }
    used.sort_by(|a, b| a.name.cmp(&b.name));
    let mut json = String::from("{\"type_description\": ");
    json_individual(main, &mut json);
    json.push_str(", \"referenced_type_descriptions\": [");
    for (i, t) in used.iter().enumerate() {
        if i > 0 {
            json.push_str(", ");
        }
        json_individual(t, &mut json);
    }
    json.push_str("]}");
    let digest = Sha256::digest(json.as_bytes());
    let hex: String = digest.iter().map(|b| format!("{b:02x}")).collect();
    Ok(format!("RIHS01_{hex}"))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::msgs::{
        CameraInfo, CompressedImage, GridMap, Image, OccupancyGrid, Odometry, PoseStamped,
    };

    /// Hashes published by ROS 2 Jazzy for these types (`std_msgs/msg/String`, and
    /// `rcl_interfaces/msg/Log`: a nested type, constants and a `byte`-free field list).
    #[test]
    fn published_hashes_are_reproduced() {
        assert_eq!(
            rihs01("std_msgs/msg/String", "string data\n").unwrap(),
            "RIHS01_df668c740482bbd48fb39d76a70dfd4bd59db1288021743503259e948f6b1a18"
        );
        let log = "byte DEBUG=10\nbyte INFO=20\nbyte WARN=30\nbyte ERROR=40\nbyte FATAL=50\n\
                   builtin_interfaces/Time stamp\nuint8 level\nstring name # the logger\n\
                   string msg\nstring file\nstring function\nuint32 line\n\
                   ================================================================================\n\
                   MSG: builtin_interfaces/Time\nint32 sec\nuint32 nanosec\n";
        assert_eq!(
            rihs01("rcl_interfaces/msg/Log", log).unwrap(),
            "RIHS01_e28ce254ca8abc06abf92773b74602cdbf116ed34fbaf294fb9f81da9f318eac"
        );
    }

    #[test]
    fn every_message_type_has_a_hash_of_its_own() {
        let hashes = [
            rihs01_of::<Image>(),
            rihs01_of::<CompressedImage>(),
            rihs01_of::<CameraInfo>(),
            rihs01_of::<PoseStamped>(),
            rihs01_of::<Odometry>(),
            rihs01_of::<OccupancyGrid>(),
            rihs01_of::<GridMap>(),
        ]
        .map(Result::unwrap);
        for (i, h) in hashes.iter().enumerate() {
            assert!(h.starts_with("RIHS01_") && h.len() == 71, "{h}");
            assert!(!hashes[..i].contains(h), "{h} twice");
        }
    }

    #[test]
    fn field_types_follow_the_type_description_ids() {
        let t = |s| field_type(s, "sensor_msgs").unwrap();
        assert_eq!((t("float64[9]").type_id, t("float64[9]").capacity), (59, 9));
        assert_eq!(t("uint8[]").type_id, 147);
        assert_eq!(t("int8[]").type_id, 146);
        assert_eq!(t("string<=8").string_capacity, 8);
        let n = t("std_msgs/MultiArrayDimension[]");
        assert_eq!(
            (n.type_id, n.nested.as_str()),
            (145, "std_msgs/msg/MultiArrayDimension")
        );
        assert_eq!(
            t("RegionOfInterest").nested,
            "sensor_msgs/msg/RegionOfInterest"
        );
    }

    #[test]
    fn a_definition_that_does_not_hash_says_where() {
        let said = |def| rihs01("pkg/msg/T", def).expect_err("no hash").to_string();
        assert_eq!(said("float64\n"), "pkg/msg/T: line \"float64\"");
        assert_eq!(said("uint8[4 data\n"), "array type \"uint8[4\"");
        assert_eq!(
            said("uint8[x] data\n"),
            "\"uint8[x]\": invalid digit found in string"
        );
        assert_eq!(said("pkg/U u\n"), "pkg/msg/T: no definition of pkg/msg/U");
    }
}
