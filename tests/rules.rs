//! Each rule of the 3D refinement beyond the oracle's estimate (`wavrad::three_d::rules`),
//! shown necessary: on two different scenes, the solve at the defaults (or at a smaller ε,
//! where the requirement is convergence) meets what the method must achieve there, and the
//! same solve with that rule alone turned off does not, against the independent path tracer
//! of [`tracer`]. What must be achieved is the requirement the
//! scene is held to elsewhere: the gallery's (`tests/gallery.rs`: every surface's mean within
//! 1 % and every cell within 5 %, each beyond four of the reference's standard errors) or the
//! scene's own in `tests/path_traced.rs` (the cell means' relative L2 gap net of the
//! reference's noise).
//!
//! The rules whose necessity is not a scene's accuracy are held by unit tests where they
//! live: the dim receivers' least share keeps the refinement finite (`hierarchy::tolerance`),
//! the separated clusters keep the iteration a contraction (`hierarchy::clustered`), and
//! the partly covered senders keep it from diverging on slivers between books
//! (`three_d::cover`, and `a_row_of_books_on_a_meshed_floor` at ε = 2.5e-4).

mod icosphere;
mod support;
mod tracer;

use serde_json::{json, Value};
use tracer::{compare_with, reference, Gaps, Tracer, V3};
use wavrad::job::{self, Rules};
use wavrad::progress::Silent;
use wavrad::scene::{parse_value, Limits};

/// The worst surface-mean and cell gaps beyond four standard errors of `want`, solved with
/// `rules`.
fn gaps(doc: &Value, want: &[Vec<(V3, V3)>], rules: &Rules, label: &str) -> Gaps {
    let j = parse_value(doc, &Limits::default()).expect("valid document");
    let out = job::run_with(&j, rules, &Silent).expect("solves");
    let g = Tracer::new(doc).gaps(&out.result.surfaces, want, 4.0);
    eprintln!(
        "{label}: worst surface mean {:.2} % ({}), worst cell {:.2} % ({})",
        100.0 * g.surface.0,
        g.surface.1,
        100.0 * g.cell.0,
        g.cell.1,
    );
    g
}

/// Whether the gaps meet the gallery's requirement: the surface means', and the cells' when
/// `cells`.
fn meets_the_gallery(g: &Gaps, cells: bool) -> bool {
    g.surface.0 < 0.01 && (!cells || g.cell.0 < 0.05)
}

/// The gallery's requirement on `doc` (cells on its own grid, `per_side²` paths each; the
/// surface means alone unless `cells`): met with the default rules, and missed with `without`.
fn necessary_for_the_gallery(
    doc: &Value,
    per_side: usize,
    cells: bool,
    without: Rules,
    label: &str,
) {
    let want = reference(doc, per_side);
    let with = gaps(doc, &want, &Rules::DEFAULT, &format!("{label}, every rule"));
    assert!(
        meets_the_gallery(&with, cells),
        "{label}: missed with every rule"
    );
    let off = gaps(doc, &want, &without, &format!("{label}, without the rule"));
    assert!(
        !meets_the_gallery(&off, cells),
        "{label}: met without the rule"
    );
}

/// Coarse receivers first: without it a receiver's one polynomial holds the curvature of
/// many small links from a large source, and the cells of the walls near their corners go
/// wrong while every surface mean stays right. The two scenes' requirements are those of
/// `tests/path_traced.rs`: the cell means' L2 gap net of the reference's noise under 0.5 %
/// in the room lit through its ceiling (measured 0.11 % with the rule, 1.41 % without) and
/// under 0.35 % in the Cornell box (0.25 %, 0.59 %).
#[test]
fn coarse_receivers_first_are_necessary() {
    let without = Rules::without_receivers_first();
    for (label, doc, per_side, bound) in [
        (
            "room lit through its ceiling",
            support::room_lit_through_its_ceiling(json!({ "method": "hierarchical" })),
            128,
            0.005,
        ),
        (
            "Cornell box",
            support::scene_file("cornell-box"),
            128,
            0.0035,
        ),
    ] {
        let want = reference(&doc, per_side);
        let with = compare_with(
            &doc,
            &want,
            &format!("{label}, every rule"),
            &Rules::DEFAULT,
        );
        let off = compare_with(&doc, &want, &format!("{label}, without the rule"), &without);
        eprintln!(
            "{label}: net {:.3} % with the rule, {:.3} % without",
            100.0 * with.net(),
            100.0 * off.net()
        );
        assert!(with.net() < bound, "{label}: {} with the rule", with.net());
        assert!(off.net() > bound, "{label}: {} without the rule", off.net());
    }
}

/// Lids: without it the surface under a rug lying just above it is one polynomial across the
/// rug's outline. The Cornell box's room with a rug 2 units above its floor (the floor's cells
/// under the rug, which no light reaches, come out lit) and a room lit through a window with a
/// rug 5 mm above its meshed floor (the surfaces' means, which is what
/// `a_rug_just_above_a_meshed_floor_darkens_only_the_floor_under_it` holds: the ceiling
/// 1.5 % beyond the noise) then miss the gallery's requirement. (The Cornell box without its
/// blocks, whose ceiling behind the hung light was the first scene to need lids, no longer does:
/// the shadow budget resolves the walls' partly visible links into the ceiling there.)
#[test]
fn lids_are_necessary() {
    let base = support::scene_file("cornell-box");
    let mut doc = base.clone();
    let mut surfaces = base["scene"]["surfaces"].as_array().expect("surfaces")[..6].to_vec();
    surfaces.push(json!({"name": "rug", "reflectance": 0.5,
        "corners": [[100, 2, 100], [100, 2, 450], [450, 2, 450], [450, 2, 100]]}));
    doc["scene"]["surfaces"] = json!(surfaces);
    necessary_for_the_gallery(
        &doc,
        64,
        true,
        Rules::without_lids(),
        "the Cornell box's room with a rug",
    );
    let (y0, y1, z0, z1) = support::WINDOW;
    let mut surfaces = support::meshed_walls(12, 10, 0.6);
    surfaces.push(
        json!({"name": "window", "emission": 8.5, "reflectance": 0.0,
        "corners": [[0.002, y0, z1], [0.002, y0, z0], [0.002, y1, z0], [0.002, y1, z1]]}),
    );
    surfaces.push(json!({"name": "rug", "reflectance": 0.6,
        "corners": [[1.3, 0.005, 0.9], [1.3, 0.005, 2.9], [3.9, 0.005, 2.9], [3.9, 0.005, 0.9]]}));
    let doc = json!({
        "scene": {"kind": "3d", "name": "a rug on a floor", "surfaces": surfaces},
        "solver": {"method": "hierarchical"},
        "output": {"grid": 4}
    });
    necessary_for_the_gallery(
        &doc,
        64,
        false,
        Rules::without_lids(),
        "a rug on a meshed floor",
    );
}

/// The gallery's room with a light in a corner, an icosphere of 320 triangles (radius 1)
/// resting on its floor in place of the box.
fn a_ball_under_a_corner_light() -> Value {
    let mut doc = support::scene_file("gallery/corner-light");
    let surfaces = doc["scene"]["surfaces"].as_array_mut().expect("surfaces");
    surfaces.retain(|s| !s["name"].as_str().expect("a name").starts_with("box"));
    let mut ball = icosphere::sphere(2);
    for p in ball["positions"].as_array_mut().expect("positions") {
        let v: [f64; 3] = serde_json::from_value(p.clone()).expect("a point");
        // the icosphere's lowest vertex is (0, −1, 0): it touches the floor
        *p = json!([5.0 + v[0], 1.0 + v[1], 3.5 + v[2]]);
    }
    surfaces.push(json!({"name": "ball", "mesh": ball, "reflectance": 0.7}));
    doc
}

/// The shadow budget: without it the partly visible links into a receiver are each held to
/// the tolerance alone, and where their shadows fall together their errors add up: every
/// wall's link into the floor's coarse element that holds a ball's contact point sends light
/// into the ball's shadow there, and the ball's bottom triangles, which see little but that
/// floor, come out far too bright. A ball resting on a floor in two of the gallery's rooms:
/// that of its meshes on a floor (without the small ball; the worst cell 0.14 % beyond the
/// noise with the budget, 105 % without) and that of its light in a corner (1.8 %, 47 %).
#[test]
fn the_shadow_budget_is_necessary() {
    let mut doc = support::scene_file("gallery/meshes-on-a-floor");
    let surfaces = doc["scene"]["surfaces"].as_array_mut().expect("surfaces");
    surfaces.retain(|s| s["name"] != "small-ball");
    necessary_for_the_gallery(
        &doc,
        64,
        true,
        Rules::without_shadow_budget(),
        "a ball on a floor",
    );
    necessary_for_the_gallery(
        &a_ball_under_a_corner_light(),
        64,
        true,
        Rules::without_shadow_budget(),
        "a ball under a light in a corner",
    );
}

/// Contact lines: without them a receiver along the line where a solid stands on it takes
/// light through links whose rays, drawn from inside it, mostly miss the solid's shadow at its
/// foot. The gallery's small cube under the central light of a 10-unit room (surface means and
/// cells: worst 0 and 1.65 % beyond four standard errors of a reference of 128² paths a cell
/// with the rule, 2.01 % and 3.90 % without) and its cube of 0.25 turned by 15° in the room
/// lit from a corner (0 and 4.80 % with, 4.27 and 12.79 % without). The sides of both
/// are lit mostly by the floor at their foot.
#[test]
fn contact_lines_are_necessary() {
    necessary_for_the_gallery(
        &support::scene_file("gallery/small-object"),
        128,
        true,
        Rules::without_contact_lines(),
        "a small cube under the light",
    );
    necessary_for_the_gallery(
        &support::scene_file("gallery/small-cube-corner-light"),
        128,
        true,
        Rules::without_contact_lines(),
        "a small cube under a light in a corner",
    );
}

/// Near occluders: without them a pair whose rays all miss an occluder near the receiver is
/// credited as smooth, and kept at levels whose receivers span the occluder's narrow shadow.
/// A shelf 4 cm thick 10 cm in front of a wall: its side toward the wall came out 2.07 %
/// bright beyond four standard errors of a reference of 128² paths a cell at ε = 2.5e-4
/// without the rule, 0.13 % with it. At ε = 1e-3 it is 1.28 % with the rule and 2.06 %
/// without: with the rule, lowering ε to 2.5e-4 brings it in; without, it does not. So this
/// scene is held at ε = 2.5e-4, the convergence that the refinement must show. A shelf
/// 10 cm from the side wall of the room lit from a corner, at the defaults against 256²
/// paths a cell (the gallery's `a_shelf_near_a_side_wall`): 0 with the rule, 2.30 % (the
/// shelf's side toward the wall) without.
#[test]
fn near_occluders_are_necessary() {
    let mut shelf = support::scene_file("gallery/shelf");
    shelf["solver"]["epsilon"] = json!(2.5e-4);
    necessary_for_the_gallery(
        &shelf,
        128,
        true,
        Rules::without_near_occluders(),
        "a shelf 10 cm from a wall, at ε = 2.5e-4",
    );
    necessary_for_the_gallery(
        &support::scene_file("gallery/side-shelf"),
        256,
        true,
        Rules::without_near_occluders(),
        "a shelf 10 cm from a side wall",
    );
}
