//! The roughness annotator (spec v1) on the real RGB-D frames of `../shared/data/real-rgbd`:
//! holes stay holes, the floor boxes of `tests/fixtures/real_floor.json` read under 1 cm, and
//! sparse depth does not panic (the synthetic scenes: `crates/tre-core/tests/core/annotate.rs`).
#![allow(clippy::unwrap_used)] // Test helpers fail loudly by design.

use tre::geometry::Grid;

use crate::common::{real, real_frames, spec};

#[test]
fn real_frames_annotate_and_their_floors_read_under_one_cm() {
    crate::common::skip_unless_shared!("data/real-rgbd");
    let frames = real_frames();
    assert_eq!(frames.len(), 10);
    for f in &frames {
        let (depth, k) = f.depth();
        let ann = spec(&depth, &k);
        let valid = ann
            .roughness_m
            .as_slice()
            .iter()
            .filter(|r| r.is_finite())
            .count();
        let holes = depth.as_slice().iter().filter(|d| **d <= 0.0).count();
        assert!(
            holes > 0 && valid + holes == depth.as_slice().len(),
            "{}: holes stay holes",
            f.depth
        );
        let Some([x0, y0, x1, y1]) = f.floor else {
            continue;
        };
        let mut floor: Vec<f64> = (y0..y1)
            .flat_map(|y| (x0..x1).map(move |x| (x, y)))
            .map(|p| ann.roughness_m[p])
            .filter(|r| r.is_finite())
            .collect();
        assert!(
            floor.len() > 3000,
            "{}: {} floor pixels",
            f.depth,
            floor.len()
        );
        floor.sort_by(f64::total_cmp);
        let median = floor[floor.len() / 2];
        assert!(
            median < 0.01,
            "{}/{}: floor median {median} m",
            f.dir,
            f.depth
        );
    }
}

#[test]
fn sparse_depth_does_not_panic() {
    crate::common::skip_unless_shared!("data/real-rgbd");
    // Keep 1 pixel in 37 of a real frame, and a frame with a single valid pixel.
    let dir = real("slambook2_ch5");
    let (cam, k) = tre::io::read_camera(&dir.join("intrinsics.json")).unwrap();
    let mut depth =
        tre::io::read_depth(&dir.join("depth/1.png"), cam.depth_scale.unwrap()).unwrap();
    for (i, d) in depth.as_mut_slice().iter_mut().enumerate() {
        if i % 37 != 0 {
            *d = 0.0;
        }
    }
    let ann = spec(&depth, &k);
    assert!(ann.roughness_m.as_slice().iter().any(|r| r.is_finite()));
    let mut one = Grid::new(5, 4, 0.0);
    one[(2, 1)] = 1.0;
    let ann = spec(&one, &k);
    assert_eq!(
        ann.roughness_m
            .as_slice()
            .iter()
            .filter(|r| r.is_finite())
            .count(),
        1
    );
}
