//! The draws of each scene and view: the camera mounting and optics, the views' headings, the
//! terrain within their reach, the lighting and weather, and the depth sensor. Each is a pure
//! function of the settings, the scene and the view.

use super::SynthConfig;
use crate::appearance::{Conditions, Lighting, Weather};
use crate::heightgrid::HeightGrid;
use crate::render::{Scene, View};
use crate::terrain::Terrain;
use tre_core::geometry::hash::splitmix64;
use tre_core::geometry::{Intrinsics, Mounting};
use tre_core::roughness::noise::SensorPreset;

/// Deterministic uniform number for (seed, scene, what).
pub(super) fn draw(seed: u64, scene: u32, what: u64) -> f64 {
    let h = splitmix64(splitmix64(seed ^ 0xDA7A) ^ (u64::from(scene) << 16) ^ what);
    (h >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
}

/// The scene's camera mounting.
pub fn scene_mounting(cfg: &SynthConfig, scene: u32) -> Mounting {
    if !cfg.random_mounting {
        return Mounting::default();
    }
    let height = 0.4 + 0.8 * draw(cfg.seed, scene, 1);
    let pitch = (40.0 + 35.0 * draw(cfg.seed, scene, 2)).to_radians();
    Mounting::new(pitch, height).expect("pitch and height drawn in range; this is a bug")
}

/// The ranges `--random-optics` draws each frame's camera from, uniformly.
pub struct OpticsRanges {
    /// Pitch below the horizon, degrees.
    pub pitch_deg: (f64, f64),
    /// Height above the ground, metres.
    pub height_m: (f64, f64),
    /// Roll about the optical axis, degrees.
    pub roll_deg: (f64, f64),
    /// Horizontal field of view, degrees.
    pub hfov_deg: (f64, f64),
    /// Frame shapes, height over width: 4:3, 16:9 and KITTI's 1242×375.
    pub aspects: [f64; 3],
}

/// The documented ranges of `--random-optics`.
pub const OPTICS: OpticsRanges = OpticsRanges {
    pitch_deg: (0.0, 85.0),
    height_m: (0.2, 2.0),
    roll_deg: (-10.0, 10.0),
    hfov_deg: (45.0, 110.0),
    aspects: [3.0 / 4.0, 9.0 / 16.0, 375.0 / 1242.0],
};

/// A frame's view under `--random-optics`: every quantity drawn from [`OPTICS`] with the
/// dataset seed, the scene and the view.
fn random_view(cfg: &SynthConfig, scene: u32, view: u32, yaw_rad: f64) -> View {
    let pick = |what: u64| {
        draw(
            cfg.seed,
            scene,
            (u64::from(view) << 32) | (0x0F71 << 8) | what,
        )
    };
    let lerp = |(lo, hi): (f64, f64), t: f64| lo + (hi - lo) * t;
    let pitch = lerp(OPTICS.pitch_deg, pick(1)).to_radians();
    let height = lerp(OPTICS.height_m, pick(2));
    let roll = lerp(OPTICS.roll_deg, pick(3)).to_radians();
    let hfov = lerp(OPTICS.hfov_deg, pick(4));
    let aspect = OPTICS.aspects[((pick(5) * 3.0) as usize).min(2)];
    let w = cfg.size.0;
    let h = ((w as f64 * aspect / 2.0).round() as usize * 2).max(2);
    View {
        mounting: Mounting::new(pitch, height)
            .expect("pitch and height drawn in range; this is a bug"),
        yaw_rad,
        roll_rad: roll,
        intrinsics: Intrinsics::from_hfov(w, h, hfov).expect("hfov drawn in range; this is a bug"),
        width: w,
        height: h,
    }
}

/// The views of a scene.
pub fn scene_views(cfg: &SynthConfig, scene: u32) -> Vec<View> {
    // The fixed camera of every view, unless each view draws its own.
    let (w, h) = cfg.size;
    let fixed = (!cfg.random_optics).then(|| {
        let k = Intrinsics::from_hfov(w, h, cfg.hfov_deg).expect("hfov checked; this is a bug");
        (k, scene_mounting(cfg, scene))
    });
    (0..cfg.views)
        .map(|v| {
            let f = if cfg.views == 1 {
                0.5
            } else {
                f64::from(v) / f64::from(cfg.views - 1)
            };
            let yaw = (-cfg.yaw_span_deg + 2.0 * cfg.yaw_span_deg * f).to_radians();
            match fixed {
                Some((intrinsics, mounting)) => View {
                    mounting,
                    yaw_rad: yaw,
                    roll_rad: 0.0,
                    intrinsics,
                    width: w,
                    height: h,
                },
                None => random_view(cfg, scene, v, yaw),
            }
        })
        .collect()
}

/// How far ahead a view can see ground, metres (capped at 12 m).
fn reach(view: &View) -> f64 {
    let vfov_half = (view.height as f64 / 2.0 / view.intrinsics.fy_px).atan();
    let lowest = (view.mounting.pitch_rad - vfov_half).max(5f64.to_radians());
    (view.mounting.height_m / lowest.tan()).min(12.0)
}

/// Builds scene `s`: terrain and its sampled grid, covering what its views can see.
pub fn build_scene(cfg: &SynthConfig, s: u32, views: &[View]) -> Scene {
    let terrain = scene_terrain(cfg, s, views);
    sample_scene(cfg, views, terrain)
}

/// How far the scene's grid reaches: the farthest ground its views see, plus 0.5 m.
fn scene_reach(views: &[View]) -> f64 {
    views.iter().map(reach).fold(1.0f64, f64::max) + 0.5
}

/// The terrain of scene `s` (of the dataset's content), with content within its views' reach.
pub fn scene_terrain(cfg: &SynthConfig, s: u32, views: &[View]) -> Terrain {
    let r = scene_reach(views);
    cfg.content.terrain(cfg.seed, u64::from(s), r.min(4.0))
}

/// Samples `terrain`'s grid over what `views` can see.
pub(super) fn sample_scene(cfg: &SynthConfig, views: &[View], terrain: Terrain) -> Scene {
    let r = scene_reach(views);
    let grid = HeightGrid::sample(&terrain, (-r, -0.8), (r, r), cfg.cell_m);
    Scene { terrain, grid }
}

/// Conditions of view `v` of scene `s`: the 4 lightings × 5 weathers cycle so that every 20
/// consecutive frames hold each combination once; the sun's azimuth is drawn per scene.
pub fn view_conditions(cfg: &SynthConfig, s: u32, v: u32) -> Conditions {
    // Frame k takes combination 7k mod 20 (7 is prime to 20): every 20 frames hold all 20.
    let k = (u64::from(s) * u64::from(cfg.views) + u64::from(v)) as usize;
    let combo = (7 * k) % 20;
    Conditions {
        lighting: Lighting::ALL[combo % 4],
        weather: Weather::ALL[combo / 4],
        sun_azimuth_rad: draw(cfg.seed, s, 3) * std::f64::consts::TAU,
    }
}

/// The depth sensor of view `v` of scene `s` and the seed of its noise.
pub fn view_sensor(cfg: &SynthConfig, s: u32, v: u32) -> (SensorPreset, u64) {
    let what = 0x5E45_0000 | u64::from(v);
    let seed = splitmix64(splitmix64(cfg.seed ^ 0x5E45) ^ (u64::from(s) << 20) ^ what);
    let n = cfg.sensors.len().max(1);
    let pick = ((draw(cfg.seed, s, what) * n as f64) as usize).min(n - 1);
    let sensor = cfg
        .sensors
        .get(pick)
        .copied()
        .unwrap_or(SensorPreset::Exact);
    (sensor, seed)
}
