//! The receiving side of a recording: counts the session's events, hands maps and CSV rows to
//! the writer thread, and gives the progress line once a second.

use std::future::Future;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, PoisonError};
use std::time::{Duration, SystemTime};

use tokio::sync::mpsc;

use super::send::{Sent, SentLog};
use super::stats::Stats;
use super::writer::Job;
use super::{Notice, RecordError};
use crate::{unix_us, ClientError, Event, Events, FrameResult};

/// The receiving side of a recording.
pub(super) struct Sink<'n, N> {
    /// Name and send time of the frames awaiting their answer.
    pub log: SentLog,
    /// Frames sent so far.
    pub sent: Arc<AtomicU64>,
    stats: Stats,
    out: PathBuf,
    jobs: mpsc::Sender<Job>,
    notify: &'n mut N,
    /// Error codes already warned about: each is logged once, then only counted.
    warned: std::collections::BTreeSet<String>,
    /// The mode, stand-ins and gravity source last told, so a change is told once.
    answering: Option<(String, Vec<String>, String)>,
}

impl<'n, N: FnMut(Notice)> Sink<'n, N> {
    /// A sink writing into `out` through `jobs`, telling `notify`.
    pub(super) fn new(out: &Path, jobs: mpsc::Sender<Job>, notify: &'n mut N) -> Self {
        Self {
            log: SentLog::default(),
            sent: Arc::new(AtomicU64::new(0)),
            stats: Stats::new(),
            out: out.to_owned(),
            jobs,
            notify,
            warned: std::collections::BTreeSet::new(),
            answering: None,
        }
    }

    /// Logs a server error the first time its code comes; later ones are counted only.
    fn warn_once(&mut self, sequence: Option<u64>, code: &str, message: &str) {
        if self.warned.insert(code.to_owned()) {
            tracing::warn!(
                ?sequence,
                %code,
                "{message} (further `{code}` errors are counted, not repeated)"
            );
        }
    }

    /// Tells the mode, the stand-ins and the gravity source of a result when they differ from
    /// the last ones told.
    fn tell_answering(&mut self, r: &FrameResult) {
        let source = r.gravity.split(';').next().unwrap_or_default().to_owned();
        let now = (r.mode.clone(), r.assumed.clone(), source);
        if self.answering.as_ref() != Some(&now) {
            (self.notify)(Notice::Answering {
                mode: r.mode.clone(),
                assumed: r.assumed.clone(),
                gravity: r.gravity.clone(),
            });
            self.answering = Some(now);
        }
    }

    /// Handles events until the session ends; `stop` aborts the sending (the frames in flight
    /// still get their answers).
    pub(super) async fn drain(
        &mut self,
        events: &mut Events,
        sending: &tokio::task::JoinHandle<Result<(), ClientError>>,
        stop: impl Future<Output = ()>,
    ) -> Result<(), RecordError> {
        let mut tick = tokio::time::interval(Duration::from_secs(1));
        tick.tick().await;
        tokio::pin!(stop);
        let mut stopping = false;
        loop {
            tokio::select! {
                ev = events.recv() => match ev {
                    Some(ev) => self.on_event(ev).await?,
                    None => return Ok(()),
                },
                _ = tick.tick() => {
                    let live = self.stats.progress(self.sent.load(Ordering::Relaxed), true);
                    (self.notify)(Notice::Progress(live));
                }
                () = &mut stop, if !stopping => {
                    stopping = true;
                    sending.abort();
                    (self.notify)(Notice::Stopping);
                }
            }
        }
    }

    /// Ends the sink (the writer thread finishes once its last job is done); returns the
    /// counts and the frames sent.
    pub(super) fn close(self) -> (Stats, Arc<AtomicU64>) {
        (self.stats, self.sent)
    }

    async fn on_event(&mut self, ev: Event) -> Result<(), RecordError> {
        let Some(job) = self.job_for(ev) else {
            return Ok(());
        };
        self.jobs
            .send(job)
            .await
            .map_err(|_| RecordError::Writer("stopped"))
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
                self.warn_once(Some(sequence), code.as_str(), &message);
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
        let sent = self.take_entry(sequence);
        let send_us = sent.at.map(unix_us);
        let line = csv_row(sequence, &sent.name, send_us, received_us, &rest);
        Some(Job::Row {
            line,
            input: sent.input.map(|i| (i, send_us.unwrap_or(received_us))),
        })
    }

    /// A result's map and row, with the send and receive times its latency runs between.
    fn result_job(&mut self, r: Box<FrameResult>) -> Job {
        self.tell_answering(&r);
        let Sent { name, input, .. } = self.take_entry(r.sequence);
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
        // Metres as float32 go to `.npy`; the PNG encodings stay PNG.
        let ext = r.format.extension();
        let path = self.out.join(format!("{}_{name}.{ext}", r.sequence));
        Job::Map {
            path,
            result: r,
            line,
            input,
        }
    }

    /// Events that settle no frame: told (or logged).
    fn report(&mut self, ev: Event) {
        match ev {
            Event::Error { code, message, .. } => {
                self.stats.errors += 1;
                self.warn_once(None, code.as_str(), &message);
            }
            Event::Disconnected { reason } => (self.notify)(Notice::Disconnected { reason }),
            Event::Reconnected {
                attempts, downtime, ..
            } => (self.notify)(Notice::Reconnected { attempts, downtime }),
            Event::GaveUp { reason } => {
                (self.notify)(Notice::GaveUp {
                    reason: reason.clone(),
                });
                self.stats.gave_up = Some(reason);
            }
            Event::Map(m) => self.stats.map = Some(m),
            Event::Result(_) | Event::Dropped { .. } | Event::Lost { .. } => {}
        }
    }

    /// Takes a settled frame's log entry: its name, send time and kept bytes.
    fn take_entry(&self, sequence: u64) -> Sent {
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn csv_fields_are_quoted_when_needed() {
        assert_eq!(csv_field("frame_1"), "frame_1");
        assert_eq!(csv_field("a,b"), "\"a,b\"");
        assert_eq!(csv_field("say \"hi\""), "\"say \"\"hi\"\"\"");
    }

    #[test]
    fn csv_rows_leave_a_missing_send_time_empty() {
        assert_eq!(
            csv_row(4, "a,b", None, 17, ",,,lost:timed_out"),
            "4,\"a,b\",,17,,,,lost:timed_out\n"
        );
        assert_eq!(csv_row(5, "f", Some(3), 9, "x"), "5,f,3,9,x\n");
    }
}
