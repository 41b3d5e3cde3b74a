//! Sensor noise: the uncertainty map's prediction against annotation spec v1 run on simulated
//! noisy planes, three-state traversability on the shared real RGB-D frames, and the maps through
//! `tre infer`, HTTP and the stream.
#![allow(clippy::unwrap_used)] // Test helpers fail loudly by design.

use crate::common;

use std::path::{Path, PathBuf};
use std::process::Command;

use tre::geometry::{Grid, Intrinsics, Vec3};
use tre::roughness::noise::{pixel_noise_map, SensorNoise, SensorPreset};
use tre::roughness::traversal::{shares, ThreeStateRule, Traversal};
use tre::roughness::{annotate, AnnotateConfig, AnnotateInput};

/// SplitMix64: a deterministic stream of uniform numbers for the simulated noise.
struct Rng(u64);

impl Rng {
    fn uniform(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
    }

    /// A standard normal number (Box–Muller).
    fn normal(&mut self) -> f64 {
        let u = self.uniform().max(1e-300);
        (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * self.uniform()).cos()
    }
}

/// Depth of a plane through `(0, 0, range_m)` whose normal is tilted `tilt_deg` from the
/// optical axis (about the camera's x axis), with Gaussian depth noise σ_z(z) added.
fn noisy_plane(
    k: &Intrinsics,
    size: (usize, usize),
    range_m: f64,
    tilt_deg: f64,
    sensor: &SensorNoise,
    rng: &mut Rng,
) -> (Grid<f64>, Vec3) {
    let t = tilt_deg.to_radians();
    let n = Vec3::new(0.0, -t.sin(), -t.cos());
    let d = n.dot(&Vec3::new(0.0, 0.0, range_m));
    let depth = Grid::from_fn(size.0, size.1, |x, y| {
        let ray = Vec3::new(
            (x as f64 - k.cx_px) / k.fx_px,
            (y as f64 - k.cy_px) / k.fy_px,
            1.0,
        );
        let z = d / n.dot(&ray);
        z + sensor.sigma_z_m(z) * rng.normal()
    });
    (depth, n)
}

/// The 95th percentile of `v` (sorted in place).
fn p95(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    v[((v.len() as f64) * 0.95) as usize]
}

/// One row of the table: predicted and simulated p95 of the surface term and of the full
/// spec roughness over the plane's interior.
#[derive(Debug)]
struct Row {
    range_m: f64,
    tilt_deg: f64,
    surface: (f64, f64),
    full: (f64, f64),
    break_fraction: f64,
}

fn simulate(sensor: &SensorNoise, range_m: f64, tilt_deg: f64, seed: u64) -> Row {
    let size = (120, 90);
    let k = Intrinsics::new(525.0, 525.0, 59.5, 44.5).unwrap();
    let mut rng = Rng(seed);
    let (depth, _) = noisy_plane(&k, size, range_m, tilt_deg, sensor, &mut rng);
    let input = AnnotateInput {
        depth_m: &depth,
        intrinsics: &k,
        normals: None,
        labels: None,
    };
    let cfg = AnnotateConfig::default();
    let ann = annotate(&input, &cfg).unwrap();
    let noise = pixel_noise_map(&depth, &k, &ann.normals, sensor, &cfg);
    // The interior: windows reach 7 px, so border pixels see one-sided windows.
    let inner =
        |(x, y): &(usize, usize)| (8..size.0 - 8).contains(x) && (8..size.1 - 8).contains(y);
    let pixels: Vec<(usize, usize)> = (0..size.1)
        .flat_map(|y| (0..size.0).map(move |x| (x, y)))
        .filter(inner)
        .collect();
    let (mut s_sim, mut r_sim, mut s_pred, mut r_pred) = (vec![], vec![], vec![], vec![]);
    let mut breaks = 0.0;
    for &p in &pixels {
        let pn = noise[p].unwrap();
        s_sim.push(ann.surface_m[p]);
        r_sim.push(ann.roughness_m[p]);
        breaks += pn.break_fraction;
        // The predicted distribution: half-normal with the predicted σ, sampled.
        let sigma = pn.surface_p95_m / tre::roughness::noise::HALF_NORMAL_P95;
        for _ in 0..16 {
            let s = (sigma * rng.normal()).abs();
            s_pred.push(s);
            r_pred.push(s.max(pn.edge_m));
        }
    }
    Row {
        range_m,
        tilt_deg,
        surface: (p95(&mut s_pred), p95(&mut s_sim)),
        full: (p95(&mut r_pred), p95(&mut r_sim)),
        break_fraction: breaks / pixels.len() as f64,
    }
}

fn table(sensor: SensorPreset) -> Vec<Row> {
    let s = SensorNoise::Preset(sensor);
    let mut rows = vec![];
    for (i, range_m) in [1.0, 2.0, 3.0, 4.0].into_iter().enumerate() {
        for (j, tilt_deg) in [0.0, 30.0, 60.0].into_iter().enumerate() {
            rows.push(simulate(
                &s,
                range_m,
                tilt_deg,
                1000 + 10 * i as u64 + j as u64,
            ));
        }
    }
    eprintln!("{sensor}: range m | tilt ° | surface p95 predicted / simulated mm (ratio) | full p95 predicted / simulated mm (ratio) | joins broken");
    for r in &rows {
        eprintln!(
            "| {:.0} | {:.0} | {:.2} | {:.2} | {:.2} | {:.2} | {:.2} | {:.2} | {:.3} |",
            r.range_m,
            r.tilt_deg,
            r.surface.0 * 1e3,
            r.surface.1 * 1e3,
            r.surface.1 / r.surface.0,
            r.full.0 * 1e3,
            r.full.1 * 1e3,
            r.full.1 / r.full.0,
            r.break_fraction
        );
    }
    rows
}

/// The prediction's domain (docs/sensor-noise.md): the surface term while the depth noise is
/// under a fifth of the radius R; the full roughness (surface and edge terms) while noise
/// breaks under 1% of the segment joins (no edge term) and once it breaks over 90% of them
/// (boundaries everywhere; at 60° tilt the prediction may overstate it by up to 35%: it is
/// conservative there). Between, and for the surface term under larger noise, the table
/// is printed but not asserted; every domain must hold some cells.
#[test]
fn noise_floor_matches_simulation_within_20_percent_in_its_domain() {
    let mut checked = [0; 3];
    for sensor in [
        SensorPreset::KinectV1,
        SensorPreset::RealsenseD435,
        SensorPreset::Lidar,
    ] {
        for r in table(sensor) {
            let surface = r.surface.1 / r.surface.0;
            let full = r.full.1 / r.full.0;
            if sensor.sigma_z_m(r.range_m) <= 0.2 * 0.05 {
                checked[0] += 1;
                assert!(
                    (0.8..=1.2).contains(&surface),
                    "{sensor} {r:?}: surface {surface:.3}"
                );
            }
            let broken = r.break_fraction >= 0.9;
            if r.break_fraction < 0.01 || broken {
                checked[usize::from(broken) + 1] += 1;
                // At 60° the prediction overstates the edge term (conservative), see the docs.
                let domain = if broken && r.tilt_deg >= 60.0 {
                    0.65..=1.2
                } else {
                    0.8..=1.2
                };
                assert!(domain.contains(&full), "{sensor} {r:?}: full {full:.3}");
            }
        }
    }
    assert!(
        checked.iter().all(|&c| c >= 3),
        "cells checked per domain: {checked:?}"
    );
}

#[derive(serde::Deserialize)]
struct RealFrames {
    frames: Vec<RealFrame>,
}

#[derive(serde::Deserialize)]
struct RealFrame {
    dir: String,
    depth: String,
    floor: Option<[usize; 4]>,
}

fn real_data() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data/real-rgbd")
}

/// Counts of (traversable, hazard, unknown) among `states`.
fn tally(states: impl Iterator<Item = Traversal>) -> [usize; 3] {
    let mut c = [0; 3];
    for s in states {
        c[match s {
            Traversal::Traversable => 0,
            Traversal::Hazard => 1,
            Traversal::Unknown => 2,
        }] += 1;
    }
    c
}

/// The spec (no labels, LS normals), its uncertainty under the Kinect v1 model, and the
/// three-state map with the roughness threshold alone (these frames' mountings are unknown,
/// so no slope test).
fn real_frame(f: &RealFrame) -> (Grid<f64>, Grid<f64>, Grid<f64>, Grid<Traversal>) {
    let dir = real_data().join(&f.dir);
    let (cam, k) = tre::io::read_camera(&dir.join("intrinsics.json")).unwrap();
    let depth = tre::io::read_depth(&dir.join(&f.depth), cam.depth_scale.unwrap()).unwrap();
    let input = AnnotateInput {
        depth_m: &depth,
        intrinsics: &k,
        normals: None,
        labels: None,
    };
    let cfg = AnnotateConfig::default();
    let ann = annotate(&input, &cfg).unwrap();
    let kinect = SensorNoise::Preset(SensorPreset::KinectV1);
    let u = tre::roughness::noise::uncertainty_map(&depth, &k, &ann.normals, &kinect, &cfg);
    let rule = ThreeStateRule::default();
    let ok = ann.roughness_m.map(|&r| r <= rule.max_roughness_m);
    let states = rule.map(&ann.roughness_m, &u, &ok);
    (depth, ann.roughness_m, u, states)
}

#[test]
fn real_kinect_frames_near_floor_traversable_far_rough_unknown_drops_hazard() {
    let fixture = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/real_floor.json");
    let frames: RealFrames =
        serde_json::from_str(&std::fs::read_to_string(fixture).unwrap()).unwrap();
    let (mut near_floor, mut far_rough, mut drops) = ([0; 3], [0; 3], [0; 3]);
    let mut near_drops = [0; 3];
    eprintln!("frame | traversable % | hazard % | unknown % | far (≥ 4 m) rough px: unknown %");
    for f in &frames.frames {
        let (depth, r, _u, states) = real_frame(f);
        let (t, h, u) = shares(&states);
        let px = |(x, y): (usize, usize)| (depth[(x, y)], r[(x, y)], states[(x, y)]);
        let all: Vec<_> = (0..depth.height())
            .flat_map(|y| (0..depth.width()).map(move |x| (x, y)))
            .map(px)
            .collect();
        let far = tally(
            all.iter()
                .filter(|(z, r, _)| *z >= 4.0 && *r >= 0.05)
                .map(|p| p.2),
        );
        eprintln!(
            "| {}/{} | {:.1} | {:.1} | {:.1} | {} px, {:.1}% unknown, {:.1}% hazard |",
            f.dir,
            f.depth,
            100.0 * t,
            100.0 * h,
            100.0 * u,
            far.iter().sum::<usize>(),
            100.0 * far[2] as f64 / far.iter().sum::<usize>().max(1) as f64,
            100.0 * far[1] as f64 / far.iter().sum::<usize>().max(1) as f64
        );
        for i in 0..3 {
            far_rough[i] += far[i];
        }
        let d = tally(all.iter().filter(|(_, r, _)| *r >= 0.1).map(|p| p.2));
        let near = tally(
            all.iter()
                .filter(|(z, r, _)| *r >= 0.1 && *z < 2.5)
                .map(|p| p.2),
        );
        for i in 0..3 {
            drops[i] += d[i];
            near_drops[i] += near[i];
        }
        if let Some([x0, y0, x1, y1]) = f.floor {
            let floor = (y0..y1).flat_map(|y| (x0..x1).map(move |x| (x, y))).map(px);
            let c = tally(floor.filter(|(z, _, _)| *z > 0.0 && *z < 2.0).map(|p| p.2));
            for i in 0..3 {
                near_floor[i] += c[i];
            }
        }
    }
    let share = |c: [usize; 3], i: usize| c[i] as f64 / c.iter().sum::<usize>().max(1) as f64;
    eprintln!("near floor {near_floor:?}, far rough {far_rough:?}, drops {drops:?}");
    assert!(near_floor.iter().sum::<usize>() > 10_000, "{near_floor:?}");
    assert!(
        share(near_floor, 0) > 0.97,
        "near floor traversable: {near_floor:?}"
    );
    assert!(far_rough.iter().sum::<usize>() > 1_000, "{far_rough:?}");
    assert!(
        share(far_rough, 2) > 0.8,
        "far rough pixels unknown: {far_rough:?}"
    );
    eprintln!("drops (r ≥ 0.1 m) within 2.5 m: {near_drops:?}");
    assert!(drops[0] == 0, "no drop is traversable: {drops:?}");
    let near_total = near_drops.iter().sum::<usize>() as f64;
    assert!(
        near_drops[1] > 1_000 && near_drops[1] as f64 > 0.99 * near_total,
        "drops within 2.5 m stay hazards: {near_drops:?}"
    );
}

/// The TUM frame's depth and camera (whose `sensor` is free text, naming no preset).
/// `tre annotate`'s roughness of the TUM frame's depth as the service's 16-bit PNG values.
fn spec_png16() -> Vec<u16> {
    let (depth, camera) = tum();
    let (cam, k) = tre::io::read_camera(&camera).unwrap();
    let depth_m = tre::io::read_depth(&depth, cam.depth_scale.unwrap()).unwrap();
    let input = tre::roughness::AnnotateInput {
        depth_m: &depth_m,
        intrinsics: &k,
        normals: None,
        labels: None,
    };
    let spec = tre::roughness::annotate(&input, &Default::default()).unwrap();
    let hazards = spec
        .roughness_m
        .as_slice()
        .iter()
        .filter(|&&r| r >= 0.1)
        .count();
    assert!(hazards > 1000, "the frame has drops: {hazards}");
    tre::io::roughness_png16(&spec.roughness_m).into_raw()
}

fn tum() -> (PathBuf, PathBuf) {
    (
        common::real("slambook2_ch7/1_depth.png"),
        common::real("slambook2_ch7/intrinsics.json"),
    )
}

fn infer(args: &[&str], out: &Path) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_tre"))
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .arg("infer")
        .args(args)
        .args(["-o", out.to_str().unwrap()])
        .output()
        .unwrap()
}

/// The values of an 8-bit three-state PNG, checked to be 0, 1 or 2.
fn traversal_values(png: &[u8]) -> [usize; 3] {
    let img = image::load_from_memory(png).unwrap();
    assert_eq!(img.color(), image::ColorType::L8);
    let mut c = [0; 3];
    for v in img.to_luma8().into_raw() {
        assert!(v <= 2, "traversal value {v}");
        c[v as usize] += 1;
    }
    c
}

#[test]
fn tre_infer_writes_the_uncertainty_and_three_state_maps_with_a_sensor() {
    let (depth, camera) = tum();
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("r.png");
    let base = [
        "--depth",
        depth.to_str().unwrap(),
        "--camera",
        camera.to_str().unwrap(),
    ];
    // The camera's free-text sensor: roughness only, and a note naming the presets.
    let o = infer(&base, &out);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("names no noise model") && err.contains("kinect_v1"),
        "{err}"
    );
    assert!(!dir.path().join("r_traversal.png").exists());
    // --sensor overrides it.
    let o = infer(&[&base[..], &["--sensor", "kinect_v1"]].concat(), &out);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(
        stdout.contains("sensor kinect_v1") && stdout.contains("% unknown"),
        "{stdout}"
    );
    let (w, h, u) =
        common::png16_values(&std::fs::read(dir.path().join("r_uncertainty.png")).unwrap());
    assert_eq!((w, h), (640, 480));
    // Grey + alpha: some valid pixels with a positive uncertainty, holes masked.
    assert!(u.chunks(2).any(|p| p[1] == u16::MAX && p[0] > 0));
    assert!(u.chunks(2).any(|p| p[1] == 0));
    let c = traversal_values(&std::fs::read(dir.path().join("r_traversal.png")).unwrap());
    assert!(c.iter().all(|&n| n > 1000), "every state present: {c:?}");
    let preview = image::open(dir.path().join("r_traversal_preview.png")).unwrap();
    assert_eq!(preview.color(), image::ColorType::Rgb8);
    // A bad sensor name is refused, naming the presets.
    let o = infer(&[&base[..], &["--sensor", "kinect"]].concat(), &out);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("realsense_d435"));
}

/// Splits a multipart/mixed body into (part name, bytes).
fn parts(content_type: &str, body: &[u8]) -> Vec<(String, Vec<u8>)> {
    let boundary = format!(
        "--{}",
        content_type
            .split("boundary=")
            .nth(1)
            .unwrap()
            .trim_matches('"')
    );
    let find = |hay: &[u8], needle: &[u8], from: usize| {
        hay[from..]
            .windows(needle.len())
            .position(|w| w == needle)
            .map(|i| i + from)
    };
    let mut out = vec![];
    let mut at = find(body, boundary.as_bytes(), 0).unwrap();
    while let Some(head_end) = find(body, b"\r\n\r\n", at) {
        let head = String::from_utf8_lossy(&body[at..head_end]).into_owned();
        let Some(end) = find(body, format!("\r\n{boundary}").as_bytes(), head_end) else {
            break;
        };
        let name = head
            .split("name=\"")
            .nth(1)
            .map(|n| n.split('"').next().unwrap().to_owned());
        out.push((name.unwrap_or_default(), body[head_end + 4..end].to_vec()));
        at = end + 2;
    }
    out
}

#[test]
fn http_and_stream_answer_the_sensor_maps() {
    let server = common::Server::start(&["--workers", "1"]);
    let (depth, camera) = tum();
    let depth = std::fs::read(depth).unwrap();
    // The service takes only the camera keys it knows: the shared file's intrinsics, its
    // depth scale and its free-text sensor description (no noise model).
    let file: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(camera).unwrap()).unwrap();
    let keys = ["fx", "fy", "cx", "cy", "depth_scale", "sensor"];
    let camera = serde_json::Value::Object(
        keys.iter()
            .map(|k| ((*k).to_owned(), file[*k].clone()))
            .collect(),
    )
    .to_string();
    let rt = tokio::runtime::Runtime::new().unwrap();
    rt.block_on(async {
        let post = |query: &str| {
            let form = reqwest::multipart::Form::new()
                .part("depth", reqwest::multipart::Part::bytes(depth.clone()))
                .part("camera", reqwest::multipart::Part::text(camera.clone()));
            reqwest::Client::new()
                .post(format!("{}/v1/roughness?{query}", server.url()))
                .multipart(form)
                .send()
        };
        let resp = post("mode=geometric&outputs=uncertainty,traversal")
            .await
            .unwrap();
        assert_eq!(resp.status().as_u16(), 422);
        let body = resp.text().await.unwrap();
        assert!(
            body.contains("bad_camera") && body.contains("kinect_v1") && body.contains("freiburg2"),
            "{body}"
        );
        let resp = post("mode=geometric&sensor=kinect_v1&outputs=uncertainty,traversal")
            .await
            .unwrap();
        assert_eq!(resp.status().as_u16(), 200);
        let ct = resp.headers()["content-type"].to_str().unwrap().to_owned();
        let parts = parts(&ct, &resp.bytes().await.unwrap());
        let names: Vec<&str> = parts.iter().map(|(n, _)| n.as_str()).collect();
        assert_eq!(names, ["roughness", "uncertainty", "traversal"]);
        let (w, h, _) = common::png16_values(&parts[1].1);
        assert_eq!((w, h), (640, 480));
        // The geometric mode served over HTTP is the spec: the same 16-bit map as the annotator
        // on the same depth (drops included).
        let (_, _, served) = common::png16_values(&parts[0].1);
        assert_eq!(
            served,
            spec_png16(),
            "HTTP geometric map differs from the spec"
        );
        let c = traversal_values(&parts[2].1);
        assert!(c.iter().all(|&n| n > 1000), "{c:?}");
        let resp = post("mode=geometric&sensor=kinect&outputs=traversal")
            .await
            .unwrap();
        assert_eq!(resp.status().as_u16(), 400);
        assert!(resp.text().await.unwrap().contains("sensor"));
        stream(&server, &depth).await;
    });
}

/// Over the stream: a Hello whose camera names the sensor and asks for the maps.
async fn stream(server: &common::Server, depth: &[u8]) {
    use futures_util::{SinkExt, StreamExt};
    use prost::Message as _;
    use tokio_tungstenite::tungstenite::Message;
    use tre::proto::v1 as pb;
    let url = format!("ws://{}/v1/stream", server.addr);
    let mut ws = tokio_tungstenite::connect_async(url).await.unwrap().0;
    let hello = pb::Hello {
        camera: Some(pb::Camera {
            fx: 520.9,
            fy: 521.0,
            cx: 325.1,
            cy: 249.7,
            depth_scale: Some(5000.0),
            sensor: Some("kinect_v1".into()),
            ..Default::default()
        }),
        mode: pb::Mode::Geometric as i32,
        want_traversal: true,
        want_uncertainty: true,
        ..Default::default()
    };
    let frame = pb::Frame {
        sequence: 1,
        depth: depth.to_vec(),
        ..Default::default()
    };
    for msg in [
        pb::client_message::Msg::Hello(hello),
        pb::client_message::Msg::Frame(frame),
    ] {
        let bytes = pb::ClientMessage { msg: Some(msg) }.encode_to_vec();
        ws.send(Message::Binary(bytes.into())).await.unwrap();
    }
    loop {
        let Message::Binary(b) = ws.next().await.unwrap().unwrap() else {
            continue;
        };
        match pb::ServerMessage::decode(&b[..]).unwrap().msg.unwrap() {
            pb::server_message::Msg::Ready(_) => continue,
            pb::server_message::Msg::Result(r) => {
                let n = (r.width * r.height) as usize;
                assert_eq!((r.traversal.len(), r.uncertainty.len()), (n, 4 * n));
                // The stream's geometric map is the spec too.
                let (_, _, served) = common::png16_values(&r.roughness);
                assert_eq!(
                    served,
                    spec_png16(),
                    "stream geometric map differs from the spec"
                );
                assert!(r.traversal.iter().all(|&t| t <= 2));
                assert!(
                    r.traversal.contains(&0)
                        && r.traversal.contains(&1)
                        && r.traversal.contains(&2)
                );
                return;
            }
            other => panic!("expected a Result, got {other:?}"),
        }
    }
}
