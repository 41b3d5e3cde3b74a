//! The integration tests, one test binary (each binary links the whole crate): one module per
//! area, with the helpers they share in `common`. The tests run on parallel threads of one
//! process, so none of them changes what the process shares (environment variables, working
//! directory, global subscribers). Two live in binaries of their own, each saying why:
//! `tests/ort_missing.rs` and `tests/loadtest.rs`.

mod common;

mod annotate;
mod cli_annotate;
mod cli_infer_eval;
mod client_e2e;
mod demo_page;
mod deploy;
mod dsac_parity;
mod geometry;
mod gravity;
mod jpeg_decode;
mod links;
mod map;
mod model_manifest;
mod onnx_parity;
mod ort_runtime;
mod pipeline;
mod readme;
mod sensor;
mod server_http;
mod server_stream;
mod synth;
