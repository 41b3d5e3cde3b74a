//! A depth part: 16-bit PNG or .npy, decoded and checked (`tre::server::fuzzing::depth`).
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    tre::server::fuzzing::depth(data);
});
