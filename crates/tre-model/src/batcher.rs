//! Dynamic batching: one session per model on a thread of its own, shared by every worker.
//!
//! A worker's call ([`SharedNet::run_with`]) sends its inputs (batch 1, or any N) to the model's
//! thread and waits. The thread takes the first request, then gathers more of the same height
//! and width until the batch holds [`Batching::max_batch`] frames or [`Batching::max_delay`]
//! has passed since the first arrived, runs them as one batch and hands each caller its slice.
//! Requests of another size wait for the next batch, in arrival order. Both bounds hold for
//! every request: no batch exceeds `max_batch`, and no request waits longer than `max_delay`
//! for company (only for the batches ahead of it). A request whose inputs do not fit the model
//! is refused on its own, never failing the batch it would have joined.

use std::collections::VecDeque;
use std::path::Path;
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use crossbeam_channel::{bounded, Receiver, Sender};
use ndarray::{concatenate, s, Array4, ArrayView4, Axis};

use super::manifest::Manifest;
use super::session::{ModelSession, SessionConfig};
use super::ModelError;

/// The largest `max_batch` accepted.
pub const MAX_BATCH: usize = 64;
/// The longest `max_delay` accepted.
pub const MAX_BATCH_DELAY: Duration = Duration::from_secs(1);

/// The bounds of dynamic batching.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Batching {
    /// Frames in one batch at most, 1 to [`MAX_BATCH`] (1: no batching).
    pub max_batch: usize,
    /// How long the first request of a batch waits for more, at most [`MAX_BATCH_DELAY`].
    pub max_delay: Duration,
}

impl Default for Batching {
    fn default() -> Self {
        Self {
            max_batch: 1,
            max_delay: Duration::from_millis(2),
        }
    }
}

/// Settings [`Batching`] refuses.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum BatchingError {
    /// `max_batch` of 0 or above [`MAX_BATCH`].
    #[error("batch size {0}: must be 1 to {MAX_BATCH}")]
    Size(usize),
    /// `max_delay` above [`MAX_BATCH_DELAY`].
    #[error("batch delay {0:?}: must be at most {MAX_BATCH_DELAY:?}")]
    Delay(Duration),
}

impl Batching {
    /// Checks the bounds.
    ///
    /// # Errors
    ///
    /// [`BatchingError`] for a size of 0 or above [`MAX_BATCH`], or a delay above
    /// [`MAX_BATCH_DELAY`].
    pub fn check(&self) -> Result<(), BatchingError> {
        if self.max_batch == 0 || self.max_batch > MAX_BATCH {
            return Err(BatchingError::Size(self.max_batch));
        }
        if self.max_delay > MAX_BATCH_DELAY {
            return Err(BatchingError::Delay(self.max_delay));
        }
        Ok(())
    }

    /// Whether requests are batched at all.
    pub fn is_on(&self) -> bool {
        self.max_batch > 1
    }
}

/// Told the model's name and the size of every batch a model's thread runs.
pub type BatchObserver = Arc<dyn Fn(&str, usize) + Send + Sync>;

/// What a caller gets back: its slice of the output, the batch's time inside ONNX Runtime, and
/// the batch's size.
type Answer = Result<(Array4<f32>, Duration, usize), ModelError>;

/// One caller's inputs and where to answer.
struct Request {
    inputs: Vec<Array4<f32>>,
    reply: Sender<Answer>,
}

impl Request {
    fn n(&self) -> usize {
        self.inputs.first().map_or(0, |x| x.dim().0)
    }

    fn size(&self) -> (usize, usize) {
        self.inputs
            .first()
            .map_or((0, 0), |x| (x.dim().2, x.dim().3))
    }
}

/// A worker's handle on one model's batching thread.
#[derive(Debug, Clone)]
pub struct SharedNet {
    name: String,
    tx: Sender<Request>,
    /// ONNX Runtime time of the batches this handle's requests ran in.
    busy: Duration,
}

impl SharedNet {
    /// The model's name in the manifest.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// ONNX Runtime time of the batches this handle's requests were part of.
    pub fn onnx_runtime_time(&self) -> Duration {
        self.busy
    }

    /// Runs the model on `inputs` within a batch and hands this caller's slice of the first
    /// output to `consume`.
    ///
    /// # Errors
    ///
    /// Those of [`ModelSession::run`] (for this request's inputs or for the batch's run), and
    /// [`ModelError::BatcherStopped`] when the model's thread is gone.
    pub fn run_with<R>(
        &mut self,
        inputs: &[ArrayView4<'_, f32>],
        consume: impl FnOnce(ArrayView4<'_, f32>) -> R,
    ) -> Result<R, ModelError> {
        let (reply, answer) = bounded(1);
        let request = Request {
            inputs: inputs.iter().map(|x| x.to_owned()).collect(),
            reply,
        };
        let stopped = || ModelError::BatcherStopped {
            model: self.name.clone(),
        };
        self.tx.send(request).map_err(|_| stopped())?;
        let (y, busy, _) = answer.recv().map_err(|_| stopped())??;
        self.busy += busy;
        Ok(consume(y.view()))
    }
}

/// One batching thread per model; dropping it (and every [`SharedNet`] handle) ends them.
pub struct SharedModels {
    manifest: Manifest,
    nets: Vec<SharedNet>,
    threads: Vec<JoinHandle<()>>,
}

impl std::fmt::Debug for SharedModels {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SharedModels")
            .field("nets", &self.nets)
            .finish_non_exhaustive()
    }
}

impl SharedModels {
    /// Loads every model of `dir/manifest.json` once (checked as [`ModelSession::load`] checks)
    /// and starts its batching thread.
    ///
    /// # Errors
    ///
    /// Those of [`ModelSession::load`], and [`ModelError::Batching`] for bounds [`Batching::check`]
    /// refuses.
    pub fn load(
        dir: &Path,
        cfg: &SessionConfig,
        batching: Batching,
        observer: Option<BatchObserver>,
    ) -> Result<Self, ModelError> {
        batching.check().map_err(ModelError::Batching)?;
        let manifest = Manifest::read(dir)?;
        let mut nets = Vec::new();
        let mut threads = Vec::new();
        for (name, entry) in &manifest.models {
            let session = ModelSession::load(dir, name, entry, manifest.stride, cfg)?;
            // Room for a request from each of many workers; a full channel holds its sender.
            let (tx, rx) = bounded::<Request>(4 * MAX_BATCH);
            let observer = observer.clone();
            let thread = std::thread::Builder::new()
                .name(format!("tre-batch-{name}"))
                .spawn(move || serve(session, &rx, batching, observer.as_ref()))
                .map_err(|e| ModelError::BatcherStart {
                    model: name.clone(),
                    reason: e.to_string(),
                })?;
            nets.push(SharedNet {
                name: name.clone(),
                tx,
                busy: Duration::ZERO,
            });
            threads.push(thread);
        }
        Ok(Self {
            manifest,
            nets,
            threads,
        })
    }

    /// The manifest the models were checked against.
    pub fn manifest(&self) -> &Manifest {
        &self.manifest
    }

    /// A handle on model `name`'s thread.
    pub fn net(&self, name: &str) -> Option<SharedNet> {
        self.nets.iter().find(|n| n.name == name).cloned()
    }

    /// Closes the channels and waits for the threads (after every handle is dropped too).
    pub fn join(self) {
        drop(self.nets);
        for t in self.threads {
            let _ = t.join();
        }
    }
}

/// The model's thread: batches until every handle is dropped.
fn serve(
    mut session: ModelSession,
    rx: &Receiver<Request>,
    batching: Batching,
    observer: Option<&BatchObserver>,
) {
    // Requests waiting for a batch of their own size; each was checked when it arrived.
    let mut held: VecDeque<Request> = VecDeque::new();
    // A request that does not fit the model is answered at once and joins nothing.
    let admit = |session: &ModelSession, r: Request| match session.check(&views(&r.inputs)) {
        Ok(()) => Some(r),
        Err(e) => {
            let _ = r.reply.send(Err(e));
            None
        }
    };
    loop {
        let first = match held.pop_front() {
            Some(r) => r,
            None => match rx.recv() {
                Ok(r) => match admit(&session, r) {
                    Some(r) => r,
                    None => continue,
                },
                Err(_) => return,
            },
        };
        let size = first.size();
        let deadline = Instant::now() + batching.max_delay;
        let mut n = first.n();
        let mut batch = vec![first];
        let joins = |r: &Request, n: usize| r.size() == size && n + r.n() <= batching.max_batch;
        // Those held from before, in order, then new arrivals until full or the deadline.
        for r in std::mem::take(&mut held) {
            if joins(&r, n) {
                n += r.n();
                batch.push(r);
            } else {
                held.push_back(r);
            }
        }
        while n < batching.max_batch {
            let Ok(r) = rx.recv_deadline(deadline) else {
                break;
            };
            match admit(&session, r) {
                Some(r) if joins(&r, n) => {
                    n += r.n();
                    batch.push(r);
                }
                Some(r) => held.push_back(r),
                None => {}
            }
        }
        if let Some(observe) = observer {
            observe(session.name(), n);
        }
        // A panic (a bug) fails this batch's callers (their answers are dropped), not the thread.
        let ran = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            run_batch(&mut session, batch);
        }));
        if ran.is_err() {
            tracing::error!(
                model = session.name(),
                "a batch hit a bug; its frames failed"
            );
        }
    }
}

fn views(inputs: &[Array4<f32>]) -> Vec<ArrayView4<'_, f32>> {
    inputs.iter().map(|x| x.view()).collect()
}

/// Runs the requests as one batch (their inputs joined along N) and answers each with its rows.
fn run_batch(session: &mut ModelSession, batch: Vec<Request>) {
    let n = batch.iter().map(Request::n).sum::<usize>();
    let before = session.onnx_runtime_time();
    let result = if batch.len() == 1 {
        session.run(&views(&batch[0].inputs))
    } else {
        let joined: Result<Vec<Array4<f32>>, _> = (0..batch[0].inputs.len())
            .map(|k| {
                let parts: Vec<ArrayView4<'_, f32>> =
                    batch.iter().map(|r| r.inputs[k].view()).collect();
                concatenate(Axis(0), &parts)
            })
            .collect();
        match joined {
            Ok(joined) => session.run(&views(&joined)),
            Err(e) => Err(ModelError::BatchJoin {
                model: session.name().to_owned(),
                reason: e.to_string(),
            }),
        }
    };
    let busy = session.onnx_runtime_time() - before;
    match result {
        Ok(y) => {
            let mut at = 0;
            for r in batch {
                let k = r.n();
                let part = y.slice(s![at..at + k, .., .., ..]).to_owned();
                at += k;
                let _ = r.reply.send(Ok((part, busy, n)));
            }
        }
        Err(e) => {
            // Every member gets the reason; the error itself goes to the first.
            let reason = e.to_string();
            let mut batch = batch.into_iter();
            if let Some(first) = batch.next() {
                let _ = first.reply.send(Err(e));
            }
            for r in batch {
                let _ = r.reply.send(Err(ModelError::BatchFailed {
                    model: session.name().to_owned(),
                    reason: reason.clone(),
                }));
            }
        }
    }
}
