//! .npy parsing, bounded as a client's depth is (`tre::server::fuzzing::npy`).
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    tre::server::fuzzing::npy(data);
});
