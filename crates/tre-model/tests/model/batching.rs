//! Dynamic batching ([`SharedModels`]) with the committed models on the CPU: every caller gets
//! what a run of its own inputs alone gives, no batch exceeds its bound, frames of other sizes
//! never share a batch, and a request that does not fit the model fails alone.

#![allow(clippy::unwrap_used)] // Test helpers fail loudly by design.

use std::error::Error;
use std::sync::{Arc, Barrier, Mutex};
use std::time::Duration;

use ndarray::Array4;
use tre_model::{
    BatchObserver, Batching, BatchingError, Manifest, ModelError, ModelSession, Models,
    SharedModels, DEPTH_NET, MAX_BATCH,
};

use super::{cfg, models_dir};

/// A deterministic RGB image and prior of `h`×`w`, different for each `seed`.
fn inputs(seed: u64, h: usize, w: usize) -> (Array4<f32>, Array4<f32>) {
    let mut x = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
    let mut next = || {
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        (x >> 40) as f32 / (1u64 << 24) as f32
    };
    let rgb = Array4::from_shape_fn((1, 3, h, w), |_| next());
    let prior = Array4::from_shape_fn((1, 1, h, w), |(_, _, y, _)| 1.0 + 4.0 * y as f32 / h as f32);
    (rgb, prior)
}

/// The depth net run alone on each input, as the reference.
fn alone(cases: &[(u64, usize, usize)]) -> Result<Vec<Array4<f32>>, Box<dyn Error>> {
    let dir = models_dir();
    let manifest = Manifest::read(&dir)?;
    let entry = manifest.entry(DEPTH_NET)?;
    let mut s = ModelSession::load(&dir, DEPTH_NET, entry, manifest.stride, &cfg())?;
    cases
        .iter()
        .map(|&(seed, h, w)| {
            let (rgb, prior) = inputs(seed, h, w);
            Ok(s.run(&[rgb.view(), prior.view()])?)
        })
        .collect()
}

/// A named thread (the workspace's rule).
fn spawn<T: Send + 'static>(f: impl FnOnce() -> T + Send + 'static) -> std::thread::JoinHandle<T> {
    std::thread::Builder::new()
        .name("batching-test".into())
        .spawn(f)
        .unwrap()
}

/// Each caller's answer, and the depth net's batch sizes.
type Outcome = (Vec<Result<Array4<f32>, ModelError>>, Vec<usize>);

/// An observer that records the depth net's batch sizes, and the record.
fn depth_batches() -> (Arc<Mutex<Vec<usize>>>, BatchObserver) {
    let sizes = Arc::new(Mutex::new(Vec::new()));
    let seen = Arc::clone(&sizes);
    let observer: BatchObserver = Arc::new(move |model: &str, n: usize| {
        if model == DEPTH_NET {
            seen.lock().unwrap().push(n);
        }
    });
    (sizes, observer)
}

/// Runs the cases on threads released together through `shared`; returns each result and the
/// depth net's batch sizes.
fn together(batching: Batching, cases: &[(u64, usize, usize)]) -> Result<Outcome, Box<dyn Error>> {
    let (sizes, observer) = depth_batches();
    let shared = SharedModels::load(&models_dir(), &cfg(), batching, Some(observer))?;
    let barrier = Arc::new(Barrier::new(cases.len()));
    let threads: Vec<_> = cases
        .iter()
        .map(|&(seed, h, w)| {
            let mut models = Models::shared(&shared).expect("every stage is in the manifest");
            let barrier = Arc::clone(&barrier);
            spawn(move || {
                let (rgb, prior) = inputs(seed, h, w);
                barrier.wait();
                models.depth(rgb.view(), prior.view())
            })
        })
        .collect();
    let results = threads
        .into_iter()
        .map(|t| t.join().expect("no thread panics"))
        .collect();
    shared.join();
    let sizes = sizes.lock().unwrap().clone();
    Ok((results, sizes))
}

fn worst_relative(a: &Array4<f32>, b: &Array4<f32>) -> f64 {
    assert_eq!(a.dim(), b.dim());
    a.iter()
        .zip(b.iter())
        .map(|(&x, &y)| f64::from(x - y).abs() / f64::from(y).abs().max(1.0))
        .fold(0.0, f64::max)
}

/// Every answer within 1e-4 (relative to max(1, |y|)) of the run alone.
fn assert_as_alone(
    got: Vec<Result<Array4<f32>, ModelError>>,
    want: &[Array4<f32>],
) -> Result<(), Box<dyn Error>> {
    for (g, w) in got.into_iter().zip(want) {
        let worst = worst_relative(&g?, w);
        assert!(worst <= 1e-4, "relative error {worst:e}");
    }
    Ok(())
}

/// Long enough that threads released together always meet in one batch.
const WAIT: Duration = Duration::from_millis(500);

/// Batches of at most `max_batch`, gathered for [`WAIT`].
fn waiting(max_batch: usize) -> Batching {
    Batching {
        max_batch,
        max_delay: WAIT,
    }
}

#[test]
fn batched_answers_equal_runs_alone() -> Result<(), Box<dyn Error>> {
    let cases: Vec<_> = (0..4).map(|i| (i, 64, 96)).collect();
    let want = alone(&cases)?;
    let batching = waiting(4);
    let (got, sizes) = together(batching, &cases)?;
    assert_as_alone(got, &want)?;
    assert_eq!(sizes.iter().sum::<usize>(), 4);
    assert!(sizes.iter().any(|&n| n > 1), "never batched: {sizes:?}");
    Ok(())
}

#[test]
fn no_batch_exceeds_its_bound_and_sizes_never_mix() -> Result<(), Box<dyn Error>> {
    // Seven frames of one size and three of another, at most three to a batch.
    let cases: Vec<_> = (0..10)
        .map(|i| if i % 3 == 2 { (i, 32, 48) } else { (i, 64, 64) })
        .collect();
    let want = alone(&cases)?;
    let batching = waiting(3);
    let (got, sizes) = together(batching, &cases)?;
    assert_as_alone(got, &want)?;
    assert_eq!(sizes.iter().sum::<usize>(), 10, "{sizes:?}");
    assert!(sizes.iter().all(|&n| (1..=3).contains(&n)), "{sizes:?}");
    // Seven of one size need at least three batches, three of the other at least one.
    assert!(sizes.len() >= 4, "{sizes:?}");
    Ok(())
}

#[test]
fn a_request_that_does_not_fit_fails_alone() -> Result<(), Box<dyn Error>> {
    let (sizes, observer) = depth_batches();
    let batching = waiting(4);
    let shared = SharedModels::load(&models_dir(), &cfg(), batching, Some(observer))?;
    let want = alone(&[(7, 64, 64)])?;
    let barrier = Arc::new(Barrier::new(3));
    let run = |bad: bool| {
        let mut models = Models::shared(&shared).expect("every stage is in the manifest");
        let barrier = Arc::clone(&barrier);
        spawn(move || {
            let (rgb, prior) = inputs(7, 64, 64);
            // Two channels where the net takes three; or a height not a multiple of 16.
            let rgb = if bad {
                rgb.slice_move(ndarray::s![.., 0..2, .., ..])
            } else {
                rgb
            };
            barrier.wait();
            models.depth(rgb.view(), prior.view())
        })
    };
    let threads = [run(false), run(true), run(false)];
    let results: Vec<_> = threads.into_iter().map(|t| t.join().unwrap()).collect();
    assert!(
        matches!(results[1], Err(ModelError::InputShape { .. })),
        "{:?}",
        results[1]
    );
    for r in [&results[0], &results[2]] {
        let y = r.as_ref().map_err(ToString::to_string)?;
        assert!(worst_relative(y, &want[0]) <= 1e-4);
    }
    shared.join();
    assert_eq!(sizes.lock().unwrap().iter().sum::<usize>(), 2);
    Ok(())
}

#[test]
fn a_lone_request_is_answered_after_the_delay() -> Result<(), Box<dyn Error>> {
    let want = alone(&[(3, 32, 32)])?;
    let batching = Batching {
        max_batch: MAX_BATCH,
        max_delay: Duration::from_millis(5),
    };
    let (got, sizes) = together(batching, &[(3, 32, 32)])?;
    let y = got.into_iter().next().unwrap()?;
    assert!(worst_relative(&y, &want[0]) <= 1e-4);
    assert_eq!(sizes, vec![1]);
    Ok(())
}

#[test]
fn bounds_out_of_range_are_refused() {
    let b = |max_batch, ms| Batching {
        max_batch,
        max_delay: Duration::from_millis(ms),
    };
    assert_eq!(b(0, 1).check(), Err(BatchingError::Size(0)));
    assert_eq!(
        b(MAX_BATCH + 1, 1).check(),
        Err(BatchingError::Size(MAX_BATCH + 1))
    );
    assert!(matches!(b(8, 1001).check(), Err(BatchingError::Delay(_))));
    assert!(b(1, 0).check().is_ok() && b(MAX_BATCH, 1000).check().is_ok());
    let refused = SharedModels::load(&models_dir(), &cfg(), b(0, 1), None);
    assert!(matches!(
        refused,
        Err(ModelError::Batching(BatchingError::Size(0)))
    ));
}
