//! Depth-sensor noise σ_z(z) (presets and explicit coefficients) and the uncertainty map: the
//! roughness that noise alone gives annotation spec v1 on a flat surface (docs/sensor-noise.md).

use std::fmt;
use std::str::FromStr;

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::annotate::{edge_term, AnnotateConfig};
use crate::geometry::neighbours::neighbour_counts_into;
use crate::geometry::normals::PackedPoints;
use crate::geometry::{is_valid_point, PointMap};
use crate::geometry::{Grid, Intrinsics, Vec3};

/// A named depth sensor whose noise model is built in (sources in docs/sensor-noise.md).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SensorPreset {
    /// Structured light, Kinect v1: σ_z = 1.2 mm + 1.9 mm·(z − 0.4 m)² (Nguyen et al. 2012).
    KinectV1,
    /// Active stereo, RealSense D435 at 848×480: σ_z = z²·σ_d/(f·b), σ_d = 0.08 px,
    /// f = 447 px, b = 50 mm (Intel's D400 tuning white paper).
    RealsenseD435,
    /// Time of flight, Azure Kinect DK: constant 17 mm (the hardware spec's random-error bound).
    AzureKinect,
    /// Spinning LiDAR (HDL-64E class, ±2 cm), one sweep: constant 20 mm.
    Lidar,
    /// Accumulated (semi-dense) LiDAR: several sweeps moved into one frame by the poses. The
    /// range noise of one sweep (20 mm) plus the sweeps' registration error, an angle of
    /// [`REGISTRATION_DEG`] that offsets whole scan lines (correlated, so averaging does not
    /// remove it): [`SensorNoise::registration_m`].
    LidarAccumulated,
    /// Passive stereo (a ZED-class rig: baseline 120 mm, focal length 700 px at 1280×720, the
    /// matcher's sub-pixel step 0.25 px): σ_z = z²·step/(f·b). Another rig: explicit
    /// coefficients `[0, 0, 1000·step/(f·b)]` mm (docs/sensor-noise.md).
    PassiveStereo,
    /// Exact depth (synthetic data): no noise.
    Exact,
}

impl SensorPreset {
    /// Every preset, in the order the docs list them.
    pub const ALL: [Self; 7] = [
        Self::KinectV1,
        Self::RealsenseD435,
        Self::AzureKinect,
        Self::Lidar,
        Self::LidarAccumulated,
        Self::PassiveStereo,
        Self::Exact,
    ];

    /// The preset's name on the wire (`kinect_v1`, …), as serde writes it.
    pub fn name(self) -> &'static str {
        match self {
            Self::KinectV1 => "kinect_v1",
            Self::RealsenseD435 => "realsense_d435",
            Self::AzureKinect => "azure_kinect",
            Self::Lidar => "lidar",
            Self::LidarAccumulated => "lidar_accumulated",
            Self::PassiveStereo => "passive_stereo",
            Self::Exact => "exact",
        }
    }

    /// The names of all presets, comma-separated (for messages).
    pub fn names() -> String {
        Self::ALL.map(Self::name).join(", ")
    }

    /// σ_z(z), metres, for depth `z_m` metres.
    pub fn sigma_z_m(self, z_m: f64) -> f64 {
        match self {
            Self::KinectV1 => 0.0012 + 0.0019 * (z_m - 0.4).powi(2),
            Self::RealsenseD435 => z_m * z_m * D435_SUBPIXEL_PX / (D435_FOCAL_PX * D435_BASELINE_M),
            Self::AzureKinect => 0.017,
            Self::Lidar | Self::LidarAccumulated => 0.02,
            Self::PassiveStereo => {
                z_m * z_m * STEREO_SUBPIXEL_PX / (STEREO_FOCAL_PX * STEREO_BASELINE_M)
            }
            Self::Exact => 0.0,
        }
    }
}

/// Registration error of accumulated LiDAR sweeps, degrees: at 10 m it offsets a sweep's scan
/// lines by 5 cm. The one semi-dense set here (real-rgbd-3) shows layers of about this size.
pub const REGISTRATION_DEG: f64 = 0.3;
/// Passive stereo preset: the matcher's sub-pixel step, pixels.
const STEREO_SUBPIXEL_PX: f64 = 0.25;
/// Passive stereo preset: focal length, pixels (ZED class at 1280×720).
const STEREO_FOCAL_PX: f64 = 700.0;
/// Passive stereo preset: baseline, metres.
const STEREO_BASELINE_M: f64 = 0.12;

/// RealSense D435 sub-pixel disparity accuracy σ_d, pixels (Intel's typical figure).
const D435_SUBPIXEL_PX: f64 = 0.08;
/// RealSense D435 depth focal length at 848×480 (87° horizontal field of view), pixels.
const D435_FOCAL_PX: f64 = 447.0;
/// RealSense D435 stereo baseline, metres.
const D435_BASELINE_M: f64 = 0.050;

impl fmt::Display for SensorPreset {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for SensorPreset {
    type Err = String;

    /// A preset by name (case and `-`/`_` do not matter).
    ///
    /// ```
    /// use tre_core::roughness::noise::SensorPreset;
    /// assert_eq!("Kinect-V1".parse(), Ok(SensorPreset::KinectV1));
    /// assert!("kinect".parse::<SensorPreset>().unwrap_err().contains("kinect_v1"));
    /// ```
    fn from_str(s: &str) -> Result<Self, String> {
        let key = s.trim().to_ascii_lowercase().replace('-', "_");
        Self::ALL
            .into_iter()
            .find(|p| p.name() == key)
            .ok_or_else(|| format!("unknown sensor {s:?}: the presets are {}", Self::names()))
    }
}

/// A depth-noise model: a preset, or σ_z(z) = a + b·z + c·z² millimetres with z in metres.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum SensorNoise {
    /// A built-in sensor.
    Preset(SensorPreset),
    /// Explicit coefficients.
    Coefficients {
        /// `[a, b, c]`: σ_z = a + b·z + c·z² mm, z in metres.
        sigma_mm: [f64; 3],
    },
    /// A passive stereo rig: `{"stereo": {"baseline_m", "focal_px", "step_px", "block_px"}}`.
    Stereo {
        /// The rig.
        stereo: StereoRig,
    },
}

/// A passive stereo rig's noise: σ_z = z²·step/(f·b) (the matcher's sub-pixel step as the
/// disparity's σ), errors shared over the matcher's block.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StereoRig {
    /// Baseline b, metres.
    pub baseline_m: f64,
    /// Focal length f of the rectified pair, pixels.
    pub focal_px: f64,
    /// The matcher's sub-pixel disparity step, pixels (0.25 for a quarter-pixel matcher).
    pub step_px: f64,
    /// Side of the matcher's block, pixels (errors are shared within it).
    #[serde(default = "default_block_px")]
    pub block_px: f64,
}

fn default_block_px() -> f64 {
    5.0
}

impl StereoRig {
    /// The rig checked: every field a positive, finite number, else what is wrong.
    ///
    /// # Errors
    ///
    /// A message naming the field.
    pub fn checked(self) -> Result<Self, String> {
        for (name, v) in [
            ("baseline_m", self.baseline_m),
            ("focal_px", self.focal_px),
            ("step_px", self.step_px),
            ("block_px", self.block_px),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return Err(format!(
                    "sensor.stereo.{name} must be a positive number, got {v}"
                ));
            }
        }
        Ok(self)
    }

    /// σ_z(z), metres.
    pub fn sigma_z_m(&self, z_m: f64) -> f64 {
        z_m * z_m * self.sigma_mm()[2] * 1e-3
    }

    /// The rig's σ_z as coefficients `[a, b, c]` mm (σ_z = c·z²), as the stream and the query
    /// carry it (without the block's correlation).
    pub fn sigma_mm(&self) -> [f64; 3] {
        [
            0.0,
            0.0,
            1e3 * self.step_px / (self.focal_px * self.baseline_m),
        ]
    }
}

impl SensorNoise {
    /// Explicit coefficients `[a, b, c]` (σ_z = a + b·z + c·z² mm), checked: finite, with
    /// σ_z ≥ 0 for every z ≥ 0 (so `c ≥ 0`, and `b ≥ 0` when `c = 0`). For why not, an error
    /// whose message names the field.
    ///
    /// ```
    /// use tre_core::roughness::noise::{CoefficientsProblem, SensorNoise};
    /// let kinect = SensorNoise::coefficients([1.504, -1.52, 1.9]).unwrap();
    /// assert!((kinect.sigma_z_m(4.0) - 0.025_824).abs() < 1e-9);
    /// let e = SensorNoise::coefficients([1.0, 0.0, -1.0]).unwrap_err();
    /// assert_eq!(e.problem, CoefficientsProblem::Negative);
    /// assert!(e.to_string().contains("sigma_mm"));
    /// ```
    pub fn coefficients(sigma_mm: [f64; 3]) -> Result<Self, CoefficientsError> {
        let [a, b, c] = sigma_mm;
        let bad = |problem| Err(CoefficientsError { sigma_mm, problem });
        if !sigma_mm.iter().all(|v| v.is_finite()) {
            return bad(CoefficientsProblem::NotFinite);
        }
        if a < 0.0 || c < 0.0 || (c == 0.0 && b < 0.0) {
            return bad(CoefficientsProblem::Negative);
        }
        if c > 0.0 && b < 0.0 && a - b * b / (4.0 * c) < 0.0 {
            return bad(CoefficientsProblem::DipsBelowZero);
        }
        Ok(Self::Coefficients { sigma_mm })
    }

    /// σ_z(z), metres, for depth `z_m` metres.
    pub fn sigma_z_m(&self, z_m: f64) -> f64 {
        match self {
            Self::Preset(p) => p.sigma_z_m(z_m),
            Self::Coefficients {
                sigma_mm: [a, b, c],
            } => (a + b * z_m + c * z_m * z_m) * 1e-3,
            Self::Stereo { stereo } => stereo.sigma_z_m(z_m),
        }
    }

    /// How the noise is shared between neighbouring pixels: `(side, share)`, the side in
    /// pixels of the patches within which a `share` of the variance is common (a triangulating
    /// sensor's correlation window, as the synthetic sensor models render it: docs/synth.md),
    /// `(1, 0)` for independent pixels.
    pub fn correlation(&self) -> (f64, f64) {
        match self {
            Self::Preset(SensorPreset::KinectV1) => (9.0, 0.9),
            Self::Preset(SensorPreset::RealsenseD435) => (7.0, 0.8),
            Self::Preset(SensorPreset::PassiveStereo) => (5.0, 0.5),
            Self::Stereo { stereo } => (stereo.block_px, 0.5),
            _ => (1.0, 0.0),
        }
    }

    /// The variance of the mean of `n` neighbouring points' noise, in units of one point's:
    /// `(1 − s)/n + s·min(1, c²/n)` for side `c` and share `s` ([`Self::correlation`]).
    pub fn mean_variance(&self, n: f64) -> f64 {
        let (c, s) = self.correlation();
        let n = n.max(1.0);
        (1.0 - s) / n + s * (c * c / n).min(1.0)
    }

    /// The correlated part of the noise at range `z_m`, metres: an offset shared by many
    /// neighbouring points (a sweep's scan lines, for accumulated LiDAR), which averaging over
    /// a window does not reduce. 0 for every sensor but accumulated LiDAR.
    pub fn registration_m(&self, z_m: f64) -> f64 {
        match self {
            Self::Preset(SensorPreset::LidarAccumulated) => {
                z_m * REGISTRATION_DEG.to_radians().tan()
            }
            _ => 0.0,
        }
    }

    /// The preset's name, or `sigma_mm [a, b, c]`.
    pub fn label(&self) -> String {
        match self {
            Self::Preset(p) => p.name().to_string(),
            Self::Coefficients { sigma_mm } => format!("sigma_mm {sigma_mm:?}"),
            Self::Stereo { stereo } => format!(
                "stereo b {} m, f {} px, step {} px",
                stereo.baseline_m, stereo.focal_px, stereo.step_px
            ),
        }
    }
}

/// Coefficients `[a, b, c]` that make no noise model ([`SensorNoise::coefficients`]); the
/// message names the field, `sensor.sigma_mm`.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
#[error("sensor.sigma_mm {sigma_mm:?}: {problem}")]
pub struct CoefficientsError {
    /// The coefficients given.
    pub sigma_mm: [f64; 3],
    /// What is wrong with them.
    pub problem: CoefficientsProblem,
}

/// What is wrong with noise coefficients `[a, b, c]`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum CoefficientsProblem {
    /// A coefficient that is NaN or infinite.
    #[error("all three coefficients must be finite numbers")]
    NotFinite,
    /// `a < 0` or `c < 0` (or `b < 0` with `c = 0`): σ_z falls below 0 as z grows.
    #[error("σ_z = a + b·z + c·z² mm must stay ≥ 0 for z ≥ 0 (a ≥ 0, c ≥ 0)")]
    Negative,
    /// A parabola whose minimum, at some z > 0, is below 0.
    #[error("σ_z = a + b·z + c·z² mm dips below 0 at some z > 0")]
    DipsBelowZero,
}

impl FromStr for SensorNoise {
    type Err = String;

    /// A preset name, or `a,b,c` coefficients in millimetres.
    fn from_str(s: &str) -> Result<Self, String> {
        if s.contains(',') {
            let v: Result<Vec<f64>, _> = s.split(',').map(|c| c.trim().parse::<f64>()).collect();
            return match v.as_deref() {
                Ok(&[a, b, c]) => Self::coefficients([a, b, c]).map_err(|e| e.to_string()),
                _ => Err(format!(
                    "sensor {s:?}: coefficients are three numbers a,b,c (mm)"
                )),
            };
        }
        s.parse().map(Self::Preset)
    }
}

/// The 95th percentile of a half-normal distribution, in units of its σ.
pub const HALF_NORMAL_P95: f64 = 1.959_964;

/// Fraction of neighbour joins that noise alone must fail (spec step 2, the ε test) for the
/// segments to break up and the edge term to fire on flat ground (see docs/sensor-noise.md).
pub const SEGMENT_BREAK_FRACTION: f64 = 0.05;

/// The 95th percentile of the largest of 8 half-normal values, in units of their σ: solves
/// `(2Φ(t) − 1)^8 = 0.95` (the edge weight W is the largest of 8 neighbour distances).
pub const MAX_OF_8_HALF_NORMAL_P95: f64 = 2.728;

/// Per-pixel noise statistics behind the uncertainty map.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PixelNoise {
    /// σ of the point's offset along the surface normal, metres.
    pub sigma_normal_m: f64,
    /// Points in the surface term's neighbourhood (the pixel's own included).
    pub neighbours: usize,
    /// Predicted p95 of the surface term, metres.
    pub surface_p95_m: f64,
    /// Fraction of 4-neighbour joins failing the ε test on noise alone.
    pub break_fraction: f64,
    /// Predicted edge term where segments break up (0 where they hold), metres.
    pub edge_m: f64,
}

impl PixelNoise {
    /// The uncertainty: the larger of the surface and edge predictions, metres.
    pub fn uncertainty_m(&self) -> f64 {
        self.surface_p95_m.max(self.edge_m)
    }
}

/// The uncertainty map: at each valid pixel, the p95 of the roughness that sensor noise alone
/// gives spec v1 on a flat surface with the pixel's normal (NaN where there is no depth).
/// `normals` (unit, camera frame; NaN: unknown, read as facing the camera) are the surface's,
/// e.g. the LS normals of the annotation or the pipeline's.
///
/// ```
/// use tre_core::geometry::{Grid, Intrinsics, Vec3};
/// use tre_core::roughness::noise::{uncertainty_map, SensorNoise, SensorPreset};
/// let k = Intrinsics::new(525.0, 525.0, 16.0, 12.0).unwrap();
/// let normals = Grid::new(32, 24, Vec3::new(0.0, 0.0, -1.0));
/// let kinect = SensorNoise::Preset(SensorPreset::KinectV1);
/// let at = |z: f64| {
///     let u = uncertainty_map(&Grid::new(32, 24, z), &k, &normals, &kinect, &Default::default());
///     u[(16, 12)]
/// };
/// // 1 m: σ_z = 1.88 mm, 225 points in the window: 1.96 · 1.88 · √(224/225) ≈ 3.7 mm.
/// assert!((at(1.0) - 0.003_676).abs() < 2e-5, "{}", at(1.0));
/// // 2 m: σ_z = 6.06 mm breaks 8% of the segment joins; the edge term takes over.
/// assert!(at(2.0) > 0.02, "{}", at(2.0));
/// ```
pub fn uncertainty_map(
    depth_m: &Grid<f64>,
    intrinsics: &Intrinsics,
    normals: &Grid<Vec3>,
    sensor: &SensorNoise,
    cfg: &AnnotateConfig,
) -> Grid<f64> {
    with_counts(depth_m, intrinsics, normals, cfg, |frame| {
        let mut out = Grid::new(frame.points.width(), frame.points.height(), f64::NAN);
        out.par_rows_mut().for_each(|(y, row)| {
            for (x, u) in row.iter_mut().enumerate() {
                if let Some(n) = frame.noise_at((x, y), sensor, cfg) {
                    *u = n.uncertainty_m();
                }
            }
        });
        out
    })
}

/// [`PixelNoise`] at every pixel (`None` where there is no depth).
pub fn pixel_noise_map(
    depth_m: &Grid<f64>,
    intrinsics: &Intrinsics,
    normals: &Grid<Vec3>,
    sensor: &SensorNoise,
    cfg: &AnnotateConfig,
) -> Grid<Option<PixelNoise>> {
    with_counts(depth_m, intrinsics, normals, cfg, |frame| {
        let (w, h) = frame.points.size();
        Grid::par_from_fn(w, h, |x, y| frame.noise_at((x, y), sensor, cfg))
    })
}

/// The buffers of [`with_counts`], kept per thread from frame to frame: a 640×480 frame's
/// points, packed points and counts are about 12 MB, which the allocator would otherwise map
/// and fault in afresh for every frame.
#[derive(Default)]
struct CountScratch {
    points: PointMap,
    packed: PackedPoints,
    counts: Grid<u32>,
}

thread_local! {
    static COUNT_SCRATCH: std::cell::RefCell<CountScratch> = Default::default();
}

/// Runs `f` on the frame of `depth_m`: its points and their neighbour counts (spec
/// neighbourhood of `cfg`) in this thread's buffers (fresh ones where they are in use, as when
/// a rayon task started inside `f` on this thread computes another frame's maps), `normals`
/// and `k`.
fn with_counts<T>(
    depth_m: &Grid<f64>,
    k: &Intrinsics,
    normals: &Grid<Vec3>,
    cfg: &AnnotateConfig,
    f: impl FnOnce(&NoiseFrame<'_>) -> T,
) -> T {
    let run = |s: &mut CountScratch| {
        k.back_project_map_into(depth_m, &mut s.points);
        neighbour_counts_into(&s.points, k.fx_px, &cfg.hood, &mut s.packed, &mut s.counts);
        f(&NoiseFrame {
            points: &s.points,
            counts: &s.counts,
            normals,
            k,
        })
    };
    COUNT_SCRATCH.with(|cell| match cell.try_borrow_mut() {
        Ok(mut s) => run(&mut s),
        Err(_) => run(&mut CountScratch::default()),
    })
}

/// A frame's points, their neighbour counts and normals, and its intrinsics.
struct NoiseFrame<'a> {
    points: &'a PointMap,
    counts: &'a Grid<u32>,
    normals: &'a Grid<Vec3>,
    k: &'a Intrinsics,
}

impl NoiseFrame<'_> {
    /// The noise statistics at pixel `(x, y)` (`None` where there is no depth); a missing or
    /// zero normal reads as facing the camera.
    fn noise_at(
        &self,
        (x, y): (usize, usize),
        sensor: &SensorNoise,
        cfg: &AnnotateConfig,
    ) -> Option<PixelNoise> {
        let p = self.points[(x, y)];
        if !is_valid_point(&p) {
            return None;
        }
        let n = self
            .normals
            .get(x, y)
            .copied()
            .filter(|n| n.norm().is_finite() && n.norm() > 0.0);
        let n = n.map_or(-p / p.norm(), |n| n / n.norm());
        let pixel = Pixel {
            xy: (x, y),
            neighbours: self.counts[(x, y)] as usize,
        };
        Some(pixel_noise(self.points, self.k, &pixel, &n, sensor, cfg))
    }
}

/// A valid pixel and its neighbour count ([`crate::geometry::neighbours::count_within`] in its
/// window).
struct Pixel {
    xy: (usize, usize),
    neighbours: usize,
}

/// The noise statistics of `pixel` (valid) with unit normal `n`.
fn pixel_noise(
    points: &PointMap,
    k: &Intrinsics,
    pixel: &Pixel,
    n: &Vec3,
    sensor: &SensorNoise,
    cfg: &AnnotateConfig,
) -> PixelNoise {
    let (x, y) = pixel.xy;
    let p = points[(x, y)];
    let sigma_z = sensor.sigma_z_m(p.z).max(0.0);
    // Depth noise δz moves the point along its ray by δz·p/z: along the normal by δz·(n·p)/z.
    let sigma_normal_m = sigma_z * n.dot(&p).abs() / p.z;
    let half = cfg.hood.half_width(k.fx_px, p.z);
    let neighbours = pixel.neighbours;
    let residual = (1.0 - 1.0 / neighbours.max(1) as f64).sqrt();
    let surface_p95_m = HALF_NORMAL_P95 * sigma_normal_m * residual;
    let sigma_ray_m = sigma_z * p.norm() / p.z;
    let extent_m = (half as f64 * p.z / k.fx_px).min(cfg.hood.radius_m);
    let (break_fraction, noisy_normals) =
        joins_broken(sigma_ray_m, sigma_normal_m, extent_m, cfg.epsilon_m);
    let edge_m = if break_fraction >= SEGMENT_BREAK_FRACTION {
        // A neighbour's distance moves by the difference of two ray offsets, σ√2 each.
        // A noise-led normal says nothing of the surface: the spacing facing the camera then.
        let facing = -p / p.norm();
        let spacing = neighbour_spacing(k, (x, y), &p, if noisy_normals { &facing } else { n });
        let spread = MAX_OF_8_HALF_NORMAL_P95 * std::f64::consts::SQRT_2 * sigma_ray_m;
        edge_term(spacing.hypot(spread), cfg.epsilon_m)
    } else {
        0.0
    };
    PixelNoise {
        sigma_normal_m,
        neighbours,
        surface_p95_m,
        break_fraction,
        edge_m,
    }
}

/// The fraction of segment joins (spec step 2) that noise breaks on a plane, and whether the LS
/// normals follow the noise. Two neighbours' offsets along the normal differ by N(0, 2σ_n²), so
/// the ε test fails with erfc(ε/2σ_n). Where 3σ along the ray exceeds the window's extent
/// (`extent_m`), LS normals follow the noise and the 10° test breaks every join; the estimated
/// normal cannot tell, being the noisy one.
fn joins_broken(
    sigma_ray_m: f64,
    sigma_normal_m: f64,
    extent_m: f64,
    epsilon_m: f64,
) -> (f64, bool) {
    if 3.0 * sigma_ray_m > extent_m {
        (1.0, true)
    } else if sigma_normal_m > 0.0 {
        (erfc(epsilon_m / (2.0 * sigma_normal_m)), false)
    } else {
        (0.0, false)
    }
}

/// The largest distance from `p` (pixel `(x, y)`) to its 8 neighbours' rays where they meet
/// the plane through `p` with normal `n` (rays that miss it are left out).
fn neighbour_spacing(k: &Intrinsics, (x, y): (usize, usize), p: &Vec3, n: &Vec3) -> f64 {
    let d = n.dot(p);
    let mut far: f64 = 0.0;
    for (dx, dy) in crate::geometry::NEIGHBOURS_8 {
        let ray = Vec3::new(
            (x as f64 + f64::from(dx) - k.cx_px) / k.fx_px,
            (y as f64 + f64::from(dy) - k.cy_px) / k.fy_px,
            1.0,
        );
        let t = d / n.dot(&ray);
        if t.is_finite() && t > 0.0 {
            far = far.max((ray * t - p).norm());
        }
    }
    far
}

/// The complementary error function (Abramowitz and Stegun 7.1.26, error below 1.5e-7).
///
/// ```
/// use tre_core::roughness::noise::erfc;
/// assert!((erfc(0.0) - 1.0).abs() < 1e-6);
/// assert!((erfc(1.0) - 0.157_299_2).abs() < 1e-6);
/// assert!((erfc(-1.0) - 1.842_700_8).abs() < 1e-6);
/// ```
pub fn erfc(x: f64) -> f64 {
    let t = 1.0 / (1.0 + 0.327_591_1 * x.abs());
    let poly = t
        * (0.254_829_592
            + t * (-0.284_496_736
                + t * (1.421_413_741 + t * (-1.453_152_027 + t * 1.061_405_429))));
    let tail = poly * (-x * x).exp();
    if x >= 0.0 {
        tail
    } else {
        2.0 - tail
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn preset_names_are_serdes_and_parse_back() {
        for p in SensorPreset::ALL {
            let json = serde_json::to_string(&SensorNoise::Preset(p)).unwrap();
            assert_eq!(json, format!("\"{}\"", p.name()));
            assert_eq!(p.name().parse::<SensorPreset>(), Ok(p));
            assert_eq!(
                serde_json::from_str::<SensorNoise>(&json).unwrap(),
                SensorNoise::Preset(p)
            );
        }
    }

    #[test]
    fn presets_give_the_cited_figures() {
        let k = SensorPreset::KinectV1;
        assert!((k.sigma_z_m(0.4) - 0.0012).abs() < 1e-12);
        assert!((k.sigma_z_m(4.0) - (0.0012 + 0.0019 * 12.96)).abs() < 1e-12);
        // D435: 1 m → 0.08 / (447 · 0.05) = 3.58 mm; quadratic in z.
        let d = SensorPreset::RealsenseD435;
        assert!((d.sigma_z_m(1.0) - 0.003_579).abs() < 1e-6);
        assert!((d.sigma_z_m(2.0) / d.sigma_z_m(1.0) - 4.0).abs() < 1e-9);
        assert_eq!(SensorPreset::Exact.sigma_z_m(10.0), 0.0);
        assert_eq!(SensorPreset::Lidar.sigma_z_m(30.0), 0.02);
    }

    #[test]
    fn coefficients_parse_from_text_and_json() {
        let c: SensorNoise = "1.5, 0, 2".parse().unwrap();
        assert!((c.sigma_z_m(2.0) - 0.0095).abs() < 1e-12);
        let j: SensorNoise = serde_json::from_str(r#"{"sigma_mm": [1.5, 0, 2]}"#).unwrap();
        assert_eq!(j, c);
        assert!("1,2".parse::<SensorNoise>().is_err());
        assert!(SensorNoise::coefficients([1.0, -4.0, 1.0]).is_err());
        assert!(SensorNoise::coefficients([f64::NAN, 0.0, 1.0]).is_err());
    }

    #[test]
    fn grazing_views_see_less_noise_along_the_normal_and_exact_sees_none() {
        let k = Intrinsics::new(500.0, 500.0, 10.0, 10.0).unwrap();
        let depth = Grid::new(21, 21, 3.0);
        let facing = Grid::new(21, 21, Vec3::new(0.0, 0.0, -1.0));
        let tilted = Grid::new(21, 21, Vec3::new(0.0, -0.8, -0.6));
        let cfg = AnnotateConfig::default();
        let s = SensorNoise::Preset(SensorPreset::KinectV1);
        let a = pixel_noise_map(&depth, &k, &facing, &s, &cfg)[(10, 10)].unwrap();
        let b = pixel_noise_map(&depth, &k, &tilted, &s, &cfg)[(10, 10)].unwrap();
        assert!((b.sigma_normal_m / a.sigma_normal_m - 0.6).abs() < 1e-9);
        let exact = SensorNoise::Preset(SensorPreset::Exact);
        let u = uncertainty_map(&depth, &k, &facing, &exact, &cfg);
        assert!(u.as_slice().iter().all(|&v| v == 0.0));
    }
}
