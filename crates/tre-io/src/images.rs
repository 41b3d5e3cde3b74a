//! Images: strict decoding of image files and JPEGs, the 16-bit PNG encodings of roughness,
//! depth and metre maps, grey and mask images, and saving with the project's PNG settings.

use std::fs::File;
use std::io::BufWriter;
use std::path::Path;

use image::{DynamicImage, ImageBuffer, LumaA};

use tre_core::geometry::Grid;

use super::{IoError, ROUGHNESS_PNG_SCALE_M};

/// Decodes an image file, naming the file in errors. JPEGs are decoded strictly
/// ([`decode_jpeg`]).
pub fn read_image(path: &Path) -> Result<DynamicImage, IoError> {
    let failed = |reason| IoError::Image {
        path: path.to_owned(),
        reason,
    };
    let bytes = std::fs::read(path).map_err(|reason| IoError::Read {
        path: path.to_owned(),
        reason,
    })?;
    if image::guess_format(&bytes).ok() == Some(image::ImageFormat::Jpeg) {
        return decode_jpeg(&bytes).map_err(|e| failed(ImageProblem::Jpeg(e)));
    }
    image::load_from_memory(&bytes).map_err(|e| failed(ImageProblem::Decode(e)))
}

/// Why a file does not decode as an image ([`IoError::Image`]).
#[derive(Debug, thiserror::Error)]
pub enum ImageProblem {
    /// A JPEG that the strict decoder refused ([`decode_jpeg`]).
    #[error(transparent)]
    Jpeg(JpegError),
    /// Any other file that the `image` crate could not decode.
    #[error(transparent)]
    Decode(image::ImageError),
}

/// Why an image cannot be an RGB frame, if it cannot: 16-bit grey (with or without alpha) is
/// how depth comes, never colour, so running it as colour would give an answer about nothing.
///
/// ```
/// use image::ColorType;
/// assert!(tre_io::not_rgb(ColorType::L16).unwrap().contains("depth"));
/// assert!(tre_io::not_rgb(ColorType::Rgb8).is_none());
/// ```
pub fn not_rgb(color: image::ColorType) -> Option<&'static str> {
    matches!(color, image::ColorType::L16 | image::ColorType::La16).then_some(
        "a 16-bit grey image is depth, not an RGB frame: send it as depth (with the camera's \
         depth_scale), alone for the geometric mode or beside the colour frame",
    )
}

/// Decodes a JPEG, refusing truncated or corrupt data. (`image`'s own JPEG decoding is lenient,
/// as browsers are: it fills what is missing with grey, so half a frame would pass for a whole
/// one.) Grey JPEGs come back as 8-bit grey, every other kind as RGB. One flaw is not caught:
/// scan data that ends with a proper end marker before the header's size is filled (a header
/// edited to claim more pixels) decodes with the rest filled, as the decoder reports no error.
///
/// ```
/// let img = image::RgbImage::from_fn(32, 24, |x, y| image::Rgb([x as u8 * 8, y as u8 * 10, 99]));
/// let mut jpeg = Vec::new();
/// image::codecs::jpeg::JpegEncoder::new(&mut jpeg).encode_image(&img).unwrap();
/// assert_eq!(tre_io::decode_jpeg(&jpeg).unwrap().to_rgb8().dimensions(), (32, 24));
/// assert!(tre_io::decode_jpeg(&jpeg[..jpeg.len() / 2]).is_err());
/// ```
pub fn decode_jpeg(bytes: &[u8]) -> Result<DynamicImage, JpegError> {
    use zune_core::bytestream::ZCursor;
    use zune_core::colorspace::ColorSpace;
    use zune_core::options::DecoderOptions;
    let options = DecoderOptions::default()
        .set_strict_mode(true)
        .set_max_width(usize::MAX)
        .set_max_height(usize::MAX);
    let mut decoder = zune_jpeg::JpegDecoder::new_with_options(ZCursor::new(bytes), options);
    decoder.decode_headers().map_err(JpegError::Decode)?;
    let grey = matches!(
        decoder.input_colorspace(),
        Some(ColorSpace::Luma | ColorSpace::LumaA)
    );
    let out = if grey {
        ColorSpace::Luma
    } else {
        ColorSpace::RGB
    };
    decoder.set_options(decoder.options().jpeg_set_out_colorspace(out));
    let pixels = decoder.decode().map_err(JpegError::Decode)?;
    let (w, h) = decoder.dimensions().ok_or(JpegError::NoDimensions)?;
    let (w, h) = (w as u32, h as u32);
    let image = if grey {
        image::GrayImage::from_raw(w, h, pixels).map(DynamicImage::ImageLuma8)
    } else {
        image::RgbImage::from_raw(w, h, pixels).map(DynamicImage::ImageRgb8)
    };
    image.ok_or(JpegError::SizeMismatch {
        width: w,
        height: h,
    })
}

/// Why bytes are not a whole, valid JPEG.
#[derive(Debug, thiserror::Error)]
pub enum JpegError {
    /// The decoder refused the data (truncated, corrupt, unsupported).
    #[error("not a whole, valid JPEG: {0}")]
    Decode(zune_jpeg::errors::DecodeErrors),
    /// The decoder gave no size.
    #[error("not a whole, valid JPEG: no dimensions")]
    NoDimensions,
    /// The decoded pixels do not fill the size the header states.
    #[error("not a whole, valid JPEG: {width}×{height} pixels do not match the data")]
    SizeMismatch {
        /// Width from the header.
        width: u32,
        /// Height from the header.
        height: u32,
    },
}

/// Encodes roughness as 16-bit grey + alpha: grey = round(r / 0.1 mm) saturated at 65535
/// (6.5535 m), alpha = 65535 where valid and 0 (with grey 0) where there is no data.
pub fn roughness_png16(roughness_m: &Grid<f64>) -> ImageBuffer<LumaA<u16>, Vec<u16>> {
    let (w, h) = (roughness_m.width() as u32, roughness_m.height() as u32);
    ImageBuffer::from_fn(w, h, |x, y| {
        let r = roughness_m[(x as usize, y as usize)];
        if r.is_finite() {
            LumaA([
                (r / ROUGHNESS_PNG_SCALE_M).round().clamp(0.0, 65535.0) as u16,
                u16::MAX,
            ])
        } else {
            LumaA([0, 0])
        }
    })
}

/// Encodes a non-negative map in metres as 16-bit grey at 0.1 mm per unit (saturating at
/// 6.5535 m; non-finite: 0).
pub fn metres_png16(map_m: &Grid<f64>) -> image::ImageBuffer<image::Luma<u16>, Vec<u16>> {
    luma16(map_m, |v| {
        v.is_finite()
            .then(|| (v / ROUGHNESS_PNG_SCALE_M).round().clamp(0.0, 65535.0) as u16)
    })
}

/// A 16-bit grey image of a float map, `encode` giving each pixel's value (`None`: 0).
fn luma16(
    map: &Grid<f64>,
    encode: impl Fn(f64) -> Option<u16>,
) -> image::ImageBuffer<image::Luma<u16>, Vec<u16>> {
    image::ImageBuffer::from_fn(map.width() as u32, map.height() as u32, |x, y| {
        image::Luma([encode(map[(x as usize, y as usize)]).unwrap_or(0)])
    })
}

/// Decodes a roughness PNG written by [`roughness_png16`] back to metres (NaN: no data).
pub fn decode_roughness_png16(img: &DynamicImage) -> Grid<f64> {
    let la = img.to_luma_alpha16();
    let (w, h) = (la.width() as usize, la.height() as usize);
    let data = la
        .pixels()
        .map(|p| {
            if p[1] == 0 {
                f64::NAN
            } else {
                f64::from(p[0]) * ROUGHNESS_PNG_SCALE_M
            }
        })
        .collect();
    Grid::from_vec(w, h, data).expect("decoder sizes agree; this is a bug")
}

/// A three-state map as 8-bit grey: 0 unknown, 1 traversable, 2 hazard.
pub fn traversal_gray8(map: &Grid<tre_core::roughness::traversal::Traversal>) -> image::GrayImage {
    image::GrayImage::from_fn(map.width() as u32, map.height() as u32, |x, y| {
        image::Luma([map[(x as usize, y as usize)] as u8])
    })
}

/// Writes a boolean mask as an 8-bit PNG (255 = true).
pub fn write_mask_png(path: &Path, mask: &Grid<bool>) -> Result<(), IoError> {
    let img = image::GrayImage::from_fn(mask.width() as u32, mask.height() as u32, |x, y| {
        image::Luma([if mask[(x as usize, y as usize)] {
            255
        } else {
            0
        }])
    });
    save(path, &DynamicImage::ImageLuma8(img))
}

/// Saves an image, choosing the format from the extension.
/// PNG files use fast compression: frames are written often and read by machines.
pub fn save(path: &Path, img: &DynamicImage) -> Result<(), IoError> {
    let err = |reason| IoError::Encode {
        path: path.to_owned(),
        reason,
    };
    if path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("png"))
    {
        let out = BufWriter::new(File::create(path).map_err(|reason| IoError::Write {
            path: path.to_owned(),
            reason,
        })?);
        return encode_png(img, out).map_err(err);
    }
    img.save(path).map_err(err)
}

/// Encodes `img` as PNG into `out` with the settings [`save`] uses (fast compression, the
/// Paeth filter on every row), so a file and a network answer carry the same bytes. On the
/// spec's 16-bit roughness of a real 640×480 Kinect frame, Paeth alone comes within 1% of the
/// adaptive filter's size (which tries all five filters on every row) in about 70% of its time
/// (`cargo bench --bench pipeline -- png/`, docs/benchmarks.md).
pub fn encode_png(img: &DynamicImage, out: impl std::io::Write) -> Result<(), image::ImageError> {
    use image::codecs::png::{CompressionType, FilterType, PngEncoder};
    let enc = PngEncoder::new_with_quality(out, CompressionType::Fast, FilterType::Paeth);
    img.write_with_encoder(enc)
}

/// Encodes depth (metres) as a 16-bit grey PNG in millimetres (0: no data; saturates at
/// 65.535 m).
pub fn depth_png16(depth_m: &Grid<f64>) -> image::ImageBuffer<image::Luma<u16>, Vec<u16>> {
    luma16(depth_m, |d| {
        (d > 0.0 && d.is_finite()).then(|| (d * 1000.0).round().clamp(1.0, 65535.0) as u16)
    })
}

/// An 8-bit grey image of a byte map.
pub fn gray8(map: &Grid<u8>) -> image::GrayImage {
    image::GrayImage::from_fn(map.width() as u32, map.height() as u32, |x, y| {
        image::Luma([map[(x as usize, y as usize)]])
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unreadable_images_say_which_decoder_refused_them() {
        let dir = tempfile::tempdir().unwrap();
        let junk = dir.path().join("junk.png");
        std::fs::write(&junk, b"not an image").unwrap();
        let e = read_image(&junk).unwrap_err();
        assert!(
            matches!(
                &e,
                IoError::Image {
                    reason: ImageProblem::Decode(_),
                    ..
                }
            ),
            "{e:?}"
        );
        assert!(
            e.to_string().contains("junk.png: not a readable image: "),
            "{e}"
        );
        let img = image::RgbImage::from_pixel(16, 16, image::Rgb([10, 20, 30]));
        let mut jpeg = Vec::new();
        image::codecs::jpeg::JpegEncoder::new(&mut jpeg)
            .encode_image(&img)
            .unwrap();
        let half = dir.path().join("half.jpg");
        std::fs::write(&half, &jpeg[..jpeg.len() / 2]).unwrap();
        let e = read_image(&half).unwrap_err();
        assert!(
            matches!(
                &e,
                IoError::Image {
                    reason: ImageProblem::Jpeg(_),
                    ..
                }
            ),
            "{e:?}"
        );
        assert!(e.to_string().contains("not a whole, valid JPEG"), "{e}");
    }

    #[test]
    fn images_that_cannot_be_written_name_the_file() {
        let dir = tempfile::tempdir().unwrap();
        let img = DynamicImage::ImageLuma8(image::GrayImage::new(2, 2));
        let nowhere = dir.path().join("no/such/dir/out.png");
        let e = save(&nowhere, &img).unwrap_err();
        assert!(
            matches!(&e, IoError::Write { path, .. } if path == &nowhere),
            "{e:?}"
        );
        let unknown = dir.path().join("out.xyz");
        let e = save(&unknown, &img).unwrap_err();
        assert!(
            matches!(&e, IoError::Encode { path, .. } if path == &unknown),
            "{e:?}"
        );
        assert!(
            e.to_string().contains("out.xyz: cannot write the image: "),
            "{e}"
        );
    }
}
