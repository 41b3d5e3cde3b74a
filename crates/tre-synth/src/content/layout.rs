//! A layout in progress, shared by the indoor and urban families: a frame turned from the
//! robot's, and objects placed in it clear of the robot and of each other.

use crate::objects::{Object, Profile, Shape};
use crate::surface::{Category, Region};
use crate::terrain::{Rng, Terrain};
use tre_core::geometry::hash::splitmix64;

/// Distance kept free around the robot (its own footprint), metres.
pub(super) const ROBOT_CLEAR_M: f64 = 0.35;

/// A layout in progress: a frame turned by `angle` (a: across, b: ahead of the robot), the
/// distance within which object centres stand (so that the views see them), the objects so far
/// and the circles they take.
pub(super) struct Layout {
    /// The layout's random draws.
    pub rng: Rng,
    /// Turn of the frame from the world's axes, radians.
    pub angle: f64,
    /// Distance within which object centres stand, metres.
    pub near_m: f64,
    /// The objects so far, in drawing order.
    pub objects: Vec<Object>,
    /// The circles taken (world centre, radius).
    pub taken: Vec<((f64, f64), f64)>,
}

impl Layout {
    /// A layout for content within `reach_m` (the views' farthest ground plus 0.5 m).
    pub(super) fn new(seed: u64, scene: u64, salt: u64, reach_m: f64) -> Self {
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
    pub(super) fn world(&self, a: f64, b: f64) -> (f64, f64) {
        let (s, c) = self.angle.sin_cos();
        (a * c - b * s, a * s + b * c)
    }

    /// A fresh seed for the next object.
    fn seed(&mut self) -> u64 {
        self.rng.0 = splitmix64(self.rng.0 ^ 0x5EED);
        self.rng.0
    }

    /// Adds an object of `category`.
    pub(super) fn add(&mut self, category: Category, shape: Shape, profile: Profile) {
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
    pub(super) fn rect(&self, (a, b): (f64, f64), half: (f64, f64), turn: f64) -> Shape {
        Shape::rect(self.world(a, b), half, self.angle + turn)
    }

    /// A free spot (frame coordinates) for a circle of radius `r` drawn by `spot`: clear of
    /// the robot and of the circles taken (circles may overlap by 30% of the smaller radius: they
    /// bound rectangles loosely), within `fits(spot, radius)`. Tries 50 draws, then
    /// 50 at each smaller scale (0.85, 0.7, 0.55) of the object; returns the spot and the scale.
    pub(super) fn place(
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
    pub(super) fn take(&mut self, (a, b): (f64, f64), r: f64) {
        let w = self.world(a, b);
        self.taken.push((w, r));
    }

    /// The terrain: one region of `category` under the objects.
    pub(super) fn into_terrain(self, category: Category, seed: u64) -> Terrain {
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
pub(super) const FAR_M: f64 = 30.0;
