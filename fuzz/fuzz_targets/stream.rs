//! A binary stream message: protobuf decoding and conversion, then the frame's decoding
//! (`tre::server::fuzzing::stream`).
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    tre::server::fuzzing::stream(data);
});
