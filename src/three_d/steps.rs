//! Step functions over a receiver: the [`STEP`] × [`STEP`] cells on which a link keeps its
//! visible fraction (and a partly covered element its mask), and the Gram matrices of the
//! tensor Legendre basis on each cell, by which a block is weighted with such a step.

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
        Steps { k, m }
    }
}
