//! A folder of frames: images with optional depth of the same stems, or depth alone, each
//! with optional poses.

use std::ffi::OsStr;
use std::path::{Path, PathBuf};

use super::poses::Poses;
use super::{source_err, stem, SourceFrame, SourceProblem};
use crate::ClientError;

/// The frames of a folder, read one at a time.
#[derive(Debug)]
pub struct FolderSource {
    files: std::vec::IntoIter<FolderEntry>,
}

/// One frame of a folder: its name, files and pose.
#[derive(Debug)]
struct FolderEntry {
    name: String,
    image: Option<PathBuf>,
    depth: Option<PathBuf>,
    pose: Option<Vec<f64>>,
}

impl FolderSource {
    /// Lists `frames` and pairs each frame with its depth file in `depth` and its pose in
    /// `poses`.
    pub fn open(
        frames: &Path,
        depth: Option<&Path>,
        poses: Option<&Path>,
    ) -> Result<Self, ClientError> {
        let images = sorted(list_images(frames)?);
        if images.is_empty() {
            return Err(source_err(frames, SourceProblem::NoImages));
        }
        let entries = images
            .into_iter()
            .map(|img| {
                let d = depth.map(|dir| depth_for(&img, dir)).transpose()?;
                Ok((stem(&img), Some(img), d))
            })
            .collect::<Result<Vec<_>, ClientError>>()?;
        Self::with_poses(entries, poses)
    }

    /// Lists the depth frames of `depth` (`.png`, `.npy`) as depth-only frames, each with its
    /// pose in `poses`.
    pub fn depth_only(depth: &Path, poses: Option<&Path>) -> Result<Self, ClientError> {
        let files = sorted(list_files(depth, &["png", "npy"])?);
        if files.is_empty() {
            return Err(source_err(depth, SourceProblem::NoDepthFiles));
        }
        let entries = files.into_iter().map(|d| (stem(&d), None, Some(d)));
        Self::with_poses(entries.collect(), poses)
    }

    fn with_poses(
        entries: Vec<(String, Option<PathBuf>, Option<PathBuf>)>,
        poses: Option<&Path>,
    ) -> Result<Self, ClientError> {
        let poses = match poses {
            Some(p) => {
                let list = Poses::open(p)?;
                list.check_count(p, entries.len())?;
                Some(list)
            }
            None => None,
        };
        let files = entries
            .into_iter()
            .enumerate()
            .map(|(i, (name, image, depth))| {
                let pose = poses.as_ref().map(|p| p.pose(i, &name)).transpose()?;
                Ok(FolderEntry {
                    name,
                    image,
                    depth,
                    pose,
                })
            })
            .collect::<Result<Vec<_>, ClientError>>()?;
        Ok(Self {
            files: files.into_iter(),
        })
    }
}

impl Iterator for FolderSource {
    type Item = Result<SourceFrame, ClientError>;

    fn next(&mut self) -> Option<Self::Item> {
        let e = self.files.next()?;
        let read = |p: &Path| std::fs::read(p).map_err(|e| source_err(p, SourceProblem::Io(e)));
        Some((|| {
            Ok(SourceFrame {
                name: e.name,
                image: e
                    .image
                    .as_deref()
                    .map(read)
                    .transpose()?
                    .unwrap_or_default(),
                depth: e.depth.as_deref().map(read).transpose()?,
                pose: e.pose,
            })
        })())
    }
}

/// `paths` in file-name order.
fn sorted(mut paths: Vec<PathBuf>) -> Vec<PathBuf> {
    paths.sort_by(|a, b| a.file_name().cmp(&b.file_name()));
    paths
}

/// The image files (by extension) directly in `dir`.
fn list_images(dir: &Path) -> Result<Vec<PathBuf>, ClientError> {
    list_files(dir, &["png", "jpg", "jpeg"])
}

/// The files directly in `dir` whose extension is one of `exts` (any case).
fn list_files(dir: &Path, exts: &[&str]) -> Result<Vec<PathBuf>, ClientError> {
    let io_err = |e| source_err(dir, SourceProblem::Io(e));
    let entries = std::fs::read_dir(dir).map_err(io_err)?;
    let mut out = Vec::new();
    for entry in entries {
        let path = entry.map_err(io_err)?.path();
        let ext = path.extension().and_then(OsStr::to_str).unwrap_or("");
        if path.is_file() && exts.iter().any(|e| ext.eq_ignore_ascii_case(e)) {
            out.push(path);
        }
    }
    Ok(out)
}

/// `dir/<stem>.png` or `dir/<stem>.npy` for `image`.
fn depth_for(image: &Path, dir: &Path) -> Result<PathBuf, ClientError> {
    let s = stem(image);
    ["png", "npy"]
        .iter()
        .map(|ext| dir.join(format!("{s}.{ext}")))
        .find(|p| p.is_file())
        .ok_or_else(|| source_err(dir, SourceProblem::NoDepth { stem: s.clone() }))
}
