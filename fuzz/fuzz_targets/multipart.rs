//! An HTTP multipart body: the handler's parsing and shape checks, then the worker's decoding
//! (`tre::server::fuzzing::multipart`).
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    tre::server::fuzzing::multipart(data);
});
