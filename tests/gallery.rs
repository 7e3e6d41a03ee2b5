//! The gallery: 3D scenes that no part of the solver was tuned on (rooms with 3 × 3 and 7 × 7
//! boxes, rotated boxes, an object much smaller than its room, a box against a wall, a light in
//! a corner, spheres and boxes as meshes; `scenes/gallery/make.py` writes them), solved at the document's defaults and
//! compared with the independent path tracer of [`tracer`].
//!
//! What the method must achieve at its defaults (order 1): every surface's mean within 1 % of
//! the reference and every cell of the 4 × 4 grid within 5 %, each beyond four of the
//! reference's standard errors; at order 0, every surface's mean within 3 %; order 2 no worse
//! than order 1. Six small objects in a large room meet it (a cube under the light, in a
//! corner, turned by 30°, beside a box and under a light in a corner, and a low slab), two
//! boxes 2 cm apart and nine everyday shapes (the shelf near a side wall was written with the
//! near occluders' rule, which it needs; a cabinet 1 cm from a wall and a box 5 mm from one
//! with the narrow gaps' sizes). Two more scenes of `make.py` do not yet and are not
//! tested here (`benches/README.md`, "Scenes it was not made from").

mod support;
mod tracer;

use serde_json::{json, Value};
use tracer::{reference, Gaps, Tracer};
use wavrad::job;
use wavrad::progress::Silent;
use wavrad::scene::{parse_value, Limits};

fn gallery(name: &str) -> Value {
    support::scene_file(&format!("gallery/{name}"))
}

fn gaps(doc: &Value, per_side: usize, z: f64) -> Gaps {
    let want = reference(doc, per_side);
    let j = parse_value(doc, &Limits::default()).expect("valid document");
    let out = job::run(&j, &Silent).expect("solves");
    eprintln!(
        "{}",
        out.result
            .timings_ms
            .iter()
            .map(|(k, v)| format!("{k} {v:.0} ms"))
            .collect::<Vec<_>>()
            .join(", ")
    );
    let g = Tracer::new(doc).gaps(&out.result.surfaces, &want, z);
    eprintln!(
        "{}: worst surface mean {:.2} % ({}), worst cell {:.2} % ({}), {} links",
        doc["scene"]["name"],
        100.0 * g.surface.0,
        g.surface.1,
        100.0 * g.cell.0,
        g.cell.1,
        out.result.hierarchical.as_ref().map_or(0, |h| h.links)
    );
    g
}

fn at_defaults(name: &str, per_side: usize) {
    let doc = gallery(name);
    let g = gaps(&doc, per_side, 4.0);
    assert!(
        g.surface.0 < 0.01,
        "{name}: {} off by {:.2} %",
        g.surface.1,
        100.0 * g.surface.0
    );
    assert!(
        g.cell.0 < 0.05,
        "{name}: a cell of {} off by {:.2} %",
        g.cell.1,
        100.0 * g.cell.0
    );
}

fn at_order_0(name: &str, per_side: usize) {
    let mut doc = gallery(name);
    doc["solver"]["order"] = json!(0);
    let g = gaps(&doc, per_side, 4.0);
    assert!(
        g.surface.0 < 0.03,
        "{name}: {} off by {:.2} %",
        g.surface.1,
        100.0 * g.surface.0
    );
}

#[test]
fn a_room_with_3_by_3_boxes() {
    at_defaults("room-3x3", 128);
}

/// 252 surfaces, most of them small and partly hidden from each other: a receiver's
/// tolerance shared by form factor alone put the corner boxes' faces toward the walls 5.5 %
/// bright (`hierarchy::tolerance`).
#[test]
fn a_room_with_7_by_7_boxes() {
    at_defaults("room-7x7", 128);
}

#[test]
fn rotated_boxes() {
    at_defaults("rotated-boxes", 128);
}

#[test]
fn a_box_against_a_wall() {
    at_defaults("box-against-wall", 128);
}

#[test]
fn a_light_in_a_corner() {
    at_defaults("corner-light", 128);
}

#[test]
fn order_0_in_the_3_by_3_room() {
    at_order_0("room-3x3", 64);
}

#[test]
fn order_2_is_no_worse_than_order_1() {
    let doc = gallery("rotated-boxes");
    // 192² paths per cell: the reference's noise (0.37 % of the cell means) below the gaps
    // it compares (at 64², 1.1 %, the two orders' gaps were both within its noise, and
    // which came out ahead was the reference's draw)
    let want = reference(&doc, 192);
    let mut net = Vec::new();
    for order in [1, 2] {
        let mut d = doc.clone();
        d["solver"]["order"] = json!(order);
        net.push(tracer::compare(&d, &want, &format!("order {order}")).net());
    }
    // within the reference's noise of each other, or better
    assert!(
        net[1] <= net[0] + 0.002,
        "order 2: {:.2} %, order 1: {:.2} %",
        100.0 * net[1],
        100.0 * net[0]
    );
}

/// A cube of 0.3 units in a 10-unit room: under its light, in a corner (at (1.5, 1.5)) and
/// turned by 30°. Its sides see mostly the floor at their foot, where the cube hides part of
/// every wall; before the contact lines' split was made on the receiver whatever the pieces'
/// sizes, the walls' pieces lit that strip through links of coarse floor elements as if the
/// cube were not there, and the sides came out 1.0–1.7 % beyond the noise (raw 1.9–2.6 %).
#[test]
fn a_small_object() {
    at_defaults("small-object", 128);
}

#[test]
fn a_small_cube_in_a_corner() {
    at_defaults("small-cube-in-a-corner", 128);
}

#[test]
fn a_small_cube_turned() {
    at_defaults("small-cube-turned", 128);
}

/// Three small objects whose features are finer than a 64th of the room's diagonal, which the
/// default `min_element_size` follows down to their size: a cube of 0.25 under a light in a
/// corner (at a 64th each face was one element and a cell 6.5 % off), a slab 0.15 high (the
/// floor's first 3 cm at its foot inside one element: 2.3 % and 8.0 %) and a cube of 0.3
/// beside a box (1.1 %, 11.4 %).
#[test]
fn a_small_cube_under_a_light_in_a_corner() {
    at_defaults("small-cube-corner-light", 128);
}

#[test]
fn a_low_slab() {
    at_defaults("small-slab", 128);
}

#[test]
fn a_small_cube_beside_a_box() {
    at_defaults("small-cube-beside-a-box", 128);
}

/// Two boxes 2 cm apart: each side in the gap sees the other's B at the scale of the gap, and
/// the elements around the space between faces that see each other across a gap narrower than
/// the default size go down to no larger than the gap (`sizing`'s narrow parts). At the
/// room's 0.24 alone, the side of the lower box in the gap came out 25 % bright and a cell of
/// it 76 %.
#[test]
fn two_boxes_a_narrow_gap_apart() {
    at_defaults("two-boxes-apart", 128);
}

/// Everyday shapes written after the default element size followed the smallest face and the
/// narrowest gap, to try it on scenes it was not made from: a small cube on a box, a pillar
/// 0.2 thick, a partition 5 cm thick, a table on legs 6 cm thick, a light 10 cm from a wall,
/// three cubes stacked, and a shelf near a side wall.
#[test]
fn a_small_cube_on_a_box() {
    at_defaults("cube-on-a-box", 128);
}

#[test]
fn a_thin_pillar() {
    at_defaults("pillar", 128);
}

#[test]
fn a_thin_partition() {
    at_defaults("partition", 128);
}

#[test]
fn a_table_on_thin_legs() {
    at_defaults("table", 128);
}

#[test]
fn a_light_near_a_wall() {
    at_defaults("light-near-a-wall", 128);
}

/// A shelf 4 cm thick, 10 cm from a side wall, lit from a corner: its side toward the wall
/// needs the near occluders' rule (`tests/rules.rs`).
#[test]
fn a_shelf_near_a_side_wall() {
    at_defaults("side-shelf", 128);
}

/// Gaps narrower than a 256th of the room's diagonal: a cabinet whose back is 1 cm from the
/// wall, lit from a corner (6.1 % off on its back, a cell 9.3 %, when one size for the whole
/// scene stopped at that 256th), and a box turned by 5° whose nearest edge is 5 mm from a
/// side wall (a cell of its side toward the wall 26 %): the elements across a narrow gap go
/// down to its width at its mouth and grade to coarser inside it (`sizing`). The cabinet's
/// back is lit only by paths through the 1 cm slot: at 128² paths a cell the tracer finds
/// almost none on some of its cells and states a noise far too small (a cell "3967 %" off),
/// so it takes 256².
#[test]
fn a_cabinet_a_centimetre_from_the_wall() {
    at_defaults("cabinet", 256);
}

#[test]
fn a_turned_box_near_a_wall() {
    at_defaults("turned-box-near-a-wall", 128);
}

/// Three cubes stacked, each turned: the top cube covers most of the middle cube's top, whose
/// cells under it were reported as the partly covered elements' projections (0.021 where the
/// tracer has 0.0069, 214 % beyond the noise) before the numbers took the covered part apart
/// from the exposed one (`Hierarchy::reported_fields`).
#[test]
fn a_stack_of_turned_cubes() {
    at_defaults("stack", 128);
}

/// The defaults bound each link's error against ε times the brightest emission, so a surface
/// much dimmer than the light (the sides of a small cube under a bright light) gets a larger
/// relative error; it falls to the reference's noise as ε shrinks.
#[test]
fn a_small_object_converges_as_epsilon_shrinks() {
    let mut gaps_at = Vec::new();
    for epsilon in [1e-3, 2.5e-4, 6.25e-5] {
        let mut doc = gallery("small-object");
        doc["solver"]["epsilon"] = json!(epsilon);
        gaps_at.push(gaps(&doc, 64, 4.0).surface.0);
    }
    assert!(
        gaps_at[2] < 0.01,
        "at ε = 6.25e-5: {:.2} %",
        100.0 * gaps_at[2]
    );
    assert!(gaps_at[2] <= gaps_at[0], "{gaps_at:?}");
}

/// Two icospheres (320 and 80 triangles) and two turned boxes, each one mesh, in a room of
/// parallelograms, held to the gallery's requirement: every surface's mean within 1 % and
/// every triangle within 5 % of the reference, beyond four of its standard errors. (The big
/// ball's bottom was 125 % off before the shadow budget, `hierarchy::shadows`: the walls'
/// partly visible links into the floor's element that holds its contact point, each within
/// the tolerance, all sent light into its shadow. The small ball's two bottom triangles were
/// 8.7 % and 6.9 % bright while the floor's elements lit them through cluster links at the
/// angle toward the ball's centre rather than their own, `hierarchy::clustered`.)
#[test]
fn meshes_on_a_floor() {
    at_defaults("meshes-on-a-floor", 64);
}

/// The room with 3 × 3 boxes, each box one mesh of ten triangles, so that the boxes are
/// clusters and their light reaches the room through cluster links: each member's held kernel
/// read at its points and its ray drawn by the light it carries
/// (`three_d::hierarchy::clustered`), its worst box 0.86 % off beyond four standard errors
/// (1.40 % raw) and its worst triangle's cell 4.68 %. (Read at each member's centroid with a
/// ray between uniform points, 1.26 % and 3.79 %.) 256² paths a cell: a box's triangles are
/// small.
#[test]
fn a_room_with_3_by_3_boxes_as_meshes() {
    at_defaults("room-3x3-meshes", 256);
}
