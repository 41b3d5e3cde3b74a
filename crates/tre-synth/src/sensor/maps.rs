//! The per-frame maps the pixels read: correlated noise, flying-pixel neighbours, fattened
//! edges, texture, the projector's shadow, concavity and the LiDAR's beam pattern.

use image::RgbImage;

use super::{normal, SensorInput, SensorModel, Stream};
use tre_core::geometry::{Grid, Intrinsics};

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
pub(super) fn flying_mask(model: &SensorModel, depth_m: &Grid<f64>) -> Grid<Option<f64>> {
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
pub(super) fn fatten(depth_m: &Grid<f64>, r: usize) -> Grid<f64> {
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
pub(super) fn texture(rgb: &RgbImage, r: usize) -> Grid<f64> {
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
pub(super) fn concavity(input: &SensorInput<'_>, scale: f64) -> Grid<f64> {
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
}
