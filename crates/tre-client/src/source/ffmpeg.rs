//! Video files and V4L2 cameras decoded by an `ffmpeg` process into a stream of PNG images,
//! the newest frame kept in a one-slot buffer.

use std::ffi::OsStr;
use std::io::{self, BufReader, Read};
use std::path::{Path, PathBuf};
use std::process::{Child, ChildStdout, Command, Stdio};
use std::sync::{Arc, Condvar, Mutex, PoisonError};
use std::thread::JoinHandle;

use super::{source_err, stem, FfmpegProblem, PngStreamError, SourceFrame, SourceProblem};
use crate::ClientError;

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
pub(super) fn failed(input: &str, reason: FfmpegProblem) -> ClientError {
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
pub(super) struct LatestSlot {
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
    pub(super) fn fill(&self, mut r: impl Read) {
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
    pub(super) fn take(&self) -> Result<Option<Vec<u8>>, PngStreamError> {
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
pub(super) const MAX_PNG_BYTES: usize = 256 << 20;

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
