//! Every reference the repository's own text makes resolves: the relative links of every
//! Markdown file, and every repository path cited in Markdown prose, in Rust comments and in the
//! comments of Python, shell and TOML files. A file moved or renamed without its citations fails
//! here, with each broken reference named as `file:line: path`.
#![allow(clippy::unwrap_used)] // Test helpers fail loudly by design.

use std::path::{Component, Path, PathBuf};
use std::process::Command;

use crate::common::repo_root;

/// A cited path is checked when it starts with one of these: the repository's top-level folders,
/// and `../shared/` (the shared data beside a clone: checked where it is there, in the folder
/// `common::shared_root` names; where it is not, the test says so and leaves those paths
/// unchecked, unless `TRE_REQUIRE_SHARED=1`). `data/` and
/// `out/` are not among them: they hold what `tre synth` and the examples write, git-ignored, so a
/// clone has neither.
const ROOTS: &[&str] = &[
    "crates/",
    "src/",
    "docs/",
    "tests/",
    "scripts/",
    "models/",
    "results/",
    "samples/",
    "cameras/",
    "benches/",
    "fuzz/",
    "deploy/",
    "../shared/",
];

/// Cited paths that name no file on purpose, each with the reason. A glob or a placeholder in
/// `*`, `{…}` or `<…>` needs no entry: the folder before it is checked instead.
const NOT_FILES: &[(&str, &str)] = &[(
    "tests/fixtures/onnx_parity/NAME.npz",
    "a placeholder in the export's docstring: one file per model, NAME the model",
)];

/// The folders skipped when git cannot list the files.
const SKIPPED_DIRS: &[&str] = &["target", "node_modules", "data", "out", "__pycache__"];

/// What a file cites: the 1-based line, the text as written, and whether it is a Markdown link
/// (relative to the file) or a path (relative to the repository or to the file's package).
struct Cited {
    line: usize,
    target: String,
    link: bool,
}

/// The files git tracks or would track (untracked but not ignored) that exist, relative to the
/// root; without git, every file under the root less hidden and generated folders.
fn repository_files(root: &Path) -> Vec<PathBuf> {
    let listed = Command::new("git")
        .args([
            "ls-files",
            "-z",
            "--cached",
            "--others",
            "--exclude-standard",
        ])
        .current_dir(root)
        .output()
        .ok()
        .filter(|o| o.status.success());
    let mut files: Vec<PathBuf> = match listed {
        Some(o) => o
            .stdout
            .split(|&b| b == 0)
            .filter(|s| !s.is_empty())
            .map(|s| PathBuf::from(String::from_utf8_lossy(s).into_owned()))
            .collect(),
        None => {
            let mut files = Vec::new();
            walk(root, root, &mut files);
            files
        }
    };
    files.retain(|f| root.join(f).is_file());
    files.sort();
    files.dedup();
    files
}

/// Every file under `dir`, relative to `root`, less hidden folders and `SKIPPED_DIRS`.
fn walk(root: &Path, dir: &Path, files: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        let name = path.file_name().unwrap().to_string_lossy().into_owned();
        if path.is_dir() {
            if !name.starts_with('.') && !SKIPPED_DIRS.contains(&name.as_str()) {
                walk(root, &path, files);
            }
        } else {
            files.push(path.strip_prefix(root).unwrap().to_path_buf());
        }
    }
}

/// The prose of a file, one entry per line of the file (so line numbers stay the file's): a
/// Markdown file outside its fenced blocks; the comments of Rust (`//`, `///`, `//!`), shell and
/// TOML files; the comments and docstrings of Python. Other lines are empty. `None`: a kind of
/// file whose text is not read.
fn prose(path: &Path, text: &str) -> Option<Vec<String>> {
    let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("");
    let mut fenced = false;
    let mut docstring = false;
    let lines = text.lines().map(|line| {
        let t = line.trim_start();
        let kept = match ext {
            "md" => {
                let fence = t.starts_with("```") || t.starts_with("~~~");
                fenced ^= fence;
                !fence && !fenced
            }
            "rs" => t.starts_with("//"),
            "sh" | "toml" => t.starts_with('#') && !t.starts_with("#!"),
            _ => {
                let quotes = line.matches("\"\"\"").count();
                let kept = docstring || quotes > 0 || t.starts_with('#');
                docstring ^= quotes % 2 == 1;
                kept
            }
        };
        if !kept {
            return String::new();
        }
        match ext {
            "rs" => t.trim_start_matches('/').trim_start_matches('!').to_owned(),
            "sh" | "toml" => t.trim_start_matches('#').to_owned(),
            _ => line.to_owned(),
        }
    });
    matches!(ext, "md" | "rs" | "py" | "sh" | "toml").then(|| lines.collect())
}

/// The length of the run of backticks at `at`.
fn backticks(b: &[u8], at: usize) -> usize {
    b[at..].iter().take_while(|&&c| c == b'`').count()
}

/// Where the code span opened by `n` backticks before `from` closes: the next run of exactly
/// `n`, not across a blank line.
fn span_end(b: &[u8], from: usize, n: usize) -> Option<usize> {
    let mut j = from;
    while j < b.len() {
        if b[j] == b'\n' && b.get(j + 1) == Some(&b'\n') {
            return None;
        }
        if b[j] == b'`' {
            let m = backticks(b, j);
            if m == n {
                return Some(j);
            }
            j += m;
        } else {
            j += 1;
        }
    }
    None
}

/// The inline code spans of `text` as (byte offset, content), and `text` with every span
/// blanked out (newlines kept).
fn code_spans(text: &str) -> (Vec<(usize, String)>, String) {
    let b = text.as_bytes();
    let mut blanked = b.to_vec();
    let mut spans = Vec::new();
    let mut i = 0;
    while i < b.len() {
        if b[i] != b'`' {
            i += 1;
            continue;
        }
        let n = backticks(b, i);
        match span_end(b, i + n, n) {
            Some(end) => {
                spans.push((i, text[i + n..end].to_owned()));
                for c in &mut blanked[i..end + n] {
                    if *c != b'\n' {
                        *c = b' ';
                    }
                }
                i = end + n;
            }
            None => i += n,
        }
    }
    (spans, String::from_utf8(blanked).unwrap())
}

/// The targets of the Markdown links `[…](target)` and images in `text` as (byte offset,
/// target), and `text` with the targets blanked out.
fn link_targets(text: &str) -> (Vec<(usize, String)>, String) {
    let mut blanked = text.as_bytes().to_vec();
    let mut links = Vec::new();
    let mut from = 0;
    while let Some(at) = text[from..].find("](").map(|a| from + a + 2) {
        let Some(len) = text[at..].find([')', '\n']) else {
            break;
        };
        let raw = text[at..at + len].trim();
        let target = raw.split_whitespace().next().unwrap_or("");
        links.push((at, target.trim_matches(['<', '>']).to_owned()));
        blanked[at..at + len].fill(b' ');
        from = at + len;
    }
    (links, String::from_utf8(blanked).unwrap())
}

/// The bare repository paths in `text` (a root at the start of a word) as (byte offset, path); a
/// path followed by `{` or `<` comes back with that character, as a pattern.
fn bare_paths(text: &str) -> Vec<(usize, String)> {
    let b = text.as_bytes();
    let path_char = |c: u8| c.is_ascii_alphanumeric() || b"_./*-".contains(&c);
    let mut found = Vec::new();
    for (i, _) in text.char_indices() {
        let starts_word = i == 0 || b" \t\n([\"'".contains(&b[i - 1]);
        if !starts_word || !ROOTS.iter().any(|r| text[i..].starts_with(r)) {
            continue;
        }
        let mut end = i + b[i..].iter().take_while(|&&c| path_char(c)).count();
        if b.get(end).is_some_and(|c| b"{<".contains(c)) {
            end += 1;
        }
        let path = text[i..end].trim_end_matches(['.', '-']);
        found.push((i, path.to_owned()));
    }
    found
}

/// A reference found at byte `at` of `joined`, with its line.
fn cited(joined: &str, link: bool) -> impl Fn((usize, String)) -> Cited + '_ {
    move |(at, target)| Cited {
        line: joined[..at].matches('\n').count() + 1,
        target,
        link,
    }
}

/// Everything `path` cites, from its prose (see `prose`).
fn citations(path: &Path, text: &str) -> Vec<Cited> {
    let Some(lines) = prose(path, text) else {
        return Vec::new();
    };
    let joined = lines.join("\n");
    let (spans, without_code) = code_spans(&joined);
    let mut all: Vec<Cited> = spans
        .into_iter()
        .map(|(at, s)| (at, s.trim().to_owned()))
        .filter(|(_, s)| !s.contains(char::is_whitespace))
        .filter(|(_, s)| ROOTS.iter().any(|r| s.starts_with(r)))
        .map(cited(&joined, false))
        .collect();
    let (links, prose_only) = if path.extension().is_some_and(|e| e == "md") {
        link_targets(&without_code)
    } else {
        (Vec::new(), without_code)
    };
    all.extend(links.into_iter().map(cited(&joined, true)));
    all.extend(
        bare_paths(&prose_only)
            .into_iter()
            .map(cited(&joined, false)),
    );
    all
}

/// `path` with `.` and `..` resolved lexically (the target may not exist).
fn normalise(path: &Path) -> PathBuf {
    let mut out = PathBuf::new();
    for c in path.components() {
        match c {
            Component::CurDir => {}
            Component::ParentDir
                if matches!(out.components().next_back(), Some(Component::Normal(_))) =>
            {
                out.pop();
            }
            other => out.push(other),
        }
    }
    out
}

/// `cited` without a trailing `:LINE`, `:LINE:COL` or `:LINE-LINE`.
fn without_line(cited: &str) -> &str {
    let line_suffix = |rest: &str| {
        !rest.is_empty()
            && rest
                .chars()
                .all(|c| c.is_ascii_digit() || c == ':' || c == '-')
    };
    match cited.split_once(':') {
        Some((path, rest)) if line_suffix(rest) => path,
        _ => cited,
    }
}

/// The folders a cited repository path may be relative to: the root, then each folder from the
/// citing file up that holds a package manifest (`Cargo.toml`, `pyproject.toml`).
fn bases(root: &Path, file: &Path) -> Vec<PathBuf> {
    let mut bases = vec![root.to_path_buf()];
    let mut dir = file.parent();
    while let Some(d) = dir.filter(|d| !d.as_os_str().is_empty()) {
        let full = root.join(d);
        if full.join("Cargo.toml").is_file() || full.join("pyproject.toml").is_file() {
            bases.push(full);
        }
        dir = d.parent();
    }
    bases
}

/// Whether a cited repository path resolves from `file`: an allowed non-file, something under
/// `../shared/` where that is missing (`shared` is `None`), the folder before a glob or
/// placeholder, or the path itself.
fn path_resolves(root: &Path, shared: Option<&Path>, file: &Path, cited: &str) -> bool {
    let path = without_line(cited);
    if NOT_FILES.iter().any(|(p, _)| *p == path) {
        return true;
    }
    let checked = match path.find(['*', '{', '<', '…']) {
        Some(at) => &path[..path[..at].rfind('/').map_or(0, |s| s + 1)],
        None => path,
    };
    if let Some(rest) = checked.strip_prefix("../shared/") {
        return shared.is_none_or(|dir| dir.join(rest).exists());
    }
    bases(root, file)
        .iter()
        .any(|base| base.join(checked).exists())
}

/// Whether a Markdown link target in `file` resolves: external and in-page links always do;
/// one into `../shared/` only counts where that folder is there (`shared`).
fn link_resolves(root: &Path, shared: Option<&Path>, file: &Path, target: &str) -> bool {
    let external = ["http://", "https://", "mailto:", "#"];
    if target.is_empty() || external.iter().any(|e| target.starts_with(e)) {
        return true;
    }
    let local = target.split(['#', '?']).next().unwrap_or("");
    let dir = file.parent().unwrap_or(Path::new(""));
    let resolved = normalise(&dir.join(local));
    if let Ok(rest) = resolved.strip_prefix("../shared") {
        return shared.is_none_or(|dir| dir.join(rest).exists());
    }
    root.join(resolved).exists()
}

/// Every Markdown link and every cited repository path of the repository's text resolves: a doc,
/// a comment or a script that names a file names one that is there. Guards the moves of files
/// (a crate split, a document renamed, run outputs moved to `results/`): the message lists each
/// broken reference as `file:line: path`.
#[test]
fn every_link_and_cited_path_resolves() {
    let root = repo_root();
    let shared = crate::common::shared_data("");
    let mut broken = Vec::new();
    let mut checked = 0;
    for file in repository_files(root) {
        let Ok(text) = std::fs::read_to_string(root.join(&file)) else {
            continue;
        };
        for c in citations(&file, &text) {
            checked += 1;
            let ok = if c.link {
                link_resolves(root, shared.as_deref(), &file, &c.target)
            } else {
                path_resolves(root, shared.as_deref(), &file, &c.target)
            };
            if !ok {
                broken.push(format!("{}:{}: {}", file.display(), c.line, c.target));
            }
        }
    }
    assert!(
        checked > 300,
        "only {checked} references found: is the scan reading the files?"
    );
    assert!(
        broken.is_empty(),
        "{} broken references (fix the reference, or the file it names):\n{}",
        broken.len(),
        broken.join("\n")
    );
}
