//! glTF 2.0 (`.gltf` with data-URI or external buffers, and GLB), read and validated by the
//! `gltf` crate: the meshes of the scene's node hierarchy with every node's transform applied,
//! one part per node and material; reflectance from `baseColorFactor` times the mean of
//! `baseColorTexture`, emission from `emissiveFactor` × `KHR_materials_emissive_strength`.
//!
//! Errors name the JSON pointer of what is at fault (`/accessors/3`, `/buffers/0/uri`).

use super::{Files, ImportError, Location, Model, Part};
use base64::Engine;
use gltf::mesh::Mode;

type Matrix = [[f64; 4]; 4];

const IDENTITY: Matrix = [
    [1.0, 0.0, 0.0, 0.0],
    [0.0, 1.0, 0.0, 0.0],
    [0.0, 0.0, 1.0, 0.0],
    [0.0, 0.0, 0.0, 1.0],
];

/// Column-major product a · b (glTF matrices are column-major: `m[column][row]`).
fn multiply(a: &Matrix, b: &Matrix) -> Matrix {
    let mut c = [[0.0; 4]; 4];
    for col in 0..4 {
        for row in 0..4 {
            c[col][row] = (0..4).map(|k| a[k][row] * b[col][k]).sum();
        }
    }
    c
}

fn apply(m: &Matrix, p: [f32; 3]) -> [f64; 3] {
    let p = p.map(f64::from);
    let mut out = [0.0; 3];
    for (row, o) in out.iter_mut().enumerate() {
        *o = m[0][row] * p[0] + m[1][row] * p[1] + m[2][row] * p[2] + m[3][row];
    }
    out
}

/// The determinant of the linear part: negative for a mirroring transform, which turns the
/// triangles' winding (and so their fronts) around.
fn determinant(m: &Matrix) -> f64 {
    m[0][0] * (m[1][1] * m[2][2] - m[2][1] * m[1][2])
        - m[1][0] * (m[0][1] * m[2][2] - m[2][1] * m[0][2])
        + m[2][0] * (m[0][1] * m[1][2] - m[1][1] * m[0][2])
}

/// A glTF path of the `gltf` crate (`meshes[0].primitives[1].indices`) as a JSON pointer
/// (`/meshes/0/primitives/1/indices`).
fn pointer(path: &str) -> String {
    let mut out = String::with_capacity(path.len() + 1);
    for c in path.chars() {
        match c {
            '.' | '[' => out.push('/'),
            ']' | '"' => {}
            c => out.push(c),
        }
    }
    if out.starts_with('/') || out.is_empty() {
        out
    } else {
        format!("/{out}")
    }
}

fn read_error(file: &str, e: gltf::Error) -> ImportError {
    match e {
        gltf::Error::Validation(errors) => {
            let (path, error) = errors
                .into_iter()
                .next()
                .expect("a validation error names at least one path");
            ImportError::new(
                file,
                Location::Pointer(pointer(&path.to_string())),
                format!("invalid glTF: {error}"),
            )
        }
        gltf::Error::Deserialize(e) if e.line() > 0 => ImportError::new(
            file,
            Location::Line(e.line()),
            format!("not glTF JSON: {e}"),
        ),
        gltf::Error::Deserialize(e) => {
            ImportError::new(file, Location::Whole, format!("not glTF JSON: {e}"))
        }
        gltf::Error::Binary(e) => {
            ImportError::new(file, Location::Whole, format!("not a GLB file: {e}"))
        }
        e => ImportError::new(file, Location::Whole, e.to_string()),
    }
}

/// The validation of the `gltf` crate, after the one check it does not make before relying on
/// it (a primitive's POSITION accessor exists), which would otherwise stop it.
fn validate(root: &gltf::json::Root) -> Result<(), gltf::Error> {
    use gltf::json::validation::{Checked, Error, Validate};
    use gltf::json::Path;
    let mut errors = Vec::new();
    for (m, mesh) in root.meshes.iter().enumerate() {
        for (p, primitive) in mesh.primitives.iter().enumerate() {
            let position = primitive
                .attributes
                .get(&Checked::Valid(gltf::Semantic::Positions));
            if position.is_some_and(|i| i.value() >= root.accessors.len()) {
                let path = Path::new()
                    .field("meshes")
                    .index(m)
                    .field("primitives")
                    .index(p)
                    .field("attributes")
                    .key("POSITION");
                errors.push((path, Error::IndexOutOfBounds));
            }
        }
    }
    if errors.is_empty() {
        root.validate(root, Path::new, &mut |path, error| {
            errors.push((path(), error))
        });
    }
    if errors.is_empty() {
        Ok(())
    } else {
        Err(gltf::Error::Validation(errors))
    }
}

/// The bytes of a `data:` URI (base64 or percent-free plain text), or `None` when it is not one.
fn data_uri(uri: &str) -> Option<Result<Vec<u8>, String>> {
    let rest = uri.strip_prefix("data:")?;
    let Some((head, data)) = rest.split_once(',') else {
        return Some(Err("a data URI without ','".into()));
    };
    Some(if head.ends_with(";base64") {
        base64::engine::general_purpose::STANDARD
            .decode(data.trim())
            .map_err(|e| format!("its base64 does not decode: {e}"))
    } else {
        Ok(data.as_bytes().to_vec())
    })
}

/// The bytes an external or data URI stands for.
fn resolve(uri: &str, files: Files) -> Option<Result<Vec<u8>, String>> {
    if let Some(data) = data_uri(uri) {
        return Some(data);
    }
    files(uri)
        .or_else(|| {
            // a name with spaces is written %20 in a URI
            let decoded = uri.replace("%20", " ");
            (decoded != uri).then(|| files(&decoded)).flatten()
        })
        .map(Ok)
}

/// sRGB-encoded 8-bit value to linear.
fn linear(v: u8) -> f64 {
    let c = f64::from(v) / 255.0;
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

/// The mean linear RGB of a base colour texture (sRGB-encoded, as glTF has it), or why not.
fn texture_mean(image: gltf::Image, buffers: &[Vec<u8>], files: Files) -> Result<[f64; 3], String> {
    let bytes = match image.source() {
        gltf::image::Source::View { view, .. } => {
            let start = view.offset();
            buffers[view.buffer().index()]
                .get(start..start + view.length())
                .ok_or("its buffer view lies outside its buffer")?
                .to_vec()
        }
        gltf::image::Source::Uri { uri, .. } => match resolve(uri, files) {
            Some(r) => r?,
            None => return Err(format!("the image {uri:?} was not given")),
        },
    };
    let decoded = image::load_from_memory(&bytes).map_err(|e| e.to_string())?;
    let rgb = decoded.to_rgb8();
    let lut: Vec<f64> = (0..=255u8).map(linear).collect();
    let mut sum = [0.0f64; 3];
    for p in rgb.pixels() {
        for c in 0..3 {
            sum[c] += lut[p.0[c] as usize];
        }
    }
    let n = (rgb.width() as f64 * rgb.height() as f64).max(1.0);
    Ok(sum.map(|s| s / n))
}

pub(super) fn parts(
    model: Model,
    files: Files,
    warnings: &mut Vec<String>,
) -> Result<Vec<Part>, ImportError> {
    let file = model.file;
    let gltf::Gltf { document, blob } =
        gltf::Gltf::from_slice_without_validation(model.bytes).map_err(|e| read_error(file, e))?;
    let err =
        |path: String, message: String| ImportError::new(file, Location::Pointer(path), message);
    validate(document.as_json()).map_err(|e| read_error(file, e))?;

    // every buffer's bytes, at least as long as it says
    let mut blob = blob;
    let mut buffers = Vec::new();
    for buffer in document.buffers() {
        let i = buffer.index();
        let data = match buffer.source() {
            gltf::buffer::Source::Bin => blob.take().ok_or_else(|| {
                err(
                    format!("/buffers/{i}"),
                    "the buffer is the GLB's BIN chunk, which the file does not have".into(),
                )
            })?,
            gltf::buffer::Source::Uri(uri) => match resolve(uri, files) {
                Some(Ok(bytes)) => bytes,
                Some(Err(e)) => return Err(err(format!("/buffers/{i}/uri"), e)),
                None => {
                    return Err(err(
                        format!("/buffers/{i}/uri"),
                        format!("the buffer {uri:?} was not given (upload it with the model, or embed it as a data URI)"),
                    ))
                }
            },
        };
        if data.len() < buffer.length() {
            return Err(err(
                format!("/buffers/{i}"),
                format!(
                    "the buffer has {} bytes, fewer than its byteLength {}",
                    data.len(),
                    buffer.length()
                ),
            ));
        }
        buffers.push(data);
    }
    for view in document.views() {
        let end = view.offset().checked_add(view.length());
        if end.is_none_or(|end| end > view.buffer().length()) {
            return Err(err(
                format!("/bufferViews/{}", view.index()),
                "the buffer view lies outside its buffer".into(),
            ));
        }
    }

    // the nodes to draw: the default scene's (or the first scene's, or every root node)
    let roots: Vec<gltf::Node> = match document
        .default_scene()
        .or_else(|| document.scenes().next())
    {
        Some(scene) => scene.nodes().collect(),
        None => {
            let mut child = vec![false; document.nodes().len()];
            for n in document.nodes() {
                for c in n.children() {
                    child[c.index()] = true;
                }
            }
            document.nodes().filter(|n| !child[n.index()]).collect()
        }
    };
    let node_count = document.nodes().len();
    let mut stack: Vec<(gltf::Node, Matrix, usize)> =
        roots.into_iter().rev().map(|n| (n, IDENTITY, 0)).collect();
    let mut materials_seen: std::collections::HashMap<Option<usize>, [f64; 3]> = Default::default();
    let mut parts: Vec<Part> = Vec::new();
    while let Some((node, parent, depth)) = stack.pop() {
        if depth > node_count {
            return Err(err(
                format!("/nodes/{}/children", node.index()),
                "the node hierarchy has a cycle".into(),
            ));
        }
        let local = node.transform().matrix().map(|c| c.map(f64::from));
        let world = multiply(&parent, &local);
        for child in node.children().collect::<Vec<_>>().into_iter().rev() {
            stack.push((child, world, depth + 1));
        }
        let Some(mesh) = node.mesh() else { continue };
        let flip = determinant(&world) < 0.0;
        let object = node
            .name()
            .or(mesh.name())
            .map(str::to_string)
            .unwrap_or_else(|| format!("node{}", node.index()));
        // this node's parts, by material
        let mut mine: Vec<(Option<usize>, Part)> = Vec::new();
        for primitive in mesh.primitives() {
            let at = format!("/meshes/{}/primitives/{}", mesh.index(), primitive.index());
            let mode = primitive.mode();
            if !matches!(
                mode,
                Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan
            ) {
                warnings.push(format!(
                    "{at}: a primitive of points or lines ({mode:?}) has no area; left out"
                ));
                continue;
            }
            let reader = primitive.reader(|b| buffers.get(b.index()).map(|d| d.as_slice()));
            let position = primitive
                .get(&gltf::Semantic::Positions)
                .ok_or_else(|| err(format!("{at}/attributes"), "no POSITION attribute".into()))?;
            let accessor_at = format!("/accessors/{}", position.index());
            let positions: Vec<[f64; 3]> = reader
                .read_positions()
                .ok_or_else(|| {
                    err(
                        accessor_at.clone(),
                        "the POSITION accessor's data lies outside its buffer view (or it has none)".into(),
                    )
                })?
                .map(|p| apply(&world, p))
                .collect();
            if positions.iter().flatten().any(|x| !x.is_finite()) {
                return Err(err(
                    accessor_at,
                    "a position is not a finite number (after the node transforms)".into(),
                ));
            }
            let indices: Vec<u32> = match primitive.indices() {
                Some(acc) => reader
                    .read_indices()
                    .ok_or_else(|| {
                        err(
                            format!("/accessors/{}", acc.index()),
                            "the index accessor's data lies outside its buffer view (or it has none)".into(),
                        )
                    })?
                    .into_u32()
                    .collect(),
                None => (0..positions.len() as u32).collect(),
            };
            if let Some(bad) = indices.iter().find(|&&i| i as usize >= positions.len()) {
                return Err(err(
                    format!("{at}/indices"),
                    format!("index {bad} is past the {} positions", positions.len()),
                ));
            }
            let mut triangles: Vec<[u32; 3]> = match mode {
                Mode::Triangles => indices
                    .chunks_exact(3)
                    .map(|t| [t[0], t[1], t[2]])
                    .collect(),
                Mode::TriangleStrip => (0..indices.len().saturating_sub(2))
                    .map(|i| {
                        let t = [indices[i], indices[i + 1], indices[i + 2]];
                        if i % 2 == 0 {
                            t
                        } else {
                            [t[1], t[0], t[2]]
                        }
                    })
                    .collect(),
                _ => (1..indices.len().saturating_sub(1))
                    .map(|i| [indices[0], indices[i], indices[i + 1]])
                    .collect(),
            };
            if flip {
                for t in &mut triangles {
                    t.swap(1, 2);
                }
            }
            let material = primitive.material();
            let key = material.index();
            let reflectance = match materials_seen.get(&key) {
                Some(r) => *r,
                None => {
                    let pbr = material.pbr_metallic_roughness();
                    let factor = pbr.base_color_factor();
                    let mut r = [0, 1, 2].map(|c| f64::from(factor[c]));
                    if let Some(info) = pbr.base_color_texture() {
                        let image = info.texture().source();
                        match texture_mean(image, &buffers, files) {
                            Ok(mean) => {
                                for c in 0..3 {
                                    r[c] *= mean[c];
                                }
                            }
                            Err(e) => warnings.push(format!(
                                "/images/{}: the base colour texture cannot be read ({e}); baseColorFactor alone is used",
                                info.texture().source().index()
                            )),
                        }
                    }
                    materials_seen.insert(key, r);
                    r
                }
            };
            let strength = f64::from(material.emissive_strength().unwrap_or(1.0));
            let emission = material.emissive_factor().map(|e| f64::from(e) * strength);
            let name = material
                .name()
                .map(str::to_string)
                .or_else(|| key.map(|i| format!("material{i}")));
            let part = match mine.iter_mut().find(|(k, _)| *k == key) {
                Some((_, p)) => p,
                None => {
                    mine.push((
                        key,
                        Part {
                            object: object.clone(),
                            material: name,
                            reflectance,
                            emission,
                            ..Default::default()
                        },
                    ));
                    &mut mine.last_mut().expect("just pushed").1
                }
            };
            let base = part.positions.len() as u32;
            part.positions.extend(positions);
            part.triangles
                .extend(triangles.into_iter().map(|t| t.map(|i| i + base)));
        }
        parts.extend(mine.into_iter().map(|(_, p)| p));
    }
    Ok(parts)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn paths_become_pointers() {
        assert_eq!(
            pointer("meshes[0].primitives[1].indices"),
            "/meshes/0/primitives/1/indices"
        );
        assert_eq!(pointer("accessors[3]"), "/accessors/3");
        assert_eq!(pointer(""), "");
    }

    #[test]
    fn transforms_compose_column_major() {
        let mut t = IDENTITY;
        t[3] = [1.0, 2.0, 3.0, 1.0];
        let mut s = IDENTITY;
        s[0][0] = -2.0;
        let m = multiply(&t, &s);
        assert_eq!(apply(&m, [1.0, 1.0, 1.0]), [-1.0, 3.0, 4.0]);
        assert!(determinant(&m) < 0.0);
    }
}
