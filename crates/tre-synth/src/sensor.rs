//! Depth-sensor models for synthetic frames: from exact depth to what a structured-light,
//! active-stereo, time-of-flight or spinning-LiDAR sensor would have measured (docs/synth.md).
//!
//! Every model keeps the noise of its [`SensorPreset`]: the depth error on a flat surface has
//! the standard deviation σ_z(z) of `tre_core::roughness::noise` (along the optical axis for the
//! triangulating sensors, along the ray for time of flight and LiDAR), quantisation included.
//! Holes are 0. Deterministic: the same input and seed give the same depth on any number of
//! threads.

use image::RgbImage;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use tre_core::geometry::hash::uniform;
use tre_core::geometry::{Grid, Intrinsics, Vec3};
use tre_core::roughness::noise::SensorPreset;

/// What a sensor model reads from a rendered frame.
pub struct SensorInput<'a> {
    /// Exact depth (camera z), metres; 0 where nothing is seen.
    pub depth_m: &'a Grid<f64>,
    /// Unit normals in the camera frame, towards the camera; NaN where none.
    pub normals_cam: &'a Grid<Vec3>,
    /// The frame's image (dark materials and texture are read from it).
    pub rgb: &'a RgbImage,
    /// Pinhole intrinsics of the frame.
    pub intrinsics: &'a Intrinsics,
}

/// A depth sensor's model parameters, as written to each frame's metadata. Lengths in metres,
/// `*_native_px` in pixels of the sensor's own depth image (scaled to the frame by
/// `fx / native_focal_px`), angles in degrees. A zero turns an effect off.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SensorModel {
    /// Which sensor (σ_z(z) comes from its preset).
    pub sensor: SensorPreset,
    /// Nearest usable range.
    pub min_range_m: f64,
    /// Farthest usable range.
    pub max_range_m: f64,
    /// Focal length of the sensor's own depth image.
    pub native_focal_px: f64,
    /// Projector–camera or stereo baseline (triangulating sensors).
    pub baseline_m: f64,
    /// Disparity quantisation step, native pixels.
    pub disparity_step_px: f64,
    /// Side of the correlation (matching) window, native pixels.
    pub correlation_native_px: f64,
    /// Share of the noise variance that is correlated over that window (the rest is white).
    pub correlated_share: f64,
    /// Dropouts start when the ray meets the surface this far from its normal…
    pub grazing_start_deg: f64,
    /// …and are certain from this angle on.
    pub grazing_end_deg: f64,
    /// Dropouts on dark material: certain at linear luminance 0, none from this value on.
    pub dark_luminance: f64,
    /// Holes where the local texture (mean absolute grey step, 0–1) is below this.
    pub min_texture: f64,
    /// Side of the square cells in which dropouts come as one blob, native pixels.
    pub dropout_cell_native_px: f64,
    /// Shadow holes where the projector (at +x, `baseline_m`) does not see the surface.
    pub projector_shadow: bool,
    /// Invalid band on the left, as wide as the disparity (stereo, left imager reference).
    pub left_band: bool,
    /// Edge fattening: foreground depth spreads this far into the background, native pixels.
    pub fatten_native_px: f64,
    /// Depth jump between neighbours that makes flying pixels.
    pub flying_jump_m: f64,
    /// Share of flying pixels the sensor's own filter invalidates (the rest keep a mixed depth).
    pub flying_invalid_share: f64,
    /// Multipath: range bias per unit of concavity (0 flat, 1 a closed corner).
    pub multipath_gain_m: f64,
    /// Multipath: largest bias.
    pub multipath_max_m: f64,
    /// LiDAR: rings spread over the image's vertical field of view (0: a dense sensor).
    pub lidar_rings: u32,
    /// LiDAR: azimuth step between returns of a ring.
    pub lidar_azimuth_step_deg: f64,
}

impl SensorModel {
    /// The model of a preset, with parameters from the sensors' datasheets and literature
    /// (sources in docs/synth.md).
    pub fn preset(sensor: SensorPreset) -> Self {
        let off = Self::off(sensor);
        match sensor {
            SensorPreset::KinectV1 => Self {
                min_range_m: 0.5,
                max_range_m: 4.5,
                native_focal_px: 580.0,
                baseline_m: 0.075,
                disparity_step_px: 0.125,
                correlation_native_px: 9.0,
                correlated_share: 0.9,
                grazing_start_deg: 75.0,
                grazing_end_deg: 88.0,
                dark_luminance: 0.02,
                dropout_cell_native_px: 4.0,
                projector_shadow: true,
                ..off
            },
            SensorPreset::RealsenseD435 => Self {
                min_range_m: 0.2,
                max_range_m: 10.0,
                native_focal_px: 447.0,
                baseline_m: 0.05,
                disparity_step_px: 1.0 / 32.0,
                correlation_native_px: 7.0,
                correlated_share: 0.8,
                grazing_start_deg: 80.0,
                grazing_end_deg: 89.0,
                min_texture: 0.0015,
                dropout_cell_native_px: 4.0,
                left_band: true,
                fatten_native_px: 3.0,
                ..off
            },
            SensorPreset::AzureKinect => Self {
                min_range_m: 0.5,
                max_range_m: 3.86,
                native_focal_px: 504.0,
                grazing_start_deg: 80.0,
                grazing_end_deg: 89.0,
                dark_luminance: 0.02,
                dropout_cell_native_px: 2.0,
                flying_jump_m: 0.05,
                flying_invalid_share: 0.5,
                multipath_gain_m: 0.03,
                multipath_max_m: 0.03,
                ..off
            },
            SensorPreset::Lidar => Self {
                min_range_m: 0.5,
                max_range_m: 120.0,
                lidar_rings: 64,
                lidar_azimuth_step_deg: 0.2,
                ..off
            },
            SensorPreset::Exact => off,
        }
    }

    /// Every effect off: exact depth within an unlimited range.
    fn off(sensor: SensorPreset) -> Self {
        Self {
            sensor,
            min_range_m: 0.0,
            max_range_m: f64::INFINITY,
            native_focal_px: 0.0,
            baseline_m: 0.0,
            disparity_step_px: 0.0,
            correlation_native_px: 0.0,
            correlated_share: 0.0,
            grazing_start_deg: 90.0,
            grazing_end_deg: 90.0,
            dark_luminance: 0.0,
            min_texture: 0.0,
            dropout_cell_native_px: 1.0,
            projector_shadow: false,
            left_band: false,
            fatten_native_px: 0.0,
            flying_jump_m: 0.0,
            flying_invalid_share: 0.0,
            multipath_gain_m: 0.0,
            multipath_max_m: 0.0,
            lidar_rings: 0,
            lidar_azimuth_step_deg: 0.0,
        }
    }

    /// Frame pixels per native pixel (1 when the model has no native image).
    fn scale(&self, k: &Intrinsics) -> f64 {
        if self.native_focal_px > 0.0 {
            k.fx_px / self.native_focal_px
        } else {
            1.0
        }
    }

    /// True for the sensors that triangulate (noise and quantisation in disparity).
    fn triangulates(&self) -> bool {
        self.baseline_m > 0.0 && self.native_focal_px > 0.0
    }
}

/// Independent random streams of one frame.
#[derive(Clone, Copy)]
enum Stream {
    White = 1,
    Correlated = 2,
    Dropout = 3,
    Flying = 4,
}

/// A standard normal number for pixel `i` of `stream` (Box–Muller on the counter hash).
fn normal(seed: u64, i: u64, stream: Stream) -> f64 {
    let u1 = uniform(seed, i, stream as u32, 0);
    let u2 = uniform(seed, i, stream as u32, 1);
    (-2.0 * (1.0 - u1).ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
}

/// The sensor depth (metres, 0 = no return) of `input` under `model`, seeded by `seed`.
pub fn simulate(model: &SensorModel, input: &SensorInput<'_>, seed: u64) -> Grid<f64> {
    let exact = input.depth_m;
    if model.sensor == SensorPreset::Exact {
        return exact.clone();
    }
    let scale = model.scale(input.intrinsics);
    let mut depth = if model.fatten_native_px > 0.0 {
        fatten(exact, (model.fatten_native_px * scale).round() as usize)
    } else {
        exact.clone()
    };
    let noise = noise_field(model, exact.size(), scale, seed);
    let flying = flying_mask(model, exact);
    let concavity = if model.multipath_gain_m > 0.0 {
        Some(concavity(input, scale))
    } else {
        None
    };
    let texture = (model.min_texture > 0.0).then(|| texture(input.rgb, 3));
    let lidar = (model.lidar_rings > 0).then(|| lidar_mask(model, input.intrinsics, exact.size()));
    let shadow = model
        .projector_shadow
        .then(|| projector_shadow(exact, input.intrinsics, model.baseline_m));
    let ctx = PixelContext {
        model,
        input,
        seed,
        scale,
        noise: &noise,
        flying: &flying,
        concavity: concavity.as_ref(),
        texture: texture.as_ref(),
        lidar: lidar.as_ref(),
        shadow: shadow.as_ref(),
    };
    let (w, _) = exact.size();
    depth
        .as_mut_slice()
        .par_chunks_mut(w.max(1))
        .enumerate()
        .for_each(|(y, row)| {
            for (x, z) in row.iter_mut().enumerate() {
                *z = ctx.pixel(x, y, *z);
            }
        });
    depth
}

/// The per-frame maps a pixel's measurement reads.
struct PixelContext<'a> {
    model: &'a SensorModel,
    input: &'a SensorInput<'a>,
    seed: u64,
    scale: f64,
    noise: &'a Grid<f64>,
    flying: &'a Grid<Option<f64>>,
    concavity: Option<&'a Grid<f64>>,
    texture: Option<&'a Grid<f64>>,
    lidar: Option<&'a Grid<bool>>,
    shadow: Option<&'a Grid<bool>>,
}

impl PixelContext<'_> {
    /// The measured depth of pixel (x, y) whose (possibly fattened) exact depth is `z`.
    fn pixel(&self, x: usize, y: usize, z: f64) -> f64 {
        let m = self.model;
        let k = self.input.intrinsics;
        if !(z > 0.0) || self.lidar.is_some_and(|l| !l[(x, y)]) {
            return 0.0;
        }
        let ray = k.back_project(x as f64, y as f64, 1.0);
        let range_per_z = ray.norm();
        // Triangulating sensors state their limits in depth, the others in range.
        let reach = if m.triangulates() { z } else { z * range_per_z };
        if reach < m.min_range_m || reach > m.max_range_m || self.shadow.is_some_and(|s| s[(x, y)])
        {
            return 0.0;
        }
        if m.left_band && (x as f64) < k.fx_px * m.baseline_m / z {
            return 0.0;
        }
        if self.drops(x, y, &ray) {
            return 0.0;
        }
        let i = (y * self.input.depth_m.width() + x) as u64;
        let mut z = z;
        if let Some(other) = self.flying[(x, y)] {
            if uniform(self.seed, i, Stream::Flying as u32, 0) < m.flying_invalid_share {
                return 0.0;
            }
            z += uniform(self.seed, i, Stream::Flying as u32, 1) * (other - z);
        }
        if m.triangulates() {
            return self.disparity_noise(z, self.noise[(x, y)]);
        }
        let bias = self.concavity.map_or(0.0, |c| {
            (m.multipath_gain_m * c[(x, y)]).min(m.multipath_max_m)
        });
        let r = z * range_per_z + bias + m.sensor.sigma_z_m(z) * self.noise[(x, y)];
        (r / range_per_z).max(0.0)
    }

    /// True where the surface returns nothing: grazing angle, dark material, low texture,
    /// drawn per dropout cell so that holes come as blobs.
    fn drops(&self, x: usize, y: usize, ray: &Vec3) -> bool {
        let m = self.model;
        let n = self.input.normals_cam[(x, y)];
        let mut p: f64 = 0.0;
        if n.x.is_finite() {
            let cos = (-n.dot(ray) / ray.norm()).abs().clamp(0.0, 1.0);
            p = ramp(
                cos.acos().to_degrees(),
                m.grazing_start_deg,
                m.grazing_end_deg,
            );
        }
        if m.dark_luminance > 0.0 {
            let l = linear_luminance(self.input.rgb.get_pixel(x as u32, y as u32).0);
            p = p.max(1.0 - ramp(l, 0.0, m.dark_luminance));
        }
        if self.texture.is_some_and(|t| t[(x, y)] < m.min_texture) {
            p = 1.0;
        }
        if p <= 0.0 {
            return false;
        }
        let cell = (m.dropout_cell_native_px * self.scale).round().max(1.0) as usize;
        let key = ((y / cell) as u64) << 32 | (x / cell) as u64;
        uniform(self.seed, key, Stream::Dropout as u32, 0) < p
    }

    /// Depth `z` measured through disparity: noise `unit_noise`·σ_c in disparity, then
    /// quantised to the sensor's step; σ_c keeps the total at the preset's σ_z.
    fn disparity_noise(&self, z: f64, unit_noise: f64) -> f64 {
        let m = self.model;
        let fb = m.native_focal_px * m.baseline_m;
        let d = fb / z;
        let sigma_total_px = m.sensor.sigma_z_m(z) * fb / (z * z);
        let q = m.disparity_step_px;
        let sigma_px = (sigma_total_px * sigma_total_px - q * q / 12.0)
            .max(0.0)
            .sqrt();
        let noisy = d + sigma_px * unit_noise;
        let quantised = if q > 0.0 {
            (noisy / q).round() * q
        } else {
            noisy
        };
        if quantised > 0.0 {
            fb / quantised
        } else {
            0.0
        }
    }
}

/// 0 below `a`, 1 above `b`, linear between (a step at `a` when `a ≥ b`).
fn ramp(v: f64, a: f64, b: f64) -> f64 {
    if b <= a {
        return if v >= a { 1.0 } else { 0.0 };
    }
    ((v - a) / (b - a)).clamp(0.0, 1.0)
}

/// Linear luminance (0–1) of an sRGB pixel.
fn linear_luminance([r, g, b]: [u8; 3]) -> f64 {
    let lin = |c: u8| {
        let c = f64::from(c) / 255.0;
        if c <= 0.04045 {
            c / 12.92
        } else {
            ((c + 0.055) / 1.055).powf(2.4)
        }
    };
    0.2126 * lin(r) + 0.7152 * lin(g) + 0.0722 * lin(b)
}

/// Unit-variance noise: a share `correlated_share` of the variance from white noise averaged
/// over a square window of the correlation size (a box filter, renormalised), the rest white.
pub fn noise_field(
    model: &SensorModel,
    (w, h): (usize, usize),
    scale: f64,
    seed: u64,
) -> Grid<f64> {
    let white = |i: u64| normal(seed, i, Stream::White);
    let side = (model.correlation_native_px * scale).round().max(1.0) as usize;
    let share = model.correlated_share.clamp(0.0, 1.0);
    if share == 0.0 || side <= 1 {
        return Grid::par_from_fn(w, h, |x, y| white((y * w + x) as u64));
    }
    let corr = box_noise(w, h, side, seed);
    let (a, b) = (share.sqrt(), (1.0 - share).sqrt());
    Grid::par_from_fn(w, h, |x, y| {
        a * corr[(x, y)] + b * white((y * w + x) as u64)
    })
}

/// White normal noise on a grid padded by `side − 1`, summed over `side`×`side` windows and
/// divided by `side`: unit variance, correlated over `side` pixels, no border effects.
fn box_noise(w: usize, h: usize, side: usize, seed: u64) -> Grid<f64> {
    let (pw, ph) = (w + side - 1, h + side - 1);
    let raw = Grid::par_from_fn(pw, ph, |x, y| {
        normal(seed, (y * pw + x) as u64, Stream::Correlated)
    });
    let rows = Grid::par_from_fn(w, ph, |x, y| raw.row(y)[x..x + side].iter().sum::<f64>());
    Grid::par_from_fn(w, h, |x, y| {
        (y..y + side).map(|yy| rows[(x, yy)]).sum::<f64>() / side as f64
    })
}

/// Per pixel, the depth of the neighbour (4-connected) across a jump larger than the model's
/// `flying_jump_m`, the largest such jump; `None` elsewhere or when the effect is off.
fn flying_mask(model: &SensorModel, depth_m: &Grid<f64>) -> Grid<Option<f64>> {
    let (w, h) = depth_m.size();
    let jump = model.flying_jump_m;
    Grid::from_fn(w, h, |x, y| {
        let z = depth_m[(x, y)];
        if jump <= 0.0 || !(z > 0.0) {
            return None;
        }
        let nbs = [(0, -1), (-1, 0), (1, 0), (0, 1)];
        nbs.iter()
            .filter_map(|&(dx, dy)| {
                let (nx, ny) = (x as i64 + dx, y as i64 + dy);
                let inside = nx >= 0 && ny >= 0 && (nx as usize) < w && (ny as usize) < h;
                inside.then(|| depth_m[(nx as usize, ny as usize)])
            })
            .filter(|&o| o > 0.0 && (o - z).abs() > jump)
            .max_by(|a, b| (a - z).abs().total_cmp(&(b - z).abs()))
    })
}

/// Stereo edge fattening: where a pixel within `r` (square window) is nearer by more than 3%,
/// the pixel takes the nearest such depth.
fn fatten(depth_m: &Grid<f64>, r: usize) -> Grid<f64> {
    let (w, h) = depth_m.size();
    Grid::from_fn(w, h, |x, y| {
        let z = depth_m[(x, y)];
        if !(z > 0.0) || r == 0 {
            return z;
        }
        let mut near = z;
        for yy in y.saturating_sub(r)..(y + r + 1).min(h) {
            for &o in &depth_m.row(yy)[x.saturating_sub(r)..(x + r + 1).min(w)] {
                if o > 0.0 && o < near {
                    near = o;
                }
            }
        }
        if near < 0.97 * z {
            near
        } else {
            z
        }
    })
}

/// Local texture: the mean absolute step of grey (0–1) between horizontal neighbours over a
/// window of half-width `r`.
fn texture(rgb: &RgbImage, r: usize) -> Grid<f64> {
    let (w, h) = (rgb.width() as usize, rgb.height() as usize);
    let grey = Grid::from_fn(w, h, |x, y| {
        let [r, g, b] = rgb.get_pixel(x as u32, y as u32).0;
        (f64::from(r) + f64::from(g) + f64::from(b)) / (3.0 * 255.0)
    });
    Grid::from_fn(w, h, |x, y| {
        let (mut sum, mut n) = (0.0, 0usize);
        for yy in y.saturating_sub(r)..(y + r + 1).min(h) {
            let row = grey.row(yy);
            for xx in x.saturating_sub(r)..(x + r).min(w - 1) {
                sum += (row[xx + 1] - row[xx]).abs();
                n += 1;
            }
        }
        if n == 0 {
            0.0
        } else {
            sum / n as f64
        }
    })
}

/// Pixels the projector (at +x by `baseline_m`, a rectified pair) does not light: along each
/// row, pixel u is shadowed when a pixel to its right lands left of it in the projector
/// image (u_p = u − f·b/z).
pub fn projector_shadow(depth_m: &Grid<f64>, k: &Intrinsics, baseline_m: f64) -> Grid<bool> {
    let (w, h) = depth_m.size();
    let mut out = Grid::new(w, h, false);
    let fb = k.fx_px * baseline_m;
    for y in 0..h {
        let mut min_up = f64::INFINITY;
        for x in (0..w).rev() {
            let z = depth_m[(x, y)];
            if !(z > 0.0) {
                continue;
            }
            let up = x as f64 - fb / z;
            if up > min_up {
                out[(x, y)] = true;
            }
            min_up = min_up.min(up);
        }
    }
    out
}

/// Concavity per pixel (0 flat or convex, towards 1 in a closed corner): the mean over 16
/// neighbours at 8 and 24 native pixels of how far they rise above the pixel's tangent plane
/// (sine of their elevation, negatives counted as 0).
fn concavity(input: &SensorInput<'_>, scale: f64) -> Grid<f64> {
    let (w, h) = input.depth_m.size();
    let k = input.intrinsics;
    let dirs = [
        (1, 0),
        (1, 1),
        (0, 1),
        (-1, 1),
        (-1, 0),
        (-1, -1),
        (0, -1),
        (1, -1),
    ];
    Grid::from_fn(w, h, |x, y| {
        let z = input.depth_m[(x, y)];
        let n = input.normals_cam[(x, y)];
        if !(z > 0.0) || !n.x.is_finite() {
            return 0.0;
        }
        let p = k.back_project(x as f64, y as f64, z);
        let mut sum = 0.0;
        for radius in [8.0, 24.0] {
            let r = (radius * scale).round().max(1.0) as i64;
            for (dx, dy) in dirs {
                let (nx, ny) = (x as i64 + dx * r, y as i64 + dy * r);
                if nx < 0 || ny < 0 || nx as usize >= w || ny as usize >= h {
                    continue;
                }
                let zo = input.depth_m[(nx as usize, ny as usize)];
                if zo > 0.0 {
                    let q = k.back_project(nx as f64, ny as f64, zo) - p;
                    sum += (n.dot(&q) / q.norm()).max(0.0);
                }
            }
        }
        sum / 16.0
    })
}

/// The pixels a spinning LiDAR's beams hit: `lidar_rings` rings evenly spread over the image's
/// vertical field of view (elevation measured from the camera's x–z plane), one return every
/// `lidar_azimuth_step_deg` of azimuth, each at the nearest pixel.
pub fn lidar_mask(model: &SensorModel, k: &Intrinsics, (w, h): (usize, usize)) -> Grid<bool> {
    let mut mask = Grid::new(w, h, false);
    let top = ((0.0 - k.cy_px) / k.fy_px).atan();
    let bottom = ((h as f64 - 1.0 - k.cy_px) / k.fy_px).atan();
    let left = ((0.0 - k.cx_px) / k.fx_px).atan();
    let right = ((w as f64 - 1.0 - k.cx_px) / k.fx_px).atan();
    let step = model.lidar_azimuth_step_deg.max(0.01).to_radians();
    let rings = model.lidar_rings.max(1);
    for ring in 0..rings {
        let t = (f64::from(ring) + 0.5) / f64::from(rings);
        let elevation = top + t * (bottom - top);
        let mut azimuth = left;
        while azimuth <= right {
            let u = k.cx_px + k.fx_px * azimuth.tan();
            let v = k.cy_px + k.fy_px * elevation.tan() / azimuth.cos();
            let (ui, vi) = (u.round(), v.round());
            if ui >= 0.0 && vi >= 0.0 && (ui as usize) < w && (vi as usize) < h {
                mask[(ui as usize, vi as usize)] = true;
            }
            azimuth += step;
        }
    }
    mask
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn box_noise_has_unit_variance_and_is_correlated() {
        let g = box_noise(200, 200, 9, 3);
        let v: Vec<f64> = g.as_slice().to_vec();
        let mean = v.iter().sum::<f64>() / v.len() as f64;
        let var = v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / v.len() as f64;
        assert!((var - 1.0).abs() < 0.15, "variance {var}");
        let lag1: f64 = (0..199)
            .flat_map(|y| (0..199).map(move |x| (x, y)))
            .map(|(x, y)| g[(x, y)] * g[(x + 1, y)])
            .sum::<f64>()
            / (199.0 * 199.0);
        assert!((lag1 - 8.0 / 9.0).abs() < 0.1, "lag-1 correlation {lag1}");
    }

    #[test]
    fn disparity_quantisation_matches_the_kinect_resolution() {
        // Step in depth at 5 m: z²·q/(f·b) = 25 · 0.125 / 43.5 ≈ 7.2 cm (Khoshelham 2012: ~7 cm).
        let m = SensorModel::preset(SensorPreset::KinectV1);
        let step = 25.0 * m.disparity_step_px / (m.native_focal_px * m.baseline_m);
        assert!((step - 0.0718).abs() < 1e-3, "{step}");
    }

    #[test]
    fn ramp_and_luminance() {
        assert_eq!(ramp(0.5, 1.0, 2.0), 0.0);
        assert_eq!(ramp(1.5, 1.0, 2.0), 0.5);
        assert_eq!(ramp(3.0, 1.0, 1.0), 1.0);
        assert!((linear_luminance([255, 255, 255]) - 1.0).abs() < 1e-9);
        assert_eq!(linear_luminance([0, 0, 0]), 0.0);
    }
}
