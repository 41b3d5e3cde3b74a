//! The files of one frame's result, as `tre infer` writes them: the roughness map (16-bit PNG
//! or float `.npy`) with its colour preview, and the uncertainty and three-state maps beside it
//! (`<stem>_uncertainty.png|npy`, `<stem>_lo.npy` / `<stem>_hi.npy`, `<stem>_traversal.png`,
//! `<stem>_traversal_preview.png`).

use std::path::{Path, PathBuf};

use image::DynamicImage;
use tre_core::geometry::Grid;
use tre_core::roughness::traversal::Traversal;

use crate::IoError;

/// How a map is written to a file.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MapFile {
    /// 16-bit grey + alpha PNG, 0.1 mm per unit, alpha 0 where there is no data.
    Png16,
    /// `(H, W)` float32 `.npy` in metres, NaN where there is no data.
    Npy,
}

impl MapFile {
    /// The file extension it writes.
    #[must_use]
    pub fn extension(self) -> &'static str {
        match self {
            Self::Png16 => "png",
            Self::Npy => "npy",
        }
    }
}

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

/// Writes the roughness map `roughness_m` to `out` as `file`, creating its folder, and its
/// preview (colour scale 0 to `preview_max_m`, titled `title`) beside it.
pub fn write_roughness(
    out: &Path,
    file: MapFile,
    roughness_m: &Grid<f64>,
    preview_max_m: f64,
    title: &str,
) -> Result<(), IoError> {
    crate::paths::create_parent(out)?;
    write_map(out, file, roughness_m)?;
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

/// Writes `maps` beside `out`: `<stem>_uncertainty.png|npy` (and with `.npy` the interval's
/// ends `<stem>_lo.npy`, `<stem>_hi.npy`), `<stem>_traversal.png` (0 unknown, 1 traversable,
/// 2 hazard) and `<stem>_traversal_preview.png` titled `title`.
pub fn write_sensor_maps(
    out: &Path,
    file: MapFile,
    maps: &SensorMapFiles<'_>,
    title: &str,
) -> Result<(), IoError> {
    let ext = file.extension();
    write_map(&beside(out, "uncertainty", ext), file, maps.uncertainty_m)?;
    if let (MapFile::Npy, Some((lo, hi))) = (file, maps.interval_m) {
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

/// Writes one map of metres to `path` as `file`.
fn write_map(path: &Path, file: MapFile, map_m: &Grid<f64>) -> Result<(), IoError> {
    match file {
        MapFile::Png16 => crate::save(
            path,
            &DynamicImage::ImageLumaA16(crate::roughness_png16(map_m)),
        ),
        MapFile::Npy => crate::write_npy_f32(path, map_m),
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
        write_roughness(&out, MapFile::Npy, &r, 0.05, "test").unwrap();
        assert!(out.is_file() && preview_path(&out).is_file());
        let t = Grid::from_vec(2, 1, vec![Traversal::Traversable, Traversal::Unknown]).unwrap();
        let maps = SensorMapFiles {
            uncertainty_m: &r,
            interval_m: Some((&r, &r)),
            traversal: &t,
        };
        write_sensor_maps(&out, MapFile::Npy, &maps, "test").unwrap();
        for what in ["uncertainty", "lo", "hi"] {
            assert!(beside(&out, what, "npy").is_file(), "{what}");
        }
        assert!(beside(&out, "traversal_preview", "png").is_file());
    }
}
