//! Refusals at the service's limits: connections, concurrent requests, streams, the queue, and a
//! body's or a message's size and rate.

use std::time::Duration;

use tre_proto::ErrorCode;

use crate::pace::TooSlow;

/// A request refused at one of the service's limits (`--max-connections`, `--max-concurrent`,
/// `--max-streams`, the queue, `--max-body-bytes`, `--ws-max-message-bytes`, the body's
/// deadline and `--min-body-rate`).
#[derive(Debug, thiserror::Error)]
pub enum LimitError {
    /// `--max-connections` connections are open.
    #[error(
        "the server holds its limit of {max_open} open connections (--max-connections); retry \
         later"
    )]
    TooManyConnections {
        /// The limit.
        max_open: usize,
    },
    /// `--max-concurrent` requests are being handled.
    #[error("more than {max_concurrent} requests at once (--max-concurrent); retry later")]
    TooManyRequests {
        /// The limit.
        max_concurrent: usize,
    },
    /// `--max-streams` streams are open.
    #[error("{max_streams} streams are open, the limit (--max-streams); retry later")]
    StreamsFull {
        /// The limit.
        max_streams: usize,
    },
    /// `--max-connections` streams wait for their first message.
    #[error(
        "{max_connections} streams wait for their first message, the limit \
         (--max-connections); retry later"
    )]
    StreamsWaiting {
        /// The limit.
        max_connections: usize,
    },
    /// The queue is full.
    #[error("all {workers} workers are busy and {queued} frames are queued; retry later")]
    QueueFull {
        /// Worker threads.
        workers: usize,
        /// Frames the queue holds.
        queued: usize,
    },
    /// The body did not arrive within `--body-timeout-ms`.
    #[error(
        "the body did not arrive within {} ms (--body-timeout-ms)",
        timeout.as_millis()
    )]
    BodyTimeout {
        /// The timeout.
        timeout: Duration,
    },
    /// The body fell below `--min-body-rate` over a window.
    #[error(
        "the body arrived at {rate:.0} bytes/s over {secs:.1} s, below the minimum of \
         {min_bytes_per_s} bytes/s (--min-body-rate)"
    )]
    BodyTooSlow {
        /// Its rate over the window, bytes a second.
        rate: f64,
        /// The window, seconds.
        secs: f64,
        /// The least rate, bytes a second.
        min_bytes_per_s: u64,
    },
    /// A body over `--max-body-bytes`.
    #[error(
        "the body is larger than the limit of {} (--max-body-bytes)",
        tre_io::units::format_size(*limit, "B")
    )]
    BodyTooLarge {
        /// The limit, bytes.
        limit: usize,
    },
    /// A message over `--ws-max-message-bytes`.
    #[error("message of {bytes} bytes, more than the limit of {limit}")]
    MessageTooLarge {
        /// Its size.
        bytes: usize,
        /// The limit.
        limit: usize,
    },
    /// A message that arrived below `--min-body-rate` over a window.
    #[error(
        "a message arrived at {:.0} bytes/s over {secs:.1} s, below the minimum of \
         {min_bytes_per_s} bytes/s (--min-body-rate); closed with 1008",
        *bytes as f64 / secs.max(1e-9)
    )]
    MessageTooSlow {
        /// Its bytes over the window.
        bytes: u64,
        /// The window's length, seconds.
        secs: f64,
        /// The least rate, bytes a second.
        min_bytes_per_s: u64,
    },
}

impl LimitError {
    /// The code of this error in the one [`ErrorCode`] table.
    pub fn code(&self) -> ErrorCode {
        match self {
            Self::TooManyRequests { .. }
            | Self::StreamsFull { .. }
            | Self::StreamsWaiting { .. } => ErrorCode::TooManyRequests,
            Self::TooManyConnections { .. } | Self::QueueFull { .. } => ErrorCode::Overloaded,
            Self::BodyTimeout { .. } | Self::BodyTooSlow { .. } | Self::MessageTooSlow { .. } => {
                ErrorCode::RequestTimeout
            }
            Self::BodyTooLarge { .. } | Self::MessageTooLarge { .. } => ErrorCode::TooLarge,
        }
    }
}

impl From<TooSlow> for LimitError {
    fn from(slow: TooSlow) -> Self {
        Self::MessageTooSlow {
            bytes: slow.bytes,
            secs: slow.secs,
            min_bytes_per_s: slow.min_bytes_per_s,
        }
    }
}
