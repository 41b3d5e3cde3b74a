//! ONNX Runtime location and start-up.
//!
//! `ort` is built with `load-dynamic`: the ONNX Runtime shared library is opened at run time,
//! once per process. [`locate_dylib`] finds it and [`environment`] loads it and creates the one
//! [`Environment`] all sessions share:
//!
//! ```no_run
//! # fn main() -> Result<(), Box<dyn std::error::Error>> {
//! let env = tre_model::runtime::environment()?;
//! let session = ort::session::Session::builder(env)?.commit_from_file("models/depth_net.onnx")?;
//! # Ok(())
//! # }
//! ```

use std::env::consts::{DLL_PREFIX, DLL_SUFFIX};
use std::path::{Path, PathBuf};
use std::sync::{Mutex, OnceLock, PoisonError};

use ort::environment::Environment;

/// The ONNX Runtime release `ort` 2.0.0-rc.15 is built against (API version 31).
pub const ORT_VERSION: &str = "1.31.1";

/// Environment variable that names the ONNX Runtime library to load, overriding the search.
pub const DYLIB_ENV: &str = "ORT_DYLIB_PATH";

/// How to provide the library; quoted by [`RuntimeError::DylibNotFound`].
const FIX: &str = concat!(
    "fix: run `python3 scripts/fetch_onnxruntime.py` in the tre source tree, ",
    "or `pip install onnxruntime==1.31.1` and set ORT_DYLIB_PATH to ",
    "<site-packages>/onnxruntime/capi/libonnxruntime.so.1.31.1, ",
    "or copy libonnxruntime.so.1.31.1 next to the executable"
);

/// Errors of ONNX Runtime location and start-up.
#[derive(Debug, thiserror::Error)]
pub enum RuntimeError {
    /// `ORT_DYLIB_PATH` is set but names no file.
    #[error("ORT_DYLIB_PATH is set to {}, but there is no such file; point it at libonnxruntime.so.{ORT_VERSION} or unset it", path.display())]
    DylibPathMissing {
        /// The value of `ORT_DYLIB_PATH`.
        path: PathBuf,
    },
    /// No library in any of the places searched.
    #[error(
        "ONNX Runtime {ORT_VERSION} not found: ORT_DYLIB_PATH is unset and none of {} exists; {FIX}",
        join_paths(searched)
    )]
    DylibNotFound {
        /// Every path tried, in order.
        searched: Vec<PathBuf>,
    },
    /// The library exists but could not be loaded (not a shared library, too old, ...).
    #[error("cannot load ONNX Runtime from {}", path.display())]
    Load {
        /// The library that failed to load.
        path: PathBuf,
        /// Why it failed.
        #[source]
        source: ort::LoadDynamicError,
    },
    /// ONNX Runtime loaded but refused to create its environment.
    #[error("cannot create the ONNX Runtime environment")]
    Environment(#[source] ort::Error),
}

/// Where [`locate_dylib`] looks for the library, in order; fill it to test the search itself.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct DylibSearch {
    /// The value of `ORT_DYLIB_PATH`; when set it is the only candidate (relative to the
    /// working directory). Empty counts as unset.
    pub env_override: Option<PathBuf>,
    /// The running executable's folder: searched itself, then its `../lib`.
    pub exe_dir: Option<PathBuf>,
    /// The path compiled in by `build.rs` (`TRE_ORT_DEFAULT_DYLIB`), searched last.
    pub built_in: Option<PathBuf>,
}

impl DylibSearch {
    /// The search this process would do: its environment, executable and build.
    pub fn from_process() -> Self {
        let exe = std::env::current_exe().ok();
        Self {
            env_override: std::env::var_os(DYLIB_ENV)
                .filter(|v| !v.is_empty())
                .map(PathBuf::from),
            exe_dir: exe.as_deref().and_then(Path::parent).map(Path::to_path_buf),
            built_in: option_env!("TRE_ORT_DEFAULT_DYLIB").map(PathBuf::from),
        }
    }

    /// The first candidate that is a file, made absolute.
    ///
    /// # Errors
    ///
    /// [`RuntimeError::DylibPathMissing`] when the override names no file, else
    /// [`RuntimeError::DylibNotFound`] when no candidate exists; both say how to fix it.
    pub fn resolve(&self) -> Result<PathBuf, RuntimeError> {
        let env_override = self.env_override.as_ref();
        if let Some(path) = env_override.filter(|path| !path.as_os_str().is_empty()) {
            if path.is_file() {
                // ort would try a relative path beside the executable first; pin it down here.
                return Ok(std::path::absolute(path).unwrap_or_else(|_| path.clone()));
            }
            return Err(RuntimeError::DylibPathMissing { path: path.clone() });
        }
        let searched = self.candidates();
        match searched.iter().find(|path| path.is_file()) {
            Some(path) => Ok(path.clone()),
            None => Err(RuntimeError::DylibNotFound { searched }),
        }
    }

    /// Candidates after `ORT_DYLIB_PATH`: the library names in the executable's folder and in
    /// its `../lib`, then the built-in path.
    fn candidates(&self) -> Vec<PathBuf> {
        let names = [
            format!("libonnxruntime.so.{ORT_VERSION}"),
            "libonnxruntime.so.1".to_owned(),
            format!("{DLL_PREFIX}onnxruntime{DLL_SUFFIX}"),
        ];
        let dirs = self
            .exe_dir
            .iter()
            .flat_map(|dir| [dir.clone(), dir.join("..").join("lib")]);
        let beside_exe = dirs.flat_map(|dir| names.iter().map(move |name| dir.join(name)));
        beside_exe.chain(self.built_in.iter().cloned()).collect()
    }
}

/// Finds the ONNX Runtime library: `ORT_DYLIB_PATH` if set (it must exist), else
/// `libonnxruntime.so*` beside the executable or in its `../lib`, else the library `build.rs`
/// fetched into `.ort/`. See [`DylibSearch`].
///
/// # Errors
///
/// As [`DylibSearch::resolve`]: the message names the path or the places searched and the fix.
pub fn locate_dylib() -> Result<PathBuf, RuntimeError> {
    DylibSearch::from_process().resolve()
}

/// The process-wide ONNX Runtime environment, created on first use from [`locate_dylib`].
///
/// ONNX Runtime allows one environment per process, so every session should be built from this
/// one rather than from `ort::init`. A failure is not cached: a later call tries again.
///
/// # Errors
///
/// Those of [`locate_dylib`], [`RuntimeError::Load`] when the library cannot be loaded (not a
/// shared library, or older than [`ORT_VERSION`]), and [`RuntimeError::Environment`].
pub fn environment() -> Result<&'static Environment, RuntimeError> {
    static ENVIRONMENT: OnceLock<Environment> = OnceLock::new();
    static INIT: Mutex<()> = Mutex::new(());
    if let Some(env) = ENVIRONMENT.get() {
        return Ok(env);
    }
    let _guard = INIT.lock().unwrap_or_else(PoisonError::into_inner);
    if let Some(env) = ENVIRONMENT.get() {
        return Ok(env);
    }
    let env = create_environment(&locate_dylib()?)?;
    Ok(ENVIRONMENT.get_or_init(|| env))
}

/// Loads the library at `path` and builds the environment (telemetry off).
fn create_environment(path: &Path) -> Result<Environment, RuntimeError> {
    let builder = ort::init_from(path).map_err(|source| RuntimeError::Load {
        path: path.to_path_buf(),
        source,
    })?;
    builder
        .with_name("tre")
        .with_telemetry(false)
        .build()
        .map_err(RuntimeError::Environment)
}

/// `a, b, c` for error messages.
fn join_paths(paths: &[PathBuf]) -> String {
    let shown: Vec<_> = paths.iter().map(|p| p.display().to_string()).collect();
    shown.join(", ")
}

#[cfg(test)]
mod tests {
    use std::error::Error;

    use super::*;

    type TestResult = Result<(), Box<dyn Error>>;

    /// Creates an empty file, and its folders.
    fn touch(path: &Path) -> std::io::Result<()> {
        if let Some(dir) = path.parent() {
            std::fs::create_dir_all(dir)?;
        }
        std::fs::write(path, b"")
    }

    #[test]
    fn missing_override_names_the_path() -> TestResult {
        let dir = tempfile::tempdir()?;
        let missing = dir.path().join("nowhere").join("libonnxruntime.so");
        let search = DylibSearch {
            env_override: Some(missing.clone()),
            ..DylibSearch::default()
        };
        let err = search.resolve().expect_err("the override does not exist");
        assert!(matches!(&err, RuntimeError::DylibPathMissing { path } if *path == missing));
        assert!(
            err.to_string().contains(&missing.display().to_string()),
            "{err}"
        );
        Ok(())
    }

    #[test]
    fn override_wins_over_everything_else() -> TestResult {
        let dir = tempfile::tempdir()?;
        let chosen = dir.path().join("custom.so");
        let built_in = dir.path().join("built_in.so");
        touch(&chosen)?;
        touch(&built_in)?;
        let search = DylibSearch {
            env_override: Some(chosen.clone()),
            exe_dir: None,
            built_in: Some(built_in),
        };
        assert_eq!(search.resolve()?, chosen);
        Ok(())
    }

    #[test]
    fn beside_executable_then_lib_then_built_in() -> TestResult {
        let dir = tempfile::tempdir()?;
        let exe_dir = dir.path().join("bin");
        let built_in = dir.path().join("built_in.so");
        touch(&built_in)?;
        let search = DylibSearch {
            env_override: None,
            exe_dir: Some(exe_dir.clone()),
            built_in: Some(built_in.clone()),
        };
        assert_eq!(search.resolve()?, built_in);
        let in_lib = exe_dir.join("..").join("lib").join("libonnxruntime.so");
        touch(&in_lib)?;
        assert_eq!(search.resolve()?, in_lib);
        let beside = exe_dir.join(format!("libonnxruntime.so.{ORT_VERSION}"));
        touch(&beside)?;
        assert_eq!(search.resolve()?, beside);
        Ok(())
    }

    #[test]
    fn not_found_lists_candidates_and_the_fix() -> TestResult {
        let dir = tempfile::tempdir()?;
        let built_in = dir.path().join("absent.so");
        let search = DylibSearch {
            env_override: None,
            exe_dir: Some(dir.path().to_path_buf()),
            built_in: Some(built_in.clone()),
        };
        let message = search.resolve().expect_err("nothing exists").to_string();
        assert!(
            message.contains(&built_in.display().to_string()),
            "{message}"
        );
        assert!(
            message.contains("python3 scripts/fetch_onnxruntime.py"),
            "{message}"
        );
        assert!(
            message.contains("pip install onnxruntime==1.31.1"),
            "{message}"
        );
        assert!(message.contains("ORT_DYLIB_PATH"), "{message}");
        Ok(())
    }

    #[test]
    fn versions_agree() {
        assert!(FIX.contains(&format!("onnxruntime=={ORT_VERSION}")));
        let built_in = env!("TRE_ORT_DEFAULT_DYLIB");
        assert!(built_in.ends_with(&format!("libonnxruntime.so.{ORT_VERSION}")));
    }

    #[test]
    fn errors_cross_threads() {
        fn assert_send_sync<T: Send + Sync + 'static>() {}
        assert_send_sync::<RuntimeError>();
    }
}
