//! Contact sheets: RGB, the spec, each row, the geometric row's three-state map, one colour scale.

use super::*;

/// Top of the contact sheets' shared colour scale, metres.
pub const SHEET_MAX_M: f64 = 0.10;

/// `map` at half size, each pixel the largest of its 2×2 block (NaN where all four are), so
/// one-pixel edges stay visible.
pub(super) fn max_pool2(map: &Grid<f64>) -> Grid<f64> {
    let (w, h) = map.size();
    Grid::from_fn(w.div_ceil(2), h.div_ceil(2), |x, y| {
        let mut best = f64::NAN;
        for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
            if let Some(&v) = map.get(2 * x + dx, 2 * y + dy) {
                best = best.max(v);
            }
        }
        best
    })
}

/// The panels of a frame's contact sheet at half size: the RGB image, the spec, then each
/// configuration's roughness, titled; roughness in one colour scale ([`SHEET_MAX_M`]).
pub fn sheet_panels(
    loaded: &LoadedFrame,
    rows: &[(String, PipelineConfig)],
    maps: &[RowMaps],
) -> Vec<Panel> {
    let colour = |m: &Grid<f64>| roughness_panel(&max_pool2(m), SHEET_MAX_M);
    let mut panels = Vec::new();
    if let Some(rgb) = &loaded.input.rgb {
        let (w, h) = (rgb.width().div_ceil(2), rgb.height().div_ceil(2));
        let small = image::imageops::resize(rgb, w, h, image::imageops::FilterType::Triangle);
        panels.push(Panel::new("RGB", small));
    }
    panels.push(Panel::new(
        "spec (tre annotate)",
        colour(&loaded.spec.roughness_m),
    ));
    for ((key, _), map) in rows.iter().zip(maps) {
        panels.push(Panel::new(key.clone(), colour(&map.roughness_m)));
    }
    // The three-state map of the geometric mode (the spec), else of the first that has one.
    let with_map = || {
        rows.iter()
            .zip(maps)
            .filter_map(|(r, m)| m.traversal.as_ref().map(|t| (r, t)))
    };
    let spec_first = with_map()
        .find(|((_, c), _)| c.mode == Mode::Geometric && c.geometric == GeometricMethod::Spec)
        .or_else(|| with_map().next());
    if let Some(((key, _), t)) = spec_first {
        let half = Grid::from_fn(t.width().div_ceil(2), t.height().div_ceil(2), |x, y| {
            t[(2 * x, 2 * y)]
        });
        let mode = key.split(':').next().unwrap_or(key);
        panels.push(Panel::new(
            format!("three-state ({mode})"),
            traversal_panel(&half),
        ));
    }
    panels
}

/// Colours of the three states on the contact sheets.
pub(super) const STATE_COLOURS: [(&str, Rgb<u8>); 3] = [
    ("traversable", Rgb([60, 170, 90])),
    ("hazard", Rgb([210, 40, 40])),
    ("unknown (noise or no data)", Rgb([150, 150, 220])),
];

/// A three-state map in [`STATE_COLOURS`].
pub(super) fn traversal_panel(t: &Grid<Traversal>) -> image::RgbImage {
    image::RgbImage::from_fn(t.width() as u32, t.height() as u32, |x, y| {
        match t[(x as usize, y as usize)] {
            Traversal::Traversable => STATE_COLOURS[0].1,
            Traversal::Hazard => STATE_COLOURS[1].1,
            Traversal::Unknown => STATE_COLOURS[2].1,
        }
    })
}

/// Writes `DIR/<sequence>_<depth stem>.png`: the frame's panels in a grid of three columns
/// over the colour scale's legend.
///
/// # Errors
///
/// When the file cannot be written.
pub fn write_sheet(
    dir: &Path,
    frame: &RealFrame,
    loaded: &LoadedFrame,
    rows: &[(String, PipelineConfig)],
    maps: &[RowMaps],
) -> Result<(), io::IoError> {
    let panels = sheet_panels(loaded, rows, maps);
    let width = panels.first().map_or(320, |p| p.image.width()) * 2;
    let legend = stack(&[
        colour_bar_legend(width, SHEET_MAX_M, &[0.0, 1.0, 2.0, 5.0, 10.0]),
        categorical_legend(&STATE_COLOURS),
    ]);
    let sheet = contact_sheet(&panels, 4, Some(&legend));
    let stem = frame
        .depth_rel
        .trim_end_matches(".png")
        .replace(['/', '\\'], "_");
    let path = dir.join(format!("{}_{stem}.png", frame.sequence));
    io::save(&path, &image::DynamicImage::ImageRgb8(sheet))
}
