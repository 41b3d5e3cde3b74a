//! The query of `POST /v1/roughness`: its parameters, documented here for the OpenAPI document
//! (each field's doc comment is its description there), and their checks. Choices are parsed
//! by their enums ([`tre_core::kinds`], [`MapFormat`], [`OutputMap`]), whose names are also the
//! document's allowed values.

use std::str::FromStr;

use serde::Deserialize;
use strum::{EnumMessage, IntoEnumIterator};
use utoipa::openapi::schema::{ObjectBuilder, Schema, Type};
use utoipa::openapi::RefOr;
use utoipa::{IntoParams, PartialSchema, ToSchema};

use super::error::{CameraError, OptionError, RequestError};
use super::options::{Extras, FrameOptions, OutputMap};
use super::request::{check_camera_ranges, DecodeLimits};
use tre_core::kinds::{
    names, names_of_these, parse_choice, parse_choice_of, MapFormat, Mode, NormalsMethod,
};
use tre_io::CameraFile;
use tre_pipeline::{check_dsac_hypotheses, Traversability, MAX_DSAC_HYPOTHESES};

/// Query of `POST /v1/roughness`.
#[derive(Debug, Default, Deserialize, IntoParams)]
#[serde(deny_unknown_fields)]
#[into_params(parameter_in = Query)]
pub(crate) struct RoughnessQuery {
    /// png16: 16-bit grey+alpha PNG, X-Roughness-Scale-M metres per unit, alpha 0 = no data;
    /// color (or colour): 8-bit turbo preview; npy: (H, W) float32 metres, NaN = no data.
    #[param(value_type = Option<FormatParam>, inline)]
    format: Option<String>,
    /// Default: rgbd with rgb and depth, geometric with depth alone, else rgb.
    #[param(value_type = Option<ModeParam>, inline)]
    mode: Option<String>,
    /// DSAC sampler seed: the same seed gives the same map.
    #[param(default = 0)]
    seed: Option<u64>,
    /// Initial normals: dsac (neighbour net + DSAC, the paper's method) or ls (least squares,
    /// faster). Default: the server's --normals (dsac).
    #[param(value_type = Option<NormalsParam>, inline)]
    normals: Option<String>,
    /// DSAC plane hypotheses per pixel (fewer are faster; 4 keeps the accuracy of 12 on the
    /// synthetic test split). Default: the server's --dsac-hypotheses (12, as trained).
    #[param(value_type = Option<DsacHypothesesParam>, inline)]
    dsac_hypotheses: Option<u32>,
    /// Top of the colour scale of format=color.
    #[param(exclusive_minimum = 0, default = 5)]
    preview_max_cm: Option<f64>,
    /// Traversability: the largest roughness a pixel may have, centimetres.
    #[param(exclusive_minimum = 0, default = 5)]
    max_roughness_cm: Option<f64>,
    /// Traversability: the steepest slope a pixel may have in the gravity frame, degrees.
    #[param(minimum = 0, maximum = 90, default = 20)]
    max_slope_deg: Option<f64>,
    /// Extra maps, comma-separated: depth, normals, slope, traversable, boundary, uncertainty,
    /// traversal. With any, the answer is multipart/mixed with one part per map. uncertainty
    /// (16-bit grey + alpha PNG, 0.1 mm per unit: the p95 of the roughness sensor noise alone
    /// gives on a flat surface; in rgb the calibrated interval's half-width) and traversal
    /// (8-bit grey PNG: 0 unknown, 1 traversable, 2 hazard) need sensor depth (modes rgbd and
    /// geometric) and a noise model (the sensor parameter or the camera's sensor; otherwise
    /// 422 bad_camera), or in rgb the models' calibrated intervals (otherwise 422 bad_input).
    /// Where the models have calibrated intervals, a pixel is traversable only where the 90%
    /// interval's upper end is below max_roughness_cm and a hazard only where its lower end
    /// is above; see docs/uncertainty.md and docs/sensor-noise.md.
    outputs: Option<String>,
    /// Intrinsics in pixels; default: 60 degree horizontal field of view, centred. The camera
    /// in the query (fx, fy, cx, cy, pitch_deg, height_m, depth_scale) is for a body with no
    /// camera part (a bare image, or multipart without camera; both is 400 bad_request): with
    /// any of its seven parameters, all four intrinsics are required (else 422 bad_camera).
    fx: Option<f64>,
    fy: Option<f64>,
    cx: Option<f64>,
    cy: Option<f64>,
    /// Camera pitch below the horizon, degrees; needs fx, fy, cx, cy.
    #[param(default = 60)]
    pitch_deg: Option<f64>,
    /// Camera height above the ground, metres; needs fx, fy, cx, cy.
    #[param(default = 1)]
    height_m: Option<f64>,
    /// Units per metre of a 16-bit depth PNG; needs fx, fy, cx, cy.
    #[param(default = 1000)]
    depth_scale: Option<f64>,
    /// Depth sensor noise model for the uncertainty and traversal maps, overriding the
    /// camera's sensor: a preset (kinect_v1, realsense_d435, azure_kinect, lidar, lidar_accumulated, passive_stereo, exact) or
    /// coefficients a,b,c (sigma_z = a + b*z + c*z^2 mm, z in metres).
    sensor: Option<String>,
}

/// The schema of a parameter whose values are the names an enum parses from.
macro_rules! choice_param {
    ($(#[$doc:meta])* $param:ident, $choice:ty) => {
        $(#[$doc])*
        pub(crate) struct $param;

        impl PartialSchema for $param {
            fn schema() -> RefOr<Schema> {
                choice_schema::<$choice>().into()
            }
        }

        impl ToSchema for $param {}
    };
}

choice_param!(
    /// The schema of `mode`: a choice of [`Mode`].
    ModeParam,
    Mode
);
choice_param!(
    /// The schema of `normals`: a choice of [`NormalsMethod`].
    NormalsParam,
    NormalsMethod
);

fn choice_schema<E: IntoEnumIterator + EnumMessage + Copy + Into<&'static str>>() -> ObjectBuilder {
    ObjectBuilder::new()
        .schema_type(Type::String)
        .enum_values(Some(names::<E>()))
}

/// The schema of `format`: a choice of [`MapFormat::HTTP`], defaulting to the default.
pub(crate) struct FormatParam;

impl PartialSchema for FormatParam {
    fn schema() -> RefOr<Schema> {
        let default = MapFormat::default().get_serializations().first().copied();
        ObjectBuilder::new()
            .schema_type(Type::String)
            .enum_values(Some(names_of_these(MapFormat::HTTP)))
            .default(default.map(Into::into))
            .into()
    }
}

impl ToSchema for FormatParam {}

/// The schema of `dsac_hypotheses`: 1 to [`MAX_DSAC_HYPOTHESES`].
pub(crate) struct DsacHypothesesParam;

impl PartialSchema for DsacHypothesesParam {
    fn schema() -> RefOr<Schema> {
        ObjectBuilder::new()
            .schema_type(Type::Integer)
            .minimum(Some(1))
            .maximum(Some(MAX_DSAC_HYPOTHESES))
            .into()
    }
}

impl ToSchema for DsacHypothesesParam {}

/// `value`, when given, as a choice of `E` (400 `bad_request` naming `field` otherwise).
fn choice<E>(field: &str, value: Option<&str>) -> Result<Option<E>, RequestError>
where
    E: IntoEnumIterator + FromStr + Copy + Into<&'static str>,
{
    value
        .map(|v| parse_choice(field, v))
        .transpose()
        .map_err(|e| OptionError::Choice(e).into())
}

impl RoughnessQuery {
    /// The options, checked.
    pub(crate) fn options(&self) -> Result<FrameOptions, RequestError> {
        let format = self
            .format
            .as_deref()
            .map(|v| parse_choice_of("format", v, MapFormat::HTTP))
            .transpose()
            .map_err(OptionError::Choice)?
            .unwrap_or_default();
        let mode = choice::<Mode>("mode", self.mode.as_deref())?;
        let normals = choice::<NormalsMethod>("normals", self.normals.as_deref())?;
        let dsac_hypotheses = self
            .dsac_hypotheses
            .map(check_dsac_hypotheses)
            .transpose()
            .map_err(|e| OptionError::DsacHypotheses {
                field: "dsac_hypotheses",
                source: Box::new(e),
            })?;
        if let Some(cm) = self.preview_max_cm.filter(|c| !(c.is_finite() && *c > 0.0)) {
            return Err(OptionError::PreviewMax {
                field: "preview_max_cm",
                value: cm,
            }
            .into());
        }
        Ok(FrameOptions {
            mode,
            format,
            seed: self.seed.unwrap_or(0),
            normals,
            dsac_hypotheses,
            preview_max_m: self.preview_max_cm.map(|c| c / 100.0),
            extras: self.extras()?,
            traversable_bytes: false,
            traversability: Traversability::from_cm_deg(self.max_roughness_cm, self.max_slope_deg)
                .map_err(|source| OptionError::Traversability { prefix: "", source })?,
            sensor: self
                .sensor
                .as_deref()
                .map(str::parse)
                .transpose()
                .map_err(|why| OptionError::Sensor {
                    field: "sensor",
                    source: Box::new(why),
                })?,
            traversal_bytes: false,
            uncertainty_f32: false,
        })
    }

    /// The extra maps of `outputs`.
    fn extras(&self) -> Result<Extras, RequestError> {
        let mut extras = Extras::default();
        for name in self
            .outputs
            .iter()
            .flat_map(|o| o.split(','))
            .filter(|s| !s.is_empty())
        {
            let map: OutputMap = name.parse().map_err(|_| OptionError::UnknownOutput {
                name: name.to_owned(),
            })?;
            extras.add(map);
        }
        Ok(extras)
    }

    /// Camera from the query (all four intrinsics, or none of them).
    pub(crate) fn camera(&self, limits: DecodeLimits) -> Result<Option<CameraFile>, RequestError> {
        let k = [self.fx, self.fy, self.cx, self.cy];
        let any = k.iter().any(Option::is_some)
            || self.pitch_deg.is_some()
            || self.height_m.is_some()
            || self.depth_scale.is_some();
        if !any {
            return Ok(None);
        }
        let [Some(fx), Some(fy), Some(cx), Some(cy)] = k else {
            return Err(CameraError::PartialIntrinsics.into());
        };
        let cam = CameraFile {
            fx,
            fy,
            cx,
            cy,
            width: None,
            height: None,
            depth_scale: self.depth_scale,
            pitch_deg: self.pitch_deg,
            height_m: self.height_m,
            sensor: None,
        };
        check_camera_ranges(&cam, limits)?;
        Ok(Some(cam))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn query(q: &str) -> Result<FrameOptions, RequestError> {
        parse_query(q).options()
    }

    /// A query string of `name=value` pairs as the handler's extractor reads it.
    fn parse_query(q: &str) -> RoughnessQuery {
        let uri: axum::http::Uri = format!("/v1/roughness?{q}").parse().expect("a URI");
        let axum::extract::Query(parsed) =
            axum::extract::Query::try_from_uri(&uri).expect("a query the struct takes");
        parsed
    }

    /// Choices are parsed by their enums, and a bad one is refused with the same message as
    /// ever: the field, the choices, what was given.
    #[test]
    fn choices_parse_through_their_enums() {
        let o = query("format=colour&mode=rgbd&normals=ls&outputs=depth,traversal").unwrap();
        assert_eq!(o.format, MapFormat::Color);
        assert_eq!(o.mode, Some(Mode::Rgbd));
        assert_eq!(o.normals, Some(NormalsMethod::Ls));
        assert!(o.extras.depth && o.extras.traversal && !o.extras.slope);
        let o = query("seed=3").unwrap();
        assert_eq!(
            (o.format, o.mode, o.normals),
            (MapFormat::Png16, None, None)
        );
        for (q, message) in [
            (
                "format=f32",
                r#"format: expected png16, color or npy, got "f32""#,
            ),
            (
                "mode=depth",
                r#"mode: expected rgb, rgbd or geometric, got "depth""#,
            ),
            ("normals=pca", r#"normals: expected ls or dsac, got "pca""#),
            (
                "outputs=depth,edges",
                r#"outputs: unknown map "edges" (depth, normals, slope, traversable, boundary, uncertainty, traversal)"#,
            ),
        ] {
            let e = query(q).unwrap_err();
            assert_eq!(
                (e.code(), e.to_string().as_str()),
                (tre_proto::ErrorCode::BadRequest, message)
            );
        }
    }
}
