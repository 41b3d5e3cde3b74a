//! The domain choices a client, the CLI and the pipeline share (input mode, method, normals,
//! centroids, the roughness map's encoding) and the traversability thresholds: each choice is one
//! enum whose string forms (`rgbd`, `surface-only`, `png16`) are derived once, by strum for
//! parsing and printing, by serde for JSON, and by clap for the CLI.
//!
//! clap's `ValueEnum` is derived behind the `cli` feature (the root package `tre` enables it):
//! the CLI then takes these very enums, instead of copies converted by hand, while the crates
//! that never parse a command line (pipeline, server, client) build this one without clap. A
//! newtype in the CLI could not derive `ValueEnum` and would list the values a second time.
//! The `value(help)` texts are the CLI's one-line help of each value.

use std::str::FromStr;

use serde::{Deserialize, Serialize};
use strum::{EnumMessage, IntoEnumIterator};

/// Declares a domain choice: an enum with the derives every choice has (strum's string forms,
/// serde, and clap's `ValueEnum` behind the `cli` feature). Attributes given inside (docs,
/// `serde`/`strum` casing, an extra `derive(Default)`) follow them.
macro_rules! choice {
    ($(#[$meta:meta])* pub enum $name:ident { $($body:tt)* }) => {
        #[derive(
            Debug,
            Clone,
            Copy,
            PartialEq,
            Eq,
            Hash,
            Serialize,
            Deserialize,
            strum::EnumString,
            strum::AsRefStr,
            strum::IntoStaticStr,
            strum::Display,
            strum::EnumIter,
            strum::VariantNames,
            strum::EnumMessage,
        )]
        #[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
        $(#[$meta])*
        pub enum $name { $($body)* }
    };
}

choice! {
/// Where depth comes from (the paper's Table IV rows).
#[serde(rename_all = "lowercase")]
#[strum(serialize_all = "lowercase")]
pub enum Mode {
    /// One RGB frame; the depth net predicts depth.
    #[cfg_attr(
        feature = "cli",
        value(help = "One RGB frame: the depth net predicts depth")
    )]
    Rgb,
    /// RGB plus a depth-sensor frame; the depth net is skipped.
    #[cfg_attr(
        feature = "cli",
        value(help = "RGB plus a registered depth frame: the depth net is skipped")
    )]
    Rgbd,
    /// Depth only, no networks: annotation spec v1 as `tre annotate` computes it without
    /// labels (LS normals, window centroids, surface and edge terms), or the paper's
    /// surface-only baseline ([`GeometricMethod`]); the switches are ignored.
    #[cfg_attr(
        feature = "cli",
        value(
            help = "Depth only, no networks: annotation spec v1 (surface and edge terms), as `tre annotate`"
        )
    )]
    Geometric,
}
}

impl Mode {
    /// The mode of a frame that does not choose one, from the inputs it has: rgbd with RGB and
    /// depth, geometric with depth alone, else rgb (`tre infer`, HTTP and the stream alike).
    ///
    /// ```
    /// use tre_core::kinds::Mode;
    /// assert_eq!(Mode::implied(true, true), Mode::Rgbd);
    /// assert_eq!(Mode::implied(false, true), Mode::Geometric);
    /// assert_eq!(Mode::implied(true, false), Mode::Rgb);
    /// ```
    #[must_use]
    pub fn implied(rgb: bool, depth: bool) -> Self {
        match (rgb, depth) {
            (true, true) => Self::Rgbd,
            (false, true) => Self::Geometric,
            _ => Self::Rgb,
        }
    }
}

choice! {
/// What the `geometric` mode computes.
#[derive(Default)]
#[serde(rename_all = "kebab-case")]
#[strum(serialize_all = "kebab-case")]
pub enum GeometricMethod {
    /// The terrain estimate (docs/terrain.md): the spec's surface and step terms read through
    /// the sensor's noise model, with supports in metres that need points on both sides of a
    /// step, so holes, scan-line gaps, disparity steps and range noise are not hazards.
    #[default]
    #[cfg_attr(
        feature = "cli",
        value(
            help = "The terrain estimate: surface and step terms through the sensor's noise model (holes, scan-line gaps and noise are not hazards)"
        )
    )]
    Terrain,
    /// The whole of annotation spec v1 on the depth as given: surface term and edge term with
    /// its transient, so drops and steps read as hazards, and so do a sensor's holes and
    /// noise. Equal to `tre annotate` on the same depth.
    #[cfg_attr(
        feature = "cli",
        value(
            help = "The whole annotation spec v1: surface term and edge term (drops and steps are hazards)"
        )
    )]
    Spec,
    /// Annotation spec v1 on the depth cleaned through the terrain estimate's supports under
    /// the sensor's noise model (each point moved towards its support's plane by what the
    /// noise explains, scan-line gaps filled; what the `rgbd` mode reads): the spec's edges
    /// and creases without most of the sensor's noise. For dense structured-light and
    /// time-of-flight depth (docs/terrain.md); on LiDAR and passive stereo the terrain
    /// estimate is the one to use.
    #[cfg_attr(
        feature = "cli",
        value(
            help = "The spec on depth cleaned through the terrain estimate's supports: its edges and creases without most sensor noise (dense structured-light or time-of-flight depth)"
        )
    )]
    SpecCleaned,
    /// The paper's classical baseline: Eq. 1 with LS normals and window centroids, no edge
    /// term (every drop is missed). What the paper's tables use.
    #[cfg_attr(
        feature = "cli",
        value(
            help = "The paper's surface-only baseline: Eq. 1 with LS normals and window centroids, no edge term"
        )
    )]
    SurfaceOnly,
}
}

choice! {
/// The full pipeline or the end-to-end baseline of the paper's Table II.
#[derive(Default)]
#[serde(rename_all = "kebab-case")]
#[strum(serialize_all = "kebab-case")]
pub enum Method {
    /// The staged pipeline of Fig. 5 (the switches choose its stages).
    #[default]
    #[cfg_attr(
        feature = "cli",
        value(help = "The staged pipeline of the paper's Fig. 5")
    )]
    Pipeline,
    /// `end_to_end.onnx`: RGB and the flat-ground prior straight to roughness (needs RGB; the
    /// mode and switches are ignored; no depth, normals or slope come out).
    #[cfg_attr(
        feature = "cli",
        value(help = "The end-to-end baseline (end_to_end.onnx; RGB only)")
    )]
    EndToEnd,
}
}

choice! {
/// How initial normals are estimated.
#[serde(rename_all = "lowercase")]
#[strum(serialize_all = "lowercase")]
pub enum NormalsMethod {
    /// Least-squares planes over the metric neighbourhood (no network).
    #[cfg_attr(feature = "cli", value(help = "Least-squares planes"))]
    Ls,
    /// Neighbour net probabilities and DSAC plane hypotheses.
    #[cfg_attr(feature = "cli", value(help = "Neighbour net and DSAC hypotheses"))]
    Dsac,
}
}

choice! {
/// How the local-plane centroid of Eq. 1 is found.
#[serde(rename_all = "lowercase")]
#[strum(serialize_all = "lowercase")]
pub enum CentroidMethod {
    /// The centroid net (edge- and semantics-aware).
    #[cfg_attr(feature = "cli", value(help = "The centroid net"))]
    Net,
    /// The mean of the neighbourhood's points (no network).
    #[cfg_attr(feature = "cli", value(help = "The mean of the metric neighbourhood"))]
    Window,
}
}

choice! {
/// How a roughness map is encoded: the file `tre infer` writes, the body of an HTTP answer, the
/// map of a stream's result. One enum for all of them; each interface takes the encodings it
/// can carry ([`MapFormat::FILE`], [`MapFormat::HTTP`], [`MapFormat::STREAM`]), and the stream's
/// protocol has its own generated enum, converted in one place (`tre-proto`).
#[derive(Default)]
#[serde(rename_all = "lowercase")]
#[strum(serialize_all = "lowercase")]
pub enum MapFormat {
    /// 16-bit grey + alpha PNG, 0.1 mm per unit, alpha 0 where there is no data (what
    /// `tre infer` writes; decoded to metres by the client).
    #[default]
    #[cfg_attr(
        feature = "cli",
        value(help = "16-bit grey + alpha PNG, 0.1 mm per unit, alpha 0 where there is no data")
    )]
    Png16,
    /// 8-bit turbo colour map PNG of the frame's size (dark grey: no data), for people; not
    /// decoded to metres.
    #[strum(to_string = "color", serialize = "colour")]
    #[cfg_attr(
        feature = "cli",
        value(help = "8-bit turbo colour map PNG of the frame's size")
    )]
    Color,
    /// `(H, W)` float32 `.npy` in metres, NaN where there is no data.
    #[cfg_attr(
        feature = "cli",
        value(help = "(H, W) float32 .npy in metres, NaN where there is no data")
    )]
    Npy,
    /// Raw little-endian float32 metres, row-major, NaN where there is no data (the stream's
    /// `FORMAT_F32`; a file of them is written as `.npy`).
    #[cfg_attr(
        feature = "cli",
        value(help = "Float32 metres, NaN where there is no data (written as .npy)")
    )]
    F32,
}
}

impl MapFormat {
    /// What a file of a map can be (`tre infer --format`).
    pub const FILE: &'static [Self] = &[Self::Png16, Self::Npy];
    /// What an HTTP answer can be (`format=` of `POST /v1/roughness`).
    pub const HTTP: &'static [Self] = &[Self::Png16, Self::Color, Self::Npy];
    /// What a stream's result can be (the protocol's `Format`; `tre client --format`).
    pub const STREAM: &'static [Self] = &[Self::Png16, Self::Color, Self::F32];

    /// The extension of a file holding a map so encoded: `png`, or `npy` for float32 metres.
    #[must_use]
    pub fn extension(self) -> &'static str {
        match self {
            Self::Png16 | Self::Color => "png",
            Self::Npy | Self::F32 => "npy",
        }
    }

    /// MIME type of the encoded map.
    #[must_use]
    pub fn content_type(self) -> &'static str {
        match self {
            Self::Png16 | Self::Color => "image/png",
            Self::Npy | Self::F32 => "application/octet-stream",
        }
    }
}

/// The names a choice of `E` parses from, in declaration order, as a message lists them:
/// `rgb, rgbd or geometric`. Each variant gives its printed name (strum's `to_string`, or the
/// name from `serialize_all`); aliases are left out.
///
/// ```
/// use tre_core::kinds::{one_of, Mode};
/// assert_eq!(one_of::<Mode>(), "rgb, rgbd or geometric");
/// ```
pub fn one_of<E: IntoEnumIterator + Copy + Into<&'static str>>() -> String {
    one_of_these(&E::iter().collect::<Vec<_>>())
}

/// Every name a choice of `E` parses from, aliases after their variant's printed name: the
/// allowed values of a document (`png16, color, colour, npy`).
pub fn names<E: IntoEnumIterator + EnumMessage + Copy + Into<&'static str>>() -> Vec<&'static str> {
    names_of_these(&E::iter().collect::<Vec<_>>())
}

/// `value` as a choice of `E`, or an error naming `field`, the choices and what was given:
/// `mode: expected rgb, rgbd or geometric, got "depth"`.
///
/// ```
/// use tre_core::kinds::{parse_choice, NormalsMethod};
/// assert_eq!(parse_choice::<NormalsMethod>("normals", "ls"), Ok(NormalsMethod::Ls));
/// assert_eq!(
///     parse_choice::<NormalsMethod>("normals", "LS").unwrap_err().to_string(),
///     r#"normals: expected ls or dsac, got "LS""#
/// );
/// ```
pub fn parse_choice<E: IntoEnumIterator + FromStr + Copy + Into<&'static str>>(
    field: &str,
    value: &str,
) -> Result<E, ChoiceError> {
    value.parse().map_err(|_| ChoiceError {
        field: field.to_owned(),
        expected: one_of::<E>(),
        got: value.to_owned(),
    })
}

/// A value that is none of a field's choices: `mode: expected rgb, rgbd or geometric, got "depth"`.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{field}: expected {expected}, got {got:?}")]
pub struct ChoiceError {
    /// The field, as the interface names it.
    pub field: String,
    /// The choices, listed as [`one_of`] writes them.
    pub expected: String,
    /// The value given.
    pub got: String,
}

/// As [`one_of`], for the choices in `allowed` alone: `png16, color or npy`.
pub fn one_of_these<E: Copy + Into<&'static str>>(allowed: &[E]) -> String {
    let names: Vec<&str> = allowed.iter().map(|&v| v.into()).collect();
    match names.split_last() {
        None => String::new(),
        Some((last, [])) => (*last).to_owned(),
        Some((last, rest)) => format!("{} or {last}", rest.join(", ")),
    }
}

/// As [`names`], for the choices in `allowed` alone.
pub fn names_of_these<E: EnumMessage + Copy + Into<&'static str>>(
    allowed: &[E],
) -> Vec<&'static str> {
    let mut names = Vec::new();
    for &v in allowed {
        let first: &'static str = v.into();
        for name in std::iter::once(first).chain(v.get_serializations().iter().copied()) {
            if !names.contains(&name) {
                names.push(name);
            }
        }
    }
    names
}

/// As [`parse_choice`], for an interface that takes the choices in `allowed` alone.
///
/// ```
/// use tre_core::kinds::{parse_choice_of, MapFormat};
/// let http = MapFormat::HTTP;
/// assert_eq!(parse_choice_of("format", "colour", http), Ok(MapFormat::Color));
/// assert_eq!(
///     parse_choice_of("format", "f32", http).unwrap_err().to_string(),
///     r#"format: expected png16, color or npy, got "f32""#
/// );
/// ```
pub fn parse_choice_of<E: FromStr + PartialEq + Copy + Into<&'static str>>(
    field: &str,
    value: &str,
    allowed: &[E],
) -> Result<E, ChoiceError> {
    value
        .parse()
        .ok()
        .filter(|v| allowed.contains(v))
        .ok_or_else(|| ChoiceError {
            field: field.to_owned(),
            expected: one_of_these(allowed),
            got: value.to_owned(),
        })
}

/// clap's parser of an option that takes the choices in `allowed` alone, each listed in
/// `--help` with its own help (`tre infer --format`: [`MapFormat::FILE`]).
#[cfg(feature = "cli")]
pub fn value_parser_of<E>(allowed: &'static [E]) -> impl clap::builder::TypedValueParser<Value = E>
where
    E: clap::ValueEnum + Clone + Send + Sync + 'static,
{
    use clap::builder::TypedValueParser;
    let values = allowed
        .iter()
        .filter_map(clap::ValueEnum::to_possible_value);
    clap::builder::PossibleValuesParser::new(values).map(|name| {
        E::from_str(&name, false).expect("clap accepted one of the listed names; this is a bug")
    })
}

/// DSAC hypotheses per pixel that the models were trained with (docs/design.md: K = 12).
pub const DEFAULT_DSAC_HYPOTHESES: u32 = 12;

/// Most DSAC hypotheses per pixel accepted. With the same seed, hypothesis `j` is the same for
/// every K above `j`, so a larger K never scores lower.
pub const MAX_DSAC_HYPOTHESES: u32 = 64;

/// clap's parser of a `--dsac-hypotheses` option: 1 to [`MAX_DSAC_HYPOTHESES`].
#[cfg(feature = "cli")]
pub fn dsac_hypotheses_parser() -> clap::builder::RangedI64ValueParser<u32> {
    clap::value_parser!(u32).range(1..=i64::from(MAX_DSAC_HYPOTHESES))
}

/// Thresholds of the traversability map: a pixel is traversable when its roughness and its
/// slope are both at most these (pixels without data are not traversable).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Traversability {
    /// Largest roughness a robot drives over, metres (default 0.05).
    pub max_roughness_m: f64,
    /// Steepest slope a robot drives on, radians from horizontal (default 20°).
    pub max_slope_rad: f64,
}

impl Default for Traversability {
    fn default() -> Self {
        Self {
            max_roughness_m: 0.05,
            max_slope_rad: 20f64.to_radians(),
        }
    }
}

impl Traversability {
    /// The thresholds as a robot states them: roughness in centimetres (above 0) and slope in
    /// degrees (0 to 90), each defaulting to [`Traversability::default`]'s (5 cm, 20°); for
    /// values that cannot be thresholds, why not.
    ///
    /// ```
    /// use tre_core::kinds::Traversability;
    /// let t = Traversability::from_cm_deg(Some(2.0), None).unwrap();
    /// assert_eq!((t.max_roughness_m, t.max_slope_rad), (0.02, 20f64.to_radians()));
    /// assert!(Traversability::from_cm_deg(Some(0.0), None).is_err());
    /// assert!(Traversability::from_cm_deg(None, Some(95.0)).is_err());
    /// ```
    pub fn from_cm_deg(
        max_roughness_cm: Option<f64>,
        max_slope_deg: Option<f64>,
    ) -> Result<Self, TraversabilityError> {
        let default = Self::default();
        if let Some(cm) = max_roughness_cm.filter(|cm| !(cm.is_finite() && *cm > 0.0)) {
            return Err(TraversabilityError::Roughness(cm));
        }
        if let Some(deg) = max_slope_deg.filter(|d| !(0.0..=90.0).contains(d)) {
            return Err(TraversabilityError::Slope(deg));
        }
        Ok(Self {
            max_roughness_m: max_roughness_cm.map_or(default.max_roughness_m, |cm| cm / 100.0),
            max_slope_rad: max_slope_deg.map_or(default.max_slope_rad, f64::to_radians),
        })
    }
}

/// Limits of [`Traversability::from_cm_deg`] out of their range; the message starts with the
/// setting's name (`max_roughness_cm`, `max_slope_deg`), as every interface spells it.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum TraversabilityError {
    /// A largest roughness that is not a positive number of centimetres.
    #[error("max_roughness_cm: must be positive, got {0}")]
    Roughness(f64),
    /// A steepest slope outside 0 to 90 degrees.
    #[error("max_slope_deg: must be 0 to 90, got {0}")]
    Slope(f64),
}

#[cfg(test)]
mod tests {
    use super::*;
    use strum::VariantNames;

    /// strum's names (parsing, printing) and serde's (JSON) of every variant of `E` are the
    /// same, and `expected` in order.
    fn one_spelling<E>(expected: &[&str])
    where
        E: IntoEnumIterator + EnumMessage + AsRef<str> + FromStr + VariantNames + Serialize,
        E: PartialEq + Copy + Into<&'static str>,
        E: std::fmt::Debug + std::fmt::Display + for<'de> Deserialize<'de>,
    {
        assert_eq!(E::VARIANTS, expected);
        assert_eq!(names::<E>(), expected);
        for (v, name) in E::iter().zip(expected) {
            assert_eq!((v.as_ref(), v.to_string().as_str()), (*name, *name));
            assert_eq!(name.parse::<E>().ok().as_ref(), Some(&v));
            let json = serde_json::to_value(v).expect("serialises");
            assert_eq!(json, serde_json::json!(name), "{v:?}");
            let back: E = serde_json::from_value(json).expect("deserialises");
            assert_eq!(back, v);
        }
    }

    #[test]
    fn each_choice_has_one_spelling_everywhere() {
        one_spelling::<Mode>(&["rgb", "rgbd", "geometric"]);
        one_spelling::<GeometricMethod>(&["terrain", "spec", "spec-cleaned", "surface-only"]);
        one_spelling::<Method>(&["pipeline", "end-to-end"]);
        one_spelling::<NormalsMethod>(&["ls", "dsac"]);
        one_spelling::<CentroidMethod>(&["net", "window"]);
    }

    #[test]
    fn bad_choices_name_the_field_and_the_choices() {
        assert_eq!(
            parse_choice::<Mode>("mode", "depth")
                .unwrap_err()
                .to_string(),
            r#"mode: expected rgb, rgbd or geometric, got "depth""#
        );
        assert_eq!(
            parse_choice::<Mode>("mode", "RGB").unwrap_err().to_string(),
            r#"mode: expected rgb, rgbd or geometric, got "RGB""#
        );
        assert_eq!(
            parse_choice::<Method>("method", "end-to-end"),
            Ok(Method::EndToEnd)
        );
        assert_eq!(one_of::<MapFormat>(), "png16, color, npy or f32");
        assert_eq!(one_of_these(MapFormat::STREAM), "png16, color or f32");
        assert_eq!(MapFormat::Color.to_string(), "color");
        assert_eq!(
            serde_json::json!(MapFormat::Color),
            serde_json::json!("color")
        );
        assert_eq!("colour".parse(), Ok(MapFormat::Color));
        assert_eq!(
            names::<MapFormat>(),
            ["png16", "color", "colour", "npy", "f32"]
        );
        assert_eq!(
            names_of_these(MapFormat::HTTP),
            ["png16", "color", "colour", "npy"]
        );
    }

    /// The CLI's values are the same names (clap derives its own from the variants).
    #[cfg(feature = "cli")]
    #[test]
    fn the_cli_values_are_the_same_names() {
        fn same<E: clap::ValueEnum + AsRef<str>>() {
            for v in E::value_variants() {
                let pv = v.to_possible_value().expect("no variant is skipped");
                assert_eq!(pv.get_name(), v.as_ref());
                assert!(pv.get_help().is_some(), "{} has no help", v.as_ref());
            }
        }
        same::<Mode>();
        same::<GeometricMethod>();
        same::<Method>();
        same::<NormalsMethod>();
        same::<CentroidMethod>();
        same::<MapFormat>();
    }
}
