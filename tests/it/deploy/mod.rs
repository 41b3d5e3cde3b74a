//! `deploy/` agrees with the service it deploys: ports, probe paths, labels, names, image tag,
//! ONNX Runtime version, and every option and `TRE_*` variable the files use is one `tre serve`
//! has.
//!
//! Tests whose name ends in `_serve` run `tre serve --help` or read `docs/openapi.json`;
//! the others read only the files under `deploy/`.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;

use serde_yaml_ng::Value;
use tre::model::runtime::ORT_VERSION;

use crate::common::repo_text;

mod dockerfile;
mod k8s;
mod serve;
mod systemd;

use dockerfile::{dockerfile, final_env, final_stage};
use k8s::{container, container_env, deployment, named_port, text};
use systemd::{unit_env, unit_seconds, unit_service, unit_value};

/// Variables the deploy files may name that are not `tre serve` options: build-time settings.
const BUILD_ENV: &[&str] = &["TRE_ORT_NO_FETCH"];

/// Memory budget of `tre serve`, from measurements (two workers: about 450 MB resident after
/// serving frames; each frame in flight about 60 bytes per pixel for RGB frames, from 5 to 40
/// Mpx, and up to about 146 for a depth-only frame, which the geometric mode runs at its own
/// size with every map of the spec: `tre infer --depth` on 4096 × 4096 peaked at 2.45 GB): per
/// worker, its sessions plus one frame of `TRE_MAX_PIXELS` at the worst case; plus every
/// concurrent request's body.
const SESSIONS_BYTES_PER_WORKER: u64 = 256 << 20;
const BYTES_PER_PIXEL_IN_FLIGHT: u64 = 150;

/// The memory `tre serve` may need with these settings, bytes.
fn memory_needed(env: &BTreeMap<String, String>, file: &str) -> u64 {
    let number = |name: &str| -> u64 {
        let v = env
            .get(name)
            .unwrap_or_else(|| panic!("{file} sets no {name}, so its memory use is unbounded"));
        v.parse()
            .unwrap_or_else(|_| panic!("{file}: {name}={v:?} is not a number"))
    };
    let per_worker =
        SESSIONS_BYTES_PER_WORKER + number("TRE_MAX_PIXELS") * BYTES_PER_PIXEL_IN_FLIGHT;
    number("TRE_WORKERS") * per_worker + number("TRE_MAX_CONCURRENT") * number("TRE_MAX_BODY_BYTES")
}

/// Bytes of a size with a binary (`Ki`, `Mi`, `Gi`; systemd's `K`, `M`, `G` too when
/// `k_is_1024`) or decimal suffix.
fn bytes(size: &str, k_is_1024: bool) -> u64 {
    let digits = size
        .find(|c: char| !c.is_ascii_digit())
        .unwrap_or(size.len());
    let n: u64 = size[..digits]
        .parse()
        .unwrap_or_else(|_| panic!("size {size:?}"));
    let k = if k_is_1024 { 1024 } else { 1000 };
    let unit = match &size[digits..] {
        "" => 1,
        "Ki" => 1 << 10,
        "Mi" => 1 << 20,
        "Gi" => 1 << 30,
        "K" | "k" => k,
        "M" => k * k,
        "G" => k * k * k,
        other => panic!("size unit {other:?} in {size:?}"),
    };
    n * unit
}

/// Every `TRE_NAME` token in `text` (comments included).
fn tre_vars(text: &str) -> BTreeSet<String> {
    let mut found = BTreeSet::new();
    let bytes = text.as_bytes();
    let word = |b: u8| b.is_ascii_uppercase() || b.is_ascii_digit() || b == b'_';
    for (i, _) in text.match_indices("TRE_") {
        if i > 0 && (word(bytes[i - 1]) || bytes[i - 1].is_ascii_lowercase()) {
            continue;
        }
        let end = bytes[i..]
            .iter()
            .position(|&b| !word(b))
            .map_or(text.len(), |n| i + n);
        if end > i + 4 {
            found.insert(text[i..end].to_owned());
        }
    }
    found
}

/// Splits on whitespace outside quotes and drops the quotes (`A="b c" D=e` → `A=b c`, `D=e`).
fn words(s: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut cur = String::new();
    let mut quote = None;
    let mut in_word = false;
    for c in s.chars() {
        match (quote, c) {
            (Some(q), c) if c == q => quote = None,
            (Some(_), c) => cur.push(c),
            (None, '"' | '\'') => {
                quote = Some(c);
                in_word = true;
            }
            (None, c) if c.is_whitespace() => {
                if in_word {
                    out.push(std::mem::take(&mut cur));
                    in_word = false;
                }
            }
            (None, c) => {
                cur.push(c);
                in_word = true;
            }
        }
    }
    if in_word {
        out.push(cur);
    }
    out
}

/// `NAME=value` words as pairs.
fn assignments(s: &str) -> Vec<(String, String)> {
    words(s)
        .into_iter()
        .map(|w| match w.split_once('=') {
            Some((k, v)) => (k.to_owned(), v.to_owned()),
            None => panic!("{w:?} is not NAME=value"),
        })
        .collect()
}

/// The long options (`--name`, without `=value`) in `text`: `--` at the start of a word (after
/// space, a quote, a backtick or a bracket) followed by lower-case letters, digits and dashes.
fn long_flags(text: &str) -> BTreeSet<String> {
    let bytes = text.as_bytes();
    text.match_indices("--")
        .filter(|&(i, _)| i == 0 || b" \t\"'`([".contains(&bytes[i - 1]))
        .filter_map(|(i, _)| {
            let rest = &text[i + 2..];
            let end = rest
                .find(|c: char| !(c.is_ascii_lowercase() || c.is_ascii_digit() || c == '-'))
                .unwrap_or(rest.len());
            let name = &rest[..end];
            name.starts_with(|c: char| c.is_ascii_lowercase())
                .then(|| name.to_owned())
        })
        .collect()
}

/// Every `marker` + version in `text` (e.g. `onnxruntime==` → `1.31.1`).
fn versions_after(text: &str, marker: &str) -> Vec<String> {
    text.match_indices(marker)
        .map(|(i, _)| {
            let rest = &text[i + marker.len()..];
            let end = rest
                .find(|c: char| !(c.is_ascii_digit() || c == '.'))
                .unwrap_or(rest.len());
            rest[..end].trim_end_matches('.').to_owned()
        })
        .collect()
}

/// The logical lines of a Dockerfile or unit file: trimmed, a line ending in `\\` joined to the
/// next with a space, blank lines and lines starting with one of `comments` left out.
fn logical_lines(text: &str, comments: &[char]) -> Vec<String> {
    let mut out = Vec::new();
    let mut pending = String::new();
    for line in text.lines().map(str::trim) {
        if line.is_empty() || line.starts_with(comments) {
            continue;
        }
        match line.strip_suffix('\\') {
            Some(head) => {
                pending.push_str(head);
                pending.push(' ');
            }
            None => {
                pending.push_str(line);
                out.push(std::mem::take(&mut pending));
            }
        }
    }
    out
}

#[test]
fn readme_features_exist_in_cargo_toml() {
    let readme = repo_text("deploy/README.md");
    let manifest = repo_text("Cargo.toml");
    let features: BTreeSet<&str> = readme
        .split("--features")
        .skip(1)
        .filter_map(|rest| rest.split_whitespace().next())
        .flat_map(|list| list.trim_matches(['"', '\'', '`', '=']).split(','))
        .collect();
    assert!(
        features.contains("cuda") && features.contains("tensorrt"),
        "{features:?}"
    );
    for f in features {
        assert!(
            manifest.lines().any(|l| l.starts_with(&format!("{f} = ["))),
            "deploy/README.md names cargo feature {f:?}, which Cargo.toml lacks"
        );
    }
}
