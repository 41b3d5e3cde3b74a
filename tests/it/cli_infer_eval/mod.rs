//! `tre infer` and `tre eval` end to end through the binary: outputs on a real frame in every
//! mode, clear errors for bad input, the models found from outside the checkout,
//! `eval --tables --json` on a tiny synthetic dataset and `eval --real` on a real frame.
#![allow(clippy::unwrap_used)] // Test helpers fail loudly by design.

use std::path::{Path, PathBuf};

use crate::common::{real, s, shared_data, stderr, tre};
use std::process::{Command, Output};

mod eval;
mod infer;
mod models;
mod record;

/// Runs `tre args`, which must fail with a message holding `needle` (and no panic).
fn fails_saying(args: &[&str], needle: &str) {
    let o = tre(args);
    let err = stderr(&o);
    assert!(!o.status.success(), "{args:?} should fail");
    assert!(!err.contains("panicked"), "{args:?}: {err}");
    assert!(
        err.contains(needle),
        "{args:?}: expected {needle:?} in {err}"
    );
}
