//! The geometric mode against truth that is not the same raw depth: the known-flat and
//! known-hazard regions of every shared set's test frames (tests/fixtures/real_regions.json),
//! per sensor class. The spec on the raw depth fails on LiDAR and stereo; the terrain
//! estimate must not; the spec on cleaned depth must keep Kinect's flat floor flat.

use std::error::Error;
use std::path::{Path, PathBuf};

use tre::eval::real::{frames_of, score_regions, RegionFile, RegionReport};
use tre::pipeline::{GeometricMethod, Mode, Pipeline, PipelineConfig};
use tre::roughness::noise::{SensorNoise, SensorPreset};

type TestResult = Result<(), Box<dyn Error>>;

fn share(a: usize, b: usize) -> f64 {
    a as f64 / b.max(1) as f64
}

/// The terrain estimate's and the spec's region figures on the test frames of the three
/// corpora.
fn report() -> Result<RegionReport, Box<dyn Error>> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let dirs: Vec<PathBuf> = ["data/real-rgbd", "data/real-rgbd-2", "data/real-rgbd-3"]
        .iter()
        .map(|c| crate::common::shared_root().join(c))
        .collect();
    let splits = root.join("models/real_splits.json");
    let frames = frames_of(&dirs, Some(&splits), "test", None)?;
    let file = RegionFile::read(&root.join("tests/fixtures/real_regions.json"))?;
    let rows: Vec<(String, PipelineConfig)> = [
        GeometricMethod::Terrain,
        GeometricMethod::Spec,
        GeometricMethod::SpecCleaned,
    ]
    .into_iter()
    .map(|geometric| {
        let cfg = PipelineConfig {
            mode: Mode::Geometric,
            geometric,
            ..PipelineConfig::default()
        };
        (cfg.label(), cfg)
    })
    .collect();
    let mut pipeline = Pipeline::new(None);
    let kinect = SensorNoise::Preset(SensorPreset::KinectV1);
    Ok(score_regions(
        &frames,
        &file,
        &rows,
        &mut pipeline,
        &kinect,
    )?)
}

#[test]
fn flat_ground_reads_flat_and_hazards_are_seen_on_every_sensor_class() -> TestResult {
    for corpus in ["data/real-rgbd", "data/real-rgbd-2", "data/real-rgbd-3"] {
        crate::common::skip_unless_shared!(corpus, Ok(()));
    }
    let report = report()?;
    let (terrain, spec, cleaned) = (&report.rows[0], &report.rows[1], &report.rows[2]);
    for class in [
        "kinect",
        "lidar (one sweep)",
        "lidar_accumulated",
        "passive_stereo",
    ] {
        let (name, t) = terrain
            .iter()
            .find(|(c, _)| c.starts_with(class))
            .ok_or_else(|| format!("no {class} regions"))?;
        assert!(
            t.flat_px > 5000 || class.starts_with("lidar ("),
            "{name}: {} px",
            t.flat_px
        );
        let rough = share(t.flat_rough, t.flat_read);
        assert!(rough <= 0.02, "{name}: flat ground read >= 5 cm on {rough}");
        let hazard = share(t.flat_states[1], t.flat_px_gravity);
        assert!(
            hazard <= 0.03,
            "{name}: flat ground read hazard on {hazard}"
        );
        // Without gravity a wall's foot (a crease, no step) is neither rough nor steep.
        let (boxes, seen) = t.hazard_boxes_gravity;
        assert!(
            share(seen, boxes) >= 0.9,
            "{name}: hazards seen {seen} of {boxes}"
        );
        // The spec on the same raw depth (the old geometric mode) fails where noted.
        let s = &spec[name];
        if class.starts_with("lidar_accumulated") || class.starts_with("passive") {
            let spec_rough = share(s.flat_rough, s.flat_read);
            assert!(spec_rough > 0.5, "{name}: the spec reads {spec_rough}");
        }
    }
    // Where noise is small enough to tell, flat ground is traversable (the goal is 90%; stereo
    // reaches 88.7%, the rest unknown beyond ~12 m: docs/terrain.md).
    for (class, least) in [
        ("kinect", 0.88),
        ("lidar (one sweep)", 0.9),
        ("passive_stereo", 0.85),
    ] {
        let t = terrain
            .iter()
            .find(|(c, _)| c.starts_with(class))
            .ok_or(class)?
            .1;
        let ok = share(t.flat_states[0], t.flat_px_gravity);
        assert!(ok >= least, "{class}: flat ground traversable on {ok}");
    }
    assert_cleaned_keeps_the_kinect_floor_flat(spec, cleaned)
}

/// The spec on cleaned depth (for dense depth): on Kinect frames it drops most of what the
/// sensor's noise made of the flat floor and sees most hazards (24 of 32 boxes here, with no
/// intervals table; 28 through its table, docs/terrain.md).
fn assert_cleaned_keeps_the_kinect_floor_flat(
    spec: &std::collections::BTreeMap<String, tre::eval::real::RegionFigures>,
    cleaned: &std::collections::BTreeMap<String, tre::eval::real::RegionFigures>,
) -> TestResult {
    let c = cleaned
        .iter()
        .find(|(c, _)| c.starts_with("kinect"))
        .ok_or("no kinect regions")?
        .1;
    let s = spec
        .iter()
        .find(|(c, _)| c.starts_with("kinect"))
        .ok_or("no kinect regions")?
        .1;
    let (c_rough, s_rough) = (
        share(c.flat_rough, c.flat_read),
        share(s.flat_rough, s.flat_read),
    );
    assert!(
        c_rough <= 0.02 && c_rough < s_rough / 2.0,
        "kinect: flat read >= 5 cm on {c_rough} cleaned, {s_rough} raw"
    );
    let (boxes, seen) = c.hazard_boxes;
    assert!(
        share(seen, boxes) >= 0.7,
        "kinect, cleaned: hazards seen {seen} of {boxes}"
    );
    Ok(())
}

/// Against the kitchen's surface fused from its neighbouring posed views (truth without the
/// single view's noise), the spec on cleaned depth keeps the creases the terrain estimate
/// spreads out, with few false hazards (docs/terrain.md).
#[test]
fn the_spec_on_cleaned_depth_keeps_the_kitchens_creases() -> TestResult {
    crate::common::skip_unless_shared!("data/real-rgbd-2", Ok(()));
    let kitchen = crate::common::shared_root().join("data/real-rgbd-2/sevenscenes_redkitchen");
    let dir = tempfile::tempdir()?;
    let json = dir.path().join("fused.json");
    let o = crate::common::tre(&[
        "eval",
        "--real",
        crate::common::s(&kitchen),
        "--real-splits",
        "models/real_splits.json",
        "--split",
        "test",
        "--reference",
        "fused",
        "--mode",
        "geometric",
        "--limit",
        "16",
        "--json",
        crate::common::s(&json),
    ]);
    assert!(o.status.success(), "{}", crate::common::stderr(&o));
    let report: serde_json::Value = serde_json::from_slice(&std::fs::read(&json)?)?;
    let row = |key: &str| -> Result<(f64, f64), String> {
        let all = report["pooled"]
            .as_array()
            .and_then(|rows| rows.iter().find(|r| r["key"] == key))
            .map(|r| &r["all"])
            .ok_or(format!("no row {key}"))?;
        Ok((
            all["edge_recall"].as_f64().ok_or("edge_recall")?,
            all["false_hazards"].as_f64().ok_or("false_hazards")?,
        ))
    };
    let (recall, false_hazards) = row("geometric:cleaned+LS+window+edge")?;
    let (terrain_recall, _) = row("geometric:terrain")?;
    assert!(
        recall >= 0.8 && recall > 2.0 * terrain_recall,
        "edge recall {recall} (terrain estimate {terrain_recall})"
    );
    assert!(false_hazards <= 0.06, "false hazards {false_hazards}");
    Ok(())
}
