//! What a client asks for beside the frame, in domain types: the encoding of the roughness
//! map, the extra maps and the settings of the run ([`FrameOptions`]). HTTP queries and the
//! stream's Hello both become these; the names a client writes are derived from the enums.

use strum::{EnumIter, EnumMessage, EnumString, IntoEnumIterator, IntoStaticStr};

use tre_core::kinds::{MapFormat, Mode, NormalsMethod, Traversability};
use tre_core::roughness::noise::SensorNoise;

/// An extra map a client may ask for beside roughness, by the name of its part in the answer
/// (HTTP `outputs=depth,slope`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, EnumString, EnumIter, EnumMessage, IntoStaticStr)]
#[strum(serialize_all = "lowercase")]
pub enum OutputMap {
    /// Depth used, 16-bit grey PNG in millimetres.
    Depth,
    /// Unit normals (camera frame), `(H, W, 3)` float32 `.npy`.
    Normals,
    /// Slope in the gravity frame, `(H, W)` float32 `.npy`, radians.
    Slope,
    /// Traversability mask, 8-bit grey PNG (255 = traversable).
    Traversable,
    /// Boundary mask (depth steps and creases), 8-bit grey PNG (255 = boundary).
    Boundary,
    /// Uncertainty, 16-bit grey + alpha PNG at 0.1 mm per unit.
    Uncertainty,
    /// Three-state traversability, 8-bit grey PNG: 0 unknown, 1 traversable, 2 hazard.
    Traversal,
}

impl OutputMap {
    /// Every map's name, comma-separated: `depth, normals, ..., traversal`.
    pub fn all_names() -> String {
        let names: Vec<&str> = Self::iter()
            .filter_map(|m| m.get_serializations().first().copied())
            .collect();
        names.join(", ")
    }
}

/// Extra maps a client may ask for beside roughness.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Extras {
    /// Depth used, 16-bit grey PNG in millimetres.
    pub depth: bool,
    /// Unit normals (camera frame), `(H, W, 3)` float32 `.npy`.
    pub normals: bool,
    /// Slope in the gravity frame, `(H, W)` float32 `.npy`, radians.
    pub slope: bool,
    /// Traversability mask, 8-bit grey PNG (255 = traversable).
    pub traversable: bool,
    /// Boundary mask (depth steps and creases), 8-bit grey PNG (255 = boundary).
    pub boundary: bool,
    /// Uncertainty (p95 of the roughness noise alone gives), 16-bit grey + alpha PNG at 0.1 mm
    /// per unit, as roughness (modes with sensor depth and a noise model only).
    pub uncertainty: bool,
    /// Three-state traversability, 8-bit grey PNG: 0 unknown, 1 traversable, 2 hazard (as
    /// `uncertainty`).
    pub traversal: bool,
}

impl Extras {
    /// Asks for `map` too.
    pub fn add(&mut self, map: OutputMap) {
        let wanted = match map {
            OutputMap::Depth => &mut self.depth,
            OutputMap::Normals => &mut self.normals,
            OutputMap::Slope => &mut self.slope,
            OutputMap::Traversable => &mut self.traversable,
            OutputMap::Boundary => &mut self.boundary,
            OutputMap::Uncertainty => &mut self.uncertainty,
            OutputMap::Traversal => &mut self.traversal,
        };
        *wanted = true;
    }

    /// Whether any extra map is asked for.
    #[cfg(test)]
    pub(crate) fn any(self) -> bool {
        self.depth
            || self.normals
            || self.slope
            || self.traversable
            || self.boundary
            || self.uncertainty
            || self.traversal
    }
}

/// How to run and answer one frame.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct FrameOptions {
    /// Input mode; `None`: rgbd with RGB and depth, geometric with depth alone, else rgb.
    pub mode: Option<Mode>,
    /// Encoding of the roughness map ([`MapFormat::HTTP`] over HTTP, [`MapFormat::STREAM`] on
    /// the stream).
    pub format: MapFormat,
    /// Seed of the DSAC sampler.
    pub seed: u64,
    /// Initial normals; `None`: the server's default (`tre serve --normals`).
    pub normals: Option<NormalsMethod>,
    /// DSAC hypotheses per pixel (checked: 1 to 64); `None`: the server's default
    /// (`tre serve --dsac-hypotheses`).
    pub dsac_hypotheses: Option<u32>,
    /// Top of the colour preview's scale, metres (default 0.05).
    pub preview_max_m: Option<f64>,
    /// Extra maps.
    pub extras: Extras,
    /// The traversability mask as raw bytes (1 per pixel), for the stream.
    pub traversable_bytes: bool,
    /// Thresholds of the traversability mask.
    pub traversability: Traversability,
    /// The depth sensor's noise model, overriding the camera's `sensor`.
    pub sensor: Option<SensorNoise>,
    /// The three-state map as raw bytes (0 unknown, 1 traversable, 2 hazard), for the stream.
    pub traversal_bytes: bool,
    /// The uncertainty map as raw little-endian float32 metres, for the stream.
    pub uncertainty_f32: bool,
}

impl FrameOptions {
    /// Whether any sensor-noise map is asked for.
    pub fn wants_sensor_maps(&self) -> bool {
        self.extras.uncertainty
            || self.extras.traversal
            || self.traversal_bytes
            || self.uncertainty_f32
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_output_map_has_its_part_name_and_sets_its_flag() {
        assert_eq!(
            OutputMap::all_names(),
            "depth, normals, slope, traversable, boundary, uncertainty, traversal"
        );
        let mut extras = Extras::default();
        for map in OutputMap::iter() {
            let before = extras;
            extras.add(map);
            assert_ne!(extras, before, "{map:?}");
            assert_eq!(<&str>::from(map).parse::<OutputMap>(), Ok(map));
        }
        assert!(extras.any());
    }
}
