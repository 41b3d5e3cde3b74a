//! Objects placed over the ground of indoor and urban scenes: a footprint (rectangle, disc or
//! path) and a height profile each (floors, rugs, blocks, cables, stair flights, kerb ramps,
//! drain grates). The terrain draws them in order, each over what lies below it, so every
//! object is its own surface with its own semantic label.

use serde::{Deserialize, Serialize};

use super::surface::{surface_height, Category, Region};
use tre_core::geometry::Vec3;

/// The footprint of an object on the ground plane (metres, world x and y).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", tag = "shape")]
pub enum Shape {
    /// A rectangle: centre, half extents along its own axes u and v, and the angle of u from +x.
    Rect {
        /// Centre.
        centre: (f64, f64),
        /// Half extents along u and v.
        half_m: (f64, f64),
        /// Angle of the u axis from +x towards +y.
        angle_rad: f64,
    },
    /// A disc.
    Disc {
        /// Centre.
        centre: (f64, f64),
        /// Radius.
        radius_m: f64,
    },
    /// A tube of radius `radius_m` around a polyline (a cable).
    Path {
        /// The polyline's points.
        points: Vec<(f64, f64)>,
        /// Half the tube's width.
        radius_m: f64,
    },
}

/// Where a ground point lies in a shape: coordinates in the shape's frame (from its centre, or
/// from a path's first point) and the distance to its axis (discs and paths; 0 for rectangles).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Local {
    /// Along the shape's first axis, metres.
    pub u: f64,
    /// Along its second axis, metres.
    pub v: f64,
    /// Distance to the centre or the polyline, metres.
    pub d: f64,
}

impl Shape {
    /// A rectangle from its centre, half extents and angle.
    pub fn rect(centre: (f64, f64), half_m: (f64, f64), angle_rad: f64) -> Self {
        Self::Rect {
            centre,
            half_m,
            angle_rad,
        }
    }

    /// The shape's reference point (a path's first point).
    pub fn centre(&self) -> (f64, f64) {
        match self {
            Self::Rect { centre, .. } | Self::Disc { centre, .. } => *centre,
            Self::Path { points, .. } => points.first().copied().unwrap_or((0.0, 0.0)),
        }
    }

    /// The point's place in the shape, if inside.
    ///
    /// ```
    /// use tre_synth::objects::Shape;
    /// let r = Shape::rect((1.0, 0.0), (0.5, 0.2), std::f64::consts::FRAC_PI_2);
    /// let l = r.locate(1.0, 0.4).unwrap(); // 0.4 m along the rectangle's u axis (+y)
    /// assert!((l.u - 0.4).abs() < 1e-12 && l.v.abs() < 1e-12);
    /// assert!(r.locate(1.3, 0.0).is_none());
    /// ```
    pub fn locate(&self, x: f64, y: f64) -> Option<Local> {
        self.locate_within(x, y, 0.0)
            .and_then(|(l, inside)| (inside >= 0.0).then_some(l))
    }

    /// The point's place in the shape and its signed distance inside the outline (negative
    /// outside), if it lies inside or within `margin_m` of the outline.
    pub fn locate_within(&self, x: f64, y: f64, margin_m: f64) -> Option<(Local, f64)> {
        match self {
            Self::Rect {
                centre,
                half_m: (a, b),
                angle_rad,
            } => {
                let (dx, dy) = (x - centre.0, y - centre.1);
                let reach = a + b + margin_m;
                if dx.abs() > reach || dy.abs() > reach {
                    return None;
                }
                let (s, c) = angle_rad.sin_cos();
                let (u, v) = (dx * c + dy * s, dy * c - dx * s);
                let inside = (a - u.abs()).min(b - v.abs());
                (inside >= -margin_m).then_some((Local { u, v, d: 0.0 }, inside))
            }
            Self::Disc { centre, radius_m } => {
                let (dx, dy) = (x - centre.0, y - centre.1);
                let d = dx.hypot(dy);
                let inside = radius_m - d;
                (inside >= -margin_m).then_some((Local { u: dx, v: dy, d }, inside))
            }
            Self::Path { points, radius_m } => {
                let d = points
                    .windows(2)
                    .map(|w| segment_distance(w[0], w[1], (x, y)))
                    .fold(f64::INFINITY, f64::min);
                let o = self.centre();
                let inside = radius_m - d;
                let l = Local {
                    u: x - o.0,
                    v: y - o.1,
                    d: d.min(*radius_m),
                };
                (inside >= -margin_m).then_some((l, inside))
            }
        }
    }

    /// Half extents of a rectangle; (radius, radius) otherwise.
    fn half(&self) -> (f64, f64) {
        match self {
            Self::Rect { half_m, .. } => *half_m,
            Self::Disc { radius_m, .. } | Self::Path { radius_m, .. } => (*radius_m, *radius_m),
        }
    }

    /// Angle of the shape's u axis from +x (0 for discs and paths).
    fn angle(&self) -> f64 {
        match self {
            Self::Rect { angle_rad, .. } => *angle_rad,
            _ => 0.0,
        }
    }
}

/// Distance from `p` to the segment `a`–`b`.
fn segment_distance(a: (f64, f64), b: (f64, f64), p: (f64, f64)) -> f64 {
    let (ex, ey) = (b.0 - a.0, b.1 - a.1);
    let len2 = ex * ex + ey * ey;
    let t = if len2 > 0.0 {
        (((p.0 - a.0) * ex + (p.1 - a.1) * ey) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (p.0 - a.0 - t * ex).hypot(p.1 - a.1 - t * ey)
}

/// The height of an object over its footprint (metres, z up; the robot stands at 0).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", tag = "profile")]
pub enum Profile {
    /// A floor at `base_m` with its material's relief (tile joints, planks, pile, aggregate,
    /// pavers), in the rectangle's frame.
    Floor {
        /// Level of the floor.
        base_m: f64,
    },
    /// A layer `dz_m` thick over what lies below, with its material's relief (a rug).
    Layer {
        /// Thickness.
        dz_m: f64,
    },
    /// A flat top at `top_m` (walls, sills, boxes, furniture, curbs, posts).
    Block {
        /// Level of the top.
        top_m: f64,
    },
    /// A round cable lying on what lies below: its top is r + √(r² − d²) above it, r the
    /// path's radius.
    Round,
    /// A flight of stairs along the rectangle's u axis from its −u edge: `steps` risers of
    /// `riser_m` (negative: down) every `tread_m`, then a landing to the +u edge.
    Flight {
        /// Level before the first riser.
        base_m: f64,
        /// Riser height, metres (negative for stairs down).
        riser_m: f64,
        /// Tread depth.
        tread_m: f64,
        /// Number of risers.
        steps: u32,
    },
    /// A kerb ramp: from `low_m` at the rectangle's −u edge (the curb line) up to `high_m` at its
    /// +u edge, its sides (the outer `flare_m` of v) flared up to `high_m`.
    Ramp {
        /// Level at the curb line (the road).
        low_m: f64,
        /// Level of the sidewalk.
        high_m: f64,
        /// Width of each flared side.
        flare_m: f64,
    },
    /// A drain: a frame `frame_m` wide at `top_m`, inside it a grate `recess_m` lower whose
    /// slots (`slot_m` wide, every `pitch_m` along u) go `slot_depth_m` deeper.
    Grate {
        /// Level of the frame (the road).
        top_m: f64,
        /// Depth of the grate below the frame.
        recess_m: f64,
        /// Width of the frame.
        frame_m: f64,
        /// Width of a slot.
        slot_m: f64,
        /// Slot spacing.
        pitch_m: f64,
        /// Depth of the slots below the grate.
        slot_depth_m: f64,
    },
}

/// An object: a labelled footprint with a height profile.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Object {
    /// Its category (the semantic label of its surface).
    pub category: Category,
    /// Seed of its material's relief and texture.
    pub seed: u64,
    /// Footprint.
    pub shape: Shape,
    /// Height over the footprint.
    pub profile: Profile,
}

impl Object {
    /// The object's height at `(x, y)` drawn over `below_m` (the height of what lies below),
    /// if the object takes that point. Its outline and the risers of a flight are blended over
    /// `edge_m` (the grid's cell), so that a face at any angle is a plane, not a staircase of
    /// cells; 0 gives hard edges.
    pub fn height_over(&self, x: f64, y: f64, below_m: f64, edge_m: f64) -> Option<f64> {
        let (l, inside) = self.shape.locate_within(x, y, edge_m / 2.0)?;
        let cover = if edge_m > 0.0 {
            (0.5 + inside / edge_m).clamp(0.0, 1.0)
        } else {
            1.0
        };
        if cover <= 0.0 {
            return None;
        }
        let z = self.profile_height(&l, below_m, edge_m)?;
        Some(below_m + cover * (z - below_m))
    }

    /// The profile's height at a point of the footprint.
    fn profile_height(&self, l: &Local, below_m: f64, edge_m: f64) -> Option<f64> {
        let (a, b) = self.shape.half();
        let relief = || surface_height(self.category, self.seed, l.u, l.v);
        match self.profile {
            Profile::Floor { base_m } => Some(base_m + relief()),
            Profile::Layer { dz_m } => Some(below_m + dz_m + relief()),
            Profile::Block { top_m } => Some(top_m),
            Profile::Round => {
                let r = a;
                Some(below_m + r + (r * r - l.d * l.d).max(0.0).sqrt())
            }
            Profile::Flight {
                base_m,
                riser_m,
                tread_m,
                steps,
            } => {
                // Riser k stands at k·tread from the −u edge; each after the first (the
                // outline's) is blended over edge_m.
                let along = l.u + a;
                let risen: f64 = (1..steps)
                    .map(|k| {
                        let past = along - f64::from(k) * tread_m;
                        if edge_m > 0.0 {
                            (0.5 + past / edge_m).clamp(0.0, 1.0)
                        } else {
                            f64::from(u8::from(past >= 0.0))
                        }
                    })
                    .sum();
                Some(base_m + (1.0 + risen) * riser_m)
            }
            Profile::Ramp {
                low_m,
                high_m,
                flare_m,
            } => {
                let run = (l.u + a) / (2.0 * a);
                let flare = (l.v.abs() - (b - flare_m)) / flare_m.max(1e-6);
                Some(low_m + (high_m - low_m) * run.max(flare).clamp(0.0, 1.0))
            }
            Profile::Grate {
                top_m,
                recess_m,
                frame_m,
                slot_m,
                pitch_m,
                slot_depth_m,
            } => {
                if a - l.u.abs() < frame_m || b - l.v.abs() < frame_m {
                    return Some(top_m);
                }
                let in_slot = (l.u + a - frame_m).rem_euclid(pitch_m) < slot_m;
                Some(top_m - recess_m - if in_slot { slot_depth_m } else { 0.0 })
            }
        }
    }

    /// The material of this object's surface at world point `p`: a region standing for it (its
    /// category and seed) and `p` in the object's own frame, for the appearance.
    pub fn surface(&self, p: &Vec3) -> (Region, Vec3) {
        let o = self.shape.centre();
        let (s, c) = self.shape.angle().sin_cos();
        let (dx, dy) = (p.x - o.0, p.y - o.1);
        let region = Region {
            centre: (0.0, 0.0),
            category: self.category,
            seed: self.seed,
            steps: None,
        };
        (region, Vec3::new(dx * c + dy * s, dy * c - dx * s, p.z))
    }

    /// A circle around the footprint (centre, radius), for placing objects apart.
    pub fn bounds(&self) -> ((f64, f64), f64) {
        match &self.shape {
            Shape::Rect { centre, half_m, .. } => (*centre, half_m.0.hypot(half_m.1)),
            Shape::Disc { centre, radius_m } => (*centre, *radius_m),
            Shape::Path { points, radius_m } => {
                let n = points.len().max(1) as f64;
                let c = points
                    .iter()
                    .fold((0.0, 0.0), |s, p| (s.0 + p.0 / n, s.1 + p.1 / n));
                let r = points
                    .iter()
                    .map(|p| (p.0 - c.0).hypot(p.1 - c.1))
                    .fold(0.0, f64::max);
                (c, r + radius_m)
            }
        }
    }
}
