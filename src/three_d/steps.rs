//! Step functions over a receiver: the [`CELLS`] cells on which a link keeps its visible
//! fraction (and a partly covered element its mask), and the Gram matrices of the basis on
//! each cell, by which a block is weighted with such a step.
//!
//! On a parallelogram the cells are the [`STEP`] × [`STEP`] grid of its (s, t) square, with the
//! tensor Legendre basis; on a triangle they are the sixteen triangles of two levels of the
//! four-way midpoint split (the element's grandchildren), with the triangle basis
//! ([`crate::math::triangle`]). In both, cell c lies in quarter c / 4 for triangles, and the
//! quarter of [`quarter_of`] for parallelograms: the element's child that holds it.

/// Cells per side of the receiver over which a link's visible fraction is a step.
pub(super) const STEP: usize = 4;
pub(super) const CELLS: usize = STEP * STEP;

/// M_cell[a][c] = ∫_cell φ_a φ_c over the unit square, for the tensor products
/// φ_a = φ_p(ŝ) φ_q(t̂) (`a = q k + p`) of the orthonormal shifted Legendre polynomials of
/// [`crate::math::basis::legendre`]: the Gram matrices of the basis on the [`STEP`] × [`STEP`]
/// cells (they sum to the identity).
#[derive(Debug, Clone)]
pub(super) struct Steps {
    pub(super) k: usize,
    pub(super) m: Vec<Vec<f64>>,
    /// The same for the triangle basis of order k − 1 on the sixteen cells of a triangle
    /// ([`tri_cell`]): (1 / area(T̂)) ∫_cell φ_a φ_c, in `k² × k²` matrices whose first
    /// (m + 1)(m + 2)/2 rows and columns are used.
    pub(super) tri: Vec<Vec<f64>>,
}

impl Steps {
    pub(super) fn new(k: usize) -> Steps {
        // ∫ φ_p φ_q over each [i / STEP, (i + 1) / STEP]
        let strips: Vec<Vec<f64>> = (0..STEP)
            .map(|i| {
                let u = [i as f64 / STEP as f64, (i + 1) as f64 / STEP as f64];
                crate::math::basis::legendre::interval_gram(u, k)
            })
            .collect();
        let kk = k * k;
        let m = (0..CELLS)
            .map(|c| {
                let (hs, ht) = (&strips[c % STEP], &strips[c / STEP]);
                let mut m = vec![0.0; kk * kk];
                for a in 0..kk {
                    for d in 0..kk {
                        m[a * kk + d] = ht[(a / k) * k + d / k] * hs[(a % k) * k + d % k];
                    }
                }
                m
            })
            .collect();
        Steps {
            k,
            m,
            tri: triangle_grams(k),
        }
    }
}

/// The quarter (the element's child, `ds + 2 dt`) that holds cell `i + STEP j` of a
/// parallelogram.
pub(super) fn quarter_of(c: usize) -> usize {
    let (i, j) = (c % STEP, c / STEP);
    usize::from(2 * i >= STEP) + 2 * usize::from(2 * j >= STEP)
}

/// The cell of a triangle that holds its point of local coordinates (ŝ, t̂): 4 c₁ + c₂ for
/// its grandchild c₂ of child c₁ in the midpoint split ([`crate::math::triangle::locate`]).
pub(super) fn tri_cell(s: f64, t: f64) -> usize {
    use crate::math::triangle::locate;
    let (c1, [s1, t1]) = locate(s, t);
    let (c2, _) = locate(s1, t1);
    4 * c1 + c2
}

/// The Gram matrices of the triangle basis on the sixteen cells of [`tri_cell`], by a rule
/// exact for their degree 2m mapped onto each cell (a sixteenth of the triangle's area).
fn triangle_grams(k: usize) -> Vec<Vec<f64>> {
    use crate::math::triangle::{dimension, to_parent, TriangleBasis, TriangleRule};
    let (basis, n, kk) = (TriangleBasis::of_order(k - 1), dimension(k - 1), k * k);
    let rule = TriangleRule::for_degree(2 * (k - 1));
    let mut phi = vec![0.0; n];
    (0..CELLS)
        .map(|c| {
            let mut g = vec![0.0; kk * kk];
            for (p, w) in rule.points.iter().zip(&rule.weights) {
                let [s1, t1] = to_parent(c % 4, p[0], p[1]);
                let [s, t] = to_parent(c / 4, s1, t1);
                basis.eval(s, t, &mut phi);
                for a in 0..n {
                    for d in 0..n {
                        g[a * kk + d] += w / CELLS as f64 * phi[a] * phi[d];
                    }
                }
            }
            g
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The cells' Gram matrices add up to the identity (on the basis' functions), for both
    /// kinds of receiver and orders 0 to 3; the cell of a triangle's point is the grandchild
    /// of the midpoint split that holds it, each holding a sixteenth of the area.
    #[test]
    fn the_cells_gram_matrices_add_up_to_the_identity() {
        for k in 1..=4 {
            let steps = Steps::new(k);
            let kk = k * k;
            let n = crate::math::triangle::dimension(k - 1);
            for (grams, used) in [(&steps.m, kk), (&steps.tri, n)] {
                for a in 0..kk {
                    for d in 0..kk {
                        let sum: f64 = grams.iter().map(|g| g[a * kk + d]).sum();
                        let want = f64::from(u8::from(a == d && a < used));
                        assert!((sum - want).abs() < 1e-13, "k {k} ({a}, {d}): {sum}");
                    }
                }
            }
            // G_00 of a cell is its share of the area
            for g in &steps.tri {
                assert!((g[0] - 1.0 / 16.0).abs() < 1e-14);
            }
        }
        // a point near each corner child's corner, and the centre child's centre
        assert_eq!(tri_cell(0.01, 0.01), 0);
        assert_eq!(tri_cell(0.98, 0.01), 4 + 1);
        assert_eq!(tri_cell(0.01, 0.98), 8 + 2);
        assert_eq!(tri_cell(1.0 / 3.0, 1.0 / 3.0), 12 + 3);
        // uniform points fall sixteen to a cell
        let mut count = [0usize; CELLS];
        let n = 64;
        for j in 0..n {
            for i in 0..n - j {
                let (s, t) = ((i as f64 + 0.25) / n as f64, (j as f64 + 0.25) / n as f64);
                count[tri_cell(s, t)] += 1;
            }
        }
        let total: usize = count.iter().sum();
        for c in count {
            assert!(
                (c as f64 / total as f64 - 1.0 / 16.0).abs() < 0.005,
                "{count:?}"
            );
        }
    }
}
