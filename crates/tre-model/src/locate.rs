//! Where the models folder is: `--models`, `TRE_MODELS`, beside the executable, its
//! `../share/tre/models`, then `models/` in the working directory.
//!
//! A deployed binary runs from anywhere, so a fixed relative `models/` is not enough.
//! [`locate_models`] tries each place in [`ModelsRule`] order and returns the first folder that
//! holds `manifest.json`, with the rule that found it:
//!
//! ```no_run
//! # fn main() -> Result<(), tre_model::ModelError> {
//! let found = tre_model::locate_models(None)?;
//! println!("models: {} ({})", found.dir.display(), found.rule);
//! # Ok(())
//! # }
//! ```

use std::fmt;
use std::path::{Path, PathBuf};

use super::manifest::MANIFEST_FILE;
use super::ModelError;

/// Environment variable that names the models folder.
pub const MODELS_ENV: &str = "TRE_MODELS";

/// How to provide the models; quoted by [`ModelError::ModelsNotFound`].
pub(crate) const MODELS_FIX: &str = "fix: pass `--models DIR` or set TRE_MODELS=DIR to a folder \
     holding manifest.json and the .onnx files it lists (the checkout's `models/`), or install \
     that folder as `models/` beside the executable or as `../share/tre/models` relative to it";

/// The rule that names a candidate models folder, in the order they are tried.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum ModelsRule {
    /// `--models DIR` on the command line.
    Flag,
    /// The `TRE_MODELS` environment variable.
    Env,
    /// `models/` in the executable's folder.
    BesideExecutable,
    /// `../share/tre/models` relative to the executable's folder (an install prefix).
    SharePrefix,
    /// `models/` in the working directory.
    WorkingDir,
}

impl ModelsRule {
    /// Whether the user named the folder; such a folder must hold the models, the search does
    /// not go on past it.
    pub fn is_explicit(self) -> bool {
        matches!(self, Self::Flag | Self::Env)
    }
}

impl fmt::Display for ModelsRule {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Self::Flag => "--models",
            Self::Env => "TRE_MODELS",
            Self::BesideExecutable => "models/ beside the executable",
            Self::SharePrefix => "../share/tre/models relative to the executable",
            Self::WorkingDir => "models/ in the working directory",
        })
    }
}

/// A models folder and the rule that found it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct FoundModels {
    /// The folder holding `manifest.json`.
    pub dir: PathBuf,
    /// Which rule named it.
    pub rule: ModelsRule,
}

/// The inputs of the search; fill it to test the search itself.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct ModelSearch {
    /// `--models DIR`.
    pub flag: Option<PathBuf>,
    /// The value of `TRE_MODELS`; empty counts as unset.
    pub env: Option<PathBuf>,
    /// The running executable's folder.
    pub exe_dir: Option<PathBuf>,
    /// The working directory.
    pub working_dir: Option<PathBuf>,
}

impl ModelSearch {
    /// The search this process would do, given the `--models` value the CLI parsed.
    ///
    /// The CLI's parser already falls back on `TRE_MODELS` for `--models`; a value equal to
    /// `TRE_MODELS` is therefore credited to the variable.
    pub fn from_process(cli_value: Option<&Path>) -> Self {
        let env = std::env::var_os(MODELS_ENV)
            .filter(|v| !v.is_empty())
            .map(PathBuf::from);
        let flag = cli_value
            .filter(|v| env.as_deref() != Some(*v))
            .map(Path::to_path_buf);
        let exe = std::env::current_exe().ok();
        Self {
            flag,
            env,
            exe_dir: exe.as_deref().and_then(Path::parent).map(Path::to_path_buf),
            working_dir: std::env::current_dir().ok(),
        }
    }

    /// Every candidate, in the order tried, with its rule.
    pub fn candidates(&self) -> Vec<(ModelsRule, PathBuf)> {
        let flag = self.flag.iter().map(|d| (ModelsRule::Flag, d.clone()));
        let env = self.env.iter().filter(|d| !d.as_os_str().is_empty());
        let env = env.map(|d| (ModelsRule::Env, d.clone()));
        let exe = self.exe_dir.iter().flat_map(|d| {
            [
                (ModelsRule::BesideExecutable, d.join("models")),
                (ModelsRule::SharePrefix, d.join("../share/tre/models")),
            ]
        });
        let cwd = self.working_dir.iter();
        let cwd = cwd.map(|d| (ModelsRule::WorkingDir, d.join("models")));
        flag.chain(env).chain(exe).chain(cwd).collect()
    }

    /// The first candidate holding `manifest.json`.
    ///
    /// # Errors
    ///
    /// [`ModelError::ModelsDirMissing`] when the folder given by `--models` or `TRE_MODELS`
    /// holds no manifest (the search stops there: a named folder is never silently replaced),
    /// else [`ModelError::ModelsNotFound`] listing every place tried, in order, and the fix.
    pub fn resolve(&self) -> Result<FoundModels, ModelError> {
        let searched = self.candidates();
        for (rule, dir) in &searched {
            if dir.join(MANIFEST_FILE).is_file() {
                return Ok(FoundModels {
                    dir: tidy(dir),
                    rule: *rule,
                });
            }
            if rule.is_explicit() {
                return Err(ModelError::ModelsDirMissing {
                    rule: *rule,
                    dir: dir.clone(),
                });
            }
        }
        Err(ModelError::ModelsNotFound { searched })
    }
}

/// Finds the models folder for the `--models` value the CLI parsed (`None` when not given),
/// following [`ModelsRule`]'s order. See [`ModelSearch`].
///
/// # Errors
///
/// As [`ModelSearch::resolve`].
pub fn locate_models(cli_value: Option<&Path>) -> Result<FoundModels, ModelError> {
    ModelSearch::from_process(cli_value).resolve()
}

/// As [`locate_models`], logging the folder found and the rule that found it: the models folder
/// of every command that loads models.
///
/// # Errors
///
/// As [`ModelSearch::resolve`].
pub fn find_models(cli_value: Option<&Path>) -> Result<PathBuf, ModelError> {
    let found = locate_models(cli_value)?;
    tracing::info!(path = %found.dir.display(), "models folder found by {}", found.rule);
    Ok(found.dir)
}

/// `dir` without `..` components where the filesystem can resolve them, so that messages show
/// `/usr/share/tre/models` rather than `/usr/bin/../share/tre/models`.
fn tidy(dir: &Path) -> PathBuf {
    dir.canonicalize().unwrap_or_else(|_| dir.to_path_buf())
}

/// `1. PATH (RULE); 2. ...` for [`ModelError::ModelsNotFound`].
pub(crate) fn list_searched(searched: &[(ModelsRule, PathBuf)]) -> String {
    let items = searched
        .iter()
        .enumerate()
        .map(|(i, (rule, dir))| format!("{}. {} ({rule})", i + 1, dir.display()));
    items.collect::<Vec<_>>().join("; ")
}

#[cfg(test)]
mod tests {
    use std::error::Error;

    use super::*;

    type TestResult = Result<(), Box<dyn Error>>;

    /// Makes `dir` a models folder (an empty manifest is enough for the search).
    fn make_models(dir: &Path) -> std::io::Result<()> {
        std::fs::create_dir_all(dir)?;
        std::fs::write(dir.join(MANIFEST_FILE), b"{}")
    }

    /// A search rooted in `root`: executable in `root/prefix/bin`, working dir `root/cwd`.
    fn search(root: &Path) -> ModelSearch {
        ModelSearch {
            flag: None,
            env: None,
            exe_dir: Some(root.join("prefix/bin")),
            working_dir: Some(root.join("cwd")),
        }
    }

    #[test]
    fn each_rule_wins_over_the_ones_after_it() -> TestResult {
        let root = tempfile::tempdir()?;
        let root = root.path().canonicalize()?;
        std::fs::create_dir_all(root.join("prefix/bin"))?;
        let mut s = search(&root);
        let found = |s: &ModelSearch| s.resolve().map(|f| (f.rule, f.dir));
        make_models(&root.join("cwd/models"))?;
        assert_eq!(
            found(&s)?,
            (ModelsRule::WorkingDir, root.join("cwd/models"))
        );
        make_models(&root.join("prefix/share/tre/models"))?;
        let share = root.join("prefix/share/tre/models");
        assert_eq!(found(&s)?, (ModelsRule::SharePrefix, share));
        make_models(&root.join("prefix/bin/models"))?;
        let beside = root.join("prefix/bin/models");
        assert_eq!(found(&s)?, (ModelsRule::BesideExecutable, beside));
        make_models(&root.join("env"))?;
        s.env = Some(root.join("env"));
        assert_eq!(found(&s)?, (ModelsRule::Env, root.join("env")));
        make_models(&root.join("flag"))?;
        s.flag = Some(root.join("flag"));
        assert_eq!(found(&s)?, (ModelsRule::Flag, root.join("flag")));
        Ok(())
    }

    #[test]
    fn a_named_folder_without_manifest_is_an_error_not_skipped() -> TestResult {
        let root = tempfile::tempdir()?;
        let root = root.path();
        make_models(&root.join("cwd/models"))?;
        let mut s = search(root);
        s.env = Some(root.join("empty"));
        let err = s.resolve().expect_err("TRE_MODELS names no models folder");
        assert!(
            matches!(&err, ModelError::ModelsDirMissing { rule: ModelsRule::Env, dir } if *dir == root.join("empty")),
            "{err}"
        );
        let message = err.to_string();
        assert!(message.contains("TRE_MODELS"), "{message}");
        assert!(message.contains(MANIFEST_FILE), "{message}");
        Ok(())
    }

    #[test]
    fn empty_env_counts_as_unset() -> TestResult {
        let root = tempfile::tempdir()?;
        let root = root.path().canonicalize()?;
        make_models(&root.join("cwd/models"))?;
        let mut s = search(&root);
        s.env = Some(PathBuf::new());
        assert_eq!(s.resolve()?.rule, ModelsRule::WorkingDir);
        Ok(())
    }

    #[test]
    fn not_found_lists_every_place_in_order_and_the_fix() -> TestResult {
        let root = tempfile::tempdir()?;
        let err = search(root.path()).resolve().expect_err("nothing exists");
        let ModelError::ModelsNotFound { searched } = &err else {
            panic!("expected ModelsNotFound, got {err}");
        };
        let rules: Vec<_> = searched.iter().map(|(rule, _)| *rule).collect();
        assert_eq!(
            rules,
            [
                ModelsRule::BesideExecutable,
                ModelsRule::SharePrefix,
                ModelsRule::WorkingDir
            ]
        );
        let message = err.to_string();
        let at = |p: &str| {
            let path = root.path().join(p).display().to_string();
            message
                .find(&path)
                .unwrap_or_else(|| panic!("{path} in {message}"))
        };
        assert!(at("prefix/bin/models") < at("prefix/bin/../share/tre/models"));
        assert!(at("prefix/bin/../share/tre/models") < at("cwd/models"));
        assert!(message.contains("--models DIR"), "{message}");
        assert!(message.contains("TRE_MODELS=DIR"), "{message}");
        Ok(())
    }
}
