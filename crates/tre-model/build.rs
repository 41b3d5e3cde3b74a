//! Build script: provisions the ONNX Runtime library that `tre` loads at run time.
//!
//! ONNX Runtime is not linked: `ort` loads it with `dlopen` (`load-dynamic`), so this step only
//! makes sure a library is there for development and compiles its path in as
//! `TRE_ORT_DEFAULT_DYLIB`, the last place `tre_model::runtime::locate_dylib` looks. It never
//! fails the build. The library lives in the workspace root's `.ort/`.

use std::env;
use std::path::{Path, PathBuf};
use std::process::Command;

/// ONNX Runtime release matched to the pinned `ort`; keep in step with
/// `tre_model::runtime::ORT_VERSION`.
const ORT_VERSION: &str = "1.31.1";

fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    provision_onnxruntime();
}

/// Compiles in the default library path and fetches the library there when it is missing,
/// unless `ORT_DYLIB_PATH` chooses another one or `TRE_ORT_NO_FETCH` is set (offline builds).
fn provision_onnxruntime() {
    println!("cargo:rerun-if-env-changed=ORT_DYLIB_PATH");
    println!("cargo:rerun-if-env-changed=TRE_ORT_NO_FETCH");
    let root = &workspace_root();
    let library = default_dylib(root);
    println!(
        "cargo:rustc-env=TRE_ORT_DEFAULT_DYLIB={}",
        library.display()
    );
    let chosen = env::var_os("ORT_DYLIB_PATH").is_some_and(|path| !path.is_empty());
    if chosen || env::var_os("TRE_ORT_NO_FETCH").is_some() || !fetchable() {
        return;
    }
    // Cargo reruns this script on every build while the file is missing, so a failed fetch is
    // retried next time; once the file exists, only a change to it reruns the script.
    println!("cargo:rerun-if-changed={}", library.display());
    if library.is_file() {
        return;
    }
    if let Err(why) = fetch_onnxruntime(root) {
        println!("cargo:warning=could not fetch ONNX Runtime {ORT_VERSION}: {why}");
        println!(
            "cargo:warning=fix: run `python3 scripts/fetch_onnxruntime.py`, or \
             `pip install onnxruntime=={ORT_VERSION}` and set ORT_DYLIB_PATH to \
             <site-packages>/onnxruntime/capi/libonnxruntime.so.{ORT_VERSION}"
        );
    }
}

/// `<root>/.ort/onnxruntime-VERSION/libonnxruntime.so.VERSION`, where the fetch script puts it.
fn default_dylib(root: &Path) -> PathBuf {
    root.join(".ort")
        .join(format!("onnxruntime-{ORT_VERSION}"))
        .join(format!("libonnxruntime.so.{ORT_VERSION}"))
}

/// Whether the wheel pip picks (one for the build machine) suits the target: Linux, not cross.
fn fetchable() -> bool {
    let linux = env::var("CARGO_CFG_TARGET_OS").is_ok_and(|os| os == "linux");
    linux && env::var("TARGET").ok() == env::var("HOST").ok()
}

/// Runs `scripts/fetch_onnxruntime.py`; an error says why it did not succeed.
fn fetch_onnxruntime(root: &Path) -> Result<(), String> {
    let script = root.join("scripts").join("fetch_onnxruntime.py");
    let output = Command::new("python3")
        .arg(&script)
        .current_dir(root)
        .output()
        .map_err(|err| format!("cannot run python3: {err}"))?;
    if output.status.success() {
        return Ok(());
    }
    let stderr = String::from_utf8_lossy(&output.stderr);
    let last = stderr
        .lines()
        .rfind(|line| line.contains("error"))
        .unwrap_or("");
    Err(format!(
        "{} exited with {}: {last}",
        script.display(),
        output.status
    ))
}

/// The workspace root: this crate is `crates/tre-model` in it.
fn workspace_root() -> PathBuf {
    let manifest = Path::new(env!("CARGO_MANIFEST_DIR"));
    manifest.join("..").join("..")
}
