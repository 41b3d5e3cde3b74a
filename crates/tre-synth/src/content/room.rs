//! Indoor scenes: a room with floors of three materials, walls with a doorway and its sill,
//! stairs, a rug, furniture-like blocks, boxes and cables.

use std::f64::consts::{FRAC_PI_2, PI};

use super::layout::{Layout, FAR_M};
use crate::objects::{Profile, Shape};
use crate::surface::Category;
use crate::terrain::{Rng, Terrain};
use tre_core::geometry::hash::splitmix64;

/// The room: back wall `depth` ahead (thickness, height), a doorway in it, a side wall.
struct Room {
    depth: f64,
    wall_m: f64,
    side: Option<f64>,
}

impl Room {
    /// A free spot for a circle of radius `r` ([`Layout::place`]) in the room's half-plane
    /// ahead, clear of its walls.
    fn place(&self, l: &mut Layout, r: f64) -> Option<((f64, f64), f64)> {
        l.place(r, room_spot(self.depth), |c, r| in_room(self, c, r))
    }
}

/// An indoor scene: a room whose back wall stands 0.75–0.95 × (`reach_m` − 0.5 m) ahead (at
/// least 1 m) with a doorway and its sill; floors of tile, wood and carpet (the room split in
/// two, the room beyond the third, sometimes a rug); a flight of stairs up or down;
/// furniture-like blocks, boxes and cables. Everything stands in the robot's half-plane of view.
pub fn indoor(seed: u64, scene: u64, reach_m: f64) -> Terrain {
    let mut l = Layout::new(seed, scene, 0x1D00, reach_m);
    let room = Room {
        depth: (l.near_m * l.rng.range(0.75, 0.95)).max(1.0),
        wall_m: l.rng.range(0.10, 0.15),
        side: l.rng.chance(0.6).then(|| {
            let a = l.rng.range(1.3, 2.2);
            if l.rng.chance(0.5) {
                a
            } else {
                -a
            }
        }),
    };
    indoor_floors(&mut l, &room);
    indoor_stairs(&mut l, &room);
    // Furniture is placed before the cables (it needs more room) but drawn after them, so
    // that it stands on a cable rather than a cable lies over it.
    let mark = l.objects.len();
    indoor_furniture(&mut l, &room);
    let furniture = l.objects.len() - mark;
    indoor_cables(&mut l, &room);
    l.objects[mark..].rotate_left(furniture);
    indoor_walls(&mut l, &room);
    indoor_boxes(&mut l, &room);
    let floor = l.objects[0].category;
    l.into_terrain(floor, splitmix64(seed ^ scene))
}

/// Whether a circle (frame coordinates) fits in the room, clear of its walls.
fn in_room(room: &Room, (a, b): (f64, f64), r: f64) -> bool {
    let side_ok = room.side.is_none_or(|s| {
        if s > 0.0 {
            a + r < s - 0.02
        } else {
            a - r > s + 0.02
        }
    });
    b + r < room.depth - 0.02 && b - r > -0.75 && side_ok
}

/// A spot in the room's half-plane ahead: |a| ≤ 2.4 m, b from −0.4 m to the back wall.
fn room_spot(depth: f64) -> impl FnMut(&mut Rng) -> (f64, f64) {
    move |rng: &mut Rng| (rng.range(-2.4, 2.4), rng.range(-0.4, depth))
}

fn indoor_floors(l: &mut Layout, room: &Room) {
    let mut mats = [Category::Tile, Category::Wood, Category::Carpet];
    for i in (1..3).rev() {
        mats.swap(i, (l.rng.next() * (i + 1) as f64) as usize);
    }
    let floor = Profile::Floor { base_m: 0.0 };
    l.add(mats[0], l.rect((0.0, 0.0), (FAR_M, FAR_M), 0.0), floor);
    // The room split in two along a line across or ahead.
    let zone = if l.rng.chance(0.5) {
        let from = l.rng.range(-0.8, 0.8);
        l.rect(
            ((from + FAR_M) / 2.0, 0.0),
            ((FAR_M - from) / 2.0, FAR_M),
            0.0,
        )
    } else {
        let from = l.rng.range(0.5, room.depth - 0.2);
        l.rect(
            (0.0, (from + FAR_M) / 2.0),
            (FAR_M, (FAR_M - from) / 2.0),
            0.0,
        )
    };
    l.add(mats[1], zone, floor);
    let beyond = room.depth + room.wall_m / 2.0;
    let far = l.rect(
        (0.0, (beyond + FAR_M) / 2.0),
        (FAR_M, (FAR_M - beyond) / 2.0),
        0.0,
    );
    l.add(mats[2], far, floor);
}

fn indoor_stairs(l: &mut Layout, room: &Room) {
    let steps = 3 + (l.rng.next() * 2.0) as u32;
    let tread = l.rng.range(0.26, 0.32);
    let riser = l.rng.range(0.15, 0.19) * if l.rng.chance(0.5) { 1.0 } else { -1.0 };
    let width = l.rng.range(0.8, 1.1);
    let half = ((f64::from(steps) * tread + 0.3) / 2.0, width / 2.0);
    let turn = f64::from((l.rng.next() * 4.0) as u32) * FRAC_PI_2;
    let r = half.0.hypot(half.1);
    let spot = room.place(l, r);
    if let Some((c, k)) = spot {
        l.take(c, r * k);
        let shape = l.rect(c, (half.0 * k, half.1 * k), turn);
        let profile = Profile::Flight {
            base_m: 0.0,
            riser_m: riser,
            tread_m: tread * k,
            steps,
        };
        l.add(Category::Stairs, shape, profile);
    }
    // A rug, where the stairs are not (boxes and furniture may stand on it).
    if l.rng.chance(0.5) {
        let half = (l.rng.range(0.5, 0.9), l.rng.range(0.35, 0.6));
        let r = half.0.hypot(half.1);
        let turn = l.rng.range(-0.3, 0.3);
        let dz = l.rng.range(0.006, 0.012);
        if let Some((c, k)) = room.place(l, r) {
            let shape = l.rect(c, (half.0 * k, half.1 * k), turn);
            l.add(Category::Carpet, shape, Profile::Layer { dz_m: dz });
        }
    }
}

fn indoor_walls(l: &mut Layout, room: &Room) {
    let height = l.rng.range(2.4, 2.7);
    let wall = Profile::Block { top_m: height };
    let (t, b) = (room.wall_m, room.depth + room.wall_m / 2.0);
    let door_w = l.rng.range(0.8, 1.0);
    // Within sight: the doorway's centre no farther than the layout's near distance.
    let span = (l.near_m.powi(2) - room.depth.powi(2)).max(0.04).sqrt();
    let door_a = l.rng.range(-0.8, 0.8) * span;
    let (left, right) = (door_a - door_w / 2.0, door_a + door_w / 2.0);
    let piece = |from: f64, to: f64| (((from + to) / 2.0, b), ((to - from) / 2.0, t / 2.0));
    for (c, half) in [piece(-FAR_M, left), piece(right, FAR_M)] {
        let shape = l.rect(c, half, 0.0);
        l.add(Category::Wall, shape, wall);
    }
    if let Some(s) = room.side {
        let a = s + s.signum() * t / 2.0;
        let from = -2.8;
        let shape = l.rect((a, (from + b) / 2.0), (t / 2.0, (b - from) / 2.0), 0.0);
        l.add(Category::Wall, shape, wall);
    }
    let sill = Profile::Block {
        top_m: l.rng.range(0.01, 0.03),
    };
    let shape = l.rect((door_a, b), (door_w / 2.0, t / 2.0 + 0.01), 0.0);
    l.add(Category::Sill, shape, sill);
}

/// One or two furniture-like blocks: a sofa (seat and back) or a cabinet.
fn indoor_furniture(l: &mut Layout, room: &Room) {
    let count = 1 + usize::from(l.rng.chance(0.25));
    for _ in 0..count {
        let sofa = l.rng.chance(0.5);
        let half = if sofa {
            (l.rng.range(0.5, 0.8), l.rng.range(0.3, 0.4))
        } else {
            (l.rng.range(0.2, 0.5), l.rng.range(0.2, 0.3))
        };
        let turn = l.rng.range(-PI, PI);
        let r = half.0.hypot(half.1);
        let Some((c, k)) = room.place(l, r) else {
            continue;
        };
        l.take(c, r * k);
        let half = (half.0 * k, half.1 * k);
        if sofa {
            let seat = l.rng.range(0.40, 0.48);
            let back = l.rng.range(0.75, 0.9);
            l.add(
                Category::Furniture,
                l.rect(c, half, turn),
                Profile::Block { top_m: seat },
            );
            // The back: the rectangle's outer 0.2 m along its v axis.
            let (s, co) = turn.sin_cos();
            let off = half.1 - 0.1 * k;
            let bc = (c.0 - off * s, c.1 + off * co);
            l.add(
                Category::Furniture,
                l.rect(bc, (half.0, 0.1 * k), turn),
                Profile::Block { top_m: back },
            );
        } else {
            let top = l.rng.range(0.45, 0.9);
            l.add(
                Category::Furniture,
                l.rect(c, half, turn),
                Profile::Block { top_m: top },
            );
        }
    }
}

/// One to three boxes.
fn indoor_boxes(l: &mut Layout, room: &Room) {
    let boxes = 1 + usize::from(l.rng.chance(0.5)) + usize::from(l.rng.chance(0.25));
    for _ in 0..boxes {
        let half = (l.rng.range(0.1, 0.3), l.rng.range(0.1, 0.3));
        let top = l.rng.range(0.1, 0.5);
        let turn = l.rng.range(-PI, PI);
        let r = half.0.hypot(half.1);
        if let Some((c, k)) = room.place(l, r) {
            l.take(c, r * k);
            let shape = l.rect(c, (half.0 * k, half.1 * k), turn);
            l.add(Category::Box, shape, Profile::Block { top_m: top });
        }
    }
}

/// One or two cables (polylines of three segments) on the floor, clear of the stairs; the
/// furniture and boxes placed later keep clear of their middle only, so may stand on an end.
fn indoor_cables(l: &mut Layout, room: &Room) {
    let cables = 1 + usize::from(l.rng.chance(0.5));
    for _ in 0..cables {
        let radius = l.rng.range(0.004, 0.006);
        let (len, mut heading) = (l.rng.range(0.25, 0.4), l.rng.range(-PI, PI));
        let mut turns = [0.0; 3];
        for t in &mut turns {
            *t = heading;
            heading += l.rng.range(-0.8, 0.8);
        }
        let r = 1.5 * len;
        let Some((c, k)) = room.place(l, r) else {
            continue;
        };
        l.take(c, 0.5 * r * k);
        let len = len * k;
        let mut p = (
            c.0 - 1.5 * len * turns[1].cos(),
            c.1 - 1.5 * len * turns[1].sin(),
        );
        let mut points = vec![l.world(p.0, p.1)];
        for h in turns {
            p = (p.0 + len * h.cos(), p.1 + len * h.sin());
            points.push(l.world(p.0, p.1));
        }
        let shape = Shape::Path {
            points,
            radius_m: radius,
        };
        l.add(Category::Cable, shape, Profile::Round);
    }
}
