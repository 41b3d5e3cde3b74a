//! Train / validation / test splits of the real frames (`models/real_splits.json`,
//! docs/real-splits.md): by sequence, with contiguous parts of one long sequence and gaps
//! between them.

use super::*;
use crate::error::SplitsError;

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
    pub fn read(path: &Path) -> Result<Self, SplitsError> {
        let s: Self = read_json(path)?;
        for (seq, parts) in &s.sequences {
            for p in parts {
                if p.from.unwrap_or(0) >= p.to.unwrap_or(usize::MAX) {
                    return Err(SplitsError::PartOrder {
                        path: path.to_owned(),
                        sequence: seq.clone(),
                    });
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
    pub fn split_of(&self, sequence: &str, index: usize) -> Result<Option<&str>, SplitsError> {
        let parts = self
            .sequences
            .get(sequence)
            .ok_or_else(|| SplitsError::Unsplit {
                sequence: sequence.to_owned(),
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
    pub fn select(
        &self,
        frames: Vec<RealFrame>,
        name: &str,
    ) -> Result<Vec<RealFrame>, SplitsError> {
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
        let unsplit = s.split_of("elsewhere", 0).expect_err("not listed");
        assert_eq!(
            unsplit.to_string(),
            "sequence \"elsewhere\" has no split in the splits file; add it there"
        );
    }
}
