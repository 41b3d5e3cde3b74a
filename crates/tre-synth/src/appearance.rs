//! Appearance: material textures tied to each terrain category (natural, indoor and urban),
//! four lightings (with cast shadows) and five weathers, so that an RGB network can learn
//! geometry from shading.

use serde::{Deserialize, Serialize};

use super::noise;
use super::surface::{
    boulder, joint_distance, paver, paver_joint_distance, plank_m, tile_size_m, Category, Region,
};
use tre_core::geometry::Vec3;

/// Light of a frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Lighting {
    /// Sun 65° high.
    HighSun,
    /// Sun 12° high: long shadows.
    LowSun,
    /// Sky light only.
    Overcast,
    /// Sun at the horizon, dim sky, and a lamp on the robot.
    Dusk,
}

/// Weather of a frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Weather {
    /// Clear air.
    Clear,
    /// Grey fog, visibility about 6 m.
    Fog,
    /// Wet ground: darker, glossy.
    Rain,
    /// Snow on surfaces that face up.
    Snow,
    /// Brown dust haze, visibility about 9 m.
    Dust,
}

impl Lighting {
    /// All lightings.
    pub const ALL: [Lighting; 4] = [
        Lighting::HighSun,
        Lighting::LowSun,
        Lighting::Overcast,
        Lighting::Dusk,
    ];
}

impl Weather {
    /// All weathers.
    pub const ALL: [Weather; 5] = [
        Weather::Clear,
        Weather::Fog,
        Weather::Rain,
        Weather::Snow,
        Weather::Dust,
    ];
}

/// Conditions of one frame.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Conditions {
    /// Light.
    pub lighting: Lighting,
    /// Weather.
    pub weather: Weather,
    /// Sun azimuth, radians from +y towards +x.
    pub sun_azimuth_rad: f64,
}

/// A light source: direction to the sun (unit) or a point lamp position, and its colour.
#[derive(Debug, Clone, Copy)]
pub enum Light {
    /// Parallel light towards `dir`.
    Sun {
        /// Unit vector towards the sun.
        dir: Vec3,
        /// Colour × intensity.
        colour: [f64; 3],
    },
    /// A lamp at `pos`.
    Lamp {
        /// Position, world frame.
        pos: Vec3,
        /// Colour × intensity at 1 m.
        colour: [f64; 3],
    },
}

impl Conditions {
    /// The direct lights of these conditions, with the camera at `camera`.
    pub fn lights(&self, camera: &Vec3) -> Vec<Light> {
        let sun = |elev_deg: f64, colour| {
            let (e, a) = (elev_deg.to_radians(), self.sun_azimuth_rad);
            Light::Sun {
                dir: Vec3::new(a.sin() * e.cos(), a.cos() * e.cos(), e.sin()),
                colour,
            }
        };
        match self.lighting {
            Lighting::HighSun => vec![sun(65.0, [1.25, 1.2, 1.1])],
            Lighting::LowSun => vec![sun(12.0, [1.5, 1.2, 0.9])],
            Lighting::Overcast => vec![],
            Lighting::Dusk => vec![
                sun(3.0, [0.5, 0.28, 0.15]),
                Light::Lamp {
                    pos: camera + Vec3::new(0.0, 0.0, 0.15),
                    colour: [1.4, 1.3, 1.1],
                },
            ],
        }
    }

    /// Sky (ambient) light colour.
    pub fn sky(&self) -> [f64; 3] {
        match self.lighting {
            Lighting::HighSun => [0.25, 0.3, 0.4],
            Lighting::LowSun => [0.22, 0.25, 0.33],
            Lighting::Overcast => [0.7, 0.72, 0.75],
            Lighting::Dusk => [0.06, 0.06, 0.10],
        }
    }

    /// Haze colour and visibility (metres), if any.
    pub fn haze(&self) -> Option<([f64; 3], f64)> {
        match self.weather {
            Weather::Fog => Some(([0.72, 0.74, 0.76], 6.0)),
            Weather::Dust => Some(([0.62, 0.52, 0.38], 9.0)),
            _ => None,
        }
    }
}

/// The material colour (linear RGB) of `region` at world point `p` with upward normal `n`.
pub(crate) fn albedo(region: &Region, p: &Vec3, n: &Vec3, weather: Weather) -> [f64; 3] {
    let base = material(region, p);
    match weather {
        Weather::Rain => [base[0] * 0.5, base[1] * 0.52, base[2] * 0.58],
        Weather::Snow => {
            let cover = smoothstep(0.55, 0.85, n.z)
                * smoothstep(-0.3, 0.3, noise::fbm(region.seed ^ 9, p.x, p.y, 0.4, 3));
            mix(base, [0.92, 0.93, 0.96], cover)
        }
        Weather::Dust => mix(base, [0.55, 0.45, 0.32], 0.25),
        _ => base,
    }
}

fn material(region: &Region, p: &Vec3) -> [f64; 3] {
    let s = region.seed;
    let grain = |scale: f64, amp: f64| grain_at(s, p, scale, amp);
    match region.category {
        Category::Pavement => {
            let (u, v) = ((p.x / 0.5).fract().abs(), (p.y / 0.5).fract().abs());
            let joint = u < 0.02 || v < 0.02;
            let g = if joint {
                0.22
            } else {
                0.46 * grain(0.03, 0.25)
            };
            [g, g, g * 1.02]
        }
        Category::Grass => {
            let blades = noise::value(s ^ 0x33, p.x * 350.0, p.y * 90.0);
            let patch = smoothstep(-0.2, 0.6, noise::fbm(s ^ 0x34, p.x, p.y, 0.7, 2));
            let g = mix([0.16, 0.34, 0.08], [0.42, 0.40, 0.16], patch);
            scale(g, 0.8 + 0.35 * blades)
        }
        Category::Gravel => {
            let (d, r) = noise::worley(s, p.x, p.y, 0.022);
            let shade = if d < 0.009 + 0.006 * r { 1.0 } else { 0.45 };
            let tone = mix([0.52, 0.50, 0.46], [0.55, 0.44, 0.32], r);
            scale(tone, shade * grain(0.01, 0.15))
        }
        Category::Rocks => {
            if boulder(s, p.x, p.y) > 0.002 {
                scale([0.50, 0.50, 0.48], grain(0.05, 0.3))
            } else {
                scale([0.36, 0.27, 0.18], grain(0.08, 0.25))
            }
        }
        Category::Sand => scale([0.76, 0.66, 0.48], grain(0.02, 0.1)),
        Category::Stairs => scale([0.58, 0.57, 0.55], grain(0.04, 0.2)),
        other => built_material(other, s, p),
    }
}

/// One of `n` colours picked by `seed`.
fn pick(seed: u64, colours: &[[f64; 3]]) -> [f64; 3] {
    let k = (noise::lattice(seed ^ 0xC01, 0, 0) * colours.len() as f64) as usize;
    colours[k.min(colours.len() - 1)]
}

/// `1 + amp·fbm`: the material's grain at `p`, of feature size `scale` metres (seed `s`).
fn grain_at(s: u64, p: &Vec3, scale: f64, amp: f64) -> f64 {
    1.0 + amp * noise::fbm(s ^ 0x51, p.x, p.y, scale, 3)
}

/// Materials of the indoor and urban categories, at `p` in the material's own frame.
fn built_material(category: Category, s: u64, p: &Vec3) -> [f64; 3] {
    match category {
        Category::Tile | Category::Wood | Category::Carpet => floor_material(category, s, p),
        Category::Asphalt
        | Category::Paving
        | Category::Curb
        | Category::KerbRamp
        | Category::Drain
        | Category::Post => street_material(category, s, p),
        _ => indoor_object_material(category, s, p),
    }
}

/// Indoor floors: tiles with joints, wooden planks, carpet.
fn floor_material(category: Category, s: u64, p: &Vec3) -> [f64; 3] {
    let grain = |scale: f64, amp: f64| grain_at(s, p, scale, amp);
    match category {
        Category::Tile => {
            let size = tile_size_m(s);
            let (i, j) = ((p.x / size).floor() as i64, (p.y / size).floor() as i64);
            let joint = joint_distance(p.x, size).min(joint_distance(p.y, size)) < 0.004;
            let base = pick(
                s,
                &[[0.78, 0.76, 0.72], [0.45, 0.44, 0.43], [0.70, 0.60, 0.48]],
            );
            let tone = 0.94 + 0.12 * noise::lattice(s ^ 0x7A, i, j);
            if joint {
                scale(base, 0.55)
            } else {
                scale(base, tone * grain(0.05, 0.05))
            }
        }
        Category::Wood => {
            let (width, length) = plank_m(s);
            let row = (p.y / width).floor();
            let shift = noise::lattice(s ^ 0x3D, row as i64, 0) * length;
            let plank = ((p.x + shift) / length).floor() as i64;
            let tone = 0.8 + 0.4 * noise::lattice(s ^ 0x3F, plank, row as i64);
            let streak = 1.0 + 0.12 * noise::value(s ^ 0x40, p.x * 6.0, p.y * 250.0);
            let base = pick(
                s,
                &[[0.55, 0.38, 0.22], [0.70, 0.55, 0.36], [0.36, 0.24, 0.15]],
            );
            scale(base, tone * streak)
        }
        Category::Carpet => {
            let base = pick(
                s,
                &[[0.30, 0.32, 0.40], [0.45, 0.20, 0.18], [0.55, 0.50, 0.42]],
            );
            scale(
                base,
                0.9 + 0.2 * noise::value(s ^ 0xCB, p.x * 300.0, p.y * 300.0),
            )
        }
        _ => [0.5, 0.5, 0.5],
    }
}

/// Walls, sills, cables, boxes and furniture.
fn indoor_object_material(category: Category, s: u64, p: &Vec3) -> [f64; 3] {
    let grain = |scale: f64, amp: f64| grain_at(s, p, scale, amp);
    match category {
        Category::Wall => scale([0.80, 0.78, 0.74], grain(0.3, 0.04)),
        Category::Sill => pick(
            s,
            &[[0.55, 0.42, 0.28], [0.62, 0.62, 0.62], [0.40, 0.38, 0.36]],
        ),
        Category::Cable => pick(
            s,
            &[[0.03, 0.03, 0.03], [0.85, 0.85, 0.82], [0.15, 0.15, 0.35]],
        ),
        Category::Box => {
            let tape = p.y.abs() < 0.025;
            let base = [0.60, 0.45, 0.28];
            if tape {
                [0.70, 0.62, 0.48]
            } else {
                scale(base, grain(0.1, 0.06))
            }
        }
        Category::Furniture => scale(
            pick(
                s,
                &[[0.25, 0.28, 0.35], [0.50, 0.35, 0.22], [0.72, 0.70, 0.66]],
            ),
            grain(0.05, 0.08),
        ),
        _ => [0.5, 0.5, 0.5],
    }
}

/// Road, sidewalk paving, curb, kerb ramp, drain and posts.
fn street_material(category: Category, s: u64, p: &Vec3) -> [f64; 3] {
    let grain = |scale: f64, amp: f64| grain_at(s, p, scale, amp);
    match category {
        Category::Asphalt => {
            let speck = noise::value(s ^ 0xA7, p.x * 250.0, p.y * 250.0);
            scale([0.11, 0.11, 0.12], (1.0 + 0.35 * speck) * grain(0.5, 0.15))
        }
        Category::Paving => {
            let (block, row) = paver(p.x, p.y);
            let joint = paver_joint_distance(p.x, p.y) < 0.004;
            let base = pick(
                s,
                &[[0.55, 0.50, 0.46], [0.50, 0.32, 0.26], [0.42, 0.42, 0.44]],
            );
            let tone = 0.85 + 0.3 * noise::lattice(s ^ 0x9B, block, row);
            if joint {
                [0.30, 0.27, 0.22]
            } else {
                scale(base, tone * grain(0.03, 0.1))
            }
        }
        Category::Curb => scale([0.62, 0.62, 0.60], grain(0.02, 0.15)),
        Category::KerbRamp => scale([0.58, 0.57, 0.54], grain(0.03, 0.12)),
        Category::Drain => scale([0.13, 0.13, 0.14], grain(0.02, 0.2)),
        Category::Post => pick(
            s,
            &[[0.15, 0.15, 0.16], [0.50, 0.50, 0.52], [0.60, 0.45, 0.08]],
        ),
        _ => [0.5, 0.5, 0.5],
    }
}

/// Linear RGB radiance of a surface point: Lambert from each light (times its visibility) plus
/// hemispherical sky light, a wet sheen in rain, and haze by distance.
pub(crate) struct ShadeInput<'a> {
    /// Surface colour.
    pub albedo: [f64; 3],
    /// Unit upward normal (world).
    pub normal: Vec3,
    /// Surface point (world).
    pub point: Vec3,
    /// Unit vector from the point to the camera.
    pub to_camera: Vec3,
    /// Distance to the camera, metres.
    pub distance_m: f64,
    /// Direct lights.
    pub lights: &'a [Light],
    /// Visibility of each light (0: in shadow, 1: lit).
    pub visibility: &'a [f64],
    /// Frame conditions.
    pub conditions: &'a Conditions,
}

/// Shades one surface point.
pub(crate) fn shade(i: &ShadeInput<'_>) -> [f64; 3] {
    let sky = i.conditions.sky();
    let hemi = 0.55 + 0.45 * i.normal.z;
    let mut light = [sky[0] * hemi, sky[1] * hemi, sky[2] * hemi];
    let mut spec = 0.0;
    for (l, vis) in i.lights.iter().zip(i.visibility) {
        let (dir, colour, falloff) = match *l {
            Light::Sun { dir, colour } => (dir, colour, 1.0),
            Light::Lamp { pos, colour } => {
                let v = pos - i.point;
                let d2 = v.norm_squared().max(0.04);
                (v / d2.sqrt(), colour, 1.0 / d2)
            }
        };
        let lambert = i.normal.dot(&dir).max(0.0) * vis * falloff;
        for c in 0..3 {
            light[c] += colour[c] * lambert;
        }
        if i.conditions.weather == Weather::Rain {
            let h = (dir + i.to_camera).normalize();
            spec += 0.6 * i.normal.dot(&h).max(0.0).powi(60) * vis * falloff;
        }
    }
    let lit = [0, 1, 2].map(|c| i.albedo[c] * light[c] + spec);
    match i.conditions.haze() {
        Some((colour, vis_m)) => mix(lit, colour, 1.0 - (-i.distance_m / vis_m).exp()),
        None => lit,
    }
}

/// Radiance of the sky seen along unit direction `d` (world).
pub(crate) fn sky_radiance(d: &Vec3, conditions: &Conditions) -> [f64; 3] {
    let up = d.z.max(0.0);
    let sky = conditions.sky();
    let horizon = [sky[0] * 1.6 + 0.1, sky[1] * 1.5 + 0.1, sky[2] * 1.3 + 0.1];
    let c = mix(
        horizon,
        [sky[0] * 1.2, sky[1] * 1.3, sky[2] * 1.6],
        up.sqrt(),
    );
    match conditions.haze() {
        Some((colour, _)) => mix(c, colour, 0.85),
        None => c,
    }
}

/// Linear radiance to 8-bit sRGB (with exposure 1).
pub(crate) fn to_srgb8(c: [f64; 3]) -> [u8; 3] {
    c.map(|v| {
        let v = v.clamp(0.0, 1.0);
        let s = if v <= 0.003_130_8 {
            12.92 * v
        } else {
            1.055 * v.powf(1.0 / 2.4) - 0.055
        };
        (s * 255.0).round() as u8
    })
}

fn smoothstep(a: f64, b: f64, x: f64) -> f64 {
    let t = ((x - a) / (b - a)).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

fn mix(a: [f64; 3], b: [f64; 3], t: f64) -> [f64; 3] {
    [0, 1, 2].map(|c| a[c] + (b[c] - a[c]) * t)
}

fn scale(a: [f64; 3], k: f64) -> [f64; 3] {
    a.map(|v| v * k)
}
