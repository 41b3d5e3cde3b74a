//! Per-pixel maps as files: labels and normals read from `.npy` (labels also from PNG), float,
//! id and normal maps written as `.npy`, and point clouds written as PLY.

use std::fs::File;
use std::io::{BufReader, BufWriter};
use std::path::Path;

use image::DynamicImage;

use tre_core::geometry::{Grid, Vec3};

use super::npy::{self, NpyArray, NpyElement, NpyError};
use super::{is_npy, open, read_image, IoError};

/// Reads labels: an 8- or 16-bit grey PNG or an integer `.npy` (0 = void).
pub fn read_labels(path: &Path) -> Result<Grid<u32>, IoError> {
    if is_npy(path) {
        let npy_error = |reason: NpyError| IoError::Npy {
            path: path.to_owned(),
            reason,
        };
        let a = npy::read_npy(BufReader::new(open(path)?)).map_err(npy_error)?;
        if a.is_float() {
            return Err(npy_error(NpyError::LabelsNotInteger { dtype: a.dtype }));
        }
        // Negative ids (often "ignore") are void too.
        return Ok(npy_grid(a).map_err(npy_error)?.map(|&v| v.max(0.0) as u32));
    }
    let img = read_image(path)?;
    let (w, h) = (img.width() as usize, img.height() as usize);
    let data: Vec<u32> = match img {
        DynamicImage::ImageLuma8(i) => i.into_raw().into_iter().map(u32::from).collect(),
        DynamicImage::ImageLuma16(i) => i.into_raw().into_iter().map(u32::from).collect(),
        other => {
            return Err(IoError::ImageKind {
                path: path.to_owned(),
                expected: "labels must be a grey PNG or .npy",
                got: other.color(),
            })
        }
    };
    Ok(Grid::from_vec(w, h, data).expect("decoder sizes agree; this is a bug"))
}

/// Reads normals from an `H × W × 3` float `.npy` (camera frame).
pub fn read_normals(path: &Path) -> Result<Grid<Vec3>, IoError> {
    let npy_error = |reason: NpyError| IoError::Npy {
        path: path.to_owned(),
        reason,
    };
    let a = npy::read_npy(BufReader::new(open(path)?)).map_err(npy_error)?;
    let [h, w, 3] = a.shape[..] else {
        return Err(npy_error(NpyError::Shape {
            expected: "normals of shape (H, W, 3)",
            got: a.shape,
        }));
    };
    let data = a
        .data
        .chunks_exact(3)
        .map(|c| Vec3::new(c[0], c[1], c[2]))
        .collect();
    Ok(Grid::from_vec(w, h, data).expect("shape checked; this is a bug"))
}

/// A 2-D `(H, W)` array as a grid; for any other shape, or no pixels, an error saying so.
pub fn npy_grid(a: NpyArray) -> Result<Grid<f64>, NpyError> {
    let [h, w] = a.shape[..] else {
        return Err(NpyError::Shape {
            expected: "a 2-D array (H, W)",
            got: a.shape,
        });
    };
    Ok(Grid::from_vec(w, h, a.data)?)
}

/// Writes `data` with `shape` as a `.npy` at `path`, naming the file in errors.
fn write_npy_file<T: NpyElement>(path: &Path, shape: &[usize], data: &[T]) -> Result<(), IoError> {
    let failed = |reason| IoError::Write {
        path: path.to_owned(),
        reason,
    };
    npy::write_npy(File::create(path).map_err(failed)?, shape, data).map_err(failed)
}

/// Writes a float map as an `(H, W)` float32 `.npy` (NaN: no data).
pub fn write_npy_f32(path: &Path, grid: &Grid<f64>) -> Result<(), IoError> {
    let data: Vec<f32> = grid.as_slice().iter().map(|&v| v as f32).collect();
    write_npy_file(path, &[grid.height(), grid.width()], &data)
}

/// Writes an id map as an `(H, W)` uint32 `.npy`.
pub fn write_npy_u32(path: &Path, grid: &Grid<u32>) -> Result<(), IoError> {
    write_npy_file(path, &[grid.height(), grid.width()], grid.as_slice())
}

/// Writes normals as an `(H, W, 3)` float32 `.npy` (NaN: none).
pub fn write_normals_npy(path: &Path, normals: &Grid<Vec3>) -> Result<(), IoError> {
    let data: Vec<f32> = normals
        .as_slice()
        .iter()
        .flat_map(|n| [n.x as f32, n.y as f32, n.z as f32])
        .collect();
    write_npy_file(path, &[normals.height(), normals.width(), 3], &data)
}

/// Writes the valid points of a point map with their colours as a binary little-endian PLY
/// (x, y, z float32 metres in the camera frame; red, green, blue uchar).
pub fn write_ply(
    path: &Path,
    points: &tre_core::geometry::PointMap,
    rgb: &image::RgbImage,
) -> Result<(), IoError> {
    use std::io::Write;
    let valid: Vec<(usize, usize)> = (0..points.height())
        .flat_map(|y| (0..points.width()).map(move |x| (x, y)))
        .filter(|&(x, y)| tre_core::geometry::is_valid_point(&points[(x, y)]))
        .collect();
    let mut out = BufWriter::new(File::create(path)?);
    write!(
        out,
        "ply\nformat binary_little_endian 1.0\nelement vertex {}\nproperty float x\nproperty float y\nproperty float z\n\
         property uchar red\nproperty uchar green\nproperty uchar blue\nend_header\n",
        valid.len()
    )?;
    for (x, y) in valid {
        let p = points[(x, y)];
        for c in [p.x, p.y, p.z] {
            out.write_all(&(c as f32).to_le_bytes())?;
        }
        out.write_all(&rgb.get_pixel(x as u32, y as u32).0)?;
    }
    out.flush()?;
    Ok(())
}

/// Reads a pose file: a 4×4 camera-to-world matrix as 16 finite numbers, row by row
/// (`poses/NAME.txt` beside a sequence, as 7-Scenes writes them).
pub fn read_pose(path: &Path) -> Result<[f64; 16], IoError> {
    let text = std::fs::read_to_string(path).map_err(|reason| IoError::Read {
        path: path.to_owned(),
        reason,
    })?;
    let bad = |reason| IoError::Pose {
        path: path.to_owned(),
        reason,
    };
    let v: Vec<f64> = text
        .split_whitespace()
        .map(str::parse)
        .collect::<Result<_, _>>()
        .map_err(|e| bad(PoseProblem::NotNumbers(e)))?;
    if v.iter().any(|x| !x.is_finite()) {
        return Err(bad(PoseProblem::NotFinite));
    }
    v.try_into()
        .map_err(|v: Vec<f64>| bad(PoseProblem::Count(v.len())))
}

/// Why a pose file is not a pose ([`read_pose`]).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum PoseProblem {
    /// Text that is not all numbers.
    #[error("not numbers ({0})")]
    NotNumbers(std::num::ParseFloatError),
    /// A number that is NaN or infinite.
    #[error("a pose is 16 finite numbers")]
    NotFinite,
    /// Another count of numbers than 16.
    #[error("a pose is 16 finite numbers, got {0}")]
    Count(usize),
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn labels_are_integer_ids_and_negative_ones_are_void() {
        let dir = tempfile::tempdir().unwrap();
        let ints = dir.path().join("labels.npy");
        write_npy_u32(&ints, &Grid::from_vec(2, 1, vec![0, 7]).unwrap()).unwrap();
        assert_eq!(read_labels(&ints).unwrap().as_slice(), &[0, 7]);
        let signed = dir.path().join("signed.npy");
        npy::write_npy(File::create(&signed).unwrap(), &[1, 2], &[-1i32, 3]).unwrap();
        assert_eq!(read_labels(&signed).unwrap().as_slice(), &[0, 3]);
        // Floats would be truncated (0.7 → 0: void): refused.
        let floats = dir.path().join("floats.npy");
        write_npy_f32(&floats, &Grid::from_vec(2, 1, vec![0.7, 2.0]).unwrap()).unwrap();
        let e = read_labels(&floats).unwrap_err();
        assert!(
            matches!(&e, IoError::Npy { path, reason: NpyError::LabelsNotInteger { dtype } }
                if path == &floats && dtype == "<f4"),
            "{e:?}"
        );
        let e = e.to_string();
        assert!(e.contains("integer") && e.contains("<f4"), "{e}");
    }

    #[test]
    fn pose_errors_say_what_is_wrong() {
        let dir = tempfile::tempdir().unwrap();
        let pose = dir.path().join("pose.txt");
        let read = |text: &str| {
            std::fs::write(&pose, text).unwrap();
            read_pose(&pose)
        };
        let identity = "1 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1";
        assert_eq!(read(identity).unwrap()[15], 1.0);
        let e = read("1 0 x").unwrap_err();
        assert!(
            matches!(
                &e,
                IoError::Pose {
                    reason: PoseProblem::NotNumbers(_),
                    ..
                }
            ),
            "{e:?}"
        );
        assert!(e.to_string().contains("pose.txt: not numbers ("), "{e}");
        let e = read(&identity.replace("1 0 0 0 0 1", "NaN 0 0 0 0 1")).unwrap_err();
        assert!(
            matches!(
                &e,
                IoError::Pose {
                    reason: PoseProblem::NotFinite,
                    ..
                }
            ),
            "{e:?}"
        );
        let e = read("1 2 3").unwrap_err();
        assert!(
            matches!(
                &e,
                IoError::Pose {
                    reason: PoseProblem::Count(3),
                    ..
                }
            ),
            "{e:?}"
        );
        assert!(
            e.to_string()
                .ends_with("a pose is 16 finite numbers, got 3"),
            "{e}"
        );
    }

    #[test]
    fn file_errors_name_the_file_and_what_is_wrong() {
        let dir = tempfile::tempdir().unwrap();
        let flat = dir.path().join("flat.npy");
        write_npy_f32(&flat, &Grid::new(4, 3, 1.0)).unwrap();
        let e = read_normals(&flat).unwrap_err();
        assert!(
            matches!(&e, IoError::Npy { reason: NpyError::Shape { got, .. }, .. } if got == &[3, 4]),
            "{e:?}"
        );
        assert!(e.to_string().contains("flat.npy") && e.to_string().contains("(H, W, 3)"));
        let nowhere = dir.path().join("no/such/dir/out.npy");
        let e = write_npy_f32(&nowhere, &Grid::new(2, 2, 0.0)).unwrap_err();
        assert!(
            matches!(&e, IoError::Write { path, .. } if path == &nowhere),
            "{e:?}"
        );
    }
}
