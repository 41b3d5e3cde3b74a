//! Three-state traversability on the shared real RGB-D frames.

use super::*;
use crate::common::{real_frames, RealFrame};

/// Counts of (traversable, hazard, unknown) among `states`.
fn tally(states: impl Iterator<Item = Traversal>) -> [usize; 3] {
    let mut c = [0; 3];
    for s in states {
        c[match s {
            Traversal::Traversable => 0,
            Traversal::Hazard => 1,
            Traversal::Unknown => 2,
        }] += 1;
    }
    c
}

/// The spec (no labels, LS normals), its uncertainty under the Kinect v1 model, and the
/// three-state map with the roughness threshold alone (these frames' mountings are unknown,
/// so no slope test).
fn real_frame(f: &RealFrame) -> (Grid<f64>, Grid<f64>, Grid<f64>, Grid<Traversal>) {
    let (depth, k) = f.depth();
    let input = AnnotateInput::depth(&depth, &k);
    let cfg = AnnotateConfig::default();
    let ann = annotate(&input, &cfg).unwrap();
    let kinect = SensorNoise::Preset(SensorPreset::KinectV1);
    let u = tre::roughness::noise::uncertainty_map(&depth, &k, &ann.normals, &kinect, &cfg);
    let rule = ThreeStateRule::default();
    let ok = ann.roughness_m.map(|&r| r <= rule.max_roughness_m);
    let states = rule.map(&ann.roughness_m, &u, &ok);
    (depth, ann.roughness_m, u, states)
}

/// Counts of (traversable, hazard, unknown) over the real frames: near floor (inside the floor
/// boxes, nearer than 2 m), far rough (≥ 4 m, r ≥ 5 cm), drops (r ≥ 10 cm) and drops nearer
/// than 2.5 m.
#[derive(Default)]
struct RealCounts {
    near_floor: [usize; 3],
    far_rough: [usize; 3],
    drops: [usize; 3],
    near_drops: [usize; 3],
}

/// Adds frame `f`'s pixels to `counts` and prints its row of the table.
fn count_real_frame(f: &RealFrame, counts: &mut RealCounts) {
    let RealCounts {
        near_floor,
        far_rough,
        drops,
        near_drops,
    } = counts;
    let (depth, r, _u, states) = real_frame(f);
    let (t, h, u) = shares(&states);
    let px = |(x, y): (usize, usize)| (depth[(x, y)], r[(x, y)], states[(x, y)]);
    let all: Vec<_> = (0..depth.height())
        .flat_map(|y| (0..depth.width()).map(move |x| (x, y)))
        .map(px)
        .collect();
    let far = tally(
        all.iter()
            .filter(|(z, r, _)| *z >= 4.0 && *r >= 0.05)
            .map(|p| p.2),
    );
    eprintln!(
        "| {}/{} | {:.1} | {:.1} | {:.1} | {} px, {:.1}% unknown, {:.1}% hazard |",
        f.dir,
        f.depth,
        100.0 * t,
        100.0 * h,
        100.0 * u,
        far.iter().sum::<usize>(),
        100.0 * far[2] as f64 / far.iter().sum::<usize>().max(1) as f64,
        100.0 * far[1] as f64 / far.iter().sum::<usize>().max(1) as f64
    );
    for i in 0..3 {
        far_rough[i] += far[i];
    }
    let d = tally(all.iter().filter(|(_, r, _)| *r >= 0.1).map(|p| p.2));
    let near = tally(
        all.iter()
            .filter(|(z, r, _)| *r >= 0.1 && *z < 2.5)
            .map(|p| p.2),
    );
    for i in 0..3 {
        drops[i] += d[i];
        near_drops[i] += near[i];
    }
    if let Some([x0, y0, x1, y1]) = f.floor {
        let floor = (y0..y1).flat_map(|y| (x0..x1).map(move |x| (x, y))).map(px);
        let c = tally(floor.filter(|(z, _, _)| *z > 0.0 && *z < 2.0).map(|p| p.2));
        for i in 0..3 {
            near_floor[i] += c[i];
        }
    }
}

#[test]
fn real_kinect_frames_near_floor_traversable_far_rough_unknown_drops_hazard() {
    crate::common::skip_unless_shared!("data/real-rgbd");
    let frames = real_frames();
    let mut counts = RealCounts::default();
    eprintln!("frame | traversable % | hazard % | unknown % | far (≥ 4 m) rough px: unknown %");
    for f in &frames {
        count_real_frame(f, &mut counts);
    }
    let (near_floor, far_rough) = (counts.near_floor, counts.far_rough);
    let (drops, near_drops) = (counts.drops, counts.near_drops);
    let share = |c: [usize; 3], i: usize| c[i] as f64 / c.iter().sum::<usize>().max(1) as f64;
    eprintln!("near floor {near_floor:?}, far rough {far_rough:?}, drops {drops:?}");
    assert!(near_floor.iter().sum::<usize>() > 10_000, "{near_floor:?}");
    assert!(
        share(near_floor, 0) > 0.97,
        "near floor traversable: {near_floor:?}"
    );
    assert!(far_rough.iter().sum::<usize>() > 1_000, "{far_rough:?}");
    assert!(
        share(far_rough, 2) > 0.8,
        "far rough pixels unknown: {far_rough:?}"
    );
    eprintln!("drops (r ≥ 0.1 m) within 2.5 m: {near_drops:?}");
    assert!(drops[0] == 0, "no drop is traversable: {drops:?}");
    let near_total = near_drops.iter().sum::<usize>() as f64;
    assert!(
        near_drops[1] > 1_000 && near_drops[1] as f64 > 0.99 * near_total,
        "drops within 2.5 m stay hazards: {near_drops:?}"
    );
}
