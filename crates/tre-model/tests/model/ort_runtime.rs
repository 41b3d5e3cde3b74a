//! ONNX Runtime end to end: load the runtime through `tre_model::runtime`, run a tiny conv
//! model (`tests/fixtures/tiny_conv.onnx`, from `scripts/make_tiny_onnx.py`) and compare it with
//! the same convolution computed here.

use std::error::Error;
use std::path::Path;

use ndarray::Array4;
use ort::session::Session;
use ort::value::TensorRef;
use tre_model::runtime;

/// Kernel and bias of the fixture, row-major; the same numbers as in `make_tiny_onnx.py`.
const WEIGHTS: [[f32; 3]; 3] = [[0.5, -1.0, 0.25], [1.5, 2.0, -0.75], [-0.5, 0.125, 1.0]];
const BIAS: f32 = -0.1;
/// Largest allowed |ONNX Runtime - reference| per element.
const TOLERANCE: f32 = 1e-5;

/// Input with values of both signs: -1.25, -1.0, ..., 1.25, repeating every 11 elements.
fn input(shape: (usize, usize, usize, usize)) -> Array4<f32> {
    let (_, _, h, w) = shape;
    Array4::from_shape_fn(shape, |(n, _, i, j)| {
        ((n * h * w + i * w + j) % 11) as f32 * 0.25 - 1.25
    })
}

/// relu(cross-correlation with `WEIGHTS`, zero padding 1, + `BIAS`), as ONNX Conv defines it.
fn reference(x: &Array4<f32>) -> Array4<f32> {
    let (_, _, h, w) = x.dim();
    Array4::from_shape_fn(x.dim(), |(n, c, i, j)| {
        let mut sum = BIAS;
        for (ki, row) in WEIGHTS.iter().enumerate() {
            for (kj, weight) in row.iter().enumerate() {
                let (y, x_) = ((i + ki).checked_sub(1), (j + kj).checked_sub(1));
                if let (Some(y), Some(x_)) = (y, x_) {
                    if y < h && x_ < w {
                        sum += weight * x[(n, c, y, x_)];
                    }
                }
            }
        }
        sum.max(0.0)
    })
}

fn session() -> Result<Session, Box<dyn Error>> {
    let model = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/fixtures/tiny_conv.onnx");
    let env = runtime::environment()?;
    Ok(Session::builder(env)?
        .with_intra_threads(1)?
        .commit_from_file(model)?)
}

#[test]
fn tiny_conv_matches_reference() -> Result<(), Box<dyn Error>> {
    let mut session = session()?;
    assert_eq!(session.inputs()[0].name(), "x");
    assert_eq!(session.outputs()[0].name(), "y");

    let x = input((2, 1, 5, 7));
    let expected = reference(&x);
    let outputs = session.run(ort::inputs!["x" => TensorRef::from_array_view(&x)?])?;
    let y = outputs["y"].try_extract_array::<f32>()?;

    assert_eq!(y.shape(), &[2, 1, 5, 7]);
    for ((at, want), got) in expected.indexed_iter().zip(y.iter()) {
        assert!(
            (got - want).abs() <= TOLERANCE,
            "y{at:?} = {got}, expected {want}"
        );
    }
    // The fixture is only a useful check if ReLU clips some outputs and passes others.
    assert!(expected.iter().any(|&v| v == 0.0) && expected.iter().any(|&v| v > 0.5));
    Ok(())
}

#[test]
fn environment_is_created_once() -> Result<(), Box<dyn Error>> {
    let first = runtime::environment()?;
    let second = runtime::environment()?;
    assert!(std::ptr::eq(first, second));
    Ok(())
}
