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
//!
//! With the default size, the parts of surfaces across a gap narrower than it go further, to
//! elements no larger than the gap ([`narrow_parts`]): what varies across a gap varies at its
//! width, and only there.

use crate::three_d::bvh::boxes_meet;
use crate::three_d::geometry::{bounding_box, box_of, norm, quad_quad, sub, Parallelogram, V3};

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

/// Elements may reach down to a narrow gap d within this many gaps of the space between its
/// two faces (that space's box grown by this times d): the kernel across the gap varies over
/// d, and a point x away from it sees it vary over x, so beyond a few gaps the size of the
/// rest of the surface serves.
const NARROW_REACH: f64 = 2.0;

/// Inside a slot, an element at depth x from its sides may be as large as x over this. The
/// light that comes in through the mouth falls off as about d / x, which a plane over [x, 2x]
/// fits to a few percent: at 1 the side of a box in a 2 cm gap had a cell 5.9 % off the
/// tracer (256² paths) and a plank 3 cm above a box 1.2 %; at 4 they are as with elements
/// of d all over the slot (4.1 % and 0.73 %), for fewer links (596 k → 509 k; a cabinet 1 cm
/// from a wall 6.4 M → 1.8 M, 1.1 M at 1).
const NARROW_GRADING: f64 = 4.0;

/// The smallest element edge and, when the document gives it, the finest resolution; with
/// the default size, also the parts of surfaces across a narrow gap, which go finer.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct Sizing {
    pub(super) min_element_size: f64,
    resolution: Option<usize>,
    /// For each surface (empty when no surface has any), its parts across a gap narrower
    /// than `min_element_size` ([`narrow_parts`]).
    narrow: Vec<Vec<Narrow>>,
}

/// A narrow gap near a surface: an element whose bounding box comes within [`NARROW_REACH`]
/// gaps of the space between the two faces may be split to [`Narrow::size`].
#[derive(Debug, Clone, Copy, PartialEq)]
struct Narrow {
    /// The space between the two faces: each one's box grown by the gap, met with the other's.
    lo: V3,
    hi: V3,
    /// The gap's width.
    gap: f64,
}

impl Sizing {
    /// `min_element_size` when given (the same everywhere), else the default from the scene's
    /// size, with the narrow gaps' parts finer.
    pub(super) fn new(
        quads: &[Parallelogram],
        min_element_size: Option<f64>,
        resolution: Option<usize>,
    ) -> Sizing {
        let mut sizing = Sizing {
            min_element_size: min_element_size.unwrap_or_else(|| default_size(quads)),
            resolution,
            narrow: Vec::new(),
        };
        if min_element_size.is_none() {
            sizing.narrow = narrow_parts(quads, &sizing);
        }
        sizing
    }

    /// The finest quadtree level of surface `q`: of a parallelogram by its longer side (and
    /// `resolution`, when given), of a triangle by its longest side.
    pub(super) fn finest_level(&self, q: &Parallelogram) -> u32 {
        self.level_for(q, self.min_element_size, f64::floor)
    }

    /// The level of `q` whose elements are about `size`: the deepest at least that size
    /// (`round` = floor) or the shallowest no larger (`round` = ceil).
    fn level_for(&self, q: &Parallelogram, size: f64, round: fn(f64) -> f64) -> u32 {
        let edge = if q.tri {
            q.diameter()
        } else {
            norm(q.e1).max(norm(q.e3))
        };
        let ratio = edge / size;
        let by_size = if ratio >= 1.0 {
            (round(ratio.log2()) as u32).min(MAX_LEVEL)
        } else {
            0
        };
        match self.resolution {
            Some(r) if !q.tri => by_size.min(r.trailing_zeros()),
            _ => by_size,
        }
    }

    /// The finest level anywhere on surface `i` (`q`): [`Sizing::finest_level`], or deeper
    /// across a narrow gap.
    pub(super) fn deepest_level(&self, i: usize, q: &Parallelogram) -> u32 {
        let parts = self.narrow.get(i).map_or(&[][..], |n| &n[..]);
        parts
            .iter()
            .map(|n| self.level_for(q, n.gap, f64::ceil))
            .fold(self.finest_level(q), u32::max)
    }

    /// The finest level of an element of surface `i` (`q`) with the given corners, whose
    /// surface away from narrow gaps goes down to `level`: across a gap, elements no larger
    /// than the gap within [`NARROW_REACH`] gaps of its mouth, and no larger than their depth
    /// into it beyond ([`Narrow::size`]).
    pub(super) fn level_at(
        &self,
        i: usize,
        q: &Parallelogram,
        level: u32,
        corners: impl FnOnce() -> [V3; 4],
    ) -> u32 {
        let Some(parts) = self.narrow.get(i).filter(|n| !n.is_empty()) else {
            return level;
        };
        let (lo, hi) = box_of(corners());
        parts
            .iter()
            .filter_map(|n| n.size(lo, hi))
            .map(|size| self.level_for(q, size, f64::ceil))
            .fold(level, u32::max)
    }
}

impl Narrow {
    /// The largest size of an element with bounding box `lo`–`hi` across this gap d, or
    /// `None` when it lies farther than [`NARROW_REACH`] d from the space between the faces.
    /// Where that space is wide in two directions (a slot, not the strip under an edge), an
    /// element inside it at depth x from its sides, where light comes in, may be as large as
    /// x / [`NARROW_GRADING`]: what comes in through the mouth falls off there over x, not
    /// over d (the view of the mouth from depth x is about d / x), so a slot costs elements
    /// along its rim, and fewer and fewer inside, rather than d's over its whole area.
    fn size(&self, lo: V3, hi: V3) -> Option<f64> {
        let reach = NARROW_REACH * self.gap;
        let around = (self.lo.map(|x| x - reach), self.hi.map(|x| x + reach));
        if !boxes_meet((lo, hi), around) {
            return None;
        }
        // (called for every element judged on such a surface: no allocation)
        let wide = [0, 1, 2].map(|k| self.hi[k] - self.lo[k] > 2.0 * reach);
        let depth = if wide.iter().filter(|&&w| w).count() >= 2 {
            (0..3)
                .filter(|&k| wide[k])
                .map(|k| (lo[k] - self.lo[k]).min(self.hi[k] - hi[k]))
                .fold(f64::INFINITY, f64::min)
                .max(0.0)
        } else {
            0.0
        };
        Some(self.gap.max(depth / NARROW_GRADING))
    }
}

/// The parts of surfaces across a gap narrower than the default size. For two parallelograms
/// that see each other d apart ([`gaps`]), the space between them is where each one's box,
/// grown by d, meets the other's; every surface with elements within [`NARROW_REACH`] d of it
/// may split them until they are no larger than d (the two faces, and the floor under the gap
/// and in front of its mouth), or inside a slot than their depth into it over
/// [`NARROW_GRADING`] ([`Narrow::size`]). Across a gap d each face sees the other's B, and
/// the light that comes in through the gap's mouth, vary over d: the bottom of a box 2 cm
/// above a floor, lit only through that slot, was 7.7 % off the tracer at a size of 0.06
/// everywhere and is 3.2 % at the defaults with this (0.8 % at ε = 2.5e-4; rounded to
/// elements at least d instead, 1.9 % there); elsewhere the surfaces keep the scene's size,
/// so one narrow gap does not make the whole scene fine.
fn narrow_parts(quads: &[Parallelogram], sizing: &Sizing) -> Vec<Vec<Narrow>> {
    let diagonal = scene_diagonal(quads);
    let mut narrow = vec![Vec::new(); quads.len()];
    let boxes: Vec<(V3, V3)> = quads.iter().map(|q| box_of(q.outline())).collect();
    let grown = |(lo, hi): (V3, V3), by: f64| (lo.map(|x| x - by), hi.map(|x| x + by));
    for (a, b, d) in gaps(quads, sizing.min_element_size, diagonal) {
        // the space between the two: where each one's box, grown by the gap, meets the other's
        let (alo, ahi) = grown(boxes[a], d);
        let (blo, bhi) = grown(boxes[b], d);
        let part = Narrow {
            lo: [0, 1, 2].map(|k| alo[k].max(blo[k])),
            hi: [0, 1, 2].map(|k| ahi[k].min(bhi[k])),
            gap: d,
        };
        for (i, q) in quads.iter().enumerate() {
            let (qlo, qhi) = boxes[i];
            if part.size(qlo, qhi).is_some()
                && sizing.level_for(q, d, f64::ceil) > sizing.finest_level(q)
            {
                narrow[i].push(part);
            }
        }
    }
    if narrow.iter().all(Vec::is_empty) {
        narrow.clear();
    }
    narrow
}

/// The default smallest element size: a 64th of the scene's diagonal, or the smallest face's
/// size when that is smaller, but no less than a 256th of the diagonal.
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
/// Narrow gaps between faces that see each other are resolved where they are
/// ([`narrow_parts`]), not by the whole scene's size. Faces that touch are the contact lines'
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
    (diagonal / DEFAULT_DIVISIONS)
        .min(smallest_face)
        .max(diagonal / FINEST_DEFAULT_DIVISIONS)
}

/// Every pair of parallelograms (i, j, distance) less than `within` apart that see each other
/// (each has a part in front of the other's plane) and do not touch (farther apart than a
/// 10⁹th of the scene's `diagonal`): the back-to-back faces of a thin slab do not count, nor a
/// box's side and the floor it stands on. Pairs are swept along x by their bounding boxes
/// grown by `within`, so a room of many faces costs about one test per near pair.
fn gaps(quads: &[Parallelogram], within: f64, diagonal: f64) -> Vec<(usize, usize, f64)> {
    let touch = 1e-9 * diagonal;
    let faces: Vec<(usize, V3, V3)> = quads
        .iter()
        .enumerate()
        .filter(|(_, q)| !q.tri)
        .map(|(i, q)| {
            let (lo, hi) = box_of(q.outline());
            (i, lo, hi)
        })
        .collect();
    let mut order: Vec<usize> = (0..faces.len()).collect();
    order.sort_by(|&a, &b| faces[a].1[0].total_cmp(&faces[b].1[0]));
    let mut found = Vec::new();
    for (k, &a) in order.iter().enumerate() {
        let (i, plo, phi) = faces[a];
        for &b in &order[k + 1..] {
            let (j, qlo, qhi) = faces[b];
            if qlo[0] > phi[0] + within {
                break;
            }
            let apart = (1..3).any(|x| qlo[x] > phi[x] + within || plo[x] > qhi[x] + within);
            let (p, q) = (&quads[i], &quads[j]);
            if apart || !in_front(q, p, touch) || !in_front(p, q, touch) {
                continue;
            }
            let d = quad_quad(&p.outline(), p.n, &q.outline(), q.n);
            if d > touch && d < within {
                found.push((i.min(j), i.max(j), d));
            }
        }
    }
    found
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
            narrow: Vec::new(),
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
            narrow: Vec::new(),
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
        let gap = |quads: &[Parallelogram]| {
            let found = gaps(quads, 1.0, diagonal);
            assert!(found.len() <= 1);
            found.first().map(|g| g.2)
        };
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
    fn a_narrow_gap_is_resolved_where_it_is() {
        // a room of 10 with two boxes' faces 2 cm apart in it
        let mut quads = vec![square(10.0), square_at(10.0, 10.0)];
        let at = |q: Parallelogram, dx: f64| {
            let c = q.outline().map(|c| [c[0] + dx, c[1], c[2] + 4.0]);
            Parallelogram::new(&c)
        };
        quads.push(at(wall(0.0, 1.0), 4.0));
        quads.push(at(wall(0.02, -1.0), 4.0));
        let sizing = Sizing::new(&quads, None, None);
        // the scene keeps the room's size: the gap does not make it finer
        assert_eq!(sizing.min_element_size, 300f64.sqrt() / DEFAULT_DIVISIONS);
        // the faces in the gap go down to elements no larger than it (1 / 64 ≤ 0.02 < 1 / 32)
        for i in [2, 3] {
            assert_eq!(sizing.finest_level(&quads[i]), 1);
            assert_eq!(sizing.deepest_level(i, &quads[i]), 6);
            let corner = quads[i].piece([0.0, 0.25], [0.0, 0.25]);
            assert_eq!(sizing.level_at(i, &quads[i], 1, || corner), 6);
            // inside the slot, 0.395 from its sides: no larger than a quarter of that
            // (1 / 16 ≤ 0.099 < 1 / 8)
            let centre = quads[i].piece([0.375, 0.625], [0.375, 0.625]);
            assert_eq!(sizing.level_at(i, &quads[i], 1, || centre), 4);
        }
        // the floor and the ceiling, 4 and 5 from it, do not
        for i in [0, 1] {
            assert_eq!(
                sizing.deepest_level(i, &quads[i]),
                sizing.finest_level(&quads[i])
            );
        }
        // a size the document gives is the same everywhere
        let given = Sizing::new(&quads, Some(0.25), None);
        assert_eq!(
            given.deepest_level(2, &quads[2]),
            given.finest_level(&quads[2])
        );
        // and a given resolution caps the gap's level too
        let capped = Sizing::new(&quads, None, Some(16));
        assert_eq!(capped.deepest_level(2, &quads[2]), 4);
    }

    #[test]
    fn only_the_part_across_the_gap_goes_finer() {
        // a face 2 × 1 standing 3 cm above a floor of 10, its foot along x = 5, y from 4 to 6
        let floor = square(10.0);
        assert!(floor.n[2] > 0.0);
        let side = Parallelogram::new(&[
            [5.0, 4.0, 0.03],
            [5.0, 6.0, 0.03],
            [5.0, 6.0, 1.03],
            [5.0, 4.0, 1.03],
        ]);
        let quads = [floor, side];
        let sizing = Sizing::new(&quads, None, None);
        let base = sizing.finest_level(&floor);
        // elements of the floor no larger than 0.03: 10 / 512
        assert_eq!(sizing.deepest_level(0, &floor), 9);
        assert!(base < 9);
        // a floor element under the face's foot may go there, one 2 away may not; along the
        // strip under the edge there is no inside to grade
        let under = floor.piece([0.49, 0.51], [0.49, 0.51]);
        let away = floor.piece([0.69, 0.71], [0.49, 0.51]);
        assert_eq!(sizing.level_at(0, &floor, base, || under), 9);
        assert_eq!(sizing.level_at(0, &floor, base, || away), base);
        // on the face, its bottom row may, its top may not
        let face_base = sizing.finest_level(&side);
        let bottom = side.piece([0.0, 1.0], [0.0, 0.05]);
        let top = side.piece([0.0, 1.0], [0.5, 1.0]);
        assert!(sizing.level_at(1, &side, face_base, || bottom) > face_base);
        assert_eq!(sizing.level_at(1, &side, face_base, || top), face_base);
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
