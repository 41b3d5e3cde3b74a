//! The files of one frame's result, as `tre infer` writes them: the roughness map (16-bit PNG
//! or float `.npy`, a [`MapFormat`]) with its colour preview, and the uncertainty and three-state maps beside it
//! (`<stem>_uncertainty.png|npy`, `<stem>_lo.npy` / `<stem>_hi.npy`, `<stem>_traversal.png`,
//! `<stem>_traversal_preview.png`); and the files of an annotation, as `tre annotate` writes
//! them ([`write_annotation`]).

use std::path::{Path, PathBuf};

use image::DynamicImage;
use tre_core::geometry::Grid;
use tre_core::kinds::MapFormat;
use tre_core::roughness::annotate::Annotation;
use tre_core::roughness::traversal::Traversal;

use crate::IoError;

/// `DIR/<stem>_<what>.<ext>` beside `out`.
#[must_use]
pub fn beside(out: &Path, what: &str, ext: &str) -> PathBuf {
    let stem = out.file_stem().map_or_else(
        || "roughness".to_owned(),
        |s| s.to_string_lossy().into_owned(),
    );
    out.with_file_name(format!("{stem}_{what}.{ext}"))
}

/// `DIR/<stem>_preview.png` beside `out`.
#[must_use]
pub fn preview_path(out: &Path) -> PathBuf {
    beside(out, "preview", "png")
}

/// The sensor maps' files beside `out`, for the refusal to write over an input.
#[must_use]
pub fn sensor_map_paths(out: &Path) -> Vec<PathBuf> {
    vec![
        beside(out, "uncertainty", "png"),
        beside(out, "uncertainty", "npy"),
        beside(out, "traversal", "png"),
        beside(out, "traversal_preview", "png"),
    ]
}

/// Writes the roughness map `roughness_m` to `out` as `format`, creating its folder, and its
/// preview (colour scale 0 to `preview_max_m`, titled `title`) beside it.
pub fn write_roughness(
    out: &Path,
    format: MapFormat,
    roughness_m: &Grid<f64>,
    preview_max_m: f64,
    title: &str,
) -> Result<(), IoError> {
    crate::paths::create_parent(out)?;
    write_map(out, format, roughness_m, preview_max_m)?;
    let preview = crate::previews::roughness_preview(roughness_m, preview_max_m, title);
    crate::save(&preview_path(out), &DynamicImage::ImageRgb8(preview))
}

/// The maps of the noise model beside a roughness map.
#[derive(Debug, Clone, Copy)]
pub struct SensorMapFiles<'a> {
    /// Uncertainty, metres (NaN: none).
    pub uncertainty_m: &'a Grid<f64>,
    /// The calibrated interval's ends, metres, when calibrated.
    pub interval_m: Option<(&'a Grid<f64>, &'a Grid<f64>)>,
    /// The three-state map.
    pub traversal: &'a Grid<Traversal>,
}

/// Writes `maps` beside `out`: `<stem>_uncertainty.png|npy` as `format` (colour scale 0 to
/// `preview_max_m` for `color`; with `.npy` also the interval's ends `<stem>_lo.npy`,
/// `<stem>_hi.npy`), `<stem>_traversal.png` (0 unknown, 1 traversable, 2 hazard) and
/// `<stem>_traversal_preview.png` titled `title`.
pub fn write_sensor_maps(
    out: &Path,
    format: MapFormat,
    maps: &SensorMapFiles<'_>,
    preview_max_m: f64,
    title: &str,
) -> Result<(), IoError> {
    let path = beside(out, "uncertainty", format.extension());
    write_map(&path, format, maps.uncertainty_m, preview_max_m)?;
    if let ("npy", Some((lo, hi))) = (format.extension(), maps.interval_m) {
        crate::write_npy_f32(&beside(out, "lo", "npy"), lo)?;
        crate::write_npy_f32(&beside(out, "hi", "npy"), hi)?;
    }
    let grey = crate::traversal_gray8(maps.traversal);
    crate::save(
        &beside(out, "traversal", "png"),
        &DynamicImage::ImageLuma8(grey),
    )?;
    let preview = crate::previews::traversal_preview(maps.traversal, title);
    crate::save(
        &beside(out, "traversal_preview", "png"),
        &DynamicImage::ImageRgb8(preview),
    )
}

/// Writes `ann` into the folder `out` (created if missing): `roughness.png` (16-bit, 0.1 mm per
/// unit), `roughness.npy`, `boundary.png`, `edge_weight.npy`, `segments.npy` and `preview.png`
/// (colour scale 0 to `preview_max_m`, titled `title`).
pub fn write_annotation(
    out: &Path,
    ann: &Annotation,
    preview_max_m: f64,
    title: &str,
) -> Result<(), IoError> {
    crate::paths::create_dir(out)?;
    let p = |name: &str| out.join(name);
    let png16 = DynamicImage::ImageLumaA16(crate::roughness_png16(&ann.roughness_m));
    crate::save(&p("roughness.png"), &png16)?;
    crate::write_npy_f32(&p("roughness.npy"), &ann.roughness_m)?;
    crate::write_mask_png(&p("boundary.png"), &ann.boundary)?;
    crate::write_npy_f32(&p("edge_weight.npy"), &ann.edge_weight_m)?;
    crate::write_npy_u32(&p("segments.npy"), &ann.segments)?;
    let preview = crate::previews::roughness_preview(&ann.roughness_m, preview_max_m, title);
    crate::save(&p("preview.png"), &DynamicImage::ImageRgb8(preview))
}

/// Writes one map of metres to `path` as `format`: a float32 `.npy` for `npy` and `f32`, a
/// turbo colour map from 0 to `colour_max_m` for `color`.
fn write_map(
    path: &Path,
    format: MapFormat,
    map_m: &Grid<f64>,
    colour_max_m: f64,
) -> Result<(), IoError> {
    match format {
        MapFormat::Png16 => crate::save(
            path,
            &DynamicImage::ImageLumaA16(crate::roughness_png16(map_m)),
        ),
        MapFormat::Color => crate::save(
            path,
            &DynamicImage::ImageRgb8(crate::colormap::colourise(map_m, 0.0, colour_max_m)),
        ),
        MapFormat::Npy | MapFormat::F32 => crate::write_npy_f32(path, map_m),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn files_go_beside_the_map_with_its_stem() {
        let out = Path::new("out/desk.png");
        assert_eq!(preview_path(out), Path::new("out/desk_preview.png"));
        assert_eq!(
            beside(out, "traversal", "png"),
            Path::new("out/desk_traversal.png")
        );
        assert_eq!(sensor_map_paths(out).len(), 4);
    }

    #[test]
    fn a_map_and_its_sensor_maps_are_written() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("sub/r.npy");
        let r = Grid::from_vec(2, 1, vec![0.01, f64::NAN]).unwrap();
        write_roughness(&out, MapFormat::Npy, &r, 0.05, "test").unwrap();
        assert!(out.is_file() && preview_path(&out).is_file());
        let t = Grid::from_vec(2, 1, vec![Traversal::Traversable, Traversal::Unknown]).unwrap();
        let maps = SensorMapFiles {
            uncertainty_m: &r,
            interval_m: Some((&r, &r)),
            traversal: &t,
        };
        write_sensor_maps(&out, MapFormat::Npy, &maps, 0.05, "test").unwrap();
        for what in ["uncertainty", "lo", "hi"] {
            assert!(beside(&out, what, "npy").is_file(), "{what}");
        }
        assert!(beside(&out, "traversal_preview", "png").is_file());
    }
}
