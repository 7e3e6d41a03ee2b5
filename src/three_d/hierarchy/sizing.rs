//! How fine the elements of each surface may get: `solver.min_element_size` of the job
//! document, an edge length in scene units that is the same on every surface, so that a small
//! object in a large room is meshed as finely as the room around it needs, and an element of
//! a large wall is no finer than one of a small box. The refinement oracle decides how far
//! towards it each part of a surface goes; this only bounds it.
//!
//! A surface's quadtree level ℓ has elements with edges |e₁| / 2^ℓ and |e₃| / 2^ℓ; the finest
//! level is the deepest whose longer edge is still at least the smallest element size h:
//! ℓ_max = ⌊log₂(max(|e₁|, |e₃|) / h)⌋, at least 0 (a surface smaller than h is one element)
//! and at most [`MAX_LEVEL`]. When the document also gives `resolution`, ℓ_max is at most
//! log₂ of it as well.

use crate::three_d::geometry::{bounding_box, norm, quad_quad, sub, Parallelogram, V3};

/// The deepest level of any surface's quadtree: 1024 × 1024 elements, the document's largest
/// `resolution`; also the deepest that the numbers split a covered part off to
/// (`Hierarchy::reported_fields`).
pub(super) const MAX_LEVEL: u32 = 10;

/// The default smallest element size is at most the diagonal of the scene's bounding box
/// divided by this. The Cornell box (diagonal 961) gets 15 units: its 555-unit walls at most
/// 32 × 32, the resolution its document gives. A 10-unit room with 3 × 3 boxes gets 0.27: its
/// floor at most 32 × 32, each 1.7-unit box face at most 4 × 4. On that room the surface means
/// at a 64th, a 128th and a 256th of the diagonal agree within 0.02 % of each other (and
/// within the path tracer's 0.5 % noise of it), for 564 k, 847 k and 1.33 M links.
const DEFAULT_DIVISIONS: f64 = 64.0;

/// The default smallest element size is at least the diagonal divided by this, however small
/// the scene's smallest face: a sliver does not make the whole scene's refinement unbounded
/// (its links grow about as 1 / h along the contact lines and shadow edges). A 256th closes
/// every small object of the gallery (benches/README, "A finer default size"); a document
/// that needs finer gives `min_element_size`.
const FINEST_DEFAULT_DIVISIONS: f64 = 256.0;

/// The smallest element edge and, when the document gives it, the finest resolution.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Sizing {
    pub(super) min_element_size: f64,
    resolution: Option<usize>,
}

impl Sizing {
    /// `min_element_size` when given, else the default from the scene's size.
    pub(super) fn new(
        quads: &[Parallelogram],
        min_element_size: Option<f64>,
        resolution: Option<usize>,
    ) -> Sizing {
        Sizing {
            min_element_size: min_element_size.unwrap_or_else(|| default_size(quads)),
            resolution,
        }
    }

    /// The finest quadtree level of surface `q`: of a parallelogram by its longer side (and
    /// `resolution`, when given), of a triangle by its longest side.
    pub(super) fn finest_level(&self, q: &Parallelogram) -> u32 {
        let edge = if q.tri {
            q.diameter()
        } else {
            norm(q.e1).max(norm(q.e3))
        };
        let ratio = edge / self.min_element_size;
        let by_size = if ratio >= 1.0 {
            (ratio.log2().floor() as u32).min(MAX_LEVEL)
        } else {
            0
        };
        match self.resolution {
            Some(r) if !q.tri => by_size.min(r.trailing_zeros()),
            _ => by_size,
        }
    }
}

/// The default smallest element size: a 64th of the scene's diagonal, or the smallest face's
/// size or the narrowest gap when either is smaller, but no less than a 256th of the diagonal.
///
/// The refinement bounds each link's error by splitting, and stops at the finest level: below
/// it, ε bounds nothing. What the finest element must still resolve is set by the geometry,
/// and its scale is the size of the faces that make it: the shadow and the dip in irradiance
/// at the foot of a face of height a are about a wide, so a floor element larger than a puts
/// one plane across them; and a face whose longer side is one element has one plane for its
/// own variation, however the light falls across it. So a parallelogram's size is its shorter
/// side, or half its longer side when that is less: a 0.3 cube in a 10-unit room gets 0.15,
/// a slab 0.15 high 0.15, instead of the room's 0.27 (benches/README: three of the gallery's
/// six small objects miss its requirement at a 64th, and all six meet it at this size).
/// Likewise the narrowest gap between two faces that see each other without touching
/// ([`narrowest_gap`]): across a gap d the kernel 1 / r² varies over d, and each face sees the
/// other's B at that scale (two boxes 2 cm apart: the one's side in the gap 25 % bright at
/// the room's 0.24, within the noise at 0.06). Faces that touch are the contact lines'
/// (`refine`), not the size's.
///
/// Triangles (lone or of meshes) take no part: a mesh's triangles tessellate an object, and
/// their sizes are not the object's (a sphere's 1280 triangles, a book's 2 cm edge), so they
/// would ask the whole scene for the finest triangle's size; their own level is already set
/// by their longest side.
fn default_size(quads: &[Parallelogram]) -> f64 {
    let diagonal = scene_diagonal(quads);
    let smallest_face = quads
        .iter()
        .filter(|q| !q.tri)
        .map(|q| {
            let (a, b) = (norm(q.e1), norm(q.e3));
            a.min(b).min(a.max(b) / 2.0)
        })
        .fold(f64::INFINITY, f64::min);
    let coarsest = diagonal / DEFAULT_DIVISIONS;
    coarsest
        .min(smallest_face)
        .min(narrowest_gap(quads, coarsest, diagonal).unwrap_or(f64::INFINITY))
        .max(diagonal / FINEST_DEFAULT_DIVISIONS)
}

/// The smallest distance below `within` between two parallelograms that see each other (each
/// has a part in front of the other's plane) and do not touch (farther apart than a 10⁹th of
/// the scene's `diagonal`): the back-to-back faces of a thin slab do not count, nor a box's
/// side and the floor it stands on. Pairs are swept along x by their bounding boxes grown by
/// `within`, so a room of many faces costs about one test per near pair.
fn narrowest_gap(quads: &[Parallelogram], within: f64, diagonal: f64) -> Option<f64> {
    let touch = 1e-9 * diagonal;
    let faces: Vec<(&Parallelogram, V3, V3)> = quads
        .iter()
        .filter(|q| !q.tri)
        .map(|q| {
            let (lo, hi) = bounding_box(std::slice::from_ref(q));
            (q, lo, hi)
        })
        .collect();
    let mut order: Vec<usize> = (0..faces.len()).collect();
    order.sort_by(|&a, &b| faces[a].1[0].total_cmp(&faces[b].1[0]));
    let mut narrowest: Option<f64> = None;
    for (k, &a) in order.iter().enumerate() {
        let (p, plo, phi) = faces[a];
        for &b in &order[k + 1..] {
            let (q, qlo, qhi) = faces[b];
            if qlo[0] > phi[0] + within {
                break;
            }
            let apart = (1..3).any(|i| qlo[i] > phi[i] + within || plo[i] > qhi[i] + within);
            if apart || !in_front(q, p, touch) || !in_front(p, q, touch) {
                continue;
            }
            let d = quad_quad(&p.outline(), p.n, &q.outline(), q.n);
            if d > touch && d < within && narrowest.is_none_or(|n| d < n) {
                narrowest = Some(d);
            }
        }
    }
    narrowest
}

/// Whether some corner of `q` lies in front of `p`'s plane.
fn in_front(q: &Parallelogram, p: &Parallelogram, touch: f64) -> bool {
    q.outline().iter().any(|&c| p.side(c) > touch)
}

/// The diagonal of the bounding box of every corner of the scene.
fn scene_diagonal(quads: &[Parallelogram]) -> f64 {
    let (lo, hi) = bounding_box(quads);
    norm(sub(hi, lo))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square_at(z: f64, side: f64) -> Parallelogram {
        Parallelogram::new(&[
            [0.0, 0.0, z],
            [side, 0.0, z],
            [side, side, z],
            [0.0, side, z],
        ])
    }

    fn square(side: f64) -> Parallelogram {
        square_at(0.0, side)
    }

    #[test]
    fn the_finest_level_is_the_deepest_whose_edge_is_at_least_the_size() {
        let sizing = Sizing {
            min_element_size: 1.0,
            resolution: None,
        };
        // 10 / 2³ = 1.25 ≥ 1 > 10 / 2⁴
        assert_eq!(sizing.finest_level(&square(10.0)), 3);
        assert_eq!(sizing.finest_level(&square(8.0)), 3);
        assert_eq!(sizing.finest_level(&square(7.99)), 2);
        // smaller than one element: the whole surface
        assert_eq!(sizing.finest_level(&square(0.3)), 0);
        // never past the deepest level
        assert_eq!(sizing.finest_level(&square(1e9)), MAX_LEVEL);
    }

    #[test]
    fn a_given_resolution_caps_the_level() {
        let sizing = Sizing {
            min_element_size: 0.01,
            resolution: Some(32),
        };
        assert_eq!(sizing.finest_level(&square(10.0)), 5);
        assert_eq!(sizing.finest_level(&square(0.04)), 2);
    }

    #[test]
    fn the_default_follows_the_scene_size() {
        // a unit cube's diagonal is √3
        let quads = [square(1.0), square_at(1.0, 1.0)];
        let sizing = Sizing::new(&quads, None, None);
        let want = 3f64.sqrt() / DEFAULT_DIVISIONS;
        assert!((sizing.min_element_size - want).abs() < 1e-15);
        assert_eq!(Sizing::new(&quads, Some(0.5), None).min_element_size, 0.5);
    }

    /// A room of 10 with one face of `w` × `l` on its floor.
    fn room_with_face(w: f64, l: f64) -> Vec<Parallelogram> {
        let face = Parallelogram::new(&[
            [4.0, 0.0, 4.0],
            [4.0 + l, 0.0, 4.0],
            [4.0 + l, w, 4.0],
            [4.0, w, 4.0],
        ]);
        vec![square(10.0), square_at(10.0, 10.0), face]
    }

    #[test]
    fn the_default_resolves_the_smallest_face() {
        let diagonal = 300f64.sqrt();
        let size = |w, l| Sizing::new(&room_with_face(w, l), None, None).min_element_size;
        let near = |a: f64, b: f64| (a - b).abs() < 1e-12;
        // a face larger than the room's 64th leaves the default as it was
        assert_eq!(size(1.0, 1.0), diagonal / DEFAULT_DIVISIONS);
        // a square of 0.2: half its side, so that it is split at least once
        assert!(near(size(0.2, 0.2), 0.1));
        // a side 0.15 × 0.3: its 0.15, and half the 0.3; 0.25 × 0.3: half the 0.3
        assert!(near(size(0.15, 0.3), 0.15));
        assert!(near(size(0.25, 0.3), 0.15));
        // a long thin face: its width; a short wide one too
        assert!(near(size(0.1, 5.0), 0.1));
        assert!(near(size(5.0, 0.25), 0.25));
        // a sliver: no finer than a 256th of the diagonal
        assert_eq!(size(1e-4, 1.0), diagonal / FINEST_DEFAULT_DIVISIONS);
        // every one of them along the room's own side: at most 256 elements
        let finest = Sizing::new(&room_with_face(1e-4, 1.0), None, None);
        assert_eq!(finest.finest_level(&square(10.0)), 7);
    }

    /// A unit box's face at `x` facing `dir` (±1) along x: its corners at y, z ∈ [0, 1].
    fn wall(x: f64, dir: f64) -> Parallelogram {
        let (z0, z1) = if dir > 0.0 { (0.0, 1.0) } else { (1.0, 0.0) };
        Parallelogram::new(&[[x, 0.0, z0], [x, 1.0, z0], [x, 1.0, z1], [x, 0.0, z1]])
    }

    #[test]
    fn the_narrowest_gap_is_between_faces_that_see_each_other() {
        let diagonal = 10.0;
        let gap = |quads: &[Parallelogram]| narrowest_gap(quads, 1.0, diagonal);
        assert!(wall(0.0, 1.0).n[0] > 0.0 && wall(0.0, -1.0).n[0] < 0.0);
        // two faces 2 cm apart, facing each other
        let facing = [wall(0.0, 1.0), wall(0.02, -1.0)];
        assert!((gap(&facing).unwrap() - 0.02).abs() < 1e-12);
        // back to back (a slab 2 cm thick), facing the same way, or farther than `within`
        assert_eq!(gap(&[wall(0.0, -1.0), wall(0.02, 1.0)]), None);
        assert_eq!(gap(&[wall(0.0, 1.0), wall(0.02, 1.0)]), None);
        assert_eq!(gap(&[wall(0.0, 1.0), wall(1.5, -1.0)]), None);
        // a box's side on the floor it stands on: they touch
        let side = wall(0.5, 1.0);
        assert_eq!(gap(&[square(1.0), side]), None);
        // the same side lifted 3 cm: the gap is its lower edge's to the floor
        let lifted = Parallelogram::new(&[
            [0.5, 0.03, 0.0],
            [0.5, 1.03, 0.0],
            [0.5, 1.03, 1.0],
            [0.5, 0.03, 1.0],
        ]);
        let floor_up = Parallelogram::new(&[
            [0.0, 0.0, 0.0],
            [0.0, 0.0, 1.0],
            [1.0, 0.0, 1.0],
            [1.0, 0.0, 0.0],
        ]);
        assert!(floor_up.n[1] > 0.0);
        assert!((gap(&[floor_up, lifted]).unwrap() - 0.03).abs() < 1e-12);
        // a face through another: they touch
        let through = Parallelogram::new(&[
            [0.5, -0.5, 0.5],
            [0.5, 0.5, 0.5],
            [0.5, 0.5, 0.7],
            [0.5, -0.5, 0.7],
        ]);
        assert_eq!(gap(&[floor_up, through]), None);
        // edge to edge, the corners of neither over the other
        let beside = Parallelogram::new(&[
            [1.05, 0.0, 0.0],
            [1.05, 0.0, 1.0],
            [2.05, 0.0, 1.0],
            [2.05, 0.0, 0.0],
        ]);
        let tilted = Parallelogram::new(&[
            [1.05, 0.0, 0.0],
            [1.05, 0.0, 1.0],
            [2.05, 1.0, 1.0],
            [2.05, 1.0, 0.0],
        ]);
        assert_eq!(gap(&[floor_up, beside]), None, "coplanar: neither in front");
        assert!((gap(&[floor_up, tilted]).unwrap() - 0.05).abs() < 1e-12);
    }

    #[test]
    fn the_default_resolves_the_narrowest_gap() {
        // a room of 10 with two boxes' faces 10 cm apart in it: the gap, above a 256th
        let mut quads = vec![square(10.0), square_at(10.0, 10.0)];
        let at = |q: Parallelogram, dx: f64| {
            let c = q.outline().map(|c| [c[0] + dx, c[1], c[2] + 4.0]);
            Parallelogram::new(&c)
        };
        quads.push(at(wall(0.0, 1.0), 4.0));
        quads.push(at(wall(0.1, -1.0), 4.0));
        let size = Sizing::new(&quads, None, None).min_element_size;
        assert!((size - 0.1).abs() < 1e-12, "{size}");
        // 5 mm apart: a 256th of the diagonal
        quads[3] = at(wall(0.005, -1.0), 4.0);
        let size = Sizing::new(&quads, None, None).min_element_size;
        assert_eq!(size, 300f64.sqrt() / FINEST_DEFAULT_DIVISIONS);
    }

    #[test]
    fn triangles_do_not_set_the_default() {
        let mut quads = room_with_face(1.0, 1.0);
        let mut tiny = Parallelogram::new(&[
            [5.0, 5.0, 5.0],
            [5.001, 5.0, 5.0],
            [5.001, 5.001, 5.0],
            [5.0, 5.001, 5.0],
        ]);
        tiny.tri = true;
        quads.push(tiny);
        let size = Sizing::new(&quads, None, None).min_element_size;
        assert_eq!(size, 300f64.sqrt() / DEFAULT_DIVISIONS);
    }
}
