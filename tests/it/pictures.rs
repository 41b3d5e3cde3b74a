//! `docs/pictures.json` against the repository: every committed picture (each PNG under
//! `docs/`, and every image the README or a doc shows from there) is listed with the command
//! that made it, and one made with the networks names the committed models' hash
//! (`models_key` of `models/manifest.json`). A model retrained without its pictures redrawn
//! fails here.
#![allow(clippy::unwrap_used)] // Test helpers fail loudly by design.

use std::collections::BTreeSet;
use std::path::Path;

use crate::common::repo_root;

/// The PNGs under `dir`, relative to the repository's root.
fn pngs(dir: &Path, found: &mut BTreeSet<String>) {
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.is_dir() {
            pngs(&path, found);
        } else if path.extension().is_some_and(|e| e == "png") {
            let rel = path.strip_prefix(repo_root()).unwrap();
            found.insert(rel.to_string_lossy().replace('\\', "/"));
        }
    }
}

fn manifest() -> serde_json::Value {
    let text = std::fs::read_to_string(repo_root().join("docs/pictures.json")).unwrap();
    serde_json::from_str(&text).unwrap()
}

#[test]
fn every_committed_picture_names_its_command_and_the_committed_models() {
    let doc = manifest();
    let pictures = doc["pictures"].as_array().unwrap();
    let models = tre::model::Manifest::read(&repo_root().join("models")).unwrap();
    let key = tre::pipeline::models_key(&models);
    let mut listed = BTreeSet::new();
    for p in pictures {
        let path = p["path"].as_str().unwrap();
        assert!(listed.insert(path.to_owned()), "{path} listed twice");
        assert!(
            repo_root().join(path).is_file(),
            "{path} is listed but missing"
        );
        let command = p["command"].as_str().unwrap_or_default();
        assert!(
            command.contains("tre ") || command.contains("cargo "),
            "{path}: {command:?}"
        );
        match p["models"].as_str() {
            Some(made_with) => assert_eq!(
                made_with, key,
                "{path} was made with other models than the committed ones: redraw it ({command}) \
                 and record the models' hash in docs/pictures.json"
            ),
            None => assert!(
                p["no_models"].as_str().is_some_and(|w| !w.is_empty()),
                "{path}: no models' hash and no word on why no network ran"
            ),
        }
        for page in p["shown_in"].as_array().unwrap() {
            let page = page.as_str().unwrap();
            let text = std::fs::read_to_string(repo_root().join(page)).unwrap();
            let name = Path::new(path).file_name().unwrap().to_str().unwrap();
            assert!(text.contains(name), "{page} does not show {path}");
        }
    }
    let mut committed = BTreeSet::new();
    pngs(&repo_root().join("docs"), &mut committed);
    let unlisted: Vec<_> = committed.difference(&listed).collect();
    assert!(
        unlisted.is_empty(),
        "not in docs/pictures.json: {unlisted:?}"
    );
    // The README's pictures are among them.
    let readme = std::fs::read_to_string(repo_root().join("README.md")).unwrap();
    for shown in readme.split("](docs/").skip(1) {
        let path = format!("docs/{}", shown.split(')').next().unwrap());
        if path.ends_with(".png") {
            assert!(
                listed.contains(&path),
                "the README shows {path}, not listed"
            );
        }
    }
}
