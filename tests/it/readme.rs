//! The README's and docs' cheap commands run as written, and what they print is what the docs
//! say they print; the repository's own sample frame and camera files are what they claim.
#![allow(clippy::unwrap_used)] // Test helpers fail loudly by design.

use std::path::Path;
use std::process::Command;

use crate::common::repo_text;

/// The first fenced block of `doc` after the first line containing `marker`, line by line.
fn block_after(doc: &str, marker: &str) -> Vec<String> {
    let start = doc.find(marker).unwrap_or_else(|| panic!("no {marker:?}"));
    let rest = &doc[start..];
    let open = rest.find("```").unwrap();
    let body_start = open + rest[open..].find('\n').unwrap() + 1;
    let close = body_start + rest[body_start..].find("```").unwrap();
    rest[body_start..close].lines().map(str::to_owned).collect()
}

/// A shell command of a fenced block (lines joined at trailing backslashes, comments dropped),
/// as arguments of `tre` after `cargo run --release --`.
fn tre_args(block: &[String], starts: &str) -> Vec<String> {
    let joined = block
        .iter()
        .filter(|l| !l.trim_start().starts_with('#'))
        .map(|l| l.trim_end_matches('\\').trim().to_owned())
        .collect::<Vec<_>>()
        .join(" ");
    let at = joined
        .find(starts)
        .unwrap_or_else(|| panic!("no {starts:?} in {joined}"));
    let after = &joined[at + starts.len()..];
    let cmd = after.split("cargo test").next().unwrap();
    cmd.split_whitespace().map(str::to_owned).collect()
}

#[test]
fn readme_command_one_runs_and_prints_what_the_readme_and_cli_docs_say() {
    let readme = repo_text("README.md");
    let setup = block_after(&readme, "## Set-up: two commands");
    let mut args = tre_args(&setup, "cargo run --release --");
    assert_eq!(args[0], "infer", "{args:?}");
    // The output goes to a temporary folder instead of out/.
    let dir = tempfile::tempdir().unwrap();
    let out = args.iter().position(|a| a == "-o").unwrap() + 1;
    args[out] = dir.path().join("roughness.png").display().to_string();
    let o = Command::new(env!("CARGO_BIN_EXE_tre"))
        .args(&args)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .env_remove("RUST_LOG")
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&o.stdout);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{stderr}");
    // Nothing was assumed: the sample's camera file states intrinsics, depth scale, sensor.
    assert!(!stderr.contains("warning:"), "{stderr}");
    let printed: Vec<&str> = stdout.lines().filter(|l| !l.starts_with("ms:")).collect();
    let said = block_after(&readme, "Command 1 prints");
    assert_eq!(printed, said, "README.md, 'Command 1 prints'");
    let cli = block_after(&repo_text("docs/cli.md"), "It runs the `geometric` mode");
    assert_eq!(printed, cli, "docs/cli.md, `tre infer`");
    for f in [
        "roughness.png",
        "roughness_preview.png",
        "roughness_uncertainty.png",
        "roughness_traversal.png",
        "roughness_traversal_preview.png",
        "roughness.json",
    ] {
        assert!(dir.path().join(f).is_file(), "{f} not written");
    }
}

#[test]
fn a_frame_without_a_camera_warns_of_every_default_it_took() {
    let dir = tempfile::tempdir().unwrap();
    let o = Command::new(env!("CARGO_BIN_EXE_tre"))
        .args(["infer", "--depth", "samples/tum_fr2_desk/depth.png", "-o"])
        .arg(dir.path().join("r.png"))
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{stderr}");
    for says in [
        "warning: no camera intrinsics",
        "warning: no depth_scale: the 16-bit depth was read as millimetres",
        "warning: no mode asked for: ran geometric",
    ] {
        assert!(stderr.contains(says), "{says:?} not in {stderr}");
    }
    // Depth given as the colour frame is refused, saying where it goes.
    let o = Command::new(env!("CARGO_BIN_EXE_tre"))
        .args(["infer", "samples/tum_fr2_desk/depth.png", "-o"])
        .arg(dir.path().join("s.png"))
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success());
    assert!(
        stderr.contains("16-bit grey image is depth") && stderr.contains("--depth"),
        "{stderr}"
    );
}

#[test]
fn every_shipped_camera_file_reads_and_names_a_noise_model() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("cameras");
    let mut n = 0;
    for entry in std::fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_none_or(|e| e != "json") {
            continue;
        }
        let (cam, _) = tre::io::read_camera(&path).unwrap();
        assert!(
            cam.sensor
                .as_ref()
                .and_then(tre::io::SensorSpec::noise)
                .is_some(),
            "{} names no noise model",
            path.display()
        );
        assert!(
            cam.depth_scale.is_some(),
            "{}: no depth_scale",
            path.display()
        );
        n += 1;
    }
    // One per shared sequence: 3 of real-rgbd, 14 of real-rgbd-2, 2 of real-rgbd-3.
    assert_eq!(n, 19);
    let sample = repo_text("samples/tum_fr2_desk/camera.json");
    assert_eq!(sample, repo_text("cameras/real-rgbd_slambook2_ch7.json"));
}
