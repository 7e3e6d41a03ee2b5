//! Models in, job documents out: Wavefront OBJ with its MTL (`obj`, by `tobj`) and glTF 2.0,
//! as `.gltf` or GLB (`gltf`, by the `gltf` crate), each turned into a 3d job document
//! (`serde_json::Value`) with one `mesh` surface per object and material.
//!
//! No file or network I/O here: the model comes as bytes, and the files it refers to (the MTL of
//! an OBJ, the buffers and images of a glTF) are asked for by name through a `Files` callback,
//! which the command line answers from the model's folder and the server from the parts of an
//! upload.
//!
//! What the document gets: reflectance from the diffuse colour, clamped to [0, 0.99]; emission
//! from OBJ `Ke` or glTF `emissiveFactor` × `KHR_materials_emissive_strength`; triangles of zero
//! area dropped; positions a surface does not use dropped; names unique. Each of these that
//! changes something, and a model without emission, is said in [`Imported::warnings`].

mod gltf;
mod obj;

use crate::scene::Limits;
use serde_json::{json, Value};
use std::fmt;

/// The files a model refers to, by the name it gives them (`mtllib`, a buffer's or image's
/// `uri`): their bytes, or `None` when there is no such file.
type Files<'a> = &'a dyn Fn(&str) -> Option<Vec<u8>>;

/// The largest reflectance an imported surface gets: the document needs ρ < 1.
const MAX_REFLECTANCE: f64 = 0.99;

/// The reflectance of a surface without a material (or whose material was not found).
const DEFAULT_REFLECTANCE: f64 = 0.5;

/// A triangle whose doubled area |e1 × e2| is at most this fraction of its longest edge squared
/// is of zero area (collinear or repeated corners) and is dropped.
const ZERO_AREA: f64 = 1e-9;

/// The kinds of model read.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Format {
    /// Wavefront OBJ (its materials in an MTL file, or in the OBJ itself).
    Obj,
    /// glTF 2.0 JSON (`.gltf`).
    Gltf,
    /// Binary glTF (`.glb`).
    Glb,
}

impl Format {
    /// From a media type: `model/obj`, `model/gltf+json`, `model/gltf-binary`.
    pub(crate) fn from_media_type(mime: &str) -> Option<Format> {
        let mime = mime.split(';').next().unwrap_or("").trim();
        match mime.to_ascii_lowercase().as_str() {
            "model/obj" => Some(Format::Obj),
            "model/gltf+json" => Some(Format::Gltf),
            "model/gltf-binary" => Some(Format::Glb),
            _ => None,
        }
    }

    /// From a file name's extension: `.obj`, `.gltf`, `.glb` (any case).
    pub fn from_file_name(name: &str) -> Option<Format> {
        let ext = name.rsplit_once('.')?.1.to_ascii_lowercase();
        match ext.as_str() {
            "obj" => Some(Format::Obj),
            "gltf" => Some(Format::Gltf),
            "glb" => Some(Format::Glb),
            _ => None,
        }
    }
}

/// A model to import: its file name (the scene is named after it, errors say it), its format
/// and its bytes.
#[derive(Debug, Clone, Copy)]
pub struct Model<'a> {
    pub file: &'a str,
    pub format: Format,
    pub bytes: &'a [u8],
}

/// Where in a model an error is.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Location {
    /// The model as a whole (no triangles at all, a file missing, …).
    Whole,
    /// A line of an OBJ or MTL file, from 1.
    Line(usize),
    /// A JSON pointer into a glTF document (`/meshes/0/primitives/1/indices`).
    Pointer(String),
}

/// A model that cannot be imported: the file at fault, where in it, and what is wrong.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ImportError {
    pub file: String,
    pub location: Location,
    pub message: String,
}

impl ImportError {
    fn new(file: &str, location: Location, message: impl Into<String>) -> ImportError {
        ImportError {
            file: file.to_string(),
            location,
            message: message.into(),
        }
    }

    /// The JSON pointer of a glTF error, or `""`.
    pub(crate) fn pointer(&self) -> &str {
        match &self.location {
            Location::Pointer(p) => p,
            _ => "",
        }
    }

    /// The line of an OBJ or MTL error.
    pub(crate) fn line(&self) -> Option<usize> {
        match self.location {
            Location::Line(n) => Some(n),
            _ => None,
        }
    }
}

impl fmt::Display for ImportError {
    fn fmt(&self, f: &mut fmt::Formatter) -> fmt::Result {
        match &self.location {
            Location::Whole => write!(f, "{}: {}", self.file, self.message),
            Location::Line(n) => write!(f, "{} line {n}: {}", self.file, self.message),
            Location::Pointer(p) => write!(f, "{} at {p}: {}", self.file, self.message),
        }
    }
}

impl std::error::Error for ImportError {}

/// An imported model: the job document and what the import changed or could not take over.
#[derive(Debug, Clone)]
pub struct Imported {
    pub document: Value,
    pub warnings: Vec<String>,
    /// Surfaces and triangles in the document.
    pub surfaces: usize,
    pub triangles: usize,
}

/// Imports a model: the job document of [`Imported`], or where the model is broken. `limits`
/// only adds a warning when the document has more surfaces than they allow.
/// A reader that stops on a model it did not expect (a panic in a crate) is answered as a
/// model that cannot be read, not passed on.
pub fn import(model: Model, files: Files, limits: &Limits) -> Result<Imported, ImportError> {
    let mut warnings = Vec::new();
    let read = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| match model.format {
        Format::Obj => obj::parts(model, files, &mut warnings),
        Format::Gltf | Format::Glb => gltf::parts(model, files, &mut warnings),
    }));
    let parts = read.unwrap_or_else(|panic| {
        let why = panic
            .downcast_ref::<&str>()
            .map(|s| s.to_string())
            .or_else(|| panic.downcast_ref::<String>().cloned())
            .unwrap_or_default();
        Err(ImportError::new(
            model.file,
            Location::Whole,
            format!("the model cannot be read ({why})"),
        ))
    })?;
    assemble(model.file, parts, warnings, limits)
}

/// One object in one material: triangles over positions, with the material's colours as read.
#[derive(Debug, Clone, Default)]
struct Part {
    object: String,
    material: Option<String>,
    positions: Vec<[f64; 3]>,
    triangles: Vec<[u32; 3]>,
    reflectance: [f64; 3],
    emission: [f64; 3],
}

/// The scene's name: the file name without folders and extension.
fn stem(file: &str) -> &str {
    let base = file.rsplit(['/', '\\']).next().unwrap_or(file);
    match base.rsplit_once('.') {
        Some((s, _)) if !s.is_empty() => s,
        _ => base,
    }
}

/// Twice the area of a triangle, and its longest edge squared.
fn doubled_area(p: [f64; 3], q: [f64; 3], r: [f64; 3]) -> (f64, f64) {
    let e1 = [q[0] - p[0], q[1] - p[1], q[2] - p[2]];
    let e2 = [r[0] - p[0], r[1] - p[1], r[2] - p[2]];
    let e3 = [r[0] - q[0], r[1] - q[1], r[2] - q[2]];
    let c = [
        e1[1] * e2[2] - e1[2] * e2[1],
        e1[2] * e2[0] - e1[0] * e2[2],
        e1[0] * e2[1] - e1[1] * e2[0],
    ];
    let n2 = |v: [f64; 3]| v[0] * v[0] + v[1] * v[1] + v[2] * v[2];
    (n2(c).sqrt(), n2(e1).max(n2(e2)).max(n2(e3)))
}

fn colour(v: [f64; 3]) -> String {
    format!("[{}, {}, {}]", v[0], v[1], v[2])
}

/// Names, clean-up and the document.
fn assemble(
    file: &str,
    parts: Vec<Part>,
    mut warnings: Vec<String>,
    limits: &Limits,
) -> Result<Imported, ImportError> {
    // an object in several materials is one surface per material, named object-material
    let mut materials_of: std::collections::HashMap<&str, std::collections::HashSet<Option<&str>>> =
        Default::default();
    for p in &parts {
        materials_of
            .entry(p.object.as_str())
            .or_default()
            .insert(p.material.as_deref());
    }
    let wanted: Vec<String> = parts
        .iter()
        .map(|p| {
            let object = if p.object.trim().is_empty() {
                "object"
            } else {
                p.object.trim()
            };
            match (&p.material, materials_of[p.object.as_str()].len() > 1) {
                (Some(m), true) => format!("{object}-{m}"),
                _ => object.to_string(),
            }
        })
        .collect();
    let mut taken: std::collections::HashSet<String> = Default::default();
    let mut surfaces = Vec::with_capacity(parts.len());
    let mut triangles_total = 0;
    let mut lit = false;
    for (part, want) in parts.into_iter().zip(wanted) {
        let mut name = want.clone();
        let mut k = 2;
        while taken.contains(&name) {
            name = format!("{want}-{k}");
            k += 1;
        }
        if name != want {
            warnings.push(format!(
                "the name {want:?} is given twice: this surface is named {name:?}"
            ));
        }
        // triangles of zero area out, then only the positions still used, in their order
        let mut kept = Vec::with_capacity(part.triangles.len());
        let mut dropped = 0usize;
        for t in &part.triangles {
            let [a, b, c] = t.map(|i| part.positions[i as usize]);
            let (area2, edge2) = doubled_area(a, b, c);
            if area2 > ZERO_AREA * edge2 && area2 > 0.0 {
                kept.push(*t);
            } else {
                dropped += 1;
            }
        }
        if dropped > 0 {
            warnings.push(format!(
                "surface {name:?}: {dropped} triangle(s) of zero area dropped"
            ));
        }
        if kept.is_empty() {
            warnings.push(format!(
                "object {:?}: no triangle of non-zero area; left out",
                part.object
            ));
            continue;
        }
        let mut index = vec![u32::MAX; part.positions.len()];
        let mut positions = Vec::new();
        for t in kept.iter_mut() {
            for i in t.iter_mut() {
                let slot = &mut index[*i as usize];
                if *slot == u32::MAX {
                    *slot = positions.len() as u32;
                    positions.push(part.positions[*i as usize]);
                }
                *i = *slot;
            }
        }
        let mut reflectance = part.reflectance;
        if reflectance.iter().any(|r| !r.is_finite() || *r < 0.0) {
            warnings.push(format!(
                "surface {name:?}: reflectance {} has a negative or non-finite channel, taken as 0",
                colour(reflectance)
            ));
            reflectance = reflectance.map(|r| if r.is_finite() { r.max(0.0) } else { 0.0 });
        }
        if reflectance.iter().any(|r| *r > MAX_REFLECTANCE) {
            let clamped = reflectance.map(|r| r.min(MAX_REFLECTANCE));
            warnings.push(format!(
                "surface {name:?}: reflectance {} clamped to {} (a surface must absorb some light: ρ < 1)",
                colour(reflectance),
                colour(clamped)
            ));
            reflectance = clamped;
        }
        let mut emission = part.emission;
        if emission.iter().any(|e| !e.is_finite() || *e < 0.0) {
            warnings.push(format!(
                "surface {name:?}: emission {} has a negative or non-finite channel, taken as 0",
                colour(emission)
            ));
            emission = emission.map(|e| if e.is_finite() { e.max(0.0) } else { 0.0 });
        }
        lit |= emission.iter().any(|e| *e > 0.0);
        triangles_total += kept.len();
        taken.insert(name.clone());
        surfaces.push(json!({
            "name": name,
            "reflectance": reflectance,
            "emission": emission,
            "mesh": {"positions": positions, "triangles": kept},
        }));
    }
    if surfaces.is_empty() {
        return Err(ImportError::new(
            file,
            Location::Whole,
            "the model has no triangles of non-zero area",
        ));
    }
    if !lit {
        warnings.push(
            "the model emits no light (no OBJ Ke, no glTF emissiveFactor): the solve will need a light; give a surface an emission"
                .into(),
        );
    }
    if surfaces.len() > limits.max_surfaces {
        warnings.push(format!(
            "{} surfaces, more than max_surfaces ({}): merge objects or raise the limit before solving",
            surfaces.len(),
            limits.max_surfaces
        ));
    }
    let count = surfaces.len();
    let document = json!({
        "scene": {"kind": "3d", "name": stem(file), "surfaces": surfaces},
        // meshes are solved by the hierarchical method (the projection method takes
        // parallelograms only); everything else at its default
        "solver": {"method": "hierarchical"},
        "output": {},
    });
    Ok(Imported {
        document,
        warnings,
        surfaces: count,
        triangles: triangles_total,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn formats_by_name_and_type() {
        assert_eq!(Format::from_file_name("a/b.OBJ"), Some(Format::Obj));
        assert_eq!(Format::from_file_name("x.glb"), Some(Format::Glb));
        assert_eq!(Format::from_file_name("x.gltf"), Some(Format::Gltf));
        assert_eq!(Format::from_file_name("x.json"), None);
        assert_eq!(
            Format::from_media_type("model/gltf+json; charset=utf-8"),
            Some(Format::Gltf)
        );
        assert_eq!(Format::from_media_type("application/json"), None);
        assert_eq!(stem("dir/room.obj"), "room");
        assert_eq!(stem("room"), "room");
    }
}
