//! The writer thread of a recording: each result's maps into the output folder (as `tre infer`
//! writes them) and each frame's row into `frames.csv`, in the order the answers came.

use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::thread::JoinHandle;

use image::DynamicImage;
use tokio::sync::mpsc;

use super::RecordError;
use crate::FrameResult;
use tre_core::kinds::MapFormat;
use tre_io as io;

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
    },
    /// A CSV row.
    Row(String),
}

/// The writer thread's outcome.
type Written = Result<(), RecordError>;

/// Starts the writer thread: maps into `out`, rows into `out/frames.csv`.
pub(super) fn start_writer(
    out: &Path,
) -> Result<(mpsc::Sender<Job>, JoinHandle<Written>), RecordError> {
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
                    Job::Map { path, result, line } => {
                        write_map(&path, &result)?;
                        line
                    }
                    Job::Row(line) => line,
                };
                csv.write_all(line.as_bytes())
                    .and_then(|()| csv.flush())
                    .map_err(io_error("writing", &csv_path))?;
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
