//! The frames a load test sends: files, a folder of images, or one synthetic terrain frame
//! rendered in memory by [`tre_synth`]; each encoded once and cycled.

use std::io::Cursor;
use std::path::{Path, PathBuf};

use image::{DynamicImage, ImageFormat};
use tokio_tungstenite::tungstenite::Bytes;

use super::problems::FrameProblem;
use super::{LoadConfigProblem, LoadError};
use tre_synth::dataset::{build_scene, scene_views, view_conditions};
use tre_synth::{dataset::SynthConfig, render};

/// Where a load test's frames come from (a client session's are a
/// [`tre_client::source::SourceSpec`]).
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum LoadSource {
    /// One synthetic terrain frame of this size (width, height), rendered with a fixed seed.
    Synthetic {
        /// Width and height, pixels.
        size: (usize, usize),
    },
    /// These PNG or JPEG files, in order.
    Files(Vec<PathBuf>),
    /// Every `.png`, `.jpg` and `.jpeg` file in this folder, by name.
    Dir(PathBuf),
}

impl Default for LoadSource {
    fn default() -> Self {
        Self::Synthetic { size: (256, 256) }
    }
}

/// One frame of a load test, encoded once for both transports (a client session's frame is
/// a [`tre_client::Frame`]).
#[derive(Debug, Clone)]
pub struct LoadFrame {
    /// The HTTP body: the image alone (PNG or JPEG), or with depth or a camera a multipart
    /// form of parts `rgb`, `depth` and `camera`, built once.
    pub bytes: Bytes,
    /// `image/png`, `image/jpeg` or the multipart form's type.
    pub content_type: &'static str,
    /// The image for the stream (empty: depth only).
    pub image: Bytes,
    /// The depth for the stream (empty: none): a 16-bit PNG or a float `.npy`.
    pub depth: Bytes,
}

/// The multipart boundary of load-test bodies.
const BOUNDARY: &str = "tre-loadtest-5e1f7c";
/// The content type of a multipart load-test body.
const MULTIPART: &str = "multipart/form-data; boundary=tre-loadtest-5e1f7c";

impl LoadFrame {
    /// A frame of `image` (may be empty) and `depth` (may be empty), with the camera JSON
    /// `camera` as written (may be empty) for the HTTP form.
    pub fn new(image: Vec<u8>, depth: Vec<u8>, camera: &[u8]) -> Self {
        if depth.is_empty() && camera.is_empty() {
            return Self {
                content_type: content_type(&image).unwrap_or("image/png"),
                bytes: Bytes::from(image.clone()),
                image: Bytes::from(image),
                depth: Bytes::new(),
            };
        }
        let mut body = Vec::new();
        let mut part = |name: &str, file: &str, ct: &str, bytes: &[u8]| {
            if bytes.is_empty() {
                return;
            }
            body.extend_from_slice(
                format!(
                    "--{BOUNDARY}\r\nContent-Disposition: form-data; name=\"{name}\"; \
                     filename=\"{file}\"\r\nContent-Type: {ct}\r\n\r\n"
                )
                .as_bytes(),
            );
            body.extend_from_slice(bytes);
            body.extend_from_slice(b"\r\n");
        };
        part(
            "rgb",
            "rgb",
            content_type(&image).unwrap_or("image/png"),
            &image,
        );
        let depth_type = if depth.starts_with(b"\x93NUMPY") {
            "application/octet-stream"
        } else {
            "image/png"
        };
        part("depth", "depth", depth_type, &depth);
        part("camera", "camera.json", "application/json", camera);
        body.extend_from_slice(format!("--{BOUNDARY}--\r\n").as_bytes());
        Self {
            bytes: Bytes::from(body),
            content_type: MULTIPART,
            image: Bytes::from(image),
            depth: Bytes::from(depth),
        }
    }
}

/// The frames of a run, cycled by request index.
#[derive(Debug, Clone)]
pub struct Frames {
    frames: Vec<LoadFrame>,
    /// What they are, for the report (`synthetic 256×256 PNG, 151 KB`).
    pub description: String,
}

impl Frames {
    /// Loads or renders the frames of `source`.
    pub fn load(source: &LoadSource) -> Result<Self, LoadError> {
        match source {
            LoadSource::Synthetic { size } => synthetic(*size),
            LoadSource::Files(paths) => from_files(paths),
            LoadSource::Dir(dir) => from_files(&files_in(dir, &["png", "jpg", "jpeg"])?),
        }
    }

    /// Frames from bytes already in memory (each a PNG or JPEG).
    pub fn from_bytes(images: Vec<Vec<u8>>, description: impl Into<String>) -> Self {
        let frames = images
            .into_iter()
            .map(|b| LoadFrame::new(b, Vec::new(), &[]))
            .collect();
        Self {
            frames,
            description: description.into(),
        }
    }

    /// The frames of `images` (`None`: depth only), each with the depth of `depth` at the same
    /// place (cycled; both lists of files must then be as long), and the camera JSON `camera`
    /// (as written, sent with every HTTP request; empty: none).
    pub fn with_depth(
        images: Option<&LoadSource>,
        depth: Option<&LoadSource>,
        camera: &[u8],
    ) -> Result<Self, LoadError> {
        let images = match images {
            Some(src) => Some(Self::load(src)?),
            None => None,
        };
        let Some(depth) = depth else {
            let images = images.unwrap_or_else(|| Self::from_bytes(Vec::new(), ""));
            if camera.is_empty() {
                return Ok(images);
            }
            let frames = images
                .frames
                .iter()
                .map(|f| LoadFrame::new(f.image.to_vec(), Vec::new(), camera))
                .collect();
            return Ok(Self {
                frames,
                description: format!("{} with a camera", images.description),
            });
        };
        let paths = match depth {
            LoadSource::Files(p) => p.clone(),
            LoadSource::Dir(d) => files_in(d, &["png", "npy"])?,
            LoadSource::Synthetic { .. } => {
                return Err(LoadError::Config(LoadConfigProblem::SyntheticDepth))
            }
        };
        let depths = read_depth_files(&paths)?;
        let kb = depths.iter().map(Vec::len).sum::<usize>().div_ceil(1024);
        let frames: Vec<LoadFrame> = match &images {
            Some(images) if images.len() != depths.len() => {
                return Err(LoadError::Config(LoadConfigProblem::DepthCount {
                    images: images.len(),
                    depths: depths.len(),
                }))
            }
            Some(images) => images
                .frames
                .iter()
                .zip(depths)
                .map(|(f, d)| LoadFrame::new(f.image.to_vec(), d, camera))
                .collect(),
            None => depths
                .into_iter()
                .map(|d| LoadFrame::new(Vec::new(), d, camera))
                .collect(),
        };
        let with_camera = if camera.is_empty() { "" } else { ", a camera" };
        let description = match &images {
            Some(i) => format!("{} with depth ({kb} KB{with_camera})", i.description),
            None => format!("depth only: {} files, {kb} KB{with_camera}", frames.len()),
        };
        Ok(Self {
            frames,
            description,
        })
    }

    /// The frame for request `i` (cycling).
    pub fn get(&self, i: u64) -> &LoadFrame {
        let n = self.frames.len().max(1) as u64;
        &self.frames[(i % n) as usize]
    }

    /// Number of distinct frames.
    pub fn len(&self) -> usize {
        self.frames.len()
    }

    /// Whether there is no frame (never, once loaded).
    pub fn is_empty(&self) -> bool {
        self.frames.is_empty()
    }
}

/// The bytes of depth files, each a 16-bit PNG or a float `.npy` (checked by its magic bytes).
fn read_depth_files(paths: &[PathBuf]) -> Result<Vec<Vec<u8>>, LoadError> {
    let mut depths = Vec::with_capacity(paths.len());
    for path in paths {
        let bytes = std::fs::read(path).map_err(|e| LoadError::Frame {
            path: path.clone(),
            why: e.into(),
        })?;
        if !(bytes.starts_with(b"\x93NUMPY") || content_type(&bytes) == Some("image/png")) {
            return Err(LoadError::Frame {
                path: path.clone(),
                why: FrameProblem::DepthFormat,
            });
        }
        depths.push(bytes);
    }
    Ok(depths)
}

/// `image/png` or `image/jpeg` from the magic bytes.
pub(crate) fn content_type(bytes: &[u8]) -> Option<&'static str> {
    if bytes.starts_with(b"\x89PNG\r\n\x1a\n") {
        Some("image/png")
    } else if bytes.starts_with(&[0xFF, 0xD8, 0xFF]) {
        Some("image/jpeg")
    } else {
        None
    }
}

/// View 4 (straight ahead) of scene 0 of seed 7, rendered at `size` and encoded as PNG.
pub(crate) fn synthetic_png(size: (usize, usize)) -> Result<Vec<u8>, LoadError> {
    if size.0 == 0 || size.1 == 0 || size.0 * size.1 > 16_000_000 {
        return Err(LoadError::Config(LoadConfigProblem::SyntheticSize { size }));
    }
    let cfg = SynthConfig {
        seed: 7,
        size,
        views: 9,
        ply: false,
        ..SynthConfig::default()
    };
    let views = scene_views(&cfg, 0);
    let view = views[4];
    let scene = build_scene(&cfg, 0, &[view]);
    let frame = render(&scene, &view, &view_conditions(&cfg, 0, 4));
    let mut png = Cursor::new(Vec::new());
    DynamicImage::ImageRgb8(frame.rgb)
        .write_to(&mut png, ImageFormat::Png)
        .map_err(LoadError::Synthetic)?;
    Ok(png.into_inner())
}

fn synthetic(size: (usize, usize)) -> Result<Frames, LoadError> {
    let png = synthetic_png(size)?;
    let description = format!(
        "synthetic {}×{} PNG, {} KB",
        size.0,
        size.1,
        png.len().div_ceil(1024)
    );
    Ok(Frames::from_bytes(vec![png], description))
}

fn from_files(paths: &[PathBuf]) -> Result<Frames, LoadError> {
    let mut frames = Vec::with_capacity(paths.len());
    let mut total = 0;
    for path in paths {
        let bytes = std::fs::read(path).map_err(|e| LoadError::Frame {
            path: path.clone(),
            why: e.into(),
        })?;
        content_type(&bytes).ok_or_else(|| LoadError::Frame {
            path: path.clone(),
            why: FrameProblem::NotAnImage,
        })?;
        total += bytes.len();
        frames.push(LoadFrame::new(bytes, Vec::new(), &[]));
    }
    let description = match paths {
        [one] => format!("{} ({} KB)", one.display(), total.div_ceil(1024)),
        _ => format!("{} files, {} KB in all", paths.len(), total.div_ceil(1024)),
    };
    Ok(Frames {
        frames,
        description,
    })
}

/// The files of `dir` with one of the extensions `exts`, sorted by name; none is an error.
fn files_in(dir: &Path, exts: &[&str]) -> Result<Vec<PathBuf>, LoadError> {
    let err = |why: FrameProblem| LoadError::Frame {
        path: dir.to_path_buf(),
        why,
    };
    let mut paths: Vec<PathBuf> = std::fs::read_dir(dir)
        .map_err(|e| err(e.into()))?
        .filter_map(Result::ok)
        .map(|e| e.path())
        .filter(|p| {
            p.extension()
                .and_then(|e| e.to_str())
                .is_some_and(|e| exts.contains(&e.to_ascii_lowercase().as_str()))
        })
        .collect();
    paths.sort();
    if paths.is_empty() {
        return Err(err(FrameProblem::NoFile {
            extensions: exts.iter().map(|e| (*e).to_owned()).collect(),
        }));
    }
    Ok(paths)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_synthetic_frame_is_a_png_of_the_asked_size_and_the_same_every_time() {
        let a = synthetic_png((64, 48)).expect("renders");
        assert_eq!(content_type(&a), Some("image/png"));
        let img = image::load_from_memory(&a).expect("decodes");
        assert_eq!((img.width(), img.height()), (64, 48));
        assert_eq!(a, synthetic_png((64, 48)).expect("renders"));
    }

    #[test]
    fn frames_cycle_and_bad_files_are_named() {
        let f = Frames::from_bytes(
            vec![b"\x89PNG\r\n\x1a\n1".to_vec(), vec![0xFF, 0xD8, 0xFF]],
            "two",
        );
        assert_eq!(f.get(0).content_type, "image/png");
        assert_eq!(f.get(3).content_type, "image/jpeg");
        let dir = tempfile::tempdir().expect("tempdir");
        let txt = dir.path().join("a.png");
        std::fs::write(&txt, "hello").expect("write");
        let e = Frames::load(&LoadSource::Files(vec![txt])).expect_err("not an image");
        assert!(e.to_string().contains("not a PNG or JPEG"), "{e}");
        let empty = tempfile::tempdir().expect("tempdir");
        let e = Frames::load(&LoadSource::Dir(empty.path().into())).expect_err("empty");
        assert!(e.to_string().contains("no .png"), "{e}");
    }
}
