//! Exact visibility in flatland.
//!
//! Seen from a point x, an occluding segment casts onto the line of a target segment a shadow
//! that is one interval of the target's parameter (the central projection from x of the part of
//! the occluder that lies between x and the target line). The visible part of a target cell is
//! what is left after removing those intervals, so the inner integral of eq. (4) over y can be
//! taken exactly over the visible pieces instead of sampling the discontinuous V.

use crate::flatland::geometry::{Line, V2};

/// Up to this many visible pieces are kept without allocating.
pub(super) type Pieces = smallvec::SmallVec<[[f64; 2]; 8]>;

/// The parts of `range` (parameters of `target`) visible from `x`, which must be strictly in
/// front of `target`, past the occluding segments `occluders`.
pub(super) fn visible_from(
    x: V2,
    target: &Line,
    range: [f64; 2],
    occluders: &[Line],
    out: &mut Pieces,
) {
    out.clear();
    let sx = target.side(x);
    debug_assert!(sx > 0.0);
    let mut blocked: Pieces = Pieces::new();
    for occ in occluders {
        if let Some(iv) = shadow(x, sx, target, occ) {
            let lo = iv[0].max(range[0]);
            let hi = iv[1].min(range[1]);
            if hi > lo {
                blocked.push([lo, hi]);
            }
        }
    }
    if blocked.is_empty() {
        out.push(range);
        return;
    }
    blocked.sort_by(|a, b| a[0].total_cmp(&b[0]));
    let mut at = range[0];
    for b in &blocked {
        if b[0] > at {
            out.push([at, b[0]]);
        }
        at = at.max(b[1]);
    }
    if at < range[1] {
        out.push([at, range[1]]);
    }
}

/// The target-parameter interval shadowed by `occ` as seen from x (side `sx` > 0 of the target).
fn shadow(x: V2, sx: f64, target: &Line, occ: &Line) -> Option<[f64; 2]> {
    // The occluder's side values at its ends; keep the part with 0 ≤ side ≤ sx (1 − 1e-12).
    let s0 = target.side(occ.a);
    let s1 = target.side(occ.b);
    let top = sx * (1.0 - 1e-12);
    let (mut u0, mut u1) = (0.0f64, 1.0f64);
    let ds = s1 - s0;
    // clip to side ≥ 0
    if ds.abs() < 1e-300 {
        if s0 < 0.0 || s0 > top {
            return None;
        }
    } else {
        let at_zero = -s0 / ds;
        let at_top = (top - s0) / ds;
        let (lo, hi) = if ds > 0.0 {
            (at_zero, at_top)
        } else {
            (at_top, at_zero)
        };
        u0 = u0.max(lo);
        u1 = u1.min(hi);
        if u1 <= u0 {
            return None;
        }
    }
    let project = |u: f64| {
        let p = occ.at(u);
        let sp = target.side(p);
        let lambda = sx / (sx - sp);
        target.param_of(x + (p - x) * lambda)
    };
    let t0 = project(u0);
    let t1 = project(u1);
    Some([t0.min(t1), t0.max(t1)])
}

/// Whether segment `occ` can block a ray between the sub-segments `p` and `q`: whether it meets
/// the interior of their convex hull (touching its boundary at a point does not block).
pub(super) fn may_block(p: [V2; 2], q: [V2; 2], occ: [V2; 2]) -> bool {
    let pts = [p[0], p[1], q[0], q[1]];
    let hull = convex_hull(pts);
    if hull.len() < 3 {
        return false;
    }
    let scale = pts
        .iter()
        .chain(occ.iter())
        .fold(0.0f64, |m, v| m.max(v.x.abs()).max(v.y.abs()))
        .max(1e-300);
    let eps = 1e-12 * scale;
    // Hull edges (counter-clockwise): outward normal (dy, −dx).
    for i in 0..hull.len() {
        let u = hull[i];
        let v = hull[(i + 1) % hull.len()];
        let nrm = V2::new(v.y - u.y, u.x - v.x);
        let len = nrm.norm();
        if len == 0.0 {
            continue;
        }
        let limit = nrm.dot(u) / len;
        if nrm.dot(occ[0]) / len >= limit - eps && nrm.dot(occ[1]) / len >= limit - eps {
            return false;
        }
    }
    // The occluder's own normal.
    let d = occ[1] - occ[0];
    let len = d.norm();
    if len > 0.0 {
        let nrm = d.perp() * (1.0 / len);
        let c = nrm.dot(occ[0]);
        let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
        for h in &hull {
            lo = lo.min(nrm.dot(*h));
            hi = hi.max(nrm.dot(*h));
        }
        if lo >= c - eps || hi <= c + eps {
            return false;
        }
    }
    true
}

/// Counter-clockwise convex hull (Andrew's monotone chain) of four points; collinear points dropped.
fn convex_hull(mut pts: [V2; 4]) -> smallvec::SmallVec<[V2; 4]> {
    pts.sort_by(|a, b| a.x.total_cmp(&b.x).then(a.y.total_cmp(&b.y)));
    let mut hull: smallvec::SmallVec<[V2; 8]> = smallvec::SmallVec::new();
    for pass in 0..2 {
        let start = hull.len();
        let iter: Box<dyn Iterator<Item = &V2>> = if pass == 0 {
            Box::new(pts.iter())
        } else {
            Box::new(pts.iter().rev())
        };
        for &p in iter {
            while hull.len() >= start + 2 {
                let a = hull[hull.len() - 2];
                let b = hull[hull.len() - 1];
                if (b - a).cross(p - a) <= 0.0 {
                    hull.pop();
                } else {
                    break;
                }
            }
            hull.push(p);
        }
        hull.pop();
    }
    hull.into_iter().collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn line(a: [f64; 2], b: [f64; 2]) -> Line {
        Line::new(a.into(), b.into())
    }

    #[test]
    fn shadow_of_a_short_segment_between_plates() {
        // target: the top plate facing down, x on the bottom plate, occluder halfway up.
        let top = line([1.0, 1.0], [0.0, 1.0]);
        let occ = line([0.4, 0.5], [0.6, 0.5]);
        let mut out = Pieces::new();
        visible_from(V2::new(0.5, 0.0), &top, [0.0, 1.0], &[occ], &mut out);
        // the occluder projects to x ∈ [0.3, 0.7], i.e. t ∈ [0.3, 0.7] on the reversed top plate
        assert_eq!(out.len(), 2);
        assert!((out[0][0] - 0.0).abs() < 1e-15 && (out[0][1] - 0.3).abs() < 1e-12);
        assert!((out[1][0] - 0.7).abs() < 1e-12 && (out[1][1] - 1.0).abs() < 1e-15);
    }

    #[test]
    fn occluder_crossing_the_target_line_and_behind_the_viewer() {
        let top = line([1.0, 1.0], [0.0, 1.0]);
        let mut out = Pieces::new();
        // vertical occluder crossing y = 1: only its part below the line blocks
        let occ = line([0.75, 0.5], [0.75, 1.5]);
        visible_from(V2::new(0.5, 0.0), &top, [0.0, 1.0], &[occ], &mut out);
        // from (0.5,0) through (0.75,0.5) hits y=1 at x=1.0 → t=0; crossing at x=0.75 → t=0.25
        assert_eq!(out.len(), 1);
        assert!((out[0][0] - 0.25).abs() < 1e-12 && out[0][1] == 1.0);
        // an occluder below the viewer blocks nothing
        let below = line([0.0, -0.5], [1.0, -0.5]);
        visible_from(V2::new(0.5, 0.0), &top, [0.0, 1.0], &[below], &mut out);
        assert_eq!(out.as_slice(), &[[0.0, 1.0]]);
    }

    #[test]
    fn hull_test() {
        let p = [V2::new(0.0, 0.0), V2::new(1.0, 0.0)];
        let q = [V2::new(1.0, 1.0), V2::new(0.0, 1.0)];
        assert!(may_block(p, q, [V2::new(0.4, 0.5), V2::new(0.6, 0.5)]));
        assert!(!may_block(p, q, [V2::new(1.5, 0.5), V2::new(2.0, 0.5)]));
        // a wall touching the hull only along its side does not block
        assert!(!may_block(p, q, [V2::new(0.0, 0.0), V2::new(0.0, 1.0)]));
        assert!(!may_block(p, q, [V2::new(1.0, 1.0), V2::new(2.0, 2.0)]));
    }
}
