//! Wavefront OBJ with its MTL, read by `tobj`: one part per object (`o`, `g`) and material
//! (`usemtl`), polygons fan-triangulated, reflectance from `Kd`, emission from `Ke`.
//!
//! `tobj` says what is wrong but not where; the line is found by reading ever shorter prefixes
//! of the file (a bisection: the first line whose prefix fails), which costs a few more reads
//! only when the file is broken.

use super::{Files, ImportError, Location, Model, Part, DEFAULT_REFLECTANCE};
use std::cell::RefCell;
use std::io::Cursor;

/// The `mtllib` name under which the materials written in the OBJ itself are read.
const INLINE: &str = "\u{1}inline";

fn options() -> tobj::LoadOptions {
    tobj::LoadOptions {
        triangulate: true,
        ignore_points: true,
        ignore_lines: true,
        ..Default::default()
    }
}

/// Reads an OBJ (with `inline`, after a first line that loads its own materials).
fn load(
    text: &[u8],
    inline: bool,
    materials: impl Fn(&std::path::Path) -> tobj::MTLLoadResult,
) -> tobj::LoadResult {
    if inline {
        let head = format!("mtllib {INLINE}\n");
        let mut reader = std::io::Read::chain(Cursor::new(head.as_bytes()), Cursor::new(text));
        tobj::load_obj_buf(&mut reader, &options(), materials)
    } else {
        tobj::load_obj_buf(&mut Cursor::new(text), &options(), materials)
    }
}

/// The first line (from 1) whose prefix of the text fails `fails`; the whole text fails.
fn first_failing_line(text: &[u8], fails: impl Fn(&[u8]) -> bool) -> usize {
    let mut ends: Vec<usize> = text
        .iter()
        .enumerate()
        .filter(|(_, b)| **b == b'\n')
        .map(|(i, _)| i + 1)
        .collect();
    if ends.last() != Some(&text.len()) {
        ends.push(text.len());
    }
    let (mut lo, mut hi) = (1usize, ends.len());
    while lo < hi {
        let mid = (lo + hi) / 2;
        if fails(&text[..ends[mid - 1]]) {
            hi = mid;
        } else {
            lo = mid + 1;
        }
    }
    lo
}

fn message(e: &tobj::LoadError) -> String {
    match e {
        tobj::LoadError::ReadError => "cannot read the line (not UTF-8 text?)".into(),
        e => e.to_string(),
    }
}

/// The first `v` line with a coordinate that is not a finite number.
fn non_finite_line(text: &[u8]) -> Option<usize> {
    String::from_utf8_lossy(text)
        .lines()
        .enumerate()
        .find(|(_, line)| {
            let mut words = line.split_whitespace();
            words.next() == Some("v")
                && words
                    .take(3)
                    .any(|w| w.parse::<f64>().is_ok_and(|x| !x.is_finite()))
        })
        .map(|(i, _)| i + 1)
}

pub(super) fn parts(
    model: Model,
    files: Files,
    warnings: &mut Vec<String>,
) -> Result<Vec<Part>, ImportError> {
    let text = model.bytes;
    // materials written in the OBJ itself (`newmtl` lines) are read as an MTL of their own
    let inline = String::from_utf8_lossy(text)
        .lines()
        .any(|l| l.trim_start().starts_with("newmtl"));
    let mtl_error: RefCell<Option<ImportError>> = RefCell::new(None);
    let missing: RefCell<Vec<String>> = RefCell::new(Vec::new());
    let loader = |path: &std::path::Path| -> tobj::MTLLoadResult {
        let name = path.to_string_lossy().to_string();
        let (file, bytes) = if name == INLINE {
            (model.file.to_string(), text.to_vec())
        } else {
            match files(&name) {
                Some(bytes) => (name.clone(), bytes),
                None => {
                    missing.borrow_mut().push(name);
                    return Err(tobj::LoadError::OpenFileFailed);
                }
            }
        };
        tobj::load_mtl_buf(&mut Cursor::new(&bytes)).inspect_err(|e| {
            let line = first_failing_line(&bytes, |prefix| {
                tobj::load_mtl_buf(&mut Cursor::new(prefix)).is_err()
            });
            mtl_error
                .borrow_mut()
                .get_or_insert_with(|| ImportError::new(&file, Location::Line(line), message(e)));
        })
    };
    let loaded = load(text, inline, loader);
    if let Some(e) = mtl_error.into_inner() {
        return Err(e);
    }
    let (models, materials) = match loaded {
        Ok((models, materials)) => (models, materials.unwrap_or_default()),
        Err(e) => {
            let line = first_failing_line(text, |prefix| {
                load(prefix, false, |_| Ok(Default::default())).is_err()
            });
            return Err(ImportError::new(
                model.file,
                Location::Line(line),
                message(&e),
            ));
        }
    };
    for name in missing.into_inner() {
        warnings.push(format!(
            "mtllib {name:?} was not given: its materials are missing (reflectance {DEFAULT_REFLECTANCE}, no emission)"
        ));
    }
    let mut parts = Vec::with_capacity(models.len());
    for m in models {
        let mesh = &m.mesh;
        let positions: Vec<[f64; 3]> = mesh
            .positions
            .chunks_exact(3)
            .map(|p| [p[0], p[1], p[2]])
            .collect();
        if positions.iter().flatten().any(|x| !x.is_finite()) {
            let location = non_finite_line(text).map_or(Location::Whole, Location::Line);
            return Err(ImportError::new(
                model.file,
                location,
                "a vertex position is not a finite number",
            ));
        }
        let triangles: Vec<[u32; 3]> = mesh
            .indices
            .chunks_exact(3)
            .map(|t| [t[0], t[1], t[2]])
            .collect();
        if triangles.is_empty() {
            continue;
        }
        let object = if m.name == "unnamed_object" {
            "object".to_string()
        } else {
            m.name.clone()
        };
        let material = mesh.material_id.and_then(|i| materials.get(i));
        let (reflectance, emission) = match material {
            Some(mat) => {
                if mat.diffuse.is_none() {
                    warnings.push(format!(
                        "material {:?} has no Kd: reflectance {DEFAULT_REFLECTANCE}",
                        mat.name
                    ));
                }
                (
                    mat.diffuse.unwrap_or([DEFAULT_REFLECTANCE; 3]),
                    mat.emissive.unwrap_or([0.0; 3]),
                )
            }
            None => {
                warnings.push(format!(
                    "object {object:?} has no material (or its material was not found): reflectance {DEFAULT_REFLECTANCE}, no emission"
                ));
                ([DEFAULT_REFLECTANCE; 3], [0.0; 3])
            }
        };
        parts.push(Part {
            object,
            material: material.map(|m| m.name.clone()),
            positions,
            triangles,
            reflectance,
            emission,
        });
    }
    Ok(parts)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_failing_line_is_found() {
        let text = b"v 0 0 0\nv 1 0 0\nv 0 x 0\nf 1 2 3\n";
        let line = first_failing_line(text, |p| {
            load(p, false, |_| Ok(Default::default())).is_err()
        });
        assert_eq!(line, 3);
        assert_eq!(non_finite_line(b"v 0 0 0\nv nan 0 0\n"), Some(2));
    }
}
