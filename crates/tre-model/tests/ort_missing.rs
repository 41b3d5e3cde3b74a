//! `ORT_DYLIB_PATH` naming a missing file or a file that is no library: the errors name the
//! path. Environment variables are process-wide, so these checks run in one test, in a test
//! binary of their own.
//!
//! Separate from the crate's other tests (`tests/model/`) because it changes process-wide
//! state: it sets `ORT_DYLIB_PATH` to bad paths (another test's model load would read them), and
//! it needs a process whose ONNX Runtime environment was never created
//! (`runtime::environment()` keeps the first one made, so after any other test that loads a
//! model it could no longer fail).

use tre_model::runtime::{self, RuntimeError};

#[test]
fn bad_ort_dylib_path_is_named_in_the_error() -> Result<(), Box<dyn std::error::Error>> {
    let dir = tempfile::tempdir()?;
    let missing = dir
        .path()
        .join("no-such-dir")
        .join("libonnxruntime.so.1.31.1");
    std::env::set_var(runtime::DYLIB_ENV, &missing);

    let err = runtime::locate_dylib().expect_err("the library does not exist");
    assert!(matches!(&err, RuntimeError::DylibPathMissing { path } if *path == missing));
    assert!(
        err.to_string().contains(&missing.display().to_string()),
        "{err}"
    );
    let err = runtime::environment().expect_err("the library does not exist");
    assert!(
        matches!(err, RuntimeError::DylibPathMissing { .. }),
        "{err}"
    );

    let not_a_library = dir.path().join("libonnxruntime.so");
    std::fs::write(&not_a_library, "not an ELF file")?;
    std::env::set_var(runtime::DYLIB_ENV, &not_a_library);
    let err = runtime::environment().expect_err("the file is no library");
    assert!(
        matches!(&err, RuntimeError::Load { path, .. } if *path == not_a_library),
        "{err}"
    );
    Ok(())
}
