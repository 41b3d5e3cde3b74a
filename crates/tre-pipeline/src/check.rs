//! [`check_input`]: a frame checked against the configuration before any stage runs.

use crate::{FrameInput, Method, Mode, PipelineConfig, PipelineError};
use tre_core::geometry::Grid;

/// Checks a frame against the configuration without running anything (as [`Pipeline::run`]
/// does first): the inputs the mode needs are there, depth and RGB agree in size, the frame is
/// neither empty nor too large. Returns its `(width, height)`.
///
/// # Errors
///
/// [`PipelineError::MissingInput`], [`PipelineError::DepthSizeMismatch`],
/// [`PipelineError::EmptyImage`] or [`PipelineError::TooLarge`].
///
/// [`Pipeline::run`]: crate::Pipeline::run
pub fn check_input(
    input: &FrameInput,
    cfg: &PipelineConfig,
) -> Result<(usize, usize), PipelineError> {
    let (mode, needs_rgb, needs_depth) = match (cfg.method, cfg.mode) {
        (Method::EndToEnd, _) => ("the end-to-end method", true, false),
        (Method::Pipeline, Mode::Rgb) => ("rgb mode", true, false),
        (Method::Pipeline, Mode::Rgbd) => ("rgbd mode", true, true),
        (Method::Pipeline, Mode::Geometric) => ("geometric mode", false, true),
    };
    if needs_rgb && input.rgb.is_none() {
        return Err(PipelineError::MissingInput { mode, input: "rgb" });
    }
    let depth = input.depth_m.as_ref().filter(|_| needs_depth);
    if needs_depth && depth.is_none() {
        return Err(PipelineError::MissingInput {
            mode,
            input: "depth",
        });
    }
    let rgb_size = input
        .rgb
        .as_ref()
        .map(|i| (i.width() as usize, i.height() as usize));
    let depth_size = depth.map(Grid::size);
    if let (Some(rgb), Some(depth)) = (rgb_size, depth_size) {
        if rgb != depth {
            return Err(PipelineError::DepthSizeMismatch { rgb, depth });
        }
    }
    let what = if rgb_size.is_some() { "rgb" } else { "depth" };
    let size = rgb_size.or(depth_size).ok_or(PipelineError::MissingInput {
        mode,
        input: "rgb or depth",
    })?;
    if size.0 == 0 || size.1 == 0 {
        return Err(PipelineError::EmptyImage { what, size });
    }
    if size.0.saturating_mul(size.1) > cfg.max_input_pixels {
        return Err(PipelineError::TooLarge {
            size,
            max_pixels: cfg.max_input_pixels,
        });
    }
    Ok(size)
}
