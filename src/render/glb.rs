//! `scene.glb`: the solved 3D scene as binary glTF 2.0 with the lighting baked into vertex
//! colours (`docs/api.md`).
//!
//! Two steps, so that any kind of surface can be added: each surface becomes a [`LitMesh`]
//! (triangles whose vertices carry the displayed colour), and [`write`] turns the meshes into
//! a GLB (one node and one mesh per surface, named after it; one unlit material,
//! `KHR_materials_unlit`; the camera of `image.png`; the exposure in the scene's `extras`).
//!
//! A parallelogram's field is a tiling of [0,1]² by leaves of different sizes
//! ([`parallelogram`]). Where a coarse leaf meets finer ones, the finer side's vertices are
//! inserted on the coarse leaf's edge and the leaf is triangulated as a fan from its centre,
//! so that no vertex lies inside another triangle's edge (no T-vertex, no crack).
//!
//! Colours are those of `image.png` ([`super::camera`]): radiance L = B/π divided by the same
//! white point, clamped to [0, 1], kept linear in `COLOR_0` (glTF vertex colours are linear;
//! a viewer's sRGB output encoding then gives the image's pixels). B at a vertex is the
//! solution's polynomial there, averaged over the leaves that meet at it; a leaf's centre
//! shows its own polynomial (orders ≥ 1), not the element's mean.

use crate::math::field::{Field, Leaf};
use crate::scene::{Camera, Job, SceneKind, Shape3};
use gltf::json;
use json::validation::{Checked, USize64};
use rayon::prelude::*;
use rustc_hash::FxHashMap;
use std::collections::BTreeMap;

/// One surface as lit triangles.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct LitMesh {
    name: String,
    positions: Vec<[f32; 3]>,
    /// Linear RGB in [0, 1], one per position.
    colours: Vec<[f32; 3]>,
    /// Counter-clockwise seen from the front.
    pub triangles: Vec<[u32; 3]>,
}

/// The displayed colour of B: radiance B/π over `white`, clamped to [0, 1], linear.
fn colour(b: [f64; 3], white: f64) -> [f32; 3] {
    b.map(|v| ((v / std::f64::consts::PI) / white).clamp(0.0, 1.0) as f32)
}

/// A parallelogram `p(s,t) = p0 + s (p1 − p0) + t (p3 − p0)` lit by its field: the leaves as
/// triangles without T-vertices, coloured by `colour` with the given white point.
pub fn parallelogram(name: &str, corners: &[[f64; 3]; 4], field: &Field, white: f64) -> LitMesh {
    let n = field.res as u32;
    let [p0, p1, _, p3] = *corners;
    let at = |s: f64, t: f64| -> [f32; 3] {
        std::array::from_fn(|a| (p0[a] + s * (p1[a] - p0[a]) + t * (p3[a] - p0[a])) as f32)
    };
    let grid = |x: f64| (x * n as f64).round() as u32;
    let cell = |i: u32| (i as f64 + 0.5) / n as f64;
    let mut mesh = LitMesh {
        name: name.to_string(),
        ..LitMesh::default()
    };
    // vertices on the grid of the finest cells, shared by the leaves that meet there
    let mut shared: FxHashMap<(u32, u32), u32> = FxHashMap::default();
    let mut corner_keys: Vec<(u32, u32)> = Vec::new();
    let mut ring: Vec<(u32, u32)> = Vec::new();
    for leaf in &field.leaves {
        let (i0, i1, j0, j1) = (
            grid(leaf.s[0]),
            grid(leaf.s[1]),
            grid(leaf.t[0]),
            grid(leaf.t[1]),
        );
        // The extent along the edge of the neighbour across it, from the finest cell `x`.
        let along_s = |x: u32, t: f64| {
            let l = field.leaf_at(cell(x), t);
            grid(l.s[1])
        };
        let along_t = |y: u32, s: f64| {
            let l = field.leaf_at(s, cell(y));
            grid(l.t[1])
        };
        // the boundary, counter-clockwise: bottom (t = t0), right, top, left
        ring.clear();
        ring.push((i0, j0));
        if j0 > 0 {
            let mut x = i0;
            while x < i1 {
                x = along_s(x, cell(j0 - 1)).min(i1);
                if x < i1 {
                    ring.push((x, j0));
                }
            }
        }
        ring.push((i1, j0));
        if i1 < n {
            let mut y = j0;
            while y < j1 {
                y = along_t(y, cell(i1)).min(j1);
                if y < j1 {
                    ring.push((i1, y));
                }
            }
        }
        ring.push((i1, j1));
        let top = ring.len();
        if j1 < n {
            let mut x = i0;
            while x < i1 {
                x = along_s(x, cell(j1)).min(i1);
                if x < i1 {
                    ring.push((x, j1));
                }
            }
        }
        ring[top..].reverse();
        ring.push((i0, j1));
        let left = ring.len();
        if i0 > 0 {
            let mut y = j0;
            while y < j1 {
                y = along_t(y, cell(i0 - 1)).min(j1);
                if y < j1 {
                    ring.push((i0, y));
                }
            }
        }
        ring[left..].reverse();

        let ids: Vec<u32> = ring
            .iter()
            .map(|&key| {
                *shared.entry(key).or_insert_with(|| {
                    corner_keys.push(key);
                    mesh.positions
                        .push(at(key.0 as f64 / n as f64, key.1 as f64 / n as f64));
                    mesh.colours.push([0.0; 3]);
                    (mesh.positions.len() - 1) as u32
                })
            })
            .collect();
        if ids.len() == 4 && field.order == 0 {
            mesh.triangles.push([ids[0], ids[1], ids[2]]);
            mesh.triangles.push([ids[0], ids[2], ids[3]]);
        } else {
            // a fan from the centre, which shows the leaf's own polynomial there
            let (s, t) = (0.5 * (leaf.s[0] + leaf.s[1]), 0.5 * (leaf.t[0] + leaf.t[1]));
            let c = mesh.positions.len() as u32;
            mesh.positions.push(at(s, t));
            mesh.colours
                .push(colour(field.eval_leaf(leaf, s, t), white));
            for k in 0..ids.len() {
                mesh.triangles.push([c, ids[k], ids[(k + 1) % ids.len()]]);
            }
        }
    }
    // B at the shared vertices: the mean of the polynomials of the leaves that meet there
    for (key, &id) in &shared {
        let b = mean_at(field, key.0, key.1);
        mesh.colours[id as usize] = colour(b, white);
    }
    mesh
}

/// The lit meshes of a solved 3D job's surfaces, in document order (none for other kinds).
fn lit_meshes(job: &Job, fields: &[Field], white: f64) -> Vec<LitMesh> {
    let SceneKind::ThreeD(d) = &job.scene.kind else {
        return Vec::new();
    };
    d.surfaces
        .par_iter()
        .map(|s| match &s.shape {
            Shape3::Parallelogram => {
                let i = s.patches.start;
                parallelogram(&s.name, &d.patches[i].corners, &fields[i], white)
            }
            Shape3::Triangle => {
                let q = &d.patches[s.patches.start];
                let positions = vec![q.corners[0], q.corners[1], q.corners[3]];
                triangles(
                    &s.name,
                    &positions,
                    &[[0, 1, 2]],
                    &fields[s.patches.clone()],
                    white,
                )
            }
            Shape3::Mesh {
                positions,
                triangles: t,
            } => triangles(&s.name, positions, t, &fields[s.patches.clone()], white),
        })
        .collect()
}

/// A triangle or a mesh lit by its triangles' fields: its own triangles (crack-free as the
/// model is), each position coloured by B there averaged over the triangles that meet at it
/// (the values of the polynomials at the vertices, as the result's `vertices`). The elements
/// inside a triangle are not shown.
fn triangles(
    name: &str,
    positions: &[[f64; 3]],
    triangles: &[[usize; 3]],
    fields: &[Field],
    white: f64,
) -> LitMesh {
    LitMesh {
        name: name.to_string(),
        positions: positions.iter().map(|p| p.map(|x| x as f32)).collect(),
        colours: crate::job::vertex_values(positions.len(), triangles, fields)
            .into_iter()
            .map(|b| colour(b, white))
            .collect(),
        triangles: triangles.iter().map(|t| t.map(|i| i as u32)).collect(),
    }
}

/// `scene.glb` of a solved 3D job, with the white point and camera of its `image.png`.
pub(super) fn scene(job: &Job, fields: &[Field], white: f64, view: Option<View>) -> Vec<u8> {
    write(
        job.scene.name.as_deref(),
        &lit_meshes(job, fields, white),
        white,
        view,
    )
}

/// The mean over the leaves that hold grid point (i, j) of their polynomials there.
fn mean_at(field: &Field, i: u32, j: u32) -> [f64; 3] {
    let n = field.res as u32;
    let (s, t) = (i as f64 / n as f64, j as f64 / n as f64);
    let mut seen: [Option<&Leaf>; 4] = [None; 4];
    let mut count = 0;
    let mut sum = [0.0; 3];
    for (di, dj) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
        // the finest cell to the lower left (0) or upper right (1) of the point
        let (ci, cj) = (i as i64 - 1 + di, j as i64 - 1 + dj);
        if ci < 0 || cj < 0 || ci >= n as i64 || cj >= n as i64 {
            continue;
        }
        let leaf = field.leaf_at((ci as f64 + 0.5) / n as f64, (cj as f64 + 0.5) / n as f64);
        if seen[..count].iter().any(|l| std::ptr::eq(l.unwrap(), leaf)) {
            continue;
        }
        seen[count] = Some(leaf);
        count += 1;
        let v = field.eval_leaf(leaf, s, t);
        (0..3).for_each(|c| sum[c] += v[c]);
    }
    sum.map(|v| v / count as f64)
}

/// The camera of `image.png`, for the viewer to start from.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct View {
    pub(super) camera: Camera,
    /// Width over height.
    pub(super) aspect: f64,
}

const ARRAY_BUFFER: u32 = 34962;
const ELEMENT_ARRAY_BUFFER: u32 = 34963;

/// The GLB of lit meshes: the scene named `scene_name`, one node and mesh per [`LitMesh`]
/// (meshes without triangles are left out), a camera node for `view`, and `white` (the
/// radiance shown as white) in the scene's `extras`.
pub fn write(
    scene_name: Option<&str>,
    meshes: &[LitMesh],
    white: f64,
    view: Option<View>,
) -> Vec<u8> {
    let mut root = json::Root {
        asset: json::Asset {
            generator: Some(format!("wavrad {}", env!("CARGO_PKG_VERSION"))),
            version: "2.0".into(),
            ..Default::default()
        },
        extensions_used: vec!["KHR_materials_unlit".into()],
        ..Default::default()
    };
    let material = root.push(json::Material {
        name: Some("radiosity (unlit, vertex colours)".into()),
        pbr_metallic_roughness: json::material::PbrMetallicRoughness {
            base_color_factor: json::material::PbrBaseColorFactor([1.0; 4]),
            metallic_factor: json::material::StrengthFactor(0.0),
            roughness_factor: json::material::StrengthFactor(1.0),
            ..Default::default()
        },
        // from its JSON, whatever other material extensions the crate's features add
        extensions: Some(
            serde_json::from_value(serde_json::json!({ "KHR_materials_unlit": {} }))
                .expect("the unlit extension"),
        ),
        ..Default::default()
    });
    let mut bin: Vec<u8> = Vec::new();
    let buffer = json::Index::<json::Buffer>::new(0);
    // one buffer view per accessor, each 4-byte aligned
    let mut view_of = |root: &mut json::Root, bytes: &[u8], target: u32| {
        let offset = bin.len();
        bin.extend_from_slice(bytes);
        bin.resize(bin.len().next_multiple_of(4), 0);
        root.push(json::buffer::View {
            buffer,
            byte_length: USize64(bytes.len() as u64),
            byte_offset: Some(USize64(offset as u64)),
            byte_stride: None,
            name: None,
            target: Some(Checked::Valid(if target == ARRAY_BUFFER {
                json::buffer::Target::ArrayBuffer
            } else {
                json::buffer::Target::ElementArrayBuffer
            })),
            extensions: None,
            extras: None,
        })
    };
    let accessor = |view: json::Index<json::buffer::View>,
                    count: usize,
                    component: json::accessor::ComponentType,
                    type_: json::accessor::Type,
                    bounds: Option<([f32; 3], [f32; 3])>| json::Accessor {
        buffer_view: Some(view),
        byte_offset: None,
        count: USize64(count as u64),
        component_type: Checked::Valid(json::accessor::GenericComponentType(component)),
        extensions: None,
        extras: None,
        type_: Checked::Valid(type_),
        min: bounds.map(|b| serde_json::json!(b.0)),
        max: bounds.map(|b| serde_json::json!(b.1)),
        name: None,
        normalized: false,
        sparse: None,
    };
    let mut nodes = Vec::new();
    for m in meshes.iter().filter(|m| !m.triangles.is_empty()) {
        let mut lo = [f32::INFINITY; 3];
        let mut hi = [f32::NEG_INFINITY; 3];
        for p in &m.positions {
            for a in 0..3 {
                lo[a] = lo[a].min(p[a]);
                hi[a] = hi[a].max(p[a]);
            }
        }
        let floats = |v: &[[f32; 3]]| -> Vec<u8> {
            v.iter().flatten().flat_map(|x| x.to_le_bytes()).collect()
        };
        let pv = view_of(&mut root, &floats(&m.positions), ARRAY_BUFFER);
        let positions = root.push(accessor(
            pv,
            m.positions.len(),
            json::accessor::ComponentType::F32,
            json::accessor::Type::Vec3,
            Some((lo, hi)),
        ));
        let cv = view_of(&mut root, &floats(&m.colours), ARRAY_BUFFER);
        let colours = root.push(accessor(
            cv,
            m.colours.len(),
            json::accessor::ComponentType::F32,
            json::accessor::Type::Vec3,
            None,
        ));
        // 16-bit indices when they fit (65535 is the restart value, never an index)
        let (bytes, component) = if m.positions.len() < 65535 {
            let b: Vec<u8> = m
                .triangles
                .iter()
                .flatten()
                .flat_map(|&i| (i as u16).to_le_bytes())
                .collect();
            (b, json::accessor::ComponentType::U16)
        } else {
            let b: Vec<u8> = m
                .triangles
                .iter()
                .flatten()
                .flat_map(|&i| i.to_le_bytes())
                .collect();
            (b, json::accessor::ComponentType::U32)
        };
        let iv = view_of(&mut root, &bytes, ELEMENT_ARRAY_BUFFER);
        let indices = root.push(accessor(
            iv,
            3 * m.triangles.len(),
            component,
            json::accessor::Type::Scalar,
            None,
        ));
        let primitive = json::mesh::Primitive {
            attributes: BTreeMap::from([
                (Checked::Valid(json::mesh::Semantic::Positions), positions),
                (Checked::Valid(json::mesh::Semantic::Colors(0)), colours),
            ]),
            extensions: None,
            extras: None,
            indices: Some(indices),
            material: Some(material),
            mode: Checked::Valid(json::mesh::Mode::Triangles),
            targets: None,
        };
        let mesh = root.push(json::Mesh {
            extensions: None,
            extras: None,
            name: Some(m.name.clone()),
            primitives: vec![primitive],
            weights: None,
        });
        nodes.push(root.push(json::Node {
            mesh: Some(mesh),
            name: Some(m.name.clone()),
            ..Default::default()
        }));
    }
    if let Some(v) = view {
        let c = v.camera;
        let camera = root.push(json::Camera {
            name: Some("image.png".into()),
            orthographic: None,
            perspective: Some(json::camera::Perspective {
                aspect_ratio: Some(v.aspect as f32),
                yfov: c.fov_deg.to_radians() as f32,
                zfar: None,
                znear: (1e-3 * distance(c.eye, c.look_at)).max(1e-6) as f32,
                extensions: None,
                extras: None,
            }),
            type_: Checked::Valid(json::camera::Type::Perspective),
            extensions: None,
            extras: None,
        });
        nodes.push(root.push(json::Node {
            camera: Some(camera),
            name: Some("camera".into()),
            rotation: Some(json::scene::UnitQuaternion(look_rotation(&c))),
            translation: Some(c.eye.map(|x| x as f32)),
            extras: raw(&serde_json::json!({ "look_at": c.look_at })),
            ..Default::default()
        }));
    }
    let scene = root.push(json::Scene {
        extensions: None,
        extras: raw(&serde_json::json!({
            "exposure": white,
            "colours": "COLOR_0 = min(1, radiance / exposure), linear, radiance = B / pi \
                        (W m^-2 sr^-1); the viewer's sRGB output encoding gives image.png's colours",
        })),
        name: scene_name.map(str::to_string),
        nodes,
    });
    root.scene = Some(scene);
    root.buffers.push(json::Buffer {
        byte_length: USize64(bin.len() as u64),
        name: None,
        uri: None,
        extensions: None,
        extras: None,
    });
    let text = json::serialize::to_vec(&root).expect("a glTF document serialises");
    gltf::binary::Glb {
        header: gltf::binary::Header {
            magic: *b"glTF",
            version: 2,
            length: 0, // to_vec writes the real length
        },
        json: text.into(),
        bin: Some(bin.into()),
    }
    .to_vec()
    .expect("writing into memory cannot fail")
}

fn raw(v: &serde_json::Value) -> json::Extras {
    Some(serde_json::value::to_raw_value(v).expect("JSON serialises"))
}

fn distance(a: [f64; 3], b: [f64; 3]) -> f64 {
    (0..3).map(|i| (a[i] - b[i]).powi(2)).sum::<f64>().sqrt()
}

/// The rotation (x, y, z, w) that turns a glTF camera (looking down −z, y up) to look from
/// `eye` at `look_at` with `up` upwards.
fn look_rotation(c: &Camera) -> [f32; 4] {
    let norm = |v: [f64; 3]| {
        let l = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        v.map(|x| x / l)
    };
    let cross = |a: [f64; 3], b: [f64; 3]| {
        [
            a[1] * b[2] - a[2] * b[1],
            a[2] * b[0] - a[0] * b[2],
            a[0] * b[1] - a[1] * b[0],
        ]
    };
    let f = norm([
        c.look_at[0] - c.eye[0],
        c.look_at[1] - c.eye[1],
        c.look_at[2] - c.eye[2],
    ]);
    let x = norm(cross(f, c.up));
    let y = cross(x, f);
    let z = f.map(|v| -v);
    // columns x, y, z of the rotation matrix m[row][col]
    let m = [[x[0], y[0], z[0]], [x[1], y[1], z[1]], [x[2], y[2], z[2]]];
    let trace = m[0][0] + m[1][1] + m[2][2];
    let q = if trace > 0.0 {
        let s = 2.0 * (trace + 1.0).sqrt();
        [
            (m[2][1] - m[1][2]) / s,
            (m[0][2] - m[2][0]) / s,
            (m[1][0] - m[0][1]) / s,
            0.25 * s,
        ]
    } else if m[0][0] > m[1][1] && m[0][0] > m[2][2] {
        let s = 2.0 * (1.0 + m[0][0] - m[1][1] - m[2][2]).sqrt();
        [
            0.25 * s,
            (m[0][1] + m[1][0]) / s,
            (m[0][2] + m[2][0]) / s,
            (m[2][1] - m[1][2]) / s,
        ]
    } else if m[1][1] > m[2][2] {
        let s = 2.0 * (1.0 + m[1][1] - m[0][0] - m[2][2]).sqrt();
        [
            (m[0][1] + m[1][0]) / s,
            0.25 * s,
            (m[1][2] + m[2][1]) / s,
            (m[0][2] - m[2][0]) / s,
        ]
    } else {
        let s = 2.0 * (1.0 + m[2][2] - m[0][0] - m[1][1]).sqrt();
        [
            (m[0][2] + m[2][0]) / s,
            (m[1][2] + m[2][1]) / s,
            0.25 * s,
            (m[1][0] - m[0][1]) / s,
        ]
    };
    let l = q.iter().map(|v| v * v).sum::<f64>().sqrt();
    q.map(|v| (v / l) as f32)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_coarse_leaf_beside_fine_ones_takes_their_vertices() {
        // one leaf over the left half, four over the right half: the left leaf's right
        // edge gets the fine side's middle vertex, and is a fan of 5 triangles
        let c = [[1.0; 3]; 4];
        let leaf = |s: [f64; 2], t: [f64; 2]| Leaf {
            s,
            t,
            coeffs: c.to_vec(),
            upper: false,
        };
        let leaves = vec![
            leaf([0.0, 0.5], [0.0, 1.0]),
            leaf([0.5, 0.75], [0.0, 0.5]),
            leaf([0.75, 1.0], [0.0, 0.5]),
            leaf([0.5, 0.75], [0.5, 1.0]),
            leaf([0.75, 1.0], [0.5, 1.0]),
        ];
        let f = Field::from_leaves(2, 1, 4, leaves);
        let quad = [
            [0.0, 0.0, 0.0],
            [2.0, 0.0, 0.0],
            [2.0, 1.0, 0.0],
            [0.0, 1.0, 0.0],
        ];
        let m = parallelogram("x", &quad, &f, 1.0);
        // 5 leaves with a centre each; the left one has 5 boundary vertices
        assert_eq!(m.triangles.len(), 5 + 4 * 4);
        // every edge inside is shared by two triangles
        let mut edges: FxHashMap<(u32, u32), usize> = FxHashMap::default();
        for t in &m.triangles {
            for k in 0..3 {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                *edges.entry((a.min(b), a.max(b))).or_default() += 1;
            }
        }
        for ((a, b), n) in edges {
            let (pa, pb) = (m.positions[a as usize], m.positions[b as usize]);
            let border = |k: usize, v: f32| pa[k] == v && pb[k] == v;
            let on_border = border(0, 0.0) || border(0, 2.0) || border(1, 0.0) || border(1, 1.0);
            assert_eq!(n, if on_border { 1 } else { 2 }, "{pa:?} {pb:?}");
        }
        // counter-clockwise seen from +z (the front of this parallelogram)
        for t in &m.triangles {
            let [a, b, c] = t.map(|i| m.positions[i as usize]);
            let z = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
            assert!(z > 0.0);
        }
    }

    #[test]
    fn the_rotation_looks_where_the_camera_looks() {
        let c = Camera {
            eye: [0.0, 0.0, 0.0],
            look_at: [1.0, 0.0, 0.0],
            up: [0.0, 1.0, 0.0],
            fov_deg: 40.0,
        };
        let [x, y, z, w] = look_rotation(&c).map(|v| v as f64);
        // rotate (0, 0, −1)
        let v = [0.0, 0.0, -1.0];
        let r = |v: [f64; 3]| {
            // q v q*
            let (qv, qw) = ([x, y, z], w);
            let cross = |a: [f64; 3], b: [f64; 3]| {
                [
                    a[1] * b[2] - a[2] * b[1],
                    a[2] * b[0] - a[0] * b[2],
                    a[0] * b[1] - a[1] * b[0],
                ]
            };
            let t = cross(qv, v).map(|e| 2.0 * e);
            let u = cross(qv, t);
            std::array::from_fn::<f64, 3, _>(|i| v[i] + qw * t[i] + u[i])
        };
        let f = r(v);
        assert!(
            (f[0] - 1.0).abs() < 1e-6 && f[1].abs() < 1e-6 && f[2].abs() < 1e-6,
            "{f:?}"
        );
        let u = r([0.0, 1.0, 0.0]);
        assert!((u[1] - 1.0).abs() < 1e-6, "{u:?}");
    }
}
