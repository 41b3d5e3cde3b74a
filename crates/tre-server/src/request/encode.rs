//! Encoding a frame's answer: the pipeline's maps in the options' formats (PNG, `.npy`, the
//! stream's bytes), with what stood in for what the request did not give.

use image::DynamicImage;
use tre_core::geometry::Grid;
use tre_core::kinds::MapFormat;
use tre_core::roughness::interval::IntervalTable;
use tre_io::{self as io, colormap};
use tre_pipeline::{Assumption, FrameInput, FrameOutput, Mode};

use super::{FrameReply, FrameRequest, Part};
use crate::error::{RequestError, ServiceError};
use crate::options::{FrameOptions, OutputMap};

/// Encodes a PNG with the settings `tre infer` uses (fast compression, adaptive filter).
fn png(img: &DynamicImage) -> Result<Vec<u8>, RequestError> {
    let mut out = Vec::new();
    io::encode_png(img, &mut out).map_err(ServiceError::EncodePng)?;
    Ok(out)
}

/// Writes an `.npy` into memory.
fn npy<T: io::npy::NpyElement>(shape: &[usize], data: &[T]) -> Result<Vec<u8>, RequestError> {
    let mut out = Vec::new();
    io::npy::write_npy(&mut out, shape, data).map_err(ServiceError::EncodeNpy)?;
    Ok(out)
}

/// A mask as PNG part `name` (file `filename`): 8-bit grey, 255 where set.
fn mask_part(
    name: OutputMap,
    filename: &'static str,
    mask: &Grid<bool>,
) -> Result<Part, RequestError> {
    let grey = mask.map(|&m| if m { 255u8 } else { 0 });
    png_part(name, filename, &DynamicImage::ImageLuma8(io::gray8(&grey)))
}

/// Part `name` of the answer: `image` as a PNG file `filename`.
fn png_part(
    name: OutputMap,
    filename: &'static str,
    image: &DynamicImage,
) -> Result<Part, RequestError> {
    Ok(Part {
        name: name.into(),
        content_type: "image/png",
        filename,
        bytes: png(image)?,
    })
}

/// The roughness map in the options' format.
fn encode_roughness(r: &Grid<f64>, opts: &FrameOptions) -> Result<Vec<u8>, RequestError> {
    let (w, h) = r.size();
    Ok(match opts.format {
        MapFormat::Png16 => png(&DynamicImage::ImageLumaA16(io::roughness_png16(r)))?,
        MapFormat::Color => png(&DynamicImage::ImageRgb8(colormap::colourise(
            r,
            0.0,
            opts.preview_max_m.unwrap_or(0.05),
        )))?,
        MapFormat::Npy => npy(
            &[h, w],
            &r.as_slice().iter().map(|&v| v as f32).collect::<Vec<_>>(),
        )?,
        MapFormat::F32 => r
            .as_slice()
            .iter()
            .flat_map(|&v| (v as f32).to_le_bytes())
            .collect(),
    })
}

/// What stood in for what `req` did not give, for `frame` (decoded from it) run in `mode`.
pub fn assumptions(req: &FrameRequest, frame: &FrameInput, mode: Mode) -> Vec<Assumption> {
    let depth_png = req
        .depth
        .as_ref()
        .is_some_and(|d| !d.starts_with(b"\x93NUMPY"));
    let scale_stated = req.camera.as_ref().is_some_and(|c| c.depth_scale.is_some());
    Assumption::of_frame(
        frame.intrinsics.is_some(),
        depth_png && !scale_stated,
        (frame.mounting.is_some(), frame.sensor.is_some()),
        (mode, req.options.mode.is_some()),
    )
}

/// Encodes the pipeline's output as the options ask (the output stays the caller's, to hand
/// back to [`Pipeline::recycle`](tre_pipeline::Pipeline::recycle)); `mode` ran, with the
/// `assumed` stand-ins ([`assumptions`]).
pub fn encode_reply(
    out: &FrameOutput,
    opts: &FrameOptions,
    (mode, assumed): (Mode, Vec<Assumption>),
) -> Result<FrameReply, RequestError> {
    let (w, h) = out.roughness_m.size();
    let roughness = encode_roughness(&out.roughness_m, opts)?;
    let mut extras = Vec::new();
    let e = opts.extras;
    if let Some(d) = e.depth.then(|| out.depth_m()).flatten() {
        extras.push(Part {
            name: OutputMap::Depth.into(),
            content_type: "image/png",
            filename: "depth.png",
            bytes: png(&DynamicImage::ImageLuma16(io::depth_png16(&d)))?,
        });
    }
    if let Some(n) = e.normals.then(|| out.normals()).flatten() {
        let data: Vec<f32> = n
            .as_slice()
            .iter()
            .flat_map(|v| [v.x as f32, v.y as f32, v.z as f32])
            .collect();
        extras.push(Part {
            name: OutputMap::Normals.into(),
            content_type: "application/octet-stream",
            filename: "normals.npy",
            bytes: npy(&[h, w, 3], &data)?,
        });
    }
    if let Some(s) = e.slope.then(|| out.slope_rad()).flatten() {
        let data: Vec<f32> = s.as_slice().iter().map(|&v| v as f32).collect();
        extras.push(Part {
            name: OutputMap::Slope.into(),
            content_type: "application/octet-stream",
            filename: "slope.npy",
            bytes: npy(&[h, w], &data)?,
        });
    }
    let ok = (e.traversable || opts.traversable_bytes).then(|| out.traversable());
    if let (true, Some(ok)) = (e.traversable, &ok) {
        extras.push(mask_part(OutputMap::Traversable, "traversable.png", ok)?);
    }
    if let Some(b) = e.boundary.then(|| out.boundary()).flatten() {
        extras.push(mask_part(OutputMap::Boundary, "boundary.png", &b)?);
    }
    let traversable = match (opts.traversable_bytes, &ok) {
        (true, Some(ok)) => ok.as_slice().iter().map(|&t| u8::from(t)).collect(),
        _ => Vec::new(),
    };
    Ok(FrameReply {
        size: (w, h),
        working_size: out.working_size,
        roughness,
        format: opts.format,
        extras,
        traversable,
        traversal: Vec::new(),
        uncertainty: Vec::new(),
        timings: out.timings.clone(),
        mode,
        assumed,
        gravity: out.gravity,
        warnings: Vec::new(),
    })
}

/// Adds the sensor-noise maps the options ask for to `reply`: parts `uncertainty` and
/// `traversal` and the stream's bytes. The noise model is the options' `sensor`, else the
/// camera's; `table`: the mode's calibrated intervals, if the models have them (docs/uncertainty.md);
/// an error names what is missing (a noise model, or sensor depth in this mode). A three-state
/// map mostly unknown adds a warning saying so.
pub fn encode_sensor_maps(
    out: &FrameOutput,
    frame: &FrameInput,
    (mode, table): (Mode, Option<&IntervalTable>),
    req: &FrameRequest,
    reply: &mut FrameReply,
) -> Result<(), RequestError> {
    let opts = &req.options;
    if !opts.wants_sensor_maps() {
        return Ok(());
    }
    let spec = req.camera.as_ref().and_then(|c| c.sensor.as_ref());
    // The frame's model, from `req.noise_model()` when it was decoded.
    let model = frame.sensor;
    let described = match spec {
        Some(io::SensorSpec::Description(d)) => Some(d.as_str()),
        _ => None,
    };
    let maps = out.sensor_maps(frame, mode, model.as_ref(), described, table)?;
    // A map almost all unknown: its roughness looks like an answer and is none; said in a
    // `Warning` header, as `tre infer` says it.
    if let Some(caveat) = maps.mostly_unknown() {
        reply
            .warnings
            .push(format!("the three-state map is {caveat}"));
    }
    if opts.extras.uncertainty {
        let image = DynamicImage::ImageLumaA16(io::roughness_png16(&maps.uncertainty_m));
        let part = png_part(OutputMap::Uncertainty, "uncertainty.png", &image)?;
        reply.extras.push(part);
    }
    if opts.extras.traversal {
        let image = DynamicImage::ImageLuma8(io::traversal_gray8(&maps.traversal));
        let part = png_part(OutputMap::Traversal, "traversal.png", &image)?;
        reply.extras.push(part);
    }
    if opts.traversal_bytes {
        reply.traversal = maps.traversal.as_slice().iter().map(|&t| t as u8).collect();
    }
    if opts.uncertainty_f32 {
        let u = maps.uncertainty_m.as_slice().iter();
        reply.uncertainty = u.flat_map(|&v| (v as f32).to_le_bytes()).collect();
    }
    Ok(())
}
