//! The integration tests of the `tre` package, one test binary (each binary links the whole
//! crate): one module per area, with the helpers they share in `common`. The tests run on
//! parallel threads of one process, so none of them changes what the process shares
//! (environment variables, working directory, global subscribers). Tests that exercise one
//! crate alone are that crate's (`crates/*/tests/`). Tests that read the shared data beside the
//! repository (`../shared/`) return early, saying so, where it is missing:
//! `common::skip_unless_shared!`, `common::shared_data`.

mod common;

mod annotate_real;
mod cli_annotate;
mod cli_infer_eval;
mod client_e2e;
mod demo_page;
mod deploy;
mod gravity;
mod jpeg_decode;
mod links;
mod loadtest;
mod map;
mod map_picture;
mod pictures;
mod pipeline;
mod readme;
mod regions;
#[cfg(feature = "ros2")]
mod ros2;
mod sensor;
mod server_http;
mod server_stream;
mod spec_reference;
mod synth;
