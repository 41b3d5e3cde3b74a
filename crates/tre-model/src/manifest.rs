//! `models/manifest.json`: what each exported stage is (file, SHA-256, opset, tensor names and
//! shapes, normalisation) and where it came from (training data, commit, metrics).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};

use super::ModelError;

/// The manifest format this code reads.
pub const MANIFEST_FORMAT: u32 = 1;

/// The manifest file name inside a models folder.
pub(crate) const MANIFEST_FILE: &str = "manifest.json";

/// The whole manifest.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Manifest {
    /// Format version ([`MANIFEST_FORMAT`]).
    pub format: u32,
    /// H and W of every input must be multiples of this, pixels.
    pub stride: usize,
    /// The size the stages were trained at and run at by default, `[width, height]` pixels.
    pub working_size: [usize; 2],
    /// Human-readable tensor layout note.
    #[serde(default)]
    pub layout: String,
    /// The models by name (`depth_net`, `neighbour_net`, `normal_refiner`, `centroid_net`,
    /// optionally `end_to_end`).
    pub models: BTreeMap<String, ModelEntry>,
    /// Anything else the exporter wrote (e.g. total FLOPs), kept as is.
    #[serde(flatten)]
    pub extra: BTreeMap<String, serde_json::Value>,
}

/// One model's entry.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ModelEntry {
    /// File name, relative to the manifest's folder.
    pub file: PathBuf,
    /// Lower-case hex SHA-256 of the file.
    pub sha256: String,
    /// Version of the default ONNX operator set the file imports.
    pub opset: i64,
    /// Inputs, in the order the graph declares them.
    pub inputs: Vec<TensorSpec>,
    /// Outputs, in the order the graph declares them.
    pub outputs: Vec<TensorSpec>,
    /// What each input holds and how it is scaled, by input name.
    #[serde(default)]
    pub normalisation: BTreeMap<String, String>,
    /// Floating-point operations for one 256×256 frame, if measured.
    #[serde(default)]
    pub flops_256x256: Option<u64>,
    /// Number of weights, if counted.
    #[serde(default)]
    pub parameters: Option<u64>,
    /// Training provenance (data, steps, commit), free-form.
    #[serde(default)]
    pub training: serde_json::Value,
    /// Test metrics, free-form.
    #[serde(default)]
    pub metrics: serde_json::Value,
    /// Anything else the exporter wrote, kept as is.
    #[serde(flatten)]
    pub extra: BTreeMap<String, serde_json::Value>,
}

/// One tensor: name, NCHW shape with symbolic or fixed dimensions, element type.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TensorSpec {
    /// Tensor name in the graph.
    pub name: String,
    /// Dimensions: a number is fixed, a string (`"N"`, `"H"`, `"W"`) is dynamic.
    pub shape: Vec<Dim>,
    /// Element type; only `float32` is served.
    pub dtype: String,
}

/// One dimension of a [`TensorSpec`].
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum Dim {
    /// A fixed size.
    Fixed(i64),
    /// A named dynamic size.
    Symbol(String),
}

impl TensorSpec {
    /// The fixed channel count (dimension 1 of NCHW), if the manifest fixes it.
    pub fn channels(&self) -> Option<usize> {
        match self.shape.get(1) {
            Some(Dim::Fixed(c)) => usize::try_from(*c).ok(),
            _ => None,
        }
    }
}

impl Manifest {
    /// Reads `DIR/manifest.json`.
    ///
    /// # Errors
    ///
    /// [`ModelError::Manifest`] when the file cannot be read or parsed, or has another format.
    pub fn read(dir: &Path) -> Result<Self, ModelError> {
        let path = dir.join(MANIFEST_FILE);
        let fail = |reason| ModelError::Manifest {
            path: path.clone(),
            reason,
        };
        let text = std::fs::read_to_string(&path).map_err(|e| fail(ManifestProblem::Read(e)))?;
        let manifest: Self =
            serde_json::from_str(&text).map_err(|e| fail(ManifestProblem::Json(e)))?;
        if manifest.format != MANIFEST_FORMAT {
            return Err(fail(ManifestProblem::Format(manifest.format)));
        }
        if manifest.stride == 0 || manifest.working_size.contains(&0) {
            return Err(fail(ManifestProblem::ZeroSize));
        }
        Ok(manifest)
    }

    /// The entry for `model`.
    ///
    /// # Errors
    ///
    /// [`ModelError::NotInManifest`] when the manifest does not list it.
    pub fn entry(&self, model: &str) -> Result<&ModelEntry, ModelError> {
        self.models
            .get(model)
            .ok_or_else(|| ModelError::NotInManifest {
                model: model.to_owned(),
            })
    }
}

/// Why a models folder's `manifest.json` does not read ([`ModelError::Manifest`]).
#[derive(Debug, thiserror::Error)]
pub enum ManifestProblem {
    /// The file cannot be read.
    #[error(transparent)]
    Read(std::io::Error),
    /// The file is not the manifest's JSON.
    #[error(transparent)]
    Json(serde_json::Error),
    /// Another format than [`MANIFEST_FORMAT`].
    #[error("format {0} is not the supported format {MANIFEST_FORMAT}")]
    Format(u32),
    /// A stride or working size of 0.
    #[error("stride and working size must be positive")]
    ZeroSize,
}

/// Lower-case hex SHA-256 of bytes (of the empty input: `e3b0c442…`, checked in the tests).
pub(crate) fn sha256_hex(bytes: &[u8]) -> String {
    hex(&Sha256::digest(bytes))
}

/// Lower-case hex of bytes.
fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

/// Lower-case hex SHA-256 of a file, read in blocks (the tests' reference for the manifest's
/// digests).
///
/// # Errors
///
/// The OS error when the file cannot be read.
#[cfg(test)]
pub(crate) fn sha256_file(path: &Path) -> std::io::Result<String> {
    use std::io::Read;
    let mut file = std::fs::File::open(path)?;
    let mut hasher = Sha256::new();
    let mut block = vec![0u8; 1 << 16];
    loop {
        let n = file.read(&mut block)?;
        if n == 0 {
            break;
        }
        hasher.update(&block[..n]);
    }
    Ok(hex(&hasher.finalize()))
}

#[cfg(test)]
mod tests {
    #[test]
    fn the_digest_of_nothing_is_sha256s() {
        assert!(super::sha256_hex(b"").starts_with("e3b0c442"));
    }

    use super::*;

    fn models_dir() -> PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../models")
    }

    #[test]
    fn the_shipped_manifest_parses_and_round_trips() {
        let m = Manifest::read(&models_dir()).expect("the shipped manifest is valid");
        for name in [
            "depth_net",
            "neighbour_net",
            "normal_refiner",
            "centroid_net",
        ] {
            let e = m.entry(name).expect("pipeline model listed");
            assert!(e.inputs.iter().all(|t| t.dtype == "float32"), "{name}");
            assert!(e.outputs.iter().all(|t| t.channels().is_some()), "{name}");
        }
        let json = serde_json::to_value(&m).expect("serialises");
        let back: Manifest = serde_json::from_value(json).expect("parses back");
        assert_eq!(back, m);
    }

    #[test]
    fn bad_manifests_name_the_file_and_what_is_wrong() {
        let dir = tempfile::tempdir().expect("temp dir");
        let path = dir.path().join(MANIFEST_FILE);
        // The reason and the message of reading `text` as the manifest (none: no file).
        let read = |text: Option<&str>| {
            if let Some(text) = text {
                std::fs::write(&path, text).expect("write");
            }
            let e = Manifest::read(dir.path()).expect_err("a bad manifest");
            let message = e.to_string();
            assert!(message.contains("manifest.json: "), "{message}");
            let ModelError::Manifest { path: p, reason } = e else {
                panic!("{e:?}");
            };
            assert_eq!(p, path);
            (reason, message)
        };
        let (reason, _) = read(None);
        assert!(
            matches!(&reason, ManifestProblem::Read(e) if e.kind() == std::io::ErrorKind::NotFound),
            "{reason:?}"
        );
        let (reason, _) = read(Some("{"));
        assert!(matches!(reason, ManifestProblem::Json(_)), "{reason:?}");
        let m = |format: u32, stride: usize| {
            format!(
                r#"{{"format": {format}, "stride": {stride}, "working_size": [256, 256], "models": {{}}}}"#
            )
        };
        let (reason, message) = read(Some(&m(2, 32)));
        assert!(matches!(reason, ManifestProblem::Format(2)), "{reason:?}");
        assert!(
            message.ends_with("format 2 is not the supported format 1"),
            "{message}"
        );
        let (reason, message) = read(Some(&m(1, 0)));
        assert!(matches!(reason, ManifestProblem::ZeroSize), "{reason:?}");
        assert!(
            message.ends_with("stride and working size must be positive"),
            "{message}"
        );
    }

    #[test]
    fn opsets_in_the_files_match_the_manifest() {
        let m = Manifest::read(&models_dir()).expect("the shipped manifest is valid");
        for (name, e) in &m.models {
            let bytes = std::fs::read(models_dir().join(&e.file)).expect("listed file exists");
            let imports = super::super::onnx::opset_imports(&bytes).expect("valid ONNX");
            assert_eq!(
                super::super::onnx::default_opset(&imports),
                Some(e.opset),
                "{name}"
            );
        }
    }

    #[test]
    fn sha256_of_a_known_string() {
        let dir = tempfile::tempdir().expect("temp dir");
        let path = dir.path().join("abc");
        std::fs::write(&path, b"abc").expect("write");
        assert_eq!(
            sha256_file(&path).expect("read"),
            "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad"
        );
    }
}
