//! Bad frames and bad settings are clear errors, never panics.

use super::*;

#[test]
fn bad_inputs_are_clear_errors() -> TestResult {
    let mut pipeline = Pipeline::new(None);
    let rgb = RgbImage::new(8, 6);
    let frame = FrameInput {
        rgb: Some(rgb.clone()),
        depth_m: Some(Grid::new(6, 8, 1.0)),
        ..FrameInput::default()
    };
    let err = pipeline
        .run(&frame, &small(Mode::Rgbd))
        .expect_err("depth of another size");
    assert!(
        matches!(
            err,
            PipelineError::DepthSizeMismatch {
                rgb: (8, 6),
                depth: (6, 8)
            }
        ),
        "{err}"
    );
    assert!(err.to_string().contains("6×8"), "{err}");

    let err = pipeline
        .run(&frame, &small(Mode::Rgb))
        .expect_err("no models");
    assert!(matches!(err, PipelineError::ModelsRequired { .. }), "{err}");
    assert!(err.to_string().contains("depth_net"), "{err}");

    let no_depth = FrameInput {
        rgb: Some(rgb),
        ..FrameInput::default()
    };
    let err = pipeline
        .run(&no_depth, &small(Mode::Geometric))
        .expect_err("no depth");
    assert!(
        matches!(err, PipelineError::MissingInput { input: "depth", .. }),
        "{err}"
    );

    let empty = FrameInput {
        rgb: Some(RgbImage::new(0, 4)),
        ..FrameInput::default()
    };
    let e2e = PipelineConfig {
        method: Method::EndToEnd,
        ..small(Mode::Rgb)
    };
    let err = Pipeline::new(Some(models()?))
        .run(&empty, &e2e)
        .expect_err("empty");
    assert!(matches!(err, PipelineError::EmptyImage { .. }), "{err}");
    Ok(())
}

#[test]
fn bad_settings_are_clear_errors() -> TestResult {
    let mut pipeline = Pipeline::new(None);
    let depth_only = FrameInput {
        depth_m: Some(Grid::new(100, 100, 1.0)),
        ..FrameInput::default()
    };
    let tiny_limit = PipelineConfig {
        max_input_pixels: 5000,
        ..small(Mode::Geometric)
    };
    let err = pipeline
        .run(&depth_only, &tiny_limit)
        .expect_err("too large");
    assert!(matches!(err, PipelineError::TooLarge { .. }), "{err}");

    for dsac_hypotheses in [0, 65] {
        let cfg = PipelineConfig {
            dsac_hypotheses,
            ..small(Mode::Geometric)
        };
        let err = pipeline.run(&depth_only, &cfg).expect_err("hypotheses");
        assert!(
            matches!(err, PipelineError::BadHypotheses { got } if got == dsac_hypotheses),
            "{err}"
        );
        assert!(err.to_string().contains("1 to 64"), "{err}");
    }

    let mut with_models = Pipeline::new(Some(models()?));
    let odd = PipelineConfig {
        working_size: Some((60, 64)),
        ..PipelineConfig::for_mode(Mode::Rgb)
    };
    let frame = FrameInput {
        rgb: Some(RgbImage::new(8, 6)),
        ..FrameInput::default()
    };
    let err = with_models
        .run(&frame, &odd)
        .expect_err("60 is not a multiple of 16");
    assert!(
        matches!(
            err,
            PipelineError::BadWorkingSize {
                stride: Some(16),
                ..
            }
        ),
        "{err}"
    );
    Ok(())
}
