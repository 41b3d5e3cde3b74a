//! The ground's surfaces: the terrain categories (natural, indoor and urban), the Voronoi
//! regions they fill, and the height of each surface at a point. Both the terrain's layout
//! (`terrain.rs`) and the objects placed over it (`objects.rs`) read these.

use serde::{Deserialize, Serialize};

use super::noise;
/// Terrain categories; the value is the semantic label written with each frame (0 = void).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
#[derive(strum::VariantArray, strum::IntoStaticStr)]
#[strum(serialize_all = "snake_case")]
pub enum Category {
    /// Flat paving with fine texture.
    Pavement = 1,
    /// Soft small bumps (±6 mm).
    Grass = 2,
    /// Stones of 1–3 cm on a fine base.
    Gravel = 3,
    /// Boulders of 5–25 cm on soil.
    Rocks = 4,
    /// Smooth undulation (±4 cm) with ripples.
    Sand = 5,
    /// Planar steps of 5–20 cm (one step: a curb); indoors, flights of 3–4 risers up or down.
    Stairs = 6,
    /// Indoor floor: ceramic tiles of 20–60 cm, grout joints 12 mm wide and 0.4 mm deep.
    Tile = 7,
    /// Indoor floor: planks 10–20 cm wide, 0.8–1.5 m long, joints 0.3 mm deep.
    Wood = 8,
    /// Indoor floor or rug: pile of ±0.2 mm.
    Carpet = 9,
    /// Walls: vertical faces 2.4–2.7 m high, 10–15 cm thick.
    Wall = 10,
    /// Door sills: 1–3 cm high across a doorway.
    Sill = 11,
    /// Cables on the floor: round, 8–12 mm across.
    Cable = 12,
    /// Boxes: 20–60 cm sides, 10–50 cm high.
    Box = 13,
    /// Furniture-like blocks: sofas (seat and back) and cabinets, 0.4–0.9 m high.
    Furniture = 14,
    /// Road: asphalt, 0.3 mm aggregate relief on a ±2 mm undulation.
    Asphalt = 15,
    /// Sidewalk: block paving of 10×20 cm in stretcher bond, joints 0.6 mm deep.
    Paving = 16,
    /// Curb stones: 12–18 cm wide, standing 10–15 cm above the road.
    Curb = 17,
    /// Kerb ramps: the sidewalk lowered to the road with flared sides.
    KerbRamp = 18,
    /// Drains: grates recessed 1–2 cm into the road, with 4–6 cm deep slots.
    Drain = 19,
    /// Posts (bollards): 5–10 cm in radius, 0.6–1.0 m high.
    Post = 20,
}

impl Category {
    /// The paper's six natural categories, in label order.
    pub const NATURAL: [Category; 6] = [
        Category::Pavement,
        Category::Grass,
        Category::Gravel,
        Category::Rocks,
        Category::Sand,
        Category::Stairs,
    ];

    /// Indoor categories: floors, walls, sills, cables, boxes, furniture and stairs.
    pub const INDOOR: [Category; 9] = [
        Category::Tile,
        Category::Wood,
        Category::Carpet,
        Category::Wall,
        Category::Sill,
        Category::Cable,
        Category::Box,
        Category::Furniture,
        Category::Stairs,
    ];

    /// Urban categories: road, sidewalk, curbs, kerb ramps, drains and posts.
    pub const URBAN: [Category; 6] = [
        Category::Asphalt,
        Category::Paving,
        Category::Curb,
        Category::KerbRamp,
        Category::Drain,
        Category::Post,
    ];

    /// All categories, in label order (labels 1–20).
    pub const ALL: &'static [Category] = <Category as strum::VariantArray>::VARIANTS;

    /// The semantic label.
    pub fn label(self) -> u8 {
        self as u8
    }

    /// Lower-case name (`kerb_ramp`), as in the dataset's JSON.
    pub fn name(self) -> &'static str {
        self.into()
    }
}

/// Steps of a stairs region: height rises by `riser_m` every `tread_m` along `dir`, from
/// `start_m` (measured from the region's seed point), `steps` times.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Steps {
    /// Unit direction of ascent in the ground plane.
    pub dir: (f64, f64),
    /// Where the first riser stands, metres along `dir` from the seed point.
    pub start_m: f64,
    /// Step depth, metres.
    pub tread_m: f64,
    /// Step height, metres (0.05–0.20).
    pub riser_m: f64,
    /// Number of risers (1: a curb).
    pub steps: u32,
}

/// One Voronoi region of the ground.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Region {
    /// Seed point (x, y), metres.
    pub centre: (f64, f64),
    /// Its category.
    pub category: Category,
    /// Noise seed of its geometry and texture.
    pub seed: u64,
    /// Steps, for stairs.
    pub steps: Option<Steps>,
}

/// Height of `region`'s geometry at `(x, y)`, metres.
pub fn region_height(region: &Region, x: f64, y: f64) -> f64 {
    let s = region.seed;
    match region.category {
        Category::Pavement => 0.0,
        Category::Grass => 0.006 * noise::fbm(s, x, y, 0.15, 3),
        Category::Gravel => gravel(s, x, y),
        Category::Rocks => 0.015 * noise::fbm(s, x, y, 0.8, 3) + boulder(s, x, y),
        Category::Sand => {
            0.04 * noise::fbm(s, x, y, 1.5, 2)
                + 0.002 * (x * 40.0 + 3.0 * noise::value(s ^ 1, x, y)).sin()
        }
        Category::Stairs => region
            .steps
            .map_or(0.0, |st| stairs(&st, region.centre, x, y)),
        other => surface_height(other, s, x, y),
    }
}

/// Relief of the indoor and urban ground materials at `(u, v)` in the material's own frame
/// (metres; 0 for the flat surfaces of walls, boxes and the like).
pub fn surface_height(category: Category, seed: u64, u: f64, v: f64) -> f64 {
    match category {
        // Joints and pile slope by less than the spec's 10° segment angle, so that flat floor
        // of any material stays one segment and reads near zero.
        Category::Tile => {
            let size = tile_size_m(seed);
            groove(grid_joint_distance(u, v, size), 0.006, 0.0004)
        }
        Category::Wood => {
            let (width, length) = plank_m(seed);
            let row = (v / width).floor();
            let shift = noise::lattice(seed ^ 0x3D, row as i64, 0) * length;
            let across = joint_distance(v, width);
            let along = joint_distance(u + shift, length);
            groove(across.min(along), 0.005, 0.0003)
        }
        Category::Carpet => 0.0002 * noise::value(seed ^ 0xCA, u * 100.0, v * 100.0),
        Category::Asphalt => {
            0.0003 * noise::fbm(seed ^ 0xA5, u, v, 0.02, 2)
                + 0.002 * noise::fbm(seed ^ 0xA6, u, v, 0.8, 2)
        }
        Category::Paving => {
            groove(paver_joint_distance(u, v), 0.008, 0.0006)
                + 0.0015 * noise::fbm(seed ^ 0x9A, u, v, 0.6, 2)
        }
        _ => 0.0,
    }
}

/// Side of the square tiles of a tile floor: 20–60 cm in steps of 10 cm.
pub(crate) fn tile_size_m(seed: u64) -> f64 {
    0.2 + 0.1 * (noise::lattice(seed ^ 0x71, 0, 0) * 5.0).floor()
}

/// Width (10–20 cm) and length (0.8–1.5 m) of the planks of a wood floor.
pub(crate) fn plank_m(seed: u64) -> (f64, f64) {
    (
        0.10 + 0.10 * noise::lattice(seed ^ 0x3B, 0, 0),
        0.8 + 0.7 * noise::lattice(seed ^ 0x3C, 0, 0),
    )
}

/// Distance from `t` to the nearest multiple of `period`.
pub(crate) fn joint_distance(t: f64, period: f64) -> f64 {
    let f = (t / period).rem_euclid(1.0);
    f.min(1.0 - f) * period
}

/// Distance to the nearer of the two joint lines of a square grid of side `size`.
fn grid_joint_distance(u: f64, v: f64, size: f64) -> f64 {
    joint_distance(u, size).min(joint_distance(v, size))
}

/// A rounded groove `depth_m` deep and `2·half_m` wide at distance `d` from its axis.
fn groove(d: f64, half_m: f64, depth_m: f64) -> f64 {
    -depth_m * (1.0 - (d / half_m).powi(2)).max(0.0)
}

/// The block (index along its row) and the row of a 10×20 cm paver in stretcher bond.
pub(crate) fn paver(u: f64, v: f64) -> (i64, i64) {
    let row = (v / 0.1).floor();
    let shift = if row.rem_euclid(2.0) == 0.0 { 0.0 } else { 0.1 };
    (((u + shift) / 0.2).floor() as i64, row as i64)
}

/// Distance to the nearest joint of 10×20 cm pavers in stretcher bond.
pub(crate) fn paver_joint_distance(u: f64, v: f64) -> f64 {
    let row = (v / 0.1).floor();
    let shift = if row.rem_euclid(2.0) == 0.0 { 0.0 } else { 0.1 };
    joint_distance(v, 0.1).min(joint_distance(u + shift, 0.2))
}

/// Stones: domes of radius 0.9–1.5 cm and height 1–3 cm on a 2 mm base texture.
fn gravel(seed: u64, x: f64, y: f64) -> f64 {
    let (d, r) = noise::worley(seed, x, y, 0.022);
    let radius = 0.009 + 0.006 * r;
    let top = 0.01 + 0.02 * noise::lattice(seed ^ 0x77, (r * 1e6) as i64, 0);
    let dome = if d < radius {
        top * (1.0 - (d / radius).powi(2)).sqrt()
    } else {
        0.0
    };
    dome + 0.001 * noise::value(seed ^ 3, x * 300.0, y * 300.0)
}

/// Boulders: half-ellipsoids of radius 12–30 cm and height 5–25 cm, about one per 0.6 m cell,
/// with 3 mm surface relief.
pub(crate) fn boulder(seed: u64, x: f64, y: f64) -> f64 {
    let (d, r) = noise::worley(seed ^ 0xB0, x, y, 0.6);
    let radius = 0.12 + 0.18 * r;
    let top = 0.05 + 0.20 * noise::lattice(seed ^ 0x99, (r * 1e6) as i64, 1);
    if d < radius {
        top * (1.0 - (d / radius).powi(2)).sqrt() + 0.003 * noise::fbm(seed ^ 5, x, y, 0.05, 2)
    } else {
        0.0
    }
}

fn stairs(st: &Steps, centre: (f64, f64), x: f64, y: f64) -> f64 {
    let along = (x - centre.0) * st.dir.0 + (y - centre.1) * st.dir.1 - st.start_m;
    let k = if along < 0.0 {
        0.0
    } else {
        ((along / st.tread_m).floor() + 1.0).min(f64::from(st.steps))
    };
    k * st.riser_m
}
