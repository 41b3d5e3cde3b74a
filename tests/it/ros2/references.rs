//! What the node's outputs are held to: `tre infer` and `tre map` on the same frames, compared
//! bit for bit, and the occupancy grid against the map's three-state layer.

use std::path::Path;
use std::process::Command;

use tre::record::msgs::{GridMap, Image, OccupancyGrid};

use super::kitchen::Kitchen;

pub(super) fn f32_values(img: &Image) -> Vec<f32> {
    assert_eq!(img.encoding, "32FC1");
    img.data
        .chunks_exact(4)
        .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
        .collect()
}

pub(super) fn same_bits(a: &[f32], b: &[f32]) -> bool {
    a.len() == b.len()
        && a.iter()
            .zip(b)
            .all(|(x, y)| x.to_bits() == y.to_bits() || (x.is_nan() && y.is_nan()))
}

/// One layer of a GridMap message in `tre map`'s layout (row-major, column 0 at the smallest
/// x, row 0 at the largest y).
pub(super) fn grid_layer(g: &GridMap, name: &str) -> Vec<f32> {
    let i = g.layers.iter().position(|l| l == name).unwrap();
    let a = &g.data[i];
    assert_eq!(a.layout.dim[0].label, "column_index");
    assert_eq!(a.layout.dim[1].label, "row_index");
    let side = a.layout.dim[1].size as usize;
    let mut out = Vec::with_capacity(side * side);
    for c in 0..side {
        out.extend(a.data[c * side..(c + 1) * side].iter().rev());
    }
    out
}

/// The folders of a `tre map` sequence, its gravity and camera (the frames and poses follow).
pub(super) fn map_sequence(k: &Kitchen, seq: &Path) {
    for sub in ["depth", "poses"] {
        std::fs::create_dir_all(seq.join(sub)).unwrap();
    }
    std::fs::copy(k.dir.join("gravity.json"), seq.join("gravity.json")).unwrap();
    std::fs::copy(&k.camera, seq.join("intrinsics.json")).unwrap();
}

pub(super) fn run_tre_map(seq: &Path, out: &Path) {
    let o = Command::new(env!("CARGO_BIN_EXE_tre"))
        .arg("map")
        .arg(seq)
        .arg("-o")
        .arg(out)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

/// `tre infer --mode geometric` on a depth PNG, written as `.npy`.
pub(super) fn infer_npy(depth: &Path, camera: &Path, npy: &Path) {
    let o = Command::new(env!("CARGO_BIN_EXE_tre"))
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .args(["infer", "--mode", "geometric", "--format", "npy", "--depth"])
        .arg(depth)
        .arg("--camera")
        .arg(camera)
        .arg("-o")
        .arg(npy)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

/// The occupancy grid is the map's three-state layer: rows from the bottom, unknown -1,
/// traversable 0, hazard 100.
pub(super) fn assert_occupancy_is_traversal(occupancy: &OccupancyGrid, traversal: &[f32]) {
    let side = occupancy.info.width as usize;
    assert_eq!(traversal.len(), side * side);
    for iy in 0..side {
        for x in 0..side {
            let want = match traversal[(side - 1 - iy) * side + x] as u8 {
                1 => 0,
                2 => 100,
                _ => -1,
            };
            assert_eq!(occupancy.data[iy * side + x], want);
        }
    }
    assert!(occupancy.data.contains(&0) && occupancy.data.contains(&-1));
}
