//! The protocol's enums as the domain choices of [`tre_core::kinds`], and back: one conversion
//! each way per enum, shared by the server and the client. `UNSPECIFIED` leaves the choice to
//! the other end (`None`), except for the format, where it means PNG16.
//!
//! The protocol's `Format` is prost's generated wire enum, not a second domain choice: it
//! carries the encodings of [`MapFormat::STREAM`], and a map asked for as `.npy` goes as its
//! float32 values (`FORMAT_F32`).

use tre_core::kinds::{MapFormat, Mode, NormalsMethod};

use super::v1;

impl From<Option<Mode>> for v1::Mode {
    /// The mode asked for (none: the server's default).
    fn from(m: Option<Mode>) -> Self {
        match m {
            None => Self::Unspecified,
            Some(Mode::Rgb) => Self::Rgb,
            Some(Mode::Rgbd) => Self::Rgbd,
            Some(Mode::Geometric) => Self::Geometric,
        }
    }
}

impl From<v1::Mode> for Option<Mode> {
    fn from(m: v1::Mode) -> Self {
        match m {
            v1::Mode::Unspecified => None,
            v1::Mode::Rgb => Some(Mode::Rgb),
            v1::Mode::Rgbd => Some(Mode::Rgbd),
            v1::Mode::Geometric => Some(Mode::Geometric),
        }
    }
}

impl From<Option<NormalsMethod>> for v1::Normals {
    /// The normals asked for (none: the server's default).
    fn from(n: Option<NormalsMethod>) -> Self {
        match n {
            None => Self::Unspecified,
            Some(NormalsMethod::Dsac) => Self::Dsac,
            Some(NormalsMethod::Ls) => Self::Ls,
        }
    }
}

impl From<v1::Normals> for Option<NormalsMethod> {
    fn from(n: v1::Normals) -> Self {
        match n {
            v1::Normals::Unspecified => None,
            v1::Normals::Dsac => Some(NormalsMethod::Dsac),
            v1::Normals::Ls => Some(NormalsMethod::Ls),
        }
    }
}

impl From<MapFormat> for v1::Format {
    /// The wire's encoding of a map (`.npy` goes as its float32 values).
    fn from(f: MapFormat) -> Self {
        match f {
            MapFormat::Png16 => Self::Png16,
            MapFormat::Color => Self::Color,
            MapFormat::Npy | MapFormat::F32 => Self::F32,
        }
    }
}

impl From<v1::Format> for MapFormat {
    /// The format of a message (unspecified: PNG16, as the protocol says).
    fn from(f: v1::Format) -> Self {
        match f {
            v1::Format::Unspecified | v1::Format::Png16 => Self::Png16,
            v1::Format::Color => Self::Color,
            v1::Format::F32 => Self::F32,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use tre_core::kinds::{MapFormat, Mode, NormalsMethod};

    /// Every choice goes to the wire and comes back the same; unspecified is `None` (PNG16 for
    /// the format).
    #[test]
    fn every_choice_round_trips() {
        use strum::IntoEnumIterator;
        for m in Mode::iter().map(Some).chain([None]) {
            assert_eq!(Option::<Mode>::from(v1::Mode::from(m)), m);
        }
        for n in NormalsMethod::iter().map(Some).chain([None]) {
            assert_eq!(Option::<NormalsMethod>::from(v1::Normals::from(n)), n);
        }
        for &f in MapFormat::STREAM {
            assert_eq!(MapFormat::from(v1::Format::from(f)), f);
        }
        assert_eq!(
            MapFormat::from(v1::Format::from(MapFormat::Npy)),
            MapFormat::F32
        );
        assert_eq!(MapFormat::from(v1::Format::Unspecified), MapFormat::Png16);
    }
}
