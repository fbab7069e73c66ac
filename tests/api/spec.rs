//! The served routes and `api/openapi.yaml` agree.

use std::collections::BTreeSet;

use yaml_rust2::{Yaml, YamlLoader};

const METHODS: &[&str] = &["get", "put", "post", "delete", "patch", "head", "options", "trace"];

fn spec() -> Yaml {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/api/openapi.yaml");
    let text = std::fs::read_to_string(path).unwrap();
    YamlLoader::load_from_str(&text).unwrap().remove(0)
}

#[test]
fn served_routes_and_spec_paths_agree() {
    let doc = spec();
    assert_eq!(doc["openapi"].as_str(), Some("3.1.0"));
    let mut in_spec = BTreeSet::new();
    let paths = doc["paths"].as_hash().expect("paths");
    for (path, item) in paths {
        let path = path.as_str().unwrap();
        for (k, op) in item.as_hash().unwrap() {
            let k = k.as_str().unwrap();
            if METHODS.contains(&k) {
                in_spec.insert((k.to_uppercase(), path.to_string()));
                assert!(op["operationId"].as_str().is_some(), "{k} {path} has no operationId");
                assert!(!op["responses"].is_badvalue(), "{k} {path} has no responses");
            }
        }
        // Every `{param}` of the path is declared.
        let declared: BTreeSet<String> = item["parameters"]
            .as_vec()
            .map(|v| v.iter().map(|p| resolve(&doc, p)["name"].as_str().unwrap().to_string()).collect())
            .unwrap_or_default();
        for seg in path.split('/').filter(|s| s.starts_with('{')) {
            let name = seg.trim_matches(|c| c == '{' || c == '}');
            assert!(declared.contains(name), "{path}: path parameter `{name}` not declared");
        }
    }
    let served: BTreeSet<(String, String)> =
        meshatlas::http::routes().iter().map(|r| (r.method.to_string(), r.path.to_string())).collect();
    assert_eq!(served, in_spec, "served routes (left) differ from api/openapi.yaml (right)");
}

/// Follows a local `$ref`.
fn resolve<'a>(doc: &'a Yaml, node: &'a Yaml) -> &'a Yaml {
    match node["$ref"].as_str() {
        Some(r) => {
            let mut cur = doc;
            for part in r.trim_start_matches("#/").split('/') {
                cur = &cur[part];
            }
            cur
        }
        None => node,
    }
}

#[test]
fn every_error_response_is_problem_json_and_every_kind_is_documented() {
    let doc = spec();
    for (name, resp) in doc["components"]["responses"].as_hash().unwrap() {
        assert!(
            !resp["content"]["application/problem+json"].is_badvalue(),
            "response {} is not problem+json",
            name.as_str().unwrap()
        );
    }
    let problem_doc = doc["components"]["schemas"]["Problem"]["description"].as_str().unwrap().to_string()
        + doc["components"]["schemas"]["JobProblem"]["description"].as_str().unwrap();
    for kind in meshatlas::failure::FailureKind::ALL {
        assert!(problem_doc.contains(&format!("`{kind}`")), "problem kind `{kind}` is not documented in the spec");
    }
}

/// Property names of the schema `name` in the spec.
fn schema_properties(doc: &Yaml, name: &str) -> BTreeSet<String> {
    doc["components"]["schemas"][name]["properties"]
        .as_hash()
        .unwrap_or_else(|| panic!("schema {name} has no properties"))
        .keys()
        .map(|k| k.as_str().unwrap().to_string())
        .collect()
}

/// Field names of a serialized default value.
fn fields(value: serde_json::Value) -> BTreeSet<String> {
    value.as_object().expect("object").keys().cloned().collect()
}

#[test]
fn option_schemas_list_exactly_the_option_fields() {
    let doc = spec();
    let cases = [
        ("PipelineParams", fields(serde_json::to_value(meshatlas::pipeline::PipelineParams::default()).unwrap())),
        ("LoadOptions", fields(serde_json::to_value(meshatlas::io::LoadOptions::default()).unwrap())),
        ("AtlasOptions", fields(serde_json::to_value(meshatlas::atlas::AtlasOptions::default()).unwrap())),
        ("FramesOptions", fields(serde_json::to_value(meshatlas::frames::FramesOptions::default()).unwrap())),
        ("QuadsOptions", fields(serde_json::to_value(meshatlas::quads::QuadsOptions::default()).unwrap())),
        ("OutputOptions", fields(serde_json::to_value(meshatlas::io::msh_output::OutputOptions::default()).unwrap())),
        (
            "CrossfieldOptions",
            fields(serde_json::to_value(meshatlas::crossfield::CrossfieldOptions::default()).unwrap()),
        ),
    ];
    for (schema, code) in cases {
        assert_eq!(schema_properties(&doc, schema), code, "schema {schema} (left) differs from the code (right)");
    }
    let stages: BTreeSet<String> =
        doc["components"]["schemas"]["PipelineParams"]["properties"]["stages"]["items"]["enum"]
            .as_vec()
            .unwrap()
            .iter()
            .map(|s| s.as_str().unwrap().to_string())
            .collect();
    for s in meshatlas::pipeline::StageName::ALL {
        assert!(stages.contains(s.as_str()), "stage {} missing from the spec", s.as_str());
    }
}

/// Operations by `operationId`, with their path item.
fn operations(doc: &Yaml) -> Vec<(String, &Yaml, &Yaml)> {
    let mut ops = Vec::new();
    for (_, item) in doc["paths"].as_hash().unwrap() {
        for (k, op) in item.as_hash().unwrap() {
            if METHODS.contains(&k.as_str().unwrap()) {
                ops.push((op["operationId"].as_str().unwrap().to_string(), op, item));
            }
        }
    }
    ops
}

/// Names of the parameters of an operation (its own and its path item's).
fn parameter_names(doc: &Yaml, op: &Yaml, item: &Yaml) -> BTreeSet<String> {
    [&item["parameters"], &op["parameters"]]
        .into_iter()
        .filter_map(Yaml::as_vec)
        .flatten()
        .map(|p| resolve(doc, p)["name"].as_str().unwrap().to_string())
        .collect()
}

#[test]
fn links_lead_from_a_new_job_to_the_job_its_artifacts_cancel_and_delete() {
    let doc = spec();
    let ops = operations(&doc);
    let mut reached = BTreeSet::new();
    for (id, op, _) in &ops {
        for (status, resp) in op["responses"].as_hash().unwrap() {
            let Some(links) = resolve(&doc, resp)["links"].as_hash() else { continue };
            for (name, link) in links {
                let target = link["operationId"].as_str().unwrap();
                let (_, top, titem) = ops
                    .iter()
                    .find(|(o, _, _)| o == target)
                    .unwrap_or_else(|| panic!("{id} {status:?} link {name:?}: no operation `{target}`"));
                let declared = parameter_names(&doc, top, titem);
                for (param, expr) in link["parameters"].as_hash().unwrap() {
                    let param = param.as_str().unwrap();
                    assert!(declared.contains(param), "link {name:?} to {target}: no parameter `{param}`");
                    assert!(expr.as_str().unwrap().starts_with("$response.body#/"), "link {name:?}: {expr:?}");
                }
                reached.insert((id.clone(), target.to_string()));
            }
        }
    }
    for target in ["getJob", "cancelJob", "deleteJob"] {
        assert!(reached.contains(&("submitJob".into(), target.into())), "no link from submitJob to {target}");
    }
    assert!(reached.contains(&("getJob".into(), "getArtifact".into())), "no link from getJob to getArtifact");
}
