//! The node's images as `sensor_msgs/CompressedImage` PNGs, on `{topic}/compressed` as
//! image_transport's `compressed` plugin names and formats them: small enough for a stock
//! subscriber's socket buffer, where a raw 640×480 image is not (docs/ros2.md).

use image::{DynamicImage, ImageBuffer, Luma};
use tre_record::encode::millimetres;
use tre_record::msgs::{CompressedImage, Image};

/// The PNG of `img` with image_transport's format string (`mono16; png compressed mono16`):
/// `32FC1` metres as `mono16` [`millimetres`] (0: no data), `mono16` and `mono8` as they
/// are. `None` for
/// another encoding or a malformed image.
pub(crate) fn png(img: &Image) -> Option<CompressedImage> {
    let (w, h) = (img.width, img.height);
    let pixels = (w as usize).checked_mul(h as usize)?;
    let (decoded, kind) = match img.encoding.as_str() {
        "32FC1" if img.data.len() == 4 * pixels && img.is_bigendian == 0 => {
            let mm = img
                .data
                .chunks_exact(4)
                .map(|b| millimetres(f64::from(f32::from_le_bytes([b[0], b[1], b[2], b[3]]))));
            (mono16(w, h, mm.collect())?, "mono16")
        }
        "mono16" if img.data.len() == 2 * pixels && img.is_bigendian == 0 => {
            let v = img
                .data
                .chunks_exact(2)
                .map(|b| u16::from_le_bytes([b[0], b[1]]));
            (mono16(w, h, v.collect())?, "mono16")
        }
        "mono8" if img.data.len() == pixels => (
            DynamicImage::ImageLuma8(ImageBuffer::from_raw(w, h, img.data.clone())?),
            "mono8",
        ),
        _ => return None,
    };
    let mut data = Vec::new();
    tre_io::encode_png(&decoded, &mut data).ok()?;
    Some(CompressedImage {
        header: img.header.clone(),
        format: format!("{kind}; png compressed {kind}"),
        data,
    })
}

fn mono16(w: u32, h: u32, v: Vec<u16>) -> Option<DynamicImage> {
    ImageBuffer::<Luma<u16>, Vec<u16>>::from_raw(w, h, v).map(DynamicImage::ImageLuma16)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn image(encoding: &str, w: u32, h: u32, data: Vec<u8>) -> Image {
        Image {
            encoding: encoding.into(),
            width: w,
            height: h,
            step: data.len() as u32 / h,
            data,
            ..Image::default()
        }
    }

    fn decode(c: &CompressedImage) -> DynamicImage {
        image::load_from_memory_with_format(&c.data, image::ImageFormat::Png).expect("a PNG")
    }

    #[test]
    fn metres_become_millimetres_and_no_data_stays_zero() {
        let vals = [0.0123_f32, f32::NAN, 0.0001, 70.0];
        let data = vals.iter().flat_map(|v| v.to_le_bytes()).collect();
        let c = png(&image("32FC1", 2, 2, data)).expect("encoded");
        assert_eq!(c.format, "mono16; png compressed mono16");
        let px = decode(&c).to_luma16().into_raw();
        assert_eq!(px, [12, 0, 1, 65535]);
    }

    #[test]
    fn mono8_and_mono16_keep_their_values() {
        let c = png(&image("mono8", 3, 1, vec![0, 1, 2])).expect("encoded");
        assert_eq!(c.format, "mono8; png compressed mono8");
        assert_eq!(decode(&c).to_luma8().into_raw(), [0, 1, 2]);
        let data = [7_u16, 65535]
            .iter()
            .flat_map(|v| v.to_le_bytes())
            .collect();
        let c = png(&image("mono16", 2, 1, data)).expect("encoded");
        assert_eq!(decode(&c).to_luma16().into_raw(), [7, 65535]);
    }

    #[test]
    fn a_short_buffer_or_another_encoding_is_not_encoded() {
        assert!(png(&image("mono16", 2, 2, vec![0; 6])).is_none());
        assert!(png(&image("rgb8", 1, 1, vec![0; 3])).is_none());
    }
}
