//! Build script: compiles the stream protocol in `proto/` with prost. The descriptors come from
//! protox, a protobuf compiler written in Rust, so no system `protoc` is needed.

use std::path::Path;

fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    compile_protos();
}

/// Compiles `proto/roughness/v1/*.proto` into Rust with prost.
fn compile_protos() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let dir = root.join("proto");
    let file = dir.join("roughness").join("v1").join("stream.proto");
    println!("cargo:rerun-if-changed={}", dir.display());
    let descriptors = protox::compile([&file], [&dir])
        .unwrap_or_else(|e| panic!("cannot compile {}: {e}", file.display()));
    prost_build::Config::new()
        .compile_fds(descriptors)
        .unwrap_or_else(|e| panic!("cannot generate Rust for {}: {e}", file.display()));
}
