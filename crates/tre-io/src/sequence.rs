//! A recorded sequence folder, as `tre map` reads it: `depth/*.png` (16-bit, the camera's
//! `depth_scale`) or `depth/*.npy`, optional `rgb/<stem>.jpg|png`, `poses/<stem>.txt` (4×4
//! camera-to-world, row by row) and `gravity.json` (`{"gravity": [x, y, z]}`, the world's down
//! direction).

use std::path::{Path, PathBuf};

use tre_core::geometry::Vec3;

use crate::IoError;

/// One frame of a sequence: its files.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SequenceFrame {
    /// The depth file's stem, which names the frame.
    pub stem: String,
    /// Its depth (`depth/<stem>.png` or `.npy`).
    pub depth: PathBuf,
    /// Its colour image, when there is one.
    pub rgb: Option<PathBuf>,
    /// Its pose file, when there is one.
    pub pose: Option<PathBuf>,
}

impl SequenceFrame {
    /// The number the frame's name ends with (`frame-000020`: 20), if it ends with one.
    pub fn number(&self) -> Option<u64> {
        let head = self.stem.trim_end_matches(|c: char| c.is_ascii_digit());
        self.stem[head.len()..].parse().ok()
    }
}

/// Which frames of a sequence to take, in which order (options of `tre map`, clap's behind the
/// `cli` feature).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "cli", derive(clap::Args))]
pub struct FrameSelection {
    /// Use every Nth frame.
    // 0 and 1: all.
    #[cfg_attr(feature = "cli", arg(long, default_value_t = 1))]
    pub stride: usize,
    /// Use at most this many frames.
    #[cfg_attr(feature = "cli", arg(long))]
    pub limit: Option<usize>,
    /// Fuse the frames in reverse order (the map should not depend on the order).
    #[cfg_attr(feature = "cli", arg(long))]
    pub reverse: bool,
}

/// The frames of the sequence at `dir` in name order, with `select` applied.
pub fn sequence_frames(dir: &Path, select: FrameSelection) -> Result<Vec<SequenceFrame>, IoError> {
    let depth_dir = dir.join("depth");
    let mut depths: Vec<PathBuf> = std::fs::read_dir(&depth_dir)
        .map_err(|reason| IoError::Read {
            path: depth_dir.clone(),
            reason,
        })?
        .filter_map(Result::ok)
        .map(|e| e.path())
        .filter(|p| p.extension().is_some_and(|e| e == "png" || e == "npy"))
        .collect();
    depths.sort();
    if depths.is_empty() {
        return Err(IoError::NoFrames { dir: depth_dir });
    }
    let mut frames: Vec<SequenceFrame> = depths
        .into_iter()
        .step_by(select.stride.max(1))
        .map(|depth| {
            let stem = depth
                .file_stem()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_default();
            let pose = Some(dir.join("poses").join(format!("{stem}.txt"))).filter(|p| p.is_file());
            let rgb = ["jpg", "png"]
                .iter()
                .map(|e| dir.join("rgb").join(format!("{stem}.{e}")))
                .find(|p| p.is_file());
            SequenceFrame {
                stem,
                depth,
                rgb,
                pose,
            }
        })
        .collect();
    if let Some(n) = select.limit {
        frames.truncate(n);
    }
    if select.reverse {
        frames.reverse();
    }
    Ok(frames)
}

/// The world's down direction from the sequence's `gravity.json`; `None` when it has none.
pub fn read_gravity(dir: &Path) -> Result<Option<Vec3>, IoError> {
    #[derive(serde::Deserialize)]
    struct GravityFile {
        gravity: [f64; 3],
    }
    let path = dir.join("gravity.json");
    if !path.is_file() {
        return Ok(None);
    }
    let bytes = std::fs::read(&path).map_err(|reason| IoError::Read {
        path: path.clone(),
        reason,
    })?;
    let g: GravityFile =
        serde_json::from_slice(&bytes).map_err(|reason| IoError::Gravity { path, reason })?;
    Ok(Some(Vec3::new(g.gravity[0], g.gravity[1], g.gravity[2])))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_frame_is_numbered_by_the_digits_its_name_ends_with() {
        let frame = |stem: &str| SequenceFrame {
            stem: stem.into(),
            depth: PathBuf::new(),
            rgb: None,
            pose: None,
        };
        assert_eq!(frame("frame-000020").number(), Some(20));
        assert_eq!(frame("7").number(), Some(7));
        assert_eq!(frame("left").number(), None);
    }

    #[test]
    fn frames_pair_their_pose_and_colour_and_the_selection_applies() {
        let dir = tempfile::tempdir().unwrap();
        for sub in ["depth", "poses", "rgb"] {
            std::fs::create_dir(dir.path().join(sub)).unwrap();
        }
        for stem in ["a", "b", "c"] {
            std::fs::write(dir.path().join(format!("depth/{stem}.png")), b"").unwrap();
        }
        std::fs::write(dir.path().join("poses/b.txt"), b"").unwrap();
        std::fs::write(dir.path().join("rgb/b.jpg"), b"").unwrap();
        std::fs::write(dir.path().join("depth/notes.txt"), b"").unwrap();
        let all = FrameSelection {
            stride: 1,
            limit: None,
            reverse: false,
        };
        let frames = sequence_frames(dir.path(), all).unwrap();
        let stems: Vec<&str> = frames.iter().map(|f| f.stem.as_str()).collect();
        assert_eq!(stems, ["a", "b", "c"]);
        assert!(frames[0].pose.is_none() && frames[0].rgb.is_none());
        assert!(frames[1].pose.is_some() && frames[1].rgb.is_some());
        let some = FrameSelection {
            stride: 2,
            limit: Some(1),
            reverse: true,
        };
        let frames = sequence_frames(dir.path(), some).unwrap();
        assert_eq!(frames.len(), 1);
        assert_eq!(frames[0].stem, "a");
        std::fs::create_dir(dir.path().join("empty")).unwrap();
        std::fs::create_dir(dir.path().join("empty/depth")).unwrap();
        let e = sequence_frames(&dir.path().join("empty"), all).unwrap_err();
        assert!(e.to_string().contains("no .png or .npy depth frame"), "{e}");
    }

    #[test]
    fn gravity_is_read_when_present_and_malformed_files_are_refused() {
        let dir = tempfile::tempdir().unwrap();
        assert_eq!(read_gravity(dir.path()).unwrap(), None);
        std::fs::write(
            dir.path().join("gravity.json"),
            br#"{"gravity": [0, 1, 0]}"#,
        )
        .unwrap();
        assert_eq!(
            read_gravity(dir.path()).unwrap(),
            Some(Vec3::new(0.0, 1.0, 0.0))
        );
        std::fs::write(dir.path().join("gravity.json"), br#"{"gravity": [0, 1]}"#).unwrap();
        let e = read_gravity(dir.path()).unwrap_err().to_string();
        assert!(e.contains("gravity.json"), "{e}");
    }
}
