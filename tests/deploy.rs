//! The deployment files under `deploy/` (issue 14 §7), checked three ways:
//! - each passes its format's schema, by tools nobody here wrote
//!   (`check-jsonschema` with the compose-spec schema, `kubernetes-validate
//!   --strict`), which `.ci/run` installs;
//! - every meshatlas container's command line is accepted by the binary,
//!   and every `MESHATLAS_*` variable it sets is one the binary reads for
//!   that role (`--help` lists them), so a renamed flag breaks the test;
//! - the processes the distributed compose file and the Kubernetes
//!   manifests describe (their replicas, commands and environment, with
//!   database, bucket and listening addresses swapped for the loopback test
//!   servers and data directories of their own) run jobs submitted through
//!   either API and serve their artifacts from the other one, and answer the
//!   probes the files name.
//!
//! There is no container runtime here: what the files add around the
//! processes (images, nginx, volumes) is covered by the schemas only.

mod common;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use serde_json::Value;
use yaml_rust2::{Yaml, YamlLoader};

fn deploy(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("deploy").join(name)
}

fn load(name: &str) -> Vec<Yaml> {
    let text = std::fs::read_to_string(deploy(name)).unwrap();
    YamlLoader::load_from_str(&text).unwrap_or_else(|e| panic!("{name}: {e}"))
}

/// `y` with YAML merge keys (`<<: *anchor`) expanded, recursively; keys of
/// the mapping itself win over merged ones, as compose reads them.
fn merged(y: &Yaml) -> Yaml {
    match y {
        Yaml::Hash(h) => {
            let mut out = yaml_rust2::yaml::Hash::new();
            if let Some(base) = h.get(&Yaml::String("<<".into()))
                && let Yaml::Hash(b) = merged(base)
            {
                out.extend(b);
            }
            for (k, v) in h {
                if k.as_str() != Some("<<") {
                    out.insert(k.clone(), merged(v));
                }
            }
            Yaml::Hash(out)
        }
        Yaml::Array(a) => Yaml::Array(a.iter().map(merged).collect()),
        other => other.clone(),
    }
}

fn text(y: &Yaml) -> String {
    match y {
        Yaml::String(s) | Yaml::Real(s) => s.clone(),
        Yaml::Integer(i) => i.to_string(),
        Yaml::Boolean(b) => b.to_string(),
        other => panic!("not a scalar: {other:?}"),
    }
}

fn strings(y: &Yaml) -> Vec<String> {
    y.as_vec().map(|v| v.iter().map(text).collect()).unwrap_or_default()
}

/// One meshatlas container (compose service or Kubernetes container).
#[derive(Debug, Clone)]
struct Container {
    name: String,
    replicas: usize,
    /// Arguments after the binary (`serve --no-worker`, `worker --addr …`).
    args: Vec<String>,
    env: BTreeMap<String, String>,
    /// Files the container mounts, by the path it sees: (path, contents).
    files: Vec<(String, String)>,
    /// HTTP probe paths and the container port name or number they use.
    probes: Vec<(String, String)>,
    /// Port names to numbers.
    ports: BTreeMap<String, String>,
}

/// The meshatlas services of a compose file.
fn compose_containers(name: &str) -> Vec<Container> {
    let doc = merged(&load(name).remove(0));
    let services = doc["services"].as_hash().unwrap();
    let mut out = Vec::new();
    for (svc, s) in services {
        if !s["image"].as_str().unwrap_or_default().starts_with("meshatlas") {
            continue;
        }
        let env = s["environment"].as_hash().map(|h| h.iter().map(|(k, v)| (text(k), text(v))).collect());
        out.push(Container {
            name: text(svc),
            replicas: s["deploy"]["replicas"].as_i64().map_or(1, |r| r as usize),
            args: match &s["command"] {
                Yaml::BadValue => vec!["serve".into()],
                c => strings(c),
            },
            env: env.unwrap_or_default(),
            files: Vec::new(),
            probes: Vec::new(),
            ports: BTreeMap::new(),
        });
    }
    out
}

/// The meshatlas containers of the Kubernetes manifests, with the
/// ConfigMap and Secret values they reference resolved.
fn kubernetes_containers() -> Vec<Container> {
    let docs = load("kubernetes.yaml");
    let find = |kind: &str, name: &str| {
        docs.iter().find(|d| d["kind"].as_str() == Some(kind) && d["metadata"]["name"].as_str() == Some(name))
    };
    let map_of = |y: &Yaml| -> BTreeMap<String, String> {
        y.as_hash().map(|h| h.iter().map(|(k, v)| (text(k), text(v))).collect()).unwrap_or_default()
    };
    let mut out = Vec::new();
    for d in docs.iter().filter(|d| d["kind"].as_str() == Some("Deployment")) {
        let pod = &d["spec"]["template"]["spec"];
        for c in pod["containers"].as_vec().unwrap() {
            let mut env = BTreeMap::new();
            for from in c["envFrom"].as_vec().into_iter().flatten() {
                let cm = from["configMapRef"]["name"].as_str().expect("configMapRef");
                env.extend(map_of(&find("ConfigMap", cm).unwrap_or_else(|| panic!("no ConfigMap {cm}"))["data"]));
            }
            for e in c["env"].as_vec().into_iter().flatten() {
                let value = match &e["valueFrom"]["secretKeyRef"] {
                    Yaml::BadValue => text(&e["value"]),
                    r => {
                        let (sn, key) = (r["name"].as_str().unwrap(), r["key"].as_str().unwrap());
                        let secret =
                            map_of(&find("Secret", sn).unwrap_or_else(|| panic!("no Secret {sn}"))["stringData"]);
                        secret.get(key).unwrap_or_else(|| panic!("Secret {sn} has no {key}")).clone()
                    }
                };
                env.insert(text(&e["name"]), value);
            }
            let mut files = Vec::new();
            for m in c["volumeMounts"].as_vec().into_iter().flatten() {
                let vol = pod["volumes"].as_vec().unwrap().iter().find(|v| v["name"] == m["name"]).unwrap();
                let Some(sn) = vol["secret"]["secretName"].as_str() else { continue };
                let secret = map_of(&find("Secret", sn).unwrap()["stringData"]);
                for item in vol["secret"]["items"].as_vec().into_iter().flatten() {
                    let path = format!("{}/{}", text(&m["mountPath"]), text(&item["path"]));
                    files.push((path, secret[&text(&item["key"])].clone()));
                }
            }
            let probes = ["readinessProbe", "livenessProbe"]
                .iter()
                .map(|p| (text(&c[*p]["httpGet"]["path"]), text(&c[*p]["httpGet"]["port"])))
                .collect();
            let ports =
                c["ports"].as_vec().into_iter().flatten().map(|p| (text(&p["name"]), text(&p["containerPort"])));
            out.push(Container {
                name: text(&d["metadata"]["name"]),
                replicas: d["spec"]["replicas"].as_i64().map_or(1, |r| r as usize),
                args: strings(&c["args"]),
                env,
                files,
                probes,
                ports: ports.collect(),
            });
        }
    }
    out
}

/// Runs a schema tool, failing with an install hint when it is missing.
fn validate(tool: &str, args: &[&str]) {
    let out = Command::new(tool)
        .args(args)
        .output()
        .unwrap_or_else(|e| panic!("cannot run {tool} ({e}); .ci/run installs it (pip)"));
    let all = format!("{}{}", String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr));
    assert!(out.status.success(), "{tool} {args:?} failed:\n{all}");
}

#[test]
fn deploy_files_pass_their_schemas() {
    let compose = [deploy("compose.yaml"), deploy("compose.distributed.yaml")];
    let compose: Vec<&str> = compose.iter().map(|p| common::path_str(p)).collect();
    validate("check-jsonschema", &[&["--builtin-schema", "vendor.compose-spec"], &compose[..]].concat());
    validate("kubernetes-validate", &["--strict", "--quiet", common::path_str(&deploy("kubernetes.yaml"))]);
}

/// The `MESHATLAS_*` variables `meshatlas ROLE --help` lists.
fn variables_of(role: &str) -> Vec<String> {
    let out = Command::new(env!("CARGO_BIN_EXE_meshatlas")).args([role, "--help"]).output().unwrap();
    assert!(out.status.success());
    let help = String::from_utf8_lossy(&out.stdout).into_owned();
    help.split("[env: ").skip(1).map(|s| s.split(['=', ']']).next().unwrap().to_string()).collect()
}

/// Variables the artifact store reads besides the `MESHATLAS_*` ones.
const AWS_VARIABLES: [&str; 4] = ["AWS_ENDPOINT_URL", "AWS_ACCESS_KEY_ID", "AWS_SECRET_ACCESS_KEY", "AWS_REGION"];

/// Variables every role reads outside its flags: the log filter.
const PROCESS_VARIABLES: [&str; 1] = ["MESHATLAS_LOG"];

#[test]
fn every_flag_and_variable_in_deploy_is_one_the_binary_takes() {
    let mut all = compose_containers("compose.yaml");
    all.extend(compose_containers("compose.distributed.yaml"));
    all.extend(kubernetes_containers());
    assert!(all.len() >= 5, "{all:#?}");
    for c in &all {
        let out = Command::new(env!("CARGO_BIN_EXE_meshatlas")).args(&c.args).arg("--help").output().unwrap();
        assert!(
            out.status.success(),
            "{}: `meshatlas {}` refused: {}",
            c.name,
            c.args.join(" "),
            String::from_utf8_lossy(&out.stderr)
        );
        let known = variables_of(&c.args[0]);
        for k in c.env.keys() {
            let ok = if k.starts_with("MESHATLAS_") {
                known.contains(k) || PROCESS_VARIABLES.contains(&k.as_str())
            } else {
                AWS_VARIABLES.contains(&k.as_str())
            };
            assert!(ok, "{}: `{k}` is not a variable `meshatlas {}` reads (it reads {known:?})", c.name, c.args[0]);
        }
        for (path, port) in &c.probes {
            assert_eq!(path, "/healthz", "{}: probe path", c.name);
            assert!(c.ports.contains_key(port), "{}: probe port {port} is not a container port {:?}", c.name, c.ports);
        }
    }
}

/// What the test servers give a topology instead of the file's hosts.
struct Loopback {
    store: String,
    artifacts: String,
    root: tempfile::TempDir,
}

impl Loopback {
    /// A fresh database and bucket prefix, or `None` without the servers
    /// (outside CI).
    fn new() -> Option<Loopback> {
        let Ok(_) = std::env::var("MESHATLAS_TEST_S3_ENDPOINT") else {
            assert!(std::env::var_os("CI").is_none(), "CI must set MESHATLAS_TEST_S3_ENDPOINT (see .ci/run)");
            eprintln!("MESHATLAS_TEST_S3_ENDPOINT is unset: deployment topology test skipped");
            return None;
        };
        let bucket = std::env::var("MESHATLAS_TEST_S3_BUCKET").unwrap_or_else(|_| "meshatlas".into());
        Some(Loopback {
            store: meshatlas::jobs::pg_store::test_database()?,
            artifacts: format!("s3://{bucket}/deploy_{}", uuid::Uuid::new_v4().simple()),
            root: tempfile::tempdir().unwrap(),
        })
    }

    /// The environment of replica `n` of `c`: the file's, with the
    /// database, bucket, S3 endpoint and credentials, addresses, data
    /// directory and mounted files swapped for this machine's.
    fn env_of(&self, c: &Container, n: usize) -> BTreeMap<String, String> {
        let dir = self.root.path().join(format!("{}-{n}", c.name));
        std::fs::create_dir_all(&dir).unwrap();
        let mut env = c.env.clone();
        for (k, v) in &mut env {
            match k.as_str() {
                "MESHATLAS_STORE" => {
                    assert!(v.starts_with("postgres://"), "{}: store {v}", c.name);
                    v.clone_from(&self.store);
                }
                "MESHATLAS_ARTIFACTS" => {
                    assert!(v.starts_with("s3://"), "{}: artifacts {v}", c.name);
                    v.clone_from(&self.artifacts);
                }
                "MESHATLAS_DATA_DIR" => *v = common::path_str(&dir.join("data")).to_string(),
                "MESHATLAS_ADDR" | "MESHATLAS_WORKER_ADDR" => *v = "127.0.0.1:0".into(),
                k if AWS_VARIABLES.contains(&k) => {
                    let ours = if k == "AWS_ENDPOINT_URL" { "MESHATLAS_TEST_S3_ENDPOINT" } else { k };
                    *v = std::env::var(ours).unwrap_or_else(|_| panic!("{ours} is unset (.ci/services.sh sets it)"));
                }
                _ => {
                    if let Some((path, _)) = c.files.iter().find(|(p, _)| p == v) {
                        let local = dir.join(Path::new(path).file_name().unwrap());
                        let (_, body) = c.files.iter().find(|(p, _)| p == path).unwrap();
                        std::fs::write(&local, body).unwrap();
                        *v = common::path_str(&local).to_string();
                    }
                }
            }
        }
        env
    }
}

/// A started replica: its process and base URL; killed on drop.
struct Replica {
    child: std::process::Child,
    base: String,
    role: String,
}

impl Drop for Replica {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// Starts every replica of `containers` on `lb`.
fn start(containers: &[Container], lb: &Loopback) -> Vec<Replica> {
    let mut out = Vec::new();
    for c in containers {
        for n in 0..c.replicas {
            let mut args = c.args.clone();
            if let Some(i) = args.iter().position(|a| a == "--addr") {
                args[i + 1] = "127.0.0.1:0".into();
            }
            let mut cmd = Command::new(env!("CARGO_BIN_EXE_meshatlas"));
            for (k, _) in std::env::vars() {
                if k.starts_with("MESHATLAS_") || k.starts_with("AWS_") {
                    cmd.env_remove(k);
                }
            }
            cmd.args(&args).envs(lb.env_of(c, n)).env("MESHATLAS_LOG", "warn").stderr(Stdio::inherit());
            let (child, base) = common::spawn_listening(cmd);
            out.push(Replica { child, base, role: c.args.join(" ") });
        }
    }
    out
}

/// A token the file gives the API, when it requires one.
fn token_of(containers: &[Container]) -> Option<String> {
    let api = containers.iter().find(|c| c.args[0] == "serve")?;
    let path = api.env.get("MESHATLAS_AUTH_TOKENS")?;
    let (_, body) = api.files.iter().find(|(p, _)| p == path)?;
    body.lines().find_map(|l| l.split_whitespace().next().filter(|t| !t.starts_with('#')).map(str::to_string))
}

/// Submits 6 jobs spread over the APIs of `containers`, each read back and
/// downloaded through another API; every process answers its probe path.
async fn run_topology(containers: &[Container]) {
    let Some(lb) = Loopback::new() else { return };
    let apis_expected: usize = containers.iter().filter(|c| c.args[0] == "serve").map(|c| c.replicas).sum();
    let workers_expected: usize = containers.iter().filter(|c| c.args[0] == "worker").map(|c| c.replicas).sum();
    assert_eq!((apis_expected, workers_expected), (2, 3), "2 API replicas and 3 workers: {containers:#?}");
    assert!(containers.iter().filter(|c| c.args[0] == "serve").all(|c| c.args.iter().any(|a| a == "--no-worker")));
    let procs = start(containers, &lb);
    let apis: Vec<&Replica> = procs.iter().filter(|p| p.role.starts_with("serve")).collect();
    let client = reqwest::Client::new();
    let auth = |r: reqwest::RequestBuilder| match token_of(containers) {
        Some(t) => r.bearer_auth(t),
        None => r,
    };
    let mut stl = Vec::new();
    meshatlas::io::stl_write::write_stl_binary(&mut stl, &meshatlas::mesh::fixtures::icosphere(2)).unwrap();
    let mut ids = Vec::new();
    for i in 0..6 {
        let url = format!("{}/v1/jobs?format=stl&stages=atlas", apis[i % 2].base);
        let r = auth(client.post(url)).body(stl.clone()).send().await.unwrap();
        assert_eq!(r.status(), 202, "{}", r.text().await.unwrap_or_default());
        ids.push(r.json::<Value>().await.unwrap()["id"].as_str().unwrap().to_string());
    }
    let start = Instant::now();
    for (i, id) in ids.iter().enumerate() {
        let other = apis[(i + 1) % 2];
        loop {
            let j: Value =
                auth(client.get(format!("{}/v1/jobs/{id}", other.base))).send().await.unwrap().json().await.unwrap();
            match j["state"].as_str() {
                Some("succeeded") => break,
                Some("failed" | "cancelled") => panic!("job {id}: {j:#}"),
                _ => {
                    assert!(start.elapsed() < Duration::from_secs(90), "job {id} not done: {j:#}");
                    tokio::time::sleep(Duration::from_millis(50)).await;
                }
            }
        }
        let r = auth(client.get(format!("{}/v1/jobs/{id}/artifacts/atlas.msh", other.base))).send().await.unwrap();
        assert_eq!(r.status(), 200);
        assert!(r.bytes().await.unwrap().starts_with(b"$MeshFormat"), "atlas.msh of job {id}");
    }
    for p in &procs {
        let r = client.get(format!("{}/healthz", p.base)).send().await.unwrap();
        assert_eq!(r.status(), 200, "{} at {}: {}", p.role, p.base, r.text().await.unwrap_or_default());
    }
}

#[tokio::test]
async fn the_distributed_compose_file_runs_jobs() {
    run_topology(&compose_containers("compose.distributed.yaml")).await;
}

#[tokio::test]
async fn the_kubernetes_manifests_run_jobs() {
    run_topology(&kubernetes_containers()).await;
}
