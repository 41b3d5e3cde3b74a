//! Procedural terrain: six categories with their own geometry (pavement, grass, gravel, rocks,
//! sand, stairs and curbs), laid out as Voronoi regions of the ground around the robot.

use serde::{Deserialize, Serialize};

use super::noise;
use crate::geometry::hash::splitmix64;

/// Terrain categories; the value is the semantic label written with each frame (0 = void).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
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
    /// Planar steps of 5–20 cm (one step: a curb).
    Stairs = 6,
}

impl Category {
    /// All categories, in label order.
    pub const ALL: [Category; 6] = [
        Category::Pavement,
        Category::Grass,
        Category::Gravel,
        Category::Rocks,
        Category::Sand,
        Category::Stairs,
    ];

    /// The semantic label.
    pub fn label(self) -> u8 {
        self as u8
    }

    /// Lower-case name.
    pub fn name(self) -> &'static str {
        match self {
            Category::Pavement => "pavement",
            Category::Grass => "grass",
            Category::Gravel => "gravel",
            Category::Rocks => "rocks",
            Category::Sand => "sand",
            Category::Stairs => "stairs",
        }
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

/// The terrain of one scene.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Terrain {
    /// The regions; every ground point belongs to the one with the nearest centre.
    pub regions: Vec<Region>,
}

/// A stream of uniform numbers from a seed.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> f64 {
        self.0 = splitmix64(self.0);
        (self.0 >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }

    fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.next()
    }
}

impl Terrain {
    /// A random terrain for scene `scene` of a dataset seeded with `seed`: 8 regions within
    /// `reach_m` of the robot (plus 4 beyond), with every category present among those 8.
    pub fn random(seed: u64, scene: u64, reach_m: f64) -> Self {
        let mut rng = Rng(splitmix64(seed ^ splitmix64(scene.wrapping_add(1))));
        let mut cats = Category::ALL.to_vec();
        for i in (1..cats.len()).rev() {
            cats.swap(i, (rng.next() * (i + 1) as f64) as usize);
        }
        let regions = (0..12)
            .map(|i| {
                let r = if i < 8 {
                    reach_m * rng.next().sqrt()
                } else {
                    rng.range(reach_m, 2.5 * reach_m)
                };
                let a = rng.range(-100f64.to_radians(), 100f64.to_radians());
                let category = if i < 6 {
                    cats[i]
                } else {
                    Category::ALL[(rng.next() * 6.0) as usize]
                };
                let seed = splitmix64(rng.0 ^ i as u64);
                let steps = (category == Category::Stairs).then(|| random_steps(&mut rng));
                Region {
                    centre: (r * a.sin(), r * a.cos()),
                    category,
                    seed,
                    steps,
                }
            })
            .collect();
        Self { regions }
    }

    /// Ground of one category everywhere (for tests and calibration).
    pub fn uniform(category: Category, seed: u64) -> Self {
        let steps = (category == Category::Stairs).then_some(Steps {
            dir: (0.0, 1.0),
            start_m: 0.8,
            tread_m: 0.35,
            riser_m: 0.10,
            steps: 3,
        });
        Self {
            regions: vec![Region {
                centre: (0.0, 0.0),
                category,
                seed,
                steps,
            }],
        }
    }

    /// The region that owns ground point `(x, y)`.
    pub fn region_at(&self, x: f64, y: f64) -> &Region {
        self.regions
            .iter()
            .min_by(|a, b| dist2(a.centre, (x, y)).total_cmp(&dist2(b.centre, (x, y))))
            .expect("a terrain has regions; this is a bug")
    }

    /// Terrain height at `(x, y)`, metres.
    pub fn height(&self, x: f64, y: f64) -> f64 {
        region_height(self.region_at(x, y), x, y)
    }
}

fn dist2(a: (f64, f64), b: (f64, f64)) -> f64 {
    (a.0 - b.0).powi(2) + (a.1 - b.1).powi(2)
}

fn random_steps(rng: &mut Rng) -> Steps {
    let a = rng.range(0.0, std::f64::consts::TAU);
    let steps = if rng.next() < 0.4 {
        1
    } else {
        2 + (rng.next() * 3.0) as u32
    };
    Steps {
        dir: (a.cos(), a.sin()),
        start_m: rng.range(-0.3, 0.3),
        tread_m: rng.range(0.28, 0.45),
        riser_m: rng.range(0.05, 0.20),
        steps,
    }
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
    }
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
