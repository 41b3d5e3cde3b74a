//! JPEG frames are decoded strictly: every valid kind (baseline 4:2:0 and 4:4:4, progressive,
//! restart intervals, grey, CMYK, bytes after the end marker) gives exactly the pixels of
//! `image`'s own decoding, while truncated data is an error instead of a frame filled with
//! grey.
#![allow(clippy::unwrap_used)] // Test helpers fail loudly by design.

use crate::common;

use std::path::PathBuf;

use common::real;
use image::DynamicImage;

fn fixtures() -> Vec<PathBuf> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/jpeg"),
    )
    .unwrap()
    .map(|e| e.unwrap().path())
    .collect();
    files.sort();
    files.extend(
        ["rgb_00000", "rgb_00050", "rgb_00100"].map(|f| real(&format!("metric3d_nyu/rgb/{f}.jpg"))),
    );
    files
}

#[test]
fn valid_jpegs_decode_to_the_same_pixels_as_image_does() {
    crate::common::skip_unless_shared!("data/real-rgbd");
    let files = fixtures();
    assert_eq!(files.len(), 10);
    for path in files {
        let bytes = std::fs::read(&path).unwrap();
        let strict = tre::io::decode_jpeg(&bytes).unwrap_or_else(|e| panic!("{path:?}: {e}"));
        let lenient = image::load_from_memory(&bytes).unwrap();
        let grey = path.ends_with("grey.jpg");
        assert_eq!(
            matches!(strict, DynamicImage::ImageLuma8(_)),
            grey,
            "{path:?}"
        );
        assert_eq!(strict.to_rgb8(), lenient.to_rgb8(), "{path:?}");
        // The file reader takes the same path.
        assert_eq!(tre::io::read_image(&path).unwrap(), strict, "{path:?}");
    }
}

#[test]
fn truncated_jpegs_are_errors() {
    crate::common::skip_unless_shared!("data/real-rgbd");
    for path in fixtures() {
        if path.ends_with("trailing_bytes.jpg") {
            continue;
        }
        let bytes = std::fs::read(&path).unwrap();
        for percent in [10, 30, 50, 70, 90, 98] {
            let cut = &bytes[..bytes.len() * percent / 100];
            match tre::io::decode_jpeg(cut) {
                Ok(_) => panic!("{path:?} cut at {percent}% decoded"),
                Err(e) => assert!(
                    e.to_string().contains("not a whole, valid JPEG"),
                    "{path:?}: {e}"
                ),
            }
            // `image` itself would have given a grey-filled frame for most of these.
        }
    }
}
