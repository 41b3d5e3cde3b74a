//! Titled previews for people: a roughness map in Turbo with its colour bar in centimetres, and
//! a three-state map with its legend, each under a title strip (the sheets' built-in font, so no
//! font files are needed).

use image::{Rgb, RgbImage};
use tre_core::geometry::Grid;

use crate::colormap::traversal_rgb;

/// Renders roughness (metres, NaN: none) for people: a title strip (`title`, e.g. the mode
/// and the frame), the map in Turbo over `[0, max_m]` (the sheets' colours: no data grey),
/// and the colour bar with ticks in centimetres below.
pub fn roughness_preview(roughness_m: &Grid<f64>, max_m: f64, title: &str) -> RgbImage {
    let max_cm = 100.0 * max_m;
    let ticks: Vec<f64> = (0..=4).map(|i| max_cm * f64::from(i) / 4.0).collect();
    let map = crate::sheet::roughness_panel(roughness_m, max_m);
    let legend = crate::sheet::colour_bar_legend(map.width(), max_m, &ticks);
    titled(title, &map, &legend)
}

/// `image` under a title strip and over `legend`, on the sheets' background.
fn titled(title: &str, image: &RgbImage, legend: &RgbImage) -> RgbImage {
    use crate::sheet::{draw_text, text_size, BACKGROUND, INK};
    const SCALE: u32 = 2;
    const PAD: u32 = 8;
    let (tw, th) = text_size(title, SCALE);
    let width = image.width().max(legend.width()).max(tw + 2 * PAD);
    let title_h = th + 2 * PAD;
    let height = title_h + image.height() + legend.height();
    let mut out = RgbImage::from_pixel(width, height, BACKGROUND);
    draw_text(&mut out, PAD, PAD, title, SCALE, INK);
    let x = (width - image.width()) / 2;
    image::imageops::replace(&mut out, image, i64::from(x), i64::from(title_h));
    let lx = (width - legend.width()) / 2;
    let ly = title_h + image.height();
    image::imageops::replace(&mut out, legend, i64::from(lx), i64::from(ly));
    out
}

/// Colour preview of a three-state map ([`traversal_rgb`]) for people: `title` above, the
/// legend (traversable, hazard, unknown) below.
pub fn traversal_preview(
    map: &Grid<tre_core::roughness::traversal::Traversal>,
    title: &str,
) -> RgbImage {
    use tre_core::roughness::traversal::Traversal;
    let image = RgbImage::from_fn(map.width() as u32, map.height() as u32, |x, y| {
        image::Rgb(traversal_rgb(map[(x as usize, y as usize)]))
    });
    let legend = crate::sheet::categorical_legend(&[
        ("traversable", Rgb(traversal_rgb(Traversal::Traversable))),
        ("hazard", Rgb(traversal_rgb(Traversal::Hazard))),
        ("unknown", Rgb(traversal_rgb(Traversal::Unknown))),
    ]);
    titled(title, &image, &legend)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// docs/outputs.md states the preview's no-data colour, its rows beyond the map's and its
    /// least width, and the colour map's no-data colour, as this code draws them.
    #[test]
    fn the_outputs_doc_states_the_previews_as_drawn() {
        let doc = include_str!("../../../docs/outputs.md");
        let h = 10;
        let map = Grid::new(4, h, f64::NAN);
        let preview = roughness_preview(&map, 0.05, "");
        let extra = preview.height() - h as u32;
        let [r, g, b] = crate::sheet::NO_DATA.0;
        let stated = [
            format!("H + {extra} rows"),
            format!("width at least {}", preview.width()),
            format!("no-data grey ({r}, {g}, {b})"),
        ];
        let [r, g, b] = crate::colormap::colourise(&map, 0.0, 0.05)
            .get_pixel(0, 0)
            .0;
        let colour = format!("no data ({r}, {g}, {b})");
        for said in stated.iter().chain([&colour]) {
            assert!(
                doc.contains(said.as_str()),
                "docs/outputs.md does not say {said:?}"
            );
        }
        // The no-data grey is the preview's: the map's pixels are all of it.
        let title_rows =
            preview.height() - h as u32 - crate::sheet::colour_bar_legend(4, 0.05, &[]).height();
        let x = (preview.width() - 4) / 2;
        assert_eq!(*preview.get_pixel(x, title_rows), crate::sheet::NO_DATA);
    }
}
