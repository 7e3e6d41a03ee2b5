//! `scene.glb` of solved 3D scenes (the Cornell box, hierarchical at order 1; the two plates,
//! projection at order 0): the Khronos glTF validator finds no error; every surface is one
//! named node and mesh that covers it exactly, with no crack (each edge shared by two
//! triangles or on the surface's border); each vertex's colour is the displayed radiance of the
//! solution there (B/π over image.png's white point, the mean of the polynomials of the leaves
//! that meet at it); the exposure and camera are image.png's; the Cornell box's is under 2 MB.
//!
//! The validator is the npm package `gltf-validator`, run by node from the directory in
//! `WAVRAD_GLTF_VALIDATOR` (default `.ci/tools`, where `scripts/test` installs it). Without it
//! the tests fail.

mod support;

use std::path::PathBuf;
use std::process::Command;
use wavrad::job::Outcome;
use wavrad::math::field::Field;
use wavrad::render::camera;
use wavrad::scene::{Job, SceneKind};

fn solve(name: &str) -> (Job, Outcome, Vec<u8>) {
    let path = format!("{}/scenes/{name}.json", env!("CARGO_MANIFEST_DIR"));
    let text = std::fs::read_to_string(path).unwrap();
    let job = wavrad::scene::parse_document(&text, &wavrad::scene::Limits::default()).unwrap();
    let outcome = wavrad::job::run(&job, &wavrad::progress::Silent).unwrap();
    let images = wavrad::render::render_all(&job, &outcome);
    let glb = images.glb.clone().expect("a 3d job has a scene.glb");
    let files: Vec<String> = images.files().into_iter().map(|(n, _)| n).collect();
    assert!(files.contains(&"scene.glb".to_string()), "{files:?}");
    (job, outcome, glb)
}

/// The validator's report; a failure when it is not installed (`scripts/test` installs it).
fn validate(glb: &[u8], what: &str) -> serde_json::Value {
    let dir = std::env::var_os("WAVRAD_GLTF_VALIDATOR")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/.ci/tools")));
    let installed = dir
        .join("node_modules/gltf-validator/package.json")
        .is_file()
        && Command::new("node").arg("--version").output().is_ok();
    assert!(
        installed,
        "validating {what} needs node and the glTF validator in {}: run scripts/test, which \
         installs them, or `npm install --prefix {} gltf-validator` (or WAVRAD_GLTF_VALIDATOR=DIR)",
        dir.display(),
        dir.display()
    );
    let file = tempfile::NamedTempFile::new().unwrap();
    std::fs::write(file.path(), glb).unwrap();
    let out = Command::new("node")
        .arg(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/tests/support/gltf-validate.js"
        ))
        .arg(&dir)
        .arg(file.path())
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "the validator failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).unwrap()
}

/// Two sRGB pixels equal but for the rounding of a value within 1e-4 of a step's edge.
fn same_pixel(a: image::Rgb<u8>, b: image::Rgb<u8>, name: &str, k: usize) {
    for c in 0..3 {
        assert!(
            a.0[c].abs_diff(b.0[c]) <= 1,
            "{name}: vertex {k} shown as {a:?}, image.png shows {b:?}"
        );
    }
}

/// What a surface's mesh must be.
fn check_surface(
    name: &str,
    corners: &[[f64; 3]; 4],
    field: &Field,
    white: f64,
    positions: &[[f32; 3]],
    colours: &[[f32; 3]],
    triangles: &[[u32; 3]],
) {
    let sub = |a: [f64; 3], b: [f64; 3]| [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
    let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let cross = |a: [f64; 3], b: [f64; 3]| {
        [
            a[1] * b[2] - a[2] * b[1],
            a[2] * b[0] - a[0] * b[2],
            a[0] * b[1] - a[1] * b[0],
        ]
    };
    let (p0, e1, e3) = (
        corners[0],
        sub(corners[1], corners[0]),
        sub(corners[3], corners[0]),
    );
    let normal = cross(e1, e3);
    let area = dot(normal, normal).sqrt();
    // (s, t) of a position: least squares on the plane
    let (g11, g13, g33) = (dot(e1, e1), dot(e1, e3), dot(e3, e3));
    let det = g11 * g33 - g13 * g13;
    let st: Vec<[f64; 2]> = positions
        .iter()
        .map(|p| {
            let d = sub(p.map(|x| x as f64), p0);
            let (a, b) = (dot(d, e1), dot(d, e3));
            [(g33 * a - g13 * b) / det, (g11 * b - g13 * a) / det]
        })
        .collect();
    let eps = 1e-5;
    for (k, [s, t]) in st.iter().enumerate() {
        assert!(
            (-eps..=1.0 + eps).contains(s) && (-eps..=1.0 + eps).contains(t),
            "{name}: vertex {k} off the surface at ({s}, {t})"
        );
        // the colour: the mean of the polynomials of every leaf that holds the point
        let holders: Vec<_> = field
            .leaves
            .iter()
            .filter(|l| {
                l.s[0] - eps <= *s && *s <= l.s[1] + eps && l.t[0] - eps <= *t && *t <= l.t[1] + eps
            })
            .collect();
        assert!(!holders.is_empty());
        let mut b = [0.0; 3];
        for l in &holders {
            let v = field.eval_leaf(l, *s, *t);
            (0..3).for_each(|c| b[c] += v[c] / holders.len() as f64);
        }
        let l = b.map(|v| v / std::f64::consts::PI);
        let got = colours[k].map(|c| c as f64);
        for c in 0..3 {
            let want = (l[c] / white).clamp(0.0, 1.0);
            assert!(
                (got[c] - want).abs() < 1e-4,
                "{name}: vertex {k} at ({s}, {t}): colour {got:?}, B/π/white {:?}",
                l.map(|v| v / white)
            );
        }
        // shown as image.png shows that radiance (to the rounding of an 8-bit step)
        same_pixel(camera::encode(got, 1.0), camera::encode(l, white), name, k);
        // a vertex inside a leaf (its centre) shows B there
        if holders.len() == 1 {
            let leaf = holders[0];
            let inside = leaf.s[0] + eps < *s && *s < leaf.s[1] - eps;
            if inside {
                let b = field.eval(*s, *t).map(|v| v / std::f64::consts::PI);
                same_pixel(camera::encode(got, 1.0), camera::encode(b, white), name, k);
            }
        }
    }
    // no two vertices in one place
    let mut keys: Vec<(i64, i64)> = st
        .iter()
        .map(|[s, t]| ((s * 1e6).round() as i64, (t * 1e6).round() as i64))
        .collect();
    keys.sort_unstable();
    let n = keys.len();
    keys.dedup();
    assert_eq!(keys.len(), n, "{name}: vertices given twice");
    // the triangles face the front and cover the surface once
    let mut covered = 0.0;
    for tri in triangles {
        let [a, b, c] = tri.map(|i| positions[i as usize].map(|x| x as f64));
        let n2 = cross(sub(b, a), sub(c, a));
        assert!(dot(n2, normal) > 0.0, "{name}: a triangle faces backwards");
        covered += dot(n2, n2).sqrt() / 2.0;
    }
    assert!(
        ((covered - area) / area).abs() < 1e-4,
        "{name}: triangles cover {covered}, the surface is {area}"
    );
    // no crack: every edge is shared by two triangles, or lies on the surface's border
    let mut edges: std::collections::HashMap<(u32, u32), u32> = Default::default();
    for tri in triangles {
        for k in 0..3 {
            let (a, b) = (tri[k], tri[(k + 1) % 3]);
            *edges.entry((a.min(b), a.max(b))).or_default() += 1;
        }
    }
    let mut border = 0;
    for ((a, b), count) in edges {
        let (pa, pb) = (st[a as usize], st[b as usize]);
        let on = |i: usize, v: f64| (pa[i] - v).abs() < eps && (pb[i] - v).abs() < eps;
        let on_border = on(0, 0.0) || on(0, 1.0) || on(1, 0.0) || on(1, 1.0);
        if on_border {
            border += 1;
        }
        assert_eq!(
            count,
            if on_border { 1 } else { 2 },
            "{name}: edge ({pa:?}, {pb:?}) in {count} triangles"
        );
    }
    assert!(border >= 4);
}

fn check(name: &str, max_bytes: usize) {
    let (job, outcome, glb) = solve(name);
    assert!(
        glb.len() < max_bytes,
        "{name}: scene.glb is {} bytes",
        glb.len()
    );
    let spec = job.output.image;
    let shot = camera::shoot(
        &job,
        &outcome.fields,
        spec.width,
        spec.height,
        camera::Options {
            raw: spec.raw,
            mesh: spec.mesh,
        },
    );
    let gltf = gltf::Gltf::from_slice(&glb).unwrap();
    let blob = gltf.blob.as_deref().expect("a BIN chunk");
    let scene = gltf.default_scene().expect("a default scene");
    assert_eq!(scene.name(), job.scene.name.as_deref());
    let extras: serde_json::Value =
        serde_json::from_str(scene.extras().as_ref().expect("extras").get()).unwrap();
    let white = extras["exposure"].as_f64().unwrap();
    assert_eq!(white, shot.white, "{name}: the exposure of image.png");
    assert_eq!(
        gltf.extensions_used().collect::<Vec<_>>(),
        ["KHR_materials_unlit"]
    );
    let SceneKind::ThreeD(quads) = &job.scene.kind else {
        unreachable!()
    };
    let nodes: Vec<_> = scene.nodes().collect();
    // one node per surface, in document order, then the camera
    assert_eq!(nodes.len(), quads.len() + 1);
    let cam = nodes.last().unwrap();
    assert!(cam.camera().is_some());
    let (eye, _, _) = cam.transform().decomposed();
    for (a, b) in eye.iter().zip(shot.camera.eye) {
        assert!((*a as f64 - b).abs() < 1e-3);
    }
    let mut triangles_total = 0;
    for ((node, quad), field) in nodes.iter().zip(quads.iter()).zip(&outcome.fields) {
        assert_eq!(node.name(), Some(quad.name.as_str()));
        let mesh = node.mesh().expect("a mesh");
        assert_eq!(mesh.name(), Some(quad.name.as_str()));
        let prim = mesh.primitives().next().unwrap();
        let material = prim.material();
        assert!(material.unlit(), "{name}: unlit");
        let reader = prim.reader(|_| Some(blob));
        let positions: Vec<[f32; 3]> = reader.read_positions().unwrap().collect();
        let colours: Vec<[f32; 3]> = reader.read_colors(0).unwrap().into_rgb_f32().collect();
        let idx: Vec<u32> = reader.read_indices().unwrap().into_u32().collect();
        let triangles: Vec<[u32; 3]> = idx.chunks(3).map(|c| [c[0], c[1], c[2]]).collect();
        triangles_total += triangles.len();
        check_surface(
            &quad.name,
            &quad.corners,
            field,
            white,
            &positions,
            &colours,
            &triangles,
        );
    }
    eprintln!(
        "{name}: scene.glb {} bytes, {triangles_total} triangles, exposure {white}",
        glb.len()
    );
    let report = validate(&glb, name);
    let issues = &report["issues"];
    assert_eq!(issues["numErrors"], 0, "{name}: {issues:#}");
    assert_eq!(issues["numWarnings"], 0, "{name}: {issues:#}");
    assert_eq!(
        report["info"]["totalTriangleCount"].as_u64(),
        Some(triangles_total as u64)
    );
}

#[test]
fn the_cornell_box_as_scene_glb() {
    check("cornell-box", 2 << 20);
}

#[test]
fn two_plates_as_scene_glb() {
    check("plates-3d", 2 << 20);
}

#[test]
fn other_kinds_have_no_scene_glb() {
    let path = format!(
        "{}/scenes/flatland-parallel.json",
        env!("CARGO_MANIFEST_DIR")
    );
    let text = std::fs::read_to_string(path).unwrap();
    let job = wavrad::scene::parse_document(&text, &wavrad::scene::Limits::default()).unwrap();
    let outcome = wavrad::job::run(&job, &wavrad::progress::Silent).unwrap();
    let images = wavrad::render::render_all(&job, &outcome);
    assert!(images.glb.is_none());
    assert!(images.files().iter().all(|(n, _)| n != "scene.glb"));
}

/// `scene.glb` of a scene of triangles and a mesh (the tetrahedron on a floor): validator
/// clean; each triangle or mesh surface is its own triangles, one vertex per position, coloured
/// by the result's `vertices` (B at the positions) as image.png's exposure shows them; no crack
/// (every edge of the tetrahedron's three sides shared by two of them, but the three on the
/// floor, its border).
#[test]
fn a_mesh_scene_as_scene_glb() {
    let (job, outcome, glb) = solve("tetrahedron-mesh");
    let gltf = gltf::Gltf::from_slice(&glb).unwrap();
    let blob = gltf.blob.as_deref().expect("a BIN chunk");
    let scene = gltf.default_scene().unwrap();
    let extras: serde_json::Value =
        serde_json::from_str(scene.extras().as_ref().unwrap().get()).unwrap();
    let white = extras["exposure"].as_f64().unwrap();
    let SceneKind::ThreeD(d) = &job.scene.kind else {
        unreachable!()
    };
    let nodes: Vec<_> = scene.nodes().collect();
    assert_eq!(nodes.len(), d.surfaces.len() + 1);
    let mut meshes = 0;
    for ((node, surface), result) in nodes.iter().zip(&d.surfaces).zip(&outcome.result.surfaces) {
        assert_eq!(node.name(), Some(surface.name.as_str()));
        let Some(vertices) = &result.vertices else {
            continue;
        };
        let prim = node.mesh().unwrap().primitives().next().unwrap();
        let reader = prim.reader(|_| Some(blob));
        let colours: Vec<[f32; 3]> = reader.read_colors(0).unwrap().into_rgb_f32().collect();
        let idx: Vec<u32> = reader.read_indices().unwrap().into_u32().collect();
        assert_eq!(colours.len(), vertices.len(), "{}", surface.name);
        for (c, b) in colours.iter().zip(vertices) {
            for k in 0..3 {
                let want = (b[k] / std::f64::consts::PI / white).clamp(0.0, 1.0);
                assert!(
                    (c[k] as f64 - want).abs() < 1e-6,
                    "{}: {c:?} {b:?}",
                    surface.name
                );
            }
        }
        if let wavrad::scene::Shape3::Mesh { triangles, .. } = &surface.shape {
            meshes += 1;
            assert_eq!(idx.len(), 3 * triangles.len());
            // every edge once each way between two triangles, or once on the border
            let mut edges = std::collections::HashMap::new();
            for t in idx.chunks(3) {
                for e in 0..3 {
                    *edges.entry((t[e], t[(e + 1) % 3])).or_insert(0) += 1;
                }
            }
            assert!(edges.values().all(|&n| n == 1), "{}", surface.name);
            let border = edges.keys().filter(|(a, b)| !edges.contains_key(&(*b, *a)));
            assert_eq!(
                border.count(),
                3,
                "{}: the base's three edges",
                surface.name
            );
        }
    }
    assert!(meshes > 0);
    let report = validate(&glb, "tetrahedron-mesh");
    assert_eq!(report["issues"]["numErrors"], 0, "{:#}", report["issues"]);
}

/// The baked example `scenes/models/room.glb` (the README's furnished room, solved through the
/// page): validator clean, and made of the triangles of `scenes/models/room.obj`, every one,
/// one node per surface of its import, named after it. A change to the model that is not
/// baked again fails here.
#[test]
fn the_baked_room_is_the_model_and_valid() {
    let models = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/models");
    let glb = std::fs::read(format!("{models}/room.glb")).unwrap();
    let report = validate(&glb, "room.glb");
    assert_eq!(report["issues"]["numErrors"], 0, "{report}");
    assert_eq!(report["issues"]["numWarnings"], 0, "{report}");
    let imported =
        support::import_file(std::path::Path::new(&format!("{models}/room.obj"))).unwrap();
    let names = support::surface_names(&imported.document);
    let gltf = gltf::Gltf::from_slice(&glb).unwrap();
    let meshes: Vec<(String, usize)> = gltf
        .default_scene()
        .unwrap()
        .nodes()
        .filter_map(|n| {
            let m = n.mesh()?;
            let triangles = m
                .primitives()
                .map(|p| p.indices().map_or(0, |a| a.count()) / 3)
                .sum();
            Some((n.name().unwrap_or("").to_string(), triangles))
        })
        .collect();
    let baked: Vec<&str> = meshes.iter().map(|(n, _)| n.as_str()).collect();
    assert_eq!(baked, names);
    let triangles: usize = meshes.iter().map(|(_, t)| t).sum();
    assert_eq!(triangles, imported.triangles);
}
