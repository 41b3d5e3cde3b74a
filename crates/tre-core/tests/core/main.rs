//! tre-core's integration tests, one test binary (`cargo test -p tre-core --test core`): the
//! geometry (camera round trips, LS normals, the gravity frame, DSAC), DSAC's parity with the
//! training code's vectors, and the roughness annotator on synthetic scenes with known answers.

mod annotate;
mod dsac_parity;
mod geometry;
