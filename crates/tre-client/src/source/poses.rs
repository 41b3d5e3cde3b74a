//! Camera-to-world poses for a folder of frames: a folder of `<stem>.txt` files (a 4×4 matrix
//! row by row, as `tre map`'s `poses/`), or one file with a pose a line in the frames' order:
//! 16 numbers (4×4 row by row), 12 (the top 3×4 rows, as KITTI's) or 8 (TUM's `t tx ty tz qx
//! qy qz qw`). Blank lines and lines starting with `#` are skipped.

use std::path::{Path, PathBuf};

use super::{source_err, PoseLineProblem, SourceProblem};
use crate::ClientError;

/// Where a folder's poses come from.
#[derive(Debug)]
pub(super) enum Poses {
    /// `<stem>.txt` in this folder.
    Folder(PathBuf),
    /// One pose a line, in frame order.
    List(Vec<[f64; 16]>),
}

impl Poses {
    /// Opens `path`: a folder of pose files, or a file of poses (read and checked whole).
    pub(super) fn open(path: &Path) -> Result<Self, ClientError> {
        if path.is_dir() {
            return Ok(Self::Folder(path.to_owned()));
        }
        let text =
            std::fs::read_to_string(path).map_err(|e| source_err(path, SourceProblem::Io(e)))?;
        let mut list = Vec::new();
        for (i, line) in text.lines().enumerate() {
            let line = line.trim();
            if line.is_empty() || line.starts_with('#') {
                continue;
            }
            let pose = parse_line(line).map_err(|reason| {
                source_err(
                    path,
                    SourceProblem::PoseLine {
                        line: i + 1,
                        reason,
                    },
                )
            })?;
            list.push(pose);
        }
        Ok(Self::List(list))
    }

    /// Checks that there is a pose for each of `frames` frames (a list long enough).
    pub(super) fn check_count(&self, path: &Path, frames: usize) -> Result<(), ClientError> {
        match self {
            Self::List(l) if l.len() < frames => Err(source_err(
                path,
                SourceProblem::TooFewPoses {
                    poses: l.len(),
                    frames,
                },
            )),
            _ => Ok(()),
        }
    }

    /// The pose of the `index`-th frame, named `stem`, row by row.
    pub(super) fn pose(&self, index: usize, stem: &str) -> Result<Vec<f64>, ClientError> {
        match self {
            Self::List(l) => l.get(index).map(|p| p.to_vec()).ok_or_else(|| {
                source_err(
                    Path::new("poses"),
                    SourceProblem::TooFewPoses {
                        poses: l.len(),
                        frames: index + 1,
                    },
                )
            }),
            Self::Folder(dir) => {
                let path = dir.join(format!("{stem}.txt"));
                if !path.is_file() {
                    return Err(source_err(
                        dir,
                        SourceProblem::NoPose {
                            stem: stem.to_owned(),
                        },
                    ));
                }
                tre_io::read_pose(&path)
                    .map(|p| p.to_vec())
                    .map_err(|e| source_err(&path, SourceProblem::Pose(Box::new(e))))
            }
        }
    }
}

/// One line of a pose list as a 4×4 matrix row by row.
fn parse_line(line: &str) -> Result<[f64; 16], PoseLineProblem> {
    let v: Vec<f64> = line
        .split(|c: char| c.is_whitespace() || c == ',')
        .filter(|t| !t.is_empty())
        .map(str::parse)
        .collect::<Result<_, _>>()
        .map_err(PoseLineProblem::NotNumbers)?;
    if v.iter().any(|x| !x.is_finite()) {
        return Err(PoseLineProblem::NotFinite);
    }
    let mut m = [0.0; 16];
    match v.len() {
        16 => m.copy_from_slice(&v),
        12 => {
            m[..12].copy_from_slice(&v);
            m[15] = 1.0;
        }
        8 => {
            let (t, q) = ([v[1], v[2], v[3]], [v[4], v[5], v[6], v[7]]);
            let r = rotation(q).ok_or(PoseLineProblem::ZeroQuaternion)?;
            for row in 0..3 {
                m[4 * row..4 * row + 3].copy_from_slice(&r[row]);
                m[4 * row + 3] = t[row];
            }
            m[15] = 1.0;
        }
        n => return Err(PoseLineProblem::Count(n)),
    }
    Ok(m)
}

/// The rotation matrix of the quaternion `(x, y, z, w)` (normalised here); `None` for zero.
fn rotation([x, y, z, w]: [f64; 4]) -> Option<[[f64; 3]; 3]> {
    let n = (x * x + y * y + z * z + w * w).sqrt();
    if n < 1e-12 {
        return None;
    }
    let (x, y, z, w) = (x / n, y / n, z / n, w / n);
    Some([
        [
            1.0 - 2.0 * (y * y + z * z),
            2.0 * (x * y - z * w),
            2.0 * (x * z + y * w),
        ],
        [
            2.0 * (x * y + z * w),
            1.0 - 2.0 * (x * x + z * z),
            2.0 * (y * z - x * w),
        ],
        [
            2.0 * (x * z - y * w),
            2.0 * (y * z + x * w),
            1.0 - 2.0 * (x * x + y * y),
        ],
    ])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pose_lines_of_16_12_and_8_numbers_read_as_one_matrix() {
        let full = parse_line("1 0 0 1.5  0 1 0 2  0 0 1 3  0 0 0 1").unwrap();
        let kitti = parse_line("1,0,0,1.5,0,1,0,2,0,0,1,3").unwrap();
        let tum = parse_line("1700000000.5 1.5 2 3 0 0 0 1").unwrap();
        assert_eq!(full, kitti);
        assert_eq!(full, tum);
        // 90° about z: x goes to y.
        let h = std::f64::consts::FRAC_1_SQRT_2;
        let quarter = parse_line(&format!("0 0 0 0 0 0 {h} {h}")).unwrap();
        assert!((quarter[4] - 1.0).abs() < 1e-12 && (quarter[1] + 1.0).abs() < 1e-12);
        assert_eq!(
            parse_line("1 2 3").unwrap_err().to_string(),
            "3 numbers: expected 16 (4×4), 12 (3×4) or 8 (t tx ty tz qx qy qz qw)"
        );
        assert_eq!(
            parse_line("0 0 0 0 0 0 0 0").unwrap_err(),
            PoseLineProblem::ZeroQuaternion
        );
        assert!(parse_line("a b").is_err());
    }

    #[test]
    fn a_pose_file_gives_one_pose_a_frame_in_order() {
        let dir = tempfile::tempdir().unwrap();
        let file = dir.path().join("poses.txt");
        std::fs::write(
            &file,
            "# t tx ty tz qx qy qz qw\n0 1 2 3 0 0 0 1\n\n1 4 5 6 0 0 0 1\n",
        )
        .unwrap();
        let poses = Poses::open(&file).unwrap();
        assert_eq!(poses.pose(1, "any").unwrap()[3], 4.0);
        assert!(poses.check_count(&file, 2).is_ok());
        let e = poses.check_count(&file, 3).unwrap_err().to_string();
        assert!(e.contains("2 poses for 3 frames"), "{e}");
        std::fs::write(&file, "0 1 2\n").unwrap();
        let e = Poses::open(&file).unwrap_err().to_string();
        assert!(e.contains("line 1"), "{e}");
        let folder = Poses::open(dir.path()).unwrap();
        let e = folder.pose(0, "frame-1").unwrap_err().to_string();
        assert!(e.contains("no pose for frame frame-1"), "{e}");
    }
}
