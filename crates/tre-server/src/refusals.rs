//! The log of refusals (413, 415, 422, 429, 401, 403, 408, 503, stream closes): each one a
//! line with its request id, code and reason, up to [`LINES_PER_WINDOW`] lines per
//! [`WINDOW`]; beyond that they are counted, and one summary line per window says how many were
//! left out, by code. A flood of 80,000 refusals thus writes a few dozen lines, not 80,000.

use std::collections::BTreeMap;
use std::sync::Mutex;
use std::time::{Duration, Instant};

/// Length of a rate-limiting window.
pub(crate) const WINDOW: Duration = Duration::from_secs(10);
/// Refusal lines written per window; the rest are summarised.
pub(crate) const LINES_PER_WINDOW: u32 = 20;
/// Longest reason written, characters.
const MAX_REASON_CHARS: usize = 300;

/// Rate-limited refusal log, shared by the HTTP handlers, the accept loop and the streams.
#[derive(Debug)]
pub(crate) struct RefusalLog {
    state: Mutex<Window>,
}

#[derive(Debug)]
struct Window {
    started: Instant,
    written: u32,
    left_out: BTreeMap<&'static str, u64>,
}

impl Default for RefusalLog {
    fn default() -> Self {
        Self {
            state: Mutex::new(Window {
                started: Instant::now(),
                written: 0,
                left_out: BTreeMap::new(),
            }),
        }
    }
}

impl RefusalLog {
    /// Records one refusal: `what` (route or `connection`/`stream`), its request id, its code
    /// (`too_large`, `ws_1009`, ...) and the reason. Returns whether a line was written.
    pub(crate) fn refused(
        &self,
        what: &str,
        request_id: &str,
        code: &'static str,
        reason: &str,
    ) -> bool {
        let now = Instant::now();
        let write = {
            let Ok(mut w) = self.state.lock() else {
                return false;
            };
            if now.duration_since(w.started) >= WINDOW {
                w.summarise(now);
            }
            if w.written < LINES_PER_WINDOW {
                w.written += 1;
                true
            } else {
                *w.left_out.entry(code).or_default() += 1;
                false
            }
        };
        if write {
            let reason = cap(reason, MAX_REASON_CHARS);
            tracing::info!(what, request_id, code, reason = %reason, "refused");
        }
        write
    }

    /// Writes the summary of a window that has ended, if anything was left out of it; called
    /// every [`WINDOW`] by the server, so a flood that stops is still summarised.
    pub(crate) fn flush(&self) {
        if let Ok(mut w) = self.state.lock() {
            if w.started.elapsed() >= WINDOW {
                w.summarise(Instant::now());
            }
        }
    }
}

impl Window {
    fn summarise(&mut self, now: Instant) {
        let total: u64 = self.left_out.values().sum();
        if total > 0 {
            let by_code = self
                .left_out
                .iter()
                .map(|(code, n)| format!("{code}={n}"))
                .collect::<Vec<_>>()
                .join(" ");
            tracing::warn!(
                left_out = total,
                window_s = now.duration_since(self.started).as_secs(),
                by_code = %by_code,
                "refusals beyond {LINES_PER_WINDOW} per {} s not logged one by one",
                WINDOW.as_secs()
            );
        }
        self.started = now;
        self.written = 0;
        self.left_out.clear();
    }
}

/// `text` cut to at most `max` characters, with `…` where it was cut.
pub(crate) fn cap(text: &str, max: usize) -> std::borrow::Cow<'_, str> {
    match text.char_indices().nth(max) {
        None => text.into(),
        Some((at, _)) => format!("{}…", &text[..at]).into(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_flood_writes_a_bounded_number_of_lines() {
        let log = RefusalLog::default();
        let written = (0..80_000)
            .filter(|i| log.refused("roughness", &i.to_string(), "too_many_requests", "full"))
            .count();
        assert_eq!(written, LINES_PER_WINDOW as usize);
        let left_out: u64 = log.state.lock().unwrap().left_out.values().sum();
        assert_eq!(left_out, 80_000 - u64::from(LINES_PER_WINDOW));
    }

    #[test]
    fn cap_cuts_on_a_character_boundary() {
        assert_eq!(cap("abc", 5), "abc");
        assert_eq!(cap("ééééé", 2), "éé…");
    }
}
