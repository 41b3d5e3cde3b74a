//! The Dockerfile: the ONNX Runtime wheel, the library where `tre` finds it, the models, the
//! exposed port and the image tag.

use super::*;

/// One Dockerfile instruction, continuation lines joined.
#[derive(Debug)]
pub(super) struct Instruction {
    pub(super) keyword: String,
    pub(super) args: String,
    /// 0 for the first `FROM`'s stage, 1 for the next, ...
    pub(super) stage: usize,
}

pub(super) fn dockerfile_text() -> String {
    repo_text("deploy/Dockerfile")
}

// Hand-parsed: a Dockerfile is line-based; splitting lines and joining `\` ends is the format.
pub(super) fn dockerfile() -> Vec<Instruction> {
    let mut out = Vec::new();
    let mut stage = None::<usize>;
    for full in logical_lines(&dockerfile_text(), &['#']) {
        let (keyword, args) = full.split_once(char::is_whitespace).unwrap_or((&full, ""));
        let keyword = keyword.to_ascii_uppercase();
        if keyword == "FROM" {
            stage = Some(stage.map_or(0, |s| s + 1));
        }
        let stage = stage.expect("the Dockerfile starts with FROM");
        let args = args.trim().to_owned();
        out.push(Instruction {
            keyword,
            args,
            stage,
        });
    }
    out
}

/// The final stage's instructions with `keyword`.
pub(super) fn final_stage<'a>(all: &'a [Instruction], keyword: &str) -> Vec<&'a Instruction> {
    let last = all.iter().map(|i| i.stage).max().expect("instructions");
    all.iter()
        .filter(|i| i.stage == last && i.keyword == keyword)
        .collect()
}

/// The final stage's `ENV` settings.
pub(super) fn final_env(all: &[Instruction]) -> BTreeMap<String, String> {
    final_stage(all, "ENV")
        .into_iter()
        .flat_map(|i| assignments(&i.args))
        .collect()
}

/// `org.opencontainers.image.version` of the final stage.
pub(super) fn image_version(all: &[Instruction]) -> String {
    let labels: BTreeMap<_, _> = final_stage(all, "LABEL")
        .into_iter()
        .flat_map(|i| assignments(&i.args))
        .collect();
    labels
        .get("org.opencontainers.image.version")
        .expect("the final stage has LABEL org.opencontainers.image.version")
        .clone()
}

#[test]
fn dockerfile_builds_with_the_ort_wheel_and_runs_tre_serve() {
    let all = dockerfile();
    let text = dockerfile_text();
    assert!(
        all.iter().filter(|i| i.keyword == "FROM").count() >= 2,
        "multi-stage build"
    );
    let pins = versions_after(&text, "onnxruntime==");
    assert!(
        !pins.is_empty(),
        "the Dockerfile installs no onnxruntime==VERSION"
    );
    let libs = versions_after(&text, "libonnxruntime.so.");
    assert!(
        !libs.is_empty(),
        "the Dockerfile names no libonnxruntime.so.VERSION"
    );
    for v in pins.iter().chain(&libs) {
        assert_eq!(
            v, ORT_VERSION,
            "ONNX Runtime {v} in the Dockerfile, tre wants {ORT_VERSION}"
        );
    }
    let build = all
        .iter()
        .find(|i| i.keyword == "RUN" && i.args.contains("cargo build"))
        .expect("a RUN with cargo build");
    assert!(build.args.contains("--release"), "{}", build.args);
    assert!(
        build.args.contains("TRE_ORT_NO_FETCH=1"),
        "the image ships the wheel's library; build.rs must not fetch its own: {}",
        build.args
    );
    let entry = final_stage(&all, "ENTRYPOINT");
    let entry = entry.last().expect("the final stage has an ENTRYPOINT");
    let argv: Vec<String> = serde_json::from_str(&entry.args).expect("ENTRYPOINT in exec form");
    let exe = argv.first().map(|a| a.rsplit('/').next().unwrap_or(a));
    assert_eq!(exe, Some("tre"), "ENTRYPOINT {argv:?}");
    assert_eq!(
        argv.get(1).map(String::as_str),
        Some("serve"),
        "ENTRYPOINT {argv:?}"
    );
    let user = final_stage(&all, "USER");
    let user = user.last().expect("the final stage sets USER").args.clone();
    let name = user.split(':').next().unwrap_or("");
    assert!(!["root", "0", ""].contains(&name), "USER {user}");
}

#[test]
fn dockerfile_puts_the_library_where_tre_finds_it() {
    let all = dockerfile();
    let dylib = final_env(&all)
        .get("ORT_DYLIB_PATH")
        .expect("the final stage sets ORT_DYLIB_PATH")
        .clone();
    let dylib = Path::new(&dylib);
    assert_eq!(
        dylib.file_name().and_then(|n| n.to_str()),
        Some(format!("libonnxruntime.so.{ORT_VERSION}").as_str())
    );
    let copies: Vec<Vec<String>> = final_stage(&all, "COPY")
        .into_iter()
        .map(|i| {
            words(&i.args)
                .into_iter()
                .filter(|w| !w.starts_with("--"))
                .collect()
        })
        .collect();
    let dest = |w: &[String]| PathBuf::from(w.last().expect("COPY SRC... DEST"));
    let exe = copies
        .iter()
        .find(|w| w.len() == 2 && w[0].ends_with("/tre"))
        .map(|w| {
            let d = dest(w);
            if w[1].ends_with('/') {
                d.join("tre")
            } else {
                d
            }
        })
        .expect("the final stage copies tre");
    assert_eq!(exe, Path::new("/usr/local/bin/tre"));
    // The library in the executable's ../lib is found even without ORT_DYLIB_PATH.
    let lib_dir = exe
        .parent()
        .and_then(Path::parent)
        .expect("bin/..")
        .join("lib");
    assert_eq!(dylib.parent(), Some(lib_dir.as_path()), "ORT_DYLIB_PATH");
    assert!(
        copies
            .iter()
            .any(|w| dest(w) == lib_dir || dest(w) == dylib),
        "nothing is copied into {}",
        lib_dir.display()
    );
}

#[test]
fn dockerfile_ships_the_models_and_exposes_the_container_port() {
    let all = dockerfile();
    let env = final_env(&all);
    let models = env
        .get("TRE_MODELS")
        .expect("the final stage sets TRE_MODELS");
    let model_copy = final_stage(&all, "COPY")
        .into_iter()
        .map(|i| words(&i.args))
        .find(|w| w.last().map(|d| d.trim_end_matches('/')) == Some(models.as_str()))
        .unwrap_or_else(|| panic!("nothing is copied into TRE_MODELS={models}"));
    assert!(
        model_copy.iter().any(|w| w == "models/manifest.json"),
        "{model_copy:?}"
    );
    assert!(
        model_copy.iter().any(|w| w.ends_with(".onnx")),
        "{model_copy:?}"
    );
    let exposed: Vec<i64> = final_stage(&all, "EXPOSE")
        .into_iter()
        .flat_map(|i| words(&i.args))
        .map(|p| {
            p.split('/')
                .next()
                .unwrap_or("")
                .parse()
                .expect("EXPOSE PORT")
        })
        .collect();
    let deploy = deployment();
    assert_eq!(exposed, [named_port(container(&deploy), "http")], "EXPOSE");
    for check in final_stage(&all, "HEALTHCHECK") {
        assert!(
            check.args.contains("/healthz"),
            "HEALTHCHECK {}",
            check.args
        );
    }
    let ignore = repo_text(".dockerignore");
    assert!(
        ignore.lines().any(|l| l.trim() == "target"),
        ".dockerignore must leave out target"
    );
}

#[test]
fn image_tag_is_the_crate_version_everywhere() {
    let version = image_version(&dockerfile());
    assert_eq!(
        version,
        env!("CARGO_PKG_VERSION"),
        "LABEL org.opencontainers.image.version"
    );
    let tag = format!("tre:{version}");
    let deploy = deployment();
    let image = text(container(&deploy), "image");
    assert_eq!(
        image.rsplit('/').next(),
        Some(tag.as_str()),
        "Deployment image"
    );
    if let Some(label) = deploy.get("metadata").and_then(|m| m.get("labels")) {
        let label = label
            .get("app.kubernetes.io/version")
            .and_then(Value::as_str);
        assert!(
            label.is_none_or(|l| l == version),
            "app.kubernetes.io/version {label:?}"
        );
    }
    let build = format!("docker build -f deploy/Dockerfile -t {tag} .");
    for (file, text) in [
        ("deploy/Dockerfile", dockerfile_text()),
        ("deploy/README.md", repo_text("deploy/README.md")),
    ] {
        assert!(text.contains(&build), "{file} documents `{build}`");
        for found in versions_after(&text, "tre:")
            .into_iter()
            .filter(|v| !v.is_empty())
        {
            assert_eq!(found, version, "{file} names the image tre:{found}");
        }
    }
}
