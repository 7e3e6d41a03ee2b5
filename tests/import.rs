//! Model import (`src/import/`, `POST /api/v1/import`): the Cornell box written by an
//! independent writer (trimesh, `tests/fixtures/import/make.py`) as OBJ + MTL, `.gltf` (data
//! URI and separate `.bin`) and GLB imports to the surfaces, areas, fronts, reflectances and
//! emissions of `scenes/cornell-box.json`; the example room imports whole with its lights;
//! every error of the contract comes with its status and where; warnings are said.

// Per-channel loops index several arrays by the same subscript.
#![allow(clippy::needless_range_loop)]

mod common;
mod support;

use axum::body::{Body, Bytes};
use axum::http::{header, HeaderMap, Request, StatusCode};
use axum::Router;
use serde_json::{json, Value};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use support::{import_file, surface_names};
use tower::ServiceExt;
use wavrad::import::{import, Format, ImportError, Imported, Location, Model};
use wavrad::scene::Limits;

fn fixtures() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/import")
}

/// Imports bytes with the given extra files.
fn import_bytes(
    file: &str,
    bytes: &[u8],
    extra: &[(&str, &[u8])],
) -> Result<Imported, ImportError> {
    let extra: Vec<(String, Vec<u8>)> = extra
        .iter()
        .map(|(n, b)| (n.to_string(), b.to_vec()))
        .collect();
    let files = move |name: &str| {
        extra
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, b)| b.clone())
    };
    let model = Model {
        file,
        format: Format::from_file_name(file).unwrap(),
        bytes,
    };
    import(model, &files, &Limits::default())
}

type V3 = [f64; 3];

fn v3(v: &Value) -> V3 {
    let a = v.as_array().unwrap();
    [0, 1, 2].map(|i| a[i].as_f64().unwrap())
}

fn sub(a: V3, b: V3) -> V3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn cross(a: V3, b: V3) -> V3 {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

fn norm(a: V3) -> f64 {
    (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt()
}

/// What the comparison needs of a surface: area, vector area (∑ area × front normal: the
/// fronts), reflectance, emission.
#[derive(Debug, Clone, Copy, Default)]
struct Summary {
    area: f64,
    vector_area: V3,
    reflectance: V3,
    emission: V3,
}

fn add_to(s: &mut Summary, doubled: V3) {
    s.area += norm(doubled) / 2.0;
    for c in 0..3 {
        s.vector_area[c] += doubled[c] / 2.0;
    }
}

/// The hand-written Cornell box, by the objects the fixtures group its surfaces into (the
/// five faces of a block are one object).
fn cornell_by_object() -> BTreeMap<String, Summary> {
    let doc = common::scene("cornell-box");
    let mut out: BTreeMap<String, Summary> = BTreeMap::new();
    for s in doc["scene"]["surfaces"].as_array().unwrap() {
        let name = s["name"].as_str().unwrap();
        let object = if let Some(b) = ["tall", "short"]
            .into_iter()
            .find(|b| name.starts_with(&format!("{b}-")))
        {
            format!("{b}-block")
        } else {
            name.to_string()
        };
        let c: Vec<V3> = s["corners"].as_array().unwrap().iter().map(v3).collect();
        let e = out.entry(object).or_default();
        // as the fixtures split it: (p0 p1 p2) and (p0 p2 p3) with p2 as written (the
        // document's corners hold p0 + p2 = p1 + p3 to 1e-6 of the size, so |e1 × e3| would
        // differ from these two triangles by some 1e-8 of the area)
        add_to(e, cross(sub(c[1], c[0]), sub(c[2], c[0])));
        add_to(e, cross(sub(c[2], c[0]), sub(c[3], c[0])));
        e.reflectance = v3(&s["reflectance"]);
        e.emission = s.get("emission").map_or([0.0; 3], v3);
    }
    out
}

/// An imported document's surfaces, summarised, checking the mesh surface's exact shape.
fn imported_by_surface(doc: &Value) -> BTreeMap<String, Summary> {
    assert_eq!(doc["scene"]["kind"], "3d");
    assert_eq!(doc["solver"], json!({"method": "hierarchical"}));
    assert_eq!(doc["output"], json!({}));
    let mut keys: Vec<&String> = doc.as_object().unwrap().keys().collect();
    keys.sort();
    assert_eq!(keys, ["output", "scene", "solver"]);
    let mut out = BTreeMap::new();
    for s in doc["scene"]["surfaces"].as_array().unwrap() {
        let mut keys: Vec<&String> = s.as_object().unwrap().keys().collect();
        keys.sort();
        assert_eq!(keys, ["emission", "mesh", "name", "reflectance"]);
        let mesh = &s["mesh"];
        assert_eq!(mesh.as_object().unwrap().len(), 2);
        let p: Vec<V3> = mesh["positions"]
            .as_array()
            .unwrap()
            .iter()
            .map(v3)
            .collect();
        let mut used = vec![false; p.len()];
        let mut summary = Summary {
            reflectance: v3(&s["reflectance"]),
            emission: v3(&s["emission"]),
            ..Default::default()
        };
        for t in mesh["triangles"].as_array().unwrap() {
            let t: Vec<usize> = t
                .as_array()
                .unwrap()
                .iter()
                .map(|i| i.as_u64().unwrap() as usize)
                .collect();
            assert_eq!(t.len(), 3);
            for &i in &t {
                used[i] = true;
            }
            add_to(
                &mut summary,
                cross(sub(p[t[1]], p[t[0]]), sub(p[t[2]], p[t[0]])),
            );
        }
        assert!(used.iter().all(|u| *u), "every position is used");
        out.insert(s["name"].as_str().unwrap().to_string(), summary);
    }
    out
}

/// The imported Cornell box against the hand-written one: areas and fronts within `tolerance`
/// relative to each object's area, reflectances and emissions within `tolerance` relative
/// (absolute below 1).
fn assert_cornell(imported: &Imported, tolerance: f64) {
    assert!(imported.warnings.is_empty(), "{:?}", imported.warnings);
    let want = cornell_by_object();
    let got = imported_by_surface(&imported.document);
    assert_eq!(
        got.keys().collect::<Vec<_>>(),
        want.keys().collect::<Vec<_>>()
    );
    for (name, w) in &want {
        let g = got[name];
        assert!(
            (g.area - w.area).abs() <= tolerance * w.area,
            "{name}: area {} against {}",
            g.area,
            w.area
        );
        assert!(
            norm(sub(g.vector_area, w.vector_area)) <= tolerance * w.area,
            "{name}: fronts {:?} against {:?}",
            g.vector_area,
            w.vector_area
        );
        for c in 0..3 {
            let close = |a: f64, b: f64| (a - b).abs() <= tolerance * b.abs().max(1.0);
            assert!(
                close(g.reflectance[c], w.reflectance[c]),
                "{name}: {:?}",
                g.reflectance
            );
            assert!(
                close(g.emission[c], w.emission[c]),
                "{name}: {:?}",
                g.emission
            );
        }
    }
    assert_eq!(imported.triangles, 16 * 2);
}

#[test]
fn the_cornell_box_as_obj_and_mtl_imports_to_the_hand_written_document() {
    let imported = import_file(&fixtures().join("cornell-box.obj")).unwrap();
    assert_eq!(imported.document["scene"]["name"], "cornell-box");
    assert_cornell(&imported, 1e-9);
}

// glTF positions are 32-bit floats (glTF 2.0, 3.7.2.1), and the gltf crate reads node matrices
// and material factors as such: everything holds to 1e-6 (relative) instead of 1e-9.
#[test]
fn the_cornell_box_as_glb_imports_with_its_node_hierarchy() {
    assert_cornell(
        &import_file(&fixtures().join("cornell-box.glb")).unwrap(),
        1e-6,
    );
}

#[test]
fn the_cornell_box_as_gltf_with_a_data_uri_imports() {
    assert_cornell(
        &import_file(&fixtures().join("cornell-box.gltf")).unwrap(),
        1e-6,
    );
}

#[test]
fn the_cornell_box_as_gltf_with_its_bin_imports() {
    assert_cornell(
        &import_file(&fixtures().join("cornell-box-split.gltf")).unwrap(),
        1e-6,
    );
}

#[test]
fn the_example_room_imports_whole_with_its_lamp_and_window_as_lights() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/models/room.obj");
    let faces = std::fs::read_to_string(&path)
        .unwrap()
        .lines()
        .filter(|l| l.starts_with("f "))
        .count();
    let imported = import_file(&path).unwrap();
    assert!(imported.warnings.is_empty(), "{:?}", imported.warnings);
    assert_eq!(imported.triangles, faces);
    assert!((10_000..=13_000).contains(&faces), "{faces} triangles");
    let surfaces = imported.document["scene"]["surfaces"].as_array().unwrap();
    assert_eq!(surfaces.len(), imported.surfaces);
    assert!(surfaces.len() <= 64, "within the server's max_surfaces");
    let emitters: Vec<&str> = surfaces
        .iter()
        .filter(|s| v3(&s["emission"]).iter().any(|e| *e > 0.0))
        .map(|s| s["name"].as_str().unwrap())
        .collect();
    assert_eq!(emitters, ["window", "lamp-shade"]);
    // an object of two materials is two surfaces, named after both
    let names = surface_names(&imported.document);
    for name in [
        "chair-1-beech",
        "chair-1-fabric-blue",
        "books-book-red",
        "table",
    ] {
        assert!(names.contains(&name), "{name} in {names:?}");
    }
}

const QUAD_OBJ: &str = "o quad\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n";

#[test]
fn polygons_are_triangulated_and_a_model_without_light_says_so() {
    let imported = import_bytes("quad.obj", QUAD_OBJ.as_bytes(), &[]).unwrap();
    assert_eq!(imported.triangles, 2);
    let s = &imported.document["scene"]["surfaces"][0];
    assert_eq!(s["name"], "quad");
    assert_eq!(s["reflectance"], json!([0.5, 0.5, 0.5]));
    assert!(
        imported
            .warnings
            .iter()
            .any(|w| w.contains("will need a light")),
        "{:?}",
        imported.warnings
    );
    assert!(imported
        .warnings
        .iter()
        .any(|w| w.contains("has no material")));
}

#[test]
fn reflectance_is_clamped_below_one_and_zero_area_triangles_are_dropped_with_warnings() {
    let obj = "mtllib m.mtl\no a\nusemtl white\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 2 0 0\n\
               f 1 2 3\nf 1 2 4\nf 1 1 3\no a\nusemtl lamp\nf 3 2 1\n";
    let mtl = "newmtl white\nKd 1 1.2 0.5\nnewmtl lamp\nKd 0 0 0\nKe 3 2 1\n";
    let imported = import_bytes("m.obj", obj.as_bytes(), &[("m.mtl", mtl.as_bytes())]).unwrap();
    let surfaces = imported.document["scene"]["surfaces"].as_array().unwrap();
    // one object in two materials: two surfaces, named after both
    assert_eq!(surfaces[0]["name"], "a-white");
    assert_eq!(surfaces[1]["name"], "a-lamp");
    assert_eq!(surfaces[0]["reflectance"], json!([0.99, 0.99, 0.5]));
    assert_eq!(surfaces[1]["emission"], json!([3.0, 2.0, 1.0]));
    // the collinear (1 2 4) and repeated (1 1 3) triangles are gone, and so is position 4
    assert_eq!(surfaces[0]["mesh"]["triangles"], json!([[0, 1, 2]]));
    assert_eq!(
        surfaces[0]["mesh"]["positions"].as_array().unwrap().len(),
        3
    );
    let w = &imported.warnings;
    assert!(
        w.iter().any(|w| w.contains("clamped to [0.99, 0.99, 0.5]")),
        "{w:?}"
    );
    assert!(
        w.iter()
            .any(|w| w.contains("2 triangle(s) of zero area dropped")),
        "{w:?}"
    );
    assert!(!w.iter().any(|w| w.contains("need a light")), "{w:?}");
}

#[test]
fn duplicate_names_get_a_suffix_and_materials_may_be_in_the_obj_itself() {
    let obj = "newmtl glow\nKd 0.2 0.2 0.2\nKe 1 1 1\n\
               o a\nusemtl glow\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\no b\nf 1 3 2\no a\nf 2 3 1\n";
    let imported = import_bytes("x.obj", obj.as_bytes(), &[]).unwrap();
    assert_eq!(surface_names(&imported.document), ["a", "b", "a-2"]);
    assert_eq!(
        imported.document["scene"]["surfaces"][0]["emission"],
        json!([1.0, 1.0, 1.0])
    );
    assert!(imported.warnings.iter().any(|w| w.contains("given twice")));
}

#[test]
fn a_missing_mtl_is_a_warning() {
    let obj = format!("mtllib gone.mtl\n{QUAD_OBJ}");
    let imported = import_bytes("q.obj", obj.as_bytes(), &[]).unwrap();
    assert!(
        imported
            .warnings
            .iter()
            .any(|w| w.contains("\"gone.mtl\" was not given")),
        "{:?}",
        imported.warnings
    );
}

fn assert_at(e: ImportError, file: &str, location: Location) {
    assert_eq!((e.file.as_str(), &e.location), (file, &location), "{e}");
}

#[test]
fn broken_obj_and_mtl_files_say_the_line() {
    let bad = |text: &[u8]| import_bytes("b.obj", text, &[]).unwrap_err();
    assert_at(
        bad(b"v 0 0 0\nv 1 0 0\nv 0 x 0\nf 1 2 3\n"),
        "b.obj",
        Location::Line(3),
    );
    // a face naming a vertex that is not there
    assert_at(
        bad(b"v 0 0 0\nv 1 0 0\nv 0 1 0\n# c\nf 1 2 9\n"),
        "b.obj",
        Location::Line(5),
    );
    assert_at(bad(b"v 0 0 0\nf 1 2 x\n"), "b.obj", Location::Line(2));
    // not UTF-8
    assert_at(
        bad(b"v 0 0 0\nv 1 0 0\nv 0 1 0\no \xff\xfe\nf 1 2 3\n"),
        "b.obj",
        Location::Line(4),
    );
    // a position that is not finite
    assert_at(
        bad(b"v 0 0 0\nv 1 0 0\nv 0 inf 0\nf 1 2 3\n"),
        "b.obj",
        Location::Line(3),
    );
    // no triangles at all: the model as a whole
    assert_at(bad(b"v 0 0 0\nv 1 0 0\n"), "b.obj", Location::Whole);
    assert_at(
        bad(b"v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n"),
        "b.obj",
        Location::Whole,
    );
    // the MTL is at fault: its own name and line
    let obj = format!("mtllib m.mtl\n{QUAD_OBJ}");
    let e = import_bytes(
        "q.obj",
        obj.as_bytes(),
        &[("m.mtl", b"newmtl a\nKd 1 1 1\nKd 0.5 zero\n")],
    )
    .unwrap_err();
    assert_at(e, "m.mtl", Location::Line(3));
}

fn fixture_gltf() -> Value {
    serde_json::from_slice(&std::fs::read(fixtures().join("cornell-box.gltf")).unwrap()).unwrap()
}

fn gltf_error(doc: &Value) -> ImportError {
    import_bytes("m.gltf", doc.to_string().as_bytes(), &[]).unwrap_err()
}

#[test]
fn broken_gltf_files_say_the_json_path() {
    let pointer = |p: &str| Location::Pointer(p.to_string());
    // an accessor that does not exist
    let mut doc = fixture_gltf();
    doc["meshes"][2]["primitives"][0]["indices"] = json!(999);
    assert_at(
        gltf_error(&doc),
        "m.gltf",
        pointer("/meshes/2/primitives/0/indices"),
    );
    // a buffer that was not given
    let mut doc = fixture_gltf();
    doc["buffers"][0]["uri"] = json!("elsewhere.bin");
    assert_at(gltf_error(&doc), "m.gltf", pointer("/buffers/0/uri"));
    // a buffer shorter than it says
    let mut doc = fixture_gltf();
    doc["buffers"][0]["uri"] = json!("data:application/octet-stream;base64,AAAA");
    assert_at(gltf_error(&doc), "m.gltf", pointer("/buffers/0"));
    // a data URI that is not base64
    let mut doc = fixture_gltf();
    doc["buffers"][0]["uri"] = json!("data:application/octet-stream;base64,***");
    assert_at(gltf_error(&doc), "m.gltf", pointer("/buffers/0/uri"));
    // a buffer view past its buffer
    let mut doc = fixture_gltf();
    doc["bufferViews"][1]["byteOffset"] = json!(1_000_000);
    assert_at(gltf_error(&doc), "m.gltf", pointer("/bufferViews/1"));
    // an index past the positions
    let mut doc = fixture_gltf();
    let positions = doc["meshes"][0]["primitives"][0]["attributes"]["POSITION"]
        .as_u64()
        .unwrap() as usize;
    doc["accessors"][positions]["count"] = json!(2);
    assert_at(
        gltf_error(&doc),
        "m.gltf",
        pointer("/meshes/0/primitives/0/indices"),
    );
    // not JSON: the line
    assert_at(
        import_bytes(
            "m.gltf",
            b"{\n  \"asset\": {\"version\": \"2.0\"},\n  oops\n}",
            &[],
        )
        .unwrap_err(),
        "m.gltf",
        Location::Line(3),
    );
    // a cut GLB
    let glb = std::fs::read(fixtures().join("cornell-box.glb")).unwrap();
    let e = import_bytes("m.glb", &glb[..glb.len() / 2], &[]).unwrap_err();
    assert_eq!(e.location, Location::Whole, "{e}");
    assert!(e.message.contains("GLB"), "{e}");
}

#[test]
fn mirroring_transforms_keep_the_fronts_and_texture_means_scale_the_base_colour() {
    // the floor, mirrored in x by its node: its front must still face up (+y)
    let mut doc = fixture_gltf();
    doc["nodes"][1]["matrix"] = json!([-1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 555, 0, 0, 1]);
    // a 2 x 1 texture, black and sRGB 188 (0.5 linear): mean 0.25 linear
    let mut png = Vec::new();
    image::RgbImage::from_raw(2, 1, vec![0, 0, 0, 188, 188, 188])
        .unwrap()
        .write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
        .unwrap();
    use base64::Engine;
    let uri = format!(
        "data:image/png;base64,{}",
        base64::engine::general_purpose::STANDARD.encode(&png)
    );
    doc["images"] = json!([{"uri": uri}]);
    doc["textures"] = json!([{"source": 0}]);
    doc["materials"][0]["pbrMetallicRoughness"]["baseColorTexture"] = json!({"index": 0});
    let imported = import_bytes("m.gltf", doc.to_string().as_bytes(), &[]).unwrap();
    let got = imported_by_surface(&imported.document);
    let floor = got["floor"];
    assert!(
        floor.vector_area[1] > 0.0 && (floor.vector_area[1] - floor.area).abs() < 1e-6 * floor.area
    );
    let linear_188 = ((188.0 / 255.0 + 0.055) / 1.055f64).powf(2.4);
    for c in 0..3 {
        assert!(
            (floor.reflectance[c] - 0.73 * linear_188 / 2.0).abs() < 1e-6,
            "{:?}",
            floor.reflectance
        );
    }
}

// ---- through HTTP ----

async fn call(app: &Router, req: Request<Body>) -> (StatusCode, HeaderMap, Bytes) {
    let res = app.clone().oneshot(req).await.unwrap();
    let (parts, body) = res.into_parts();
    let bytes = axum::body::to_bytes(body, usize::MAX).await.unwrap();
    (parts.status, parts.headers, bytes)
}

fn post(content_type: &str, body: impl Into<Body>) -> Request<Body> {
    Request::post("/api/v1/import")
        .header(header::CONTENT_TYPE, content_type)
        .body(body.into())
        .unwrap()
}

const BOUNDARY: &str = "wavrad-test-boundary";

fn multipart(parts: &[(&str, &[u8])]) -> Request<Body> {
    let mut body = Vec::new();
    for (name, bytes) in parts {
        body.extend_from_slice(
            format!(
                "--{BOUNDARY}\r\nContent-Disposition: form-data; name=\"file\"; filename=\"{name}\"\r\nContent-Type: application/octet-stream\r\n\r\n"
            )
            .as_bytes(),
        );
        body.extend_from_slice(bytes);
        body.extend_from_slice(b"\r\n");
    }
    body.extend_from_slice(format!("--{BOUNDARY}--\r\n").as_bytes());
    post(&format!("multipart/form-data; boundary={BOUNDARY}"), body)
}

fn setup(f: impl FnOnce(&mut wavrad::server::Config)) -> (tempfile::TempDir, Router) {
    let dir = tempfile::tempdir().unwrap();
    let mut c = common::config(dir.path());
    f(&mut c);
    let router = wavrad::server::app(common::state(c));
    (dir, router)
}

fn problem(st: StatusCode, h: &HeaderMap, b: &Bytes, expected: StatusCode) -> Value {
    assert_eq!(st, expected, "{}", String::from_utf8_lossy(b));
    assert_eq!(h[header::CONTENT_TYPE], "application/problem+json");
    let p: Value = serde_json::from_slice(b).unwrap();
    assert_eq!(p["status"], expected.as_u16());
    p
}

fn fixture(name: &str) -> Vec<u8> {
    std::fs::read(fixtures().join(name)).unwrap()
}

#[tokio::test(flavor = "multi_thread")]
async fn every_model_type_imports_over_http_as_the_library_does() {
    // the room's document is larger than max_body_bytes: the import route has its own limit
    let (_dir, router) = setup(|c| c.max_body_bytes = 64 * 1024);
    let library = |name: &str| import_file(&fixtures().join(name)).unwrap().document;
    let cases = [
        (
            multipart(&[
                ("cornell-box.obj", &fixture("cornell-box.obj")),
                ("cornell-box.mtl", &fixture("cornell-box.mtl")),
            ]),
            "cornell-box.obj",
        ),
        (
            multipart(&[
                ("cornell-box-split.bin", &fixture("cornell-box-split.bin")),
                ("cornell-box-split.gltf", &fixture("cornell-box-split.gltf")),
            ]),
            "cornell-box-split.gltf",
        ),
        (
            post("model/gltf-binary", fixture("cornell-box.glb")),
            "cornell-box.glb",
        ),
        (
            post("model/gltf+json", fixture("cornell-box.gltf")),
            "cornell-box.gltf",
        ),
    ];
    for (request, name) in cases {
        let (st, h, b) = call(&router, request).await;
        assert_eq!(
            st,
            StatusCode::OK,
            "{name}: {}",
            String::from_utf8_lossy(&b)
        );
        assert_eq!(h[header::CONTENT_TYPE], "application/json");
        assert!(h.get(header::WARNING).is_none(), "{name}: {h:?}");
        let mut doc: Value = serde_json::from_slice(&b).unwrap();
        let mut want = library(name);
        // a body without a file name is called model.*
        doc["scene"]["name"] = json!("x");
        want["scene"]["name"] = json!("x");
        assert_eq!(doc, want, "{name}");
    }
    // the OBJ alone: no materials, so warnings, one header each; still a document
    let (st, h, b) = call(&router, post("model/obj", fixture("cornell-box.obj"))).await;
    assert_eq!(st, StatusCode::OK, "{}", String::from_utf8_lossy(&b));
    let warnings: Vec<&str> = h
        .get_all(header::WARNING)
        .iter()
        .map(|v| v.to_str().unwrap())
        .collect();
    assert!(
        warnings.iter().all(|w| w.starts_with("299 wavrad \"")),
        "{warnings:?}"
    );
    assert!(
        warnings.iter().any(|w| w.contains("cornell-box.mtl")),
        "{warnings:?}"
    );
    assert!(
        warnings.iter().any(|w| w.contains("will need a light")),
        "{warnings:?}"
    );
    let doc: Value = serde_json::from_slice(&b).unwrap();
    assert_eq!(doc["scene"]["name"], "model");
    // the room: larger than this server's max_body_bytes as a document, which a warning says
    let room = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/models");
    let request = multipart(&[
        ("room.obj", &std::fs::read(room.join("room.obj")).unwrap()),
        ("room.mtl", &std::fs::read(room.join("room.mtl")).unwrap()),
    ]);
    let (st, h, _) = call(&router, request).await;
    assert_eq!(st, StatusCode::OK);
    let w: Vec<&str> = h
        .get_all(header::WARNING)
        .iter()
        .map(|v| v.to_str().unwrap())
        .collect();
    assert!(w.len() == 1 && w[0].contains("max_body_bytes"), "{w:?}");
}

#[tokio::test(flavor = "multi_thread")]
async fn every_import_error_has_its_status_and_where() {
    let (_dir, router) = setup(|c| c.max_import_bytes = 16384);
    // 415: not a model type
    for ct in ["application/json", "text/plain", "model/stl"] {
        let (st, h, b) = call(&router, post(ct, QUAD_OBJ)).await;
        problem(st, &h, &b, StatusCode::UNSUPPORTED_MEDIA_TYPE);
    }
    let req = Request::post("/api/v1/import")
        .body(Body::from(QUAD_OBJ))
        .unwrap();
    let (st, h, b) = call(&router, req).await;
    problem(st, &h, &b, StatusCode::UNSUPPORTED_MEDIA_TYPE);
    // 413: larger than max_import_bytes, with and without a Content-Length
    let big = QUAD_OBJ.repeat(400);
    let (st, h, b) = call(&router, post("model/obj", big.clone())).await;
    let p = problem(st, &h, &b, StatusCode::PAYLOAD_TOO_LARGE);
    assert!(p["detail"].as_str().unwrap().contains("max_import_bytes"));
    let chunks = futures_util::stream::iter(
        big.into_bytes()
            .chunks(1000)
            .map(|c| Ok::<_, std::io::Error>(c.to_vec()))
            .collect::<Vec<_>>(),
    );
    let (st, h, b) = call(&router, post("model/obj", Body::from_stream(chunks))).await;
    problem(st, &h, &b, StatusCode::PAYLOAD_TOO_LARGE);
    // 422: a broken OBJ, with its line
    let (st, h, b) = call(
        &router,
        post("model/obj", "v 0 0 0\nv 1 0 0\nv 1 y 0\nf 1 2 3\n"),
    )
    .await;
    let p = problem(st, &h, &b, StatusCode::UNPROCESSABLE_ENTITY);
    assert_eq!(p["type"], "/problems/invalid-model");
    assert_eq!(p["errors"][0]["line"], 3);
    assert_eq!(p["errors"][0]["file"], "model.obj");
    assert!(p["detail"].as_str().unwrap().contains("line 3"), "{p}");
    // 422: a broken MTL of an upload, with its name and line
    let obj = format!("mtllib m.mtl\n{QUAD_OBJ}");
    let request = multipart(&[
        ("q.obj", obj.as_bytes()),
        ("m.mtl", b"newmtl a\nKe 1 x 1\n"),
    ]);
    let (st, h, b) = call(&router, request).await;
    let p = problem(st, &h, &b, StatusCode::UNPROCESSABLE_ENTITY);
    assert_eq!(
        (
            p["errors"][0]["file"].as_str(),
            p["errors"][0]["line"].as_u64()
        ),
        (Some("m.mtl"), Some(2))
    );
    // 422: a broken glTF, with its JSON path
    let doc = json!({"asset": {"version": "2.0"}, "meshes": [{"primitives": [{"attributes": {"POSITION": 4}}]}]});
    let (st, h, b) = call(&router, post("model/gltf+json", doc.to_string())).await;
    let p = problem(st, &h, &b, StatusCode::UNPROCESSABLE_ENTITY);
    assert_eq!(
        p["errors"][0]["path"], "/meshes/0/primitives/0/attributes/POSITION",
        "{p}"
    );
    // 422: a .gltf uploaded without its .bin
    let (st, h, b) = call(
        &router,
        post("model/gltf+json", fixture("cornell-box-split.gltf")),
    )
    .await;
    let p = problem(st, &h, &b, StatusCode::UNPROCESSABLE_ENTITY);
    assert_eq!(p["errors"][0]["path"], "/buffers/0/uri");
    // 422: not a GLB
    let (st, h, b) = call(
        &router,
        post("model/gltf-binary", &b"glTF\x02\0\0\0\x10\0\0\0"[..]),
    )
    .await;
    problem(st, &h, &b, StatusCode::UNPROCESSABLE_ENTITY);
    // 422: an upload without a model part
    let (st, h, b) = call(&router, multipart(&[("m.mtl", b"newmtl a\n")])).await;
    problem(st, &h, &b, StatusCode::UNPROCESSABLE_ENTITY);
    // 400: a multipart body that is not one
    let (st, h, b) = call(
        &router,
        post(
            &format!("multipart/form-data; boundary={BOUNDARY}"),
            "garbage",
        ),
    )
    .await;
    problem(st, &h, &b, StatusCode::BAD_REQUEST);
}

#[tokio::test(flavor = "multi_thread")]
async fn the_openapi_description_lists_the_import_route() {
    let (_dir, router) = setup(|_| {});
    let req = Request::get("/api/v1/openapi.json")
        .body(Body::empty())
        .unwrap();
    let (st, _, b) = call(&router, req).await;
    assert_eq!(st, StatusCode::OK);
    let api: Value = serde_json::from_slice(&b).unwrap();
    let op = &api["paths"]["/api/v1/import"]["post"];
    let content = op["requestBody"]["content"].as_object().unwrap();
    for t in [
        "model/obj",
        "model/gltf+json",
        "model/gltf-binary",
        "multipart/form-data",
    ] {
        assert!(content.contains_key(t), "{t}");
    }
    for s in ["200", "413", "415", "422"] {
        assert!(op["responses"][s].is_object(), "{s}");
    }
}
