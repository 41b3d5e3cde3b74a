//! Camera image formation for synthetic frames: exposure and gamma, white balance, vignetting,
//! defocus and motion blur, shot and read noise, and JPEG, each drawn per frame from documented
//! ranges and each with its own switch (docs/synth.md). With every effect off the image is
//! returned unchanged.

use std::fmt;
use std::str::FromStr;

use image::RgbImage;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use tre_core::geometry::hash::uniform;

/// One image-formation effect (the switch names of `tre synth --effects`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ImageEffect {
    /// Exposure (gain in stops) and the encoding gamma.
    Exposure,
    /// White balance error: red and blue gains against green.
    WhiteBalance,
    /// Radial fall-off of brightness towards the corners.
    Vignetting,
    /// Defocus: a disk blur.
    Defocus,
    /// Motion blur: a line blur of drawn length and direction.
    MotionBlur,
    /// Shot (photon) and read noise.
    Noise,
    /// JPEG compression at a drawn quality.
    Jpeg,
}

impl ImageEffect {
    /// Every effect, in the order they are applied.
    pub const ALL: [Self; 7] = [
        Self::Exposure,
        Self::WhiteBalance,
        Self::Vignetting,
        Self::Defocus,
        Self::MotionBlur,
        Self::Noise,
        Self::Jpeg,
    ];

    /// The effect's name (`motion_blur`, …), as serde writes it.
    pub fn name(self) -> &'static str {
        match self {
            Self::Exposure => "exposure",
            Self::WhiteBalance => "white_balance",
            Self::Vignetting => "vignetting",
            Self::Defocus => "defocus",
            Self::MotionBlur => "motion_blur",
            Self::Noise => "noise",
            Self::Jpeg => "jpeg",
        }
    }
}

impl fmt::Display for ImageEffect {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// A name that is no [`ImageEffect`].
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error(
    "unknown effect {name:?}: the effects are {}",
    ImageEffect::ALL.map(ImageEffect::name).join(", ")
)]
pub struct UnknownEffect {
    /// The name given.
    pub name: String,
}

impl FromStr for ImageEffect {
    type Err = UnknownEffect;

    /// An effect by name (case and `-`/`_` do not matter).
    ///
    /// ```
    /// use tre_synth::imaging::ImageEffect;
    /// assert_eq!("Motion-Blur".parse(), Ok(ImageEffect::MotionBlur));
    /// assert!("blur".parse::<ImageEffect>().is_err());
    /// ```
    fn from_str(s: &str) -> Result<Self, UnknownEffect> {
        let key = s.trim().to_ascii_lowercase().replace('-', "_");
        Self::ALL
            .into_iter()
            .find(|e| e.name() == key)
            .ok_or_else(|| UnknownEffect { name: s.to_owned() })
    }
}

/// One frame's image-formation parameters (neutral for the effects that are off).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Imaging {
    /// The effects on.
    pub effects: Vec<ImageEffect>,
    /// Exposure, stops (gain 2^stops on linear light); drawn in [−1, 1].
    pub exposure_stops: f64,
    /// Encoding gamma (v^(1/γ)); drawn in [1.8, 2.6]; `None`: the sRGB curve.
    pub gamma: Option<f64>,
    /// Red, green, blue gains; red = 1 + t, blue = 1 − t, t drawn in [−0.15, 0.15].
    pub white_balance: [f64; 3],
    /// Brightness lost at the image corner: gain 1 − k·(r/r_corner)²; k drawn in [0, 0.5].
    pub vignetting: f64,
    /// Defocus disk radius, pixels; drawn in [0, 2].
    pub defocus_px: f64,
    /// Motion blur length, pixels; drawn in [0, 8].
    pub motion_blur_px: f64,
    /// Motion blur direction, degrees from +x; drawn in [0, 180).
    pub motion_angle_deg: f64,
    /// Electrons at full white (shot noise); drawn in [1000, 20000] (log-uniform).
    pub full_well_e: f64,
    /// Read noise, electrons; drawn in [2, 12].
    pub read_noise_e: f64,
    /// JPEG quality; drawn in [40, 95].
    pub jpeg_quality: Option<u8>,
    /// Seed of the noise.
    pub seed: u64,
}

impl Imaging {
    /// Parameters for `effects`, drawn from `seed` (the same seed gives the same draw).
    pub fn draw(effects: &[ImageEffect], seed: u64) -> Self {
        let on = |e: ImageEffect| effects.contains(&e);
        let u = |k: u32| uniform(seed, 0x1A6E, k, 0);
        let lerp = |k: u32, a: f64, b: f64| a + (b - a) * u(k);
        let t = if on(ImageEffect::WhiteBalance) {
            lerp(2, -0.15, 0.15)
        } else {
            0.0
        };
        let (shot, read) = if on(ImageEffect::Noise) {
            ((1000f64.ln() + u(7) * 20f64.ln()).exp(), lerp(8, 2.0, 12.0))
        } else {
            (f64::INFINITY, 0.0)
        };
        Self {
            effects: ImageEffect::ALL.into_iter().filter(|&e| on(e)).collect(),
            exposure_stops: if on(ImageEffect::Exposure) {
                lerp(0, -1.0, 1.0)
            } else {
                0.0
            },
            gamma: on(ImageEffect::Exposure).then(|| lerp(1, 1.8, 2.6)),
            white_balance: [1.0 + t, 1.0, 1.0 - t],
            vignetting: if on(ImageEffect::Vignetting) {
                lerp(3, 0.0, 0.5)
            } else {
                0.0
            },
            defocus_px: if on(ImageEffect::Defocus) {
                lerp(4, 0.0, 2.0)
            } else {
                0.0
            },
            motion_blur_px: if on(ImageEffect::MotionBlur) {
                lerp(5, 0.0, 8.0)
            } else {
                0.0
            },
            motion_angle_deg: if on(ImageEffect::MotionBlur) {
                lerp(6, 0.0, 180.0)
            } else {
                0.0
            },
            full_well_e: shot,
            read_noise_e: read,
            jpeg_quality: on(ImageEffect::Jpeg).then(|| lerp(9, 40.0, 95.999) as u8),
            seed,
        }
    }

    /// The image a camera with these parameters would have taken of the rendered `rgb`.
    pub fn apply(&self, rgb: &RgbImage) -> RgbImage {
        if self.effects.is_empty() {
            return rgb.clone();
        }
        let (w, h) = (rgb.width() as usize, rgb.height() as usize);
        let mut lin: Vec<[f64; 3]> = rgb.pixels().map(|p| p.0.map(srgb_to_linear)).collect();
        self.expose(&mut lin, w, h);
        let taps = blur_taps(self.defocus_px, self.motion_blur_px, self.motion_angle_deg);
        if taps.len() > 1 {
            lin = convolve(&lin, w, h, &taps);
        }
        self.add_noise(&mut lin, w);
        let encoded = RgbImage::from_fn(w as u32, h as u32, |x, y| {
            image::Rgb(lin[y as usize * w + x as usize].map(|v| self.encode(v)))
        });
        match self.jpeg_quality {
            Some(q) => jpeg_round_trip(&encoded, q),
            None => encoded,
        }
    }

    /// Exposure gain, white balance and vignetting on linear light.
    fn expose(&self, lin: &mut [[f64; 3]], w: usize, h: usize) {
        let gain = 2f64.powf(self.exposure_stops);
        let (cx, cy) = ((w as f64 - 1.0) / 2.0, (h as f64 - 1.0) / 2.0);
        let corner2 = (cx * cx + cy * cy).max(1e-9);
        lin.par_chunks_mut(w.max(1))
            .enumerate()
            .for_each(|(y, row)| {
                for (x, px) in row.iter_mut().enumerate() {
                    let r2 = ((x as f64 - cx).powi(2) + (y as f64 - cy).powi(2)) / corner2;
                    let g = gain * (1.0 - self.vignetting * r2);
                    for (c, v) in px.iter_mut().enumerate() {
                        *v *= g * self.white_balance[c];
                    }
                }
            });
    }

    /// Shot noise (Gaussian with the Poisson variance of the electrons) and read noise.
    fn add_noise(&self, lin: &mut [[f64; 3]], w: usize) {
        if !self.full_well_e.is_finite() {
            return;
        }
        let (full, read) = (self.full_well_e, self.read_noise_e);
        lin.par_chunks_mut(w.max(1))
            .enumerate()
            .for_each(|(y, row)| {
                for (x, px) in row.iter_mut().enumerate() {
                    for (c, v) in px.iter_mut().enumerate() {
                        let i = ((y * w + x) * 3 + c) as u64;
                        let e = v.clamp(0.0, 1.0) * full;
                        *v += (e + read * read).sqrt() * normal(self.seed, i) / full;
                    }
                }
            });
    }

    /// Linear light to an 8-bit code: the drawn gamma, or the sRGB curve.
    fn encode(&self, v: f64) -> u8 {
        let v = v.clamp(0.0, 1.0);
        let e = match self.gamma {
            Some(g) => v.powf(1.0 / g),
            None => linear_to_srgb(v),
        };
        (e * 255.0).round() as u8
    }
}

/// A standard normal number for index `i` (Box–Muller on the counter hash).
fn normal(seed: u64, i: u64) -> f64 {
    let (u1, u2) = (uniform(seed, i, 0x1A6F, 0), uniform(seed, i, 0x1A6F, 1));
    (-2.0 * (1.0 - u1).ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
}

/// The sRGB curve's inverse: 8-bit code to linear light.
fn srgb_to_linear(c: u8) -> f64 {
    let c = f64::from(c) / 255.0;
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

/// The sRGB curve: linear light in [0, 1] to its encoded value in [0, 1].
fn linear_to_srgb(v: f64) -> f64 {
    if v <= 0.003_130_8 {
        12.92 * v
    } else {
        1.055 * v.powf(1.0 / 2.4) - 0.055
    }
}

/// Taps (dx, dy, weight; weights sum to 1) of a disk of radius `defocus_px` convolved with a
/// line of `motion_px` at `angle_deg`.
fn blur_taps(defocus_px: f64, motion_px: f64, angle_deg: f64) -> Vec<(i32, i32, f64)> {
    let r = defocus_px.ceil() as i32;
    let disk: Vec<(i32, i32)> = (-r..=r)
        .flat_map(|dy| (-r..=r).map(move |dx| (dx, dy)))
        .filter(|&(dx, dy)| f64::from(dx * dx + dy * dy) <= defocus_px * defocus_px + 0.25)
        .collect();
    let steps = motion_px.round() as i32;
    let (c, s) = (angle_deg.to_radians().cos(), angle_deg.to_radians().sin());
    let line: Vec<(i32, i32)> = (0..=steps)
        .map(|k| {
            let t = f64::from(k) - f64::from(steps) / 2.0;
            ((t * c).round() as i32, (t * s).round() as i32)
        })
        .collect();
    let mut taps: std::collections::BTreeMap<(i32, i32), f64> = Default::default();
    let weight = 1.0 / (disk.len() * line.len()) as f64;
    for &(ax, ay) in &disk {
        for &(bx, by) in &line {
            *taps.entry((ax + bx, ay + by)).or_default() += weight;
        }
    }
    taps.into_iter().map(|((x, y), w)| (x, y, w)).collect()
}

/// `img` convolved with `taps`, borders clamped, rows in parallel.
fn convolve(img: &[[f64; 3]], w: usize, h: usize, taps: &[(i32, i32, f64)]) -> Vec<[f64; 3]> {
    let mut out = vec![[0.0; 3]; w * h];
    out.par_chunks_mut(w.max(1))
        .enumerate()
        .for_each(|(y, row)| {
            for (x, px) in row.iter_mut().enumerate() {
                for &(dx, dy, wt) in taps {
                    let sx = (x as i64 + i64::from(dx)).clamp(0, w as i64 - 1) as usize;
                    let sy = (y as i64 + i64::from(dy)).clamp(0, h as i64 - 1) as usize;
                    let s = img[sy * w + sx];
                    for c in 0..3 {
                        px[c] += wt * s[c];
                    }
                }
            }
        });
    out
}

/// `img` encoded as JPEG at `quality` and decoded again (the image unchanged if either fails,
/// which an in-memory RGB image does not).
fn jpeg_round_trip(img: &RgbImage, quality: u8) -> RgbImage {
    let mut bytes = Vec::new();
    let enc = image::codecs::jpeg::JpegEncoder::new_with_quality(&mut bytes, quality);
    if img.write_with_encoder(enc).is_err() {
        return img.clone();
    }
    image::load_from_memory(&bytes).map_or_else(|_| img.clone(), |d| d.to_rgb8())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grey(v: u8) -> RgbImage {
        RgbImage::from_pixel(64, 48, image::Rgb([v; 3]))
    }

    #[test]
    fn all_off_is_the_identity_and_srgb_round_trips() {
        let img = RgbImage::from_fn(32, 16, |x, y| {
            image::Rgb([(x * 8) as u8, (y * 16) as u8, 77])
        });
        assert_eq!(Imaging::draw(&[], 3).apply(&img), img);
        for c in 0..=255u8 {
            assert_eq!((linear_to_srgb(srgb_to_linear(c)) * 255.0).round() as u8, c);
        }
    }

    #[test]
    fn each_effect_does_what_it_says() {
        let mid = grey(128);
        let one = |e: ImageEffect, seed: u64| Imaging::draw(&[e], seed);
        // Vignetting darkens the corner and keeps the centre.
        let v = one(ImageEffect::Vignetting, 1);
        let out = v.apply(&mid);
        assert!(v.vignetting > 0.0 && out.get_pixel(0, 0)[0] < out.get_pixel(32, 24)[0]);
        assert!(out.get_pixel(32, 24)[0].abs_diff(128) <= 1);
        // Noise: a flat image gets a spread of values, as large as the draw says.
        let n = one(ImageEffect::Noise, 2);
        let px: Vec<f64> = n.apply(&mid).pixels().map(|p| f64::from(p[1])).collect();
        let mean = px.iter().sum::<f64>() / px.len() as f64;
        let sd = (px.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / px.len() as f64).sqrt();
        assert!(sd > 0.5, "noise sd {sd} codes");
        // White balance tilts red against blue.
        let wb = one(ImageEffect::WhiteBalance, 3);
        let p = wb.apply(&mid).get_pixel(10, 10).0;
        assert_eq!(
            p[0] > p[2],
            wb.white_balance[0] > 1.0,
            "{p:?} {:?}",
            wb.white_balance
        );
        // Blur spreads a bright line; JPEG keeps a flat image flat.
        let mut line = grey(0);
        (0..48).for_each(|y| line.put_pixel(32, y, image::Rgb([255; 3])));
        let b = Imaging::draw(&[ImageEffect::Defocus, ImageEffect::MotionBlur], 4);
        assert!(b.defocus_px > 0.5 || b.motion_blur_px > 1.0);
        assert!(b.apply(&line).get_pixel(32, 24)[0] < 255);
        let j = one(ImageEffect::Jpeg, 5);
        assert!((40..=95).contains(&j.jpeg_quality.unwrap_or(0)));
        assert!(j.apply(&mid).pixels().all(|p| p[0].abs_diff(128) <= 2));
        // The same seed, the same image.
        let all = Imaging::draw(&ImageEffect::ALL, 9);
        assert_eq!(all.apply(&line), all.apply(&line));
    }
}
