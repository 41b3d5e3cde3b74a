//! Latency plots as hand-written SVG: the percentile spectrum on a "nines" axis (0 to 99.99%)
//! and, for one run, latency over time; for a sweep, p50/p90/p99 against the offered rate.

use std::fmt::Write as _;

use super::report::SweepReport;
use super::stats::{fmt_rate, Report, SampleKind};

/// Width of the image, pixels.
const WIDTH: f64 = 920.0;
/// Height of one panel, pixels.
const PANEL_H: f64 = 400.0;
/// Plot area margins inside a panel: left, right (legend), top (title), bottom (x label).
const MARGIN: (f64, f64, f64, f64) = (70.0, 200.0, 44.0, 56.0);
/// Highest point of the spectrum axis, in nines (4 = 99.99%).
const MAX_NINES: f64 = 4.0;
/// Series colours, in order.
const PALETTE: [&str; 10] = [
    "#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#7f7f7f",
    "#bcbd22", "#17becf",
];

/// How a series is drawn.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Style {
    Line,
    Dashed,
    Dots,
    LineDots,
}

/// One named set of points.
struct Series {
    name: String,
    colour: &'static str,
    style: Style,
    points: Vec<(f64, f64)>,
}

/// An axis: its label, range and ticks (value, text).
struct Axis {
    label: String,
    min: f64,
    max: f64,
    ticks: Vec<(f64, String)>,
}

/// One chart.
struct Panel {
    title: String,
    x: Axis,
    y: Axis,
    series: Vec<Series>,
    /// A labelled horizontal line (the objective).
    hline: Option<(f64, String)>,
}

/// `-log10(1 − p/100)`: 0 at 0%, 1 at 90%, 2 at 99%, …, capped at 99.99%.
pub fn nines(percentile: f64) -> f64 {
    let rest = (1.0 - percentile / 100.0).max(10f64.powf(-MAX_NINES));
    (-rest.log10()).clamp(0.0, MAX_NINES)
}

/// The nines axis with ticks at 0%, 90%, 99%, 99.9%, 99.99%.
fn nines_axis() -> Axis {
    let labels = ["0%", "90%", "99%", "99.9%", "99.99%"];
    Axis {
        label: "percentile (log scale of nines)".into(),
        min: 0.0,
        max: MAX_NINES,
        ticks: labels
            .iter()
            .enumerate()
            .map(|(i, l)| (i as f64, (*l).to_string()))
            .collect(),
    }
}

/// A linear axis from 0 (or `min`) to a round number at or above `max`, with 4–8 ticks.
fn linear_axis(label: &str, min: f64, max: f64) -> Axis {
    let span = (max - min).max(1e-9);
    let raw = span / 5.0;
    let mag = 10f64.powf(raw.log10().floor());
    let step = [1.0, 2.0, 2.5, 5.0, 10.0]
        .iter()
        .map(|m| m * mag)
        .find(|s| span / s <= 7.0)
        .unwrap_or(10.0 * mag);
    let lo = (min / step).floor() * step;
    let hi = (max / step).ceil().max(1.0) * step;
    let n = ((hi - lo) / step).round() as usize;
    let ticks = (0..=n)
        .map(|k| {
            let v = lo + k as f64 * step;
            let text = if step < 1.0 {
                format!("{v:.1}")
            } else {
                format!("{v:.0}")
            };
            (v, text)
        })
        .collect();
    Axis {
        label: label.into(),
        min: lo,
        max: hi,
        ticks,
    }
}

/// `&`, `<`, `>`, `"` escaped for SVG text and attributes.
fn esc(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// Largest y of the series and the line, at least `floor`.
fn y_max(series: &[Series], hline: Option<f64>, floor: f64) -> f64 {
    series
        .iter()
        .flat_map(|s| s.points.iter().map(|p| p.1))
        .chain(hline)
        .filter(|v| v.is_finite())
        .fold(floor, f64::max)
}

/// A panel's plot area on the page, pixels: its top-left corner and size, and the panel's
/// axes that map values into it.
struct Area<'a> {
    panel: &'a Panel,
    x0: f64,
    y0: f64,
    w: f64,
    h: f64,
}

impl<'a> Area<'a> {
    /// The plot area of `panel` drawn with its top-left corner at `top` pixels.
    fn of(panel: &'a Panel, top: f64) -> Self {
        let (ml, mr, mt, mb) = MARGIN;
        Self {
            panel,
            x0: ml,
            y0: top + mt,
            w: WIDTH - ml - mr,
            h: PANEL_H - mt - mb,
        }
    }

    /// The page x of value `x`.
    fn px(&self, x: f64) -> f64 {
        let a = &self.panel.x;
        self.x0 + (x - a.min) / (a.max - a.min).max(1e-12) * self.w
    }

    /// The page y of value `y`.
    fn py(&self, y: f64) -> f64 {
        let a = &self.panel.y;
        self.y0 + self.h - (y - a.min) / (a.max - a.min).max(1e-12) * self.h
    }
}

/// Draws `panel` with its top-left corner at `top` pixels.
fn draw(out: &mut String, panel: &Panel, top: f64) {
    let area = Area::of(panel, top);
    let (x0, y0, w, h) = (area.x0, area.y0, area.w, area.h);
    let _ = writeln!(
        out,
        r#"<text x="{:.1}" y="{:.1}" font-size="15" font-weight="bold" text-anchor="middle">{}</text>"#,
        x0 + w / 2.0,
        top + 26.0,
        esc(&panel.title)
    );
    let _ = writeln!(
        out,
        r##"<rect x="{x0:.1}" y="{y0:.1}" width="{w:.1}" height="{h:.1}" fill="none" stroke="#444"/>"##
    );
    draw_axes(out, &area);
    if let Some((v, label)) = &panel.hline {
        let y = area.py(*v);
        let _ = writeln!(
            out,
            r##"<line x1="{x0:.1}" y1="{y:.1}" x2="{:.1}" y2="{y:.1}" stroke="#d62728" stroke-dasharray="6 4"/><text x="{:.1}" y="{:.1}" fill="#d62728" text-anchor="end">{}</text>"##,
            x0 + w,
            x0 + w - 4.0,
            y - 4.0,
            esc(label)
        );
    }
    for s in &panel.series {
        draw_series(out, s, &|x| area.px(x), &|y| area.py(y));
    }
    legend(out, &panel.series, x0 + w + 14.0, y0 + 6.0);
}

/// The grid lines with their tick labels, and the axis labels.
fn draw_axes(out: &mut String, area: &Area<'_>) {
    let (x0, y0, w, h) = (area.x0, area.y0, area.w, area.h);
    for (v, t) in &area.panel.x.ticks {
        let x = area.px(*v);
        let _ = writeln!(
            out,
            r##"<line x1="{x:.1}" y1="{y0:.1}" x2="{x:.1}" y2="{:.1}" stroke="#ddd"/><text x="{x:.1}" y="{:.1}" text-anchor="middle">{}</text>"##,
            y0 + h,
            y0 + h + 16.0,
            esc(t)
        );
    }
    for (v, t) in &area.panel.y.ticks {
        let y = area.py(*v);
        let _ = writeln!(
            out,
            r##"<line x1="{x0:.1}" y1="{y:.1}" x2="{:.1}" y2="{y:.1}" stroke="#ddd"/><text x="{:.1}" y="{:.1}" text-anchor="end">{}</text>"##,
            x0 + w,
            x0 - 6.0,
            y + 4.0,
            esc(t)
        );
    }
    let _ = writeln!(
        out,
        r#"<text x="{:.1}" y="{:.1}" text-anchor="middle">{}</text>"#,
        x0 + w / 2.0,
        y0 + h + 38.0,
        esc(&area.panel.x.label)
    );
    let _ = writeln!(
        out,
        r#"<text transform="translate({:.1},{:.1}) rotate(-90)" text-anchor="middle">{}</text>"#,
        x0 - 50.0,
        y0 + h / 2.0,
        esc(&area.panel.y.label)
    );
}

fn draw_series(out: &mut String, s: &Series, px: &dyn Fn(f64) -> f64, py: &dyn Fn(f64) -> f64) {
    let pts: Vec<(f64, f64)> = s
        .points
        .iter()
        .filter(|p| p.0.is_finite() && p.1.is_finite())
        .map(|&(x, y)| (px(x), py(y)))
        .collect();
    if matches!(s.style, Style::Line | Style::Dashed | Style::LineDots) && pts.len() > 1 {
        let d: Vec<String> = pts.iter().map(|(x, y)| format!("{x:.1},{y:.1}")).collect();
        let dash = if s.style == Style::Dashed {
            r#" stroke-dasharray="5 3""#
        } else {
            ""
        };
        let _ = writeln!(
            out,
            r#"<polyline fill="none" stroke="{}" stroke-width="1.8"{dash} points="{}"/>"#,
            s.colour,
            d.join(" ")
        );
    }
    if matches!(s.style, Style::Dots | Style::LineDots) || pts.len() == 1 {
        let r = if s.style == Style::Dots { 2.4 } else { 3.2 };
        let _ = writeln!(out, r#"<g fill="{}" fill-opacity="0.7">"#, s.colour);
        for (x, y) in &pts {
            let _ = writeln!(out, r#"<circle cx="{x:.1}" cy="{y:.1}" r="{r}"/>"#);
        }
        out.push_str("</g>\n");
    }
}

fn legend(out: &mut String, series: &[Series], x: f64, y: f64) {
    for (i, s) in series.iter().enumerate() {
        let yy = y + 18.0 * i as f64;
        let mark = match s.style {
            Style::Dots => format!(
                r#"<circle cx="{:.1}" cy="{:.1}" r="4" fill="{}"/>"#,
                x + 10.0,
                yy,
                s.colour
            ),
            Style::Dashed => format!(
                r#"<line x1="{x:.1}" y1="{yy:.1}" x2="{:.1}" y2="{yy:.1}" stroke="{}" stroke-width="2" stroke-dasharray="5 3"/>"#,
                x + 20.0,
                s.colour
            ),
            Style::Line | Style::LineDots => format!(
                r#"<line x1="{x:.1}" y1="{yy:.1}" x2="{:.1}" y2="{yy:.1}" stroke="{}" stroke-width="2"/>"#,
                x + 20.0,
                s.colour
            ),
        };
        let _ = writeln!(
            out,
            r#"{mark}<text x="{:.1}" y="{:.1}">{}</text>"#,
            x + 26.0,
            yy + 4.0,
            esc(&s.name)
        );
    }
}

/// Spectrum series of `r`: results, and refusals dashed (the 100% point left out: the legend
/// names the maximum).
fn spectrum_series(r: &Report, name: &str, colour: &'static str, refusals: bool) -> Vec<Series> {
    let pts = |spec: &[[f64; 2]]| -> Vec<(f64, f64)> {
        spec.iter()
            .filter(|p| p[0] < 100.0)
            .map(|p| (nines(p[0]), p[1]))
            .collect()
    };
    let mut v = Vec::new();
    if !r.spectrum_ok.is_empty() {
        v.push(Series {
            name: format!("{name} ok (max {:.0} ms)", r.latency_ms.max_ms),
            colour,
            style: Style::Line,
            points: pts(&r.spectrum_ok),
        });
    }
    if refusals && !r.spectrum_refused.is_empty() {
        v.push(Series {
            name: format!("{name} refused (max {:.1} ms)", r.refusal_latency_ms.max_ms),
            colour,
            style: Style::Dashed,
            points: pts(&r.spectrum_refused),
        });
    }
    v
}

fn spectrum_panel(title: String, series: Vec<Series>, slo_ms: Option<f64>) -> Panel {
    let top = y_max(&series, slo_ms, 1.0) * 1.05;
    Panel {
        title,
        x: nines_axis(),
        y: linear_axis("latency from intended send (ms)", 0.0, top),
        series,
        hline: slo_ms.map(|v| (v, format!("SLO {} ms", fmt_rate(v)))),
    }
}

fn svg(panels: &[Panel], footer: &str) -> String {
    let height = PANEL_H * panels.len() as f64 + 24.0;
    let mut out = format!(
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{WIDTH:.0}" height="{height:.0}" viewBox="0 0 {WIDTH:.0} {height:.0}" font-family="sans-serif" font-size="12">
<rect width="100%" height="100%" fill="white"/>
"#
    );
    for (i, p) in panels.iter().enumerate() {
        draw(&mut out, p, PANEL_H * i as f64);
    }
    let _ = writeln!(
        out,
        r##"<text x="8" y="{:.1}" fill="#555" font-size="11">{}</text>"##,
        height - 8.0,
        esc(footer)
    );
    out.push_str("</svg>\n");
    out
}

/// The plot of one run: the latency spectrum of results and refusals, and latency over time.
pub fn plot_run(r: &Report) -> String {
    let title = format!(
        "tre loadtest: {} — {:.2} ok/s, {} ok, {} refused, {} errors",
        r.label(),
        r.throughput_ok_per_s,
        r.ok,
        r.refused,
        r.errors
    );
    let spectrum = spectrum_panel(
        format!("Latency spectrum: {}", r.label()),
        spectrum_series(r, "", PALETTE[0], true),
        None,
    );
    let kinds = [
        (SampleKind::Ok, "ok", PALETTE[0]),
        (SampleKind::Refused, "refused", PALETTE[1]),
        (SampleKind::Error, "error", PALETTE[3]),
        (SampleKind::Dropped, "dropped", PALETTE[7]),
    ];
    let series: Vec<Series> = kinds
        .iter()
        .map(|(kind, name, colour)| Series {
            name: (*name).into(),
            colour,
            style: Style::Dots,
            points: r
                .samples
                .iter()
                .filter(|s| s.kind == *kind)
                .map(|s| (s.t_s, s.ms))
                .collect(),
        })
        .filter(|s| !s.points.is_empty())
        .collect();
    let t_max = r
        .samples
        .iter()
        .map(|s| s.t_s)
        .fold(r.window_s, f64::max)
        .max(1e-3);
    let over_time = Panel {
        title: "Latency over time (by intended send time)".into(),
        x: linear_axis("time in the measured window (s)", 0.0, t_max),
        y: linear_axis("latency (ms)", 0.0, y_max(&series, None, 1.0) * 1.05),
        series,
        hline: None,
    };
    svg(
        &[spectrum, over_time],
        &format!("{title}; frames: {}", r.run.frames),
    )
}

/// The plot of a sweep: one spectrum per rate, and p50/p90/p99 against the offered rate with
/// the objective.
pub fn plot_sweep(sw: &SweepReport) -> String {
    let series: Vec<Series> = sw
        .rows
        .iter()
        .enumerate()
        .flat_map(|(i, r)| {
            let name = format!("{}/s", fmt_rate(offered_rate(r)));
            spectrum_series(r, &name, PALETTE[i % PALETTE.len()], false)
        })
        .collect();
    let spectrum = spectrum_panel(
        "Latency spectrum of results per offered rate".into(),
        series,
        Some(sw.slo_ms),
    );
    let footer = sw.rows.first().map_or_else(String::new, |r| {
        format!(
            "tre loadtest sweep: {} {}; frames: {}",
            r.run.protocol.as_str(),
            r.run.url,
            r.run.frames
        )
    });
    svg(&[spectrum, by_rate_panel(sw)], &footer)
}

/// The offered rate of a sweep's row, requests per second (0 for an unpaced row).
fn offered_rate(r: &Report) -> f64 {
    r.run.offered_rate_per_s.unwrap_or(0.0)
}

/// p50, p90, p99 and the share refused against the offered rate, with the objective and the
/// knee.
fn by_rate_panel(sw: &SweepReport) -> Panel {
    let line = |name: &str, colour, f: fn(&Report) -> f64| Series {
        name: name.into(),
        colour,
        style: Style::LineDots,
        points: sw
            .rows
            .iter()
            .filter(|r| r.ok > 0)
            .map(|r| (offered_rate(r), f(r)))
            .collect(),
    };
    let lines = vec![
        line("p50", PALETTE[0], |r| r.latency_ms.p50_ms),
        line("p90", PALETTE[2], |r| r.latency_ms.p90_ms),
        line("p99", PALETTE[1], |r| r.latency_ms.p99_ms),
        line("refused %", PALETTE[7], |r| {
            100.0 * r.refused as f64 / r.requests.max(1) as f64
        }),
    ];
    let (lo, hi) = sw
        .rows
        .iter()
        .map(offered_rate)
        .fold((f64::MAX, 0.0f64), |(a, b), v| (a.min(v), b.max(v)));
    let knee = sw.knee.as_ref().map_or_else(
        || "knee: not reached".into(),
        |k| format!("knee at {}/s", fmt_rate(k.rate_per_s)),
    );
    Panel {
        title: format!("Latency against offered rate ({knee})"),
        x: linear_axis("offered rate (requests/s)", lo.min(hi), hi),
        y: linear_axis(
            "latency (ms); refused (% of requests)",
            0.0,
            y_max(&lines, Some(sw.slo_ms), 1.0) * 1.05,
        ),
        series: lines,
        hline: Some((sw.slo_ms, format!("SLO p99 {} ms", fmt_rate(sw.slo_ms)))),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::report::tests::report;
    use crate::stats::Sample;
    use approx::assert_relative_eq;

    /// Light well-formedness check: balanced tags, one root, no stray `<` or `&` in text.
    fn check_well_formed(svg: &str) {
        assert!(svg.starts_with("<svg "), "starts with <svg");
        assert!(svg.trim_end().ends_with("</svg>"));
        let mut stack: Vec<String> = Vec::new();
        let mut rest = svg;
        while let Some(i) = rest.find('<') {
            let text = &rest[..i];
            assert!(!text.contains('>'), "stray > in {text:?}");
            for (k, _) in text.match_indices('&') {
                let ent = &text[k..];
                assert!(
                    ["&amp;", "&lt;", "&gt;", "&quot;"]
                        .iter()
                        .any(|e| ent.starts_with(e)),
                    "bare & in {text:?}"
                );
            }
            let end = rest[i..].find('>').expect("tag closes") + i;
            let tag = &rest[i + 1..end];
            if let Some(name) = tag.strip_prefix('/') {
                assert_eq!(stack.pop().as_deref(), Some(name), "closing {name}");
            } else if !tag.ends_with('/') {
                let name = tag.split_whitespace().next().expect("tag name");
                stack.push(name.to_string());
            }
            assert_eq!(tag.matches('"').count() % 2, 0, "quotes in <{tag}>");
            rest = &rest[end + 1..];
        }
        assert!(stack.is_empty(), "unclosed {stack:?}");
    }

    #[test]
    fn nines_put_90_99_and_99_9_percent_one_step_apart() {
        assert_relative_eq!(nines(0.0), 0.0);
        assert_relative_eq!(nines(90.0), 1.0, epsilon = 1e-12);
        assert_relative_eq!(nines(99.0), 2.0, epsilon = 1e-12);
        assert_relative_eq!(nines(99.9), 3.0, epsilon = 1e-9);
        assert_relative_eq!(nines(100.0), 4.0);
    }

    #[test]
    fn ticks_are_round_and_cover_the_range() {
        let a = linear_axis("ms", 0.0, 437.0);
        assert_eq!(a.min, 0.0);
        assert!(a.max >= 437.0 && a.max <= 600.0, "{}", a.max);
        assert!((4..=9).contains(&a.ticks.len()), "{}", a.ticks.len());
        assert_eq!(a.ticks[1].1, "100");
    }

    #[test]
    fn the_run_plot_is_well_formed_and_labelled() {
        let mut r = report(10.0, 100, 120, 5);
        r.samples = vec![
            Sample {
                t_s: 0.5,
                ms: 120.0,
                kind: SampleKind::Ok,
            },
            Sample {
                t_s: 0.7,
                ms: 1.0,
                kind: SampleKind::Refused,
            },
        ];
        r.run.frames = "a <weird> & \"frame\"".into();
        let svg = plot_run(&r);
        check_well_formed(&svg);
        for label in [
            "percentile (log scale of nines)",
            "latency from intended send (ms)",
            "99.9%",
            "Latency over time",
            "time in the measured window (s)",
            "refused",
        ] {
            assert!(svg.contains(label), "{label:?} missing");
        }
    }

    #[test]
    fn the_sweep_plot_is_well_formed_and_shows_the_knee() {
        let rows = vec![
            report(4.0, 40, 100, 0),
            report(8.0, 80, 200, 0),
            report(12.0, 90, 400, 30),
        ];
        let svg = plot_sweep(&SweepReport::new(rows, 150.0));
        check_well_formed(&svg);
        for label in [
            "knee at 8/s",
            "SLO p99 150 ms",
            "offered rate (requests/s)",
            "4/s ok",
        ] {
            assert!(svg.contains(label), "{label:?} missing");
        }
    }
}
