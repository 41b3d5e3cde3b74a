//! The inference workers: named threads, each with its own [`Pipeline`] (ONNX Runtime sessions
//! need `&mut`), fed by one bounded queue. Async handlers only enqueue and await a oneshot
//! reply; decoding, the pipeline and encoding all run here, never on the async runtime.

use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex, OnceLock, PoisonError};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use crossbeam_channel::{bounded, Receiver, Sender, TrySendError};
use tokio::sync::oneshot;

use super::error::{ApiError, LimitError, RequestError, ServiceError};
use super::metrics::Metrics;
use super::request::{
    assumptions, config_for, decode_frame, encode_reply, encode_sensor_maps, DecodeLimits,
    FrameDefaults, FrameReply, FrameRequest,
};
use tre_core::geometry::Grid;
use tre_core::roughness::interval::Calibration;
use tre_model::{BatchObserver, Batching, Models, SessionConfig, SharedModels};
use tre_pipeline::{FrameInput, Mode, Pipeline, PipelineConfig};

/// How the pool is built.
#[derive(Debug, Clone)]
pub(crate) struct PoolConfig {
    /// Worker threads.
    pub workers: usize,
    /// Jobs that may wait for a worker; more are refused at once.
    pub queue: usize,
    /// Folder with `manifest.json` and the models.
    pub models: PathBuf,
    /// ONNX Runtime settings of every worker's sessions.
    pub session: SessionConfig,
    /// Dynamic batching: when on, one session per model shared by every worker.
    pub batching: Batching,
    /// Decoding limits.
    pub limits: DecodeLimits,
    /// What frames get for the settings they do not choose.
    pub defaults: FrameDefaults,
    /// The models' calibrated intervals (`uncertainty.json`), read once for every worker.
    pub calibration: Option<Calibration>,
}

/// A frame's answer, or why there is none.
pub(crate) type JobResult = Result<FrameReply, ApiError>;

/// One frame to run, with where to send the answer.
struct Job {
    request: FrameRequest,
    reply: oneshot::Sender<(JobResult, Duration)>,
    enqueued: Instant,
}

impl Job {
    /// Whether its client has left (timed out or disconnected): nobody waits for the answer.
    fn abandoned(&self) -> bool {
        self.reply.is_closed()
    }
}

/// Why a worker could not start serving.
#[derive(Debug, thiserror::Error)]
pub enum WorkerError {
    /// The models could not be loaded.
    #[error("worker {worker}: loading models from {}: {reason}", models.display())]
    Load {
        /// The worker's number.
        worker: usize,
        /// The models folder.
        models: PathBuf,
        /// What loading said.
        reason: tre_model::ModelError,
    },
    /// The models failed their warm-up run.
    #[error("worker {worker}: warming up the models: {reason}")]
    WarmUp {
        /// The worker's number.
        worker: usize,
        /// What the pipeline said.
        reason: tre_pipeline::PipelineError,
    },
}

/// Start-up state of the workers.
#[derive(Debug, Default)]
struct Startup {
    warm: AtomicUsize,
    failed: Mutex<Option<Arc<WorkerError>>>,
    stopped: AtomicBool,
}

impl Startup {
    /// Records why a worker could not start (the first reason stays).
    fn fail(&self, why: WorkerError) {
        let mut failed = self.failed.lock().unwrap_or_else(PoisonError::into_inner);
        failed.get_or_insert_with(|| Arc::new(why));
    }
}

/// The models every worker shares when batching is on, loaded by the first worker to need them
/// (`None` once loading failed: that worker reported why).
type Shared = Arc<OnceLock<Option<SharedModels>>>;

/// The worker pool.
#[derive(Debug)]
pub(crate) struct Workers {
    tx: Mutex<Option<Sender<Job>>>,
    rx_probe: Receiver<Job>,
    capacity: usize,
    count: usize,
    startup: Arc<Startup>,
    handles: Mutex<Vec<JoinHandle<()>>>,
}

impl Workers {
    /// Starts `cfg.workers` named threads; each loads the models and warms them up, then
    /// serves jobs. Use [`Workers::ready`] and [`Workers::failure`] to follow the start.
    pub(crate) fn start(cfg: &PoolConfig, metrics: Arc<Metrics>) -> std::io::Result<Self> {
        let (tx, rx) = bounded::<Job>(cfg.queue);
        let startup = Arc::new(Startup::default());
        let shared: Shared = Arc::new(OnceLock::new());
        let mut handles = Vec::with_capacity(cfg.workers);
        for i in 0..cfg.workers.max(1) {
            let (rx, startup, metrics, cfg, shared) = (
                rx.clone(),
                startup.clone(),
                metrics.clone(),
                cfg.clone(),
                shared.clone(),
            );
            let handle = std::thread::Builder::new()
                .name(format!("tre-worker-{i}"))
                .spawn(move || worker(i, &cfg, &rx, &startup, &metrics, &shared))?;
            handles.push(handle);
        }
        Ok(Self {
            tx: Mutex::new(Some(tx)),
            rx_probe: rx,
            capacity: cfg.queue,
            count: cfg.workers.max(1),
            startup,
            handles: Mutex::new(handles),
        })
    }

    /// Whether every worker has loaded and warmed up its models.
    pub(crate) fn ready(&self) -> bool {
        self.startup.warm.load(Ordering::Acquire) == self.count
            && !self.startup.stopped.load(Ordering::Acquire)
    }

    /// Why a worker could not start, if one could not.
    pub(crate) fn failure(&self) -> Option<Arc<WorkerError>> {
        self.startup
            .failed
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .clone()
    }

    /// Jobs waiting for a worker.
    pub(crate) fn queue_depth(&self) -> usize {
        self.rx_probe.len()
    }

    /// Capacity of the queue.
    pub(crate) fn capacity(&self) -> usize {
        self.capacity
    }

    /// Worker threads.
    pub(crate) fn count(&self) -> usize {
        self.count
    }

    /// Enqueues a frame. Refused at once when the queue is full (`overloaded`), before the
    /// workers are warm or after shutdown began (`not_ready`). The receiver yields the answer
    /// and the time the job waited in the queue; dropping it cancels a job not yet started.
    pub(crate) fn submit(
        &self,
        request: FrameRequest,
    ) -> Result<oneshot::Receiver<(JobResult, Duration)>, RequestError> {
        if !self.ready() {
            return Err(ServiceError::Loading.into());
        }
        let guard = self.tx.lock().unwrap_or_else(PoisonError::into_inner);
        let Some(tx) = guard.as_ref() else {
            return Err(ServiceError::ShuttingDown.into());
        };
        let (reply, rx) = oneshot::channel();
        let job = Job {
            request,
            reply,
            enqueued: Instant::now(),
        };
        let sent = match tx.try_send(job) {
            Err(TrySendError::Full(job)) => {
                self.drop_abandoned(tx);
                tx.try_send(job)
            }
            sent => sent,
        };
        match sent {
            Ok(()) => Ok(rx),
            Err(TrySendError::Full(_)) => Err(LimitError::QueueFull {
                workers: self.count,
                queued: self.capacity,
            }
            .into()),
            Err(TrySendError::Disconnected(_)) => Err(ServiceError::WorkersStopped.into()),
        }
    }

    /// Takes the jobs whose clients have left (timed out or disconnected) out of a full queue,
    /// so that their slots go to new frames instead of waiting for a worker to skip them. The
    /// others go back in their order; `tx` is the sender under the lock [`Workers::submit`]
    /// holds, so no new job can come between them.
    fn drop_abandoned(&self, tx: &Sender<Job>) {
        let mut kept = Vec::with_capacity(self.capacity);
        let mut abandoned = 0usize;
        for _ in 0..self.capacity {
            let Ok(job) = self.rx_probe.try_recv() else {
                break;
            };
            if job.abandoned() {
                abandoned += 1;
            } else {
                kept.push(job);
            }
        }
        for job in kept {
            // Fewer jobs go back than came out, and nothing else can send meanwhile, so this
            // cannot fail; if it did, the client hears why instead of waiting.
            if let Err(e) = tx.try_send(job) {
                let job = e.into_inner();
                let error = ServiceError::RequeueFailed.into();
                let _ = job.reply.send((Err(error), job.enqueued.elapsed()));
            }
        }
        if abandoned > 0 {
            tracing::debug!(abandoned, "freed the queue slots of clients that left");
        }
    }

    /// Stops taking jobs, lets the workers finish the queued ones, and joins them.
    pub(crate) fn shutdown(&self) {
        self.startup.stopped.store(true, Ordering::Release);
        drop(
            self.tx
                .lock()
                .unwrap_or_else(PoisonError::into_inner)
                .take(),
        );
        let handles =
            std::mem::take(&mut *self.handles.lock().unwrap_or_else(PoisonError::into_inner));
        for h in handles {
            if h.join().is_err() {
                tracing::error!("a worker thread panicked");
            }
        }
    }
}

/// The worker's models: sessions of its own, or, with batching on, handles on the shared ones
/// (loaded by the first worker here; the others wait for it). `None` when loading failed (the
/// reason is recorded in `startup`).
fn models_of(
    i: usize,
    cfg: &PoolConfig,
    startup: &Startup,
    metrics: &Arc<Metrics>,
    shared: &Shared,
) -> Option<Models> {
    let failed = |reason| {
        startup.fail(WorkerError::Load {
            worker: i,
            models: cfg.models.clone(),
            reason,
        });
    };
    if !cfg.batching.is_on() {
        return Models::load(&cfg.models, &cfg.session).map_err(failed).ok();
    }
    let loaded = shared.get_or_init(|| {
        let metrics = Arc::clone(metrics);
        let observer: BatchObserver = Arc::new(move |_model: &str, n: usize| metrics.batch(n));
        // One run of each model at a time, so each may use every worker's threads.
        let session = SessionConfig {
            intra_threads: cfg.session.intra_threads * cfg.workers.max(1),
            ..cfg.session
        };
        let loaded = SharedModels::load(&cfg.models, &session, cfg.batching, Some(observer));
        loaded.map_err(failed).ok()
    });
    let models = Models::shared(loaded.as_ref()?);
    models.map_err(failed).ok()
}

/// One worker: load, warm up, then serve until the queue closes.
fn worker(
    i: usize,
    cfg: &PoolConfig,
    rx: &Receiver<Job>,
    startup: &Startup,
    metrics: &Arc<Metrics>,
    shared: &Shared,
) {
    let started = Instant::now();
    let Some(models) = models_of(i, cfg, startup, metrics, shared) else {
        return;
    };
    let mut pipeline = Pipeline::new(Some(models)).with_calibration(cfg.calibration.clone());
    if let Err(reason) = warm_up(&mut pipeline) {
        startup.fail(WorkerError::WarmUp { worker: i, reason });
        return;
    }
    startup.warm.fetch_add(1, Ordering::AcqRel);
    tracing::info!(
        worker = i,
        took_ms = started.elapsed().as_millis() as u64,
        "worker ready"
    );
    while let Ok(job) = rx.recv() {
        let queued = job.enqueued.elapsed();
        if job.abandoned() {
            tracing::debug!(worker = i, "client gone before its frame started; skipped");
            continue;
        }
        if !cfg.batching.is_on() {
            // Each frame's nets run alone; with batching, the models' threads report.
            metrics.batch(1);
        }
        let mut result = guarded(i, || run_job(&mut pipeline, &job.request, cfg));
        if let Ok(reply) = &mut result {
            metrics.frame(&reply.timings, queued);
            // The wait for a worker, before the job's own stages (`Server-Timing`'s first).
            reply.timings.add_first("queue", queued);
        }
        // A closed receiver means the client left; nothing to do with the answer.
        let _ = job.reply.send((result, queued));
    }
}

/// Runs one job on worker `i`, turning a panic (a bug) into an `internal` error for that frame
/// alone: the worker lives on for the next frames instead of leaving the queue unserved while
/// the server still reports ready. Every buffer the pipeline reuses is sized afresh per frame.
fn guarded(i: usize, job: impl FnOnce() -> JobResult) -> JobResult {
    std::panic::catch_unwind(std::panic::AssertUnwindSafe(job)).unwrap_or_else(|panic| {
        let what = panic
            .downcast_ref::<&str>()
            .map(|s| s.to_string())
            .or_else(|| panic.downcast_ref::<String>().cloned())
            .unwrap_or_else(|| "no message".to_string());
        tracing::error!(worker = i, panic = %what, "a frame hit a bug; the worker goes on");
        Err(ServiceError::Panic { panic: what }.into())
    })
}

/// Decodes, runs and encodes one frame. Its timings are the pipeline's stages between
/// `decode` and `encode` (the answer's map and the extra maps, which are computed on request
/// while they are encoded).
fn run_job(pipeline: &mut Pipeline, req: &FrameRequest, pool: &PoolConfig) -> JobResult {
    let started = Instant::now();
    let frame = decode_frame(req, pool.limits)?;
    let decoded = started.elapsed();
    let cfg = config_for(&frame, &req.options, pool.limits.max_pixels, pool.defaults);
    let out = pipeline.run(&frame, &cfg)?;
    if let Some(job) = &req.map {
        fuse_into_map(req, &frame, &out, job);
    }
    let started = Instant::now();
    let table = pipeline.interval_table_for(&cfg);
    let facts = (cfg.mode, assumptions(req, &frame, cfg.mode));
    let reply = encode_reply(&out, &req.options, facts).and_then(|mut reply| {
        encode_sensor_maps(&out, &frame, (cfg.mode, table), req, &mut reply)?;
        if let Some(bad) = &out.implausible {
            let scale = req
                .camera
                .as_ref()
                .and_then(|c| c.depth_scale)
                .unwrap_or(1000.0);
            let words = bad.message(scale);
            tracing::warn!(warning = %words, "implausible depth");
            reply.warnings.push(words);
        }
        Ok(reply)
    });
    let encoded = started.elapsed();
    pipeline.recycle(out);
    let large = frame
        .size()
        .is_some_and(|(w, h)| w.saturating_mul(h) > LARGE_FRAME_PIXELS);
    drop(frame);
    if large {
        pipeline.release_buffers();
        give_back_freed_memory();
    }
    let mut reply = reply?;
    reply.timings.add_first("decode", decoded);
    reply.timings.add("encode", encoded);
    Ok(reply)
}

/// Fuses an answered frame into its stream's map, with the request's noise model (checked
/// present when the Hello asked for the map).
fn fuse_into_map(
    req: &FrameRequest,
    frame: &FrameInput,
    out: &tre_pipeline::FrameOutput,
    job: &crate::map::MapJob,
) {
    let Some(sensor) = req.noise_model() else {
        return;
    };
    let mut map = job.map.lock().unwrap_or_else(PoisonError::into_inner);
    map.fuse(frame, out, job, &sensor);
}

/// Frames of more pixels than this (1280×1024) give their memory back once answered: the
/// pipeline drops the buffers it keeps from frame to frame, and the allocator returns what is
/// free to the system. Smaller frames, the usual sensor sizes, keep them warm.
const LARGE_FRAME_PIXELS: usize = 1280 * 1024;

/// Returns the heap's free pages to the system (glibc's `malloc_trim(0)`, which releases free
/// memory inside every arena, not only at its top; a few milliseconds after a large frame).
/// Elsewhere a no-op.
#[allow(unsafe_code)] // One FFI call with no pointer arguments; glibc's malloc_trim is thread-safe.
fn give_back_freed_memory() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: malloc_trim takes a size and touches only the allocator's own state, under its
    // locks.
    unsafe {
        libc::malloc_trim(0);
    }
}

/// Runs every mode once on a synthetic 256×192 frame, so that ONNX Runtime has allocated and
/// tuned everything before the first request.
fn warm_up(pipeline: &mut Pipeline) -> Result<(), tre_pipeline::PipelineError> {
    let (w, h) = (256u32, 192u32);
    let rgb = image::RgbImage::from_fn(w, h, |x, y| {
        image::Rgb([(x % 256) as u8, (y % 256) as u8, 128])
    });
    let depth = Grid::from_fn(w as usize, h as usize, |_, y| 1.0 + y as f64 / 100.0);
    let frame = FrameInput {
        rgb: Some(rgb),
        depth_m: Some(depth),
        ..FrameInput::default()
    };
    for mode in [Mode::Rgb, Mode::Rgbd, Mode::Geometric] {
        let out = pipeline.run(&frame, &PipelineConfig::for_mode(mode))?;
        pipeline.recycle(out);
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::error::ImageError;
    use tre_proto::ErrorCode;

    #[test]
    fn a_panicking_job_is_an_internal_error_and_the_next_one_runs() {
        let e = guarded(0, || panic!("index 7 out of range")).unwrap_err();
        assert_eq!(e.code, ErrorCode::Internal);
        assert!(e.message.contains("index 7 out of range"), "{e}");
        let e = guarded(0, || panic!("{}", String::from("formatted"))).unwrap_err();
        assert!(e.message.contains("formatted"), "{e}");
        let ok = guarded(0, || Err(ImageError::NoInput.into()));
        assert_eq!(ok.unwrap_err().code, ErrorCode::BadRequest);
    }
}
