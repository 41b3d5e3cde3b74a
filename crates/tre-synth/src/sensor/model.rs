//! The parameters of each depth sensor's model.

use serde::{Deserialize, Serialize};

use tre_core::geometry::Intrinsics;
use tre_core::roughness::noise::SensorPreset;

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
            SensorPreset::LidarAccumulated => Self::lidar_accumulated(off),
            SensorPreset::PassiveStereo => Self::passive_stereo(off),
            SensorPreset::Exact => off,
        }
    }

    /// Accumulated LiDAR: denser rings than one sweep (the sweeps' registration error is not
    /// rendered).
    fn lidar_accumulated(off: Self) -> Self {
        Self {
            min_range_m: 0.5,
            max_range_m: 120.0,
            lidar_rings: 256,
            lidar_azimuth_step_deg: 0.1,
            ..off
        }
    }

    /// A ZED-class passive rig: quarter-pixel disparity steps, holes on weak texture.
    fn passive_stereo(off: Self) -> Self {
        Self {
            min_range_m: 0.3,
            max_range_m: 20.0,
            native_focal_px: 700.0,
            baseline_m: 0.12,
            disparity_step_px: 0.25,
            correlation_native_px: 5.0,
            correlated_share: 0.5,
            grazing_start_deg: 80.0,
            grazing_end_deg: 89.0,
            min_texture: 0.003,
            dropout_cell_native_px: 2.0,
            left_band: true,
            fatten_native_px: 2.0,
            ..off
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
    pub(super) fn scale(&self, k: &Intrinsics) -> f64 {
        if self.native_focal_px > 0.0 {
            k.fx_px / self.native_focal_px
        } else {
            1.0
        }
    }

    /// True for the sensors that triangulate (noise and quantisation in disparity).
    pub(super) fn triangulates(&self) -> bool {
        self.baseline_m > 0.0 && self.native_focal_px > 0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn disparity_quantisation_matches_the_kinect_resolution() {
        // Step in depth at 5 m: z²·q/(f·b) = 25 · 0.125 / 43.5 ≈ 7.2 cm (Khoshelham 2012: ~7 cm).
        let m = SensorModel::preset(SensorPreset::KinectV1);
        let step = 25.0 * m.disparity_step_px / (m.native_focal_px * m.baseline_m);
        assert!((step - 0.0718).abs() < 1e-3, "{step}");
    }
}
