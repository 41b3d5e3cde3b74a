//! Urban scenes: a street edge with road, sidewalk, curb, kerb ramp, drains and posts.

use std::f64::consts::FRAC_PI_2;

use super::layout::{Layout, FAR_M, ROBOT_CLEAR_M};
use crate::objects::{Profile, Shape};
use crate::surface::Category;
use crate::terrain::Terrain;
use tre_core::geometry::hash::splitmix64;

/// The street edge: curb line `curb_b` ahead, the robot on the sidewalk or on the road.
struct Street {
    curb_b: f64,
    curb_h: f64,
    on_walk: bool,
}

impl Street {
    fn walk_z(&self) -> f64 {
        if self.on_walk {
            0.0
        } else {
            self.curb_h
        }
    }

    fn road_z(&self) -> f64 {
        self.walk_z() - self.curb_h
    }

    /// Unit step (in b) from the curb line into the sidewalk.
    fn walk_dir(&self) -> f64 {
        if self.on_walk {
            -1.0
        } else {
            1.0
        }
    }
}

/// An urban scene: a curb line 0.35–0.55 × (`reach_m` − 0.5 m) ahead (at least 0.6 m), turned up to ±26°,
/// with the robot on the sidewalk (the curb drops 10–15 cm to the road) or on the road (it
/// rises); asphalt road, block paving or slab sidewalk, a curb strip, a kerb ramp with flared
/// sides, one or two drains in the gutter and one to three posts on the sidewalk.
pub fn urban(seed: u64, scene: u64, reach_m: f64) -> Terrain {
    let mut l = Layout::new(seed, scene, 0x0B_A400, reach_m);
    let st = Street {
        curb_b: (l.near_m * l.rng.range(0.35, 0.55)).max(0.6),
        curb_h: l.rng.range(0.10, 0.15),
        on_walk: l.rng.chance(0.5),
    };
    urban_ground(&mut l, &st);
    let ramp = urban_ramp(&mut l, &st);
    urban_drains(&mut l, &st, ramp);
    urban_posts(&mut l, &st, ramp);
    l.into_terrain(Category::Asphalt, splitmix64(seed ^ scene ^ 0x0B))
}

/// A rectangle spanning all `a`, from `b0` to `b1` ahead.
fn band(l: &Layout, b0: f64, b1: f64) -> Shape {
    let (lo, hi) = (b0.min(b1), b0.max(b1));
    l.rect((0.0, (lo + hi) / 2.0), (FAR_M, (hi - lo) / 2.0), 0.0)
}

fn urban_ground(l: &mut Layout, st: &Street) {
    let c = st.curb_b;
    let walk_side = c + st.walk_dir() * FAR_M;
    let road_side = c - st.walk_dir() * FAR_M;
    let walk = if l.rng.chance(0.7) {
        Category::Paving
    } else {
        Category::Pavement
    };
    l.add(
        Category::Asphalt,
        band(l, c, road_side),
        Profile::Floor {
            base_m: st.road_z(),
        },
    );
    l.add(
        walk,
        band(l, c, walk_side),
        Profile::Floor {
            base_m: st.walk_z(),
        },
    );
    let width = l.rng.range(0.12, 0.18);
    l.add(
        Category::Curb,
        band(l, c, c + st.walk_dir() * width),
        Profile::Block { top_m: st.walk_z() },
    );
}

/// The kerb ramp; returns its centre along the curb and its width.
fn urban_ramp(l: &mut Layout, st: &Street) -> (f64, f64) {
    // Off the view's centre, so that a post fits beside it within sight.
    let side = if l.rng.chance(0.5) { 1.0 } else { -1.0 };
    let a = side * l.rng.range(0.25, 0.8) * st.curb_b.min(1.0);
    let width = l.rng.range(1.0, 1.6);
    let flare = l.rng.range(0.25, 0.4);
    let mut run = l.rng.range(0.8, 1.2);
    if st.on_walk {
        run = run.min((st.curb_b - 0.2).max(0.5));
    }
    // It starts 1 cm into the road (at road level), covering the curb's blended outline there.
    let run = run + 0.01;
    let b = st.curb_b + st.walk_dir() * (run / 2.0 - 0.01);
    // u points into the sidewalk: the frame's b axis (turned a quarter) or against it.
    let turn = if st.on_walk { -FRAC_PI_2 } else { FRAC_PI_2 };
    let shape = l.rect((a, b), (run / 2.0, width / 2.0), turn);
    let profile = Profile::Ramp {
        low_m: st.road_z(),
        high_m: st.walk_z(),
        flare_m: flare,
    };
    l.add(Category::KerbRamp, shape, profile);
    (a, width)
}

fn urban_drains(l: &mut Layout, st: &Street, (ramp_a, ramp_w): (f64, f64)) {
    let count = 1 + usize::from(l.rng.chance(0.4));
    let mut placed: Vec<(f64, f64)> = Vec::new();
    for _ in 0..count {
        let along = l.rng.range(0.4, 0.7);
        let across = l.rng.range(0.3, 0.45);
        let gap = l.rng.range(0.01, 0.12);
        let b = st.curb_b - st.walk_dir() * (gap + across / 2.0);
        let span = l.near_m.min(1.6);
        let spot = (0..40).map(|_| l.rng.range(-span, span)).find(|&a| {
            (a - ramp_a).abs() > (ramp_w + along) / 2.0 + 0.1
                && placed
                    .iter()
                    .all(|&(p, w)| (a - p).abs() > (w + along) / 2.0 + 0.1)
        });
        let Some(a) = spot else { continue };
        placed.push((a, along));
        let profile = Profile::Grate {
            top_m: st.road_z(),
            recess_m: l.rng.range(0.01, 0.02),
            frame_m: 0.03,
            slot_m: l.rng.range(0.02, 0.025),
            pitch_m: l.rng.range(0.035, 0.045),
            slot_depth_m: l.rng.range(0.04, 0.06),
        };
        let shape = l.rect((a, b), (along / 2.0, across / 2.0), 0.0);
        l.add(Category::Drain, shape, profile);
    }
}

fn urban_posts(l: &mut Layout, st: &Street, (ramp_a, ramp_w): (f64, f64)) {
    let count = 1 + (l.rng.next() * 3.0) as usize;
    for k in 0..count {
        let radius = l.rng.range(0.05, 0.10);
        let top = st.walk_z() + l.rng.range(0.6, 1.0);
        let into = l.rng.range(0.25, 0.45);
        let b = st.curb_b + st.walk_dir() * into;
        // The first flanks the ramp on the side of the view's centre; the others stand anywhere
        // along the curb; all within sight.
        let first = ramp_a - ramp_a.signum() * (ramp_w / 2.0 + 0.25);
        let candidates: Vec<f64> = (0..40)
            .map(|i| {
                if k == 0 && i == 0 {
                    first
                } else {
                    l.rng.range(-1.0, 1.0) * l.near_m.min(2.0)
                }
            })
            .collect();
        let spot = candidates.into_iter().find(|&a| {
            let w = l.world(a, b);
            (a - ramp_a).abs() > ramp_w / 2.0 + radius
                && w.0.hypot(w.1) > ROBOT_CLEAR_M + 0.2
                && w.0.hypot(w.1) < l.near_m - 0.1
                && l.taken
                    .iter()
                    .all(|(c, r)| (c.0 - w.0).hypot(c.1 - w.1) > r + radius + 0.2)
        });
        let Some(a) = spot else { continue };
        l.take((a, b), radius);
        let shape = Shape::Disc {
            centre: l.world(a, b),
            radius_m: radius,
        };
        l.add(Category::Post, shape, Profile::Block { top_m: top });
    }
}
