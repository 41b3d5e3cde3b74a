//! Scene families of `tre synth --content`: the paper's natural terrain, indoor rooms (tile,
//! wood and carpet floors, walls with a doorway and its sill, cables, boxes, furniture-like
//! blocks, stairs up or down) and urban street edges (asphalt road, paved sidewalk, curb, kerb
//! ramp, drains, posts). Each layout is drawn from the dataset seed and the scene index.

use std::f64::consts::{FRAC_PI_2, PI};
use std::fmt;
use std::str::FromStr;

use serde::{Deserialize, Serialize};

use super::objects::{Object, Profile, Shape};
use super::terrain::{Category, Region, Rng, Terrain};
use tre_core::geometry::hash::splitmix64;

/// What the scenes of a dataset show (the switch of `tre synth --content`).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Content {
    /// The paper's six natural categories as Voronoi regions (the default; unchanged output).
    #[default]
    Natural,
    /// Rooms: floors, walls, a doorway with its sill, cables, boxes, furniture, stairs.
    Indoor,
    /// Street edges: road, sidewalk, curb, kerb ramp, drains, posts.
    Urban,
    /// Each scene draws one of the three above, uniformly.
    Mixed,
}

impl Content {
    /// Every content switch.
    pub const ALL: [Self; 4] = [Self::Natural, Self::Indoor, Self::Urban, Self::Mixed];

    /// The switch's name, as serde writes it.
    pub fn name(self) -> &'static str {
        match self {
            Self::Natural => "natural",
            Self::Indoor => "indoor",
            Self::Urban => "urban",
            Self::Mixed => "mixed",
        }
    }

    /// The names, comma-separated (for messages).
    pub fn names() -> String {
        Self::ALL.map(Self::name).join(", ")
    }

    /// True for the default, natural content (whose settings are left out of `dataset.json` so
    /// that natural datasets keep their bytes).
    pub fn is_natural(&self) -> bool {
        *self == Self::Natural
    }

    /// The family of scene `scene` of a dataset seeded with `seed`: this content itself, or for
    /// `mixed` one of natural, indoor and urban drawn from the seed and the scene.
    pub fn family(self, seed: u64, scene: u64) -> Self {
        if self != Self::Mixed {
            return self;
        }
        let h = splitmix64(splitmix64(seed ^ 0xC0_47E4) ^ scene.wrapping_mul(0x9E37_79B9));
        [Self::Natural, Self::Indoor, Self::Urban][(h % 3) as usize]
    }

    /// The labels a dataset of this content lists: the six natural ones for natural content
    /// (as before the other families existed), every label otherwise.
    pub fn labels(self) -> &'static [Category] {
        match self {
            Self::Natural => &Category::NATURAL,
            _ => &Category::ALL,
        }
    }

    /// The terrain of scene `scene` (a family, not `mixed`), with content within `reach_m` of
    /// the robot.
    pub fn terrain(self, seed: u64, scene: u64, reach_m: f64) -> Terrain {
        match self.family(seed, scene) {
            Self::Indoor => indoor(seed, scene, reach_m),
            Self::Urban => urban(seed, scene, reach_m),
            _ => Terrain::random(seed, scene, reach_m),
        }
    }
}

impl fmt::Display for Content {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for Content {
    type Err = String;

    /// A content switch by name (case does not matter).
    ///
    /// ```
    /// use tre_synth::content::Content;
    /// assert_eq!("Indoor".parse(), Ok(Content::Indoor));
    /// assert!("forest".parse::<Content>().unwrap_err().contains("urban"));
    /// ```
    fn from_str(s: &str) -> Result<Self, String> {
        let key = s.trim().to_ascii_lowercase();
        Self::ALL
            .into_iter()
            .find(|c| c.name() == key)
            .ok_or_else(|| format!("unknown content {s:?}: one of {}", Self::names()))
    }
}

/// Distance kept free around the robot (its own footprint), metres.
const ROBOT_CLEAR_M: f64 = 0.35;

/// A layout in progress: a frame turned by `angle` (a: across, b: ahead of the robot), the
/// distance within which object centres stand (so that the views see them), the objects so far
/// and the circles they take.
struct Layout {
    rng: Rng,
    angle: f64,
    near_m: f64,
    objects: Vec<Object>,
    taken: Vec<((f64, f64), f64)>,
}

impl Layout {
    /// A layout for content within `reach_m` (the views' farthest ground plus 0.5 m).
    fn new(seed: u64, scene: u64, salt: u64, reach_m: f64) -> Self {
        let mut rng = Rng(splitmix64(seed ^ salt ^ splitmix64(scene.wrapping_add(1))));
        let angle = rng.range(-0.45, 0.45);
        Self {
            rng,
            angle,
            near_m: (reach_m - 0.5).max(1.0),
            objects: Vec::new(),
            taken: Vec::new(),
        }
    }

    /// World point of frame coordinates (a across, b ahead).
    fn world(&self, a: f64, b: f64) -> (f64, f64) {
        let (s, c) = self.angle.sin_cos();
        (a * c - b * s, a * s + b * c)
    }

    fn seed(&mut self) -> u64 {
        self.rng.0 = splitmix64(self.rng.0 ^ 0x5EED);
        self.rng.0
    }

    /// Adds an object of `category`.
    fn add(&mut self, category: Category, shape: Shape, profile: Profile) {
        let seed = self.seed();
        self.objects.push(Object {
            category,
            seed,
            shape,
            profile,
        });
    }

    /// A rectangle in frame coordinates: centre (a, b), half extents, its u axis turned by
    /// `turn` from the frame's across axis.
    fn rect(&self, (a, b): (f64, f64), half: (f64, f64), turn: f64) -> Shape {
        Shape::rect(self.world(a, b), half, self.angle + turn)
    }

    /// A free spot (frame coordinates) for a circle of radius `r` drawn by `spot`: clear of
    /// the robot and of the circles taken (circles may overlap by 30% of the smaller radius: they
    /// bound rectangles loosely), within `fits(spot, radius)`. Tries 50 draws, then
    /// 50 at each smaller scale (0.85, 0.7, 0.55) of the object; returns the spot and the scale.
    fn place(
        &mut self,
        r: f64,
        mut spot: impl FnMut(&mut Rng) -> (f64, f64),
        fits: impl Fn((f64, f64), f64) -> bool,
    ) -> Option<((f64, f64), f64)> {
        for scale in [1.0, 0.85, 0.7, 0.55] {
            let r = r * scale;
            for _ in 0..50 {
                let (a, b) = spot(&mut self.rng);
                let w = self.world(a, b);
                let d = w.0.hypot(w.1);
                let clear = d >= r + ROBOT_CLEAR_M
                    && d <= self.near_m
                    && self
                        .taken
                        .iter()
                        .all(|(c, rc)| (c.0 - w.0).hypot(c.1 - w.1) >= r + rc - 0.3 * r.min(*rc));
                if clear && fits((a, b), r) {
                    return Some(((a, b), scale));
                }
            }
        }
        None
    }

    /// Marks a circle (frame coordinates) as taken.
    fn take(&mut self, (a, b): (f64, f64), r: f64) {
        let w = self.world(a, b);
        self.taken.push((w, r));
    }

    fn into_terrain(self, category: Category, seed: u64) -> Terrain {
        Terrain {
            regions: vec![Region {
                centre: (0.0, 0.0),
                category,
                seed,
                steps: None,
            }],
            objects: self.objects,
        }
    }
}

/// Far enough to cover any sampled grid, metres.
const FAR_M: f64 = 30.0;

/// The room: back wall `depth` ahead (thickness, height), a doorway in it, a side wall.
struct Room {
    depth: f64,
    wall_m: f64,
    side: Option<f64>,
}

/// An indoor scene: a room whose back wall stands 0.75–0.95 × (`reach_m` − 0.5 m) ahead (at
/// least 1 m)
/// with a doorway and its sill; floors of tile, wood and carpet (the room split in two, the room
/// beyond the third, sometimes a rug); a flight of stairs up or down; furniture-like blocks,
/// boxes and cables. Everything stands in the robot's half-plane of view.
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
    let spot = l.place(r, room_spot(room.depth), |c, r| in_room(room, c, r));
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
        if let Some((c, k)) = l.place(r, room_spot(room.depth), |c, r| in_room(room, c, r)) {
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
        let Some((c, k)) = l.place(r, room_spot(room.depth), |c, r| in_room(room, c, r)) else {
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
        if let Some((c, k)) = l.place(r, room_spot(room.depth), |c, r| in_room(room, c, r)) {
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
        let Some((c, k)) = l.place(r, room_spot(room.depth), |c, r| in_room(room, c, r)) else {
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
