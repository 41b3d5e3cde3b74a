//! Output paths: writing a text file with its folder, and the refusal to write an output over
//! one of a command's inputs.

use std::path::{Path, PathBuf};

use crate::IoError;

/// An output that would replace one of the inputs, or land inside an input folder.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error(
    "{} would be written over or inside the input {}; choose another output path",
    output.display(),
    input.display()
)]
pub struct WouldOverwrite {
    /// The output, as given.
    pub output: PathBuf,
    /// The input it would replace (or the folder it would land in), as given.
    pub input: PathBuf,
}

/// Creates the folder `dir` and its parents if missing.
pub fn create_dir(dir: &Path) -> Result<(), IoError> {
    std::fs::create_dir_all(dir).map_err(|reason| IoError::Write {
        path: dir.to_owned(),
        reason,
    })
}

/// Creates the folder `path` goes in, if it names one and it is missing.
pub fn create_parent(path: &Path) -> Result<(), IoError> {
    match path.parent().filter(|d| !d.as_os_str().is_empty()) {
        Some(dir) => create_dir(dir),
        None => Ok(()),
    }
}

/// Writes `text` to `path`, creating its folder if missing.
pub fn write_text(path: &Path, text: &str) -> Result<(), IoError> {
    create_parent(path)?;
    std::fs::write(path, text).map_err(|reason| IoError::Write {
        path: path.to_owned(),
        reason,
    })
}

/// `path` as the file system names it: its longest existing ancestor made canonical, with the
/// rest appended (so that `out.png` and `./dir/../out.png` compare equal before either exists).
#[must_use]
pub fn resolved(path: &Path) -> PathBuf {
    let path = std::path::absolute(path).unwrap_or_else(|_| path.to_path_buf());
    for base in path.ancestors() {
        if let Ok(canonical) = base.canonicalize() {
            let rest = path.strip_prefix(base).unwrap_or(Path::new(""));
            return canonical.join(rest);
        }
    }
    path
}

/// Refuses, before any work, to write an output over one of the command's inputs, or (for an
/// input that is a folder) inside it: `tre infer rgb.png -o rgb.png` would replace the frame,
/// `tre eval --json DATA/dataset.json` the dataset's manifest.
pub fn refuse_overwriting(outputs: &[&Path], inputs: &[&Path]) -> Result<(), WouldOverwrite> {
    for out in outputs {
        let o = resolved(out);
        for input in inputs {
            let i = resolved(input);
            if o == i || (i.is_dir() && o.starts_with(&i)) {
                return Err(WouldOverwrite {
                    output: out.to_path_buf(),
                    input: input.to_path_buf(),
                });
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn outputs_may_not_replace_inputs() {
        let dir = tempfile::tempdir().unwrap();
        let input = dir.path().join("rgb.png");
        std::fs::write(&input, b"x").unwrap();
        let data = dir.path().join("data");
        std::fs::create_dir(&data).unwrap();
        let same = dir.path().join("data/../rgb.png");
        assert!(refuse_overwriting(&[&same], &[&input]).is_err());
        assert!(refuse_overwriting(&[&data.join("new/report.json")], &[&data]).is_err());
        let elsewhere = dir.path().join("out.png");
        assert!(refuse_overwriting(&[&elsewhere], &[&input, &data]).is_ok());
    }

    #[test]
    fn text_files_get_their_folder() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a/b/report.json");
        write_text(&path, "{}").unwrap();
        assert_eq!(std::fs::read_to_string(&path).unwrap(), "{}");
    }
}
