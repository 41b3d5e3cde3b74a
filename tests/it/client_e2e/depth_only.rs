//! Depth-only streaming: `tre client --depth DIR --camera C` (no `--frames`) sends depth-only
//! frames in the geometric mode and writes their roughness; with `--poses` and `--map` it asks
//! the stream for its grid map and writes the last one as `tre map` writes its map.

use super::*;

use common::npy_f32;

/// The kitchen sequence, `../shared/data/real-rgbd-2/sevenscenes_redkitchen`.
const KITCHEN: &str = "data/real-rgbd-2/sevenscenes_redkitchen";

/// `tre client` on the server at `url` with `args`: its stderr, once it has succeeded.
fn run_client(url: &str, args: &[&std::ffi::OsStr]) -> String {
    let o = Command::new(env!("CARGO_BIN_EXE_tre"))
        .args(["client", "--server", url, "--as-fast-as-results"])
        .args(args)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&o.stderr).into_owned();
    assert!(o.status.success(), "{stderr}");
    stderr
}

#[test]
fn depth_alone_streams_depth_only_frames_in_the_geometric_mode() {
    let (_one, dir, server) = serve(&[]);
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("samples/tum_fr2_desk");
    let depth = dir.path().join("depth");
    std::fs::create_dir_all(&depth).unwrap();
    for stem in ["a", "b"] {
        std::fs::copy(root.join("depth.png"), depth.join(format!("{stem}.png"))).unwrap();
    }
    let out = dir.path().join("out");
    let url = format!("http://{}", server.addr);
    let stderr = run_client(
        &url,
        &[
            "--depth".as_ref(),
            depth.as_os_str(),
            "--camera".as_ref(),
            root.join("camera.json").as_os_str(),
            "--out".as_ref(),
            out.as_os_str(),
        ],
    );
    assert!(stderr.contains("answers: mode geometric"), "{stderr}");
    assert!(!stderr.contains("bad_image"), "{stderr}");
    assert!(
        stderr.contains("maps of 2 frames and frames.csv in"),
        "{stderr}"
    );
    for stem in ["1_a", "2_b"] {
        let png = image::open(out.join(format!("{stem}.png"))).unwrap();
        assert_eq!((png.width(), png.height()), (640, 480), "{stem}");
    }
    let csv = std::fs::read_to_string(out.join("frames.csv")).unwrap();
    assert_eq!(
        csv.lines().filter(|l| l.ends_with(",ok")).count(),
        2,
        "{csv}"
    );
}

#[test]
fn depth_with_poses_and_map_writes_the_streams_map_as_tre_map_does() {
    common::skip_unless_shared!(KITCHEN);
    let (_one, dir, server) = serve(&[]);
    let kitchen = common::shared_root().join(KITCHEN);
    let (depth, pose_file) = depth_and_poses(&kitchen, dir.path());
    let (out, map) = (dir.path().join("out"), dir.path().join("map"));
    let url = format!("http://{}", server.addr);
    let stderr = run_client(
        &url,
        &[
            "--depth".as_ref(),
            depth.as_os_str(),
            "--poses".as_ref(),
            pose_file.as_os_str(),
            "--camera".as_ref(),
            kitchen.join("intrinsics.json").as_os_str(),
            "--map".as_ref(),
            map.as_os_str(),
            "--map-gravity".as_ref(),
            kitchen.join("gravity.json").as_os_str(),
            "--map-cell-cm".as_ref(),
            "5".as_ref(),
            "--map-size-m".as_ref(),
            "6".as_ref(),
            "--out".as_ref(),
            out.as_os_str(),
        ],
    );
    assert!(
        stderr.contains("map of 3 fused frames (0 skipped) in"),
        "{stderr}"
    );
    assert_tre_map_files(&map);
    // Three posed views of the kitchen floor: hundreds of cells seen, some more than once.
    let (_, count) = npy_f32(&map.join("count.npy"));
    let seen = count.iter().filter(|&&c| c > 0.0).count();
    assert!(seen > 500, "{seen} cells seen");
    assert!(count.iter().any(|&c| c >= 2.0), "no cell seen twice");
    assert!(
        count.iter().all(|&c| c <= 3.0),
        "more than 3 frames in a cell"
    );
}

/// Three of the kitchen's depth frames copied into `dir/depth`, and their poses as one file
/// of a pose a line: `(depth folder, pose file)`.
fn depth_and_poses(kitchen: &Path, dir: &Path) -> (PathBuf, PathBuf) {
    // Three depth frames, and their poses as one file of a pose a line.
    let depth = dir.join("depth");
    std::fs::create_dir_all(&depth).unwrap();
    let mut poses = String::from("# 4x4 camera-to-world, row by row\n");
    for i in [0, 5, 10] {
        let name = format!("frame-{i:06}");
        std::fs::copy(
            kitchen.join(format!("depth/{name}.png")),
            depth.join(format!("{name}.png")),
        )
        .unwrap();
        let pose = std::fs::read_to_string(kitchen.join(format!("poses/{name}.txt"))).unwrap();
        poses += &pose.split_whitespace().collect::<Vec<_>>().join(" ");
        poses.push('\n');
    }
    let pose_file = dir.join("poses.txt");
    std::fs::write(&pose_file, poses).unwrap();
    (depth, pose_file)
}

/// `tre map`'s files in `map`: every layer as .npy and .png, layers.png, map.json (a 6 m map
/// of 5 cm cells, three frames fused).
fn assert_tre_map_files(map: &Path) {
    let layers = [
        "elevation",
        "variance",
        "count",
        "roughness",
        "slope",
        "step",
        "score",
        "traversal",
        "last_update",
    ];
    for name in layers {
        assert!(map.join(format!("{name}.png")).is_file(), "{name}.png");
        assert_eq!(npy_f32(&map.join(format!("{name}.npy"))).0, (120, 120));
    }
    assert!(map.join("layers.png").is_file());
    let meta: serde_json::Value =
        serde_json::from_slice(&std::fs::read(map.join("map.json")).unwrap()).unwrap();
    assert_eq!(meta["side_cells"], 120);
    assert_eq!(meta["frames_fused"], 3);
    assert!((meta["cell_m"].as_f64().unwrap() - 0.05).abs() < 1e-12);
    assert_eq!(meta["map_from_world"].as_array().unwrap().len(), 9);
    assert_eq!(meta["layers"]["count"]["unit"], "measurements");
}
