//! Refusals of a frame's images: bytes that are no image, images beyond the decoding limits,
//! and depth that is not depth.

use tre_io::JpegError;
use tre_proto::ErrorCode;

/// Which image of a request an error is about.
#[derive(Debug, Clone, Copy, PartialEq, Eq, strum::Display)]
#[strum(serialize_all = "lowercase")]
pub enum ImagePart {
    /// The colour frame (the HTTP part `rgb`, the stream frame's `image`).
    Rgb,
    /// The depth frame (the HTTP part `depth`, the stream frame's `depth`).
    Depth,
}

/// An image of a frame that does not decode, or is beyond a limit, or is not what its part
/// must be.
#[derive(Debug, thiserror::Error)]
pub enum ImageError {
    /// An empty part.
    #[error("{part}: empty")]
    EmptyImage {
        /// Which.
        part: ImagePart,
    },
    /// Bytes that are neither PNG nor JPEG.
    #[error("{part}: not a PNG or JPEG image")]
    NotAnImage {
        /// Which.
        part: ImagePart,
    },
    /// A PNG (or a JPEG's header) that does not decode.
    #[error("{part}: {source}")]
    Undecodable {
        /// Which.
        part: ImagePart,
        /// The decoder's error.
        source: image::ImageError,
    },
    /// A JPEG that is not whole and valid.
    #[error("{part}: {source}")]
    Jpeg {
        /// Which.
        part: ImagePart,
        /// The decoder's error.
        source: JpegError,
    },
    /// An image without pixels.
    #[error("{part}: the image is {}×{}, it has no pixels", size.0, size.1)]
    NoPixels {
        /// Which.
        part: ImagePart,
        /// Its `(width, height)`.
        size: (usize, usize),
    },
    /// An image side over `--max-side`.
    #[error(
        "{part}: the image is {}×{}, a side longer than the limit of {max_side} pixels \
         (--max-side)",
        size.0,
        size.1
    )]
    SideTooLong {
        /// Which.
        part: ImagePart,
        /// Its `(width, height)`.
        size: (usize, usize),
        /// The limit, pixels.
        max_side: usize,
    },
    /// An image over `--max-pixels`.
    #[error(
        "{part}: the image is {}×{} = {} pixels, more than the limit of {max_pixels} ({} \
         pixels, --max-pixels)",
        size.0,
        size.1,
        (size.0 as u64).saturating_mul(size.1 as u64),
        tre_io::units::format_size(*max_pixels, "")
    )]
    TooManyPixels {
        /// Which.
        part: ImagePart,
        /// Its `(width, height)`.
        size: (usize, usize),
        /// The limit, pixels.
        max_pixels: usize,
    },
    /// An image longer than `--max-aspect` times its width.
    #[error(
        "{part}: the image is {}×{}, its longer side more than {max_aspect} times the shorter \
         (--max-aspect)",
        size.0,
        size.1
    )]
    TooNarrow {
        /// Which.
        part: ImagePart,
        /// Its `(width, height)`.
        size: (usize, usize),
        /// The limit.
        max_aspect: usize,
    },
    /// A 16-bit grey image sent as the colour frame.
    #[error(
        "rgb: {why}: the multipart part `depth` over HTTP (a `camera` part gives its \
         depth_scale), the frame's `depth` field on the stream"
    )]
    DepthAsRgb {
        /// tre-io's words for it ([`tre_io::not_rgb`]).
        why: &'static str,
    },
    /// A depth part that is no image (or a broken one): the image's error, and what depth may
    /// be.
    #[error("{0}; depth must be a 16-bit grey PNG or a float .npy")]
    NotDepth(#[source] Box<ImageError>),
    /// A depth image of another colour type than 16-bit grey.
    #[error("depth: must be a 16-bit grey PNG or a float .npy, got {color:?}")]
    DepthColour {
        /// Its colour type.
        color: image::ColorType,
    },
    /// A frame without an image or depth.
    #[error("the frame has neither an image nor depth")]
    NoInput,
}

impl ImageError {
    /// The code of this error in the one [`ErrorCode`] table.
    pub fn code(&self) -> ErrorCode {
        match self {
            Self::EmptyImage { .. }
            | Self::Undecodable { .. }
            | Self::Jpeg { .. }
            | Self::DepthAsRgb { .. } => ErrorCode::BadImage,
            Self::NotAnImage { .. } => ErrorCode::UnsupportedMedia,
            Self::SideTooLong { .. } | Self::TooManyPixels { .. } => ErrorCode::TooLarge,
            // The shape of a depth part is a depth error, as the rest of what is wrong with it.
            Self::NoPixels { part, .. } | Self::TooNarrow { part, .. } => match part {
                ImagePart::Rgb => ErrorCode::BadImage,
                ImagePart::Depth => ErrorCode::BadDepth,
            },
            Self::NotDepth(_) | Self::DepthColour { .. } => ErrorCode::BadDepth,
            Self::NoInput => ErrorCode::BadRequest,
        }
    }

    /// Whether this is an image beyond a decoding limit (`--max-side`, `--max-pixels`,
    /// `--max-aspect`), which the handler answers before the frame takes a place in the queue.
    pub(crate) fn is_over_limit(&self) -> bool {
        matches!(
            self,
            Self::SideTooLong { .. } | Self::TooManyPixels { .. } | Self::TooNarrow { .. }
        )
    }
}
