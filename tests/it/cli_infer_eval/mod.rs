//! `tre infer` and `tre eval` end to end through the binary: outputs on a real frame in every
//! mode, clear errors for bad input, the models found from outside the checkout,
//! `eval --tables --json` on a tiny synthetic dataset and `eval --real` on a real frame.
#![allow(clippy::unwrap_used)] // Test helpers fail loudly by design.

use std::path::{Path, PathBuf};

use crate::common::{real, shared_data};
use std::process::{Command, Output};

mod eval;
mod infer;
mod models;
mod record;

fn tre(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_tre"))
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .env("TRE_ORT_THREADS", "1")
        .args(args)
        .output()
        .expect("runs tre")
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

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

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}
