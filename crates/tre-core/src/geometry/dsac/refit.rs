//! The refit (module docs, step 5): the inlier moments of the best plane over f64 lanes, then the eigen-solves.

use super::*;

/// The moments, about `origins[l]`, of the inliers (distance < `tau_m`) of `planes[l]` among
/// the candidates of the window whose candidate 0 is at `base + l` in the padded planes, for
/// each lane `l`: adjacent pixels of a row, solved together. Each lane adds its inliers in `k`
/// order, with the operations of [`Plane::distance`] and [`Moments::add`]; outliers add zeros
/// instead of branching, which leaves every sum unchanged bit for bit (`x + 0.0 = x`, and no
/// sum is −0). So a lane's moments do not depend on `N` or on the other lanes.
#[inline(always)]
pub(super) fn inlier_moments<const N: usize>(
    points: &PaddedPoints,
    base: usize,
    planes: &[Plane; N],
    origins: &[Vec3; N],
    tau_m: f64,
) -> [Moments; N] {
    let by_axis = |v: [Vec3; N]| -> [[f64; N]; 3] { from_fn(|a| v.map(|v| v[a])) };
    let n = by_axis(planes.map(|p| p.normal));
    let c = by_axis(planes.map(|p| p.centroid));
    let o = by_axis(*origins);
    let mut count = [0u64; N];
    // Σd (x, y, z), then Σddᵀ (xx, xy, xz, yy, yz, zz).
    let mut acc = [[0.0f64; N]; 9];
    for k in 0..CANDIDATES {
        let i = base + (k / WINDOW) * points.stride + k % WINDOW;
        let q = points.planes.each_ref().map(|p| {
            p[i..]
                .first_chunk::<N>()
                .expect("the lanes' windows lie inside the padded planes; this is a bug")
        });
        add_inliers(&mut count, &mut acc, q, [&n, &c, &o], tau_m);
    }
    from_fn(|l| Moments {
        count: count[l] as u32,
        sum: Vec3::new(acc[0][l], acc[1][l], acc[2][l]),
        sum_sq: from_fn(|e| acc[3 + e][l]),
    })
}

/// Adds candidate points `q` (one per lane) to the lanes' inlier moments: [`inlier_moments`].
#[inline(always)]
pub(super) fn add_inliers<const N: usize>(
    count: &mut [u64; N],
    acc: &mut [[f64; N]; 9],
    q: [&[f64; N]; 3],
    [n, c, o]: [&[[f64; N]; 3]; 3],
    tau_m: f64,
) {
    for l in 0..N {
        let [qx, qy, qz] = [q[0][l], q[1][l], q[2][l]];
        let dist = ((n[0][l] * (qx - c[0][l]) + n[1][l] * (qy - c[1][l]))
            + n[2][l] * (qz - c[2][l]))
            .abs();
        let mask = if dist < tau_m { u64::MAX } else { 0 };
        // The count in integer lanes (the mask is −1 where kept).
        count[l] = count[l].wrapping_sub(mask);
        let [dx, dy, dz] =
            [qx - o[0][l], qy - o[1][l], qz - o[2][l]].map(|d| f64::from_bits(d.to_bits() & mask));
        acc[0][l] += dx;
        acc[1][l] += dy;
        acc[2][l] += dz;
        acc[3][l] += dx * dx;
        acc[4][l] += dx * dy;
        acc[5][l] += dx * dz;
        acc[6][l] += dy * dy;
        acc[7][l] += dy * dz;
        acc[8][l] += dz * dz;
    }
}

/// A pixel's LS refit before its eigen-solve: the inliers' moments, the best hypothesis' normal
/// (kept if the refit is degenerate) and the centre point.
#[derive(Clone, Copy)]
pub(super) struct Refit {
    pub(super) moments: Moments,
    pub(super) hypothesis: Vec3,
    pub(super) origin: Vec3,
}

/// Pixels whose refits are solved together.
pub(super) const REFIT_LANES: usize = 8;
/// Lanes of one [`inlier_moments`] call in a group.
pub(super) const MOMENT_LANES: usize = 4;

/// Finishes the refits of up to `N` pixels: the LS plane of each one's inliers (the smallest
/// eigenvector of their covariance, solved over lanes), or the hypothesis' normal when there
/// are fewer than 3 inliers or no unique plane; oriented towards the camera. Each lane's
/// result depends only on its own refit.
#[inline(always)]
pub(super) fn finish_refits<const N: usize>(refits: &[Option<Refit>; N]) -> [Option<Vec3>; N] {
    let moments: [Moments; N] = from_fn(|l| refits[l].map_or(Moments::default(), |r| r.moments));
    let fits = fit_normals(&moments);
    from_fn(|l| {
        let r = refits[l]?;
        let n = fits[l].unwrap_or(r.hypothesis);
        Some(orient_towards_camera(&n, &r.origin))
    })
}
