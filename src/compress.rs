//! The kernel matrix in the wavelet basis and its thresholding.
//!
//! With W the orthogonal per-surface wavelet transform of [`crate::basis::transform`], the
//! system B = E + ρKB becomes (WB) = (WE) + ρ (W K Wᵀ)(WB): the "standard form" of Beylkin,
//! Coifman and Rokhlin, in which the vanishing moments make most entries negligible (Alpert
//! 1993, §4). [`threshold`] keeps the entries that `keep` asks for, as a sparse matrix.

use crate::basis::{transform, Filters};
use crate::progress::{Cancelled, Phase, Progress};
use crate::projection::{Dense, Layout, System};
use crate::scene::Keep;
use rayon::prelude::*;

/// Transforms one vector of a surface in place (scaling → wavelet).
pub fn forward_surface(layout: Layout, data: &mut [f64], scratch: &mut Vec<f64>) {
    match layout {
        Layout::Line { cells, k } => transform::forward(data, cells, Filters::of_order(k - 1), 1, scratch),
        Layout::Square { cells, k } => transform::forward_square(data, cells, Filters::of_order(k - 1), scratch),
    }
}

/// Transforms one vector of a surface in place (wavelet → scaling).
pub fn inverse_surface(layout: Layout, data: &mut [f64], scratch: &mut Vec<f64>) {
    match layout {
        Layout::Line { cells, k } => transform::inverse(data, cells, Filters::of_order(k - 1), 1, scratch),
        Layout::Square { cells, k } => transform::inverse_square(data, cells, Filters::of_order(k - 1), scratch),
    }
}

/// Applies the per-surface transform to every surface block of a vector.
pub fn forward_vector(layout: Layout, v: &mut [f64]) {
    let mut scratch = Vec::new();
    for block in v.chunks_mut(layout.len()) {
        forward_surface(layout, block, &mut scratch);
    }
}

pub fn inverse_vector(layout: Layout, v: &mut [f64]) {
    let mut scratch = Vec::new();
    for block in v.chunks_mut(layout.len()) {
        inverse_surface(layout, block, &mut scratch);
    }
}

/// Per-channel version of [`forward_vector`].
pub fn forward_rgb(layout: Layout, v: &mut [[f64; 3]]) {
    for c in 0..3 {
        let mut ch: Vec<f64> = v.iter().map(|x| x[c]).collect();
        forward_vector(layout, &mut ch);
        v.iter_mut().zip(ch).for_each(|(x, y)| x[c] = y);
    }
}

pub fn inverse_rgb(layout: Layout, v: &mut [[f64; 3]]) {
    for c in 0..3 {
        let mut ch: Vec<f64> = v.iter().map(|x| x[c]).collect();
        inverse_vector(layout, &mut ch);
        v.iter_mut().zip(ch).for_each(|(x, y)| x[c] = y);
    }
}

/// K → W K Wᵀ and E → W E, in place: rows, transpose, rows, transpose.
pub fn to_wavelet(system: &mut System, progress: &dyn Progress) -> Result<(), Cancelled> {
    let layout = system.layout;
    let n = system.matrix.n;
    progress.report(Phase::Transform, 0.0);
    for pass in 0..2 {
        system
            .matrix
            .data
            .par_chunks_mut(n)
            .try_for_each_init(Vec::new, |scratch, row| {
                progress.check()?;
                for block in row.chunks_mut(layout.len()) {
                    forward_surface(layout, block, scratch);
                }
                Ok::<(), Cancelled>(())
            })?;
        system.matrix.transpose();
        progress.report(Phase::Transform, 0.5 * (pass + 1) as f64);
    }
    forward_rgb(layout, &mut system.emission);
    Ok(())
}

/// A compressed sparse row matrix.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Csr {
    pub n: usize,
    pub row_ptr: Vec<usize>,
    pub cols: Vec<u32>,
    pub vals: Vec<f64>,
}

impl Csr {
    pub fn nnz(&self) -> usize {
        self.vals.len()
    }
    pub fn row(&self, i: usize) -> (&[u32], &[f64]) {
        let r = self.row_ptr[i]..self.row_ptr[i + 1];
        (&self.cols[r.clone()], &self.vals[r])
    }
    pub fn diagonal(&self, i: usize) -> f64 {
        let (c, v) = self.row(i);
        c.iter().position(|&j| j as usize == i).map_or(0.0, |p| v[p])
    }
}

/// What thresholding kept.
#[derive(Debug, Clone)]
pub struct Kept {
    pub csr: Csr,
    /// The smallest magnitude kept (0 when all is kept).
    pub cut: f64,
    /// Σ of the squares of the entries dropped.
    pub dropped_squares: f64,
}

/// How many entries of `entries` the rule keeps, and the magnitude at the cut.
fn cut_of(keep: Keep, sorted_desc: &[f64]) -> (usize, f64) {
    let nonzero = sorted_desc.partition_point(|&v| v > 0.0);
    let count = match keep {
        Keep::All => nonzero,
        Keep::Top(n) => n.min(nonzero),
        Keep::Fraction(f) => ((f * sorted_desc.len() as f64).ceil() as usize).min(nonzero),
        Keep::Threshold(t) => sorted_desc.partition_point(|&v| v >= t && v > 0.0),
    };
    let cut = if count == 0 { f64::INFINITY } else { sorted_desc[count - 1] };
    (count, cut)
}

/// Magnitudes of all entries, sorted in decreasing order.
pub fn sorted_magnitudes(m: &Dense) -> Vec<f64> {
    let mut mags: Vec<f64> = m.data.par_iter().map(|v| v.abs()).collect();
    mags.par_sort_unstable_by(|a, b| b.total_cmp(a));
    mags
}

/// `count` samples of the sorted magnitudes, evenly spaced in rank: (ranks, magnitudes).
pub fn sample_ranks(sorted_desc: &[f64], count: usize) -> (Vec<usize>, Vec<f64>) {
    let len = sorted_desc.len();
    if len == 0 || count == 0 {
        return (vec![], vec![]);
    }
    let count = count.min(len);
    let ranks: Vec<usize> = (0..count)
        .map(|i| {
            if count == 1 {
                0
            } else {
                ((i as f64) * (len - 1) as f64 / (count - 1) as f64).round() as usize
            }
        })
        .collect();
    let mags = ranks.iter().map(|&r| sorted_desc[r]).collect();
    (ranks, mags)
}

/// Keeps what `keep` asks for, in row order; ties at the cut are kept in row-major order until
/// the count is reached, so the result is deterministic.
pub fn threshold(m: &Dense, keep: Keep, sorted_desc: &[f64]) -> Kept {
    let (count, cut) = cut_of(keep, sorted_desc);
    // entries strictly above the cut are all kept; those equal to it fill up the count
    let above = sorted_desc.partition_point(|&v| v > cut);
    let mut ties_left = count.saturating_sub(above);
    let n = m.n;
    let mut csr = Csr {
        n,
        row_ptr: Vec::with_capacity(n + 1),
        cols: Vec::with_capacity(count),
        vals: Vec::with_capacity(count),
    };
    let mut dropped = 0.0;
    csr.row_ptr.push(0);
    for i in 0..n {
        for (j, &v) in m.row(i).iter().enumerate() {
            let a = v.abs();
            let keep_it = a > cut || (a == cut && a > 0.0 && ties_left > 0 && {
                ties_left -= 1;
                true
            });
            if keep_it {
                csr.cols.push(j as u32);
                csr.vals.push(v);
            } else {
                dropped += v * v;
            }
        }
        csr.row_ptr.push(csr.vals.len());
    }
    Kept {
        csr,
        cut: if matches!(keep, Keep::All) || count == 0 { 0.0 } else { cut },
        dropped_squares: dropped,
    }
}

/// A picture of the matrix magnitudes for `sparsity.png`: `side × side` cells, each the largest
/// magnitude of the block of entries it covers.
#[derive(Debug, Clone, PartialEq)]
pub struct MagnitudePicture {
    pub side: usize,
    /// Row-major, `side²` values.
    pub values: Vec<f64>,
    /// Entries per picture cell along a side (1 when the matrix fits).
    pub block: usize,
    /// The smallest magnitude kept by thresholding (entries below it are drawn as dropped).
    pub cut: f64,
}

pub fn picture(m: &Dense, max_side: usize, cut: f64) -> MagnitudePicture {
    let block = m.n.div_ceil(max_side.max(1)).max(1);
    let side = m.n.div_ceil(block);
    let mut values = vec![0.0f64; side * side];
    for i in 0..m.n {
        let row = m.row(i);
        for (j, v) in row.iter().enumerate() {
            let cell = &mut values[(i / block) * side + j / block];
            *cell = cell.max(v.abs());
        }
    }
    MagnitudePicture {
        side,
        values,
        block,
        cut,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> Dense {
        let mut m = Dense::zeros(3);
        m.data = vec![3.0, -1.0, 0.0, 2.0, -2.0, 0.5, 0.0, 1.0, 4.0];
        m
    }

    #[test]
    fn keeps_top_fraction_and_threshold() {
        let m = sample();
        let sorted = sorted_magnitudes(&m);
        assert_eq!(sorted[..4], [4.0, 3.0, 2.0, 2.0]);
        let k = threshold(&m, Keep::Top(3), &sorted);
        assert_eq!(k.csr.nnz(), 3);
        assert_eq!(k.cut, 2.0);
        // of the two 2's, the first in row order is kept
        assert_eq!(k.csr.row(1), (&[0u32][..], &[2.0][..]));
        assert!((k.dropped_squares - (1.0 + 4.0 + 0.25 + 1.0)).abs() < 1e-15);
        let all = threshold(&m, Keep::All, &sorted);
        assert_eq!(all.csr.nnz(), 7);
        assert_eq!(all.dropped_squares, 0.0);
        assert_eq!(threshold(&m, Keep::Threshold(1.0), &sorted).csr.nnz(), 6);
        assert_eq!(threshold(&m, Keep::Fraction(0.5), &sorted).csr.nnz(), 5);
        assert_eq!(all.csr.diagonal(2), 4.0);
    }

    #[test]
    fn rank_samples_include_both_ends() {
        let sorted: Vec<f64> = (0..10).rev().map(|x| x as f64).collect();
        let (r, v) = sample_ranks(&sorted, 4);
        assert_eq!(r, [0, 3, 6, 9]);
        assert_eq!(v, [9.0, 6.0, 3.0, 0.0]);
    }

    #[test]
    fn picture_takes_block_maxima() {
        let p = picture(&sample(), 2, 0.0);
        assert_eq!(p.side, 2);
        assert_eq!(p.values, [3.0, 0.5, 1.0, 4.0]);
    }
}
