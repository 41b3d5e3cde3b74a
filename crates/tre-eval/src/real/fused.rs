//! A reference that is not the frame's own raw depth: the depth of a posed frame fused from the
//! neighbouring frames of its sequence part (`tre eval --real … --reference fused`). Each
//! neighbour's points move into the frame's camera by the poses; where one lands on a pixel
//! whose depth it agrees with, it joins that pixel's mean. The sensor's noise, independent
//! from view to view, averages out over the views while the surface stays; the spec on the
//! fused depth is the reference every mode (the `geometric` one included) is scored against.

use serde::Serialize;

use super::*;

/// What the real-frame benchmark scores against.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
#[serde(rename_all = "snake_case")]
pub enum Reference {
    /// Annotation spec v1 on the frame's own sensor depth (`tre annotate`): the definition on
    /// that depth, noise included, so not a truth for the modes that read it.
    #[default]
    Raw,
    /// The spec on depth fused from the neighbouring posed frames (frames without a pose are
    /// left out).
    Fused,
}

/// Settings of the fused reference.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct FuseConfig {
    /// Neighbours on each side of the frame in its sequence's list, among the frames scored.
    pub views: usize,
    /// Fewest samples (the frame's own included) for a pixel to have a reference.
    pub min_samples: u32,
    /// Depth agreement: a neighbour's point joins a pixel when within this plus
    /// `agree_per_m` × depth of the frame's own depth there, metres.
    pub agree_m: f64,
    /// Depth agreement per metre of depth.
    pub agree_per_m: f64,
}

impl Default for FuseConfig {
    fn default() -> Self {
        Self {
            views: 8,
            min_samples: 5,
            agree_m: 0.02,
            agree_per_m: 0.01,
        }
    }
}

/// Per pixel of `target`, the mean of its own depth and the points of `others` that land on
/// it with agreeing depth; 0 where fewer than `cfg.min_samples` samples. Also the sample
/// counts.
pub fn fuse_depth(
    target: &View<'_>,
    others: &[View<'_>],
    cfg: &FuseConfig,
) -> (Grid<f64>, Grid<u32>) {
    let (w, h) = target.depth_m.size();
    let own = target.depth_m.as_slice();
    let mut sum: Vec<f64> = own.iter().map(|&z| if z > 0.0 { z } else { 0.0 }).collect();
    let mut count: Vec<u32> = own.iter().map(|&z| u32::from(z > 0.0)).collect();
    for b in others {
        for (_, j, z) in b.landings(target) {
            let zt = own[j];
            if zt > 0.0 && (zt - z).abs() < cfg.agree_m + cfg.agree_per_m * zt {
                sum[j] += z;
                count[j] += 1;
            }
        }
    }
    let mut fused = Grid::new(w, h, 0.0);
    for ((f, s), &c) in fused.as_mut_slice().iter_mut().zip(&sum).zip(&count) {
        if c >= cfg.min_samples {
            *f = s / f64::from(c);
        }
    }
    let mut counts = Grid::new(w, h, 0u32);
    counts.as_mut_slice().copy_from_slice(&count);
    (fused, counts)
}

impl Reference {
    /// `loaded` with its spec on the reference's depth: unchanged for [`Reference::Raw`];
    /// for [`Reference::Fused`], the spec on the depth fused from the frame's neighbours among
    /// `frames` (same sequence, list index within `cfg.views`, with poses), or `None` when the
    /// frame has no pose or no neighbour.
    ///
    /// # Errors
    ///
    /// When a pose or a neighbour's depth does not read.
    pub fn apply(
        self,
        frame: &RealFrame,
        frames: &[RealFrame],
        cfg: &FuseConfig,
        mut loaded: LoadedFrame,
    ) -> Result<Option<LoadedFrame>, FrameLoadError> {
        if self == Self::Raw {
            return Ok(Some(loaded));
        }
        let (Some(pose), Some(depth_m)) = (Pose::of(frame)?, loaded.input.depth_m.as_ref()) else {
            return Ok(None);
        };
        let mut depths = Vec::new();
        for f in frames {
            let near = f.index.abs_diff(frame.index) <= cfg.views && f.index != frame.index;
            if f.sequence != frame.sequence || !near {
                continue;
            }
            if let Some(p) = Pose::of(f)? {
                let scale = f.camera.depth_scale.unwrap_or(1000.0);
                depths.push((io::read_depth(&f.depth, scale)?, f.intrinsics, p));
            }
        }
        if depths.is_empty() {
            return Ok(None);
        }
        let others: Vec<View<'_>> = depths
            .iter()
            .map(|(d, k, p)| View {
                depth_m: d,
                k: *k,
                pose: *p,
            })
            .collect();
        let target = View {
            depth_m,
            k: frame.intrinsics,
            pose,
        };
        let (fused, _) = fuse_depth(&target, &others, cfg);
        loaded.spec = annotate(
            &AnnotateInput::depth(&fused, &frame.intrinsics),
            &AnnotateConfig::default(),
        )?;
        Ok(Some(loaded))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pose(tx: f64) -> Pose {
        Pose::from_rows([
            [1.0, 0.0, 0.0, tx],
            [0.0, 1.0, 0.0, 0.0],
            [0.0, 0.0, 1.0, 0.0],
            [0.0, 0.0, 0.0, 1.0],
        ])
    }

    #[test]
    fn fusing_views_averages_their_noise_and_keeps_what_only_one_sees_out() {
        let k = Intrinsics {
            fx_px: 100.0,
            fy_px: 100.0,
            cx_px: 50.0,
            cy_px: 50.0,
        };
        // A wall at 2 m, seen from six poses 2 cm apart, each with its own ±1 cm error per
        // pixel (alternating in sign from view to view).
        let noisy = |s: f64| {
            let mut g = Grid::new(100, 100, 2.0);
            for (i, z) in g.as_mut_slice().iter_mut().enumerate() {
                *z += if (i + (s * 100.0) as usize).is_multiple_of(2) {
                    0.01
                } else {
                    -0.01
                };
            }
            g
        };
        let depths: Vec<Grid<f64>> = (0..6).map(|i| noisy(f64::from(i) * 0.02)).collect();
        let views: Vec<View<'_>> = depths
            .iter()
            .enumerate()
            .map(|(i, d)| View {
                depth_m: d,
                k,
                pose: pose(i as f64 * 0.02),
            })
            .collect();
        let cfg = FuseConfig::default();
        let (fused, counts) = fuse_depth(&views[0], &views[1..], &cfg);
        // Away from the edge every view lands: six samples, their errors cancel to within
        // what the rounding of the projection leaves.
        assert_eq!(counts[(50, 50)], 6);
        let err = (fused[(50, 50)] - 2.0).abs();
        assert!(err < 0.004, "fused error {err} m");
        assert!((depths[0][(50, 50)] - 2.0).abs() > 0.009);
        // The leftmost column is seen by the frame alone (the others stand to its right):
        // fewer samples than asked, no reference there.
        assert_eq!(counts[(0, 50)], 1);
        assert_eq!(fused[(0, 50)], 0.0);
        // A view whose depth disagrees (a nearer object) does not join.
        let near = Grid::new(100, 100, 1.0);
        let blocked = View {
            depth_m: &near,
            k,
            pose: pose(0.0),
        };
        let (_, counts) = fuse_depth(&views[0], &[blocked], &cfg);
        assert_eq!(counts[(50, 50)], 1);
    }
}
