//! The JSON Schemas that `/api/v1/openapi.json` publishes for the job document and the result
//! agree with what the service parses and answers: every example scene validates, every object
//! of the document's schema lists exactly the fields that the parser allows there (so that a
//! field added to one and not the other fails here), documents the parser refuses for a reason
//! a schema can express are refused by the schema too, and real results validate.

use serde_json::{json, Value};
use wavrad::scene::{parse_value, Limits};

fn api() -> Value {
    serde_json::to_value(wavrad::server::openapi::document()).unwrap()
}

/// A validator of one component of the API document, with its references resolved in it.
fn validator(api: &Value, component: &str) -> jsonschema::Validator {
    let schema = json!({
        "$schema": "https://json-schema.org/draft/2020-12/schema",
        "$ref": format!("#/components/schemas/{component}"),
        "components": api["components"],
    });
    jsonschema::validator_for(&schema).unwrap()
}

fn errors(v: &jsonschema::Validator, doc: &Value) -> Vec<String> {
    v.iter_errors(doc)
        .map(|e| format!("{}: {e}", e.instance_path()))
        .collect()
}

fn examples() -> Vec<(String, Value)> {
    let scenes = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes");
    let mut out: Vec<(String, Value)> = [scenes.to_string(), format!("{scenes}/gallery")]
        .into_iter()
        .flat_map(|dir| std::fs::read_dir(dir).unwrap())
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "json"))
        .map(|p| {
            let text = std::fs::read_to_string(&p).unwrap();
            (
                p.file_name().unwrap().to_string_lossy().into_owned(),
                serde_json::from_str(&text).unwrap(),
            )
        })
        .collect();
    out.sort_by(|a, b| a.0.cmp(&b.0));
    assert!(out.len() >= 5, "the example scenes: {}", out.len());
    out
}

/// Documents that use every field the format has, each valid for the parser.
fn full_documents() -> Vec<Value> {
    vec![
        json!({
            "scene": {"kind": "flatland", "name": "every field", "surfaces": [
                {"name": "floor", "segment": [[0, 0], [1, 0]], "reflectance": [0.5, 0.4, 0.3],
                 "emission": 1.0, "emission_region": [0.25, 0.75]},
                {"name": "ceiling", "segment": [[1, 1], [0, 1]], "reflectance": 0.5}]},
            "solver": {"method": "projection", "basis": "wavelet", "order": 1, "resolution": 4,
                "keep": {"top": 10}, "iteration": "gauss-seidel", "tolerance": 1e-6,
                "max_iterations": 100, "quadrature": 4, "epsilon": 0.01},
            "output": {"image": {"width": 64, "height": 32, "exposure": 2.5, "raw": false,
                "mesh": false}, "grid": 4, "reference": {"order": 2, "resolution": 8},
                "coefficients": 16}
        }),
        json!({
            "scene": {"kind": "3d", "name": "box", "surfaces": [
                {"name": "floor", "corners": [[0, 0, 0], [0, 0, 1], [1, 0, 1], [1, 0, 0]],
                 "reflectance": 0.5, "emission": [1, 2, 3],
                 "emission_region": {"s": [0.4, 0.6], "t": [0.4, 0.6]}},
                {"name": "ceiling", "corners": [[0, 1, 0], [1, 1, 0], [1, 1, 1], [0, 1, 1]],
                 "reflectance": 0.5}]},
            "solver": {"method": "hierarchical", "resolution": 4, "keep": {"fraction": 0.5}},
            "output": {"image": {"exposure": "auto", "raw": true, "mesh": true},
                "camera": {"eye": [0.5, 0.5, 3], "look_at": [0.5, 0.5, 0], "up": [0, 1, 0],
                    "fov_deg": 50}}
        }),
        json!({
            "scene": {"kind": "fredholm", "name": "f", "domain": [0, 1], "kernel": "x*y",
                "source": "1", "exact": "1 + 3*x/4"},
            "solver": {"basis": "scaling", "resolution": 3, "keep": {"threshold": 0.001}},
            "output": {"reference": "exact"}
        }),
        json!({
            "scene": {"kind": "fredholm", "domain": [0, 1], "kernel": "x*y", "source": "1"},
            "solver": {"keep": "all"}
        }),
    ]
}

#[test]
fn every_example_scene_validates_against_the_published_schema() {
    let api = api();
    let v = validator(&api, "JobDocument");
    for (name, doc) in examples() {
        assert!(
            parse_value(&doc, &Limits::default()).is_ok(),
            "{name} parses"
        );
        let e = errors(&v, &doc);
        assert!(e.is_empty(), "{name}: {e:#?}");
        let typed: Result<wavrad::scene::schema::Document, _> = serde_json::from_value(doc);
        assert!(typed.is_ok(), "{name}: {:?}", typed.err());
    }
    for doc in full_documents() {
        if let Err(e) = parse_value(&doc, &Limits::default()) {
            panic!("the parser refuses {doc}: {e}");
        }
        let e = errors(&v, &doc);
        assert!(e.is_empty(), "{doc}: {e:#?}");
        let typed: Result<wavrad::scene::schema::Document, _> = serde_json::from_value(doc);
        assert!(typed.is_ok(), "{:?}", typed.err());
    }
}

/// The schema node that describes the value at `path` of `doc` (following `$ref`, and among
/// alternatives the one for this kind of value), or `None`.
fn resolve<'a>(api: &'a Value, mut node: &'a Value) -> &'a Value {
    while let Some(r) = node.get("$ref").and_then(Value::as_str) {
        let name = r.rsplit('/').next().unwrap();
        node = &api["components"]["schemas"][name];
    }
    node
}

fn types_of(node: &Value) -> Vec<String> {
    match &node["type"] {
        Value::String(s) => vec![s.clone()],
        Value::Array(a) => a
            .iter()
            .filter_map(|t| t.as_str().map(str::to_string))
            .collect(),
        _ => vec![],
    }
}

fn json_type(v: &Value) -> &'static str {
    match v {
        Value::Null => "null",
        Value::Bool(_) => "boolean",
        Value::Number(_) => "number",
        Value::String(_) => "string",
        Value::Array(_) => "array",
        Value::Object(_) => "object",
    }
}

/// Among `oneOf`/`anyOf` alternatives, the one that fits `value`: of its type and, for an
/// object, naming all of its fields (and its `kind`, when the alternative fixes one).
fn pick<'a>(api: &'a Value, node: &'a Value, value: &Value) -> &'a Value {
    let node = resolve(api, node);
    let alts = node
        .get("oneOf")
        .or_else(|| node.get("anyOf"))
        .and_then(Value::as_array);
    let Some(alts) = alts else { return node };
    let t = json_type(value);
    let fits = |alt: &&Value| {
        let alt = pick(api, alt, value);
        let types = types_of(alt);
        let type_ok = types.iter().any(|s| {
            s == t || (s == "integer" && t == "number") || (s == "number" && t == "number")
        });
        if !type_ok {
            return false;
        }
        if let (Some(obj), Some(props)) = (value.as_object(), alt["properties"].as_object()) {
            if !obj.keys().all(|k| props.contains_key(k)) {
                return false;
            }
            if let (Some(kind), Some(allowed)) = (
                obj.get("kind"),
                props.get("kind").and_then(|k| k["enum"].as_array()),
            ) {
                return allowed.contains(kind);
            }
        }
        true
    };
    let found: Vec<&Value> = alts.iter().filter(fits).collect();
    assert_eq!(found.len(), 1, "one alternative of {node} fits {value}");
    pick(api, found[0], value)
}

/// The fields that the schema allows in an object described by `node`: the picked
/// alternative's when the alternatives are kinds told apart by `kind` (the scene), else every
/// object alternative's (`keep` is one of `{"top"}`, `{"fraction"}`, `{"threshold"}`, as the
/// parser's one object of three fields of which exactly one is given).
fn allowed_by_schema(api: &Value, node: &Value, value: &Value, path: &str) -> Vec<String> {
    let outer = resolve(api, node);
    let picked = pick(api, node, value);
    let alts: Vec<&Value> = outer
        .get("oneOf")
        .and_then(Value::as_array)
        .map(|a| a.iter().map(|n| resolve(api, n)).collect())
        .unwrap_or_default();
    let objects: Vec<&Value> = alts
        .into_iter()
        .filter(|a| a["properties"].is_object())
        .collect();
    let kinds = objects.iter().any(|a| a["properties"]["kind"].is_object());
    let described = if objects.is_empty() || kinds {
        vec![picked]
    } else {
        objects
    };
    let mut fields: Vec<String> = Vec::new();
    for n in described {
        assert_eq!(
            n["additionalProperties"],
            json!(false),
            "{path}: the schema must refuse unknown fields as the parser does: {n}"
        );
        for k in n["properties"]
            .as_object()
            .unwrap_or_else(|| panic!("{path}: no properties in {n}"))
            .keys()
        {
            if !fields.contains(k) {
                fields.push(k.clone());
            }
        }
    }
    fields.sort();
    fields
}

/// Every object of `value` with the fields that the schema allows there: (JSON pointer,
/// fields).
fn objects(
    api: &Value,
    node: &Value,
    value: &Value,
    path: String,
    out: &mut Vec<(String, Vec<String>)>,
) {
    let fields = if value.is_object() {
        allowed_by_schema(api, node, value, &path)
    } else {
        Vec::new()
    };
    let node = pick(api, node, value);
    match value {
        Value::Object(map) => {
            out.push((path.clone(), fields));
            for (k, v) in map {
                let child = &node["properties"][k];
                assert!(!child.is_null(), "{path}/{k}: not in the schema {node}");
                objects(api, child, v, format!("{path}/{k}"), out);
            }
        }
        Value::Array(items) => {
            for (i, v) in items.iter().enumerate() {
                let child = if node["items"].is_null() {
                    &node["prefixItems"][i]
                } else {
                    &node["items"]
                };
                objects(api, child, v, format!("{path}/{i}"), out);
            }
        }
        _ => {}
    }
}

/// The fields the parser allows in the object at `path`: the list that its error for an
/// unknown field there gives.
fn allowed_by_parser(doc: &Value, path: &str) -> Vec<String> {
    let mut doc = doc.clone();
    let target = if path.is_empty() {
        &mut doc
    } else {
        doc.pointer_mut(path).unwrap()
    };
    target
        .as_object_mut()
        .unwrap()
        .insert("zz_not_a_field".into(), json!(1));
    let errors = parse_value(&doc, &Limits::default()).unwrap_err().0;
    let at = format!("{path}/zz_not_a_field");
    let e = errors
        .iter()
        .find(|e| e.path == at)
        .unwrap_or_else(|| panic!("no error at {at}: {errors:?}"));
    let list = e.message.split("expected one of: ").nth(1).unwrap();
    let mut fields: Vec<String> = list.split(", ").map(str::to_string).collect();
    fields.sort();
    fields
}

#[test]
fn every_object_of_the_schema_lists_the_fields_the_parser_allows() {
    let api = api();
    let root = json!({"$ref": "#/components/schemas/JobDocument"});
    let mut checked = 0;
    let docs: Vec<Value> = examples()
        .into_iter()
        .map(|(_, d)| d)
        .chain(full_documents())
        .collect();
    for doc in &docs {
        let mut found = Vec::new();
        objects(&api, &root, doc, String::new(), &mut found);
        for (path, props) in found {
            assert_eq!(props, allowed_by_parser(doc, &path), "{path} in {doc}");
            checked += 1;
        }
    }
    // the root, scene, surfaces, regions, solver, keep, output, image, camera, reference
    assert!(checked >= 40, "{checked} objects checked");
}

#[test]
fn the_schema_refuses_what_the_parser_refuses_for_a_reason_a_schema_can_say() {
    let api = api();
    let v = validator(&api, "JobDocument");
    let base = full_documents();
    // (document, pointer, new value)
    let cases: &[(usize, &str, Value)] = &[
        (0, "/solver", Value::Null),
        (0, "/output", Value::Null),
        (0, "/scene/kind", json!("4d")),
        (0, "/scene/surfaces", json!([])),
        (0, "/scene/surfaces/0/reflectance", json!(1.0)),
        (0, "/scene/surfaces/0/reflectance", json!([0.5, 0.5])),
        (0, "/scene/surfaces/0/reflectance/1", json!(-0.1)),
        (0, "/scene/surfaces/0/emission", json!(-1)),
        (0, "/scene/surfaces/0/emission", json!("bright")),
        (0, "/scene/surfaces/0/emission_region", json!([0.5, 1.5])),
        (0, "/scene/surfaces/0/segment", json!([[0, 0]])),
        (0, "/scene/surfaces/0/segment/1", json!([1, 0, 0])),
        (0, "/scene/surfaces/0/name", json!("")),
        (0, "/scene/surfaces/0/name", json!("a/b")),
        (0, "/scene/surfaces/0/name", json!("x".repeat(129))),
        (0, "/solver/method", json!("direct")),
        (0, "/solver/basis", json!("haar")),
        (0, "/solver/order", json!(-1)),
        (0, "/solver/order", json!(1.5)),
        (0, "/solver/order", json!(16)),
        (0, "/solver/resolution", json!(0)),
        (0, "/solver/keep", json!({"top": 0})),
        (0, "/solver/keep", json!({"top": 1, "fraction": 0.5})),
        (0, "/solver/keep", json!("some")),
        (0, "/solver/iteration", json!("sor")),
        (0, "/solver/tolerance", json!(0)),
        (0, "/solver/tolerance", json!(1)),
        (0, "/solver/max_iterations", json!(0)),
        (0, "/solver/quadrature", json!(65)),
        (0, "/solver/epsilon", json!(-0.5)),
        (0, "/output/image/width", json!(0)),
        (0, "/output/image/height", json!(16385)),
        (0, "/output/image/exposure", json!(0)),
        (0, "/output/image/exposure", json!("dark")),
        (0, "/output/image/raw", json!("yes")),
        (0, "/output/grid", json!(0)),
        (0, "/output/reference", json!("approximate")),
        (0, "/output/reference", json!({"order": 2})),
        (0, "/output/coefficients", json!(100_001)),
        (
            1,
            "/scene/surfaces/0/corners",
            json!([[0, 0, 0], [1, 0, 0], [1, 0, 1]]),
        ),
        (1, "/scene/surfaces/0/emission_region", json!({"s": [0, 1]})),
        (1, "/output/camera/fov_deg", json!(180)),
        (1, "/output/camera", json!({"eye": [0, 0, 1]})),
        (2, "/scene/domain", json!([0])),
        (2, "/scene/kernel", json!(2)),
        (2, "/scene/exact", Value::Null),
    ];
    for (i, pointer, value) in cases {
        let mut doc = base[*i].clone();
        *doc.pointer_mut(pointer).unwrap() = value.clone();
        assert!(
            parse_value(&doc, &Limits::default()).is_err(),
            "the parser takes {pointer} = {value}"
        );
        assert!(!v.is_valid(&doc), "the schema takes {pointer} = {value}");
    }
    // and a field that neither knows
    let mut doc = base[1].clone();
    doc["scene"]["surfaces"][1]["colour"] = json!("red");
    assert!(parse_value(&doc, &Limits::default()).is_err());
    assert!(!v.is_valid(&doc));
    // nor a document without a scene
    assert!(!v.is_valid(&json!({"solver": {}})));
}

#[test]
fn results_validate_against_the_published_result_schema() {
    let api = api();
    let v = validator(&api, "JobResult");
    let limits = Limits::default();
    let mut docs: Vec<Value> = examples()
        .into_iter()
        .filter(|(name, _)| name.starts_with("flatland") || name.starts_with("fredholm"))
        .map(|(_, d)| d)
        .collect();
    docs.extend(full_documents());
    // a hierarchical flatland solve carries its link counts
    docs.push(json!({
        "scene": {"kind": "flatland", "surfaces": [
            {"name": "a", "segment": [[0, 0], [1, 0]], "reflectance": 0.5, "emission": 1},
            {"name": "b", "segment": [[1, 1], [0, 1]], "reflectance": 0.5}]},
        "solver": {"method": "hierarchical", "resolution": 8}
    }));
    for doc in docs {
        let job = parse_value(&doc, &limits).unwrap();
        let outcome = wavrad::job::run(&job, &wavrad::progress::Silent).unwrap();
        let result = serde_json::to_value(&outcome.result).unwrap();
        let e = errors(&v, &result);
        assert!(e.is_empty(), "{}: {e:#?}", doc["scene"]["kind"]);
        // and the schema is not empty: a result without surfaces is refused
        let mut broken = result.clone();
        broken.as_object_mut().unwrap().remove("surfaces");
        assert!(!v.is_valid(&broken));
    }
}
