//! Points and vectors of flatland, and the parametrisation of a segment: the r and cos θ of
//! the flatland kernel, the slides' eq. (4).

use std::ops::{Add, Mul, Sub};

#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct V2 {
    pub(super) x: f64,
    pub(super) y: f64,
}

impl V2 {
    pub(super) const fn new(x: f64, y: f64) -> V2 {
        V2 { x, y }
    }
    pub(super) fn dot(self, o: V2) -> f64 {
        self.x * o.x + self.y * o.y
    }
    /// z component of the cross product.
    pub(super) fn cross(self, o: V2) -> f64 {
        self.x * o.y - self.y * o.x
    }
    pub(super) fn norm(self) -> f64 {
        self.x.hypot(self.y)
    }
    /// Turned +90° (counter-clockwise).
    pub(super) fn perp(self) -> V2 {
        V2::new(-self.y, self.x)
    }
}

impl From<[f64; 2]> for V2 {
    fn from(p: [f64; 2]) -> V2 {
        V2::new(p[0], p[1])
    }
}

impl Add for V2 {
    type Output = V2;
    fn add(self, o: V2) -> V2 {
        V2::new(self.x + o.x, self.y + o.y)
    }
}

impl Sub for V2 {
    type Output = V2;
    fn sub(self, o: V2) -> V2 {
        V2::new(self.x - o.x, self.y - o.y)
    }
}

impl Mul<f64> for V2 {
    type Output = V2;
    fn mul(self, s: f64) -> V2 {
        V2::new(self.x * s, self.y * s)
    }
}

/// A flatland surface as geometry: p(s) = a + s d, front normal n = d⊥/‖d‖.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Line {
    pub(super) a: V2,
    pub(super) b: V2,
    d: V2,
    pub(super) n: V2,
    pub(super) len: f64,
}

impl Line {
    pub(super) fn new(a: V2, b: V2) -> Line {
        let d = b - a;
        let len = d.norm();
        Line {
            a,
            b,
            d,
            n: d.perp() * (1.0 / len),
            len,
        }
    }

    #[inline]
    pub(super) fn at(&self, s: f64) -> V2 {
        self.a + self.d * s
    }

    /// Signed distance of p from the line, positive in front.
    #[inline]
    pub(super) fn side(&self, p: V2) -> f64 {
        (p - self.a).dot(self.n)
    }

    /// Parameter of the point of the line nearest to p.
    pub(super) fn param_of(&self, p: V2) -> f64 {
        (p - self.a).dot(self.d) / (self.len * self.len)
    }

    /// Parameter s where the line through p and q meets this line, if they are not parallel.
    pub(super) fn meet(&self, p: V2, q: V2) -> Option<f64> {
        let e = q - p;
        let den = self.d.cross(e);
        if den.abs() <= 1e-14 * self.len * e.norm() {
            return None;
        }
        Some((p - self.a).cross(e) / den)
    }
}

/// Distance from p to the segment [a, b].
fn point_segment_distance(p: V2, a: V2, b: V2) -> f64 {
    let d = b - a;
    let l2 = d.dot(d);
    let t = if l2 > 0.0 {
        ((p - a).dot(d) / l2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (a + d * t - p).norm()
}

/// Whether the closed segments [a, b] and [c, d] meet.
fn segments_intersect(a: V2, b: V2, c: V2, d: V2) -> bool {
    let o1 = (b - a).cross(c - a);
    let o2 = (b - a).cross(d - a);
    let o3 = (d - c).cross(a - c);
    let o4 = (d - c).cross(b - c);
    if ((o1 > 0.0 && o2 < 0.0) || (o1 < 0.0 && o2 > 0.0))
        && ((o3 > 0.0 && o4 < 0.0) || (o3 < 0.0 && o4 > 0.0))
    {
        return true;
    }
    let on = |p: V2, q: V2, r: V2, o: f64| {
        o == 0.0
            && r.x >= p.x.min(q.x)
            && r.x <= p.x.max(q.x)
            && r.y >= p.y.min(q.y)
            && r.y <= p.y.max(q.y)
    };
    on(a, b, c, o1) || on(a, b, d, o2) || on(c, d, a, o3) || on(c, d, b, o4)
}

/// Distance between the segments [a, b] and [c, d].
pub(super) fn segment_distance(a: V2, b: V2, c: V2, d: V2) -> f64 {
    if segments_intersect(a, b, c, d) {
        return 0.0;
    }
    point_segment_distance(a, c, d)
        .min(point_segment_distance(b, c, d))
        .min(point_segment_distance(c, a, b))
        .min(point_segment_distance(d, a, b))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn normal_is_turned_counter_clockwise() {
        let l = Line::new(V2::new(0.0, 0.0), V2::new(1.0, 0.0));
        assert_eq!(l.n, V2::new(0.0, 1.0));
        assert!(l.side(V2::new(0.3, 2.0)) == 2.0);
        assert_eq!(l.meet(V2::new(0.5, 1.0), V2::new(0.5, 2.0)), Some(0.5));
    }

    #[test]
    fn distances() {
        let o = V2::new(0.0, 0.0);
        assert_eq!(
            segment_distance(o, V2::new(1.0, 0.0), V2::new(0.0, 1.0), V2::new(1.0, 1.0)),
            1.0
        );
        assert_eq!(
            segment_distance(o, V2::new(1.0, 0.0), o, V2::new(0.0, 1.0)),
            0.0
        );
        assert!(segments_intersect(
            o,
            V2::new(1.0, 1.0),
            V2::new(0.0, 1.0),
            V2::new(1.0, 0.0)
        ));
    }
}
