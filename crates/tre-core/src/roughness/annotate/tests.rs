use super::segments::Joiner;
use super::*;

/// Step 6 as the spec writes it, pixel by pixel: the reference for the sparse kernel.
fn transient_reference(edge: &Grid<f64>, points: &PointMap, sigma_px: f64) -> Grid<f64> {
    let (w, h) = edge.size();
    let reach = (3.0 * sigma_px).floor() as isize;
    Grid::from_fn(w, h, |x, y| {
        if !is_valid_point(&points[(x, y)]) {
            return 0.0;
        }
        let mut best: f64 = 0.0;
        for dy in -reach..=reach {
            for dx in -reach..=reach {
                let d2 = (dx * dx + dy * dy) as f64;
                let (nx, ny) = (x as isize + dx, y as isize + dy);
                let inside = nx >= 0 && ny >= 0 && (nx as usize) < w && (ny as usize) < h;
                if d2 > 9.0 * sigma_px * sigma_px || !inside {
                    continue;
                }
                let e = edge[(nx as usize, ny as usize)];
                if e > 0.0 {
                    best = best.max(e * (-d2 / (2.0 * sigma_px * sigma_px)).exp());
                }
            }
        }
        best
    })
}

#[test]
fn sparse_transient_equals_the_per_pixel_definition_bit_for_bit() {
    let (w, h) = (53, 37);
    // Scattered edge terms of varied size, a hole pattern, edges on the frame's border.
    let edge = Grid::from_fn(w, h, |x, y| match (x * 7 + y * 13) % 29 {
        0 => 0.01 + 0.003 * (x % 5) as f64,
        3 if x == 0 || y == h - 1 => 0.2,
        _ if x == w - 1 && y % 4 == 0 => 0.05,
        _ => 0.0,
    });
    let points = Grid::from_fn(w, h, |x, y| {
        if (x * 3 + y * 5) % 11 == 0 {
            INVALID_POINT
        } else {
            Vec3::new(x as f64, y as f64, 2.0)
        }
    });
    for sigma in [0.4, 1.0, 1.5, 2.2] {
        let got = edge_transient(&edge, &points, sigma);
        let want = transient_reference(&edge, &points, sigma);
        let same = got
            .as_slice()
            .iter()
            .zip(want.as_slice())
            .all(|(a, b)| a.to_bits() == b.to_bits());
        assert!(same, "σ = {sigma}");
        assert!(got.as_slice().iter().filter(|&&v| v > 0.0).count() > w * h / 20);
    }
}

#[test]
fn segments_do_not_depend_on_how_rows_are_split() {
    // Two planes meeting at a crease, with holes: the partition into segments is the
    // same as one pass over the whole frame would give.
    let k = Intrinsics::from_hfov(61, 203, 60.0).unwrap();
    let depth = Grid::from_fn(61, 203, |x, y| {
        if (x * 5 + y) % 17 == 0 {
            0.0
        } else {
            1.5 + 0.004 * (x as f64 - 30.0).abs() + 0.2 * ((y / 40) % 2) as f64
        }
    });
    let points = k.back_project_map(&depth);
    let planes = local_planes(&points, k.fx_px, &Neighbourhood::default());
    let cfg = AnnotateConfig::default();
    let got = segment(&points, &planes.normal, None, &cfg);
    let want = segment_serial(&points, &planes.normal, &cfg);
    assert_eq!(got, want);
    assert!(got.as_slice().iter().max().copied().unwrap_or(0) >= 5);
}

/// Step 2 in one serial pass (the reference for the banded union-find).
fn segment_serial(points: &PointMap, normals: &Grid<Vec3>, cfg: &AnnotateConfig) -> Grid<u32> {
    let (w, h) = points.size();
    let joiner = Joiner::new(points, normals, None, cfg);
    let mut forest = DisjointSets::default();
    forest.reset(w * h);
    for y in 0..h {
        for x in 0..w {
            let i = y * w + x;
            if x + 1 < w && joiner.joins(i, i + 1) {
                forest.union(i, i + 1);
            }
            if y + 1 < h && joiner.joins(i, i + w) {
                forest.union(i, i + w);
            }
        }
    }
    let mut out = Grid::default();
    forest.compact_ids(points, &mut out);
    out
}
