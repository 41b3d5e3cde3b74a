//! Counter-based random numbers: SplitMix64 of (seed, pixel, hypothesis, draw). Written
//! bit-identically in `models/training` (Python) so that training and serving draw the same
//! hypotheses on any number of threads. Also the digest with which tests hold outputs to the
//! bit ([`digest`]).

/// FNV-1a (64-bit) over the little-endian bytes of `words`: a digest of outputs that must stay
/// the same to the bit (map values as [`f64_bits`]).
///
/// ```
/// use tre_core::geometry::hash::{digest, f64_bits};
/// assert_eq!(digest([]), 0xcbf2_9ce4_8422_2325);
/// assert_eq!(digest([f64_bits(f64::NAN)]), digest([f64_bits(-f64::NAN)]));
/// assert_ne!(digest([f64_bits(0.0)]), digest([f64_bits(-0.0)]));
/// ```
pub fn digest(words: impl IntoIterator<Item = u64>) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for w in words {
        for b in w.to_le_bytes() {
            h = (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3);
        }
    }
    h
}

/// An f64's bits, every NaN read as one NaN (NaN payloads carry no output).
pub fn f64_bits(v: f64) -> u64 {
    if v.is_nan() {
        f64::NAN.to_bits()
    } else {
        v.to_bits()
    }
}

/// One SplitMix64 step (Steele, Lea and Flood 2014) as a mixing function.
///
/// ```
/// // The reference sequence of SplitMix64 seeded with 0 starts with 0xE220A8397B1DCDAF.
/// assert_eq!(tre_core::geometry::hash::splitmix64(0), 0xE220_A839_7B1D_CDAF);
/// ```
#[inline]
pub fn splitmix64(x: u64) -> u64 {
    let mut z = x.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// The uniform number in [0, 1) for one draw:
/// `splitmix64(splitmix64(splitmix64(seed) ^ pixel) ^ (hypothesis << 8 | draw)) >> 11` scaled by 2⁻⁵³.
///
/// ```
/// use tre_core::geometry::hash::uniform;
/// let u = uniform(7, 1234, 3, 2);
/// assert!((0.0..1.0).contains(&u));
/// assert_eq!(u, uniform(7, 1234, 3, 2));
/// assert_ne!(u, uniform(7, 1234, 3, 1));
/// ```
#[inline]
pub fn uniform(seed: u64, pixel: u64, hypothesis: u32, draw: u32) -> f64 {
    stream_uniform(pixel_stream(splitmix64(seed), pixel), hypothesis, draw)
}

/// The random stream of one pixel: `splitmix64(seed_key ^ pixel)` with `seed_key =
/// splitmix64(seed)`. A caller that draws many numbers for one seed computes the key once, then
/// the stream once per pixel; [`uniform`] is [`stream_uniform`] of it.
///
/// ```
/// use tre_core::geometry::hash::{pixel_stream, splitmix64, stream_uniform, uniform};
/// let stream = pixel_stream(splitmix64(7), 1234);
/// assert_eq!(stream_uniform(stream, 3, 2).to_bits(), uniform(7, 1234, 3, 2).to_bits());
/// ```
#[inline]
pub fn pixel_stream(seed_key: u64, pixel: u64) -> u64 {
    splitmix64(seed_key ^ pixel)
}

/// The uniform number in [0, 1) of draw `draw` of hypothesis `hypothesis` on a pixel's stream
/// ([`pixel_stream`]).
#[inline]
pub fn stream_uniform(stream: u64, hypothesis: u32, draw: u32) -> f64 {
    let key = (u64::from(hypothesis) << 8) | u64::from(draw);
    (splitmix64(stream ^ key) >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
}
