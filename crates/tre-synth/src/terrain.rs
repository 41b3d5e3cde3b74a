//! Procedural terrain: six natural categories with their own geometry (pavement, grass, gravel,
//! rocks, sand, stairs and curbs), laid out as Voronoi regions of the ground around the robot,
//! and the indoor and urban categories whose objects (`objects.rs`) are placed over them.

use serde::{Deserialize, Serialize};

use super::objects::Object;
use super::surface::{region_height, Category, Region, Steps};
use tre_core::geometry::hash::splitmix64;

/// The terrain of one scene.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Terrain {
    /// The regions; every ground point belongs to the one with the nearest centre.
    pub regions: Vec<Region>,
    /// Objects placed over the regions, in drawing order (indoor and urban scenes; none in
    /// natural ones).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub objects: Vec<Object>,
}

/// A stream of uniform numbers from a seed.
pub(crate) struct Rng(pub(crate) u64);

impl Rng {
    /// The next uniform number in [0, 1).
    pub(crate) fn next(&mut self) -> f64 {
        self.0 = splitmix64(self.0);
        (self.0 >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }

    /// A uniform number in [lo, hi).
    pub(crate) fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.next()
    }

    /// True with probability `p`.
    pub(crate) fn chance(&mut self, p: f64) -> bool {
        self.next() < p
    }
}

impl Terrain {
    /// A random terrain for scene `scene` of a dataset seeded with `seed`: 8 regions within
    /// `reach_m` of the robot (plus 4 beyond), with every category present among those 8.
    pub fn random(seed: u64, scene: u64, reach_m: f64) -> Self {
        let mut rng = Rng(splitmix64(seed ^ splitmix64(scene.wrapping_add(1))));
        let mut cats = Category::NATURAL.to_vec();
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
                    Category::NATURAL[(rng.next() * 6.0) as usize]
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
        Self {
            regions,
            objects: Vec::new(),
        }
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
            objects: Vec::new(),
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
        if self.objects.is_empty() {
            return region_height(self.region_at(x, y), x, y);
        }
        self.height_owner(x, y, 0.0).0
    }

    /// Terrain height at `(x, y)`, metres, and the index of the object whose surface it is
    /// (`None`: a region's). Objects are drawn in order, each over what lies below it, their
    /// edges blended over `edge_m` (the grid's cell; 0: hard edges).
    pub fn height_owner(&self, x: f64, y: f64, edge_m: f64) -> (f64, Option<usize>) {
        let mut h = region_height(self.region_at(x, y), x, y);
        let mut owner = None;
        for (k, o) in self.objects.iter().enumerate() {
            if let Some(z) = o.height_over(x, y, h, edge_m) {
                h = z;
                owner = Some(k);
            }
        }
        (h, owner)
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
