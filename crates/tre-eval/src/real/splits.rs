//! Train / validation / test splits of the real frames (`models/real_splits.json`,
//! docs/real-splits.md): by sequence, with contiguous parts of one long sequence and gaps
//! between them.

use super::*;

/// A parsed splits file: per sequence name, its parts.
#[derive(Debug, Clone, Deserialize)]
pub struct Splits {
    sequences: BTreeMap<String, Vec<Part>>,
}

/// One part of a sequence: a split over frames `[from, to)` of its frame list.
#[derive(Debug, Clone, Deserialize)]
struct Part {
    split: String,
    #[serde(default)]
    from: Option<usize>,
    #[serde(default)]
    to: Option<usize>,
}

impl Splits {
    /// Reads a splits file.
    ///
    /// # Errors
    ///
    /// When it does not read or parse, or a part has `from` ≥ `to`.
    pub fn read(path: &Path) -> anyhow::Result<Self> {
        let text =
            std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
        let s: Self =
            serde_json::from_str(&text).with_context(|| format!("parsing {}", path.display()))?;
        for (seq, parts) in &s.sequences {
            for p in parts {
                if p.from.unwrap_or(0) >= p.to.unwrap_or(usize::MAX) {
                    bail!("{}: {seq}: a part with from ≥ to", path.display());
                }
            }
        }
        Ok(s)
    }

    /// The split of frame `index` of `sequence` (`None`: in a gap between parts).
    ///
    /// # Errors
    ///
    /// When the sequence is not in the file (every sequence scored must have a split).
    pub fn split_of(&self, sequence: &str, index: usize) -> anyhow::Result<Option<&str>> {
        let parts = self.sequences.get(sequence).with_context(|| {
            format!("sequence {sequence:?} has no split in the splits file; add it there")
        })?;
        Ok(parts
            .iter()
            .find(|p| index >= p.from.unwrap_or(0) && index < p.to.unwrap_or(usize::MAX))
            .map(|p| p.split.as_str()))
    }

    /// The frames of `frames` in split `name`.
    ///
    /// # Errors
    ///
    /// Those of [`Splits::split_of`].
    pub fn select(&self, frames: Vec<RealFrame>, name: &str) -> anyhow::Result<Vec<RealFrame>> {
        let mut out = Vec::new();
        for f in frames {
            if self.split_of(&f.sequence, f.index)? == Some(name) {
                out.push(f);
            }
        }
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_committed_splits_keep_test_frames_apart() {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../models/real_splits.json");
        let s = Splits::read(&path).expect("reads");
        assert_eq!(
            s.split_of("slambook2_ch7", 1).expect("listed"),
            Some("test")
        );
        let kitchen = |i| s.split_of("sevenscenes_redkitchen", i).expect("listed");
        assert_eq!(kitchen(0), Some("train"));
        assert_eq!(kitchen(125), None, "a gap");
        assert_eq!(kitchen(140), Some("val"));
        assert_eq!(kitchen(199), Some("test"));
        assert!(s.split_of("elsewhere", 0).is_err());
    }
}
