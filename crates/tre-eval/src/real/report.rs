//! The markdown tables of a [`RealReport`].

use super::*;

/// `x` as a percentage with one decimal, `–` for NaN.
pub(super) fn pct(x: f64) -> String {
    if x.is_nan() {
        "–".to_owned()
    } else {
        format!("{:.1}%", 100.0 * x)
    }
}

/// `x` with `d` decimals, `–` for NaN or none.
pub(super) fn num(x: Option<f64>, d: usize) -> String {
    match x {
        Some(v) if v.is_finite() => format!("{v:.d$}"),
        _ => "–".to_owned(),
    }
}

/// The report as markdown: pooled figures, the split by range, each frame, and the `rgb`
/// depth errors.
pub fn markdown(report: &RealReport) -> String {
    use std::fmt::Write;
    let mut out = String::new();
    let _ = writeln!(
        out,
        "Real frames: {} from {}; the spec is annotation spec v1 {}. Edge recall: spec ≥ {} cm \
         read ≥ {} cm; false hazards: spec < {} cm read ≥ {} cm.\n",
        report.frames,
        report
            .data
            .iter()
            .map(|d| d.display().to_string())
            .collect::<Vec<_>>()
            .join(" and ")
            + &report
                .split
                .as_ref()
                .map_or(String::new(), |s| format!(" (split {s})"))
            + if report.mounting_ignored {
                ", every camera's mounting left out"
            } else {
                ""
            },
        match report.reference {
            Reference::Raw => "on the same sensor depth (`tre annotate`), a reference, not truth",
            Reference::Fused => {
                "on depth fused from the neighbouring posed frames (`--reference fused`; \
                 frames without a pose left out)"
            }
        },
        100.0 * report.hazard_m,
        100.0 * report.hazard_m,
        100.0 * report.flat_m,
        100.0 * report.hazard_m
    );
    pooled_table(&mut out, report);
    range_table(&mut out, report);
    frame_table(&mut out, report);
    traversal_table(&mut out, report);
    safety_table(&mut out, report);
    sequence_table(&mut out, report);
    depth_table(&mut out, report);
    out
}

/// The safety figures of every row's three-state map, pooled and by range.
fn safety_table(out: &mut String, report: &RealReport) {
    use std::fmt::Write;
    out.push_str("\nSafety of the three-state map (traversable only where the interval's upper end is below 5 cm, hazard only where its lower end is above): missed hazards = spec ≥ 5 cm read traversable; floor coverage = spec < 1 cm read traversable (pooled: within 3 m; by range: the whole bin); interval coverage = share of pixels whose target (the spec on the same depth, or for `geometric` the spec of the same surface in the previous frame of a sequence with poses) lies inside the 90% interval:\n\n| row | missed hazards | floor coverage ≤ 3 m | interval coverage | missed < 2 m / 2–4 m / > 4 m | floor coverage < 2 m / 2–4 m / > 4 m | coverage < 2 m / 2–4 m / > 4 m | interval checked against |\n|---|---|---|---|---|---|---|---|\n");
    for r in &report.pooled {
        let Some(s) = &r.safety else { continue };
        let by = |f: fn(&SafetyFigures) -> f64| {
            RANGE_BINS
                .iter()
                .map(|(n, _, _)| s.by_range.get(*n).map_or("–".to_owned(), |x| pct(f(x))))
                .collect::<Vec<_>>()
                .join(" / ")
        };
        let _ = writeln!(
            out,
            "| {} | {} | {} | {} | {} | {} | {} | {} |",
            r.key,
            pct(s.all.missed_hazards),
            pct(s.all.floor_coverage),
            pct(s.all.interval_coverage),
            by(|x| x.missed_hazards),
            by(|x| x.floor_coverage),
            by(|x| x.interval_coverage),
            s.coverage_target,
        );
    }
}

/// Each sequence folder's figures: edge recall and false hazards within 4 m, floor, and the
/// safety figures, per row.
fn sequence_table(out: &mut String, report: &RealReport) {
    use std::fmt::Write;
    if report.per_sequence.len() < 2 {
        return;
    }
    out.push_str("\nBy sequence folder:\n\n| sequence | row | edge recall < 4 m | false hazards < 4 m | missed hazards | floor coverage ≤ 3 m | interval coverage | depth AbsRel | δ < 1.25 |\n|---|---|---|---|---|---|---|---|---|\n");
    for (seq, rows) in &report.per_sequence {
        for r in rows {
            let near = within_4m(&r.by_range);
            let s = r.safety.as_ref().map(|s| s.all);
            let _ = writeln!(
                out,
                "| {seq} | {} | {} | {} | {} | {} | {} | {} | {} |",
                r.key,
                pct(near.0),
                pct(near.1),
                s.map_or("–".to_owned(), |s| pct(s.missed_hazards)),
                s.map_or("–".to_owned(), |s| pct(s.floor_coverage)),
                s.map_or("–".to_owned(), |s| pct(s.interval_coverage)),
                num(r.depth.map(|d| d.abs_rel), 3),
                r.depth.map_or("–".to_owned(), |d| pct(d.delta_1_25)),
            );
        }
    }
}

/// The floor box's median and p90 roughness, centimetres, as table cells.
fn floor_cells(f: &Option<FloorStats>) -> (String, String) {
    (num(f.map(|f| f.median_cm), 2), num(f.map(|f| f.p90_cm), 2))
}

/// The pooled figures: the spec's own row, then each configuration's.
fn pooled_table(out: &mut String, report: &RealReport) {
    use std::fmt::Write;
    out.push_str("| row | RMSE | B-RMSE | F-RMSE | edge recall | false hazards | floor median (cm) | floor p90 (cm) | ms/frame |\n|---|---|---|---|---|---|---|---|---|\n");
    let (m, p) = floor_cells(&report.spec.floor);
    let _ = writeln!(
        out,
        "| spec (`tre annotate`) | 0 | 0 | 0 | – | – | {m} | {p} | {:.1} |",
        report.spec.ms
    );
    for r in &report.pooled {
        let (m, p) = floor_cells(&r.floor);
        let rough = &r.all.roughness;
        let _ = writeln!(
            out,
            "| {} | {:.3} | {:.3} | {:.3} | {} | {} | {m} | {p} | {} |",
            r.key,
            rough.rmse_cm,
            rough.b_rmse_cm,
            rough.f_rmse_cm,
            pct(r.all.hazard.edge_recall),
            pct(r.all.hazard.false_hazards),
            num(r.ms.get("total").copied(), 1),
        );
    }
}

/// Each configuration's figures by range of the sensor depth, pooled.
fn range_table(out: &mut String, report: &RealReport) {
    use std::fmt::Write;
    out.push_str("\nBy range (sensor depth), pooled:\n\n| row | range | px | RMSE (cm) | edge recall | false hazards |\n|---|---|---|---|---|---|\n");
    for r in &report.pooled {
        for (name, s) in &r.by_range {
            let _ = writeln!(
                out,
                "| {} | {name} | {} | {} | {} | {} |",
                r.key,
                s.roughness.pixels,
                num(Some(s.roughness.rmse_cm), 3),
                pct(s.hazard.edge_recall),
                pct(s.hazard.false_hazards),
            );
        }
    }
}

/// Each frame: the spec's floor figures, then each configuration's.
fn frame_table(out: &mut String, report: &RealReport) {
    use std::fmt::Write;
    out.push_str("\nPer frame:\n\n| frame | row | floor median (cm) | floor p90 (cm) | edge recall | false hazards | RMSE (cm) |\n|---|---|---|---|---|---|---|\n");
    for f in &report.per_frame {
        let (m, p) = floor_cells(&f.spec.floor);
        let _ = writeln!(out, "| {} | spec | {m} | {p} | – | – | 0 |", f.name);
        for r in &f.rows {
            let (m, p) = floor_cells(&r.floor);
            let _ = writeln!(
                out,
                "| {} | {} | {m} | {p} | {} | {} | {:.3} |",
                f.name,
                r.key,
                pct(r.all.hazard.edge_recall),
                pct(r.all.hazard.false_hazards),
                r.all.roughness.rmse_cm,
            );
        }
    }
}

/// The three-state maps, pooled: shares over every pixel and the three checks.
pub(super) fn traversal_table(out: &mut String, report: &RealReport) {
    use std::fmt::Write;
    out.push_str("\nThree-state maps (through the models' calibrated intervals where they carry them, else under the sensor's noise model alone; slope left out), pooled:\n\n| row | traversable | hazard | unknown | floor boxes within 2 m: traversable | … unknown | beyond 4 m, spec ≥ 5 cm: unknown | … hazard | drops (spec ≥ 10 cm) within 4 m: hazard | median uncertainty < 2 m / 2–4 m / > 4 m (cm) |\n|---|---|---|---|---|---|---|---|---|---|\n");
    for r in &report.pooled {
        let Some(t) = &r.traversal else { continue };
        let u = |k: &str| num(t.median_uncertainty_m.get(k).map(|u| 100.0 * u), 2);
        let _ = writeln!(
            out,
            "| {} | {} | {} | {} | {} | {} | {} | {} | {} | {} / {} / {} |",
            r.key,
            pct(t.all.traversable),
            pct(t.all.hazard),
            pct(t.all.unknown),
            t.near_floor.map_or("–".to_owned(), |f| pct(f.traversable)),
            t.near_floor.map_or("–".to_owned(), |f| pct(f.unknown)),
            pct(t.far_spec_rough.unknown),
            pct(t.far_spec_rough.hazard),
            pct(t.near_drops.hazard),
            u("0_2m"),
            u("2_4m"),
            u("4m_up"),
        );
    }
}

/// The `rgb` mode's depth errors against the sensor, per frame and pooled.
pub(super) fn depth_table(out: &mut String, report: &RealReport) {
    use std::fmt::Write;
    let Some(pooled) = report.pooled.iter().find_map(|r| r.depth.map(|d| (r, d))) else {
        return;
    };
    let _ = writeln!(
        out,
        "\nDepth of `{}` against the sensor:\n\n| frame | AbsRel | RMSE (m) | δ < 1.25 |\n|---|---|---|---|",
        pooled.0.key
    );
    let line = |out: &mut String, name: &str, d: &DepthMetrics| {
        let _ = writeln!(
            out,
            "| {name} | {:.3} | {:.3} | {} |",
            d.abs_rel,
            d.rmse_m,
            pct(d.delta_1_25)
        );
    };
    for f in &report.per_frame {
        if let Some(d) = f.rows.iter().find_map(|r| r.depth) {
            line(out, &f.name, &d);
        }
    }
    line(out, "pooled", &pooled.1);
}

/// Edge recall and false hazards over the range bins nearer than 4 m (pixel-weighted).
pub(super) fn within_4m(by_range: &BTreeMap<String, ScoreMetrics>) -> (f64, f64) {
    let (mut found, mut edges, mut false_h, mut flat) = (0.0, 0.0, 0.0, 0.0);
    for bin in ["0_2m", "2_4m"] {
        let Some(h) = by_range.get(bin).map(|m| m.hazard) else {
            continue;
        };
        if h.edges > 0 {
            found += h.edge_recall * h.edges as f64;
            edges += h.edges as f64;
        }
        if h.flat > 0 {
            false_h += h.false_hazards * h.flat as f64;
            flat += h.flat as f64;
        }
    }
    let share = |a: f64, n: f64| if n > 0.0 { a / n } else { f64::NAN };
    (share(found, edges), share(false_h, flat))
}
