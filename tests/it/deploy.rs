//! `deploy/` agrees with the service it deploys: ports, probe paths, labels, names, image tag,
//! ONNX Runtime version, and every option and `TRE_*` variable the files use is one `tre serve`
//! has.
//!
//! Tests whose name ends in `_serve` run `tre serve --help` or read `src/server/openapi.json`;
//! the others read only the files under `deploy/`.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;

use serde_yaml_ng::Value;
use tre::model::runtime::ORT_VERSION;

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

// ---- files -----------------------------------------------------------------------------------

fn repo(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(rel)
}

fn read(rel: &str) -> String {
    let path = repo(rel);
    std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("cannot read {}: {e}", path.display()))
}

fn yaml(rel: &str) -> Value {
    serde_yaml_ng::from_str(&read(rel)).unwrap_or_else(|e| panic!("{rel} is not YAML: {e}"))
}

/// The value at a dotted path (`spec.template.spec`; a number indexes a sequence); panics naming
/// the path and the file's kind when it is missing.
fn at<'a>(doc: &'a Value, path: &str) -> &'a Value {
    let mut v = doc;
    for key in path.split('.') {
        let next = match key.parse::<usize>() {
            Ok(i) => v.get(i),
            Err(_) => v.get(key),
        };
        v = next.unwrap_or_else(|| panic!("{}: no `{path}` (at `{key}`)", kind(doc)));
    }
    v
}

fn kind(doc: &Value) -> &str {
    doc.get("kind").and_then(Value::as_str).unwrap_or("?")
}

fn text<'a>(doc: &'a Value, path: &str) -> &'a str {
    at(doc, path)
        .as_str()
        .unwrap_or_else(|| panic!("{}: `{path}` is not a string", kind(doc)))
}

fn int(doc: &Value, path: &str) -> i64 {
    at(doc, path)
        .as_i64()
        .unwrap_or_else(|| panic!("{}: `{path}` is not an integer", kind(doc)))
}

fn deployment() -> Value {
    let doc = yaml("deploy/k8s/deployment.yaml");
    assert_eq!(text(&doc, "apiVersion"), "apps/v1");
    assert_eq!(kind(&doc), "Deployment");
    doc
}

/// The Deployment's one container.
fn container(deploy: &Value) -> &Value {
    let containers = at(deploy, "spec.template.spec.containers")
        .as_sequence()
        .expect("containers is a list");
    assert_eq!(containers.len(), 1, "the tre pod runs one container");
    &containers[0]
}

/// The container's `env` as name → value (values that are not literals map to "").
fn container_env(container: &Value) -> BTreeMap<String, String> {
    let Some(env) = container.get("env") else {
        return BTreeMap::new();
    };
    let env = env.as_sequence().expect("env is a list");
    env.iter()
        .map(|e| {
            let name = text(e, "name").to_owned();
            let value = e.get("value").and_then(Value::as_str).unwrap_or("");
            (name, value.to_owned())
        })
        .collect()
}

/// The container port named `name`, as a number.
fn named_port(container: &Value, name: &str) -> i64 {
    let ports = at(container, "ports")
        .as_sequence()
        .expect("ports is a list");
    let port = ports
        .iter()
        .find(|p| p.get("name").and_then(Value::as_str) == Some(name))
        .unwrap_or_else(|| panic!("no container port named {name:?}"));
    int(port, "containerPort")
}

/// Whether every label of `selector` is on `labels` with the same value.
fn selects(selector: &Value, labels: &Value) -> bool {
    let selector = selector.as_mapping().expect("a selector is a map");
    !selector.is_empty() && selector.iter().all(|(k, v)| labels.get(k) == Some(v))
}

/// CPU quantity in cores: `2`, `1.5`, `1500m`.
fn cpu_cores(q: &Value) -> f64 {
    let s = match q {
        Value::Number(n) => n.to_string(),
        Value::String(s) => s.clone(),
        other => panic!("cpu quantity {other:?}"),
    };
    match s.strip_suffix('m') {
        Some(milli) => milli.parse::<f64>().expect("millicores") / 1000.0,
        None => s.parse().expect("cores"),
    }
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

// ---- Dockerfile ------------------------------------------------------------------------------

/// One Dockerfile instruction, continuation lines joined.
#[derive(Debug)]
struct Instruction {
    keyword: String,
    args: String,
    /// 0 for the first `FROM`'s stage, 1 for the next, ...
    stage: usize,
}

fn dockerfile_text() -> String {
    read("deploy/Dockerfile")
}

fn dockerfile() -> Vec<Instruction> {
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
fn final_stage<'a>(all: &'a [Instruction], keyword: &str) -> Vec<&'a Instruction> {
    let last = all.iter().map(|i| i.stage).max().expect("instructions");
    all.iter()
        .filter(|i| i.stage == last && i.keyword == keyword)
        .collect()
}

/// The final stage's `ENV` settings.
fn final_env(all: &[Instruction]) -> BTreeMap<String, String> {
    final_stage(all, "ENV")
        .into_iter()
        .flat_map(|i| assignments(&i.args))
        .collect()
}

/// `org.opencontainers.image.version` of the final stage.
fn image_version(all: &[Instruction]) -> String {
    let labels: BTreeMap<_, _> = final_stage(all, "LABEL")
        .into_iter()
        .flat_map(|i| assignments(&i.args))
        .collect();
    labels
        .get("org.opencontainers.image.version")
        .expect("the final stage has LABEL org.opencontainers.image.version")
        .clone()
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

// ---- systemd ---------------------------------------------------------------------------------

/// `[Service]` settings of the unit, in order, continuation lines joined.
fn unit_service() -> Vec<(String, String)> {
    let mut out = Vec::new();
    let mut section = String::new();
    for full in logical_lines(&read("deploy/systemd/tre.service"), &['#', ';']) {
        if full.starts_with('[') {
            section = full;
            continue;
        }
        let (key, value) = full.split_once('=').expect("unit lines are Key=value");
        if section == "[Service]" {
            out.push((key.trim().to_owned(), value.trim().to_owned()));
        }
    }
    out
}

fn unit_value<'a>(service: &'a [(String, String)], key: &str) -> Option<&'a str> {
    service
        .iter()
        .rev()
        .find(|(k, _)| k == key)
        .map(|(_, v)| v.as_str())
}

fn unit_env(service: &[(String, String)]) -> BTreeMap<String, String> {
    service
        .iter()
        .filter(|(k, _)| k == "Environment")
        .flat_map(|(_, v)| assignments(v))
        .collect()
}

/// Seconds of a systemd time span such as `30`, `30s`, `2min`, `1min 30s`.
fn unit_seconds(span: &str) -> u64 {
    words(span)
        .iter()
        .map(|w| {
            let digits = w.find(|c: char| !c.is_ascii_digit()).unwrap_or(w.len());
            let n: u64 = w[..digits]
                .parse()
                .unwrap_or_else(|_| panic!("time span {span:?}"));
            match &w[digits..] {
                "" | "s" | "sec" => n,
                "m" | "min" => 60 * n,
                other => panic!("time unit {other:?} in {span:?}"),
            }
        })
        .sum()
}

// ---- tre serve --help ------------------------------------------------------------------------

/// What `tre serve --help` lists.
#[derive(Debug, Default)]
struct Help {
    /// Long options without `--`.
    flags: BTreeSet<String>,
    /// Environment variables (`[env: NAME=`).
    env: BTreeSet<String>,
    /// Long option → its `[default: ...]`.
    defaults: BTreeMap<String, String>,
}

/// Parses clap's help (long or short form): an option starts at a line indented at most 6
/// spaces whose text starts with `-`; its `[env: ...]` and `[default: ...]` follow until the next.
fn parse_help(help: &str) -> Help {
    let mut parsed = Help::default();
    let mut blocks: Vec<(Vec<String>, String)> = Vec::new();
    for line in help.lines() {
        let indent = line.len() - line.trim_start().len();
        if indent <= 6 && line.trim_start().starts_with('-') {
            let names = line
                .split([' ', ','])
                .filter_map(|w| w.strip_prefix("--"))
                .map(|w| {
                    w.chars()
                        .take_while(|c| c.is_ascii_alphanumeric() || *c == '-')
                })
                .map(String::from_iter)
                .filter(|w| !w.is_empty())
                .collect();
            blocks.push((names, String::new()));
        }
        if let Some((_, body)) = blocks.last_mut() {
            body.push_str(line);
            body.push('\n');
        }
    }
    for (names, body) in blocks {
        let env = bracketed(&body, "[env: ").map(|e| e.split('=').next().unwrap_or("").to_owned());
        let default = bracketed(&body, "[default: ");
        for name in names {
            if let Some(d) = &default {
                parsed.defaults.insert(name.clone(), d.clone());
            }
            parsed.flags.insert(name);
        }
        parsed.env.extend(env);
    }
    parsed
}

/// The text after `open` up to the next `]`.
fn bracketed(body: &str, open: &str) -> Option<String> {
    let start = body.find(open)? + open.len();
    let len = body[start..].find(']')?;
    Some(body[start..start + len].to_owned())
}

/// `tre serve --help`, parsed once; run without any `TRE_*` variable so that the defaults shown
/// are the built-in ones.
fn serve_help() -> &'static Help {
    static HELP: OnceLock<Help> = OnceLock::new();
    HELP.get_or_init(|| {
        let mut cmd = Command::new(env!("CARGO_BIN_EXE_tre"));
        for (key, _) in std::env::vars_os() {
            if key.to_string_lossy().starts_with("TRE_") {
                cmd.env_remove(key);
            }
        }
        let out = cmd.args(["serve", "--help"]).output().expect("runs tre");
        assert!(
            out.status.success(),
            "`tre serve --help` failed ({}): {}",
            out.status,
            String::from_utf8_lossy(&out.stderr)
        );
        let help = parse_help(&String::from_utf8_lossy(&out.stdout));
        assert!(
            help.flags.contains("addr") && help.env.contains("TRE_ADDR"),
            "{help:?}"
        );
        help
    })
}

/// The port of `tre serve`'s default `--addr`.
fn default_port() -> i64 {
    let addr = serve_help()
        .defaults
        .get("addr")
        .expect("--addr has a [default: ...]");
    let port = addr.rsplit(':').next().expect("HOST:PORT");
    port.parse()
        .unwrap_or_else(|_| panic!("default --addr {addr:?} has no port"))
}

fn assert_serve_env(names: impl IntoIterator<Item = String>, file: &str) {
    let help = serve_help();
    let unknown: Vec<_> = names
        .into_iter()
        .filter(|n| n.starts_with("TRE_") && !BUILD_ENV.contains(&n.as_str()))
        .filter(|n| !help.env.contains(n))
        .collect();
    assert!(
        unknown.is_empty(),
        "{file} names {unknown:?}, which `tre serve --help` does not list (it lists {:?})",
        help.env
    );
}

fn assert_serve_flags(flags: &BTreeSet<String>, file: &str) {
    let help = serve_help();
    let unknown: Vec<_> = flags.difference(&help.flags).collect();
    assert!(
        unknown.is_empty(),
        "{file} passes {unknown:?}, which `tre serve --help` does not list (it lists {:?})",
        help.flags
    );
}

// ---- tests: deploy/ files alone --------------------------------------------------------------

#[test]
fn probes_use_healthz_readyz_on_the_named_port() {
    let deploy = deployment();
    let c = container(&deploy);
    for (probe, path) in [("livenessProbe", "/healthz"), ("readinessProbe", "/readyz")] {
        assert_eq!(text(c, &format!("{probe}.httpGet.path")), path, "{probe}");
    }
    for probe in ["livenessProbe", "readinessProbe", "startupProbe"] {
        let Some(p) = c.get(probe) else {
            continue;
        };
        let port = at(p, "httpGet.port")
            .as_str()
            .unwrap_or_else(|| panic!("{probe} must use the named container port, not a number"));
        assert!(named_port(c, port) > 0, "{probe} port {port}");
        let path = text(p, "httpGet.path");
        assert!(
            ["/healthz", "/readyz"].contains(&path),
            "{probe} path {path}"
        );
    }
}

#[test]
fn service_targets_the_container_port_and_selects_the_pods() {
    let deploy = deployment();
    let service = yaml("deploy/k8s/service.yaml");
    assert_eq!(
        (text(&service, "apiVersion"), kind(&service)),
        ("v1", "Service")
    );
    let labels = at(&deploy, "spec.template.metadata.labels");
    assert!(
        selects(at(&deploy, "spec.selector.matchLabels"), labels),
        "the Deployment's selector must match its own pod labels"
    );
    assert!(
        selects(at(&service, "spec.selector"), labels),
        "the Service's selector must match the Deployment's pod labels"
    );
    let c = container(&deploy);
    let ports = at(&service, "spec.ports")
        .as_sequence()
        .expect("ports is a list");
    assert!(!ports.is_empty(), "the Service has no port");
    for port in ports {
        let target = at(port, "targetPort");
        let number = target.as_str().map_or_else(
            || target.as_i64().expect("targetPort is a name or a number"),
            |name| named_port(c, name),
        );
        assert_eq!(
            number,
            named_port(c, "http"),
            "Service targetPort {target:?}"
        );
    }
}

#[test]
fn hpa_scales_the_deployment_on_cpu() {
    let deploy = deployment();
    let hpa = yaml("deploy/k8s/hpa.yaml");
    assert_eq!(text(&hpa, "apiVersion"), "autoscaling/v2");
    assert_eq!(kind(&hpa), "HorizontalPodAutoscaler");
    assert_eq!(text(&hpa, "spec.scaleTargetRef.apiVersion"), "apps/v1");
    assert_eq!(text(&hpa, "spec.scaleTargetRef.kind"), "Deployment");
    assert_eq!(
        text(&hpa, "spec.scaleTargetRef.name"),
        text(&deploy, "metadata.name")
    );
    let (min, max) = (int(&hpa, "spec.minReplicas"), int(&hpa, "spec.maxReplicas"));
    assert!(1 <= min && min <= max, "replicas {min}..{max}");
    let metrics = at(&hpa, "spec.metrics")
        .as_sequence()
        .expect("metrics is a list");
    let cpu = metrics
        .iter()
        .find(|m| {
            m.get("resource")
                .and_then(|r| r.get("name"))
                .and_then(Value::as_str)
                == Some("cpu")
        })
        .expect("the HPA scales on the cpu resource");
    assert_eq!(text(cpu, "resource.target.type"), "Utilization");
    let target = int(cpu, "resource.target.averageUtilization");
    assert!((1..=100).contains(&target), "averageUtilization {target}");
    // Utilisation is relative to the request: without one the HPA cannot scale.
    let request = cpu_cores(at(container(&deploy), "resources.requests.cpu"));
    assert!(request > 0.0, "cpu request {request}");
    assert!(
        at(&deploy, "spec").get("replicas").is_none(),
        "the HPA owns the replica count; a `replicas` in the Deployment resets it on every apply"
    );
    let ns = |doc: &Value| {
        doc.get("metadata")
            .and_then(|m| m.get("namespace"))
            .cloned()
    };
    assert_eq!(
        ns(&deploy),
        ns(&hpa),
        "the HPA and the Deployment share a namespace"
    );
}

#[test]
fn workers_fit_the_cpu_limit_and_shutdown_fits_the_grace_period() {
    let deploy = deployment();
    let c = container(&deploy);
    let env = container_env(c);
    let number = |name: &str| -> u64 {
        let v = env
            .get(name)
            .unwrap_or_else(|| panic!("the Deployment sets no {name}"));
        v.parse()
            .unwrap_or_else(|_| panic!("{name}={v:?} is not a number"))
    };
    let threads = number("TRE_WORKERS") * number("TRE_ORT_THREADS");
    let cores = cpu_cores(at(c, "resources.limits.cpu"));
    assert!(
        threads as f64 <= cores.ceil(),
        "{threads} ONNX Runtime threads on a {cores}-core limit"
    );
    let pre_stop = match at(c, "lifecycle.preStop.exec.command").as_sequence() {
        Some(cmd) if cmd.first().and_then(Value::as_str) == Some("sleep") => cmd[1]
            .as_str()
            .expect("sleep seconds")
            .parse::<u64>()
            .expect("sleep seconds"),
        other => panic!("preStop {other:?} is not [sleep, N]"),
    };
    let request_s = number("TRE_REQUEST_TIMEOUT_MS").div_ceil(1000);
    let drain_s = number("TRE_SHUTDOWN_GRACE_S").max(request_s);
    let grace = int(&deploy, "spec.template.spec.terminationGracePeriodSeconds");
    assert!(
        u64::try_from(grace).expect("positive") > pre_stop + drain_s,
        "terminationGracePeriodSeconds {grace} leaves no time after preStop {pre_stop} s and \
         draining {drain_s} s: in-flight work would be killed"
    );
}

#[test]
fn memory_limits_hold_the_largest_frames() {
    let deploy = deployment();
    let c = container(&deploy);
    let needed = memory_needed(&container_env(c), "deployment.yaml");
    let limit = bytes(text(c, "resources.limits.memory"), false);
    assert!(
        needed <= limit,
        "the Deployment may need {needed} bytes, its memory limit is {limit}"
    );
    let request = bytes(text(c, "resources.requests.memory"), false);
    assert!(
        request <= limit,
        "memory request {request} above the limit {limit}"
    );
    let service = unit_service();
    let needed = memory_needed(&unit_env(&service), "tre.service");
    let max = bytes(unit_value(&service, "MemoryMax").expect("MemoryMax"), true);
    assert!(
        needed <= max,
        "the unit may need {needed} bytes, MemoryMax is {max}"
    );
}

#[test]
fn systemd_unit_runs_tre_serve_hardened_with_a_stop_timeout() {
    let service = unit_service();
    let exec = words(unit_value(&service, "ExecStart").expect("ExecStart"));
    assert_eq!(exec.first().map(String::as_str), Some("/usr/local/bin/tre"));
    assert!(
        exec.iter().any(|w| w == "serve"),
        "ExecStart {exec:?} does not run `serve`"
    );
    assert_eq!(unit_value(&service, "Restart"), Some("on-failure"));
    assert_eq!(unit_value(&service, "KillSignal"), Some("SIGTERM"));
    assert_eq!(unit_value(&service, "NoNewPrivileges"), Some("yes"));
    assert_eq!(unit_value(&service, "ProtectSystem"), Some("strict"));
    let user = unit_value(&service, "User").expect("a dedicated User=");
    assert!(!["root", "0"].contains(&user), "User={user}");
    let env = unit_env(&service);
    let number = |name: &str| -> u64 {
        let v = env
            .get(name)
            .unwrap_or_else(|| panic!("the unit sets no {name}"));
        v.parse()
            .unwrap_or_else(|_| panic!("{name}={v:?} is not a number"))
    };
    let drain_s =
        number("TRE_SHUTDOWN_GRACE_S").max(number("TRE_REQUEST_TIMEOUT_MS").div_ceil(1000));
    let stop = unit_seconds(unit_value(&service, "TimeoutStopSec").expect("TimeoutStopSec"));
    assert!(
        stop > drain_s,
        "TimeoutStopSec {stop} s does not outlast draining {drain_s} s"
    );
    if let Some(path) = env.get("ORT_DYLIB_PATH") {
        assert!(
            path.ends_with(&format!("/libonnxruntime.so.{ORT_VERSION}")),
            "{path}"
        );
    }
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
    let ignore = read(".dockerignore");
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
        ("deploy/README.md", read("deploy/README.md")),
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

#[test]
fn readme_features_exist_in_cargo_toml() {
    let readme = read("deploy/README.md");
    let manifest = read("Cargo.toml");
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

#[test]
fn help_parser_reads_clap_long_and_short_help() {
    let long = "Serve\n\nUsage: tre serve [OPTIONS]\n\nOptions:\n      --addr <ADDR>\n          \
                Address\n          \n          [env: TRE_ADDR=1.2.3.4:5]\n          \
                [default: 0.0.0.0:8080]\n\n      --mode <MODE>\n          Possible values:\n          \
                - rgb: RGB\n\n  -h, --help\n          Print help\n";
    let help = parse_help(long);
    assert_eq!(
        help.defaults.get("addr").map(String::as_str),
        Some("0.0.0.0:8080")
    );
    assert_eq!(help.env, BTreeSet::from(["TRE_ADDR".to_owned()]));
    let flags: Vec<_> = help.flags.iter().map(String::as_str).collect();
    assert_eq!(flags, ["addr", "help", "mode"]);
    let short =
        "Options:\n      --log-json  JSON logs [env: TRE_LOG_JSON=]\n      --queue <QUEUE>  \
                 Queue [env: TRE_QUEUE=] [default: 0]\n";
    let help = parse_help(short);
    assert_eq!(help.defaults.get("queue").map(String::as_str), Some("0"));
    assert!(help.env.contains("TRE_LOG_JSON") && help.env.contains("TRE_QUEUE"));
    assert_eq!(
        tre_vars("A=TRE_X; #TRE_Y_2 NOT_TRE_Z tre_w `TRE_*`"),
        BTreeSet::from(["TRE_X".to_owned(), "TRE_Y_2".to_owned()])
    );
    assert_eq!(words(r#"A="b c" D=e"#), ["A=b c", "D=e"]);
    let flags = long_flags("tre serve --models=/m `--provider cuda` a--b --X (--log-json) -- x");
    let flags: Vec<_> = flags.iter().map(String::as_str).collect();
    assert_eq!(flags, ["log-json", "models", "provider"]);
    assert_eq!(unit_seconds("1min 30s"), 90);
    assert_eq!(bytes("2Gi", false), 2 << 30);
    assert_eq!(bytes("1536M", true), 1536 << 20);
    assert_eq!(bytes("500M", false), 500_000_000);
}

// ---- tests that need `tre serve` -------------------------------------------------------------

#[test]
fn container_port_is_the_serve_default_port_serve() {
    let port = default_port();
    let deploy = deployment();
    let c = container(&deploy);
    let all = dockerfile();
    // The address the container listens on: the Deployment's TRE_ADDR, else the image's, else
    // tre's default.
    let addr = container_env(c)
        .get("TRE_ADDR")
        .or(final_env(&all).get("TRE_ADDR"))
        .map(|a| {
            a.rsplit(':')
                .next()
                .expect("HOST:PORT")
                .parse::<i64>()
                .expect("port")
        });
    assert_eq!(
        named_port(c, "http"),
        addr.unwrap_or(port),
        "containerPort of `http`"
    );
    let check = final_stage(&all, "HEALTHCHECK");
    if let Some(check) = check.last() {
        let default_addr = &serve_help().defaults["addr"];
        assert!(
            check.args.contains(default_addr.as_str()),
            "HEALTHCHECK falls back to a TRE_ADDR other than tre's default {default_addr}"
        );
    }
}

#[test]
fn probe_paths_are_in_the_openapi_document_serve() {
    let doc: serde_json::Value = serde_json::from_str(&read("src/server/openapi.json"))
        .expect("src/server/openapi.json is JSON");
    let paths = doc
        .get("paths")
        .and_then(serde_json::Value::as_object)
        .expect("src/server/openapi.json has no `paths` object");
    let deploy = deployment();
    let c = container(&deploy);
    for probe in ["livenessProbe", "readinessProbe", "startupProbe"] {
        let Some(p) = c.get(probe) else {
            continue;
        };
        let path = text(p, "httpGet.path");
        let get = paths.get(path).and_then(|ops| ops.get("get"));
        assert!(get.is_some(), "openapi.json has no GET {path} ({probe})");
    }
}

#[test]
fn systemd_flags_and_variables_are_serve_options_serve() {
    let service = unit_service();
    let exec = words(unit_value(&service, "ExecStart").expect("ExecStart"));
    assert_serve_flags(&long_flags(&exec.join(" ")), "tre.service ExecStart");
    assert_serve_env(unit_env(&service).into_keys(), "tre.service Environment=");
    assert_serve_env(
        tre_vars(&read("deploy/systemd/tre.service")),
        "deploy/systemd/tre.service",
    );
}

#[test]
fn deployment_flags_and_variables_are_serve_options_serve() {
    let deploy = deployment();
    let c = container(&deploy);
    assert_serve_env(container_env(c).into_keys(), "deployment.yaml env");
    assert_serve_env(
        tre_vars(&read("deploy/k8s/deployment.yaml")),
        "deploy/k8s/deployment.yaml",
    );
    let mut args = Vec::new();
    for key in ["command", "args"] {
        if let Some(list) = c.get(key).and_then(Value::as_sequence) {
            args.extend(list.iter().filter_map(Value::as_str).map(str::to_owned));
        }
    }
    assert_serve_flags(&long_flags(&args.join(" ")), "deployment.yaml command/args");
}

#[test]
fn dockerfile_and_readme_variables_are_serve_options_serve() {
    let all = dockerfile();
    let last = all.iter().map(|i| i.stage).max().expect("instructions");
    let final_text: Vec<&str> = all
        .iter()
        .filter(|i| i.stage == last)
        .map(|i| i.args.as_str())
        .collect();
    assert_serve_env(
        tre_vars(&final_text.join("\n")),
        "the Dockerfile's final stage",
    );
    let readme = read("deploy/README.md");
    assert_serve_env(tre_vars(&readme), "deploy/README.md");
    let serve_lines: Vec<&str> = readme.lines().filter(|l| l.contains("tre serve")).collect();
    let flags = long_flags(&serve_lines.join("\n"));
    assert_serve_flags(&flags, "deploy/README.md (lines with `tre serve`)");
}
