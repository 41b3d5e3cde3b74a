//! The supports of the terrain estimate: each pixel's ladder of windows, from the half-width
//! its range asks for up to [`super::MAX_HALF_PX`], until one holds enough points spread in two
//! directions (docs/terrain.md).

use super::{Found, Frame, Support, Window, LADDER};
use crate::geometry::{
    covariance_lanes, eigen_plane, eigen_planes_of, is_valid_point, Moments, SymLanes, Vec3,
};
use crate::roughness::noise::HALF_NORMAL_P95;

impl Frame<'_> {
    /// The smallest support window of pixel `xy` (point `p`) with enough points spread in two
    /// directions, and its plane; else what the largest window with enough points says (one
    /// pixel's [`Self::row_supports`]).
    pub(super) fn support(&self, xy: (usize, usize), p: &Vec3) -> Found {
        let mut ladder = self.ladder(xy, p);
        while let Some((half, m)) = self.next_window(&mut ladder) {
            let cov = covariance_lanes(&[m]);
            let w = Window {
                half,
                m,
                cov,
                plane: eigen_plane(&cov),
            };
            if let Some(found) = self.judge(&mut ladder, &w) {
                return found;
            }
        }
        self.no_plane(&ladder)
    }

    /// The supports of the valid pixels of row `y` ([`Self::support`]), the windows of each
    /// step of their ladders solved four pixels at a time ([`eigen_planes_of`]).
    pub(super) fn row_supports(&self, y: usize) -> Vec<Option<Found>> {
        let w = self.points.size().0;
        let mut found: Vec<Option<Found>> = vec![None; w];
        let mut active: Vec<Ladder> = (0..w)
            .filter_map(|x| {
                let p = self.points[(x, y)];
                is_valid_point(&p).then(|| self.ladder((x, y), &p))
            })
            .collect();
        let mut windows: Vec<(usize, Window)> = Vec::with_capacity(active.len());
        while !active.is_empty() {
            windows.clear();
            active.retain_mut(|ladder| match self.next_window(ladder) {
                Some((half, m)) => {
                    let cov = covariance_lanes(&[m]);
                    let plane = None;
                    windows.push((
                        ladder.xy.0,
                        Window {
                            half,
                            m,
                            cov,
                            plane,
                        },
                    ));
                    true
                }
                None => {
                    found[ladder.xy.0] = Some(self.no_plane(ladder));
                    false
                }
            });
            let covs: Vec<SymLanes<1>> = windows.iter().map(|(_, w)| w.cov).collect();
            for ((_, w), plane) in windows.iter_mut().zip(eigen_planes_of(&covs)) {
                w.plane = plane;
            }
            // `active` and `windows` hold the same pixels, in the same order.
            let mut solved = windows.iter();
            active.retain_mut(|ladder| {
                let (_, w) = solved.next().expect("a window for every active ladder");
                match self.judge(ladder, w) {
                    Some(f) => {
                        found[ladder.xy.0] = Some(f);
                        false
                    }
                    None => true,
                }
            });
        }
        found
    }

    /// The ladder of pixel `xy` (point `p`), at its first window.
    fn ladder(&self, xy: (usize, usize), p: &Vec3) -> Ladder {
        Ladder {
            xy,
            p: *p,
            need: self.need(p.z),
            step: 0,
            smallest: None,
        }
    }

    /// The ladder's next window with enough points, `(half-width, moments)`; `None` past its
    /// last.
    fn next_window(&self, ladder: &mut Ladder) -> Option<(usize, Moments)> {
        let need = ladder.need.0;
        loop {
            let half = match ladder.step {
                0 => need,
                i => LADDER.into_iter().filter(|&l| l > need).nth(i - 1)?,
            };
            ladder.step += 1;
            let m = self.sums.window(ladder.xy, half);
            if m.count >= self.cfg.min_points {
                return Some((half, m));
            }
        }
    }

    /// The support the ladder's window `w` gives, when its points spread in two directions;
    /// `None` to try the next window (the smallest window with a plane is kept for the rough
    /// ground test).
    fn judge(&self, ladder: &mut Ladder, w: &Window) -> Option<Found> {
        let (p, half) = (&ladder.p, w.half);
        let (_, radius, sigma_z, sigma_c) = ladder.need;
        let z = p.z;
        let (normal, l_min, l_mid) = w.plane?;
        let count = f64::from(w.m.count);
        let normal = if normal.dot(p) > 0.0 { -normal } else { normal };
        ladder.smallest.get_or_insert((normal, l_min, count));
        // The points must spread along the plane: over half the metric radius, by more
        // than the noise along the normal (registration included) by `conditioning`,
        // and more than across it (a rough patch still has a plane; a line has none).
        let sigma_n = sigma_z * normal.dot(p).abs() / z;
        let extent = radius.min(half as f64 * z / self.fx_px);
        let noise2 = sigma_n * sigma_n + sigma_c * sigma_c;
        let spread = l_mid >= self.cfg.conditioning * noise2
            && l_mid >= 2.0 * l_min
            && l_mid.sqrt() >= 0.5 * extent;
        let cov = &w.cov;
        spread.then(|| {
            Found::Plane(Support {
                half,
                count,
                centroid: self.origin + w.m.sum / count,
                normal,
                sigma_n,
                sigma_c,
                l_mid,
                l_min,
                l_max: (cov[0][0] + cov[3][0] + cov[5][0] - l_min - l_mid).max(l_mid),
            })
        })
    }

    /// No plane: rough where the scatter off the smallest window's plane exceeds what the
    /// noise (as if the surface faced the camera, its largest) explains by the margin.
    fn no_plane(&self, ladder: &Ladder) -> Found {
        let Some((normal, l_min, count)) = ladder.smallest else {
            return Found::Nothing;
        };
        let (_, _, sigma_z, sigma_c) = ladder.need;
        let noise = sigma_z.hypot(sigma_c);
        let k = self.cfg.debias;
        let excess = (l_min - (k * noise).powi(2)).max(0.0).sqrt();
        if excess > 0.0 {
            let u = k * noise / count.sqrt();
            Found::Rough(HALF_NORMAL_P95 * excess, normal, u)
        } else {
            Found::Nothing
        }
    }
}

/// A pixel's way up the ladder of support windows: its point, the half-width and noise at its
/// range `(half, radius, σ_z, registration σ)`, the next step, and the smallest window's plane
/// so far `(normal, smallest eigenvalue, points)`.
#[derive(Debug, Clone, Copy)]
struct Ladder {
    xy: (usize, usize),
    p: Vec3,
    need: (usize, f64, f64, f64),
    step: usize,
    smallest: Option<(Vec3, f64, f64)>,
}
