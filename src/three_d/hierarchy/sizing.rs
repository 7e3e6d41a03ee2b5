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

use crate::three_d::geometry::{bounding_box, norm, sub, Parallelogram};

/// The deepest level of any surface's quadtree: 1024 × 1024 elements, the document's largest
/// `resolution`.
const MAX_LEVEL: u32 = 10;

/// The default smallest element size is the diagonal of the scene's bounding box divided by
/// this. The Cornell box (diagonal 961) gets 15 units: its 555-unit walls at most 32 × 32, the
/// resolution its document gives. A 10-unit room with 3 × 3 boxes gets 0.27: its floor at
/// most 32 × 32, each 1.7-unit box face at most 4 × 4. On that room the surface means at a
/// 64th, a 128th and a 256th of the diagonal agree within 0.02 % of each other (and within
/// the path tracer's 0.5 % noise of it), for 564 k, 847 k and 1.33 M links.
const DEFAULT_DIVISIONS: f64 = 64.0;

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
            min_element_size: min_element_size
                .unwrap_or_else(|| scene_diagonal(quads) / DEFAULT_DIVISIONS),
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
}
