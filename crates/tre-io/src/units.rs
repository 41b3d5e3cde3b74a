//! Sizes for people: byte counts and pixel counts read with binary suffixes (`32MiB`, `4Mi`,
//! `512k`) and written the same way (`32 MiB`), so that help texts, errors and logs never show
//! `33554432`; and times given as whole milliseconds or seconds (`--stall-timeout-ms 700`).

use std::num::ParseIntError;
use std::time::Duration;

/// A size or a time that does not read ([`parse_size`], [`parse_millis`], [`parse_seconds`]).
// The cause is in the message, not a `source`, as in the crate's other errors.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum UnitsError {
    /// Not a whole number with a known suffix, or too large.
    #[error("{text:?}: expected a whole number with an optional k, M or G (KiB, MiB, GiB) suffix")]
    Size {
        /// The text given.
        text: String,
    },
    /// Not a whole number of milliseconds.
    #[error("{text:?}: expected a whole number of milliseconds ({reason})")]
    Millis {
        /// The text given.
        text: String,
        /// Why it does not parse.
        reason: ParseIntError,
    },
    /// Not a whole number of seconds.
    #[error("{text:?}: expected a whole number of seconds ({reason})")]
    Seconds {
        /// The text given.
        text: String,
        /// Why it does not parse.
        reason: ParseIntError,
    },
}

/// Reads a size: a whole number with an optional suffix `k`/`Ki`/`KiB` (2¹⁰), `M`/`Mi`/`MiB`
/// (2²⁰) or `G`/`Gi`/`GiB` (2³⁰), case-insensitive, `B` optional, spaces allowed.
///
/// ```
/// use tre_io::units::parse_size;
/// assert_eq!(parse_size("32MiB"), Ok(32 << 20));
/// assert_eq!(parse_size("4 Mi"), Ok(4 << 20));
/// assert_eq!(parse_size("512k"), Ok(512 << 10));
/// assert_eq!(parse_size("1000"), Ok(1000));
/// assert!(parse_size("1.5M").is_err() && parse_size("M").is_err() && parse_size("9ZB").is_err());
/// ```
///
/// # Errors
///
/// [`UnitsError::Size`], naming `text`.
pub fn parse_size(text: &str) -> Result<usize, UnitsError> {
    let t = text.trim();
    let digits = t.chars().take_while(char::is_ascii_digit).count();
    let (number, suffix) = t.split_at(digits);
    let bad = || UnitsError::Size {
        text: text.to_owned(),
    };
    let n: usize = number.parse().map_err(|_| bad())?;
    let shift = match suffix.trim().to_ascii_lowercase().trim_end_matches('b') {
        "" => 0,
        "k" | "ki" => 10,
        "m" | "mi" => 20,
        "g" | "gi" => 30,
        _ => return Err(bad()),
    };
    n.checked_mul(1 << shift).ok_or_else(bad)
}

/// Reads a time given as a whole number of milliseconds.
///
/// ```
/// use std::time::Duration;
/// use tre_io::units::parse_millis;
/// assert_eq!(parse_millis("1500"), Ok(Duration::from_millis(1500)));
/// assert!(parse_millis("1.5").is_err() && parse_millis("-1").is_err());
/// ```
///
/// # Errors
///
/// [`UnitsError::Millis`], naming `text`.
pub fn parse_millis(text: &str) -> Result<Duration, UnitsError> {
    text.trim()
        .parse()
        .map(Duration::from_millis)
        .map_err(|reason| UnitsError::Millis {
            text: text.to_owned(),
            reason,
        })
}

/// Reads a time given as a whole number of seconds.
///
/// ```
/// use std::time::Duration;
/// use tre_io::units::parse_seconds;
/// assert_eq!(parse_seconds("30"), Ok(Duration::from_secs(30)));
/// assert!(parse_seconds("0.5").is_err());
/// ```
///
/// # Errors
///
/// [`UnitsError::Seconds`], naming `text`.
pub fn parse_seconds(text: &str) -> Result<Duration, UnitsError> {
    text.trim()
        .parse()
        .map(Duration::from_secs)
        .map_err(|reason| UnitsError::Seconds {
            text: text.to_owned(),
            reason,
        })
}

/// A count with a binary suffix when it is a whole number of them, else plain (`unit`: `B`
/// for bytes, empty for pixels).
///
/// ```
/// use tre_io::units::format_size;
/// assert_eq!(format_size(32 << 20, "B"), "32 MiB");
/// assert_eq!(format_size(4 << 20, ""), "4 Mi");
/// assert_eq!(format_size(1500, "B"), "1500 B");
/// assert_eq!(format_size(3 << 30, "B"), "3 GiB");
/// ```
pub fn format_size(n: usize, unit: &str) -> String {
    for (shift, prefix) in [(30, "Gi"), (20, "Mi"), (10, "Ki")] {
        if n >= 1 << shift && n.is_multiple_of(1 << shift) {
            return format!("{} {prefix}{unit}", n >> shift);
        }
    }
    if unit.is_empty() {
        n.to_string()
    } else {
        format!("{n} {unit}")
    }
}
