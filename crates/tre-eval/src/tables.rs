//! The rows of the paper's Tables II, IV and V for `tre eval --tables`, and their markdown.

use std::fmt::Write;

use crate::synthetic::{row_key, RowResult, RowSpec};
use tre_pipeline::{CentroidMethod, GeometricMethod, Method, Mode, NormalsMethod, PipelineConfig};

/// The ablations of Table IV per input mode: (normals, refiner, centroid).
const ABLATIONS: [(NormalsMethod, bool, CentroidMethod); 5] = [
    (NormalsMethod::Dsac, true, CentroidMethod::Net),
    (NormalsMethod::Dsac, false, CentroidMethod::Net),
    (NormalsMethod::Ls, true, CentroidMethod::Net),
    (NormalsMethod::Ls, false, CentroidMethod::Net),
    (NormalsMethod::Dsac, true, CentroidMethod::Window),
];

/// Every distinct configuration the three tables need, each run once; `base` gives the seed
/// and the other settings.
pub fn row_specs(base: &PipelineConfig) -> Vec<RowSpec> {
    let with = |mode, method, (normals, refine, centroid)| PipelineConfig {
        mode,
        method,
        normals,
        refine,
        centroid,
        ..*base
    };
    let mut cfgs = Vec::new();
    for mode in [Mode::Rgb, Mode::Rgbd] {
        for stages in ABLATIONS {
            cfgs.push(with(mode, Method::Pipeline, stages));
        }
    }
    let ls_window = (NormalsMethod::Ls, false, CentroidMethod::Window);
    cfgs.push(with(Mode::Rgb, Method::Pipeline, ls_window));
    cfgs.push(with(Mode::Rgb, Method::EndToEnd, ABLATIONS[0]));
    // The paper's tables compare against its surface-only geometric baseline.
    cfgs.push(PipelineConfig {
        geometric: GeometricMethod::SurfaceOnly,
        ..with(Mode::Geometric, Method::Pipeline, ls_window)
    });
    cfgs.into_iter()
        .map(|cfg| RowSpec {
            key: row_key(&cfg),
            cfg,
        })
        .collect()
}

/// Tables II, IV and V, and the depth errors of rgb mode, as markdown. The tables name their
/// rows with `DSAC`; rows run with another number of hypotheses are found under their own
/// label (`DSAC(K=4)`).
pub fn markdown(rows: &[RowResult]) -> String {
    let dsac = rows
        .first()
        .map_or_else(|| "DSAC".to_owned(), |r| r.config.dsac_label());
    let find = |key: &str| {
        let key = key.replace("DSAC", &dsac);
        rows.iter().find(|r| r.key == key)
    };
    let mut out = String::new();
    table_ii(&mut out, &find, &dsac);
    table_iv(&mut out, rows);
    table_v(&mut out, &find, &dsac);
    depth_table(&mut out, rows);
    out
}

type Find<'a> = dyn Fn(&str) -> Option<&'a RowResult> + 'a;

fn table_ii<'a>(out: &mut String, find: &Find<'a>, dsac: &str) {
    out.push_str(
        "Table II: roughness (cm)\n\n| method | RMSE | B-RMSE | F-RMSE |\n|---|---|---|---|\n",
    );
    let rows = [
        (
            "geometric on predicted depth (DE+LS+window)",
            "rgb:DE+LS+window",
        ),
        ("end-to-end baseline", "e2e:E2E"),
        ("TRENet, RGB (DE+DSAC+NR+ESR)", "rgb:DE+DSAC+NR+ESR"),
    ];
    for (name, key) in rows {
        if let Some(r) = find(key) {
            let name = name.replace("DSAC", dsac);
            let _ = writeln!(out, "| {name} | {} |", roughness_cells(r));
        }
    }
    out.push('\n');
}

/// RMSE, B-RMSE and F-RMSE of a row as three markdown cells (cm, 3 decimals).
fn roughness_cells(r: &RowResult) -> String {
    let m = &r.roughness;
    format!("{:.3} | {:.3} | {:.3}", m.rmse_cm, m.b_rmse_cm, m.f_rmse_cm)
}

fn table_iv(out: &mut String, rows: &[RowResult]) {
    out.push_str("Table IV: ablations, roughness (cm)\n\n| input | stages | RMSE | B-RMSE | F-RMSE |\n|---|---|---|---|---|\n");
    for r in rows.iter().filter(|r| r.config.method == Method::Pipeline) {
        let is_table_ii_only = r.key == "rgb:DE+LS+window";
        if is_table_ii_only {
            continue;
        }
        let (input, stages) = r.key.split_once(':').unwrap_or((&r.key, ""));
        let _ = writeln!(out, "| {input} | {stages} | {} |", roughness_cells(r));
    }
    out.push('\n');
}

fn table_v<'a>(out: &mut String, find: &Find<'a>, dsac: &str) {
    out.push_str("Table V: normals\n\n| input | normals | mean ° | median ° | < 11.25° % | < 22.5° % | < 30° % | ms/frame |\n|---|---|---|---|---|---|---|---|\n");
    let variants = [
        ("LS", "LS+ESR"),
        ("LS+NR", "LS+NR+ESR"),
        ("DSAC", "DSAC+ESR"),
        ("DSAC+NR", "DSAC+NR+ESR"),
    ];
    for (mode, prefix) in [("rgb", "DE+"), ("rgbd", "")] {
        for (name, stages) in variants {
            let key = format!("{mode}:{prefix}{stages}");
            let Some(r) = find(&key) else { continue };
            let Some(n) = &r.normals else { continue };
            let name = name.replace("DSAC", dsac);
            let ms = ["normals", "refine"]
                .iter()
                .filter_map(|s| r.mean_ms.get(*s))
                .sum::<f64>();
            let _ = writeln!(
                out,
                "| {mode} | {name} | {:.2} | {:.2} | {:.1} | {:.1} | {:.1} | {ms:.1} |",
                n.mean_deg, n.median_deg, n.under_11_25_pct, n.under_22_5_pct, n.under_30_pct
            );
        }
    }
    out.push('\n');
}

fn depth_table(out: &mut String, rows: &[RowResult]) {
    let Some((r, d)) = rows.iter().find_map(|r| r.depth.map(|d| (r, d))) else {
        return;
    };
    let _ = writeln!(
        out,
        "Depth (rgb mode, {}): AbsRel {:.4}, RMSE {:.3} m, δ < 1.25 {:.1}%",
        r.key,
        d.abs_rel,
        d.rmse_m,
        100.0 * d.delta_1_25
    );
}
