//! Tests of the frame sources: PNG streams, the latest-frame slot, folders, the ffmpeg lookup.

use super::ffmpeg::{failed, LatestSlot};
use super::*;

fn png(w: u32, h: u32) -> Vec<u8> {
    let mut out = Vec::new();
    tre_io::encode_png(&image::DynamicImage::new_rgb8(w, h), &mut out).unwrap();
    out
}

#[test]
fn a_png_stream_splits_into_its_images() {
    let (a, b) = (png(3, 2), png(5, 4));
    let stream = [a.clone(), b.clone()].concat();
    let mut r = &stream[..];
    assert_eq!(read_png(&mut r).unwrap(), Some(a));
    assert_eq!(read_png(&mut r).unwrap(), Some(b.clone()));
    assert_eq!(read_png(&mut r).unwrap(), None);
    let mut cut = &b[..b.len() - 3];
    assert!(read_png(&mut cut)
        .unwrap_err()
        .to_string()
        .contains("ended inside"));
    let mut junk = &b"GIF89a not a png"[..];
    assert!(matches!(read_png(&mut junk), Err(PngStreamError::NotPng)));
}

#[test]
fn the_latest_slot_keeps_only_the_newest_frame() {
    let (a, b) = (png(1, 1), png(2, 2));
    let slot = LatestSlot::default();
    slot.fill(&[a, b.clone()].concat()[..]);
    assert_eq!(slot.take().unwrap(), Some(b));
    assert_eq!(slot.take().unwrap(), None);
}

#[test]
fn a_folder_pairs_frames_with_depth_by_stem() {
    let dir = tempfile::tempdir().unwrap();
    let (rgb, depth) = (dir.path().join("rgb"), dir.path().join("depth"));
    std::fs::create_dir_all(&rgb).unwrap();
    std::fs::create_dir_all(&depth).unwrap();
    for name in ["b.png", "a.jpg", "c.PNG", "notes.txt"] {
        std::fs::write(rgb.join(name), name).unwrap();
    }
    for name in ["a.png", "b.npy", "c.png"] {
        std::fs::write(depth.join(name), format!("depth of {name}")).unwrap();
    }
    let frames: Vec<SourceFrame> = FolderSource::open(&rgb, Some(&depth), None)
        .unwrap()
        .collect::<Result<_, _>>()
        .unwrap();
    let names: Vec<&str> = frames.iter().map(|f| f.name.as_str()).collect();
    assert_eq!(names, ["a", "b", "c"]);
    assert_eq!(frames[1].image, b"b.png");
    assert_eq!(frames[1].depth.as_deref(), Some(&b"depth of b.npy"[..]));
    std::fs::remove_file(depth.join("c.png")).unwrap();
    let e = FolderSource::open(&rgb, Some(&depth), None).unwrap_err();
    assert!(e.to_string().contains("no depth for frame c"), "{e}");
    let empty = dir.path().join("empty");
    std::fs::create_dir_all(&empty).unwrap();
    assert!(FolderSource::open(&empty, None, None).is_err());
}

#[test]
fn ffmpeg_is_looked_up_on_the_path_and_its_absence_is_explained() {
    let dir = tempfile::tempdir().unwrap();
    assert_eq!(
        find_executable("ffmpeg", Some(dir.path().as_os_str())),
        None
    );
    assert_eq!(find_executable("ffmpeg", None), None);
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        let exe = dir.path().join("ffmpeg");
        std::fs::write(&exe, "#!/bin/sh\n").unwrap();
        assert_eq!(
            find_executable("ffmpeg", Some(dir.path().as_os_str())),
            None
        );
        std::fs::set_permissions(&exe, std::fs::Permissions::from_mode(0o755)).unwrap();
        assert_eq!(
            find_executable("ffmpeg", Some(dir.path().as_os_str())),
            Some(exe)
        );
    }
    #[cfg(unix)]
    {
        use std::os::unix::process::ExitStatusExt;
        let e = failed(
            "run.mp4",
            FfmpegProblem::Exited {
                status: ExitStatus::from_raw(1 << 8),
                stderr_tail: "run.mp4: Invalid data found\n".into(),
            },
        );
        assert_eq!(
            e.to_string(),
            "ffmpeg on run.mp4: exit status: 1: run.mp4: Invalid data found"
        );
    }
    let msg = ClientError::FfmpegMissing {
        input: "run.mp4".into(),
    }
    .to_string();
    assert!(msg.contains("ffmpeg") && msg.contains("--frames"), "{msg}");
}
