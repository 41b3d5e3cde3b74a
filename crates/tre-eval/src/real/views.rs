//! Two views of one surface: camera poses of a real sequence (`poses/NAME.txt` in the
//! sequence folder, a 4×4 camera-to-world matrix in metres, camera x right, y down, z forward,
//! as 7-Scenes writes them) and the pixels two frames share. The spec's value at a point seen
//! from two poses differs by what noise and view do to it: the measured spread that calibrates
//! the `geometric` mode's interval (docs/uncertainty.md).

use super::*;
use tre_io::IoError;

/// A camera-to-world pose.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pose([[f64; 4]; 4]);

/// Depth agreement of a shared pixel: the point must land within this plus
/// [`AGREE_PER_M`] × depth of the other frame's depth (else it is occluded or off the surface).
const AGREE_M: f64 = 0.02;
/// Depth agreement, per metre of depth.
const AGREE_PER_M: f64 = 0.02;

impl Pose {
    /// The pose of `frame`, when its sequence has `poses/NAME.txt` (NAME: the depth file's
    /// stem).
    ///
    /// # Errors
    ///
    /// When the file exists but does not hold 16 numbers.
    pub fn of(frame: &RealFrame) -> Result<Option<Self>, IoError> {
        let depth_rel = Path::new(&frame.depth_rel);
        let Some(seq) = frame.depth.ancestors().nth(depth_rel.components().count()) else {
            return Ok(None);
        };
        let stem = depth_rel
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned());
        let path = seq
            .join("poses")
            .join(format!("{}.txt", stem.unwrap_or_default()));
        if !path.is_file() {
            return Ok(None);
        }
        let v = io::read_pose(&path)?;
        let mut m = [[0.0; 4]; 4];
        for (i, x) in v.into_iter().enumerate() {
            m[i / 4][i % 4] = x;
        }
        Ok(Some(Self(m)))
    }

    /// The pose of a 4×4 camera-to-world matrix, by rows.
    pub fn from_rows(m: [[f64; 4]; 4]) -> Self {
        Self(m)
    }

    /// Camera point to world.
    fn to_world(self, p: [f64; 3]) -> [f64; 3] {
        let m = &self.0;
        std::array::from_fn(|r| m[r][0] * p[0] + m[r][1] * p[1] + m[r][2] * p[2] + m[r][3])
    }

    /// World point to camera (the rotation is orthonormal).
    fn to_camera(self, w: [f64; 3]) -> [f64; 3] {
        let m = &self.0;
        let d = [w[0] - m[0][3], w[1] - m[1][3], w[2] - m[2][3]];
        std::array::from_fn(|c| m[0][c] * d[0] + m[1][c] * d[1] + m[2][c] * d[2])
    }
}

/// One frame of a pair: depth (metres, 0: none), intrinsics, pose.
pub struct View<'a> {
    /// Sensor depth.
    pub depth_m: &'a Grid<f64>,
    /// Intrinsics of the depth map.
    pub k: Intrinsics,
    /// Camera to world.
    pub pose: Pose,
}

/// The pixels two views share.
pub struct ViewPair {
    /// `(pixel of B, pixel of A)` as flat indices, for every pixel of B with depth whose point
    /// lands on a pixel of A with agreeing depth.
    pub shared: Vec<(usize, usize)>,
}

impl View<'_> {
    /// Where the points of this view land in `a`: `(pixel of this view, pixel of a, depth
    /// along a's axis)` for every pixel with depth whose point falls in front of `a` and
    /// inside its image (flat indices; rounded to the nearest pixel).
    pub(super) fn landings<'s>(
        &'s self,
        a: &'s View<'_>,
    ) -> impl Iterator<Item = (usize, usize, f64)> + 's {
        let (wb, _) = self.depth_m.size();
        let (wa, ha) = a.depth_m.size();
        self.depth_m
            .as_slice()
            .iter()
            .enumerate()
            .filter_map(move |(i, &z)| {
                if !(z.is_finite() && z > 0.0) {
                    return None;
                }
                let (x, y) = ((i % wb) as f64, (i / wb) as f64);
                let p = [
                    (x - self.k.cx_px) / self.k.fx_px * z,
                    (y - self.k.cy_px) / self.k.fy_px * z,
                    z,
                ];
                let q = a.pose.to_camera(self.pose.to_world(p));
                if q[2] <= 0.0 {
                    return None;
                }
                let u = (a.k.fx_px * q[0] / q[2] + a.k.cx_px).round();
                let v = (a.k.fy_px * q[1] / q[2] + a.k.cy_px).round();
                let inside = u >= 0.0 && v >= 0.0 && u < wa as f64 && v < ha as f64;
                inside.then(|| (i, v as usize * wa + u as usize, q[2]))
            })
    }
}

impl ViewPair {
    /// The pixels of `b` seen in `a`.
    pub fn new(b: &View<'_>, a: &View<'_>) -> Self {
        let shared = b
            .landings(a)
            .filter(|&(_, j, z)| {
                let za = a.depth_m.as_slice()[j];
                za > 0.0 && (za - z).abs() < AGREE_M + AGREE_PER_M * z
            })
            .map(|(i, j, _)| (i, j))
            .collect();
        Self { shared }
    }
}

/// A frame of a sequence with poses, kept as the next frame's other view: what the `geometric`
/// interval is checked against (`tre eval`) and fitted to (`tre calibrate`).
pub struct PrevView {
    sequence: String,
    index: usize,
    depth_m: Grid<f64>,
    k: Intrinsics,
    pose: Pose,
    spec_m: Grid<f64>,
}

/// The pixels a frame shares with the previous frame of its sequence, with that frame's spec.
pub struct OtherView {
    /// The shared pixels.
    pub pair: ViewPair,
    /// The previous frame's spec.
    pub spec_m: Grid<f64>,
}

impl PrevView {
    /// A frame, kept as the next one's other view.
    pub fn new(frame: &RealFrame, pose: Pose, loaded: LoadedFrame) -> Self {
        Self {
            sequence: frame.sequence.clone(),
            index: frame.index,
            depth_m: loaded.input.depth_m.unwrap_or_else(|| Grid::new(0, 0, 0.0)),
            k: frame.intrinsics,
            pose,
            spec_m: loaded.spec.roughness_m,
        }
    }

    /// The pixels `frame` (at `pose`) shares with this frame, when it is the next one of the
    /// same sequence's list.
    pub fn shared(&self, frame: &RealFrame, pose: Pose, loaded: &LoadedFrame) -> Option<OtherView> {
        let depth_m = loaded.input.depth_m.as_ref()?;
        if self.sequence != frame.sequence || self.index + 1 != frame.index {
            return None;
        }
        let b = View {
            depth_m,
            k: frame.intrinsics,
            pose,
        };
        let a = View {
            depth_m: &self.depth_m,
            k: self.k,
            pose: self.pose,
        };
        Some(OtherView {
            pair: ViewPair::new(&b, &a),
            spec_m: self.spec_m.clone(),
        })
    }
}

/// [`PrevView::shared`] when there is a previous frame and `frame` has a pose.
pub fn shared_with(
    prev: Option<&PrevView>,
    frame: &RealFrame,
    pose: Option<Pose>,
    loaded: &LoadedFrame,
) -> Option<OtherView> {
    prev?.shared(frame, pose?, loaded)
}

impl OtherView {
    /// The previous frame's spec at the pixels of this frame it shares (NaN elsewhere).
    pub fn targets(&self) -> Grid<f64> {
        let (w, h) = self.spec_m.size();
        let mut t = Grid::new(w, h, f64::NAN);
        for &(i, j) in &self.pair.shared {
            t.as_mut_slice()[i] = self.spec_m.as_slice()[j];
        }
        t
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_shifted_camera_sees_a_wall_where_it_should() {
        let k = Intrinsics {
            fx_px: 100.0,
            fy_px: 100.0,
            cx_px: 50.0,
            cy_px: 50.0,
        };
        let wall = Grid::new(100, 100, 2.0);
        let id = Pose([
            [1.0, 0.0, 0.0, 0.0],
            [0.0, 1.0, 0.0, 0.0],
            [0.0, 0.0, 1.0, 0.0],
            [0.0, 0.0, 0.0, 1.0],
        ]);
        // B stands 0.2 m to the right of A: its pixel x sees A's pixel x + 10 at 2 m.
        let mut right = id;
        right.0[0][3] = 0.2;
        let a = View {
            depth_m: &wall,
            k,
            pose: id,
        };
        let b = View {
            depth_m: &wall,
            k,
            pose: right,
        };
        let pair = ViewPair::new(&b, &a);
        assert_eq!(pair.shared.len(), 90 * 100);
        assert!(pair.shared.iter().all(|&(i, j)| j == i + 10));
        // A wall 0.5 m nearer in A hides B's points: nothing agrees.
        let near = Grid::new(100, 100, 1.5);
        let a = View {
            depth_m: &near,
            k,
            pose: id,
        };
        assert!(ViewPair::new(&b, &a).shared.is_empty());
    }
}
