//! One pixel's measurement: range limits, shadows, dropouts, flying pixels, multipath and the
//! noise in disparity or range.

use super::{SensorInput, SensorModel, Stream};
use tre_core::geometry::hash::uniform;
use tre_core::geometry::{Grid, Vec3};

/// The per-frame maps a pixel's measurement reads.
pub(super) struct PixelContext<'a> {
    /// The sensor.
    pub model: &'a SensorModel,
    /// The rendered frame.
    pub input: &'a SensorInput<'a>,
    /// The frame's noise seed.
    pub seed: u64,
    /// Frame pixels per native pixel.
    pub scale: f64,
    /// Unit-variance noise ([`super::noise_field`]).
    pub noise: &'a Grid<f64>,
    /// Flying-pixel neighbours' depths.
    pub flying: &'a Grid<Option<f64>>,
    /// Concavity, with multipath on.
    pub concavity: Option<&'a Grid<f64>>,
    /// Local texture, with a texture threshold.
    pub texture: Option<&'a Grid<f64>>,
    /// The LiDAR's beam pattern.
    pub lidar: Option<&'a Grid<bool>>,
    /// The projector's shadow.
    pub shadow: Option<&'a Grid<bool>>,
}

impl PixelContext<'_> {
    /// The measured depth of pixel (x, y) whose (possibly fattened) exact depth is `z`.
    pub(super) fn pixel(&self, x: usize, y: usize, z: f64) -> f64 {
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ramp_and_luminance() {
        assert_eq!(ramp(0.5, 1.0, 2.0), 0.0);
        assert_eq!(ramp(1.5, 1.0, 2.0), 0.5);
        assert_eq!(ramp(3.0, 1.0, 1.0), 1.0);
        assert!((linear_luminance([255, 255, 255]) - 1.0).abs() < 1e-9);
        assert_eq!(linear_luminance([0, 0, 0]), 0.0);
    }
}
