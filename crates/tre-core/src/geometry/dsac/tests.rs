use super::*;
use crate::geometry::hash::uniform;
use proptest::prelude::*;

#[test]
fn no_candidate_adds_more_than_the_pruning_bound() {
    let scorer = Scorer::new(&DsacConfig::default());
    let tau = scorer.tau;
    // Every f32 y within 4096 ulps above −τ″, then a fine sweep up to the clamp.
    let ulps = (0..4096u32).map(|i| f32::from_bits((-tau).to_bits() - i));
    let sweep = (0..200_000).map(|i| -tau + i as f32 * 1e-3);
    for y in ulps.chain(sweep) {
        assert!(y >= -tau);
        assert!(recip_one_plus_exp2(y) <= scorer.most, "y = {y}");
    }
    assert!(scorer.most < 0.994 && scorer.most > 0.993);
}

/// The sampler exactly as the module docs define it, by linear scans.
fn reference_triple(
    rho: &[f64; CANDIDATES],
    seed: u64,
    pixel: u64,
    hyp: u32,
) -> Option<[usize; 3]> {
    let mut prefix = [0.0; CANDIDATES];
    let mut acc = 0.0;
    for k in 0..CANDIDATES {
        acc += rho[k];
        prefix[k] = acc;
    }
    let mut drawn: Vec<usize> = Vec::new();
    let mut total = prefix[CANDIDATES - 1];
    for d in 0..3u32 {
        if let Some(&e) = drawn.last() {
            total -= rho[e];
        }
        if !(total > 0.0) {
            return None;
        }
        let t = uniform(seed, pixel, hyp, d) * total;
        let f = |k: usize| {
            let mut v = prefix[k];
            for &e in &drawn {
                v -= if k >= e { rho[e] } else { 0.0 };
            }
            v
        };
        let ok = |k: usize| !drawn.contains(&k) && rho[k] > 0.0;
        let pick = (0..CANDIDATES)
            .find(|&k| ok(k) && t < f(k))
            .or_else(|| (0..CANDIDATES).rev().find(|&k| ok(k)))?;
        drawn.push(pick);
    }
    Some([drawn[0], drawn[1], drawn[2]])
}

/// One ρ entry: mostly zeros, tiny values, exact ties or random magnitudes.
fn rho_entry() -> impl Strategy<Value = f64> {
    prop_oneof![
        4 => Just(0.0),
        1 => Just(f64::from_bits(1)),
        1 => Just(1e-300),
        1 => Just(1e-17),
        2 => Just(0.25),
        2 => Just(1.0 / 3.0),
        1 => Just(7.0),
        3 => 0.0..1.0f64,
        1 => (-40.0..0.0f64).prop_map(f64::exp2),
    ]
}

/// One ρ entry of a sparse ρ: mostly zeros and tiny values, and a few large ones, so that
/// the remaining mass after large draws is made of rounding errors.
fn sparse_rho_entry() -> impl Strategy<Value = f64> {
    prop_oneof![
        14 => Just(0.0),
        2 => Just(f64::from_bits(1)),
        2 => Just(0.3 * f64::EPSILON),
        2 => Just(1e-17),
        2 => (-70.0..-40.0f64).prop_map(f64::exp2),
        1 => Just(1.0),
        1 => Just(0.75),
        1 => 0.5..4.0f64,
    ]
}

fn rho_vec() -> impl Strategy<Value = [f64; CANDIDATES]> {
    let entries = prop_oneof![
        prop::collection::vec(rho_entry(), CANDIDATES),
        prop::collection::vec(sparse_rho_entry(), CANDIDATES),
    ];
    entries.prop_map(|v| {
        let mut rho = [0.0; CANDIDATES];
        rho.copy_from_slice(&v);
        rho
    })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(2000))]
    #[test]
    fn fast_sampler_equals_linear_scan(rho in rho_vec(), seed in any::<u64>(), pixel in any::<u64>()) {
        for hyp in 0..48 {
            let p = pixel.wrapping_add(u64::from(hyp / 8));
            prop_assert_eq!(sample_triple(&rho, seed, p, hyp), reference_triple(&rho, seed, p, hyp));
        }
    }

    #[test]
    fn fast_sampler_equals_linear_scan_on_softmax(logits in prop::array::uniform32(-30.0..30.0f32), seed in any::<u64>()) {
        let points = Grid::new(7, 7, Vec3::new(0.0, 0.0, 1.0));
        let mut all = [0.0; CANDIDATES];
        all[..32].copy_from_slice(&logits);
        all[32..].copy_from_slice(&logits[..17]);
        let rho = candidate_probabilities(&all, &candidates(&points, 3, 3));
        for hyp in 0..24 {
            prop_assert_eq!(sample_triple(&rho, seed, 5, hyp), reference_triple(&rho, seed, 5, hyp));
        }
    }
}

#[test]
fn sampler_handles_unsafe_rho_by_scanning() {
    let mut rho = [0.1; CANDIDATES];
    rho[5] = -0.3;
    rho[9] = f64::NAN;
    rho[30] = f64::INFINITY;
    for hyp in 0..50 {
        assert_eq!(
            sample_triple(&rho, 3, 8, hyp),
            reference_triple(&rho, 3, 8, hyp)
        );
    }
}

#[test]
fn probabilities_match_the_f64_softmax() {
    let points = Grid::from_fn(7, 7, |x, _| {
        if x == 2 {
            INVALID_POINT
        } else {
            Vec3::new(0.0, 0.0, 1.0)
        }
    });
    let cands = candidates(&points, 3, 3);
    let logits: [f32; CANDIDATES] = std::array::from_fn(|k| ((k * 37) % 23) as f32 - 11.5);
    let rho = candidate_probabilities(&logits, &cands);
    let valid = |k: usize| k % WINDOW != 2;
    let e: Vec<f64> = (0..CANDIDATES)
        .map(|k| {
            if valid(k) {
                (f64::from(logits[k]) - 11.5).exp()
            } else {
                0.0
            }
        })
        .collect();
    let total: f64 = e.iter().sum();
    for k in 0..CANDIDATES {
        approx::assert_relative_eq!(rho[k], e[k] / total, max_relative = 4e-7);
    }
}

#[test]
fn non_finite_logits_get_no_probability() {
    let points = Grid::new(7, 7, Vec3::new(0.0, 0.0, 1.0));
    let mut logits = [1.0; CANDIDATES];
    logits[3] = f32::NAN;
    logits[4] = f32::INFINITY;
    let rho = candidate_probabilities(&logits, &candidates(&points, 3, 3));
    assert_eq!((rho[3], rho[4]), (0.0, 0.0));
    approx::assert_relative_eq!(rho[0], 1.0 / 47.0, max_relative = 1e-6);
    let none = candidate_probabilities(&[f32::NAN; CANDIDATES], &candidates(&points, 3, 3));
    assert!(none.iter().all(|&r| r == 0.0));
}

/// A bumpy surface seen from 1.5 m, with a 2 cm step along a diagonal and some holes.
fn bumpy(w: usize, h: usize) -> PointMap {
    Grid::from_fn(w, h, |x, y| {
        let (u, v) = (x as f64 * 0.004, y as f64 * 0.004);
        let step = if x + y > w { 0.02 } else { 0.0 };
        let z = 1.5 + 0.3 * u + 0.006 * (x as f64 * 1.7).sin() * (y as f64 * 2.3).cos() + step;
        if (x * 7 + y * 3) % 17 == 0 {
            INVALID_POINT
        } else {
            Vec3::new(u - 0.1, v - 0.1, z)
        }
    })
}

#[test]
fn f32_scores_match_the_f64_formula() {
    let points = bumpy(20, 20);
    let cfg = DsacConfig::default();
    let scorer = Scorer::new(&cfg);
    let cands = candidates(&points, 9, 11);
    let padded = PaddedPoints::of_candidates(&cands);
    let window = Window::new(&padded, RADIUS, RADIUS);
    for [a, b, c] in [[0, 24, 48], [3, 20, 40], [10, 11, 30], [6, 42, 24]] {
        let plane = Plane::through(&cands[a], &cands[b], &cands[c]).unwrap();
        let reference: f64 = cands
            .iter()
            .filter(|q| is_valid_point(q))
            .map(|q| cfg.soft_inlier(plane.distance(q)))
            .sum();
        let fast = f64::from(window.full_score(&window.hyp32(&plane, &scorer)));
        assert!((fast - reference).abs() < 2e-5, "{fast} vs {reference}");
    }
}

#[test]
fn pixel_hypotheses_agree_with_dsac_normals() {
    // 19 columns: two whole groups of refits and a partial one.
    let (w, h) = (19, 12);
    let points = bumpy(w, h);
    let logits: Vec<f32> = (0..CANDIDATES * w * h)
        .map(|i| ((i * 2_654_435_761usize) % 1000) as f32 / 250.0)
        .collect();
    // One hypothesis, fewer than a batch, a batch, and two batches (pruning across them).
    for hypotheses in [1, 4, 12, 20] {
        let cfg = DsacConfig {
            seed: 5,
            hypotheses,
            ..Default::default()
        };
        check_pixels_against_frame(&points, &logits, &cfg);
    }
}

/// [`pixel_hypotheses`] against [`dsac_normals`] at every pixel of `points`.
fn check_pixels_against_frame(points: &PointMap, logits: &[f32], cfg: &DsacConfig) {
    let (w, h) = points.size();
    let normals = dsac_normals(points, logits, cfg).unwrap();
    for (x, y) in (0..h).flat_map(|y| (0..w).map(move |x| (x, y))) {
        let i = y * w + x;
        let cands = candidates(points, x, y);
        let px_logits: [f32; CANDIDATES] = std::array::from_fn(|k| logits[k * w * h + i]);
        let rho = candidate_probabilities(&px_logits, &cands);
        let hyp = pixel_hypotheses(&cands, &rho, i as u64, cfg);
        assert_eq!(hyp.triples.len(), cfg.hypotheses as usize);
        let expected = match is_valid_point(&points[(x, y)]) {
            true => hyp.normal.unwrap_or(INVALID_POINT),
            false => INVALID_POINT,
        };
        let got = normals[(x, y)];
        let bits = |v: &Vec3| v.map(f64::to_bits);
        let k = cfg.hypotheses;
        assert_eq!(bits(&got), bits(&expected), "pixel ({x}, {y}), K = {k}");
        for (t, s) in hyp.triples.iter().zip(&hyp.scores) {
            assert_eq!(
                t.is_some_and(|[a, b, c]| {
                    Plane::through(&cands[a], &cands[b], &cands[c]).is_some()
                }),
                *s > f64::NEG_INFINITY
            );
        }
    }
}

#[test]
fn reused_buffers_give_the_same_normals_at_any_size() {
    let cfg = DsacConfig::default();
    let logits = |w: usize, h: usize| -> Vec<f32> {
        (0..CANDIDATES * w * h)
            .map(|i| ((i * 2_654_435_761) % 997) as f32 / 300.0)
            .collect()
    };
    let bits = |g: &Grid<Vec3>| -> Vec<[u64; 3]> {
        g.as_slice()
            .iter()
            .map(|v| [v.x, v.y, v.z].map(f64::to_bits))
            .collect()
    };
    let (mut scratch, mut out) = (DsacScratch::default(), Grid::default());
    // Larger, smaller, then larger again: stale values must never leak through.
    for (w, h) in [(20, 16), (9, 13), (23, 11)] {
        let (points, logits) = (bumpy(w, h), logits(w, h));
        dsac_normals_into(&points, &logits, &cfg, &mut scratch, &mut out).unwrap();
        let fresh = dsac_normals(&points, &logits, &cfg).unwrap();
        assert_eq!(out.size(), (w, h));
        assert_eq!(bits(&out), bits(&fresh), "{w}×{h}");
    }
}

#[test]
fn fewer_hypotheses_are_the_first_ones_of_more() {
    let points = bumpy(12, 12);
    let cands = candidates(&points, 6, 6);
    let logits: [f32; CANDIDATES] = std::array::from_fn(|k| (k % 7) as f32 * 0.3);
    let rho = candidate_probabilities(&logits, &cands);
    let run = |hypotheses| {
        let cfg = DsacConfig {
            seed: 9,
            hypotheses,
            ..Default::default()
        };
        pixel_hypotheses(&cands, &rho, 77, &cfg)
    };
    let all = run(24);
    let best_score = |h: &PixelHypotheses| h.best.map(|j| h.scores[j]);
    let mut last_best = f64::NEG_INFINITY;
    for k in [1, 2, 4, 12, 13, 24] {
        let few = run(k);
        assert_eq!(few.triples[..], all.triples[..k as usize], "K = {k}");
        assert_eq!(few.scores[..], all.scores[..k as usize], "K = {k}");
        let best = best_score(&few).unwrap();
        assert!(best >= last_best, "K = {k}: {best} < {last_best}");
        last_best = best;
    }
    // The triples differ between hypotheses: more of them are more chances.
    assert!(all.triples.iter().any(|t| *t != all.triples[0]));
}

#[test]
fn best_is_the_first_largest_score() {
    let points = bumpy(12, 12);
    let cands = candidates(&points, 6, 6);
    let rho = candidate_probabilities(&[0.0; CANDIDATES], &cands);
    let hyp = pixel_hypotheses(&cands, &rho, 3, &DsacConfig::default());
    let best = hyp.best.unwrap();
    let max = hyp.scores.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    assert_eq!(hyp.scores[best], max);
    assert!(hyp.scores[..best].iter().all(|&s| s < max));
}

/// DSAC normals of a bumpy 70 × 45 frame with holes and pseudo-random logits, to the bit: a
/// change meant for speed only must keep this digest (both compiled versions of the row kernel
/// give these bits). It held for a row kernel that read its logits pixel-major.
#[test]
fn dsac_normals_keep_their_digest() {
    let (w, h) = (70, 45);
    let k = crate::geometry::Intrinsics::from_hfov(w, h, 60.0).unwrap();
    let depth = Grid::from_fn(w, h, |x, y| {
        let (u, v) = (x as f64 / w as f64, y as f64 / h as f64);
        match (x * 7 + y * 11) % 23 {
            0 => 0.0,
            _ => 1.5 + 0.4 * v + 0.02 * (u * 40.0).sin() * (v * 25.0).cos(),
        }
    });
    let points = k.back_project_map(&depth);
    let logits: Vec<f32> = (0..CANDIDATES * w * h)
        .map(|i| (uniform(7, i as u64, 0, 0) * 8.0 - 4.0) as f32)
        .collect();
    let out = dsac_normals(&points, &logits, &DsacConfig::default()).unwrap();
    let found = out.as_slice().iter().filter(|n| n.x.is_finite()).count();
    let digest = crate::geometry::hash::digest(
        out.as_slice()
            .iter()
            .flat_map(|n| n.iter().map(|&v| crate::geometry::hash::f64_bits(v))),
    );
    assert!(found > w * h * 3 / 4, "{found} normals");
    if std::env::var("TRE_PRINT_DIGEST").is_ok() {
        eprintln!("dsac digest {digest:016x}");
    }
    assert_eq!(format!("{digest:016x}"), "4193aa64fd31358c");
}
