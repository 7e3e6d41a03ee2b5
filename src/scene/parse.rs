//! Stage two of the document: from a raw JSON value to a validated [`Job`], every error at once.

use super::walk::{child, index, Walker};
use super::*;
use serde_json::{Map, Value};

/// Parses JSON text. A text that is not JSON at all gives one error at the root path.
pub fn parse_document(text: &str, limits: &Limits) -> Result<Job, DocumentErrors> {
    let value: Value = serde_json::from_str(text).map_err(|e| {
        DocumentErrors(vec![FieldError {
            path: String::new(),
            message: format!("not valid JSON: {e}"),
        }])
    })?;
    parse_text(text, &value, limits)
}

/// [`parse_value`] of `value`, parsed from `text`, with the names that `text` repeats within
/// one object (`super::repeated_keys`) among the errors: the value keeps only the last.
pub fn parse_text(text: &str, value: &Value, limits: &Limits) -> Result<Job, DocumentErrors> {
    let repeated = super::repeated_keys(text);
    match parse_value(value, limits) {
        Ok(job) if repeated.is_empty() => Ok(job),
        Ok(_) => Err(DocumentErrors(repeated)),
        Err(DocumentErrors(mut errors)) => {
            errors.extend(repeated);
            Err(DocumentErrors(errors))
        }
    }
}

/// Validates a JSON value as a job document, applying every default of the spec.
pub fn parse_value(v: &Value, limits: &Limits) -> Result<Job, DocumentErrors> {
    let mut w = Walker::default();
    let job = document(&mut w, v, limits);
    match job {
        Some(job) if w.errors.is_empty() => Ok(job),
        _ => Err(DocumentErrors(w.errors)),
    }
}

fn document(w: &mut Walker, v: &Value, limits: &Limits) -> Option<Job> {
    let root = w.object(v, "", &["scene", "solver", "output"])?;
    let scene = w
        .required(root, "", "scene")
        .and_then(|s| scene(w, s, limits));
    let kind_name = root
        .get("scene")
        .and_then(|s| s.get("kind"))
        .and_then(Value::as_str);
    let solver = match root.get("solver") {
        Some(s) => solver(w, s, limits, kind_name),
        None => Some(Parsed::valid(Solver::default())),
    };
    let output = match root.get("output") {
        Some(o) => output(w, o, limits),
        None => Some(Parsed::valid(Output::default())),
    };
    // the checks across parts need only the scene's kind and size, so they run beside any
    // error inside a surface, on the fields of solver and output that parsed
    if let (Some(shape), Some(s), Some(o)) = (Shape::of(root, limits), &solver, &output) {
        cross_checks(w, &shape, &s.value, &o.value, limits);
    }
    if let (Some(scene), Some(s)) = (&scene, &solver) {
        finest_elements(w, scene, &s.value, limits);
        triangles_need_the_hierarchy(w, scene, &s.value);
    }
    let scene = scene?;
    let mut output = output?.ok()?;
    // scene.md: a fredholm equation's `exact` solution, when given, is what the error
    // metrics are measured against, unless the document asks for a finer solve instead
    if matches!(&scene.kind, SceneKind::Fredholm(f) if f.exact.is_some())
        && output.reference.is_none()
    {
        output.reference = Some(Reference::Exact);
    }
    Some(Job {
        scene,
        solver: solver?.ok()?,
        output,
    })
}

/// `min_element_size` may not ask for more elements along a surface's side than
/// `max_resolution` allows (the default, at least a 256th of the scene's diagonal, never does).
fn finest_elements(w: &mut Walker, scene: &Scene, solver: &Solver, limits: &Limits) {
    let (SceneKind::ThreeD(quads), Some(size)) = (&scene.kind, solver.min_element_size) else {
        return;
    };
    let side = |a: [f64; 3], b: [f64; 3]| {
        ((b[0] - a[0]).powi(2) + (b[1] - a[1]).powi(2) + (b[2] - a[2]).powi(2)).sqrt()
    };
    let longest = quads
        .iter()
        .map(|q| {
            let c = q.polygon();
            (0..c.len())
                .map(|i| side(c[i], c[(i + 1) % c.len()]))
                .fold(0.0, f64::max)
        })
        .fold(0.0, f64::max);
    let per_side = longest / size;
    if per_side > limits.max_resolution as f64 {
        w.error(
            "/solver/min_element_size",
            format!(
                "{size} would split the longest side ({longest}) into {per_side:.0} elements, more than max_resolution ({})",
                limits.max_resolution
            ),
        );
    }
}

/// The projection method works on parallelograms only: `triangle` and `mesh` surfaces need
/// `method: "hierarchical"`.
fn triangles_need_the_hierarchy(w: &mut Walker, scene: &Scene, solver: &Solver) {
    let SceneKind::ThreeD(d) = &scene.kind else {
        return;
    };
    if solver.method != Method::Projection {
        return;
    }
    for (i, s) in d.surfaces.iter().enumerate() {
        let field = match s.shape {
            Shape3::Parallelogram => continue,
            Shape3::Triangle => "triangle",
            Shape3::Mesh { .. } => "mesh",
        };
        w.error(
            format!("/scene/surfaces/{i}/{field}"),
            format!("the projection method takes parallelograms only; solve a {field} with solver.method \"hierarchical\""),
        );
    }
}

/// A part of the document as far as it parsed: its invalid fields hold their defaults (their
/// errors are in the walker), so that the checks across parts can still run.
struct Parsed<T> {
    value: T,
    ok: bool,
}

impl<T> Parsed<T> {
    fn valid(value: T) -> Parsed<T> {
        Parsed { value, ok: true }
    }

    fn ok(self) -> Option<T> {
        self.ok.then_some(self.value)
    }
}

/// What the checks across parts need of the scene, read from the raw document so that they
/// run whether or not its surfaces are valid.
struct Shape {
    /// 1 (flatland, fredholm) or 2 (3d).
    dims: u32,
    surfaces: usize,
    /// A fredholm scene with an `exact` solution.
    exact: bool,
}

impl Shape {
    fn of(root: &Map<String, Value>, limits: &Limits) -> Option<Shape> {
        let scene = root.get("scene")?;
        let count = || {
            let n = scene.get("surfaces")?.as_array()?.len();
            (1..=limits.max_surfaces).contains(&n).then_some(n)
        };
        let (dims, surfaces) = match scene.get("kind")?.as_str()? {
            "flatland" => (1, count()?),
            "3d" => (2, count()?),
            "fredholm" => (1, 1),
            _ => return None,
        };
        Some(Shape {
            dims,
            surfaces,
            exact: scene.get("exact").is_some(),
        })
    }

    /// The unknowns of the projection method at this order and resolution.
    fn basis_size(&self, order: usize, resolution: usize) -> usize {
        let per_side = resolution.saturating_mul(order + 1);
        self.surfaces
            .saturating_mul(per_side.saturating_pow(self.dims))
    }
}

fn scene(w: &mut Walker, v: &Value, limits: &Limits) -> Option<Scene> {
    let path = "/scene";
    let kind = v
        .get("kind")
        .and_then(Value::as_str)
        .filter(|k| ["flatland", "3d", "fredholm"].contains(k));
    let allowed: &[&str] = match kind {
        Some("fredholm") => &["kind", "name", "domain", "kernel", "source", "exact"],
        Some(_) => &["kind", "name", "surfaces"],
        None => &[
            "kind", "name", "surfaces", "domain", "kernel", "source", "exact",
        ],
    };
    let map = w.object(v, path, allowed)?;
    let kind_value = w.required(map, path, "kind");
    if let Some(k) = kind_value {
        w.choice(k, &child(path, "kind"), &["flatland", "3d", "fredholm"]);
    }
    let name = map
        .get("name")
        .and_then(|n| w.string(n, "/scene/name"))
        .map(str::to_string);
    let kind = match kind? {
        "fredholm" => SceneKind::Fredholm(fredholm(w, map)?),
        k => {
            let surfaces = w.required(map, path, "surfaces")?;
            let p = "/scene/surfaces";
            let Some(list) = surfaces.as_array() else {
                w.error(p, "expected an array of surfaces");
                return None;
            };
            if list.is_empty() || list.len() > limits.max_surfaces {
                w.error(
                    p,
                    format!(
                        "a scene has 1 to {} surfaces (max_surfaces); found {}",
                        limits.max_surfaces,
                        list.len()
                    ),
                );
                return None;
            }
            // the checks across surfaces run over those that parsed, so that a document with
            // a bad field elsewhere still hears of them
            if k == "flatland" {
                let segs: Vec<Option<Segment>> = list
                    .iter()
                    .enumerate()
                    .map(|(i, s)| segment(w, s, &index(p, i)))
                    .collect();
                check_surfaces(
                    w,
                    list,
                    segs.iter()
                        .map(|s| s.as_ref().map(|s| (&s.name, &s.material))),
                );
                let segs: Option<Vec<Segment>> = segs.into_iter().collect();
                SceneKind::Flatland(segs?)
            } else {
                let parsed: Vec<Option<(Surface3, Vec<Quad>)>> = list
                    .iter()
                    .enumerate()
                    .map(|(i, s)| surface3(w, s, &index(p, i)))
                    .collect();
                check_surfaces(
                    w,
                    list,
                    parsed
                        .iter()
                        .map(|q| q.as_ref().map(|(s, q)| (&s.name, &q[0].material))),
                );
                let triangles: usize = parsed
                    .iter()
                    .flatten()
                    .filter(|(s, _)| !matches!(s.shape, Shape3::Parallelogram))
                    .map(|(_, q)| q.len())
                    .sum();
                if triangles > limits.max_triangles {
                    w.error(
                        p,
                        format!(
                            "the scene has {triangles} triangles, more than max_triangles ({})",
                            limits.max_triangles
                        ),
                    );
                    return None;
                }
                let parsed: Option<Vec<(Surface3, Vec<Quad>)>> = parsed.into_iter().collect();
                let mut scene = ThreeD {
                    surfaces: Vec::new(),
                    patches: Vec::new(),
                };
                for (mut s, q) in parsed? {
                    let at = scene.patches.len();
                    s.patches = at..at + q.len();
                    scene.surfaces.push(s);
                    scene.patches.extend(q);
                }
                SceneKind::ThreeD(scene)
            }
        }
    };
    Some(Scene { name, kind })
}

/// Names are unique, and some surface emits. Names are read from every surface that has a
/// valid one, also those with an error in another field. A surface that did not parse counts
/// as emitting if its `emission` reads as a positive number, so that its own error is not
/// followed by a wrong one.
fn check_surfaces<'a>(
    w: &mut Walker,
    raw: &[Value],
    parsed: impl Iterator<Item = Option<(&'a String, &'a Material)>>,
) {
    let mut seen = std::collections::HashMap::new();
    let mut any = false;
    for (i, (surface, raw)) in parsed.zip(raw).enumerate() {
        let name = match surface {
            Some((n, m)) => {
                any |= m.emission.iter().any(|e| *e > 0.0);
                Some(n.as_str())
            }
            None => {
                let positive = |v: &Value| v.as_f64().is_some_and(|x| x > 0.0);
                any |= raw.get("emission").is_some_and(|e| {
                    positive(e) || e.as_array().is_some_and(|a| a.iter().any(positive))
                });
                raw.get("name")
                    .and_then(Value::as_str)
                    .filter(|n| valid_name(n))
            }
        };
        let Some(n) = name else { continue };
        if let Some(first) = seen.insert(n, i) {
            w.error(
                format!("/scene/surfaces/{i}/name"),
                format!("duplicate surface name \"{n}\" (also surface {first})"),
            );
            seen.insert(n, first);
        }
    }
    if !any {
        w.error(
            "/scene/surfaces",
            "the scene emits no light: give at least one surface a positive emission",
        );
    }
}

fn fredholm(w: &mut Walker, map: &Map<String, Value>) -> Option<Fredholm> {
    let path = "/scene";
    let domain = w.required(map, path, "domain").and_then(|d| {
        let p = "/scene/domain";
        let [a, b] = w.coordinates::<2>(d, p)?;
        if a >= b {
            w.error(
                p,
                format!("the domain [a, b] needs a < b; found [{a}, {b}]"),
            );
            return None;
        }
        Some([a, b])
    });
    let mut expression = |key: &str, vars: &[&str], required: bool| -> Option<Option<Expr>> {
        let p = child(path, key);
        let Some(v) = map.get(key) else {
            if required {
                w.error(&p, format!("missing required field `{key}`"));
                return None;
            }
            return Some(None);
        };
        let text = w.string(v, &p)?;
        match Expr::parse(text, vars) {
            Ok(e) => Some(Some(e)),
            Err(e) => {
                w.error(&p, e.0);
                None
            }
        }
    };
    let kernel = expression("kernel", &["x", "y"], true);
    let source = expression("source", &["x"], true);
    let exact = expression("exact", &["x"], false);
    Some(Fredholm {
        domain: domain?,
        kernel: kernel??,
        source: source??,
        exact: exact?,
    })
}

fn material(w: &mut Walker, map: &Map<String, Value>, path: &str) -> Option<Material> {
    let reflectance = w.required(map, path, "reflectance").and_then(|r| {
        rgb(
            w,
            r,
            &child(path, "reflectance"),
            |x| (0.0..1.0).contains(&x),
            "reflectance is in [0, 1)",
        )
    });
    let emission = match map.get("emission") {
        Some(e) => rgb(
            w,
            e,
            &child(path, "emission"),
            // B reaches E / (1 − ρ) and its squares are summed: beyond 1e12 they overflow
            |x| (0.0..=1e12).contains(&x),
            "emission is from 0 to 1e12",
        ),
        None => Some([0.0; 3]),
    };
    Some(Material {
        reflectance: reflectance?,
        emission: emission?,
    })
}

/// A number (the same for the three channels) or `[r, g, b]`.
fn rgb(w: &mut Walker, v: &Value, path: &str, ok: fn(f64) -> bool, what: &str) -> Option<Rgb> {
    if v.is_number() {
        let x = w.number_in(v, path, ok, what)?;
        return Some([x; 3]);
    }
    if !v.is_array() {
        w.error(path, "expected a number or [r, g, b]");
        return None;
    }
    let arr = w.array_len(v, path, 3)?;
    let mut out = [0.0; 3];
    let mut good = true;
    for (i, x) in arr.iter().enumerate() {
        match w.number_in(x, &index(path, i), ok, what) {
            Some(x) => out[i] = x,
            None => good = false,
        }
    }
    good.then_some(out)
}

fn surface_name(w: &mut Walker, map: &Map<String, Value>, path: &str) -> Option<String> {
    let n = w.required(map, path, "name")?;
    let p = child(path, "name");
    let s = w.string(n, &p)?;
    if !valid_name(s) {
        w.error(
            &p,
            "a surface name is 1 to 128 characters with no slash or control character",
        );
        return None;
    }
    Some(s.to_string())
}

/// 1 to 128 characters, none of them a slash or a control character (a name is a path
/// segment of `surfaces/<name>.png`).
fn valid_name(s: &str) -> bool {
    !s.is_empty() && s.len() <= 128 && !s.contains(['/', '\\']) && !s.chars().any(char::is_control)
}

fn interval(w: &mut Walker, v: &Value, path: &str) -> Option<[f64; 2]> {
    let [a, b] = w.numbers::<2>(v, path)?;
    if !(0.0 <= a && a < b && b <= 1.0) {
        w.error(
            path,
            format!("expected [s0, s1] with 0 ≤ s0 < s1 ≤ 1; found [{a}, {b}]"),
        );
        return None;
    }
    Some([a, b])
}

fn segment(w: &mut Walker, v: &Value, path: &str) -> Option<Segment> {
    let map = w.object(
        v,
        path,
        &[
            "name",
            "segment",
            "reflectance",
            "emission",
            "emission_region",
        ],
    )?;
    let name = surface_name(w, map, path);
    let ends = w.required(map, path, "segment").and_then(|s| {
        let p = child(path, "segment");
        let arr = w.array_len(s, &p, 2)?;
        let a = w.coordinates::<2>(&arr[0], &index(&p, 0));
        let b = w.coordinates::<2>(&arr[1], &index(&p, 1));
        let (a, b) = (a?, b?);
        let len = (b[0] - a[0]).hypot(b[1] - a[1]);
        let size = a.iter().chain(&b).fold(0.0f64, |m, x| m.max(x.abs()));
        if len <= 1e-12 * size.max(1e-300) || len == 0.0 {
            w.error(&p, "the segment has zero length");
            return None;
        }
        Some((a, b))
    });
    let material = material(w, map, path);
    let region = match map.get("emission_region") {
        Some(r) => interval(w, r, &child(path, "emission_region")),
        None => Some([0.0, 1.0]),
    };
    let (a, b) = ends?;
    Some(Segment {
        name: name?,
        a,
        b,
        material: material?,
        emission_region: region?,
    })
}

/// A 3D surface: exactly one of `corners`, `triangle`, `mesh`; its patches.
fn surface3(w: &mut Walker, v: &Value, path: &str) -> Option<(Surface3, Vec<Quad>)> {
    let map = w.object(
        v,
        path,
        &[
            "name",
            "corners",
            "triangle",
            "mesh",
            "reflectance",
            "emission",
            "emission_region",
        ],
    )?;
    let name = surface_name(w, map, path);
    let given: Vec<&str> = ["corners", "triangle", "mesh"]
        .into_iter()
        .filter(|k| map.contains_key(*k))
        .collect();
    let material = material(w, map, path);
    if given.len() != 1 {
        w.error(
            path,
            if given.is_empty() {
                "a 3d surface needs one of `corners`, `triangle`, `mesh`: missing required field"
                    .to_string()
            } else {
                format!(
                    "a 3d surface has exactly one of `corners`, `triangle`, `mesh`; found {}",
                    given.join(", ")
                )
            },
        );
        return None;
    }
    let region = match map.get("emission_region") {
        Some(_) if given[0] != "corners" => {
            w.error(
                child(path, "emission_region"),
                "an emission region is for parallelograms only; give the lit part its own triangles",
            );
            None
        }
        Some(r) => {
            let p = child(path, "emission_region");
            w.object(r, &p, &["s", "t"]).and_then(|m| {
                let s = w
                    .required(m, &p, "s")
                    .and_then(|s| interval(w, s, &child(&p, "s")));
                let t = w
                    .required(m, &p, "t")
                    .and_then(|t| interval(w, t, &child(&p, "t")));
                Some((s?, t?))
            })
        }
        None => Some(([0.0, 1.0], [0.0, 1.0])),
    };
    let p = child(path, given[0]);
    match given[0] {
        "corners" => {
            let corners = points(w, &map["corners"], &p, Some(4)).and_then(|pts| {
                let c = [pts[0], pts[1], pts[2], pts[3]];
                check_parallelogram(w, &c, &p).then_some(c)
            });
            let (name, material) = (name?, material?);
            Some((
                Surface3 {
                    name: name.clone(),
                    shape: Shape3::Parallelogram,
                    patches: 0..1,
                },
                vec![Quad {
                    name,
                    corners: corners?,
                    material,
                    emission_region: region?,
                    triangle: false,
                }],
            ))
        }
        "triangle" => {
            let t = points(w, &map["triangle"], &p, Some(3)).and_then(|pts| {
                let t = [pts[0], pts[1], pts[2]];
                check_triangle(w, &t, &p).then_some(t)
            });
            let (name, material) = (name?, material?);
            region?;
            Some((
                Surface3 {
                    name: name.clone(),
                    shape: Shape3::Triangle,
                    patches: 0..1,
                },
                vec![Quad::triangle(name, t?, material)],
            ))
        }
        _ => {
            let mesh = mesh(w, &map["mesh"], &p);
            let (name, material, (positions, triangles)) = (name?, material?, mesh?);
            region?;
            let patches = triangles
                .iter()
                .map(|t| Quad::triangle(name.clone(), t.map(|i| positions[i]), material.clone()))
                .collect::<Vec<_>>();
            Some((
                Surface3 {
                    name,
                    shape: Shape3::Mesh {
                        positions,
                        triangles,
                    },
                    patches: 0..patches.len(),
                },
                patches,
            ))
        }
    }
}

/// An array of points `[x, y, z]`, of exactly `n` when given.
fn points(w: &mut Walker, v: &Value, path: &str, n: Option<usize>) -> Option<Vec<[f64; 3]>> {
    let arr = match n {
        Some(n) => w.array_len(v, path, n)?,
        None => match v.as_array() {
            Some(a) if !a.is_empty() => a.as_slice(),
            _ => {
                w.error(path, "expected a non-empty array of [x, y, z]");
                return None;
            }
        },
    };
    let before = w.errors.len();
    let mut out = Vec::with_capacity(arr.len());
    for (i, x) in arr.iter().enumerate() {
        if let Some(p) = w.coordinates::<3>(x, &index(path, i)) {
            out.push(p);
        }
        if w.errors.len() - before >= MAX_ERRORS_PER_LIST {
            return None;
        }
    }
    (out.len() == arr.len()).then_some(out)
}

/// At most this many errors are reported from one list of a mesh: a broken export can have a
/// million bad entries, and the first few say what is wrong.
const MAX_ERRORS_PER_LIST: usize = 20;

/// `{"positions": [...], "triangles": [[i, j, k], ...]}`: indices in range, no triangle of
/// zero area.
#[allow(clippy::type_complexity)]
fn mesh(w: &mut Walker, v: &Value, path: &str) -> Option<(Vec<[f64; 3]>, Vec<[usize; 3]>)> {
    let map = w.object(v, path, &["positions", "triangles"])?;
    let positions = w
        .required(map, path, "positions")
        .and_then(|p| points(w, p, &child(path, "positions"), None));
    let tp = child(path, "triangles");
    let raw = w.required(map, path, "triangles")?;
    let Some(list) = raw.as_array().filter(|a| !a.is_empty()) else {
        w.error(&tp, "expected a non-empty array of [i, j, k]");
        return None;
    };
    let n = positions.as_ref().map_or(u32::MAX as usize, Vec::len);
    let before = w.errors.len();
    let mut triangles = Vec::with_capacity(list.len());
    for (i, t) in list.iter().enumerate() {
        if w.errors.len() - before >= MAX_ERRORS_PER_LIST {
            return None;
        }
        let p = index(&tp, i);
        let Some(arr) = w.array_len(t, &p, 3) else {
            continue;
        };
        let mut ix = [0usize; 3];
        let mut ok = true;
        for (j, x) in arr.iter().enumerate() {
            match x.as_u64() {
                Some(x) if (x as usize) < n => ix[j] = x as usize,
                Some(x) => {
                    w.error(
                        index(&p, j),
                        format!("index {x} is out of range: the mesh has {n} positions"),
                    );
                    ok = false;
                }
                None => {
                    w.error(index(&p, j), "expected an index (an integer ≥ 0)");
                    ok = false;
                }
            }
        }
        if !ok {
            continue;
        }
        if let Some(pos) = &positions {
            if !check_triangle(w, &ix.map(|i| pos[i]), &p) {
                continue;
            }
        }
        triangles.push(ix);
    }
    let positions = positions?;
    (triangles.len() == list.len()).then_some((positions, triangles))
}

/// A triangle of non-zero area: |(p1 − p0) × (p2 − p0)| above 1e-12 of its longest side squared.
fn check_triangle(w: &mut Walker, t: &[[f64; 3]; 3], path: &str) -> bool {
    let sub = |a: [f64; 3], b: [f64; 3]| [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
    let norm = |a: [f64; 3]| (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt();
    let (e1, e2) = (sub(t[1], t[0]), sub(t[2], t[0]));
    let size = norm(e1).max(norm(e2)).max(norm(sub(t[2], t[1])));
    let cross = [
        e1[1] * e2[2] - e1[2] * e2[1],
        e1[2] * e2[0] - e1[0] * e2[2],
        e1[0] * e2[1] - e1[1] * e2[0],
    ];
    if size == 0.0 || norm(cross) <= 1e-12 * size * size {
        w.error(
            path,
            "the triangle has zero area (its corners are collinear or equal)",
        );
        return false;
    }
    true
}

/// p0 + p2 = p1 + p3 within 1e-6 of the size, and a non-zero area.
fn check_parallelogram(w: &mut Walker, c: &[[f64; 3]; 4], path: &str) -> bool {
    let sub = |a: [f64; 3], b: [f64; 3]| [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
    let norm = |a: [f64; 3]| (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt();
    let e1 = sub(c[1], c[0]);
    let e3 = sub(c[3], c[0]);
    let size = norm(e1).max(norm(e3)).max(norm(sub(c[2], c[0])));
    let gap = norm(sub(
        [c[0][0] + c[2][0], c[0][1] + c[2][1], c[0][2] + c[2][2]],
        [c[1][0] + c[3][0], c[1][1] + c[3][1], c[1][2] + c[3][2]],
    ));
    let cross = [
        e1[1] * e3[2] - e1[2] * e3[1],
        e1[2] * e3[0] - e1[0] * e3[2],
        e1[0] * e3[1] - e1[1] * e3[0],
    ];
    if size == 0.0 || norm(cross) <= 1e-12 * size * size {
        w.error(
            path,
            "the surface has zero area (its corners are collinear or equal)",
        );
        return false;
    }
    if gap > 1e-6 * size {
        w.error(
            path,
            format!("the corners are not a parallelogram: p0 + p2 − p1 − p3 has length {gap:.3e}, more than 1e-6 of the size {size:.3e}"),
        );
        return false;
    }
    true
}

fn solver(
    w: &mut Walker,
    v: &Value,
    limits: &Limits,
    kind: Option<&str>,
) -> Option<Parsed<Solver>> {
    let path = "/solver";
    let map = w.object(
        v,
        path,
        &[
            "method",
            "basis",
            "order",
            "resolution",
            "keep",
            "iteration",
            "tolerance",
            "max_iterations",
            "quadrature",
            "epsilon",
            "min_element_size",
        ],
    )?;
    let d = Solver::default();
    let mut ok = true;
    let get = |key: &str| map.get(key).map(|v| (v, child(path, key)));

    let method = match get("method") {
        Some((v, p)) => match w.choice(v, &p, &["projection", "hierarchical"]) {
            Some("hierarchical") => {
                if kind == Some("fredholm") {
                    w.error(&p, "\"hierarchical\" solves flatland and 3d scenes; a fredholm equation uses \"projection\"");
                    ok = false;
                }
                Method::Hierarchical
            }
            Some(_) => Method::Projection,
            None => {
                ok = false;
                d.method
            }
        },
        None => d.method,
    };
    let basis = match get("basis") {
        Some((v, p)) => match w.choice(v, &p, &["scaling", "wavelet"]) {
            Some("scaling") => BasisKind::Scaling,
            Some(_) => BasisKind::Wavelet,
            None => {
                ok = false;
                d.basis
            }
        },
        None => d.basis,
    };
    // the method and the basis say whether the resolution must be a power of two
    let known = ok;
    let mut int = |key: &str, lo: u64, hi: u64, default: usize, ok: &mut bool| match get(key) {
        Some((v, p)) => w.integer(v, &p, lo, hi).unwrap_or_else(|| {
            *ok = false;
            default
        }),
        None => default,
    };
    // the integrators keep k = m + 1 ≤ 16 coefficients on the stack
    let max_order = limits.max_order.min(15) as u64;
    let order = int("order", 0, max_order, d.order, &mut ok);
    let mut resolution_ok = true;
    let resolution = int(
        "resolution",
        1,
        limits.max_resolution as u64,
        d.resolution,
        &mut resolution_ok,
    );
    ok &= resolution_ok;
    let max_iterations = int("max_iterations", 1, 1_000_000, d.max_iterations, &mut ok);
    let quadrature = int("quadrature", 1, 64, order + 2, &mut ok);
    let needs_pow2 = basis == BasisKind::Wavelet || method == Method::Hierarchical;
    if known && resolution_ok && needs_pow2 && !resolution.is_power_of_two() {
        let why = if method == Method::Hierarchical {
            "the hierarchical method"
        } else {
            "the wavelet basis"
        };
        w.error(
            child(path, "resolution"),
            format!("{why} needs a power of two; found {resolution}"),
        );
        ok = false;
    }
    let keep = match get("keep") {
        Some((v, p)) => keep(w, v, &p).unwrap_or_else(|| {
            ok = false;
            Keep::All
        }),
        None => Keep::All,
    };
    let iteration = match get("iteration") {
        Some((v, p)) => match w.choice(v, &p, &["jacobi", "gauss-seidel"]) {
            Some("gauss-seidel") => Iteration::GaussSeidel,
            Some(_) => Iteration::Jacobi,
            None => {
                ok = false;
                d.iteration
            }
        },
        None => d.iteration,
    };
    let mut positive = |key: &str, default: f64, ok: &mut bool| match get(key) {
        Some((v, p)) => w
            .number_in(v, &p, |x| x > 0.0 && x < 1.0, "must be in (0, 1)")
            .unwrap_or_else(|| {
                *ok = false;
                default
            }),
        None => default,
    };
    let tolerance = positive("tolerance", d.tolerance, &mut ok);
    let epsilon = positive("epsilon", d.epsilon, &mut ok);
    let min_element_size = match get("min_element_size") {
        Some((v, p)) => {
            let size = w.number_in(
                v,
                &p,
                |x| x > 0.0 && x.is_finite(),
                "must be a positive length",
            );
            ok &= size.is_some();
            if size.is_some()
                && (kind.is_some_and(|k| k != "3d") || (known && method != Method::Hierarchical))
            {
                w.error(
                    &p,
                    "min_element_size sizes the elements of the hierarchical method in 3d scenes; \
                     flatland and the projection method are sized by resolution",
                );
                ok = false;
            }
            size
        }
        None => None,
    };
    Some(Parsed {
        value: Solver {
            method,
            basis,
            order,
            resolution,
            resolution_given: get("resolution").is_some(),
            keep,
            iteration,
            tolerance,
            max_iterations,
            quadrature,
            epsilon,
            min_element_size,
        },
        ok,
    })
}

fn keep(w: &mut Walker, v: &Value, path: &str) -> Option<Keep> {
    if v.as_str() == Some("all") {
        return Some(Keep::All);
    }
    let map = w.object(v, path, &["top", "fraction", "threshold"])?;
    if map.len() != 1 {
        w.error(
            path,
            "keep is {\"top\": N}, {\"fraction\": f} or {\"threshold\": t}: exactly one field",
        );
        return None;
    }
    let (key, v) = map.iter().next()?;
    let p = child(path, key);
    match key.as_str() {
        "top" => w.integer(v, &p, 1, u64::MAX >> 12).map(Keep::Top),
        "fraction" => w
            .number_in(v, &p, |f| f > 0.0 && f <= 1.0, "0 < fraction ≤ 1")
            .map(Keep::Fraction),
        _ => w
            .number_in(v, &p, |t| t >= 0.0, "threshold ≥ 0")
            .map(Keep::Threshold),
    }
}

fn output(w: &mut Walker, v: &Value, limits: &Limits) -> Option<Parsed<Output>> {
    let path = "/output";
    let map = w.object(
        v,
        path,
        &[
            "image",
            "camera",
            "grid",
            "reference",
            "coefficients",
            "vertices",
        ],
    )?;
    let d = Output::default();
    let image = match map.get("image") {
        Some(v) => image(w, v, limits),
        None => Some(d.image),
    };
    let camera = match map.get("camera") {
        Some(v) => camera(w, v).map(Some),
        None => Some(None),
    };
    let grid = match map.get("grid") {
        Some(v) => w.integer(v, "/output/grid", 1, 1024),
        None => Some(d.grid),
    };
    let reference = match map.get("reference") {
        Some(v) => reference(w, v, limits).map(Some),
        None => Some(None),
    };
    let coefficients = match map.get("coefficients") {
        Some(v) => w.integer(v, "/output/coefficients", 0, 100_000),
        None => Some(d.coefficients),
    };
    let vertices = match map.get("vertices") {
        Some(v) => w.boolean(v, "/output/vertices"),
        None => Some(d.vertices),
    };
    let ok = image.is_some()
        && vertices.is_some()
        && camera.is_some()
        && grid.is_some()
        && reference.is_some()
        && coefficients.is_some();
    Some(Parsed {
        value: Output {
            image: image.unwrap_or(d.image),
            camera: camera.flatten(),
            grid: grid.unwrap_or(d.grid),
            reference: reference.flatten(),
            coefficients: coefficients.unwrap_or(d.coefficients),
            vertices: vertices.unwrap_or(d.vertices),
        },
        ok,
    })
}

fn image(w: &mut Walker, v: &Value, limits: &Limits) -> Option<ImageSpec> {
    let path = "/output/image";
    let map = w.object(v, path, &["width", "height", "exposure", "raw", "mesh"])?;
    let flag = |w: &mut Walker, key: &str| match map.get(key) {
        Some(v) => w.boolean(v, &child(path, key)),
        None => Some(false),
    };
    let (raw, mesh) = (flag(w, "raw"), flag(w, "mesh"));
    let dim = |w: &mut Walker, key: &str| match map.get(key) {
        Some(v) => w.integer(v, &child(path, key), 1, 16384).map(|x| x as u32),
        None => Some(512),
    };
    let width = dim(w, "width");
    let height = dim(w, "height");
    let exposure = match map.get("exposure") {
        None => Some(Exposure::Auto),
        Some(Value::String(s)) if s == "auto" => Some(Exposure::Auto),
        Some(v) => w
            .number_in(
                v,
                "/output/image/exposure",
                |x| x > 0.0,
                "\"auto\" or a number > 0",
            )
            .map(Exposure::White),
    };
    let (width, height) = (width?, height?);
    if (width as usize) * (height as usize) > limits.max_image_pixels {
        w.error(
            path,
            format!(
                "{width}×{height} pixels is more than max_image_pixels ({})",
                limits.max_image_pixels
            ),
        );
        return None;
    }
    Some(ImageSpec {
        width,
        height,
        exposure: exposure?,
        raw: raw?,
        mesh: mesh?,
    })
}

fn camera(w: &mut Walker, v: &Value) -> Option<Camera> {
    let path = "/output/camera";
    let map = w.object(v, path, &["eye", "look_at", "up", "fov_deg"])?;
    let eye = w
        .required(map, path, "eye")
        .and_then(|v| w.coordinates::<3>(v, "/output/camera/eye"));
    let look_at = w
        .required(map, path, "look_at")
        .and_then(|v| w.coordinates::<3>(v, "/output/camera/look_at"));
    let given_up = map.contains_key("up");
    let up = match map.get("up") {
        Some(v) => w.numbers::<3>(v, "/output/camera/up"),
        None => Some([0.0, 1.0, 0.0]),
    };
    let fov_deg = match map.get("fov_deg") {
        Some(v) => w.number_in(
            v,
            "/output/camera/fov_deg",
            |f| f > 0.0 && f < 180.0,
            "0 < fov_deg < 180",
        ),
        None => Some(40.0),
    };
    let (eye, look_at, up, fov_deg) = (eye?, look_at?, up?, fov_deg?);
    let dir = [
        look_at[0] - eye[0],
        look_at[1] - eye[1],
        look_at[2] - eye[2],
    ];
    let dn = (dir[0] * dir[0] + dir[1] * dir[1] + dir[2] * dir[2]).sqrt();
    if dn == 0.0 {
        w.error(
            "/output/camera/look_at",
            "look_at equals eye: the camera has no direction",
        );
        return None;
    }
    let across = |up: [f64; 3]| {
        let cross = [
            dir[1] * up[2] - dir[2] * up[1],
            dir[2] * up[0] - dir[0] * up[2],
            dir[0] * up[1] - dir[1] * up[0],
        ];
        let un = (up[0] * up[0] + up[1] * up[1] + up[2] * up[2]).sqrt();
        let cn = (cross[0] * cross[0] + cross[1] * cross[1] + cross[2] * cross[2]).sqrt();
        un > 0.0 && cn > 1e-9 * dn * un
    };
    // without an `up`, +y is up unless the camera looks along y: then +z is
    let up = if !given_up && !across(up) {
        [0.0, 0.0, 1.0]
    } else {
        up
    };
    if !across(up) {
        w.error(
            "/output/camera/up",
            "up is zero or parallel to the viewing direction",
        );
        return None;
    }
    Some(Camera {
        eye,
        look_at,
        up,
        fov_deg,
    })
}

fn reference(w: &mut Walker, v: &Value, limits: &Limits) -> Option<Reference> {
    let path = "/output/reference";
    if v.as_str() == Some("exact") {
        return Some(Reference::Exact);
    }
    if v.is_string() {
        w.error(
            path,
            "expected \"exact\" or {\"order\": m, \"resolution\": n}",
        );
        return None;
    }
    let map = w.object(v, path, &["order", "resolution"])?;
    let order = w.required(map, path, "order").and_then(|o| {
        w.integer(
            o,
            "/output/reference/order",
            0,
            limits.max_order.min(15) as u64,
        )
    });
    let resolution = w.required(map, path, "resolution").and_then(|r| {
        w.integer(
            r,
            "/output/reference/resolution",
            1,
            limits.max_resolution as u64,
        )
    });
    Some(Reference::Finer {
        order: order?,
        resolution: resolution?,
    })
}

/// Checks that involve more than one part of the document.
/// The most cell means a result may list (about 16 MB of JSON): `grid` goes up to 1024, and
/// 1024² cells on each of a Cornell box's 16 surfaces would be a 2 GB result.
const MAX_RESULT_CELLS: usize = 1 << 18;

fn cross_checks(w: &mut Walker, shape: &Shape, solver: &Solver, output: &Output, limits: &Limits) {
    let per_surface = output.grid.pow(shape.dims);
    if shape.surfaces * per_surface > MAX_RESULT_CELLS {
        w.error(
            "/output/grid",
            format!(
                "{} surfaces × {per_surface} cells is more than the {MAX_RESULT_CELLS} cell means a result may hold",
                shape.surfaces
            ),
        );
    }
    let basis_size = shape.basis_size(solver.order, solver.resolution);
    match output.reference {
        Some(Reference::Exact) if !shape.exact => w.error(
            "/output/reference",
            "\"exact\" needs a fredholm scene with an `exact` solution",
        ),
        Some(Reference::Finer { order, resolution }) => {
            if order < solver.order || resolution < solver.resolution {
                w.error(
                    "/output/reference",
                    format!(
                        "the reference must be at least as fine as the solve (order ≥ {}, resolution ≥ {})",
                        solver.order, solver.resolution
                    ),
                );
            } else if order == solver.order && resolution == solver.resolution {
                w.error(
                    "/output/reference",
                    "the reference is the same discretisation as the solve: make it finer",
                );
            } else {
                if solver.basis == BasisKind::Wavelet && !resolution.is_power_of_two() {
                    w.error(
                        "/output/reference/resolution",
                        "the wavelet basis needs a power of two",
                    );
                }
                let finer = shape.basis_size(order, resolution);
                if finer > limits.max_basis_functions {
                    w.error(
                        "/output/reference",
                        format!(
                            "the reference needs {finer} basis functions, more than max_basis_functions ({})",
                            limits.max_basis_functions
                        ),
                    );
                }
            }
        }
        _ => {}
    }
    if solver.method == Method::Projection && basis_size > limits.max_basis_functions {
        w.error(
            "/solver/resolution",
            format!(
                "the projection matrix would have {n}² entries ({mib:.0} MiB): {n} basis functions is more than max_basis_functions ({max}); lower resolution or order",
                n = basis_size,
                mib = (basis_size as f64).powi(2) * 8.0 / (1024.0 * 1024.0),
                max = limits.max_basis_functions
            ),
        );
    }
    if let Keep::Top(n) = solver.keep {
        let entries = basis_size.saturating_mul(basis_size);
        if solver.method == Method::Projection && n > entries {
            w.error(
                "/solver/keep/top",
                format!("top {n} is more than the {entries} matrix entries"),
            );
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    fn errors(v: Value) -> Vec<String> {
        match parse_value(&v, &Limits::default()) {
            Ok(_) => vec![],
            Err(e) => e.0.into_iter().map(|e| e.path).collect(),
        }
    }

    fn flat(extra: Value) -> Value {
        let mut doc = json!({"scene": {"kind": "flatland", "surfaces": [
            {"name": "a", "segment": [[0, 0], [1, 0]], "reflectance": 0.5, "emission": 1},
            {"name": "b", "segment": [[1, 1], [0, 1]], "reflectance": [0.1, 0.2, 0.3]}
        ]}});
        if let (Some(d), Some(e)) = (doc.as_object_mut(), extra.as_object()) {
            for (k, v) in e {
                d.insert(k.clone(), v.clone());
            }
        }
        doc
    }

    #[test]
    fn applies_every_default() {
        let job = parse_value(&flat(json!({})), &Limits::default()).unwrap();
        assert_eq!(
            job.solver,
            Solver {
                quadrature: 3,
                ..Solver::default()
            }
        );
        assert_eq!(job.output, Output::default());
        let SceneKind::Flatland(s) = &job.scene.kind else {
            panic!()
        };
        assert_eq!(s[1].material.emission, [0.0; 3]);
        assert_eq!(s[1].material.reflectance, [0.1, 0.2, 0.3]);
        assert_eq!(s[0].emission_region, [0.0, 1.0]);
        let job = parse_value(&flat(json!({"solver": {"order": 3}})), &Limits::default()).unwrap();
        assert_eq!(job.solver.quadrature, 5);
    }

    #[test]
    fn reports_every_error_with_its_path() {
        let doc = json!({"scene": {"kind": "flatland", "surfaces": [
            {"name": "a", "segment": [[0, 0], [0, 0]], "reflectance": 1.0, "emision": 1},
            {"name": "a", "segment": [[1, 1], [0, 1]], "reflectance": [0.1, -0.2, 0.3], "emission": -1}
        ]}, "solver": {"order": 99, "resolution": 12, "keep": {"top": 0}, "metod": 1},
           "output": {"grid": 0, "reference": "exact", "image": {"raw": "yes", "mesh": 1}}});
        let mut got = errors(doc);
        got.sort();
        let mut want = vec![
            "/scene/surfaces/0/emision",
            "/scene/surfaces/0/segment",
            "/scene/surfaces/0/reflectance",
            "/scene/surfaces/1/reflectance/1",
            "/scene/surfaces/1/emission",
            "/solver/metod",
            "/solver/order",
            "/solver/keep/top",
            "/output/grid",
            "/output/image/raw",
            "/output/image/mesh",
            // no surface emits (a misspelt key, a negative value), the name is given twice
            // (by two surfaces that are invalid otherwise), 12 is not a power of two for the
            // default wavelet basis, and "exact" needs a fredholm scene
            "/scene/surfaces",
            "/scene/surfaces/1/name",
            "/solver/resolution",
            "/output/reference",
        ];
        want.sort();
        assert_eq!(got, want);
    }

    #[test]
    fn cross_field_errors() {
        assert_eq!(
            errors(flat(json!({"solver": {"resolution": 12}}))),
            ["/solver/resolution"]
        );
        assert!(errors(flat(
            json!({"solver": {"resolution": 12, "basis": "scaling"}})
        ))
        .is_empty());
        assert_eq!(
            errors(flat(json!({"output": {"reference": "exact"}}))),
            ["/output/reference"]
        );
        assert_eq!(
            errors(flat(json!({"solver": {"resolution": 1024, "order": 8}}))),
            ["/solver/resolution"]
        );
        let dark = json!({"scene": {"kind": "flatland", "surfaces": [
            {"name": "a", "segment": [[0, 0], [1, 0]], "reflectance": 0.5}]}});
        assert_eq!(errors(dark), ["/scene/surfaces"]);
        let dup = json!({"scene": {"kind": "flatland", "surfaces": [
            {"name": "a", "segment": [[0, 0], [1, 0]], "reflectance": 0.5, "emission": 1},
            {"name": "a", "segment": [[0, 1], [1, 1]], "reflectance": 0.5}]}});
        assert_eq!(errors(dup), ["/scene/surfaces/1/name"]);
        // each beside an error in another field: all are reported
        let mut got = errors(json!({"scene": {"kind": "flatland", "surfaces": [
            {"name": "a", "segment": [[0, 0], [1, 0]], "reflectance": 1.5},
            {"name": "a", "segment": [[0, 1], [1, 1]], "reflectance": 0.5}]},
            "solver": {"order": 99, "resolution": 12}}));
        got.sort();
        assert_eq!(
            got,
            [
                "/scene/surfaces",
                "/scene/surfaces/0/reflectance",
                "/scene/surfaces/1/name",
                "/solver/order",
                "/solver/resolution"
            ]
        );
        // a surface that did not parse still counts as emitting if its emission says so, and
        // its name still counts; a misspelt basis does not make the resolution wrong
        let lit = json!({"scene": {"kind": "flatland", "surfaces": [
            {"name": "a", "segment": [[0, 0], [1, 0]], "reflectance": 1.5, "emission": [0, 2, 0]},
            {"name": "b", "segment": [[0, 1], [1, 1]], "reflectance": 0.5}]},
            "solver": {"basis": "scalng", "resolution": 12}});
        let mut got = errors(lit);
        got.sort();
        assert_eq!(got, ["/scene/surfaces/0/reflectance", "/solver/basis"]);
        // the checks across parts run beside an invalid surface, camera or image: the basis
        // size, the cells a result may hold, the reference's size
        let quad = |c: Value| json!({"name": "q", "corners": c, "reflectance": 0.5, "emission": 1});
        let mut got = errors(json!({"scene": {"kind": "3d", "surfaces": [
            quad(json!([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 2, 0]]))]},
            "solver": {"resolution": 128},
            "output": {"grid": 1024, "image": {"width": 4096, "height": 4097},
                       "reference": {"order": 6, "resolution": 256}}}));
        got.sort();
        assert_eq!(
            got,
            [
                "/output/grid",
                "/output/image",
                "/output/reference",
                "/scene/surfaces/0/corners",
                "/solver/resolution"
            ]
        );
        let mut got = errors(json!({"scene": {"kind": "3d", "surfaces": [
            quad(json!([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]]))]},
            "output": {"grid": 1024, "camera": {"eye": [0, 0, 1], "look_at": [0, 0, 1]}}}));
        got.sort();
        assert_eq!(got, ["/output/camera/look_at", "/output/grid"]);
    }

    #[test]
    fn a_fredholm_exact_solution_is_the_default_reference() {
        let doc = json!({"scene": {"kind": "fredholm", "domain": [0, 1], "kernel": "x*y",
            "source": "1", "exact": "1 + 1.5*x"}});
        let job = parse_value(&doc, &Limits::default()).unwrap();
        assert_eq!(job.output.reference, Some(Reference::Exact));
        let mut finer = doc.clone();
        finer["output"] = json!({"reference": {"order": 3, "resolution": 16}});
        let job = parse_value(&finer, &Limits::default()).unwrap();
        assert!(matches!(
            job.output.reference,
            Some(Reference::Finer { .. })
        ));
        let mut none = doc;
        none["scene"].as_object_mut().unwrap().remove("exact");
        let job = parse_value(&none, &Limits::default()).unwrap();
        assert_eq!(job.output.reference, None);
    }

    #[test]
    fn a_camera_looking_along_y_gets_z_up_unless_it_says_otherwise() {
        let doc = |camera: Value| {
            json!({"scene": {"kind": "3d", "surfaces": [{"name": "q",
                "corners": [[0, 0, 0], [1, 0, 0], [1, 0, 1], [0, 0, 1]], "emission": 1,
                "reflectance": 0.5}]}, "output": {"camera": camera}})
        };
        let down = json!({"eye": [0.5, 2, 0.5], "look_at": [0.5, 0, 0.5]});
        let job = parse_value(&doc(down.clone()), &Limits::default()).unwrap();
        assert_eq!(job.output.camera.unwrap().up, [0.0, 0.0, 1.0]);
        let mut told = down;
        told["up"] = json!([0, 1, 0]);
        assert_eq!(errors(doc(told)), ["/output/camera/up"]);
    }

    #[test]
    fn emission_is_bounded() {
        // 1e308 is finite, but B = E / (1 − ρ) and the solver's sums of squares are not
        let doc = |e: f64| {
            json!({"scene": {"kind": "flatland", "surfaces": [
                {"name": "a", "segment": [[0, 0], [1, 0]], "reflectance": 0.5, "emission": e}]}})
        };
        assert!(errors(doc(1e12)).is_empty());
        assert_eq!(errors(doc(1e308)), ["/scene/surfaces/0/emission"]);
    }

    #[test]
    fn three_d_checks() {
        let doc = json!({"scene": {"kind": "3d", "surfaces": [
            {"name": "ok", "corners": [[0,0,0],[1,0,0],[1,1,0],[0,1,0]], "reflectance": 0.5, "emission": 1,
             "emission_region": {"s": [0.4, 0.6], "t": [0.4, 0.6]}},
            {"name": "skew", "corners": [[0,0,0],[1,0,0],[1,1,0.5],[0,1,0]], "reflectance": 0.5},
            {"name": "flat", "corners": [[0,0,0],[1,0,0],[2,0,0],[1,0,0]], "reflectance": 0.5},
            {"name": "region", "corners": [[0,0,0],[1,0,0],[1,1,0],[0,1,0]], "reflectance": 0.5,
             "emission_region": {"s": [0.6, 0.4], "t": [0, 1]}}
        ]}, "output": {"camera": {"eye": [0,0,0], "look_at": [0,0,0]}}});
        assert_eq!(
            errors(doc),
            [
                "/scene/surfaces/1/corners",
                "/scene/surfaces/2/corners",
                "/scene/surfaces/3/emission_region/s",
                "/output/camera/look_at"
            ]
        );
    }

    #[test]
    fn min_element_size_is_a_positive_length_for_the_3d_hierarchy() {
        let doc = |solver: Value| {
            json!({"scene": {"kind": "3d", "surfaces": [
                {"name": "a", "corners": [[0,0,0],[1,0,0],[1,1,0],[0,1,0]], "reflectance": 0.5,
                 "emission": 1}]}, "solver": solver})
        };
        let ok = json!({"method": "hierarchical", "min_element_size": 0.25});
        let job = parse_value(&doc(ok), &Limits::default()).unwrap();
        assert_eq!(job.solver.min_element_size, Some(0.25));
        assert!(!job.solver.resolution_given);
        let capped = json!({"method": "hierarchical", "min_element_size": 0.25, "resolution": 4});
        assert!(
            parse_value(&doc(capped), &Limits::default())
                .unwrap()
                .solver
                .resolution_given
        );
        for bad in [json!(0), json!(-1), json!("1")] {
            let solver = json!({"method": "hierarchical", "min_element_size": bad});
            assert_eq!(errors(doc(solver)), ["/solver/min_element_size"]);
        }
        // no finer than max_resolution elements along the longest side (1 here)
        let fine = json!({"method": "hierarchical", "min_element_size": 0.0001});
        assert_eq!(errors(doc(fine)), ["/solver/min_element_size"]);
        // the projection method and flatland are sized by resolution
        let projection = json!({"method": "projection", "min_element_size": 0.25});
        assert_eq!(errors(doc(projection)), ["/solver/min_element_size"]);
        let solver = json!({"solver": {"method": "hierarchical", "min_element_size": 0.25}});
        assert_eq!(errors(flat(solver)), ["/solver/min_element_size"]);
    }

    #[test]
    fn fredholm_documents() {
        let ok = json!({"scene": {"kind": "fredholm", "domain": [0, 1], "kernel": "x^2 + x*y",
            "source": "1", "exact": "1 + x"}, "output": {"reference": "exact"}});
        assert!(errors(ok).is_empty());
        let bad = json!({"scene": {"kind": "fredholm", "domain": [1, 0], "kernel": "x + z",
            "source": "y", "surfaces": []}, "solver": {"method": "hierarchical"}});
        let mut got = errors(bad);
        got.sort();
        assert_eq!(
            got,
            [
                "/scene/domain",
                "/scene/kernel",
                "/scene/source",
                "/scene/surfaces",
                "/solver/method"
            ]
        );
    }

    #[test]
    fn refuses_wrong_shapes() {
        assert_eq!(errors(json!([])), [""]);
        assert_eq!(errors(json!({})), ["/scene"]);
        assert_eq!(errors(json!({"scene": {"kind": "4d"}})), ["/scene/kind"]);
        assert_eq!(
            errors(flat(
                json!({"solver": {"keep": {"top": 3, "fraction": 0.5}}})
            )),
            ["/solver/keep"]
        );
        assert_eq!(
            errors(flat(json!({"solver": {"tolerance": 0}}))),
            ["/solver/tolerance"]
        );
        assert_eq!(
            errors(flat(json!({"solver": {"order": 1.5}}))),
            ["/solver/order"]
        );
    }
}
