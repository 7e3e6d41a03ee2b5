//! 3D scenes against closed forms: the furnace cube, Howell's form factors, convergence of the
//! Cornell box, the linear growth of the hierarchical method's links, and the camera images.

mod support;

use serde_json::json;
use support::{furnace_cube as furnace, job, run, scene_file};
use wavrad::job::{self, Outcome};
use wavrad::methods::projection::Discretization;
use wavrad::progress::Silent;
use wavrad::render::camera;
use wavrad::scene::{Job, SceneKind};
use wavrad::three_d::projection as three_d;

#[test]
fn furnace_cube_for_every_method_and_order() {
    let (e, rho) = (1.0, 0.5);
    let want = e / (1.0 - rho);
    let mut cases = vec![];
    for order in 0..=3 {
        cases.push(
            json!({ "method": "projection", "order": order, "resolution": 2, "tolerance": 1e-9 }),
        );
    }
    for order in 0..=3 {
        cases.push(
            json!({ "method": "hierarchical", "order": order, "resolution": 4, "tolerance": 1e-9 }),
        );
    }
    // the hierarchical method's Gauss–Seidel sweeps (a patch at a time)
    cases.push(
        json!({ "method": "hierarchical", "resolution": 4, "tolerance": 1e-9,
        "iteration": "gauss-seidel" }),
    );
    for solver in cases {
        let mut doc = furnace(e, rho);
        doc["solver"] = solver.clone();
        let out = run(doc);
        // a closed room absorbs what it emits
        let balance = out.result.metrics.energy.balance;
        assert!(
            balance.iter().all(|b| (b - 1.0).abs() < 1e-3),
            "{solver}: {balance:?}"
        );
        for s in &out.result.surfaces {
            for c in 0..3 {
                let rel = (s.mean[c] - want).abs() / want;
                assert!(rel < 1e-3, "{solver}: {} mean {:?}", s.name, s.mean);
            }
            for cell in &s.cells {
                assert!(
                    (cell[0] - want).abs() / want < 1e-3,
                    "{solver}: {} cell {:?}",
                    s.name,
                    cell
                );
            }
        }
    }
}

fn unit_pair(second: [[f64; 3]; 4]) -> Job {
    job(json!({ "scene": { "kind": "3d", "surfaces": [
        { "name": "a", "corners": [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], "reflectance": 0.5, "emission": 1 },
        { "name": "b", "corners": second, "reflectance": 0.5 }
    ]}}))
}

/// F from the first unit square to the second, from the order-0 matrix on one cell each.
fn form_factor(j: &Job) -> f64 {
    let SceneKind::ThreeD(quads) = &j.scene.kind else {
        unreachable!()
    };
    let disc = Discretization {
        order: 0,
        cells: 1,
        quadrature: 6,
    };
    let sys = three_d::build(quads, disc, &Silent).expect("builds");
    sys.matrix.get(0, 1)
}

#[test]
fn parallel_opposed_unit_squares_howell_c11() {
    use std::f64::consts::PI;
    for c in [0.5f64, 1.0, 2.0] {
        let j = unit_pair([[0.0, 0.0, c], [0.0, 1.0, c], [1.0, 1.0, c], [1.0, 0.0, c]]);
        let (x, y) = (1.0 / c, 1.0 / c);
        let want = 2.0 / (PI * x * y)
            * (((1.0 + x * x) * (1.0 + y * y) / (1.0 + x * x + y * y))
                .sqrt()
                .ln()
                + x * (1.0 + y * y).sqrt() * (x / (1.0 + y * y).sqrt()).atan()
                + y * (1.0 + x * x).sqrt() * (y / (1.0 + x * x).sqrt()).atan()
                - x * x.atan()
                - y * y.atan());
        let got = form_factor(&j);
        assert!((got - want).abs() < 1e-6, "c = {c}: {got} vs {want}");
    }
}

#[test]
fn perpendicular_unit_squares_with_a_common_edge_howell_c14() {
    use std::f64::consts::PI;
    let j = unit_pair([
        [0.0, 0.0, 0.0],
        [0.0, 0.0, 1.0],
        [1.0, 0.0, 1.0],
        [1.0, 0.0, 0.0],
    ]);
    // H = W = 1
    let (h, w) = (1.0f64, 1.0f64);
    let a = (1.0 + h * h) * (1.0 + w * w) / (1.0 + h * h + w * w);
    let b = w * w * (1.0 + h * h + w * w) / ((1.0 + w * w) * (h * h + w * w));
    let c = h * h * (1.0 + h * h + w * w) / ((1.0 + h * h) * (h * h + w * w));
    let r = (h * h + w * w).sqrt();
    let want = 1.0 / (PI * w)
        * (w * (1.0 / w).atan() + h * (1.0 / h).atan() - r * (1.0 / r).atan()
            + 0.25 * (a * b.powf(w * w) * c.powf(h * h)).ln());
    let got = form_factor(&j);
    assert!((got - want).abs() < 1e-6, "{got} vs {want}");
}

#[test]
fn plates_projection_keeps_energy_and_same_bytes() {
    let mut doc = scene_file("plates-3d");
    doc["solver"]["resolution"] = json!(4);
    let a = run(doc.clone());
    let b = run(doc);
    let top = &a.result.surfaces[1];
    // the light is under the middle of the top plate: the middle is brighter than the corners
    let g = (top.cells.len() as f64).sqrt() as usize;
    assert!(top.cells[(g / 2) * g + g / 2][0] > 1.3 * top.cells[0][0]);
    assert_eq!(a.result.surfaces, b.result.surfaces);
    // eq. (5) falls like h² for piecewise constants: a quarter per halving of the cells
    let mut doc = scene_file("plates-3d");
    doc["solver"]["resolution"] = json!(8);
    let finer = run(doc);
    let (e4, e8) = (
        a.result.metrics.kernel_relative_error.expect("eq. (5)"),
        finer.result.metrics.kernel_relative_error.expect("eq. (5)"),
    );
    assert!(e4 < 0.1 && e8 < 0.35 * e4 && e8 > 0.15 * e4, "{e4} {e8}");
    // every facing pair of the 2 × 16 cells takes at least a 2 × 2 rule on each side, and
    // the work grows about 16-fold per halving (n⁴ pairs)
    let count = |o: &Outcome| o.result.metrics.kernel_evaluations.expect("counted");
    let (c4, c8) = (count(&a), count(&finer));
    assert!(c4 >= 2 * 16 * 16 * 16, "{c4}");
    assert!(c8 > 10 * c4 && c8 < 24 * c4, "{c4} {c8}");
}

#[test]
fn plates_keep_half_and_a_quarter_of_their_coefficients() {
    // the slides' experiment at n = 4, Haar and LLMW: the two plates' blocks with themselves
    // are zero in every basis, so a fraction counts the nonzero coefficients between them
    // (at most 2 · (k² n²)²; the symmetry of the pair zeroes a few wavelet coefficients);
    // dropping the smallest raises eq. (5) by their share of ∫∫K² and moves B a little
    for (order, unknowns) in [(0usize, 16usize), (1, 64)] {
        let mut errors = vec![];
        let mut tops = vec![];
        let mut nonzero = 0;
        for f in [1.0, 0.5, 0.25] {
            let mut doc = scene_file("plates-3d");
            doc["solver"]["resolution"] = json!(4);
            doc["solver"]["order"] = json!(order);
            doc["solver"]["keep"] = json!({ "fraction": f });
            let out = run(doc);
            let c = &out.result.coefficients;
            assert_eq!(c.basis_size, 2 * unknowns);
            assert_eq!(c.matrix_entries, 4 * unknowns * unknowns);
            if f == 1.0 {
                nonzero = c.kept_entries;
                assert!(nonzero <= 2 * unknowns * unknowns && nonzero > unknowns * unknowns);
            }
            assert_eq!(
                c.kept_entries,
                (f * nonzero as f64).ceil() as usize,
                "m = {order}"
            );
            errors.push(out.result.metrics.kernel_relative_error.expect("eq. (5)"));
            tops.push(out.result.surfaces[1].mean[0]);
        }
        eprintln!("m = {order}: eq. (5) {errors:?}, top plate's mean {tops:?}");
        assert!(errors[0] < errors[1] && errors[1] < errors[2], "{errors:?}");
        // the smallest half of the coefficients carries little of the transfer
        assert!(
            errors[1] - errors[0] < 0.1 * errors[0].max(1e-3),
            "{errors:?}"
        );
        assert!(tops[1] != tops[0] && tops[2] != tops[1], "{tops:?}");
        assert!((tops[2] / tops[0] - 1.0).abs() < 0.05, "{tops:?}");
    }
}

#[test]
fn hierarchical_links_grow_linearly_with_the_leaves() {
    // the Cornell box at order 0, for several ε: doubling the resolution limit doubles the
    // leaves (the refinement reaches the limit along every shared edge) and adds links in
    // proportion to the leaves it adds, where the dense matrix of the projection method
    // would quadruple. The links per
    // leaf depend on ε only: the oracle accepts a link when F̂ × smoothness falls below
    // ε / (ρB), so each leaf links to the pieces in a ball whose radius grows like
    // ε^(−1/(m+3)), i.e. ε^(−2/(m+3)) links.
    let mut per_leaf = vec![];
    for eps in [3.2e-2, 8e-3, 2e-3] {
        let mut rows = vec![];
        for res in [32, 64, 128] {
            let mut doc = scene_file("cornell-box");
            // elements down to a unit (a 555th of a wall), so that the resolution is the limit
            doc["solver"] = json!({ "method": "hierarchical", "order": 0, "resolution": res,
                "epsilon": eps, "min_element_size": 1.0 });
            let h = run(doc).result.hierarchical.expect("stats");
            rows.push((h.leaves as f64, h.links as f64));
        }
        eprintln!("ε = {eps}: (leaves, links) at resolution 32, 64, 128: {rows:?}");
        for w in rows.windows(2) {
            assert!(w[1].0 / w[0].0 > 1.6, "{rows:?}");
        }
        // linear: each step adds links in proportion to the leaves it adds, to 15 % (the
        // links between elements coarser than the receivers' first level,
        // [`wavrad::three_d::rules::Rules::receiver_first_level`], are a fixed part that the
        // resolution does not touch); a dense matrix would add four times as many per leaf
        // at each step
        let slope = |a: (f64, f64), b: (f64, f64)| (b.1 - a.1) / (b.0 - a.0);
        let (first, second) = (slope(rows[0], rows[1]), slope(rows[1], rows[2]));
        assert!((second / first - 1.0).abs() < 0.15, "{rows:?}");
        per_leaf.push(rows[2].1 / rows[2].0);
    }
    // and as ε shrinks 16-fold the links per leaf grow by far less than 16: measured 1.90,
    // 6.51 and 12.57 at resolution 128, 6.6-fold, a little above the 16^(2/3) ≈ 6.3 of the
    // estimate above, because the receivers along the blocks' feet are judged against half
    // the tolerance ([`wavrad::three_d::rules::Rules::contact_share`]), which reaches
    // more sources as ε shrinks (5.1-fold before)
    eprintln!("links per leaf at resolution 128: {per_leaf:?}");
    assert!(per_leaf[2] / per_leaf[0] < 16f64.powf(0.75), "{per_leaf:?}");
}

#[test]
fn cornell_box_renders_with_colour_bleeding_and_deterministically() {
    let doc = scene_file("cornell-box");
    let j = job(doc);
    let out = job::run(&j, &Silent).expect("solves");
    let links = out.result.hierarchical.as_ref().expect("stats").links as u64;
    let evaluations = out.result.metrics.kernel_evaluations.expect("counted");
    assert!(evaluations > 4 * links, "{evaluations} for {links} links");
    let img = camera::render(&j, &out, 64, 64);
    let again = camera::render(&j, &out, 64, 64);
    assert_eq!(img.as_raw(), again.as_raw());
    // the camera looks along +z with +y up, so x = 0 (the red wall) is on the right
    let left = img.get_pixel(3, 32).0;
    let right = img.get_pixel(60, 32).0;
    assert!(
        left[1] > left[0] && left[1] > left[2],
        "green wall {left:?}"
    );
    assert!(
        right[0] > right[1] && right[0] > right[2],
        "red wall {right:?}"
    );
    // the white back wall picks up some red near the red wall
    let names = j.surface_names();
    let back = names.iter().position(|n| n == "back").expect("back wall");
    let cells = &out.result.surfaces[back].cells;
    // s runs along y, t along x: row t = 0 is next to the red wall
    let near_red = cells[4];
    assert!(near_red[0] > near_red[2], "{near_red:?}");
}

#[test]
fn images_show_raw_elements_and_the_mesh_on_request() {
    // the top plate seen from between the plates, at order 0 on 4 × 4 cells: smooth by
    // default (B interpolated between the cell centres), flat per element with `raw`, and
    // with `mesh` darkened along the elements' borders and nowhere else
    let view = |image: serde_json::Value| {
        let mut doc = scene_file("plates-3d");
        doc["solver"] = json!({ "order": 0, "resolution": 4 });
        doc["output"] = json!({ "image": image, "camera": {
            "eye": [0.5, 0.5, 0.05], "look_at": [0.5, 0.5, 1.0], "up": [0, 1, 0], "fov_deg": 60 } });
        let j = job(doc);
        let out = job::run(&j, &Silent).expect("solves");
        camera::render(&j, &out, 64, 64)
    };
    let size = json!({ "width": 64, "height": 64, "exposure": 0.2 });
    let plain = view(size.clone());
    let mut raw = size.clone();
    raw["raw"] = json!(true);
    let raw = view(raw);
    let mut mesh = size.clone();
    mesh["mesh"] = json!(true);
    let mesh = view(mesh);
    // along the middle row, inside the plate (pixels 3 to 60): when smooth, B rises between
    // the cell centres and changes at 22 pixels; when raw, only at the three element borders
    // (a pixel across a border blends two values)
    let changes = |img: &image::RgbImage| {
        (4..61)
            .filter(|&x| img.get_pixel(x, 32) != img.get_pixel(x - 1, 32))
            .count()
    };
    assert!(changes(&plain) >= 15, "{}", changes(&plain));
    assert!((3..=6).contains(&changes(&raw)), "{}", changes(&raw));
    // the mesh only darkens, along lines: some pixels, not most
    let (mut darker, mut other) = (0, 0);
    for (a, b) in plain.pixels().zip(mesh.pixels()) {
        if a != b {
            if b.0.iter().zip(a.0).all(|(b, a)| *b <= a) {
                darker += 1;
            } else {
                other += 1;
            }
        }
    }
    assert_eq!(other, 0);
    assert!(darker > 3 * 64 && darker < 64 * 64 / 3, "{darker}");
}

#[test]
fn cornell_box_cell_means_converge_as_epsilon_shrinks() {
    // cell means of every surface but the light, against the solution at ε = 1.25e-4
    // (itself 0.03 % from the one at 6.25e-5, which has 988 k links)
    let cells = |eps: f64| -> Vec<f64> {
        let mut doc = scene_file("cornell-box");
        doc["solver"]["epsilon"] = json!(eps);
        let out = run(doc);
        out.result
            .surfaces
            .iter()
            .filter(|s| s.name != "light")
            .flat_map(|s| {
                s.cells
                    .iter()
                    .flat_map(|c| c.iter().copied())
                    .collect::<Vec<_>>()
            })
            .collect()
    };
    let reference = cells(1.25e-4);
    let gap = |c: &[f64]| {
        let d: f64 = c.iter().zip(&reference).map(|(a, b)| (a - b).powi(2)).sum();
        let n: f64 = reference.iter().map(|b| b * b).sum();
        (d / n).sqrt()
    };
    let coarse = gap(&cells(4e-3));
    let default = gap(&cells(1e-3));
    let fine = gap(&cells(5e-4));
    eprintln!(
        "cell-mean gap to the ε = 1.25e-4 solution: ε = 4e-3: {coarse:.4}, 1e-3: {default:.4}, \
         5e-4: {fine:.4}"
    );
    // measured: 1.03 %, 0.23 %, 0.12 % (2.1 %, 0.68 %, 0.38 % before coarse receivers were
    // split before their sources, 2.4 %, 0.78 %, 0.43 % with one visible fraction per link);
    // the gaps shrink about like ε: the default document is within 1 % of the limit
    assert!(
        default < 0.5 * coarse && fine < 0.7 * default,
        "{coarse} {default} {fine}"
    );
    assert!(default < 0.01, "{default}");
}

#[test]
fn furnace_with_a_partition_standing_on_the_floor() {
    // a two-sided wall stands on the floor inside the closed cube: its bottom edge lies inside
    // the floor (a T-junction), it hides parts of the cube from each other, and every point
    // still sees emitters only, so B = E/(1 − ρ) everywhere
    let mut doc = furnace(1.0, 0.5);
    let surfaces = doc["scene"]["surfaces"].as_array_mut().expect("faces");
    for (name, c) in [
        (
            "front",
            [
                [0.4, 0., 0.2],
                [0.4, 0.5, 0.2],
                [0.4, 0.5, 0.8],
                [0.4, 0., 0.8],
            ],
        ),
        (
            "back",
            [
                [0.4, 0., 0.2],
                [0.4, 0., 0.8],
                [0.4, 0.5, 0.8],
                [0.4, 0.5, 0.2],
            ],
        ),
    ] {
        surfaces.push(json!({ "name": name, "corners": c, "reflectance": 0.5, "emission": 1.0 }));
    }
    // measured worst surface mean and cell mean: 1.1e-3 and 2.5e-2 (hierarchical m = 0),
    // 1.6e-3 and 8.7e-3 (m = 1; 2.0e-3 and 1.25e-2 with one visible fraction per link instead
    // of one per quarter of the receiver), 3.7e-4 and 5.3e-3 (projection); what is left is
    // the noise of 16 visibility rays per fine link
    for (solver, surface_tol, cell_tol) in [
        (
            json!({ "method": "hierarchical", "order": 0, "resolution": 8, "epsilon": 2e-3 }),
            3e-3,
            3e-2,
        ),
        (
            json!({ "method": "hierarchical", "order": 1, "resolution": 8, "epsilon": 2e-3 }),
            3e-3,
            1.5e-2,
        ),
        (
            json!({ "method": "projection", "order": 0, "resolution": 4 }),
            3e-3,
            1e-2,
        ),
    ] {
        let mut d = doc.clone();
        d["solver"] = solver.clone();
        d["solver"]["tolerance"] = json!(1e-9);
        let t = std::time::Instant::now();
        let out = run(d);
        let worst = |f: &dyn Fn(&wavrad::result::SurfaceResult) -> f64| {
            out.result.surfaces.iter().map(f).fold(0.0, f64::max)
        };
        eprintln!(
            "{solver}: {:?}, worst surface {:.2e}, worst cell {:.2e}",
            t.elapsed(),
            worst(&|s| (s.mean[0] / 2.0 - 1.0).abs()),
            worst(&|s| s
                .cells
                .iter()
                .map(|c| (c[0] / 2.0 - 1.0).abs())
                .fold(0.0, f64::max))
        );
        for s in &out.result.surfaces {
            assert!(
                (s.mean[0] / 2.0 - 1.0).abs() < surface_tol,
                "{solver}: {} {:?}",
                s.name,
                s.mean
            );
            for c in &s.cells {
                assert!(
                    (c[0] / 2.0 - 1.0).abs() < cell_tol,
                    "{solver}: {} {c:?}",
                    s.name
                );
            }
        }
    }
}

/// Cancels once asked `after` times.
struct CancelAfter {
    asked: std::sync::atomic::AtomicUsize,
    after: usize,
}

impl wavrad::progress::Progress for CancelAfter {
    fn report(&self, _: wavrad::progress::Phase, _: f64) {}
    fn cancelled(&self) -> bool {
        self.asked
            .fetch_add(1, std::sync::atomic::Ordering::Relaxed)
            >= self.after
    }
}

#[test]
fn a_cancel_stops_both_methods_quickly() {
    for method in ["hierarchical", "projection"] {
        let mut doc = scene_file("cornell-box");
        doc["solver"]["method"] = json!(method);
        doc["solver"]["resolution"] = json!(8);
        let j = job(doc);
        let progress = CancelAfter {
            asked: Default::default(),
            after: 3,
        };
        // on a pool of its own, as the server runs each job: on the global pool its parallel
        // loops would wait behind the other tests' work
        let pool = rayon::ThreadPoolBuilder::new().build().unwrap();
        let t = std::time::Instant::now();
        let r = pool.install(|| job::run(&j, &progress));
        assert!(matches!(r, Err(job::JobError::Cancelled)), "{method}");
        assert!(
            t.elapsed().as_secs_f64() < 1.0,
            "{method}: {:?}",
            t.elapsed()
        );
    }
}

#[test]
fn same_document_same_result_and_high_orders() {
    let mut doc = scene_file("cornell-box");
    doc["solver"]["resolution"] = json!(8);
    let a = run(doc.clone());
    let b = run(doc);
    assert_eq!(a.result.surfaces, b.result.surfaces);
    assert_eq!(a.result.hierarchical, b.result.hierarchical);
    // the highest order a document may ask for, on the furnace
    let mut doc = furnace(1.0, 0.5);
    doc["solver"] =
        json!({ "method": "hierarchical", "order": 8, "resolution": 1, "tolerance": 1e-9 });
    let out = run(doc);
    assert!(
        (out.result.surfaces[0].mean[0] - 2.0).abs() < 2e-3,
        "{:?}",
        out.result.surfaces[0].mean
    );
}

/// The form factor from a point x with normal n to a convex polygon wholly above its horizon,
/// by Lambert's formula: (1/2π) Σ γ_i n·(R_i × R_i+1)/|R_i × R_i+1|.
fn lambert(x: [f64; 3], n: [f64; 3], poly: &[[f64; 3]]) -> f64 {
    let sub = |a: [f64; 3], b: [f64; 3]| [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
    let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let cross = |a: [f64; 3], b: [f64; 3]| {
        [
            a[1] * b[2] - a[2] * b[1],
            a[2] * b[0] - a[0] * b[2],
            a[0] * b[1] - a[1] * b[0],
        ]
    };
    let mut sum = 0.0;
    for i in 0..poly.len() {
        let (a, b) = (sub(poly[i], x), sub(poly[(i + 1) % poly.len()], x));
        let c = cross(a, b);
        let len = dot(c, c).sqrt();
        if len > 0.0 {
            let gamma = (dot(a, b) / (dot(a, a) * dot(b, b)).sqrt())
                .clamp(-1.0, 1.0)
                .acos();
            sum += gamma * dot(n, c) / len;
        }
    }
    (sum / (2.0 * std::f64::consts::PI)).abs()
}

#[test]
fn the_floor_lit_by_the_face_of_a_box_standing_on_it() {
    // a closed box stands on the floor; only its front face emits, only the floor reflects:
    // B = ρ E F(x → face) in front of the face's plane and 0 behind it, with F in closed
    // form. The floor cells along the face's foot lie partly under the box; what the face
    // sends there is all on their exposed part (the kernel vanishes behind its plane).
    let (x0, x1, z0, z1, h) = (3.0, 7.0, 3.3, 7.0, 2.0);
    let face = [[x0, 0.0, z0], [x0, h, z0], [x1, h, z0], [x1, 0.0, z0]];
    let doc = json!({
        "scene": { "kind": "3d", "surfaces": [
            { "name": "floor", "corners": [[0, 0, 0], [0, 0, 10], [10, 0, 10], [10, 0, 0]],
              "reflectance": 0.5 },
            { "name": "front", "corners": face, "emission": 1.0, "reflectance": 0.0 },
            { "name": "back", "corners": [[x0, 0.0, z1], [x1, 0.0, z1], [x1, h, z1], [x0, h, z1]], "reflectance": 0.0 },
            { "name": "left", "corners": [[x0, 0.0, z0], [x0, 0.0, z1], [x0, h, z1], [x0, h, z0]], "reflectance": 0.0 },
            { "name": "right", "corners": [[x1, 0.0, z0], [x1, h, z0], [x1, h, z1], [x1, 0.0, z1]], "reflectance": 0.0 },
            { "name": "top", "corners": [[x0, h, z0], [x0, h, z1], [x1, h, z1], [x1, h, z0]], "reflectance": 0.0 }
        ]},
        "solver": { "method": "hierarchical", "order": 0, "resolution": 16, "epsilon": 1e-4 },
        "output": { "grid": 16 }
    });
    for (order, tolerance) in [(0, 3e-2), (1, 3e-2), (2, 3e-2)] {
        let mut doc = doc.clone();
        doc["solver"]["order"] = json!(order);
        let out = run(doc);
        let floor = &out.result.surfaces[0];
        // the floor's s runs along z and t along x; cells are rows of t, then s
        let (g, m) = (16, 48);
        let rule = |a: f64, b: f64| (0..m).map(move |i| a + (b - a) * (i as f64 + 0.5) / m as f64);
        let mut worst: f64 = 0.0;
        for ct in 0..g {
            for cs in 0..g {
                let (za, zb) = (
                    10.0 * cs as f64 / g as f64,
                    10.0 * (cs + 1) as f64 / g as f64,
                );
                let (xa, xb) = (
                    10.0 * ct as f64 / g as f64,
                    10.0 * (ct + 1) as f64 / g as f64,
                );
                // the exposed part in front of the face's plane, by the midpoint rule
                let zb_front = zb.min(z0);
                if zb_front <= za {
                    continue;
                }
                let sum: f64 = rule(xa, xb)
                    .flat_map(|x| rule(za, zb_front).map(move |z| (x, z)))
                    .map(|(x, z)| 0.5 * lambert([x, 0.0, z], [0.0, 1.0, 0.0], &face))
                    .sum();
                let want = sum * (zb_front - za) / (zb - za) / (m * m) as f64;
                let got = floor.cells[ct * g + cs][0];
                if want > 0.01 {
                    let gap = (got / want - 1.0).abs();
                    worst = worst.max(gap);
                    if gap > 3e-3 {
                        eprintln!(
                            "cell ({cs}, {ct}): {got:.5} against {want:.5}, {:+.2}%",
                            100.0 * (got / want - 1.0)
                        );
                    }
                }
            }
        }
        eprintln!("order {order}: worst {worst:.2e}");
        assert!(worst < tolerance, "order {order}: {worst}");
    }
}

#[test]
fn results_carry_eq6_timings_and_the_hierarchy() {
    // eq. (6) against a finer solution of the plates, the whole bottom plate emitting (B is
    // smooth): piecewise constants converge like h, so the squared-norm ratio falls about
    // fourfold per halving of the cells
    let mut errors = vec![];
    for res in [2, 4, 8] {
        let mut doc = scene_file("plates-3d");
        doc["scene"]["surfaces"][0]
            .as_object_mut()
            .expect("a surface")
            .remove("emission_region");
        doc["solver"] = json!({ "method": "projection", "order": 0, "resolution": res });
        doc["output"] = json!({ "grid": 8, "reference": { "order": 1, "resolution": 16 } });
        let out = run(doc);
        let m = &out.result.metrics;
        errors.push(m.radiosity_relative_error.expect("eq. (6)"));
        for phase in [
            "projection",
            "transform",
            "threshold",
            "solve",
            "reference",
            "total",
        ] {
            assert!(
                out.result.timings_ms.keys().any(|k| k.contains(phase)),
                "{:?}",
                out.result.timings_ms
            );
        }
        assert!(m.kernel_pairs_left_out.is_empty());
    }
    eprintln!("eq. (6) at n = 2, 4, 8: {errors:?}");
    for w in errors.windows(2) {
        assert!(w[1] < 0.33 * w[0] && w[1] > 0.2 * w[0], "{errors:?}");
    }
    // the hierarchy of the Cornell box stays within its resolution: 32 cells per side at
    // the finest of 6 levels, leaves no more than 32² per surface, and BF refinement passes
    let out = run(scene_file("cornell-box"));
    let h = out.result.hierarchical.expect("stats");
    let surfaces = out.result.surfaces.len();
    assert_eq!(h.levels, 6, "{h:?}");
    assert!(
        h.leaves <= surfaces * 32 * 32 && h.leaves > 3 * surfaces * 16,
        "{h:?}"
    );
    assert!(
        h.elements > h.leaves && h.refinements > 0 && h.rays > 0,
        "{h:?}"
    );
    // the coefficients: the space of the leaves' linear polynomials (4 per leaf), whose
    // full matrix the links replace by a few coefficients per leaf pair they join
    let c = &out.result.coefficients;
    assert_eq!(c.basis_size, 4 * h.leaves);
    assert_eq!(c.matrix_entries, c.basis_size * c.basis_size);
    assert!(
        c.kept_entries <= 16 * h.links && c.kept_entries > 8 * h.links,
        "{c:?}"
    );
    assert!(c.sparsity_ratio > 0.99, "{c:?}");
}

#[test]
fn a_hierarchy_too_large_for_memory_stops_with_a_clear_error() {
    // order 6 (2401 numbers per link block) at ε = 1e-6 would take many GiB of links: the
    // refinement stops at its budget (111 k such links in 1 GiB) and says what to change
    let mut doc = scene_file("cornell-box");
    doc["solver"] =
        json!({ "method": "hierarchical", "order": 6, "resolution": 256, "epsilon": 1e-6 });
    match job::run(&job(doc), &Silent) {
        Err(e @ wavrad::job::JobError::TooLarge { order: 6, links }) => {
            // the budget: 1 GiB of 2401-number blocks in single precision (9604 bytes) and
            // their links' ends and factors (28 bytes, with the sixteen cells of a partly
            // visible link's V in four bits each for the shadow budget): 2³⁰ / 9632
            assert_eq!(links, (1 << 30) / (4 * 2401 + 28), "{links}");
            let m = e.to_string();
            assert!(m.contains("links") && m.contains("solver.epsilon"), "{m}")
        }
        Err(e) => panic!("{e}"),
        Ok(_) => panic!("solved"),
    }
}

#[test]
fn a_grid_too_large_for_a_result_is_refused_at_its_path() {
    let mut doc = scene_file("cornell-box");
    doc["output"]["grid"] = json!(1024);
    let errors =
        wavrad::scene::parse_value(&doc, &wavrad::scene::Limits::default()).expect_err("refused");
    assert!(errors.to_string().contains("/output/grid"), "{errors}");
    doc["output"]["grid"] = json!(128);
    assert!(wavrad::scene::parse_value(&doc, &wavrad::scene::Limits::default()).is_ok());
}

#[test]
fn the_default_camera_sees_the_fronts_of_the_surfaces() {
    // without a camera: a single emitting square facing any of the six directions, the two
    // plates (seen from behind from every side outside: looked at from between them) and
    // the Cornell box (through its open side, from −z as before) fill much of the image
    let lit = |doc: serde_json::Value| {
        let j = job(doc);
        assert!(j.output.camera.is_none());
        let out = job::run(&j, &Silent).expect("solves");
        let img = camera::render(&j, &out, 48, 48);
        img.pixels().filter(|p| p.0.iter().any(|&c| c > 0)).count() as f64 / (48.0 * 48.0)
    };
    let square = |corners: serde_json::Value| {
        json!({ "scene": { "kind": "3d", "surfaces": [
            { "name": "light", "corners": corners, "reflectance": 0.5, "emission": 1 }
        ]}, "solver": { "order": 0, "resolution": 1 } })
    };
    for corners in [
        json!([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]]),
        json!([[0, 0, 0], [0, 1, 0], [1, 1, 0], [1, 0, 0]]),
        json!([[0, 0, 0], [0, 0, 1], [0, 1, 1], [0, 1, 0]]),
        json!([[0, 0, 0], [0, 1, 0], [0, 1, 1], [0, 0, 1]]),
        json!([[0, 0, 0], [1, 0, 0], [1, 0, 1], [0, 0, 1]]),
        json!([[0, 0, 0], [0, 0, 1], [1, 0, 1], [1, 0, 0]]),
    ] {
        let f = lit(square(corners.clone()));
        assert!(f > 0.2, "{corners}: {f}");
    }
    let mut plates = scene_file("plates-3d");
    plates["output"] = json!({});
    plates["solver"]["resolution"] = json!(4);
    let f = lit(plates);
    assert!(f > 0.5, "plates: {f}");
    let mut cornell = scene_file("cornell-box");
    cornell["output"] = json!({});
    cornell["solver"] =
        json!({ "method": "hierarchical", "order": 0, "resolution": 8, "epsilon": 1e-2 });
    let f = lit(cornell);
    assert!(f > 0.3, "Cornell box: {f}");
}
