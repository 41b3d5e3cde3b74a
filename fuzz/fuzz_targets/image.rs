//! An image part (PNG or JPEG): header-shape check, then decoding (`tre::server::fuzzing::image`).
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    tre::server::fuzzing::image(data);
});
