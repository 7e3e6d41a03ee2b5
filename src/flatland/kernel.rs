//! The flatland kernel of the slides' eq. (4): K(x, y) = cosθx cosθy / (2 r) · V(x, y), zero
//! unless y is in front of x and x in front of y, and Hottel's crossed strings, its closed-form
//! integral between two unoccluded segments. The visibility factor V is not part of these
//! functions: `crate::flatland::visibility` clips the integration domain to the visible
//! parts. (The 3D kernel, eq. (3), is `crate::three_d::transfer::kernel`.)

use crate::flatland::geometry::V2;

/// Eq. (4) without V: cosθx cosθy / (2r) for points x, y with unit front normals nx, ny.
#[inline(always)]
pub(super) fn flatland(x: V2, nx: V2, y: V2, ny: V2) -> f64 {
    let r = y - x;
    let cx = r.dot(nx);
    let cy = -r.dot(ny);
    if cx <= 0.0 || cy <= 0.0 {
        return 0.0;
    }
    let r2 = r.dot(r);
    // cosθx = cx / r, cosθy = cy / r
    cx * cy / (2.0 * r2 * r2.sqrt())
}

/// Eq. (4) for points known to face each other (both cosines positive): no branch, so that
/// the fill's inner loop vectorises.
#[inline(always)]
pub(super) fn flatland_facing(x: V2, nx: V2, y: V2, ny: V2) -> f64 {
    let r = y - x;
    let r2 = r.dot(r);
    r.dot(nx) * -r.dot(ny) / (2.0 * r2 * r2.sqrt())
}

/// Hottel's crossed-strings rule: the flatland form factor from segment [a1,b1] to [a2,b2]
/// (both unoccluded and facing each other): F₁₂ = (crossed − uncrossed) / (2 L₁), with the
/// strings a1–b2, b1–a2 crossed for segments oriented as opposite sides of a convex quadrilateral.
pub fn crossed_strings(a1: V2, b1: V2, a2: V2, b2: V2) -> f64 {
    let l1 = (b1 - a1).norm();
    let crossed = (a1 - a2).norm() + (b1 - b2).norm();
    let uncrossed = (a1 - b2).norm() + (b1 - a2).norm();
    (crossed - uncrossed) / (2.0 * l1)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_sided_and_symmetric() {
        let up = V2::new(0.0, 1.0);
        let down = V2::new(0.0, -1.0);
        let x = V2::new(0.0, 0.0);
        let y = V2::new(0.0, 2.0);
        assert_eq!(flatland(x, up, y, down), 1.0 / 4.0);
        assert_eq!(flatland(x, down, y, down), 0.0);
        assert_eq!(flatland(x, up, y, up), 0.0);
        assert_eq!(flatland(y, down, x, up), flatland(x, up, y, down));
    }

    #[test]
    fn crossed_strings_of_the_unit_square() {
        // Opposite sides of the unit square: F = √2 − 1.
        let f = crossed_strings(
            V2::new(0.0, 0.0),
            V2::new(1.0, 0.0),
            V2::new(1.0, 1.0),
            V2::new(0.0, 1.0),
        );
        assert!((f - (2f64.sqrt() - 1.0)).abs() < 1e-15);
    }
}
