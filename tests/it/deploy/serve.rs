//! Every option and `TRE_*` variable the deploy files use is one `tre serve --help` lists; the
//! ports and probe paths are the service's.

use super::*;

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
    let doc: serde_json::Value =
        serde_json::from_str(&repo_text("docs/openapi.json")).expect("docs/openapi.json is JSON");
    let paths = doc
        .get("paths")
        .and_then(serde_json::Value::as_object)
        .expect("docs/openapi.json has no `paths` object");
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
        tre_vars(&repo_text("deploy/systemd/tre.service")),
        "deploy/systemd/tre.service",
    );
}

#[test]
fn deployment_flags_and_variables_are_serve_options_serve() {
    let deploy = deployment();
    let c = container(&deploy);
    assert_serve_env(container_env(c).into_keys(), "deployment.yaml env");
    assert_serve_env(
        tre_vars(&repo_text("deploy/k8s/deployment.yaml")),
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
    let readme = repo_text("deploy/README.md");
    assert_serve_env(tre_vars(&readme), "deploy/README.md");
    let serve_lines: Vec<&str> = readme.lines().filter(|l| l.contains("tre serve")).collect();
    let flags = long_flags(&serve_lines.join("\n"));
    assert_serve_flags(&flags, "deploy/README.md (lines with `tre serve`)");
}
