//! The map's settings files (TOML, units in the key names; docs/map.md): `tre map --params`,
//! `tre serve --map-params` and `tre ros2 --map-params` read the same file.

use std::path::{Path, PathBuf};

use tre_core::map::{MapParams, MapParamsFile, MapPreset};

/// A settings file that cannot be used.
#[derive(Debug, thiserror::Error)]
pub enum MapParamsError {
    /// The file cannot be read.
    #[error("{}: {reason}", path.display())]
    Read {
        /// The file.
        path: PathBuf,
        /// What the OS said.
        reason: std::io::Error,
    },
    /// Not TOML, a key it does not know (a misspelling), or a value of the wrong type.
    #[error("{}: {reason}", path.display())]
    Parse {
        /// The file.
        path: PathBuf,
        /// What the parser said (line, column, the key).
        reason: Box<toml::de::Error>,
    },
    /// A value out of its range.
    #[error("{}: {reason}", path.display())]
    Range {
        /// The file.
        path: PathBuf,
        /// Which value, and its range.
        reason: tre_core::map::ParamsError,
    },
}

/// The settings of the file at `path`.
///
/// # Errors
///
/// [`MapParamsError`] when it cannot be read, parsed or checked.
pub fn read_map_params(path: &Path) -> Result<MapParams, MapParamsError> {
    let text = std::fs::read_to_string(path).map_err(|reason| MapParamsError::Read {
        path: path.to_owned(),
        reason,
    })?;
    parse_map_params(&text).map_err(|e| match e {
        ParseOrRange::Parse(reason) => MapParamsError::Parse {
            path: path.to_owned(),
            reason,
        },
        ParseOrRange::Range(reason) => MapParamsError::Range {
            path: path.to_owned(),
            reason,
        },
    })
}

/// Why a settings text is refused.
#[derive(Debug, thiserror::Error)]
pub enum ParseOrRange {
    /// Not the file's syntax or keys.
    #[error("{0}")]
    Parse(Box<toml::de::Error>),
    /// A value out of range.
    #[error("{0}")]
    Range(tre_core::map::ParamsError),
}

/// The settings a TOML text states.
///
/// ```
/// let p = tre_io::map_params::parse_map_params(
///     "preset = \"outdoor\"\n[grid]\ncell_m = 0.2\n",
/// ).unwrap();
/// assert_eq!((p.config.cell_m, p.config.max_range_m), (0.2, 20.0));
/// assert!(tre_io::map_params::parse_map_params("[grid]\ncel_m = 0.2\n").is_err());
/// ```
///
/// # Errors
///
/// [`ParseOrRange`] for a text that is not such a file or a value out of range.
pub fn parse_map_params(text: &str) -> Result<MapParams, ParseOrRange> {
    let file: MapParamsFile = toml::from_str(text).map_err(|e| ParseOrRange::Parse(Box::new(e)))?;
    MapParams::from_file(&file).map_err(ParseOrRange::Range)
}

/// The settings of a `--map-params` value: a preset's name (`indoor`, `outdoor`) or a file.
///
/// # Errors
///
/// [`MapParamsError`] for a file that cannot be used.
pub fn map_params_arg(arg: &str) -> Result<MapParams, MapParamsError> {
    match arg {
        "indoor" => Ok(MapParams::preset(MapPreset::Indoor)),
        "outdoor" => Ok(MapParams::preset(MapPreset::Outdoor)),
        path => read_map_params(Path::new(path)),
    }
}
