//! Deterministic procedural noise for terrain and textures: hashed lattice values, smooth value
//! noise, fractal sums and Worley (cellular) features. Pure functions of (seed, position).

use tre_core::geometry::hash::splitmix64;

/// A uniform value in [0, 1) for integer lattice point `(i, j)` under `seed`.
#[inline]
pub fn lattice(seed: u64, i: i64, j: i64) -> f64 {
    let h = splitmix64(
        splitmix64(seed ^ (i as u64).wrapping_mul(0x9E37_79B9))
            ^ (j as u64).wrapping_mul(0x85EB_CA6B),
    );
    (h >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
}

#[inline]
fn smooth(t: f64) -> f64 {
    t * t * t * (t * (t * 6.0 - 15.0) + 10.0)
}

/// Smooth value noise in [−1, 1] with unit lattice spacing (C² quintic interpolation).
pub fn value(seed: u64, x: f64, y: f64) -> f64 {
    let (xi, yi) = (x.floor(), y.floor());
    let (fx, fy) = (smooth(x - xi), smooth(y - yi));
    let (i, j) = (xi as i64, yi as i64);
    let v00 = lattice(seed, i, j);
    let v10 = lattice(seed, i + 1, j);
    let v01 = lattice(seed, i, j + 1);
    let v11 = lattice(seed, i + 1, j + 1);
    let a = v00 + (v10 - v00) * fx;
    let b = v01 + (v11 - v01) * fx;
    2.0 * (a + (b - a) * fy) - 1.0
}

/// Fractal sum of `octaves` value-noise layers, each at twice the frequency and half the
/// amplitude of the last, normalised to about [−1, 1]. `scale_m` is the first layer's period.
pub fn fbm(seed: u64, x: f64, y: f64, scale_m: f64, octaves: u32) -> f64 {
    let (mut sum, mut amp, mut norm, mut f) = (0.0, 1.0, 0.0, 1.0 / scale_m);
    for o in 0..octaves {
        sum += amp * value(seed.wrapping_add(u64::from(o) * 7919), x * f, y * f);
        norm += amp;
        amp *= 0.5;
        f *= 2.0;
    }
    sum / norm
}

/// The nearest feature point of a jittered grid of cell size `cell_m`: returns the distance to
/// it, metres, and a per-feature random value in [0, 1) (for sizes and colours).
pub fn worley(seed: u64, x: f64, y: f64, cell_m: f64) -> (f64, f64) {
    let (gx, gy) = (x / cell_m, y / cell_m);
    let (ci, cj) = (gx.floor() as i64, gy.floor() as i64);
    let mut best = (f64::INFINITY, 0.0);
    for dj in -1..=1 {
        for di in -1..=1 {
            let (i, j) = (ci + di, cj + dj);
            let fx = i as f64 + lattice(seed, i, j);
            let fy = j as f64 + lattice(seed ^ 0x5555, i, j);
            let d = ((gx - fx).powi(2) + (gy - fy).powi(2)).sqrt() * cell_m;
            if d < best.0 {
                best = (d, lattice(seed ^ 0xAAAA, i, j));
            }
        }
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn value_noise_is_bounded_continuous_and_deterministic() {
        for k in 0..1000 {
            let (x, y) = (k as f64 * 0.137, k as f64 * -0.071);
            let v = value(3, x, y);
            assert!((-1.0..=1.0).contains(&v));
            assert_eq!(v, value(3, x, y));
            assert!((value(3, x + 1e-7, y) - v).abs() < 1e-5);
        }
    }

    #[test]
    fn worley_distance_is_small() {
        for k in 0..100 {
            let (d, r) = worley(1, k as f64 * 0.31, 0.2, 0.05);
            assert!(d <= 0.05 * 1.5 && (0.0..1.0).contains(&r));
        }
    }
}
