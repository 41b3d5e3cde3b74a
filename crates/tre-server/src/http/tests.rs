//! Tests of the body's pace.

use super::*;
use std::time::Duration;

/// Within a window nothing is judged; at its end, too few bytes is a 408 naming the option,
/// enough starts the next window afresh (earlier bytes do not carry over).
#[test]
fn body_pace_judges_each_window() {
    let mut pace = BodyPace::new(1024);
    let t0 = pace.since;
    assert_eq!(pace.deadline(), Some(t0 + BODY_RATE_WINDOW));
    pace.check(10, t0 + Duration::from_secs(1)).unwrap();
    pace.check(6000, t0 + BODY_RATE_WINDOW).unwrap();
    assert_eq!((pace.since, pace.bytes), (t0 + BODY_RATE_WINDOW, 0));
    let e = pace.check(100, t0 + 2 * BODY_RATE_WINDOW).unwrap_err();
    assert_eq!(e.code(), ErrorCode::RequestTimeout);
    assert!(e.to_string().contains("--min-body-rate"), "{e}");
    assert!(e.to_string().contains("20 bytes/s"), "{e}");
    let mut off = BodyPace::new(0);
    assert_eq!(off.deadline(), None);
    off.check(0, t0 + Duration::from_secs(3600)).unwrap();
}
