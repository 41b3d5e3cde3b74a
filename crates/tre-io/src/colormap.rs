//! Colour maps for people: Turbo for roughness and depth, a colour per label, the three
//! states' colours. The titled previews built from them are in [`crate::previews`].

use image::{Rgb, RgbImage};

use tre_core::geometry::Grid;

/// The Turbo colour map (Mikhailov 2019, polynomial fit) at `t` in [0, 1].
///
/// ```
/// let blue = tre_io::colormap::turbo(0.15);
/// let red = tre_io::colormap::turbo(1.0);
/// assert!(blue[2] > blue[0] && red[0] > red[2]);
/// ```
pub fn turbo(t: f64) -> [u8; 3] {
    let t = t.clamp(0.0, 1.0);
    let poly = |c: [f64; 6]| c[0] + t * (c[1] + t * (c[2] + t * (c[3] + t * (c[4] + t * c[5]))));
    let r = poly([
        0.13572138,
        4.61539260,
        -42.66032258,
        132.13108234,
        -152.94239396,
        59.28637943,
    ]);
    let g = poly([
        0.09140261,
        2.19418839,
        4.84296658,
        -14.18503333,
        4.27729857,
        2.82956604,
    ]);
    let b = poly([
        0.10667330,
        12.64194608,
        -60.58204836,
        110.36276771,
        -89.90310912,
        27.34824973,
    ]);
    [r, g, b].map(|c| (c.clamp(0.0, 1.0) * 255.0).round() as u8)
}

/// Colour of pixels without data.
const NO_DATA: [u8; 3] = [40, 40, 40];

/// Turbo colours of a float map over `[lo, hi]` (non-finite: no-data grey).
pub fn colourise(map: &Grid<f64>, lo: f64, hi: f64) -> RgbImage {
    RgbImage::from_fn(map.width() as u32, map.height() as u32, |x, y| {
        let v = map[(x as usize, y as usize)];
        Rgb(if !v.is_finite() {
            NO_DATA
        } else {
            turbo((v - lo) / (hi - lo))
        })
    })
}

/// A distinct colour per label (0: black).
pub fn labels(map: &Grid<u32>) -> RgbImage {
    // Labels 0–6 (void and the natural categories) keep their colours; 7–20 are the indoor and
    // urban ones (docs/synth.md).
    const PALETTE: [[u8; 3]; 21] = [
        [0, 0, 0],
        [160, 160, 160],
        [60, 170, 60],
        [150, 120, 90],
        [110, 90, 160],
        [230, 200, 120],
        [220, 80, 60],
        [80, 160, 220],
        [190, 130, 60],
        [150, 60, 140],
        [240, 240, 240],
        [255, 160, 0],
        [255, 0, 200],
        [200, 170, 100],
        [100, 60, 30],
        [60, 60, 70],
        [200, 110, 100],
        [0, 200, 200],
        [120, 220, 120],
        [40, 80, 200],
        [255, 240, 0],
    ];
    RgbImage::from_fn(map.width() as u32, map.height() as u32, |x, y| {
        Rgb(PALETTE[map[(x as usize, y as usize)] as usize % PALETTE.len()])
    })
}

/// Colour of a three-state pixel in previews and on the demo page: traversable green, hazard
/// red, unknown grey-violet (distinct from both and from the roughness colour map's dark grey
/// for no data).
pub fn traversal_rgb(t: tre_core::roughness::traversal::Traversal) -> [u8; 3] {
    use tre_core::roughness::traversal::Traversal;
    match t {
        Traversal::Traversable => [44, 160, 44],
        Traversal::Hazard => [214, 39, 40],
        Traversal::Unknown => [150, 130, 190],
    }
}
