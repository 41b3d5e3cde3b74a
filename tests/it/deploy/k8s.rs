//! The Kubernetes manifests: probes, the Service, the HPA, CPU and memory limits against the
//! workers and the shutdown grace.

use super::*;

pub(super) fn yaml(rel: &str) -> Value {
    serde_yaml_ng::from_str(&repo_text(rel)).unwrap_or_else(|e| panic!("{rel} is not YAML: {e}"))
}

/// The value at a dotted path (`spec.template.spec`; a number indexes a sequence); panics naming
/// the path and the file's kind when it is missing.
pub(super) fn at<'a>(doc: &'a Value, path: &str) -> &'a Value {
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

pub(super) fn kind(doc: &Value) -> &str {
    doc.get("kind").and_then(Value::as_str).unwrap_or("?")
}

pub(super) fn text<'a>(doc: &'a Value, path: &str) -> &'a str {
    at(doc, path)
        .as_str()
        .unwrap_or_else(|| panic!("{}: `{path}` is not a string", kind(doc)))
}

pub(super) fn int(doc: &Value, path: &str) -> i64 {
    at(doc, path)
        .as_i64()
        .unwrap_or_else(|| panic!("{}: `{path}` is not an integer", kind(doc)))
}

pub(super) fn deployment() -> Value {
    let doc = yaml("deploy/k8s/deployment.yaml");
    assert_eq!(text(&doc, "apiVersion"), "apps/v1");
    assert_eq!(kind(&doc), "Deployment");
    doc
}

/// The Deployment's one container.
pub(super) fn container(deploy: &Value) -> &Value {
    let containers = at(deploy, "spec.template.spec.containers")
        .as_sequence()
        .expect("containers is a list");
    assert_eq!(containers.len(), 1, "the tre pod runs one container");
    &containers[0]
}

/// The container's `env` as name → value (values that are not literals map to "").
pub(super) fn container_env(container: &Value) -> BTreeMap<String, String> {
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
pub(super) fn named_port(container: &Value, name: &str) -> i64 {
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
pub(super) fn selects(selector: &Value, labels: &Value) -> bool {
    let selector = selector.as_mapping().expect("a selector is a map");
    !selector.is_empty() && selector.iter().all(|(k, v)| labels.get(k) == Some(v))
}

/// CPU quantity in cores: `2`, `1.5`, `1500m`.
pub(super) fn cpu_cores(q: &Value) -> f64 {
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
