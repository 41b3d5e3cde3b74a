//! Repeatable outputs: the same seed gives the same bits, fewer DSAC hypotheses are repeatable,
//! and recycled maps change no output.

use super::*;

#[test]
fn the_same_seed_gives_the_same_output() -> TestResult {
    let frame = read_synth(&synth_frame().1)?;
    let mut pipeline = Pipeline::new(Some(models()?));
    let cfg = PipelineConfig {
        seed: 42,
        ..small(Mode::Rgbd)
    };
    let a = pipeline.run(&frame, &cfg)?;
    let b = pipeline.run(&frame, &cfg)?;
    let bits = |g: &Grid<f64>| g.as_slice().iter().map(|v| v.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&a.roughness_m), bits(&b.roughness_m));
    let (na, nb) = (a.normals().ok_or("normals")?, b.normals().ok_or("normals")?);
    assert!(na
        .as_slice()
        .iter()
        .zip(nb.as_slice())
        .all(|(p, q)| p == q || (p.x.is_nan() && q.x.is_nan())));
    Ok(())
}

#[test]
fn fewer_dsac_hypotheses_are_repeatable_and_differ_from_twelve() -> TestResult {
    let frame = read_synth(&synth_frame().1)?;
    let mut pipeline = Pipeline::new(Some(models()?));
    let with = |dsac_hypotheses| PipelineConfig {
        seed: 42,
        dsac_hypotheses,
        refine: false,
        ..small(Mode::Rgbd)
    };
    let twelve = output_bits(&pipeline.run(&frame, &with(12))?);
    let four = output_bits(&pipeline.run(&frame, &with(4))?);
    assert_eq!(four, output_bits(&pipeline.run(&frame, &with(4))?));
    assert_ne!(four, twelve);
    assert_eq!(twelve, output_bits(&pipeline.run(&frame, &with(12))?));
    let one = pipeline.run(&frame, &with(1))?;
    assert!(finite(&one.roughness_m) > 0);
    Ok(())
}

/// Every map of an output as bits (NaN included), for exact comparisons.
fn output_bits(out: &tre::pipeline::FrameOutput) -> Vec<u64> {
    let mut bits: Vec<u64> = out
        .roughness_m
        .as_slice()
        .iter()
        .map(|v| v.to_bits())
        .collect();
    if let (Some(d), Some(n)) = (out.depth_m(), out.normals()) {
        bits.extend(d.as_slice().iter().map(|v| v.to_bits()));
        bits.extend(
            n.as_slice()
                .iter()
                .flat_map(|v| v.iter().map(|c| c.to_bits())),
        );
    }
    bits.extend(out.traversable().as_slice().iter().map(|&t| u64::from(t)));
    bits
}

#[test]
fn recycled_maps_change_no_output_and_are_reused() -> TestResult {
    let synth = read_synth(&synth_frame().1)?;
    // Depth of another size, whole or with a hole: maps kept from the frames before hold
    // values where the holed one has none.
    let depth = |hole: bool| FrameInput {
        rgb: None,
        depth_m: Some(Grid::from_fn(40, 30, |x, y| {
            if hole && (10..20).contains(&x) && (5..15).contains(&y) {
                0.0
            } else {
                1.0 + 0.01 * ((x * 7 + y * 3) % 5) as f64
            }
        })),
        ..FrameInput::default()
    };
    let (whole, holed) = (depth(false), depth(true));
    let ls = |mode| PipelineConfig {
        normals: NormalsMethod::Ls,
        ..small(mode)
    };
    let window = PipelineConfig {
        centroid: CentroidMethod::Window,
        ..small(Mode::Rgbd)
    };
    let end_to_end = PipelineConfig {
        method: Method::EndToEnd,
        ..small(Mode::Rgb)
    };
    let geometric = PipelineConfig::for_mode(Mode::Geometric);
    let steps = [
        (&synth, small(Mode::Rgb)),
        (&synth, small(Mode::Rgbd)),
        (&whole, geometric),
        (&holed, geometric),
        (&synth, ls(Mode::Rgb)),
        (&synth, window),
        (&synth, end_to_end),
        (&holed, geometric),
        (&synth, geometric),
        (&synth, small(Mode::Rgb)),
    ];
    let (mut recycling, mut fresh) = (
        Pipeline::new(Some(models()?)),
        Pipeline::new(Some(models()?)),
    );
    for (i, (frame, cfg)) in steps.iter().enumerate() {
        let a = recycling.run(frame, cfg)?;
        let b = fresh.run(frame, cfg)?;
        assert_eq!(
            output_bits(&a),
            output_bits(&b),
            "step {i}: {}",
            cfg.label()
        );
        recycling.recycle(a);
    }
    roughness_lands_in_the_buffer_handed_back(&mut recycling, &holed)
}

/// The same frame again: its roughness lands in the buffer handed back (the spec's path: the
/// terrain estimate takes three maps off the shelf, in another order).
fn roughness_lands_in_the_buffer_handed_back(
    recycling: &mut Pipeline,
    holed: &FrameInput,
) -> TestResult {
    let cfg = PipelineConfig {
        geometric: GeometricMethod::Spec,
        ..PipelineConfig::for_mode(Mode::Geometric)
    };
    let a = recycling.run(holed, &cfg)?;
    let buffer = a.roughness_m.as_slice().as_ptr();
    recycling.recycle(a);
    let b = recycling.run(holed, &cfg)?;
    assert_eq!(b.roughness_m.as_slice().as_ptr(), buffer);
    Ok(())
}
