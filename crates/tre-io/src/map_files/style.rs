//! How each layer of the map's picture is coloured: its title with the unit shown, the colour
//! scale of a continuous layer (a fixed range where the layer has a natural one, else the seen
//! values' 1st to 99th percentile, widened to round ticks), or the three states' colours.
//! Any layer name is drawn; the names it knows only choose ranges and directions.

use image::Rgb;
use tre_core::roughness::traversal::Traversal;

use crate::colormap::{traversal_rgb, turbo};
use crate::sheet::NO_DATA;

/// Colour of cells never seen.
pub(super) const NOT_SEEN: Rgb<u8> = Rgb([222, 222, 222]);

/// A layer's colour scale.
#[derive(Debug, Clone, PartialEq)]
pub(super) enum Scale {
    /// Turbo over `lo..hi` in the shown unit (values times `factor`); reversed: `hi` blue.
    Continuous {
        /// Low end, shown unit.
        lo: f64,
        /// High end, shown unit.
        hi: f64,
        /// Stored unit to shown unit.
        factor: f64,
        /// Ticks of the colour bar, shown unit.
        ticks: Vec<f64>,
        /// Decimals of the tick labels.
        decimals: usize,
        /// Whether the scale runs from red (low) to blue (high).
        reversed: bool,
    },
    /// The three states: 0 unknown, 1 traversable, 2 hazard.
    States,
}

/// How one layer is drawn.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct Style {
    /// The layer's name and its shown unit, e.g. `roughness (cm)`.
    pub(super) title: String,
    /// The shown unit (empty for the three states).
    pub(super) unit: String,
    /// Its colour scale.
    pub(super) scale: Scale,
}

impl Style {
    /// The style of layer `name`, stored in `unit`, whose seen cells hold `seen` (any order;
    /// NaN allowed).
    pub(super) fn of(name: &str, unit: &str, seen: &[f64]) -> Self {
        if name == "traversal" {
            return Self {
                title: name.to_owned(),
                unit: String::new(),
                scale: Scale::States,
            };
        }
        let (lo, hi) = fixed_range(name).unwrap_or_else(|| data_range(seen));
        let (shown, factor) = shown_unit(unit, lo, hi);
        let (lo, hi) = (lo * factor, hi * factor);
        let fixed = fixed_range(name).is_some();
        let (lo, hi, step) = ticks_step(lo, hi, fixed);
        let ticks = (0..=((hi - lo) / step).round() as usize)
            .map(|k| lo + k as f64 * step)
            .collect();
        Self {
            title: format!("{name} ({shown})"),
            unit: shown,
            scale: Scale::Continuous {
                lo,
                hi,
                factor,
                ticks,
                decimals: decimals(step),
                reversed: name == "score",
            },
        }
    }

    /// The colour of a seen cell holding `v` (NaN: [`NO_DATA`]).
    pub(super) fn colour(&self, v: f64) -> Rgb<u8> {
        match &self.scale {
            Scale::States => Rgb(traversal_rgb(match v as u8 {
                1 => Traversal::Traversable,
                2 => Traversal::Hazard,
                _ => Traversal::Unknown,
            })),
            _ if !v.is_finite() => NO_DATA,
            Scale::Continuous {
                lo,
                hi,
                factor,
                reversed,
                ..
            } => {
                let t = (v * factor - lo) / (hi - lo);
                Rgb(turbo(if *reversed { 1.0 - t } else { t }))
            }
        }
    }

    /// The colour at the fraction `t` (0 to 1) along the colour bar, low to high.
    pub(super) fn bar_colour(&self, t: f64) -> Rgb<u8> {
        match &self.scale {
            Scale::Continuous { reversed: true, .. } => Rgb(turbo(1.0 - t)),
            _ => Rgb(turbo(t)),
        }
    }

    /// A tick's label: its value with the scale's decimals, no trailing zeros after a point.
    pub(super) fn label(&self, v: f64) -> String {
        let decimals = match &self.scale {
            Scale::Continuous { decimals, .. } => *decimals,
            Scale::States => 0,
        };
        let s = format!("{:.*}", decimals, if v == 0.0 { 0.0 } else { v });
        if s.contains('.') {
            s.trim_end_matches('0').trim_end_matches('.').to_owned()
        } else {
            s
        }
    }
}

/// The range of a layer whose values have a natural one, stored unit: the traversability
/// limits' layers run to about twice their limit (docs/map.md).
fn fixed_range(name: &str) -> Option<(f64, f64)> {
    match name {
        "roughness" => Some((0.0, 0.05)),
        "step" => Some((0.0, 0.10)),
        "slope" => Some((0.0, 30.0)),
        "score" => Some((0.0, 1.0)),
        _ => None,
    }
}

/// The 1st to the 99th percentile of the finite values (0 to 1 without any).
fn data_range(values: &[f64]) -> (f64, f64) {
    let mut v: Vec<f64> = values.iter().copied().filter(|v| v.is_finite()).collect();
    if v.is_empty() {
        return (0.0, 1.0);
    }
    v.sort_by(f64::total_cmp);
    let at = |q: f64| v[(q * (v.len() - 1) as f64).round() as usize];
    (at(0.01), at(0.99))
}

/// The unit to show a layer stored in `unit` over `lo..hi` in, and the factor to it: small
/// lengths in centimetres, small areas in cm².
fn shown_unit(unit: &str, lo: f64, hi: f64) -> (String, f64) {
    let largest = lo.abs().max(hi.abs());
    match unit {
        "m" if largest < 1.0 => ("cm".to_owned(), 100.0),
        "m^2" if largest < 0.01 => ("cm^2".to_owned(), 1e4),
        _ => (unit.to_owned(), 1.0),
    }
}

/// The tick step for `lo..hi`: the least of 1, 2, 2.5 and 5 times a power of ten giving at
/// most five intervals; and the range, widened to whole steps unless `fixed`.
fn ticks_step(lo: f64, hi: f64, fixed: bool) -> (f64, f64, f64) {
    let (lo, hi) = if hi > lo {
        (lo, hi)
    } else {
        let pad = (lo.abs() * 0.05).max(1e-3);
        (lo - pad, hi + pad)
    };
    let span = hi - lo;
    let mut power = 10f64.powf((span / 5.0).log10().floor());
    let step = loop {
        if let Some(m) = [1.0, 2.0, 2.5, 5.0]
            .into_iter()
            .find(|m| span / (m * power) <= 5.0 + 1e-9)
        {
            break m * power;
        }
        power *= 10.0;
    };
    if fixed {
        return (lo, hi, step);
    }
    let lo = (lo / step + 1e-9).floor() * step;
    let hi = (hi / step - 1e-9).ceil() * step;
    (lo, hi, step)
}

/// Decimals that write every multiple of `step` exactly (2.5 needs one more than 2).
fn decimals(step: f64) -> usize {
    (0..6)
        .find(|&d| {
            let scaled = step * 10f64.powi(d as i32);
            (scaled - scaled.round()).abs() < 1e-6 * scaled.max(1.0)
        })
        .unwrap_or(6)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn continuous(s: &Style) -> (f64, f64, f64, Vec<f64>) {
        match &s.scale {
            Scale::Continuous {
                lo,
                hi,
                factor,
                ticks,
                ..
            } => (*lo, *hi, *factor, ticks.clone()),
            Scale::States => panic!("{} is continuous", s.title),
        }
    }

    #[test]
    fn small_lengths_show_in_centimetres_over_the_fixed_range() {
        let s = Style::of("roughness", "m", &[0.01, 0.2]);
        assert_eq!(s.title, "roughness (cm)");
        let (lo, hi, factor, ticks) = continuous(&s);
        assert_eq!((lo, hi, factor), (0.0, 5.0, 100.0));
        assert_eq!(ticks, [0.0, 1.0, 2.0, 3.0, 4.0, 5.0]);
        assert_eq!(
            s.colour(0.05),
            s.colour(0.2),
            "above the range: its top colour"
        );
        assert_eq!(s.colour(f64::NAN), NO_DATA);
    }

    #[test]
    fn other_layers_span_their_values_in_round_ticks() {
        let values: Vec<f64> = (0..=100).map(|i| -1.43 + 0.0153 * f64::from(i)).collect();
        let s = Style::of("elevation", "m", &values);
        assert_eq!(s.title, "elevation (m)");
        let (lo, hi, _, ticks) = continuous(&s);
        assert!(
            lo <= -1.41 && hi >= 0.08 && hi - lo <= 2.0 + 1e-9,
            "{lo}..{hi}"
        );
        assert_eq!(ticks.first(), Some(&lo));
        assert!((ticks.last().unwrap() - hi).abs() < 1e-9);
        assert!(ticks.len() <= 6);
        let upper = Style::of("upper_surface", "m", &[0.5, 0.9]);
        assert_eq!(upper.title, "upper_surface (cm)");
        assert_eq!(
            Style::of("count", "measurements", &[]).title,
            "count (measurements)"
        );
        assert_eq!(Style::of("variance", "m^2", &[1e-4, 4e-4]).unit, "cm^2");
    }

    #[test]
    fn score_runs_red_to_blue_and_states_take_their_colours() {
        let s = Style::of("score", "0 to 1", &[]);
        assert_eq!(s.colour(0.0), Rgb(turbo(1.0)));
        assert_eq!(s.bar_colour(0.0), s.colour(0.0));
        let t = Style::of("traversal", "0 unknown, 1 traversable, 2 hazard", &[]);
        assert_eq!(t.title, "traversal");
        assert_eq!(t.colour(2.0).0, traversal_rgb(Traversal::Hazard));
    }

    #[test]
    fn labels_have_the_steps_decimals() {
        let s = Style::of("slope", "degrees", &[]);
        assert_eq!(s.label(10.0), "10");
        let s = Style::of("score", "0 to 1", &[]);
        assert_eq!(s.label(0.4), "0.4");
        assert_eq!(decimals(2.5), 1);
        assert_eq!(decimals(0.25), 2);
        assert_eq!(decimals(20.0), 0);
    }
}
