//! A camera JSON part, read strictly as the service reads it (`tre::server::fuzzing::camera`).
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    tre::server::fuzzing::camera(data);
});
