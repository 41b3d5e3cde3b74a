//! Frame sources for the client: a folder of images (with an optional folder of depth frames of
//! the same stems), a folder of depth frames alone (the geometric mode), each with optional
//! camera-to-world poses (a folder of `<stem>.txt` or a pose-a-line file), or a video file or V4L2 camera decoded by an `ffmpeg`
//! process (spawned when `ffmpeg` is on `PATH`; no video library is linked in).
//!
//! Frames are sent as the encoded bytes they are read as (PNG or JPEG): nothing is decoded or
//! re-encoded on the robot.

use std::ffi::OsStr;
use std::io::{self, BufReader, Read};
use std::path::{Path, PathBuf};
use std::process::{Child, ChildStdout, Command, ExitStatus, Stdio};
use std::sync::{Arc, Condvar, Mutex, PoisonError};
use std::thread::JoinHandle;

use super::ClientError;
use poses::Poses;

mod poses;

/// Where frames come from.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum SourceSpec {
    /// Every `.png`, `.jpg` and `.jpeg` file of `frames`, in file-name order (byte order:
    /// zero-pad numbers). With `depth`, frame `frames/<stem>.<ext>` takes its depth from
    /// `depth/<stem>.png` (16-bit) or `depth/<stem>.npy`; every frame must have one.
    Folder {
        /// The frames.
        frames: PathBuf,
        /// Depth frames with the same stems.
        depth: Option<PathBuf>,
        /// Camera-to-world poses: a folder of `<stem>.txt`, or a file of one pose a line in
        /// the frames' order (16, 12 or 8 numbers a line).
        poses: Option<PathBuf>,
    },
    /// Every `.png` (16-bit) and `.npy` file of `depth`, in file-name order, sent as
    /// depth-only frames (no colour: the geometric mode).
    Depth {
        /// The depth frames.
        depth: PathBuf,
        /// Camera-to-world poses, as for [`SourceSpec::Folder`].
        poses: Option<PathBuf>,
    },
    /// A video file, decoded by `ffmpeg`; frames are named `<file stem>_<index>`.
    Video(PathBuf),
    /// A V4L2 camera (`/dev/videoN`) read by `ffmpeg`; the newest frame wins (frames the
    /// client has no time for are skipped), named `<device>_<index>`.
    Device(PathBuf),
}

/// What is wrong with a frame source's file or folder ([`ClientError::Source`]).
// The cause is in the message, not a `source`: a report that prints the chain would say it
// twice.
#[derive(Debug, thiserror::Error)]
pub enum SourceProblem {
    /// It cannot be listed or read.
    #[error("{0}")]
    Io(io::Error),
    /// A folder without frames.
    #[error("no .png, .jpg or .jpeg files")]
    NoImages,
    /// A frame without its depth file.
    #[error("no depth for frame {stem}: expected {stem}.png or {stem}.npy")]
    NoDepth {
        /// The frame's file stem.
        stem: String,
    },
    /// A video path that is not a file.
    #[error("no such video file")]
    NoVideo,
    /// A folder of depth frames without any.
    #[error("no .png or .npy depth files")]
    NoDepthFiles,
    /// A frame without its pose file.
    #[error("no pose for frame {stem}: expected {stem}.txt")]
    NoPose {
        /// The frame's file stem.
        stem: String,
    },
    /// A pose file that is not a pose.
    #[error("{0}")]
    Pose(Box<tre_io::IoError>),
    /// A line of a pose list that is not a pose.
    #[error("line {line}: {reason}")]
    PoseLine {
        /// The line, from 1.
        line: usize,
        /// Why.
        reason: String,
    },
    /// A pose list shorter than the frames.
    #[error("{poses} poses for {frames} frames")]
    TooFewPoses {
        /// Poses in the list.
        poses: usize,
        /// Frames of the folder.
        frames: usize,
    },
}

/// What went wrong with `ffmpeg` ([`ClientError::Ffmpeg`]).
// The cause is in the message, not a `source` (as [`SourceProblem`]).
#[derive(Debug, thiserror::Error)]
pub enum FfmpegProblem {
    /// The process cannot be started.
    #[error("cannot start ffmpeg: {0}")]
    Start(io::Error),
    /// The process came without one of its pipes (`stdout`, `stderr`).
    #[error("no {0} pipe")]
    NoPipe(&'static str),
    /// A thread reading its pipes cannot be started.
    #[error("cannot start a thread ({name}): {reason}")]
    Thread {
        /// The thread.
        name: &'static str,
        /// Why.
        reason: io::Error,
    },
    /// It ended cleanly without a frame.
    #[error("no frames decoded")]
    NoFrames,
    /// It failed; the end of what it wrote on stderr says why.
    #[error("{status}: {}", .stderr_tail.trim())]
    Exited {
        /// Its exit status.
        status: ExitStatus,
        /// The last few kilobytes of its stderr.
        stderr_tail: String,
    },
    /// Its exit status cannot be had.
    #[error("waiting for it: {0}")]
    Wait(io::Error),
    /// Its output is not a stream of PNG images.
    #[error("{0}")]
    Stream(PngStreamError),
}

/// Why a stream of concatenated PNGs cannot be split ([`read_png`]).
// The cause is in the message, not a `source` (as [`SourceProblem`]).
#[derive(Debug, thiserror::Error)]
pub enum PngStreamError {
    /// Bytes that do not start with the PNG signature.
    #[error("the stream is not a sequence of PNG images")]
    NotPng,
    /// The stream ended part way through an image.
    #[error("the stream ended inside a PNG")]
    Truncated,
    /// An image larger than the limit (256 MiB).
    #[error("a PNG larger than {MAX_PNG_BYTES} bytes")]
    TooLarge,
    /// Reading the stream failed.
    #[error("{0}")]
    Read(io::Error),
}

/// One frame from a source.
#[derive(Debug, Clone, PartialEq)]
pub struct SourceFrame {
    /// A name for outputs: the file stem, or `<video>_<index>`.
    pub name: String,
    /// PNG or JPEG bytes (empty for a depth-only frame).
    pub image: Vec<u8>,
    /// Depth bytes (16-bit PNG or `.npy`), if the source has depth.
    pub depth: Option<Vec<u8>>,
    /// Camera-to-world pose, 4×4 row by row, if the source has poses.
    pub pose: Option<Vec<f64>>,
}

/// An open frame source: an iterator of frames, ending at the end of the folder or video.
#[derive(Debug)]
pub enum FrameSource {
    /// A folder listing.
    Folder(FolderSource),
    /// An `ffmpeg` process.
    Ffmpeg(FfmpegSource),
}

impl FrameSource {
    /// Opens `spec`: lists and pairs a folder, or starts `ffmpeg`.
    pub fn open(spec: &SourceSpec) -> Result<Self, ClientError> {
        Ok(match spec {
            SourceSpec::Folder {
                frames,
                depth,
                poses,
            } => Self::Folder(FolderSource::open(
                frames,
                depth.as_deref(),
                poses.as_deref(),
            )?),
            SourceSpec::Depth { depth, poses } => {
                Self::Folder(FolderSource::depth_only(depth, poses.as_deref())?)
            }
            SourceSpec::Video(path) => Self::Ffmpeg(FfmpegSource::video(path)?),
            SourceSpec::Device(path) => Self::Ffmpeg(FfmpegSource::device(path)?),
        })
    }
}

impl Iterator for FrameSource {
    type Item = Result<SourceFrame, ClientError>;

    fn next(&mut self) -> Option<Self::Item> {
        match self {
            Self::Folder(f) => f.next(),
            Self::Ffmpeg(f) => f.next(),
        }
    }
}

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

fn source_err(path: &Path, reason: SourceProblem) -> ClientError {
    ClientError::Source {
        path: path.to_owned(),
        reason,
    }
}

fn stem(path: &Path) -> String {
    path.file_stem()
        .map_or_else(|| "frame".to_owned(), |s| s.to_string_lossy().into_owned())
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

/// Frames decoded by an `ffmpeg` child process, read as a stream of PNGs from its stdout.
#[derive(Debug)]
pub struct FfmpegSource {
    input: String,
    prefix: String,
    index: u64,
    child: Child,
    frames: FfmpegFrames,
    stderr: Option<JoinHandle<String>>,
    done: bool,
}

/// How frames leave the pipe: in order (a file), or newest only (a live camera).
#[derive(Debug)]
enum FfmpegFrames {
    InOrder(BufReader<ChildStdout>),
    Latest(Arc<LatestSlot>, Option<JoinHandle<()>>),
}

impl FfmpegSource {
    /// Decodes a video file.
    pub fn video(path: &Path) -> Result<Self, ClientError> {
        let input = path.display().to_string();
        if !path.is_file() {
            return Err(source_err(path, SourceProblem::NoVideo));
        }
        Self::spawn(&input, stem(path), &[], path.as_os_str(), false)
    }

    /// Reads a V4L2 camera device.
    pub fn device(path: &Path) -> Result<Self, ClientError> {
        let input = path.display().to_string();
        let name = path
            .file_name()
            .map_or_else(|| "camera".to_owned(), |s| s.to_string_lossy().into_owned());
        Self::spawn(&input, name, &["-f", "v4l2"], path.as_os_str(), true)
    }

    fn spawn(
        input: &str,
        prefix: String,
        input_args: &[&str],
        path: &OsStr,
        live: bool,
    ) -> Result<Self, ClientError> {
        let ffmpeg =
            find_executable("ffmpeg", std::env::var_os("PATH").as_deref()).ok_or_else(|| {
                ClientError::FfmpegMissing {
                    input: input.to_owned(),
                }
            })?;
        let mut child = Command::new(ffmpeg)
            .args(["-hide_banner", "-loglevel", "error", "-nostdin"])
            .args(input_args)
            .arg("-i")
            .arg(path)
            .args([
                "-f",
                "image2pipe",
                "-vcodec",
                "png",
                "-pix_fmt",
                "rgb24",
                "-",
            ])
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .map_err(|e| failed(input, FfmpegProblem::Start(e)))?;
        let no_pipe = |which| failed(input, FfmpegProblem::NoPipe(which));
        let stdout = BufReader::new(child.stdout.take().ok_or_else(|| no_pipe("stdout"))?);
        let stderr = child.stderr.take().ok_or_else(|| no_pipe("stderr"))?;
        let stderr = spawn_named(input, "tre-ffmpeg-stderr", move || tail(stderr, 4096))?;
        let frames = if live {
            let slot = Arc::new(LatestSlot::default());
            let writer = slot.clone();
            let reader = spawn_named(input, "tre-ffmpeg-frames", move || writer.fill(stdout))?;
            FfmpegFrames::Latest(slot, Some(reader))
        } else {
            FfmpegFrames::InOrder(stdout)
        };
        Ok(Self {
            input: input.to_owned(),
            prefix,
            index: 0,
            child,
            frames,
            stderr: Some(stderr),
            done: false,
        })
    }

    /// The next PNG, `Ok(None)` at the end of the stream.
    fn next_png(&mut self) -> Result<Option<Vec<u8>>, PngStreamError> {
        match &mut self.frames {
            FfmpegFrames::InOrder(r) => read_png(r),
            FfmpegFrames::Latest(slot, _) => slot.take(),
        }
    }

    /// At the end of the stream: ffmpeg's verdict.
    fn finish(&mut self) -> Option<Result<SourceFrame, ClientError>> {
        let status = self.child.wait();
        let stderr = self
            .stderr
            .take()
            .and_then(|h| h.join().ok())
            .unwrap_or_default();
        let reason = match status {
            Ok(s) if s.success() && self.index > 0 => return None,
            Ok(s) if s.success() => FfmpegProblem::NoFrames,
            Ok(status) => FfmpegProblem::Exited {
                status,
                stderr_tail: stderr,
            },
            Err(e) => FfmpegProblem::Wait(e),
        };
        Some(Err(failed(&self.input, reason)))
    }
}

impl Iterator for FfmpegSource {
    type Item = Result<SourceFrame, ClientError>;

    fn next(&mut self) -> Option<Self::Item> {
        if self.done {
            return None;
        }
        match self.next_png() {
            Ok(Some(image)) => {
                self.index += 1;
                Some(Ok(SourceFrame {
                    name: format!("{}_{:06}", self.prefix, self.index),
                    image,
                    depth: None,
                    pose: None,
                }))
            }
            Ok(None) => {
                self.done = true;
                self.finish()
            }
            Err(e) => {
                self.done = true;
                let _ = self.child.kill();
                let _ = self.child.wait();
                Some(Err(failed(&self.input, FfmpegProblem::Stream(e))))
            }
        }
    }
}

impl Drop for FfmpegSource {
    fn drop(&mut self) {
        if !self.done {
            let _ = self.child.kill();
            let _ = self.child.wait();
        }
        if let FfmpegFrames::Latest(slot, reader) = &mut self.frames {
            slot.close();
            if let Some(h) = reader.take() {
                let _ = h.join();
            }
        }
    }
}

/// The error of `ffmpeg` on `input`.
fn failed(input: &str, reason: FfmpegProblem) -> ClientError {
    ClientError::Ffmpeg {
        input: input.to_owned(),
        reason,
    }
}

/// Starts a named thread for `ffmpeg` on `input`.
fn spawn_named<T: Send + 'static>(
    input: &str,
    name: &'static str,
    f: impl FnOnce() -> T + Send + 'static,
) -> Result<JoinHandle<T>, ClientError> {
    std::thread::Builder::new()
        .name(name.to_owned())
        .spawn(f)
        .map_err(|reason| failed(input, FfmpegProblem::Thread { name, reason }))
}

/// The last `max` bytes of what `r` gives until its end, as text.
fn tail(mut r: impl Read, max: usize) -> String {
    let mut kept = Vec::new();
    let mut buf = [0u8; 1024];
    while let Ok(n) = r.read(&mut buf) {
        if n == 0 {
            break;
        }
        kept.extend_from_slice(&buf[..n]);
        if kept.len() > max {
            kept.drain(..kept.len() - max);
        }
    }
    String::from_utf8_lossy(&kept).into_owned()
}

/// One frame slot between a live camera's reader thread and the client: a new frame replaces
/// one not yet taken.
#[derive(Debug, Default)]
struct LatestSlot {
    state: Mutex<SlotState>,
    changed: Condvar,
}

#[derive(Debug, Default)]
struct SlotState {
    frame: Option<Vec<u8>>,
    /// Set at the end of the stream: `Ok` for a clean end. An error is handed out once, then
    /// reads as a clean end.
    end: Option<Result<(), PngStreamError>>,
    closed: bool,
}

impl LatestSlot {
    /// Reads PNGs from `r` into the slot until the stream ends or the slot is closed.
    fn fill(&self, mut r: impl Read) {
        loop {
            let next = read_png(&mut r);
            let mut s = self.state.lock().unwrap_or_else(PoisonError::into_inner);
            if s.closed {
                return;
            }
            match next {
                Ok(Some(png)) => s.frame = Some(png),
                Ok(None) => s.end = Some(Ok(())),
                Err(e) => s.end = Some(Err(e)),
            }
            let ended = s.end.is_some();
            drop(s);
            self.changed.notify_all();
            if ended {
                return;
            }
        }
    }

    /// The newest frame, waiting for one; `Ok(None)` at the end.
    fn take(&self) -> Result<Option<Vec<u8>>, PngStreamError> {
        let mut s = self.state.lock().unwrap_or_else(PoisonError::into_inner);
        loop {
            if let Some(f) = s.frame.take() {
                return Ok(Some(f));
            }
            if let Some(end) = s.end.as_mut() {
                return std::mem::replace(end, Ok(())).map(|()| None);
            }
            s = self.changed.wait(s).unwrap_or_else(PoisonError::into_inner);
        }
    }

    fn close(&self) {
        self.state
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .closed = true;
        self.changed.notify_all();
    }
}

const PNG_SIGNATURE: [u8; 8] = *b"\x89PNG\r\n\x1a\n";
/// Largest PNG accepted from the pipe, bytes.
const MAX_PNG_BYTES: usize = 256 << 20;

/// Reads one PNG from a stream of concatenated PNGs (`ffmpeg -f image2pipe -vcodec png`):
/// the signature, then chunks up to `IEND`. `Ok(None)` at a clean end of the stream.
pub fn read_png(r: &mut impl Read) -> Result<Option<Vec<u8>>, PngStreamError> {
    let mut sig = [0u8; 8];
    let n = read_full(r, &mut sig)?;
    if n == 0 {
        return Ok(None);
    }
    if n < sig.len() || sig != PNG_SIGNATURE {
        return Err(PngStreamError::NotPng);
    }
    let mut out = sig.to_vec();
    loop {
        let mut head = [0u8; 8];
        if read_full(r, &mut head)? < head.len() {
            return Err(PngStreamError::Truncated);
        }
        let len = u32::from_be_bytes([head[0], head[1], head[2], head[3]]) as usize;
        let start = out.len() + head.len();
        if start + len + 4 > MAX_PNG_BYTES {
            return Err(PngStreamError::TooLarge);
        }
        out.extend_from_slice(&head);
        out.resize(start + len + 4, 0);
        if read_full(r, &mut out[start..])? < len + 4 {
            return Err(PngStreamError::Truncated);
        }
        if &head[4..] == b"IEND" {
            return Ok(Some(out));
        }
    }
}

/// Fills `buf` unless the stream ends first; returns the bytes read.
fn read_full(r: &mut impl Read, buf: &mut [u8]) -> Result<usize, PngStreamError> {
    let mut n = 0;
    while n < buf.len() {
        match r.read(&mut buf[n..]) {
            Ok(0) => break,
            Ok(k) => n += k,
            Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
            Err(e) => return Err(PngStreamError::Read(e)),
        }
    }
    Ok(n)
}

/// The first executable file called `name` in the directories of `path_var` (a `PATH` value).
pub fn find_executable(name: &str, path_var: Option<&OsStr>) -> Option<PathBuf> {
    std::env::split_paths(path_var?)
        .map(|dir| dir.join(name))
        .find(|p| is_executable(p))
}

#[cfg(unix)]
fn is_executable(p: &Path) -> bool {
    use std::os::unix::fs::PermissionsExt;
    p.metadata()
        .is_ok_and(|m| m.is_file() && m.permissions().mode() & 0o111 != 0)
}

#[cfg(not(unix))]
fn is_executable(p: &Path) -> bool {
    p.is_file() || p.with_extension("exe").is_file()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn png(w: u32, h: u32) -> Vec<u8> {
        let mut out = Vec::new();
        tre_io::encode_png(&image::DynamicImage::new_rgb8(w, h), &mut out).unwrap();
        out
    }

    #[test]
    fn a_png_stream_splits_into_its_images() {
        let (a, b) = (png(3, 2), png(5, 4));
        let stream = [a.clone(), b.clone()].concat();
        let mut r = &stream[..];
        assert_eq!(read_png(&mut r).unwrap(), Some(a));
        assert_eq!(read_png(&mut r).unwrap(), Some(b.clone()));
        assert_eq!(read_png(&mut r).unwrap(), None);
        let mut cut = &b[..b.len() - 3];
        assert!(read_png(&mut cut)
            .unwrap_err()
            .to_string()
            .contains("ended inside"));
        let mut junk = &b"GIF89a not a png"[..];
        assert!(matches!(read_png(&mut junk), Err(PngStreamError::NotPng)));
    }

    #[test]
    fn the_latest_slot_keeps_only_the_newest_frame() {
        let (a, b) = (png(1, 1), png(2, 2));
        let slot = LatestSlot::default();
        slot.fill(&[a, b.clone()].concat()[..]);
        assert_eq!(slot.take().unwrap(), Some(b));
        assert_eq!(slot.take().unwrap(), None);
    }

    #[test]
    fn a_folder_pairs_frames_with_depth_by_stem() {
        let dir = tempfile::tempdir().unwrap();
        let (rgb, depth) = (dir.path().join("rgb"), dir.path().join("depth"));
        std::fs::create_dir_all(&rgb).unwrap();
        std::fs::create_dir_all(&depth).unwrap();
        for name in ["b.png", "a.jpg", "c.PNG", "notes.txt"] {
            std::fs::write(rgb.join(name), name).unwrap();
        }
        for name in ["a.png", "b.npy", "c.png"] {
            std::fs::write(depth.join(name), format!("depth of {name}")).unwrap();
        }
        let frames: Vec<SourceFrame> = FolderSource::open(&rgb, Some(&depth), None)
            .unwrap()
            .collect::<Result<_, _>>()
            .unwrap();
        let names: Vec<&str> = frames.iter().map(|f| f.name.as_str()).collect();
        assert_eq!(names, ["a", "b", "c"]);
        assert_eq!(frames[1].image, b"b.png");
        assert_eq!(frames[1].depth.as_deref(), Some(&b"depth of b.npy"[..]));
        std::fs::remove_file(depth.join("c.png")).unwrap();
        let e = FolderSource::open(&rgb, Some(&depth), None).unwrap_err();
        assert!(e.to_string().contains("no depth for frame c"), "{e}");
        let empty = dir.path().join("empty");
        std::fs::create_dir_all(&empty).unwrap();
        assert!(FolderSource::open(&empty, None, None).is_err());
    }

    #[test]
    fn ffmpeg_is_looked_up_on_the_path_and_its_absence_is_explained() {
        let dir = tempfile::tempdir().unwrap();
        assert_eq!(
            find_executable("ffmpeg", Some(dir.path().as_os_str())),
            None
        );
        assert_eq!(find_executable("ffmpeg", None), None);
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            let exe = dir.path().join("ffmpeg");
            std::fs::write(&exe, "#!/bin/sh\n").unwrap();
            assert_eq!(
                find_executable("ffmpeg", Some(dir.path().as_os_str())),
                None
            );
            std::fs::set_permissions(&exe, std::fs::Permissions::from_mode(0o755)).unwrap();
            assert_eq!(
                find_executable("ffmpeg", Some(dir.path().as_os_str())),
                Some(exe)
            );
        }
        #[cfg(unix)]
        {
            use std::os::unix::process::ExitStatusExt;
            let e = failed(
                "run.mp4",
                FfmpegProblem::Exited {
                    status: ExitStatus::from_raw(1 << 8),
                    stderr_tail: "run.mp4: Invalid data found\n".into(),
                },
            );
            assert_eq!(
                e.to_string(),
                "ffmpeg on run.mp4: exit status: 1: run.mp4: Invalid data found"
            );
        }
        let msg = ClientError::FfmpegMissing {
            input: "run.mp4".into(),
        }
        .to_string();
        assert!(msg.contains("ffmpeg") && msg.contains("--frames"), "{msg}");
    }
}
