//! `tre client`: streams frames from a folder, a video file or a camera to `tre serve` over the
//! WebSocket, writes each result's roughness map and a per-frame CSV, and prints a live summary.

use std::collections::HashMap;
use std::fmt::Write as _;
use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex, PoisonError};
use std::time::{Duration, Instant, SystemTime};

use anyhow::{bail, Context};
use clap::Args;
use hdrhistogram::Histogram;
use image::DynamicImage;
use tokio::sync::mpsc;

use super::options::dsac_hypotheses_arg;
use crate::client::source::{FrameSource, SourceFrame, SourceSpec};
use crate::client::{
    unix_us, Backoff, ClientConfig, ClientError, Event, Events, Format, Frame, FrameResult,
    FrameSender, Rate, Session,
};
use crate::io;
use crate::pipeline::{Mode, NormalsMethod};

/// Stream frames to `tre serve` and write the roughness maps it sends back.
#[derive(Debug, Args)]
pub struct Client {
    /// Server: ws://host:port/v1/stream, ws://host:port, http://host:port or host:port;
    /// wss:// or https:// for TLS (a TLS-terminating proxy in front of the service).
    #[arg(long, env = "TRE_SERVER")]
    pub server: String,
    /// API key of a server started with --api-key (sent as `Authorization: Bearer KEY`).
    #[arg(long, env = "TRE_API_KEY", hide_env_values = true)]
    pub api_key: Option<String>,
    /// PEM file of a private CA to trust beside the public roots, for a wss:// or https://
    /// server whose certificate it issued.
    #[arg(long, env = "TRE_CA_CERT")]
    pub ca_cert: Option<PathBuf>,
    /// Folder of frames (PNG or JPEG), sent in file-name order as they are on disk.
    #[arg(long, env = "TRE_CLIENT_FRAMES", required_unless_present_any = ["video", "device"], conflicts_with_all = ["video", "device"])]
    pub frames: Option<PathBuf>,
    /// Folder of registered depth frames: frame FRAMES/NAME.EXT takes DEPTH/NAME.png (16-bit,
    /// the camera's depth_scale units per metre, default 1000) or DEPTH/NAME.npy (metres).
    /// Every frame must have one.
    #[arg(long, env = "TRE_CLIENT_DEPTH")]
    pub depth: Option<PathBuf>,
    /// Video file, decoded by ffmpeg (which must be on PATH).
    #[arg(long, env = "TRE_CLIENT_VIDEO", conflicts_with = "device")]
    pub video: Option<PathBuf>,
    /// V4L2 camera device (e.g. /dev/video0), read by ffmpeg (which must be on PATH); frames
    /// the stream has no time for are skipped.
    #[arg(long, env = "TRE_CLIENT_DEVICE")]
    pub device: Option<PathBuf>,
    /// Camera JSON: fx, fy, cx, cy in pixels of the frames; optional depth_scale, pitch_deg
    /// (default 60) and height_m (default 1). Without it: the server's defaults.
    #[arg(long, env = "TRE_CAMERA")]
    pub camera: Option<PathBuf>,
    /// Frames per second to send (the server drops frames it has no time for and says so).
    #[arg(long, env = "TRE_CLIENT_RATE", conflicts_with = "as_fast_as_results")]
    pub rate: Option<f64>,
    /// Send each frame once the previous one has its answer (the default without --rate).
    #[arg(long, env = "TRE_CLIENT_AS_FAST_AS_RESULTS")]
    pub as_fast_as_results: bool,
    /// Input mode; default: rgbd for frames with depth, else rgb.
    #[arg(long, env = "TRE_MODE", value_enum)]
    pub mode: Option<Mode>,
    /// Encoding of the maps asked of the server.
    #[arg(long, env = "TRE_CLIENT_FORMAT", value_enum, default_value = "png16")]
    pub format: Format,
    /// Seed of the DSAC sampler: the same seed gives the same output.
    #[arg(long, env = "TRE_SEED", default_value_t = 0)]
    pub seed: u64,
    /// Initial normals: dsac (the paper's method) or ls (faster); default: the server's.
    #[arg(long, env = "TRE_CLIENT_NORMALS", value_enum)]
    pub normals: Option<NormalsMethod>,
    /// DSAC hypotheses per pixel, 1 to 64 (fewer are faster); default: the server's.
    #[arg(long, env = "TRE_CLIENT_DSAC_HYPOTHESES",
          value_parser = dsac_hypotheses_arg())]
    pub dsac_hypotheses: Option<u32>,
    /// Also ask for traversability, written as SEQ_NAME_traversable.png (255 = traversable).
    #[arg(long, env = "TRE_CLIENT_TRAVERSABLE")]
    pub traversable: bool,
    /// Also ask for the three-state map and the uncertainty (the camera must name a sensor
    /// noise model, docs/sensor-noise.md), written as SEQ_NAME_traversal.png (0 unknown,
    /// 1 traversable, 2 hazard) and SEQ_NAME_uncertainty.png (16-bit, 0.1 mm per unit).
    #[arg(long, env = "TRE_CLIENT_TRAVERSAL")]
    pub traversal: bool,
    /// Traversability: the largest roughness, centimetres (default 5).
    #[arg(long, env = "TRE_CLIENT_MAX_ROUGHNESS_CM")]
    pub max_roughness_cm: Option<f64>,
    /// Traversability: the steepest slope, degrees (default 20).
    #[arg(long, env = "TRE_CLIENT_MAX_SLOPE_DEG")]
    pub max_slope_deg: Option<f64>,
    /// Stop after this many frames.
    #[arg(long, env = "TRE_CLIENT_LIMIT")]
    pub limit: Option<u64>,
    /// Start over at the end of the folder or video (until --limit or Ctrl-C).
    #[arg(long = "loop", env = "TRE_CLIENT_LOOP")]
    pub repeat: bool,
    /// Output folder: SEQ_NAME.png per result (NAME: the frame's file stem) and frames.csv.
    #[arg(long, short, env = "TRE_CLIENT_OUT")]
    pub out: PathBuf,
    /// A frame without an answer after this long is counted lost, milliseconds.
    #[arg(long, env = "TRE_CLIENT_FRAME_TIMEOUT_MS", default_value_t = 30_000)]
    pub frame_timeout_ms: u64,
    /// First wait between connection attempts, milliseconds (doubling, see --reconnect-factor).
    #[arg(long, env = "TRE_CLIENT_RECONNECT_INITIAL_MS", default_value_t = 200)]
    pub reconnect_initial_ms: u64,
    /// Longest wait between connection attempts, milliseconds.
    #[arg(long, env = "TRE_CLIENT_RECONNECT_MAX_MS", default_value_t = 5_000)]
    pub reconnect_max_ms: u64,
    /// Growth of the wait per failed attempt.
    #[arg(long, env = "TRE_CLIENT_RECONNECT_FACTOR", default_value_t = 2.0)]
    pub reconnect_factor: f64,
    /// Failed connection attempts in a row before giving up (0: never).
    #[arg(long, env = "TRE_CLIENT_RECONNECT_ATTEMPTS", default_value_t = 20)]
    pub reconnect_attempts: u32,
}

/// A checked `tre client` run.
#[derive(Debug, Clone, PartialEq)]
pub struct ClientRun {
    /// The session's settings.
    pub session: ClientConfig,
    /// Where frames come from.
    pub source: SourceSpec,
    /// Output folder.
    pub out: PathBuf,
    /// Frames to send at most.
    pub limit: Option<u64>,
    /// Start the source over at its end.
    pub repeat: bool,
}

impl Default for ClientRun {
    fn default() -> Self {
        Self {
            session: ClientConfig::default(),
            source: SourceSpec::Folder {
                frames: PathBuf::from("frames"),
                depth: None,
            },
            out: PathBuf::from("out"),
            limit: None,
            repeat: false,
        }
    }
}

impl Client {
    /// The checked run configuration.
    pub fn config(&self) -> anyhow::Result<ClientRun> {
        let source = match (&self.frames, &self.video, &self.device) {
            (Some(frames), None, None) => SourceSpec::Folder {
                frames: frames.clone(),
                depth: self.depth.clone(),
            },
            (None, Some(video), None) => SourceSpec::Video(video.clone()),
            (None, None, Some(device)) => SourceSpec::Device(device.clone()),
            _ => bail!("give exactly one of --frames, --video and --device"),
        };
        if self.depth.is_some() && self.frames.is_none() {
            bail!("--depth goes with --frames (video and camera input have no depth)");
        }
        let camera = self.camera.as_deref().map(io::read_camera).transpose()?;
        let session = ClientConfig {
            server: self.server.clone(),
            api_key: self.api_key.clone(),
            ca_cert: self.ca_cert.clone(),
            camera: camera.map(|(c, _)| c),
            mode: self.mode,
            format: self.format,
            seed: self.seed,
            normals: self.normals,
            dsac_hypotheses: self.dsac_hypotheses,
            want_traversable: self.traversable,
            want_traversal: self.traversal,
            max_roughness_cm: self.max_roughness_cm,
            max_slope_deg: self.max_slope_deg,
            rate: self.rate.map_or(Rate::AsFastAsResults, Rate::Fixed),
            reconnect: Backoff {
                initial: Duration::from_millis(self.reconnect_initial_ms),
                max: Duration::from_millis(self.reconnect_max_ms),
                factor: self.reconnect_factor,
                give_up_after: (self.reconnect_attempts > 0).then_some(self.reconnect_attempts),
            },
            frame_timeout: Duration::from_millis(self.frame_timeout_ms),
            ..ClientConfig::default()
        };
        session.validate()?;
        if self.limit == Some(0) {
            bail!("--limit must be at least 1");
        }
        Ok(ClientRun {
            session,
            source,
            out: self.out.clone(),
            limit: self.limit,
            repeat: self.repeat,
        })
    }

    /// Streams the frames, writes the maps and the CSV, prints the summaries.
    pub fn run(self) -> anyhow::Result<()> {
        run(self.config()?)
    }
}

/// Runs `cfg` on its own async runtime; an error if no result came back.
pub fn run(cfg: ClientRun) -> anyhow::Result<()> {
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .thread_name("tre-client")
        .enable_all()
        .build()
        .context("starting the async runtime")?;
    runtime.block_on(stream(cfg))
}

/// Name and send time of each frame sent, by sequence number (entries leave as answers come).
type SentLog = Arc<Mutex<HashMap<u64, (String, Option<SystemTime>)>>>;

async fn stream(cfg: ClientRun) -> anyhow::Result<()> {
    std::fs::create_dir_all(&cfg.out).with_context(|| format!("creating {}", cfg.out.display()))?;
    let source = FrameSource::open(&cfg.source)?;
    let session = Session::connect(cfg.session.clone())
        .await
        .with_context(|| format!("connecting to {}", cfg.session.server))?;
    eprintln!(
        "connected to {} (models: {})",
        cfg.session.server,
        session.server().models.join(", ")
    );
    let (sender, mut events) = session.split();
    let (frames_tx, frames_rx) = mpsc::channel(2);
    let (spec, limit, repeat) = (cfg.source.clone(), cfg.limit, cfg.repeat);
    let reader = std::thread::Builder::new()
        .name("tre-frames".into())
        .spawn(move || read_frames(source, &spec, limit, repeat, &frames_tx))
        .context("starting the frame reader")?;
    let (jobs, writer) = start_writer(&cfg.out)?;
    let mut sink = Sink::new(&cfg.out, jobs);
    let sending = tokio::spawn(send_frames(
        sender,
        frames_rx,
        sink.log.clone(),
        sink.sent.clone(),
    ));
    sink.drain(&mut events, &sending).await?;
    let sent_outcome = sending.await;
    let Sink {
        mut stats,
        sent,
        jobs,
        ..
    } = sink;
    drop(jobs);
    let written = writer
        .join()
        .map_err(|_| anyhow::anyhow!("the writer thread panicked"))?;
    let _ = reader.join();
    eprintln!("{}", stats.line(sent.load(Ordering::Relaxed), false));
    eprintln!("maps and frames.csv in {}", cfg.out.display());
    written?;
    finish(stats, sent_outcome, &cfg)
}

/// The run's verdict: an error if the source failed, the session gave up or nothing came back.
fn finish(
    stats: Stats,
    sent: Result<Result<(), ClientError>, tokio::task::JoinError>,
    cfg: &ClientRun,
) -> anyhow::Result<()> {
    match sent {
        Ok(Ok(()) | Err(ClientError::Closed)) => {}
        Ok(Err(e)) => return Err(e.into()),
        Err(e) if e.is_cancelled() => {}
        Err(e) => bail!("the sending task failed: {e}"),
    }
    if let Some(reason) = stats.gave_up {
        bail!("the stream ended early: {reason}");
    }
    if stats.results == 0 {
        bail!(
            "no results came back from {} ({} dropped, {} errors, {} lost)",
            cfg.session.server,
            stats.dropped,
            stats.errors,
            stats.lost
        );
    }
    Ok(())
}

/// The frame reader thread: the source (reopened with `repeat`) into `tx`, up to `limit`.
fn read_frames(
    first: FrameSource,
    spec: &SourceSpec,
    limit: Option<u64>,
    repeat: bool,
    tx: &mpsc::Sender<Result<SourceFrame, ClientError>>,
) {
    let mut source = first;
    let mut n = 0u64;
    loop {
        let mut any = false;
        for item in source.by_ref() {
            if limit.is_some_and(|l| n >= l) {
                return;
            }
            let failed = item.is_err();
            if tx.blocking_send(item).is_err() || failed {
                return;
            }
            any = true;
            n += 1;
        }
        if !(repeat && any) || matches!(spec, SourceSpec::Device(_)) {
            return;
        }
        source = match FrameSource::open(spec) {
            Ok(s) => s,
            Err(e) => {
                let _ = tx.blocking_send(Err(e));
                return;
            }
        };
    }
}

/// The sending task: each frame through the session, its name logged under its sequence.
async fn send_frames(
    mut sender: FrameSender,
    mut frames: mpsc::Receiver<Result<SourceFrame, ClientError>>,
    log: SentLog,
    sent: Arc<AtomicU64>,
) -> Result<(), ClientError> {
    while let Some(item) = frames.recv().await {
        let f = item?;
        let sequence = sender.next_sequence();
        let name = f.name.clone();
        log_entry(&log, sequence, Some((name, None)));
        let frame = Frame {
            image: f.image,
            depth: f.depth,
            ..Frame::default()
        };
        match sender.send(frame).await {
            Ok(_) => {
                sent.fetch_add(1, Ordering::Relaxed);
                if let Some(e) = log
                    .lock()
                    .unwrap_or_else(PoisonError::into_inner)
                    .get_mut(&sequence)
                {
                    e.1 = Some(SystemTime::now());
                }
            }
            Err(e @ ClientError::FrameTooLarge { .. }) => {
                log_entry(&log, sequence, None);
                tracing::warn!(frame = %f.name, "skipped: {e}");
            }
            Err(e) => return Err(e),
        }
    }
    Ok(())
}

/// Sets (`Some`) or removes (`None`) a frame's log entry.
fn log_entry(log: &SentLog, sequence: u64, entry: Option<(String, Option<SystemTime>)>) {
    let mut log = log.lock().unwrap_or_else(PoisonError::into_inner);
    match entry {
        Some(e) => log.insert(sequence, e),
        None => log.remove(&sequence),
    };
}

/// The receiving side of a run: counts the events, hands maps and CSV rows to the writer and
/// prints the live line.
struct Sink {
    log: SentLog,
    sent: Arc<AtomicU64>,
    stats: Stats,
    out: PathBuf,
    jobs: mpsc::Sender<Job>,
}

impl Sink {
    fn new(out: &Path, jobs: mpsc::Sender<Job>) -> Self {
        Self {
            log: SentLog::default(),
            sent: Arc::new(AtomicU64::new(0)),
            stats: Stats::new(),
            out: out.to_owned(),
            jobs,
        }
    }

    /// Handles events until the session ends; Ctrl-C stops the sending (the frames in flight
    /// still get their answers).
    async fn drain(
        &mut self,
        events: &mut Events,
        sending: &tokio::task::JoinHandle<Result<(), ClientError>>,
    ) -> anyhow::Result<()> {
        let mut tick = tokio::time::interval(Duration::from_secs(1));
        tick.tick().await;
        let ctrl_c = tokio::signal::ctrl_c();
        tokio::pin!(ctrl_c);
        let mut stopping = false;
        loop {
            tokio::select! {
                ev = events.recv() => match ev {
                    Some(ev) => self.on_event(ev).await?,
                    None => return Ok(()),
                },
                _ = tick.tick() => {
                    eprintln!("{}", self.stats.line(self.sent.load(Ordering::Relaxed), true));
                }
                _ = &mut ctrl_c, if !stopping => {
                    stopping = true;
                    sending.abort();
                    eprintln!("stopping: waiting for the frames in flight");
                }
            }
        }
    }

    async fn on_event(&mut self, ev: Event) -> anyhow::Result<()> {
        let Some(job) = self.job_for(ev) else {
            return Ok(());
        };
        self.jobs
            .send(job)
            .await
            .map_err(|_| anyhow::anyhow!("the writer thread stopped"))
    }

    /// Counts the event; the map and CSV row to write, if it settles a frame.
    fn job_for(&mut self, ev: Event) -> Option<Job> {
        let (sequence, rest) = match ev {
            Event::Result(r) => return Some(self.result_job(r)),
            Event::Dropped {
                sequence,
                dropped_total,
            } => {
                self.stats.dropped += 1;
                (sequence, format!(",,{dropped_total},dropped"))
            }
            Event::Error {
                sequence: Some(sequence),
                code,
                message,
            } => {
                self.stats.errors += 1;
                tracing::warn!(sequence, %code, "{message}");
                (sequence, format!(",,,error:{code}"))
            }
            Event::Lost { sequence, reason } => {
                self.stats.lost += 1;
                (sequence, format!(",,,lost:{}", reason.as_str()))
            }
            other => {
                self.report(other);
                return None;
            }
        };
        let received_us = unix_us(SystemTime::now());
        let (name, sent) = self.take_entry(sequence);
        let row = csv_row(sequence, &name, sent.map(unix_us), received_us, &rest);
        Some(Job::Row(row))
    }

    /// A result's map and row, with the send and receive times its latency runs between.
    fn result_job(&mut self, r: Box<FrameResult>) -> Job {
        let (name, _) = self.take_entry(r.sequence);
        self.stats.result(&r);
        let rest = format!(
            "{:.3},{:.3},{},ok",
            r.latency.as_secs_f64() * 1e3,
            r.server_latency.as_secs_f64() * 1e3,
            r.dropped_total
        );
        let line = csv_row(
            r.sequence,
            &name,
            Some(r.sent_unix_us),
            r.received_unix_us,
            &rest,
        );
        let path = self.out.join(format!("{}_{name}.png", r.sequence));
        Job::Map {
            path,
            result: r,
            line,
        }
    }

    /// Events that settle no frame: said on stderr (or logged).
    fn report(&mut self, ev: Event) {
        match ev {
            Event::Error { code, message, .. } => {
                self.stats.errors += 1;
                tracing::warn!(%code, "{message}");
            }
            Event::Disconnected { reason } => eprintln!("disconnected: {reason}; reconnecting"),
            Event::Reconnected {
                attempts, downtime, ..
            } => eprintln!(
                "reconnected after {:.1} s ({attempts} attempts)",
                downtime.as_secs_f64()
            ),
            Event::GaveUp { reason } => {
                eprintln!("gave up: {reason}");
                self.stats.gave_up = Some(reason);
            }
            Event::Result(_) | Event::Dropped { .. } | Event::Lost { .. } => {}
        }
    }

    /// Takes a settled frame's log entry: its name and send time.
    fn take_entry(&self, sequence: u64) -> (String, Option<SystemTime>) {
        self.log
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .remove(&sequence)
            .unwrap_or_default()
    }
}

/// One `frames.csv` row; `rest`: latency_ms,server_latency_ms,dropped,status.
fn csv_row(sequence: u64, name: &str, send_us: Option<i64>, receive_us: i64, rest: &str) -> String {
    let send = send_us.map_or_else(String::new, |t| t.to_string());
    format!(
        "{sequence},{},{send},{receive_us},{rest}\n",
        csv_field(name)
    )
}

/// A CSV field, quoted when it needs to be.
fn csv_field(s: &str) -> String {
    if s.contains([',', '"', '\n', '\r']) {
        format!("\"{}\"", s.replace('"', "\"\""))
    } else {
        s.to_owned()
    }
}

/// Work for the writer thread.
#[derive(Debug)]
enum Job {
    /// A result's map(s) and its CSV row.
    Map {
        path: PathBuf,
        result: Box<FrameResult>,
        line: String,
    },
    /// A CSV row.
    Row(String),
}

/// Starts the writer thread: maps into `out`, rows into `out/frames.csv`.
fn start_writer(
    out: &Path,
) -> anyhow::Result<(
    mpsc::Sender<Job>,
    std::thread::JoinHandle<anyhow::Result<()>>,
)> {
    let csv_path = out.join("frames.csv");
    let mut csv = std::io::BufWriter::new(
        std::fs::File::create(&csv_path)
            .with_context(|| format!("creating {}", csv_path.display()))?,
    );
    csv.write_all(
        b"sequence,name,send_unix_us,receive_unix_us,latency_ms,server_latency_ms,dropped,status\n",
    )?;
    let (tx, mut rx) = mpsc::channel::<Job>(16);
    let handle = std::thread::Builder::new()
        .name("tre-writer".into())
        .spawn(move || -> anyhow::Result<()> {
            while let Some(job) = rx.blocking_recv() {
                let line = match job {
                    Job::Map { path, result, line } => {
                        write_map(&path, &result)?;
                        line
                    }
                    Job::Row(line) => line,
                };
                csv.write_all(line.as_bytes())?;
                csv.flush()
                    .with_context(|| format!("writing {}", csv_path.display()))?;
            }
            Ok(())
        })
        .context("starting the writer thread")?;
    Ok((tx, handle))
}

/// Writes a result's map as `tre infer` does (a PNG16 as received; F32 encoded the same way;
/// colour as received) and its traversability mask beside it.
fn write_map(path: &Path, r: &FrameResult) -> anyhow::Result<()> {
    match (r.format, r.roughness_m()) {
        (Format::F32, Some(m)) => {
            io::save(path, &DynamicImage::ImageLumaA16(io::roughness_png16(m)))?
        }
        _ => std::fs::write(path, &r.encoded)
            .with_context(|| format!("writing {}", path.display()))?,
    }
    if let Some(t) = &r.traversable {
        let stem = path
            .file_stem()
            .map_or_else(String::new, |s| s.to_string_lossy().into_owned());
        io::write_mask_png(&path.with_file_name(format!("{stem}_traversable.png")), t)?;
    }
    write_sensor_maps(path, r)?;
    Ok(())
}

/// The three-state and uncertainty maps of `r`, if it has them, beside `path`.
fn write_sensor_maps(path: &Path, r: &FrameResult) -> anyhow::Result<()> {
    let stem = path
        .file_stem()
        .map_or_else(String::new, |s| s.to_string_lossy().into_owned());
    if let Some(t) = &r.traversal {
        let grey = DynamicImage::ImageLuma8(io::traversal_gray8(t));
        io::save(&path.with_file_name(format!("{stem}_traversal.png")), &grey)?;
    }
    if let Some(u) = &r.uncertainty_m {
        let png = DynamicImage::ImageLumaA16(io::roughness_png16(u));
        io::save(
            &path.with_file_name(format!("{stem}_uncertainty.png")),
            &png,
        )?;
    }
    Ok(())
}

/// Counts and latencies so far.
struct Stats {
    start: Instant,
    results: u64,
    dropped: u64,
    errors: u64,
    lost: u64,
    latency_us: Histogram<u64>,
    last: (Instant, u64),
    gave_up: Option<String>,
}

impl Stats {
    fn new() -> Self {
        let now = Instant::now();
        Self {
            start: now,
            results: 0,
            dropped: 0,
            errors: 0,
            lost: 0,
            latency_us: Histogram::new_with_bounds(1, 3_600_000_000, 3)
                .expect("bounds and 3 significant figures are valid; this is a bug"),
            last: (now, 0),
            gave_up: None,
        }
    }

    fn result(&mut self, r: &FrameResult) {
        self.results += 1;
        let us = u64::try_from(r.latency.as_micros()).unwrap_or(u64::MAX);
        self.latency_us.saturating_record(us.max(1));
    }

    /// The live line (fps over the last interval) or the final one (fps over the run).
    fn line(&mut self, sent: u64, live: bool) -> String {
        let now = Instant::now();
        let (since, count) = if live { self.last } else { (self.start, 0) };
        let secs = now.duration_since(since).as_secs_f64().max(1e-9);
        let fps = (self.results - count) as f64 / secs;
        self.last = (now, self.results);
        let mut s = String::new();
        let _ = write!(
            s,
            "{}[{:6.1} s] sent {sent}, results {}, dropped {}, errors {}, lost {}",
            if live { "" } else { "done " },
            now.duration_since(self.start).as_secs_f64(),
            self.results,
            self.dropped,
            self.errors,
            self.lost
        );
        if self.results > 0 {
            let q = |p| self.latency_us.value_at_quantile(p) as f64 / 1e3;
            let _ = write!(s, ", latency p50 {:.1} ms p99 {:.1} ms", q(0.5), q(0.99));
        }
        let _ = write!(s, ", {fps:.1} fps");
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;

    #[derive(Debug, Parser)]
    struct Cli {
        #[command(flatten)]
        client: Client,
    }

    fn parse(args: &[&str]) -> Result<ClientRun, String> {
        let cli = Cli::try_parse_from(std::iter::once("tre").chain(args.iter().copied()))
            .map_err(|e| e.to_string())?;
        cli.client.config().map_err(|e| format!("{e:#}"))
    }

    #[test]
    fn options_become_a_checked_run() {
        let run = parse(&[
            "--server",
            "http://127.0.0.1:9",
            "--frames",
            "f",
            "--depth",
            "d",
            "--rate",
            "5",
            "--format",
            "f32",
            "--reconnect-attempts",
            "0",
            "--limit",
            "3",
            "--out",
            "o",
        ])
        .unwrap();
        assert_eq!(run.session.rate, Rate::Fixed(5.0));
        assert_eq!(run.session.format, Format::F32);
        assert_eq!(run.session.reconnect.give_up_after, None);
        assert_eq!(
            run.source,
            SourceSpec::Folder {
                frames: "f".into(),
                depth: Some("d".into())
            }
        );
        assert_eq!(run.limit, Some(3));
        let d = parse(&["--server", "h:1", "--video", "v.mp4", "-o", "o"]).unwrap();
        assert_eq!(d.session.rate, Rate::AsFastAsResults);
        assert_eq!(d.session.reconnect.give_up_after, Some(20));
    }

    #[test]
    fn conflicting_or_bad_options_are_refused() {
        for args in [
            &["--server", "h:1", "-o", "o"][..],
            &[
                "--server", "h:1", "--frames", "f", "--video", "v", "-o", "o",
            ],
            &["--server", "h:1", "--video", "v", "--depth", "d", "-o", "o"],
            &[
                "--server",
                "h:1",
                "--frames",
                "f",
                "--rate",
                "2",
                "--as-fast-as-results",
                "-o",
                "o",
            ],
            &[
                "--server", "h:1", "--frames", "f", "--rate", "-2", "-o", "o",
            ],
            &["--server", "ftp://h:1", "--frames", "f", "-o", "o"],
            &[
                "--server", "h:1", "--frames", "f", "--limit", "0", "-o", "o",
            ],
        ] {
            assert!(parse(args).is_err(), "{args:?}");
        }
    }

    #[test]
    fn csv_fields_are_quoted_when_needed() {
        assert_eq!(csv_field("frame_1"), "frame_1");
        assert_eq!(csv_field("a,b"), "\"a,b\"");
        assert_eq!(csv_field("say \"hi\""), "\"say \"\"hi\"\"\"");
    }
}
