//! Mutations of seed inputs: byte edits, truncations, insertions and words that break size
//! arithmetic, with PNG chunk checksums fixed so that a change reaches the decoder.

use std::sync::Arc;

use proptest::prelude::*;

/// One change to a seed.
#[derive(Debug, Clone)]
enum Edit {
    Set(usize, u8),
    Flip(usize, u8),
    Truncate(usize),
    Insert(usize, Vec<u8>),
    Remove(usize, usize),
    /// A big-endian word from [`WORDS`] (sizes, lengths, counts).
    Word(usize, usize),
}

/// Values that break size arithmetic.
const WORDS: [u32; 10] = [
    0,
    1,
    0xFFFF,
    0x1_0000,
    8193,
    0x7FFF_FFFF,
    0x8000_0000,
    0xFFFF_FFFF,
    16_777_216,
    2048,
];

/// A position: half the time within the first 64 bytes (headers), else anywhere.
fn position() -> impl Strategy<Value = usize> {
    prop_oneof![0usize..64, any::<usize>()]
}

fn edit() -> impl Strategy<Value = Edit> {
    prop_oneof![
        (position(), any::<u8>()).prop_map(|(i, b)| Edit::Set(i, b)),
        (position(), 0u8..8).prop_map(|(i, bit)| Edit::Flip(i, 1 << bit)),
        any::<usize>().prop_map(Edit::Truncate),
        (position(), prop::collection::vec(any::<u8>(), 1..16))
            .prop_map(|(i, b)| Edit::Insert(i, b)),
        (position(), 1usize..64).prop_map(|(i, n)| Edit::Remove(i, n)),
        (position(), 0..WORDS.len()).prop_map(|(i, w)| Edit::Word(i, w)),
    ]
}

fn apply(mut v: Vec<u8>, edits: &[Edit]) -> Vec<u8> {
    for e in edits {
        let at = |i: usize, v: &Vec<u8>| if v.is_empty() { 0 } else { i % v.len() };
        match e {
            Edit::Set(i, b) if !v.is_empty() => {
                let i = at(*i, &v);
                v[i] = *b;
            }
            Edit::Flip(i, m) if !v.is_empty() => {
                let i = at(*i, &v);
                v[i] ^= m;
            }
            Edit::Truncate(i) => v.truncate(i % (v.len() + 1)),
            Edit::Insert(i, b) => {
                let i = i % (v.len() + 1);
                v.splice(i..i, b.iter().copied());
            }
            Edit::Remove(i, n) if !v.is_empty() => {
                let i = at(*i, &v);
                v.drain(i..(i + n).min(v.len()));
            }
            Edit::Word(i, w) if v.len() >= 4 => {
                let i = i % (v.len() - 3);
                v[i..i + 4].copy_from_slice(&WORDS[*w].to_be_bytes());
            }
            _ => {}
        }
    }
    v
}

/// Rewrites the CRC of every whole chunk of a PNG, so that a change reaches the decoder instead
/// of stopping at the checksum.
fn fix_png_crcs(v: &mut [u8]) {
    let mut at = 8;
    while at + 12 <= v.len() {
        let len = u32::from_be_bytes([v[at], v[at + 1], v[at + 2], v[at + 3]]) as usize;
        let Some(end) = (at + 8).checked_add(len).filter(|&e| e + 4 <= v.len()) else {
            return;
        };
        let crc = crc32fast::hash(&v[at + 4..end]);
        v[end..end + 4].copy_from_slice(&crc.to_be_bytes());
        at = end + 4;
    }
}

/// Seeds, mutated (PNG chunks' CRCs then fixed), or arbitrary bytes.
pub(super) fn inputs(seeds: Vec<Vec<u8>>) -> impl Strategy<Value = Vec<u8>> {
    let seeds = Arc::new(seeds);
    let n = seeds.len();
    let mutated = (0..n, prop::collection::vec(edit(), 0..6), any::<bool>()).prop_map(
        move |(i, edits, keep_crcs)| {
            let mut v = apply(seeds[i].clone(), &edits);
            if !keep_crcs && v.starts_with(b"\x89PNG") {
                fix_png_crcs(&mut v);
            }
            v
        },
    );
    prop_oneof![
        4 => mutated,
        1 => prop::collection::vec(any::<u8>(), 0..512),
    ]
}
