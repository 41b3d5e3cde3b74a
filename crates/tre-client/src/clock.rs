//! One moment on both clocks: the monotonic one for durations, the wall clock for the frames'
//! timestamps and logs.

use std::time::{Instant, SystemTime, UNIX_EPOCH};

/// One moment on both clocks: the monotonic one for durations, the wall clock for logs.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Stamp {
    /// Monotonic.
    pub at: Instant,
    /// Wall clock, microseconds since the Unix epoch.
    pub unix_us: i64,
}

impl Stamp {
    /// Now.
    pub(crate) fn now() -> Self {
        Self {
            at: Instant::now(),
            unix_us: unix_us(SystemTime::now()),
        }
    }
}

/// Microseconds since the Unix epoch.
pub fn unix_us(t: SystemTime) -> i64 {
    t.duration_since(UNIX_EPOCH)
        .map_or(0, |d| i64::try_from(d.as_micros()).unwrap_or(i64::MAX))
}
