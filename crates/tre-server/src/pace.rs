//! The pace a stream's messages must keep. A WebSocket message arrives whole or not at all, so a
//! client could send one a byte at a time, answering pings in between, and keep its stream for
//! as long as it liked. The connection counts the bytes it reads ([`ReadBytes`], kept by the
//! accept loop); the stream tells [`MessagePace`] which of them belonged to the messages it got,
//! and what is left over is a message still arriving. Over each [`PACE_WINDOW`] that such a
//! message is on its way from start to end, at least `--min-body-rate` bytes a second of it
//! must come, the HTTP bodies' rule; else the stream is closed (1008) and the refusal logged.

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::Duration;

use tokio::time::Instant;

/// Window over which a message's rate is averaged, stream messages and HTTP bodies alike
/// (`--min-body-rate`); the first one is the grace a client has before its rate counts.
pub(crate) const PACE_WINDOW: Duration = Duration::from_secs(5);

/// Bytes a connection has read so far, counted where the socket is read; a request extension of
/// every request the accept loop serves.
#[derive(Debug, Clone, Default)]
pub(crate) struct ReadBytes(Arc<AtomicU64>);

impl ReadBytes {
    /// Counts `n` more bytes read.
    pub(crate) fn add(&self, n: usize) {
        self.0
            .fetch_add(u64::try_from(n).unwrap_or(u64::MAX), Ordering::Relaxed);
    }

    /// Bytes read so far.
    pub(crate) fn get(&self) -> u64 {
        self.0.load(Ordering::Relaxed)
    }
}

/// Bytes a control frame (ping, pong) takes on the wire from a client: two header bytes, the
/// four-byte mask every client frame carries, and its payload (at most 125 bytes, so no
/// extended length). An unmasked client frame is a protocol error that ends the stream.
pub(crate) fn client_control_frame_bytes(payload: usize) -> u64 {
    u64::try_from(payload).unwrap_or(u64::MAX).saturating_add(6)
}

/// A stream's message pace, judged at the end of each [`PACE_WINDOW`].
#[derive(Debug)]
pub(crate) struct MessagePace {
    read: ReadBytes,
    /// Bytes a second; 0: no pace.
    min_bytes_per_s: u64,
    /// Read bytes accounted for by whole messages: the count when the last data message came,
    /// plus the control frames since.
    accounted: u64,
    /// The count at the start of the window.
    window_start: u64,
    /// When the window started.
    since: Instant,
    /// Control-frame bytes in the window.
    window_control: u64,
    /// Whether a message was on its way at the start of the window.
    pending_at_start: bool,
    /// Whether a data message came in the window.
    message_in_window: bool,
}

/// What a window showed of a message too slow.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct TooSlow {
    /// Its bytes over the window.
    pub bytes: u64,
    /// The window's length, seconds.
    pub secs: f64,
    /// The least rate, bytes a second.
    pub min_bytes_per_s: u64,
}

impl MessagePace {
    /// The pace of a stream whose connection reads through `read`, from `now`;
    /// `min_bytes_per_s` 0: none.
    pub(crate) fn new(read: ReadBytes, min_bytes_per_s: u64, now: Instant) -> Self {
        let count = read.get();
        Self {
            read,
            min_bytes_per_s,
            accounted: count,
            window_start: count,
            since: now,
            window_control: 0,
            pending_at_start: false,
            message_in_window: false,
        }
    }

    /// Whether a pace is kept at all.
    pub(crate) fn enabled(&self) -> bool {
        self.min_bytes_per_s > 0
    }

    /// A data message (binary or text, or a close) came whole: every byte read so far is
    /// accounted for (bytes read ahead of the next message count as that message's).
    pub(crate) fn data_message(&mut self) {
        self.accounted = self.read.get();
        self.message_in_window = true;
    }

    /// A control frame with `payload` bytes came whole.
    pub(crate) fn control_frame(&mut self, payload: usize) {
        let bytes = client_control_frame_bytes(payload);
        self.accounted = self.accounted.saturating_add(bytes);
        self.window_control = self.window_control.saturating_add(bytes);
    }

    /// Bytes read that no whole message accounts for: a message on its way.
    pub(crate) fn pending(&self) -> u64 {
        self.read.get().saturating_sub(self.accounted)
    }

    /// The end of a window at `now`: `Err` when a message was on its way the whole window (from
    /// before it began, with none completed in it, still pending at its end) and fewer than the
    /// minimum of bytes came; then the next window starts.
    pub(crate) fn end_window(&mut self, now: Instant) -> Result<(), TooSlow> {
        let total = self.read.get();
        let pending = self.pending() > 0;
        let slow = TooSlow {
            bytes: total
                .saturating_sub(self.window_start)
                .saturating_sub(self.window_control),
            secs: (now - self.since).as_secs_f64(),
            min_bytes_per_s: self.min_bytes_per_s,
        };
        let judged = self.enabled() && self.pending_at_start && pending && !self.message_in_window;
        self.window_start = total;
        self.since = now;
        self.window_control = 0;
        self.pending_at_start = pending;
        self.message_in_window = false;
        if judged && (slow.bytes as f64) < self.min_bytes_per_s as f64 * slow.secs {
            return Err(slow);
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Window ends 5 s apart.
    fn clock() -> impl FnMut() -> Instant {
        let start = Instant::now();
        let mut n = 0;
        move || {
            n += 1;
            start + PACE_WINDOW * n
        }
    }

    #[test]
    fn a_message_trickling_the_whole_window_is_too_slow() {
        let read = ReadBytes::default();
        let mut tick = clock();
        let mut pace = MessagePace::new(read.clone(), 1024, Instant::now());
        read.add(3);
        assert!(pace.end_window(tick()).is_ok(), "the first window is grace");
        read.add(5);
        let slow = pace.end_window(tick()).expect_err("5 bytes in a window");
        assert_eq!(slow.bytes, 5);
        assert_eq!(slow.min_bytes_per_s, 1024);
    }

    #[test]
    fn idle_streams_and_pings_are_not_messages() {
        let read = ReadBytes::default();
        let mut tick = clock();
        let mut pace = MessagePace::new(read.clone(), 1024, Instant::now());
        for _ in 0..4 {
            read.add(client_control_frame_bytes(4) as usize);
            pace.control_frame(4);
            assert_eq!(pace.pending(), 0);
            assert!(pace.end_window(tick()).is_ok());
        }
    }

    #[test]
    fn pongs_between_the_pieces_of_a_slow_message_do_not_excuse_it() {
        let read = ReadBytes::default();
        let mut tick = clock();
        let mut pace = MessagePace::new(read.clone(), 1024, Instant::now());
        read.add(10);
        assert!(pace.end_window(tick()).is_ok());
        read.add(6);
        pace.control_frame(0);
        read.add(10);
        let slow = pace
            .end_window(tick())
            .expect_err("10 bytes of data in a window");
        assert_eq!(slow.bytes, 10, "the pong is not counted as the message's");
    }

    #[test]
    fn fast_messages_and_completed_ones_pass() {
        let read = ReadBytes::default();
        let mut tick = clock();
        let mut pace = MessagePace::new(read.clone(), 1, Instant::now());
        read.add(100);
        assert!(pace.end_window(tick()).is_ok());
        // 100 bytes in a window far shorter than 100 s: at least 1 byte a second.
        read.add(100);
        assert!(pace.end_window(tick()).is_ok());
        // A message completed within the window is not judged, however slow the window.
        let mut strict = MessagePace::new(read.clone(), u64::MAX / 2, Instant::now());
        read.add(1);
        assert!(strict.end_window(tick()).is_ok());
        read.add(1);
        strict.data_message();
        read.add(1);
        assert!(strict.end_window(tick()).is_ok());
        // Without a pace, nothing is judged.
        let mut none = MessagePace::new(read.clone(), 0, Instant::now());
        read.add(1);
        assert!(none.end_window(tick()).is_ok());
        assert!(none.end_window(tick()).is_ok());
        assert!(!none.enabled());
    }
}
