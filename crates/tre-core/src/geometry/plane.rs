//! Planes: least-squares fits from point moments, planes through three points, and Eq. 1 of the
//! paper (point-to-plane distance).

use nalgebra::Matrix3;

use super::simd::from_fn;
use super::Vec3;

/// A plane through `centroid` with unit `normal`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Plane {
    /// A point on the plane (for LS fits, the mean of the fitted points), metres.
    pub centroid: Vec3,
    /// Unit normal.
    pub normal: Vec3,
}

impl Plane {
    /// The plane through three points, or `None` when they are (nearly) collinear: exactly when
    /// `!(|ab × ac| > 1e-9·|ab|·|ac|)` or `|ab × ac|` is not finite (`ab = b − a`, `ac = c − a`).
    ///
    /// ```
    /// use nalgebra::Vector3;
    /// use tre_core::geometry::Plane;
    /// let p = Plane::through(&Vector3::zeros(), &Vector3::x(), &Vector3::y()).unwrap();
    /// assert!((p.normal.z.abs() - 1.0).abs() < 1e-12);
    /// assert!(Plane::through(&Vector3::zeros(), &Vector3::x(), &(2.0 * Vector3::x())).is_none());
    /// ```
    #[inline(always)]
    pub fn through(a: &Vec3, b: &Vec3, c: &Vec3) -> Option<Self> {
        let (ab, ac) = (b - a, c - a);
        let n = ab.cross(&ac);
        let len = n.norm();
        // Relative test: the sine of the angle between ab and ac must not vanish.
        if !(len > 1e-9 * ab.norm() * ac.norm()) || !len.is_finite() {
            return None;
        }
        Some(Self {
            centroid: *a,
            normal: n / len,
        })
    }

    /// Eq. 1: the distance from `p` to the plane, metres.
    ///
    /// ```
    /// use nalgebra::Vector3;
    /// use tre_core::geometry::Plane;
    /// let ground = Plane { centroid: Vector3::zeros(), normal: Vector3::z() };
    /// assert!((ground.distance(&Vector3::new(3.0, -1.0, 0.25)) - 0.25).abs() < 1e-15);
    /// ```
    pub fn distance(&self, p: &Vec3) -> f64 {
        self.normal.dot(&(p - self.centroid)).abs()
    }

    /// The same plane with its normal flipped, if needed, to face a camera at the origin
    /// (`n · (0 − centroid) ≥ 0`).
    pub fn oriented_towards_camera(mut self) -> Self {
        self.normal = orient_towards_camera(&self.normal, &self.centroid);
        self
    }
}

/// Flips `normal` if needed so that it faces a camera at the origin from `point`.
pub(crate) fn orient_towards_camera(normal: &Vec3, point: &Vec3) -> Vec3 {
    if normal.dot(point) > 0.0 {
        -normal
    } else {
        *normal
    }
}

/// First and second moments of a point set, taken relative to an origin for precision.
///
/// ```
/// use nalgebra::Vector3;
/// use tre_core::geometry::Moments;
/// let mut m = Moments::default();
/// for (x, y) in [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0)] {
///     m.add(&Vector3::new(x, y, 2.0 * x - y));
/// }
/// let plane = m.fit(&Vector3::zeros()).unwrap();
/// let expected = Vector3::new(2.0, -1.0, -1.0).normalize();
/// assert!(plane.normal.dot(&expected).abs() > 1.0 - 1e-12);
/// ```
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Moments {
    /// Number of points.
    pub count: u32,
    /// Σ d.
    pub sum: Vec3,
    /// Σ d dᵀ, upper triangle: xx, xy, xz, yy, yz, zz.
    pub sum_sq: [f64; 6],
}

impl Moments {
    /// Adds a point given relative to the origin the moments are taken about.
    #[inline]
    pub fn add(&mut self, d: &Vec3) {
        self.count += 1;
        self.sum += d;
        let s = &mut self.sum_sq;
        s[0] += d.x * d.x;
        s[1] += d.x * d.y;
        s[2] += d.x * d.z;
        s[3] += d.y * d.y;
        s[4] += d.y * d.z;
        s[5] += d.z * d.z;
    }

    /// The mean point, given the origin the moments were taken about.
    pub fn mean(&self, origin: &Vec3) -> Option<Vec3> {
        (self.count > 0).then(|| origin + self.sum / self.count as f64)
    }

    /// The covariance matrix of the points.
    pub fn covariance(&self) -> Matrix3<f64> {
        sym_matrix(&covariance_lanes(&[*self]), 0)
    }

    /// The least-squares plane (normal = smallest eigenvector of the covariance), or `None` for
    /// fewer than 3 points or a degenerate (collinear) set.
    pub fn fit(&self, origin: &Vec3) -> Option<Plane> {
        if self.count < 3 {
            return None;
        }
        let normal = smallest_eigenvector(&self.covariance())?;
        Some(Plane {
            centroid: self.mean(origin)?,
            normal,
        })
    }
}

/// The unit eigenvector of the smallest eigenvalue of a symmetric positive semi-definite 3×3
/// matrix (a covariance). The smallest eigenvalue is the smallest root of the characteristic
/// cubic, found by Halley's method from 0 (the cubic is positive, decreasing and convex below its
/// smallest root, so the iteration climbs to it); the eigenvector is the largest cross
/// product of two rows of `A − λI`. `None` when the two smallest eigenvalues are not separated
/// by 1e-6 of the largest entry (no unique plane: collinear or isotropic points).
pub(crate) fn smallest_eigenvector(a: &Matrix3<f64>) -> Option<Vec3> {
    let scale = a.abs().max();
    if !(scale > 0.0) || !scale.is_finite() {
        return None;
    }
    let a = sym_lanes(&[a * (1.0 / scale)]);
    let (l_min, l_mid) = smallest_two_eigenvalues(&a);
    eigenvectors_for(&a, &[l_min], &[l_mid])[0]
}

/// The least-squares planes of `N` covariances at once (as [`covariance_lanes`] gives them):
/// each one's unit eigenvector of its smallest eigenvalue, and its two smallest eigenvalues
/// (ascending, in the covariance's units, clamped at 0); `None` for a zero or non-finite
/// matrix, or where the two smallest eigenvalues are not separated by 1e-6 of the largest
/// entry (no unique plane). The solver of [`smallest_eigenvectors`] (Halley's method on the
/// characteristic cubic, in lanes, then the largest cross product of two rows of `A − λI`),
/// so the terrain estimate and the spec solve alike; a lane that has not converged after six
/// steps goes on alone. Each lane's result depends on its own matrix only, bit for bit.
#[inline(always)]
pub(crate) fn eigen_planes<const N: usize>(covs: &SymLanes<N>) -> [Option<(Vec3, f64, f64)>; N] {
    let h = halley_lanes(covs);
    let mut l = h.l_min;
    for ((l, done), cubic) in l.iter_mut().zip(h.done).zip(&h.cubic) {
        if !done {
            *l = smallest_root(cubic, *l);
        }
    }
    let l_mid: [f64; N] = from_fn(|i| next_root(&h.cubic[i], l[i]));
    let vectors = eigenvectors_for(&h.a, &l, &l_mid);
    from_fn(|i| {
        let usable = h.scale[i] > 0.0 && h.scale[i].is_finite();
        let v = vectors[i].filter(|_| usable)?;
        Some((
            v,
            l[i].max(0.0) * h.scale[i],
            l_mid[i].max(0.0) * h.scale[i],
        ))
    })
}

/// [`eigen_planes`] of any number of covariances, solved [`PLANE_LANES`] at a time.
pub(crate) fn eigen_planes_of(covs: &[SymLanes<1>]) -> Vec<Option<(Vec3, f64, f64)>> {
    let mut out = Vec::with_capacity(covs.len());
    for chunk in covs.chunks(PLANE_LANES) {
        // Unused lanes hold the identity: each lane's result is its own matrix's alone.
        let mut lanes = [[1.0; PLANE_LANES]; 6];
        for (l, cov) in chunk.iter().enumerate() {
            for (lane, e) in lanes.iter_mut().zip(cov) {
                lane[l] = e[0];
            }
        }
        out.extend_from_slice(&eigen_planes(&lanes)[..chunk.len()]);
    }
    out
}

/// Covariances solved together by [`eigen_planes_of`].
pub(crate) const PLANE_LANES: usize = 4;

/// The lanes' start: each matrix's largest entry, the matrices divided by it, their
/// characteristic cubics, and their smallest roots after at most six Halley steps from 0 taken
/// together (a lane stops once converged, so its result does not depend on the other lanes).
struct HalleyLanes<const N: usize> {
    scale: [f64; N],
    a: SymLanes<N>,
    cubic: [[f64; 3]; N],
    l_min: [f64; N],
    done: [bool; N],
}

#[inline(always)]
fn halley_lanes<const N: usize>(covs: &SymLanes<N>) -> HalleyLanes<N> {
    let mut scale = [0.0f64; N];
    for e in covs {
        for (s, v) in scale.iter_mut().zip(e) {
            *s = s.max(v.abs());
        }
    }
    let inv: [f64; N] = from_fn(|l| 1.0 / scale[l]);
    let a: SymLanes<N> = from_fn(|e| from_fn(|l| covs[e][l] * inv[l]));
    let cubic: [[f64; 3]; N] = from_fn(|l| char_poly(&a, l));
    let (mut l, mut done) = ([0.0f64; N], [false; N]);
    for _ in 0..6 {
        for i in 0..N {
            let step = halley_step(&cubic[i], l[i]);
            let next = if done[i] { l[i] } else { l[i] - step };
            done[i] = done[i] || step.abs() <= 1e-13 * (1.0 + next.abs());
            l[i] = next;
        }
        if done.iter().all(|&d| d) {
            break;
        }
    }
    HalleyLanes {
        scale,
        a,
        cubic,
        l_min: l,
        done,
    }
}

/// [`eigen_planes`] of one covariance.
pub(crate) fn eigen_plane(cov: &SymLanes<1>) -> Option<(Vec3, f64, f64)> {
    eigen_planes(cov)[0]
}

/// Symmetric 3×3 matrices in lanes (structure of arrays): the entries xx, xy, xz, yy, yz, zz,
/// each an array over the lanes.
pub(crate) type SymLanes<const N: usize> = [[f64; N]; 6];

/// The (row, column) of each entry of [`SymLanes`]: xx, xy, xz, yy, yz, zz.
const SYM_AXES: [(usize, usize); 6] = [(0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2)];

/// Symmetric matrices `m` in lanes.
fn sym_lanes<const N: usize>(m: &[Matrix3<f64>; N]) -> SymLanes<N> {
    from_fn(|e| m.map(|m| m[SYM_AXES[e]]))
}

/// Lane `l` of `a` as a matrix.
fn sym_matrix<const N: usize>(a: &SymLanes<N>, l: usize) -> Matrix3<f64> {
    let [xx, xy, xz, yy, yz, zz] = a.each_ref().map(|e| e[l]);
    Matrix3::new(xx, xy, xz, xy, yy, yz, xz, yz, zz)
}

/// The covariance matrices of `m` in lanes ([`Moments::covariance`] is one lane of it).
#[inline(always)]
pub(crate) fn covariance_lanes<const N: usize>(m: &[Moments; N]) -> SymLanes<N> {
    let inv_n: [f64; N] = from_fn(|l| 1.0 / f64::from(m[l].count.max(1)));
    let mean: [[f64; N]; 3] = from_fn(|a| from_fn(|l| m[l].sum[a] * inv_n[l]));
    from_fn(|e| {
        let (i, j) = SYM_AXES[e];
        from_fn(|l| m[l].sum_sq[e] * inv_n[l] - mean[i][l] * mean[j][l])
    })
}

/// The normals of [`Moments::fit`] for `N` sets of moments at once, solved over lanes
/// ([`covariance_lanes`], [`smallest_eigenvectors`]): `None` with fewer than 3 points or no
/// unique plane. Same normals as [`Moments::fit`] up to rounding.
#[inline(always)]
pub(crate) fn fit_normals<const N: usize>(m: &[Moments; N]) -> [Option<Vec3>; N] {
    let fits = smallest_eigenvectors(&covariance_lanes(m));
    from_fn(|l| fits[l].filter(|_| m[l].count >= 3))
}

/// [`smallest_eigenvector`] for `N` matrices at once: scaling, the characteristic cubic and the
/// Halley iterations run over lane arrays (so they vectorise and overlap) until every lane has
/// converged, at most six times; a lane that has not converged by then is finished by the
/// scalar solver. Same results as the scalar solver up to rounding, and each lane's result
/// depends on its own matrix only, bit for bit, whatever the other lanes hold.
#[inline(always)]
pub(crate) fn smallest_eigenvectors<const N: usize>(covs: &SymLanes<N>) -> [Option<Vec3>; N] {
    let HalleyLanes {
        scale,
        a,
        cubic: c,
        l_min: l,
        done,
    } = halley_lanes(covs);
    let l_mid: [f64; N] = from_fn(|i| next_root(&c[i], l[i]));
    let vectors = eigenvectors_for(&a, &l, &l_mid);
    from_fn(|i| {
        if !(scale[i] > 0.0) || !scale[i].is_finite() {
            None
        } else if done[i] {
            vectors[i]
        } else {
            smallest_eigenvector(&sym_matrix(covs, i))
        }
    })
}

/// The lanes' unit eigenvectors of eigenvalues `l_min` of the normalised matrices `a`, given
/// their next eigenvalues `l_mid`: the largest cross product of two rows of `A − λI`; `None`
/// unless `l_min` and `l_mid` are separated by 1e-6.
#[inline(always)]
fn eigenvectors_for<const N: usize>(
    a: &SymLanes<N>,
    l_min: &[f64; N],
    l_mid: &[f64; N],
) -> [Option<Vec3>; N] {
    let [xx, xy, xz, yy, yz, zz] = a;
    let mut best = [[0.0f64; N]; 3];
    let mut len = [0.0f64; N];
    for i in 0..N {
        let r0 = [xx[i] - l_min[i], xy[i], xz[i]];
        let r1 = [xy[i], yy[i] - l_min[i], yz[i]];
        let r2 = [xz[i], yz[i], zz[i] - l_min[i]];
        let cross = |u: [f64; 3], v: [f64; 3]| {
            [
                u[1] * v[2] - u[2] * v[1],
                u[2] * v[0] - u[0] * v[2],
                u[0] * v[1] - u[1] * v[0],
            ]
        };
        let norm2 = |v: [f64; 3]| v[0] * v[0] + v[1] * v[1] + v[2] * v[2];
        let mut b = cross(r0, r1);
        for c in [cross(r0, r2), cross(r1, r2)] {
            if norm2(c) > norm2(b) {
                b = c;
            }
        }
        len[i] = norm2(b).sqrt();
        for (axis, v) in best.iter_mut().zip(b) {
            axis[i] = v / len[i];
        }
    }
    from_fn(|i| {
        let separated = l_mid[i] - l_min[i] > 1e-6;
        (separated && len[i] > 0.0 && len[i].is_finite())
            .then(|| Vec3::new(best[0][i], best[1][i], best[2][i]))
    })
}

/// The two smallest eigenvalues (ascending) of a symmetric PSD 3×3 matrix.
fn smallest_two_eigenvalues(a: &SymLanes<1>) -> (f64, f64) {
    let c = char_poly(a, 0);
    let l = smallest_root(&c, 0.0);
    (l, next_root(&c, l))
}

/// The smallest root of the characteristic cubic `c` by Halley's method from `l` (at most the
/// root): cubic convergence, and monotone like Newton's on this side of the smallest root
/// (f > 0, f' < 0, f'' > 0 there).
fn smallest_root(c: &[f64; 3], mut l: f64) -> f64 {
    for _ in 0..100 {
        let step = halley_step(c, l);
        l -= step;
        if step.abs() <= 1e-15 * (1.0 + l.abs()) {
            break;
        }
    }
    l
}

/// `[c2, c1, c0]` of `det(A − λI) = −λ³ + c2·λ² − c1·λ + c0` for lane `l` of `a` (the
/// trace, the sum of the principal 2×2 minors and the determinant, with nalgebra's operations).
#[inline(always)]
fn char_poly<const N: usize>(a: &SymLanes<N>, l: usize) -> [f64; 3] {
    let [xx, xy, xz, yy, yz, zz] = a.each_ref().map(|e| e[l]);
    let c1 = xx * yy - xy * xy + xx * zz - xz * xz + yy * zz - yz * yz;
    let det = xx * (yy * zz - yz * yz) - xy * (xy * zz - xz * yz) + xz * (xy * yz - xz * yy);
    [xx + yy + zz, c1, det]
}

/// One Halley step for the characteristic cubic at `l` (0 where it is flat).
#[inline(always)]
fn halley_step(&[c2, c1, c0]: &[f64; 3], l: f64) -> f64 {
    let f = ((-l + c2) * l - c1) * l + c0;
    let df = (-3.0 * l + 2.0 * c2) * l - c1;
    let ddf = -6.0 * l + 2.0 * c2;
    let denom = 2.0 * df * df - f * ddf;
    if denom != 0.0 {
        2.0 * f * df / denom
    } else {
        0.0
    }
}

/// The smaller of the other two roots, given root `l`: their sum is `c2 − l`, their product
/// `c1 − l·(c2 − l)`.
#[inline(always)]
fn next_root(&[c2, c1, _]: &[f64; 3], l: f64) -> f64 {
    let s = c2 - l;
    let q = c1 - l * s;
    0.5 * (s - (s * s - 4.0 * q).max(0.0).sqrt())
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;
    use nalgebra::Vector3;

    #[test]
    fn eigenvector_of_diagonal() {
        let a = Matrix3::from_diagonal(&Vector3::new(3.0, 0.5, 2.0));
        let v = smallest_eigenvector(&a).unwrap();
        assert_relative_eq!(v.y.abs(), 1.0, epsilon = 1e-12);
    }

    #[test]
    fn eigenvector_of_rotated_matrix() {
        let r = nalgebra::Rotation3::from_euler_angles(0.3, -1.1, 0.7);
        let a = r.matrix()
            * Matrix3::from_diagonal(&Vector3::new(1.0, 4.0, 1e-6))
            * r.matrix().transpose();
        let v = smallest_eigenvector(&a).unwrap();
        let expected = r.matrix().column(2).into_owned();
        assert_relative_eq!(v.dot(&expected).abs(), 1.0, epsilon = 1e-10);
    }

    #[test]
    fn lane_solver_matches_the_scalar_one() {
        let r = nalgebra::Rotation3::from_euler_angles(0.3, -1.1, 0.7);
        let covs = [
            r.matrix()
                * Matrix3::from_diagonal(&Vector3::new(1.0, 4.0, 1e-6))
                * r.matrix().transpose(),
            Matrix3::from_diagonal(&Vector3::new(3.0, 0.5, 2.0)),
            Matrix3::from_diagonal(&Vector3::new(1.0, 0.0, 0.0)),
            r.matrix()
                * Matrix3::from_diagonal(&Vector3::new(1.0, 0.9, 0.6))
                * r.matrix().transpose()
                * 1e-4,
        ];
        let batch = smallest_eigenvectors(&sym_lanes(&covs));
        for (c, b) in covs.iter().zip(batch) {
            match (smallest_eigenvector(c), b) {
                (Some(s), Some(b)) => assert_relative_eq!(s.dot(&b).abs(), 1.0, epsilon = 1e-12),
                (s, b) => assert_eq!(s, b),
            }
        }
        assert!(batch[2].is_none());
    }

    #[test]
    fn a_lane_gives_the_same_bits_whatever_the_other_lanes_hold() {
        // Random covariances of points near planes, with spreads from isotropic to flat.
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let mut next = move || {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1);
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        let covs: Vec<Matrix3<f64>> = (0..256)
            .map(|_| {
                let r = nalgebra::Rotation3::from_euler_angles(next() * 6.3, next() * 6.3, next());
                let d = Vector3::new(1.0, 0.2 + next(), next().powi(6));
                r.matrix() * Matrix3::from_diagonal(&d) * r.matrix().transpose() * next()
            })
            .collect();
        for batch in covs.chunks_exact(8) {
            let batch: &[Matrix3<f64>; 8] = batch.try_into().expect("whole chunks");
            let together = smallest_eigenvectors(&sym_lanes(batch));
            for (l, c) in batch.iter().enumerate() {
                let alone = smallest_eigenvectors(&sym_lanes(&[*c; 8]))[0];
                assert_eq!(alone, together[l]);
            }
        }
    }

    #[test]
    fn collinear_points_have_no_plane() {
        let mut m = Moments::default();
        for t in 0..10 {
            m.add(&(Vector3::new(1.0, 2.0, 3.0) * t as f64));
        }
        assert!(m.fit(&Vector3::zeros()).is_none());
    }
}
