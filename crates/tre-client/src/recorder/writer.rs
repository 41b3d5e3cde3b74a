//! The writer thread of a recording: each result's maps into the output folder (as `tre infer`
//! writes them) and each frame's row into `frames.csv`, in the order the answers came; with an
//! MCAP file, each frame's inputs and outputs into it too.

use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::thread::JoinHandle;

use image::DynamicImage;
use tokio::sync::mpsc;

use super::send::SentInput;
use super::RecordError;
use crate::FrameResult;
use tre_core::geometry::{Grid, Intrinsics};
use tre_core::kinds::MapFormat;
use tre_io::{self as io, CameraFile};
use tre_record::msgs::{Header, Time};
use tre_record::{Colour, FrameRecord, RecordOptions, Recorder};

/// The header of `frames.csv`.
const CSV_HEADER: &[u8] =
    b"sequence,name,send_unix_us,receive_unix_us,latency_ms,server_latency_ms,dropped,status\n";

/// Work for the writer thread.
#[derive(Debug)]
pub(super) enum Job {
    /// A result's map(s) and its CSV row.
    Map {
        /// Where the roughness map goes (the other maps go beside it).
        path: PathBuf,
        /// The result.
        result: Box<FrameResult>,
        /// Its CSV row.
        line: String,
        /// The frame's bytes, for the MCAP recording.
        input: Option<Box<SentInput>>,
    },
    /// A CSV row (a frame without a result), and the frame's bytes for the MCAP recording with
    /// their stamp (microseconds since the epoch).
    Row {
        /// The row.
        line: String,
        /// The frame's bytes and stamp.
        input: Option<(Box<SentInput>, i64)>,
    },
}

/// The writer thread's outcome.
type Written = Result<(), RecordError>;

/// Starts the writer thread: maps into `out`, rows into `out/frames.csv`, and with `mcap` the
/// frames and answers into that file (`camera`: the session's, for the depth's units and the
/// intrinsics).
pub(super) fn start_writer(
    out: &Path,
    mcap: Option<(&Path, RecordOptions)>,
    camera: Option<&CameraFile>,
) -> Result<(mpsc::Sender<Job>, JoinHandle<Written>), RecordError> {
    let mut mcap = mcap
        .map(|(p, o)| Recorder::create_with(p, o).map(|r| McapOut::new(r, camera)))
        .transpose()?;
    let csv_path = out.join("frames.csv");
    let file = std::fs::File::create(&csv_path).map_err(io_error("creating", &csv_path))?;
    let mut csv = std::io::BufWriter::new(file);
    csv.write_all(CSV_HEADER)
        .map_err(io_error("writing", &csv_path))?;
    let (tx, mut rx) = mpsc::channel::<Job>(16);
    let handle = std::thread::Builder::new()
        .name("tre-writer".into())
        .spawn(move || -> Written {
            while let Some(job) = rx.blocking_recv() {
                let line = match job {
                    Job::Map {
                        path,
                        result,
                        line,
                        input,
                    } => {
                        write_map(&path, &result)?;
                        if let Some(m) = &mut mcap {
                            m.result(&result, input.as_deref())?;
                        }
                        line
                    }
                    Job::Row { line, input } => {
                        if let (Some(m), Some((input, us))) = (&mut mcap, input) {
                            m.input(&input, us)?;
                        }
                        line
                    }
                };
                csv.write_all(line.as_bytes())
                    .and_then(|()| csv.flush())
                    .map_err(io_error("writing", &csv_path))?;
            }
            if let Some(m) = mcap {
                m.recorder.finish()?;
            }
            Ok(())
        })
        .map_err(|source| RecordError::Spawn {
            what: "writer thread",
            source,
        })?;
    Ok((tx, handle))
}

/// The error of `action` (`creating` or `writing`) on `path`.
fn io_error<'p>(
    action: &'static str,
    path: &'p Path,
) -> impl FnOnce(std::io::Error) -> RecordError + 'p {
    move |source| RecordError::Io {
        action,
        path: path.to_owned(),
        source,
    }
}

/// Writes a result's map as `tre infer` does (a PNG16 as received; F32 as a float32 `.npy` in
/// metres, NaN where there is no data; colour as received) and its other maps beside it.
fn write_map(path: &Path, r: &FrameResult) -> Result<(), RecordError> {
    match (r.format, r.roughness_m()) {
        (MapFormat::F32 | MapFormat::Npy, Some(m)) => io::write_npy_f32(path, m)?,
        _ => std::fs::write(path, &r.encoded).map_err(io_error("writing", path))?,
    }
    let stem = path
        .file_stem()
        .map_or_else(String::new, |s| s.to_string_lossy().into_owned());
    let beside = |suffix: &str| path.with_file_name(format!("{stem}_{suffix}.png"));
    if let Some(t) = &r.traversable {
        io::write_mask_png(&beside("traversable"), t)?;
    }
    if let Some(t) = &r.traversal {
        let grey = DynamicImage::ImageLuma8(io::traversal_gray8(t));
        io::save(&beside("traversal"), &grey)?;
    }
    if let Some(u) = &r.uncertainty_m {
        let png = DynamicImage::ImageLumaA16(io::roughness_png16(u));
        io::save(&beside("uncertainty"), &png)?;
    }
    Ok(())
}

/// The MCAP side of the writer: each frame's inputs (colour as sent, depth in metres, the
/// session's intrinsics) and its answer's maps.
struct McapOut {
    recorder: Recorder,
    /// Depth units per metre of 16-bit PNG depth (the camera's, else the server's default).
    units_per_m: f64,
    intrinsics: Option<Intrinsics>,
}

impl McapOut {
    fn new(recorder: Recorder, camera: Option<&CameraFile>) -> Self {
        Self {
            recorder,
            units_per_m: camera
                .and_then(|c| c.depth_scale)
                .unwrap_or(io::DEFAULT_DEPTH_SCALE),
            intrinsics: camera.and_then(|c| c.intrinsics().ok()),
        }
    }

    /// A frame without a result: its inputs alone.
    fn input(&mut self, input: &SentInput, stamp_us: i64) -> Result<(), RecordError> {
        self.frame(Some(input), stamp_us, None)
    }

    /// A frame's inputs (when kept) and its result.
    fn result(&mut self, r: &FrameResult, input: Option<&SentInput>) -> Result<(), RecordError> {
        self.frame(input, r.timestamp_us, Some(r))
    }

    fn frame(
        &mut self,
        input: Option<&SentInput>,
        stamp_us: i64,
        r: Option<&FrameResult>,
    ) -> Result<(), RecordError> {
        let depth = input
            .and_then(|i| i.depth.as_deref())
            .and_then(|d| decode_depth(d, self.units_per_m));
        let size = r
            .map(|r| (r.width, r.height))
            .or_else(|| depth.as_ref().map(Grid::size));
        let record = FrameRecord {
            header: Header {
                stamp: Time::from_nanos(stamp_us.saturating_mul(1000)),
                frame_id: "camera".into(),
            },
            depth_m: depth.as_ref(),
            colour: input
                .filter(|i| !i.image.is_empty())
                .map(|i| Colour::Encoded(&i.image)),
            intrinsics: self.intrinsics.as_ref().zip(size),
            roughness_m: r.and_then(FrameResult::roughness_m),
            uncertainty_m: r.and_then(|r| r.uncertainty_m.as_ref()),
            traversal: r.and_then(|r| r.traversal.as_ref()),
            pose: None,
        };
        self.recorder.frame(&record, tre_record::now_ns())?;
        Ok(())
    }
}

/// Depth in metres from the bytes sent (16-bit PNG at `units_per_m`, or `.npy` metres); `None`
/// when they are neither (the server refuses such a frame, and says why).
fn decode_depth(bytes: &[u8], units_per_m: f64) -> Option<Grid<f64>> {
    if bytes.starts_with(b"\x93NUMPY") {
        let a = io::npy::read_npy(std::io::Cursor::new(bytes)).ok()?;
        return io::npy_depth(a).ok();
    }
    match image::load_from_memory(bytes).ok()? {
        DynamicImage::ImageLuma16(img) => Some(io::depth_from_luma16(img, units_per_m)),
        _ => None,
    }
}
