//! Geometry that the format allows but that cannot be right is solved all the same, and the
//! result says so: `warnings`, each with the JSON paths of the surfaces involved. Touching
//! (a corner, an edge, a wall standing on a floor) is not a warning, and no example scene has
//! any.

use serde_json::{json, Value};
use wavrad::scene::{parse_value, Limits};

fn warnings(doc: &Value) -> Vec<(Vec<String>, String)> {
    let job = parse_value(doc, &Limits::default()).unwrap();
    wavrad::warnings::geometry(&job)
        .into_iter()
        .map(|w| (w.paths, w.message))
        .collect()
}

fn paths(w: &[(Vec<String>, String)]) -> Vec<Vec<String>> {
    w.iter().map(|(p, _)| p.clone()).collect()
}

fn flatland(segments: &[[[f64; 2]; 2]]) -> Value {
    let surfaces: Vec<Value> = segments
        .iter()
        .enumerate()
        .map(|(i, s)| {
            json!({"name": format!("s{i}"), "segment": s, "reflectance": 0.5, "emission": 1})
        })
        .collect();
    json!({"scene": {"kind": "flatland", "surfaces": surfaces}, "solver": {"resolution": 4}})
}

/// A light far below the scenes of [`three_d`], facing away from them.
const LIGHT: [[f64; 3]; 4] = [
    [0.0, -10.0, 0.0],
    [1.0, -10.0, 0.0],
    [1.0, -10.0, 1.0],
    [0.0, -10.0, 1.0],
];

/// The quads, emitting nothing, and [`LIGHT`] after them: the warnings about pairs of
/// surfaces, without light falling on any of them (that has its own warning:
/// [`light_on_the_back_of_a_surface_is_a_warning`]).
fn three_d(quads: &[[[f64; 3]; 4]]) -> Value {
    let surfaces: Vec<Value> = quads
        .iter()
        .enumerate()
        .map(|(i, c)| json!({"name": format!("q{i}"), "corners": c, "reflectance": 0.5, "emission": 0}))
        .chain([json!({"name": "light", "corners": LIGHT, "reflectance": 0, "emission": 1})])
        .collect();
    json!({"scene": {"kind": "3d", "surfaces": surfaces}, "solver": {"resolution": 2, "order": 0}})
}

fn p(paths: &[&str]) -> Vec<String> {
    paths.iter().map(|s| s.to_string()).collect()
}

#[test]
fn crossing_segments_are_named_by_their_paths() {
    // an X, and a third segment apart from both
    let w = warnings(&flatland(&[
        [[0.0, 0.0], [1.0, 1.0]],
        [[0.0, 1.0], [1.0, 0.0]],
        [[3.0, 0.0], [4.0, 0.0]],
    ]));
    assert_eq!(
        paths(&w),
        vec![p(&["/scene/surfaces/0", "/scene/surfaces/1"])]
    );
    assert!(
        w[0].1.contains("\"s0\" and \"s1\" cross at (0.5, 0.5)"),
        "{}",
        w[0].1
    );
}

#[test]
fn collinear_overlapping_segments_are_a_warning() {
    let w = warnings(&flatland(&[
        [[0.0, 0.0], [2.0, 0.0]],
        [[5.0, 5.0], [6.0, 5.0]],
        [[1.0, 0.0], [1.5, 0.0]],
    ]));
    assert_eq!(
        paths(&w),
        vec![p(&["/scene/surfaces/0", "/scene/surfaces/2"])]
    );
    assert!(
        w[0].1
            .contains("facing the same way, and overlap over a length of 0.5"),
        "{}",
        w[0].1
    );
    // back to back (a two-sided thin wall) is not a warning
    let w = warnings(&flatland(&[
        [[0.0, 0.0], [2.0, 0.0]],
        [[2.0, 0.0], [0.0, 0.0]],
    ]));
    assert!(w.is_empty(), "{w:?}");
}

#[test]
fn segments_that_touch_are_not_a_warning() {
    // a closed triangle (shared ends), a T (an end on another's middle), collinear end to end
    let w = warnings(&flatland(&[
        [[0.0, 0.0], [1.0, 0.0]],
        [[1.0, 0.0], [0.0, 1.0]],
        [[0.0, 1.0], [0.0, 0.0]],
        [[0.5, 0.0], [0.5, -1.0]],
        [[1.0, 0.0], [2.0, 0.0]],
    ]));
    assert!(w.is_empty(), "{w:?}");
}

const FLOOR: [[f64; 3]; 4] = [
    [0.0, 0.0, 0.0],
    [0.0, 0.0, 1.0],
    [1.0, 0.0, 1.0],
    [1.0, 0.0, 0.0],
];

#[test]
fn surfaces_passing_through_each_other_are_named_by_their_paths() {
    // a wall at z = 0.5 from y = -0.5 to 0.5: through the floor along x from 0.2 to 0.8
    let wall = [
        [0.2, -0.5, 0.5],
        [0.8, -0.5, 0.5],
        [0.8, 0.5, 0.5],
        [0.2, 0.5, 0.5],
    ];
    let w = warnings(&three_d(&[FLOOR, wall]));
    assert_eq!(
        paths(&w),
        vec![p(&["/scene/surfaces/0", "/scene/surfaces/1"])]
    );
    let m = &w[0].1;
    assert!(m.contains("pass through each other"), "{m}");
    assert!(m.contains("length 0.6 through (0.5, 0, 0.5)"), "{m}");
}

#[test]
fn coplanar_overlapping_surfaces_are_a_warning() {
    // a light patch laid on the floor's plane, half over it
    let patch = [
        [0.75, 0.0, 0.25],
        [0.75, 0.0, 0.75],
        [1.25, 0.0, 0.75],
        [1.25, 0.0, 0.25],
    ];
    let w = warnings(&three_d(&[FLOOR, patch]));
    assert_eq!(
        paths(&w),
        vec![p(&["/scene/surfaces/0", "/scene/surfaces/1"])]
    );
    assert!(
        w[0].1
            .contains("lie in one plane, facing the same way, and overlap over an area of 0.125"),
        "{}",
        w[0].1
    );
    // next to it, sharing an edge: touching
    let beside = [
        [1.0, 0.0, 0.0],
        [1.0, 0.0, 1.0],
        [2.0, 0.0, 1.0],
        [2.0, 0.0, 0.0],
    ];
    assert!(warnings(&three_d(&[FLOOR, beside])).is_empty());
    // the floor's underside as its own surface, back to back with it: a two-sided floor
    let under = [FLOOR[0], FLOOR[3], FLOOR[2], FLOOR[1]];
    assert!(warnings(&three_d(&[FLOOR, under])).is_empty());
}

#[test]
fn a_box_of_walls_that_meet_at_their_edges_is_not_a_warning() {
    // the floor, a wall standing on it along an edge, a wall standing in its middle
    let back = [
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [1.0, 1.0, 0.0],
        [0.0, 1.0, 0.0],
    ];
    let middle = [
        [0.0, 0.0, 0.5],
        [1.0, 0.0, 0.5],
        [1.0, 1.0, 0.5],
        [0.0, 1.0, 0.5],
    ];
    let w = warnings(&three_d(&[FLOOR, back, middle]));
    assert!(w.is_empty(), "{w:?}");
}

/// A closed unit-cube room (walls facing in) with a light patch under its ceiling and a box
/// on its floor: five faces, each a surface, facing out (`inward`: false) or in.
fn room_with_a_box(inward: bool) -> Value {
    let face = |c: [[f64; 3]; 4], name: &str, emission: f64| json!({"name": name, "corners": c, "reflectance": 0.5, "emission": emission});
    // the room's walls (facing in) and the light (facing down), as seen from their fronts
    let (o, l, y) = (0.0, 1.0, 0.99);
    let room = [
        ([[o, o, o], [o, o, l], [l, o, l], [l, o, o]], "floor", 0.0),
        ([[o, l, o], [l, l, o], [l, l, l], [o, l, l]], "ceiling", 0.0),
        ([[o, o, o], [l, o, o], [l, l, o], [o, l, o]], "south", 0.0),
        ([[o, o, l], [o, l, l], [l, l, l], [l, o, l]], "north", 0.0),
        ([[o, o, o], [o, l, o], [o, l, l], [o, o, l]], "west", 0.0),
        ([[l, o, o], [l, o, l], [l, l, l], [l, l, o]], "east", 0.0),
        (
            [[0.4, y, 0.4], [0.6, y, 0.4], [0.6, y, 0.6], [0.4, y, 0.6]],
            "light",
            10.0,
        ),
    ];
    let mut surfaces: Vec<Value> = room.into_iter().map(|(c, n, e)| face(c, n, e)).collect();
    // the box [0.3, 0.7] × [0, 0.3] × [0.3, 0.7], each face as seen from outside
    let (a, b, h) = (0.3, 0.7, 0.3);
    let mut faces = vec![
        ([[a, h, a], [a, h, b], [b, h, b], [b, h, a]], "box-top"),
        (
            [[a, 0.0, a], [a, h, a], [b, h, a], [b, 0.0, a]],
            "box-south",
        ),
        (
            [[a, 0.0, b], [b, 0.0, b], [b, h, b], [a, h, b]],
            "box-north",
        ),
        ([[a, 0.0, a], [a, 0.0, b], [a, h, b], [a, h, a]], "box-west"),
        ([[b, 0.0, a], [b, h, a], [b, h, b], [b, 0.0, b]], "box-east"),
    ];
    if inward {
        for (c, _) in &mut faces {
            c.swap(1, 3);
        }
    }
    surfaces.extend(faces.into_iter().map(|(c, name)| face(c, name, 0.0)));
    json!({"scene": {"kind": "3d", "surfaces": surfaces}, "solver": {"method": "hierarchical"}})
}

#[test]
fn light_on_the_back_of_a_surface_is_a_warning() {
    assert!(warnings(&room_with_a_box(false)).is_empty());
    let w = warnings(&room_with_a_box(true));
    // the light (0.2 × 0.2 under the ceiling's centre) sees the box's top (0.4 × 0.4, 0.69
    // below it) and none of its sides: inside out, the top takes what falls on it on its
    // black back, the light's form factor to it (0.0941, the point-to-rectangle closed form
    // averaged over the light), within 4 standard errors of 4096 rays (0.46 % each)
    assert_eq!(paths(&w), vec![p(&["/scene/surfaces/7"])]);
    let top = &w[0].1;
    assert!(top.contains("on the back of surface \"box-top\""), "{top}");
    let share: f64 = top.split(" %").next().unwrap().parse().unwrap();
    assert!((share - 9.41).abs() <= 4.0 * 0.46, "{top}");
}

#[test]
fn a_light_shut_in_a_box_is_not_a_warning() {
    // the light moved into the (closed, outward) box, facing up under its top: every ray
    // meets the box from inside, where the light is covered (it sends nothing into the
    // room), so no surface is said to take the light on its back
    let mut doc = room_with_a_box(false);
    doc["scene"]["surfaces"][6]["corners"] = json!([
        [0.4, 0.1, 0.4],
        [0.4, 0.1, 0.6],
        [0.6, 0.1, 0.6],
        [0.6, 0.1, 0.4]
    ]);
    let w = warnings(&doc);
    assert!(w.is_empty(), "{w:?}");
}

#[test]
fn no_example_scene_has_a_warning() {
    let scenes = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes");
    let files = [scenes.to_string(), format!("{scenes}/gallery")]
        .into_iter()
        .flat_map(|dir| std::fs::read_dir(dir).unwrap())
        .map(|entry| entry.unwrap().path())
        .filter(|path| path.extension().is_some_and(|x| x == "json"));
    for path in files {
        let doc: Value = serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
        let w = warnings(&doc);
        assert!(w.is_empty(), "{}: {w:?}", path.display());
    }
}

#[test]
fn the_job_still_runs_and_its_result_carries_the_warnings() {
    let doc = flatland(&[[[0.0, 0.0], [1.0, 1.0]], [[0.0, 1.0], [1.0, 0.0]]]);
    let job = parse_value(&doc, &Limits::default()).unwrap();
    let outcome = wavrad::job::run(&job, &wavrad::progress::Silent).unwrap();
    let result = serde_json::to_value(&outcome.result).unwrap();
    assert_eq!(
        result["warnings"][0]["paths"],
        json!(["/scene/surfaces/0", "/scene/surfaces/1"])
    );
    assert!(result["warnings"][0]["message"]
        .as_str()
        .unwrap()
        .contains("cross"));
    assert!(result["surfaces"][0]["mean"][0].as_f64().unwrap() > 0.0);
    // a scene without such geometry answers an empty list
    let clean = flatland(&[[[0.0, 0.0], [1.0, 0.0]], [[1.0, 1.0], [0.0, 1.0]]]);
    let job = parse_value(&clean, &Limits::default()).unwrap();
    let outcome = wavrad::job::run(&job, &wavrad::progress::Silent).unwrap();
    let result = serde_json::to_value(&outcome.result).unwrap();
    assert_eq!(result["warnings"], json!([]));
}
