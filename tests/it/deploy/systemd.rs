//! The systemd unit: `tre serve`, hardened, with a stop timeout that outlasts draining.

use super::*;

// Hand-parsed: a unit file is `Key=value` lines under `[Section]`s, keys repeatable, `\` joining.
/// `[Service]` settings of the unit, in order, continuation lines joined.
pub(super) fn unit_service() -> Vec<(String, String)> {
    let mut out = Vec::new();
    let mut section = String::new();
    for full in logical_lines(&repo_text("deploy/systemd/tre.service"), &['#', ';']) {
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

pub(super) fn unit_value<'a>(service: &'a [(String, String)], key: &str) -> Option<&'a str> {
    service
        .iter()
        .rev()
        .find(|(k, _)| k == key)
        .map(|(_, v)| v.as_str())
}

pub(super) fn unit_env(service: &[(String, String)]) -> BTreeMap<String, String> {
    service
        .iter()
        .filter(|(k, _)| k == "Environment")
        .flat_map(|(_, v)| assignments(v))
        .collect()
}

/// Seconds of a systemd time span such as `30`, `30s`, `2min`, `1min 30s`.
pub(super) fn unit_seconds(span: &str) -> u64 {
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
