//! The kernel matrix in the wavelet basis and its thresholding.
//!
//! With W the orthogonal per-surface wavelet transform of [`crate::math::basis::transform`], the
//! system B = E + ρKB becomes (WB) = (WE) + ρ (W K Wᵀ)(WB): the "standard form" of Beylkin,
//! Coifman and Rokhlin, in which the vanishing moments make most entries negligible (Alpert
//! 1993, §4). [`threshold`] keeps the entries that `keep` asks for, as a sparse matrix.

use crate::math::basis::{transform, Filters};
use crate::methods::operator::Operator;
use crate::methods::projection::{Dense, Layout, System};
use crate::progress::{Cancelled, Phase, Progress};
use crate::scene::{Keep, Rgb};
use rayon::prelude::*;

/// Transforms one vector of a surface in place (scaling → wavelet).
fn forward_surface(layout: Layout, data: &mut [f64], scratch: &mut Vec<f64>) {
    match layout {
        Layout::Line { cells, k } => {
            transform::forward(data, cells, Filters::of_order(k - 1), 1, scratch)
        }
        Layout::Square { cells, k } => {
            transform::forward_square(data, cells, Filters::of_order(k - 1), scratch)
        }
    }
}

/// Transforms one vector of a surface in place (wavelet → scaling).
fn inverse_surface(layout: Layout, data: &mut [f64], scratch: &mut Vec<f64>) {
    match layout {
        Layout::Line { cells, k } => {
            transform::inverse(data, cells, Filters::of_order(k - 1), 1, scratch)
        }
        Layout::Square { cells, k } => {
            transform::inverse_square(data, cells, Filters::of_order(k - 1), scratch)
        }
    }
}

/// Applies the per-surface transform to every surface block of a vector.
fn forward_vector(layout: Layout, v: &mut [f64]) {
    let mut scratch = Vec::new();
    for block in v.chunks_mut(layout.len()) {
        forward_surface(layout, block, &mut scratch);
    }
}

fn inverse_vector(layout: Layout, v: &mut [f64]) {
    let mut scratch = Vec::new();
    for block in v.chunks_mut(layout.len()) {
        inverse_surface(layout, block, &mut scratch);
    }
}

/// Per-channel version of [`forward_vector`].
fn forward_rgb(layout: Layout, v: &mut [[f64; 3]]) {
    for c in 0..3 {
        let mut ch: Vec<f64> = v.iter().map(|x| x[c]).collect();
        forward_vector(layout, &mut ch);
        v.iter_mut().zip(ch).for_each(|(x, y)| x[c] = y);
    }
}

pub(crate) fn inverse_rgb(layout: Layout, v: &mut [[f64; 3]]) {
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
    pub(crate) n: usize,
    pub(super) row_ptr: Vec<usize>,
    pub(super) cols: Vec<u32>,
    pub(super) vals: Vec<f64>,
}

impl Csr {
    pub fn nnz(&self) -> usize {
        self.vals.len()
    }
    pub(crate) fn row(&self, i: usize) -> (&[u32], &[f64]) {
        let r = self.row_ptr[i]..self.row_ptr[i + 1];
        (&self.cols[r.clone()], &self.vals[r])
    }
    fn diagonal(&self, i: usize) -> f64 {
        let (c, v) = self.row(i);
        c.iter()
            .position(|&j| j as usize == i)
            .map_or(0.0, |p| v[p])
    }
}

/// What thresholding kept: a sparse matrix, or the dense one with the dropped entries zeroed
/// when more than a third of the entries are kept (a CSR copy would then cost more memory than
/// the dense matrix it came from).
#[derive(Debug, Clone)]
pub(crate) enum KeptMatrix {
    Sparse(Csr),
    Dense(Dense),
}

impl KeptMatrix {
    pub(crate) fn operator(&self) -> &dyn Operator {
        match self {
            KeptMatrix::Sparse(c) => c,
            KeptMatrix::Dense(d) => d,
        }
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

/// The magnitudes of a matrix's entries in decreasing order, without sorting them all: a
/// histogram of the leading bits of |v| (monotone in |v| for floats) locates any rank's bucket,
/// and only the buckets that hold the ranks asked for are gathered and sorted. One pass over the
/// matrix, memory independent of its size, and a cancellation check every few million entries.
#[derive(Debug, Clone)]
pub struct Ranking {
    /// Counts of non-zero magnitudes per bucket (the top bits of `|v|.to_bits()`); empty for a
    /// small matrix, whose magnitudes are simply sorted.
    buckets: Vec<u64>,
    /// Entries in buckets above each bucket (so the ranks of bucket b start at above[b]).
    above: Vec<u64>,
    /// Small matrices: every magnitude, decreasing.
    sorted: Vec<f64>,
    zeros: u64,
    len: usize,
}

/// Up to this many entries the magnitudes are sorted outright.
const SORT_BELOW: usize = 1 << 16;

/// Buckets of 1/256 of an octave: the sign bit is clear, so 19 bits of exponent and mantissa.
const BUCKET_SHIFT: u32 = 44;
const BUCKETS: usize = 1 << 19;
const CHUNK: usize = 1 << 22;

#[inline]
fn bucket_of(v: f64) -> usize {
    (v.abs().to_bits() >> BUCKET_SHIFT) as usize
}

impl Ranking {
    pub fn new(values: &[f64], progress: &dyn Progress) -> Result<Ranking, Cancelled> {
        if values.len() <= SORT_BELOW {
            let mut sorted: Vec<f64> = values.iter().map(|v| v.abs()).collect();
            sorted.sort_unstable_by(|a, b| b.total_cmp(a));
            return Ok(Ranking {
                zeros: sorted.iter().filter(|v| **v == 0.0).count() as u64,
                len: values.len(),
                sorted,
                buckets: Vec::new(),
                above: Vec::new(),
            });
        }
        let (buckets, zeros) = values
            .par_chunks(CHUNK)
            .map(|chunk| {
                progress.check()?;
                let mut h = vec![0u64; BUCKETS];
                let mut z = 0u64;
                for &v in chunk {
                    if v == 0.0 {
                        z += 1;
                    } else {
                        h[bucket_of(v)] += 1;
                    }
                }
                Ok((h, z))
            })
            .try_reduce(
                || (vec![0u64; BUCKETS], 0),
                |(mut a, za), (b, zb)| {
                    a.iter_mut().zip(&b).for_each(|(x, y)| *x += y);
                    Ok((a, za + zb))
                },
            )?;
        let mut above = vec![0u64; BUCKETS];
        let mut acc = 0;
        for b in (0..BUCKETS).rev() {
            above[b] = acc;
            acc += buckets[b];
        }
        Ok(Ranking {
            buckets,
            above,
            sorted: Vec::new(),
            zeros,
            len: values.len(),
        })
    }

    pub(crate) fn len(&self) -> usize {
        self.len
    }

    fn nonzero(&self) -> usize {
        self.len - self.zeros as usize
    }

    /// For each rank (0 = largest), the magnitude there and the first rank holding that same
    /// magnitude. `values` must be the slice the ranking was built from.
    pub(crate) fn locate(&self, values: &[f64], ranks: &[usize]) -> Vec<(f64, usize)> {
        if self.buckets.is_empty() {
            return ranks
                .iter()
                .map(|&r| {
                    let v = self.sorted.get(r).copied().unwrap_or(0.0);
                    (v, self.sorted.partition_point(|x| *x > v))
                })
                .collect();
        }
        // bucket and the rank of its first (largest) element, for every non-zero rank asked
        let mut wanted = vec![false; BUCKETS];
        let mut places = Vec::with_capacity(ranks.len());
        for &r in ranks {
            if r >= self.nonzero() {
                places.push(None);
                continue;
            }
            // the ranks of bucket b are above[b] .. above[b] + buckets[b], decreasing in b
            let (mut lo, mut hi) = (0, BUCKETS);
            while lo < hi {
                let mid = (lo + hi) / 2;
                if self.above[mid] + self.buckets[mid] > r as u64 {
                    lo = mid + 1;
                } else {
                    hi = mid;
                }
            }
            let b = lo - 1;
            wanted[b] = true;
            places.push(Some((b, self.above[b] as usize)));
        }
        let mut gathered: Vec<(usize, f64)> = values
            .par_chunks(CHUNK)
            .flat_map_iter(|chunk| {
                chunk
                    .iter()
                    .filter(|v| **v != 0.0 && wanted[bucket_of(**v)])
                    .map(|v| (bucket_of(*v), v.abs()))
                    .collect::<Vec<_>>()
            })
            .collect();
        gathered.par_sort_unstable_by(|a, b| b.0.cmp(&a.0).then(b.1.total_cmp(&a.1)));
        ranks
            .iter()
            .zip(places)
            .map(|(&r, place)| match place {
                None => (0.0, self.nonzero()),
                Some((b, first)) => {
                    let start = gathered.partition_point(|g| g.0 > b);
                    let v = gathered[start + (r - first)].1;
                    let eq = gathered[start..].partition_point(|g| g.0 == b && g.1 > v);
                    (v, first + eq)
                }
            })
            .collect()
    }
}

/// `count` ranks evenly spaced from the largest to the smallest entry.
pub(crate) fn sample_ranks(len: usize, count: usize) -> Vec<usize> {
    if len == 0 || count == 0 {
        return vec![];
    }
    let count = count.min(len);
    (0..count)
        .map(|i| {
            if count == 1 {
                0
            } else {
                ((i as f64) * (len - 1) as f64 / (count - 1) as f64).round() as usize
            }
        })
        .collect()
}

/// How many of `values()` there are, and the `count` of them at ranks evenly spaced from the
/// largest to the smallest ([`sample_ranks`]), exactly as a sort from the largest would give
/// them, without sorting them all: `values` yields positive finite numbers and is called
/// twice. A histogram over the top bits of the numbers (their order as floats is that of
/// their bits) finds the bin of each rank; only the bins that hold a rank are kept and
/// sorted. The 7 M links of a 10⁵-triangle scene have 116 M coefficients, which a sorted
/// copy held in 0.9 GB.
pub(crate) fn ranked<I: Iterator<Item = f64>>(
    values: impl Fn() -> I,
    count: usize,
) -> (usize, Vec<(usize, f64)>) {
    // 2¹⁹ bins of positive floats (their sign bit is 0): the exponent and 8 bits of the
    // mantissa
    const SHIFT: u32 = 44;
    let bin = |v: f64| (v.to_bits() >> SHIFT) as usize;
    let mut counts = vec![0usize; 1 << (63 - SHIFT)];
    for v in values() {
        counts[bin(v)] += 1;
    }
    let len: usize = counts.iter().sum();
    let ranks = sample_ranks(len, count);
    // the bins from the largest down, with the ranks before each: rank r is in the bin
    // where the running count passes it, at r less what the bins above hold
    let mut wanted: Vec<(usize, usize, usize)> = Vec::with_capacity(ranks.len());
    let mut above = 0;
    let mut next = ranks.iter().peekable();
    for (b, &c) in counts.iter().enumerate().rev() {
        while let Some(&&r) = next.peek() {
            if r >= above + c {
                break;
            }
            wanted.push((r, b, r - above));
            next.next();
        }
        above += c;
    }
    let mut held: std::collections::BTreeMap<usize, Vec<f64>> =
        wanted.iter().map(|&(_, b, _)| (b, Vec::new())).collect();
    for v in values() {
        if let Some(h) = held.get_mut(&bin(v)) {
            h.push(v);
        }
    }
    for h in held.values_mut() {
        h.sort_unstable_by(|a, b| b.total_cmp(a));
    }
    let out = wanted.iter().map(|&(r, b, k)| (r, held[&b][k])).collect();
    (len, out)
}

/// Which entries a keep rule keeps, decided entry by entry in row-major order: every |v| above
/// the cut, and entries at the cut while ties are left (all of them for a threshold rule), so
/// the selection is deterministic.
struct Selector {
    cut: f64,
    inclusive: bool,
    ties_left: usize,
    /// How many entries will be kept (for a threshold rule: at most this many).
    count: usize,
}

impl Selector {
    fn new(m: &Dense, keep: Keep, ranking: &Ranking) -> Selector {
        let nonzero = ranking.nonzero();
        let count = match keep {
            Keep::All | Keep::Threshold(_) => nonzero,
            Keep::Top(n) => n.min(nonzero),
            // of the nonzero coefficients: the blocks that are zero whatever the basis (a flat
            // surface with itself, pairs that face away) hold nothing to keep or drop, and
            // counting them made half of two plates' matrix all of its coefficients
            Keep::Fraction(f) => ((f * nonzero as f64).ceil() as usize).min(nonzero),
        };
        let (cut, above) = match keep {
            Keep::Threshold(t) => (t, 0),
            _ if count == 0 => (f64::INFINITY, 0),
            _ => ranking.locate(&m.data, &[count - 1])[0],
        };
        let inclusive = matches!(keep, Keep::Threshold(_));
        let count = match keep {
            // entries ≥ t: the first rank below t
            Keep::Threshold(t) => m
                .data
                .par_iter()
                .filter(|v| v.abs() >= t && **v != 0.0)
                .count(),
            _ => count,
        };
        Selector {
            cut,
            inclusive,
            ties_left: count.saturating_sub(above),
            count,
        }
    }

    #[inline]
    fn keeps(&mut self, v: f64) -> bool {
        let a = v.abs();
        if a == 0.0 || a < self.cut {
            return false;
        }
        if a > self.cut || self.inclusive {
            return true;
        }
        if self.ties_left > 0 {
            self.ties_left -= 1;
            return true;
        }
        false
    }
}

/// Keeps what `keep` asks for, consuming the dense matrix: sparse when at most a third of the
/// entries survive, else the dense matrix itself with the dropped entries set to zero (a sparse
/// copy would then cost more memory than the matrix). Also returns the number of entries kept,
/// the smallest magnitude kept, and Σ K_ij² of the kept entries per block of surfaces
/// (`S × S` for blocks of `per` rows and columns).
pub(crate) fn keep_entries(
    mut m: Dense,
    keep: Keep,
    ranking: &Ranking,
    per: usize,
) -> (KeptMatrix, usize, f64, Vec<f64>) {
    let mut sel = Selector::new(&m, keep, ranking);
    let dense = 3 * sel.count > m.n * m.n;
    let blocks = m.n / per.max(1);
    let mut squares = vec![0.0; blocks * blocks];
    let mut smallest = f64::INFINITY;
    let mut count = 0;
    let n = m.n;
    let mut csr = Csr {
        n,
        row_ptr: vec![0],
        cols: Vec::new(),
        vals: Vec::new(),
    };
    for i in 0..n {
        let row = &mut m.data[i * n..(i + 1) * n];
        for (j, v) in row.iter_mut().enumerate() {
            if sel.keeps(*v) {
                squares[(i / per) * blocks + j / per] += *v * *v;
                smallest = smallest.min(v.abs());
                count += 1;
                if !dense {
                    csr.cols.push(j as u32);
                    csr.vals.push(*v);
                }
            } else {
                *v = 0.0;
            }
        }
        if !dense {
            csr.row_ptr.push(csr.vals.len());
        }
    }
    let cut = if matches!(keep, Keep::All) || count == 0 {
        0.0
    } else {
        smallest
    };
    let kept = if dense {
        KeptMatrix::Dense(m)
    } else {
        KeptMatrix::Sparse(csr)
    };
    (kept, count, cut, squares)
}

/// Keeps what `keep` asks for as a sparse matrix, leaving the dense one as it is.
pub fn threshold(m: &Dense, keep: Keep, ranking: &Ranking) -> Kept {
    let mut sel = Selector::new(m, keep, ranking);
    let n = m.n;
    let mut csr = Csr {
        n,
        row_ptr: Vec::with_capacity(n + 1),
        cols: Vec::new(),
        vals: Vec::new(),
    };
    let mut dropped = 0.0;
    let mut smallest = f64::INFINITY;
    csr.row_ptr.push(0);
    for i in 0..n {
        for (j, &v) in m.row(i).iter().enumerate() {
            if sel.keeps(v) {
                csr.cols.push(j as u32);
                csr.vals.push(v);
                smallest = smallest.min(v.abs());
            } else {
                dropped += v * v;
            }
        }
        csr.row_ptr.push(csr.vals.len());
    }
    Kept {
        cut: if matches!(keep, Keep::All) || csr.vals.is_empty() {
            0.0
        } else {
            smallest
        },
        csr,
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
    /// What a value is: an entry of the kernel matrix, or the mean kernel value of a link of
    /// the hierarchy over the finest cells its block covers.
    pub links: bool,
}

pub(crate) fn picture(m: &Dense, max_side: usize, cut: f64) -> MagnitudePicture {
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
        links: false,
    }
}

/// A picture of an operator given as blocks of its `n` rows and columns (the links of a
/// hierarchy): each block `(rows, columns, magnitude)` fills the picture cells it covers with
/// the largest magnitude among those covering them.
pub(crate) fn block_picture(
    n: usize,
    max_side: usize,
    blocks: impl Iterator<Item = (std::ops::Range<usize>, std::ops::Range<usize>, f64)>,
) -> MagnitudePicture {
    let block = n.div_ceil(max_side.max(1)).max(1);
    let side = n.div_ceil(block);
    let mut values = vec![0.0f64; side * side];
    for (rows, cols, v) in blocks {
        for i in rows.start / block..rows.end.div_ceil(block) {
            for j in cols.start / block..cols.end.div_ceil(block) {
                let c = &mut values[i * side + j];
                *c = c.max(v);
            }
        }
    }
    MagnitudePicture {
        side,
        values,
        block,
        cut: 0.0,
        links: true,
    }
}

/// [`picture`] of a sparse matrix.
pub(crate) fn picture_sparse(m: &Csr, max_side: usize, cut: f64) -> MagnitudePicture {
    let block = m.n.div_ceil(max_side.max(1)).max(1);
    let side = m.n.div_ceil(block);
    let mut values = vec![0.0f64; side * side];
    for i in 0..m.n {
        let (cols, vals) = m.row(i);
        for (&j, v) in cols.iter().zip(vals) {
            let cell = &mut values[(i / block) * side + j as usize / block];
            *cell = cell.max(v.abs());
        }
    }
    MagnitudePicture {
        side,
        values,
        block,
        cut,
        links: false,
    }
}

impl Operator for Csr {
    fn size(&self) -> usize {
        self.n
    }
    fn diagonal(&self, i: usize) -> f64 {
        Csr::diagonal(self, i)
    }
    #[inline]
    fn off_diagonal_dot(&self, i: usize, b: &[Rgb]) -> Rgb {
        let (cols, vals) = self.row(i);
        let mut acc = [0.0; 3];
        for (&j, &v) in cols.iter().zip(vals) {
            let j = j as usize;
            if j != i {
                let bj = b[j];
                acc[0] += v * bj[0];
                acc[1] += v * bj[1];
                acc[2] += v * bj[2];
            }
        }
        acc
    }
}

#[cfg(test)]
mod tests {

    #[test]
    fn ranked_magnitudes_are_those_of_the_sorted_values() {
        // many decades, ties (as congruent blocks give), and neighbours within one bin
        let mut x = 0x2545_f491_4f6c_dd1du64;
        let mut values = Vec::new();
        for i in 0..20_000 {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            let u = (x >> 11) as f64 / (1u64 << 53) as f64;
            values.push(match i % 4 {
                0 => 10f64.powf(-12.0 + 14.0 * u),
                1 => 0.25,
                2 => 0.25 * (1.0 + 1e-9 * u),
                _ => 1e-3 * (1.0 + u),
            });
        }
        let mut sorted = values.clone();
        sorted.sort_unstable_by(|a, b| b.total_cmp(a));
        for count in [0, 1, 2, 7, 256, 20_000, 30_000] {
            let (len, got) = ranked(|| values.iter().copied(), count);
            assert_eq!(len, values.len());
            let want: Vec<(usize, f64)> = sample_ranks(len, count)
                .into_iter()
                .map(|r| (r, sorted[r]))
                .collect();
            assert_eq!(got, want, "count {count}");
        }
    }
    use super::*;
    use crate::progress::Silent;

    fn sample() -> Dense {
        let mut m = Dense::zeros(3);
        m.data = vec![3.0, -1.0, 0.0, 2.0, -2.0, 0.5, 0.0, 1.0, 4.0];
        m
    }

    #[test]
    fn keeps_top_fraction_and_threshold() {
        let m = sample();
        let sorted = Ranking::new(&m.data, &Silent).unwrap();
        let top4: Vec<f64> = sorted
            .locate(&m.data, &[0, 1, 2, 3, 8])
            .iter()
            .map(|x| x.0)
            .collect();
        assert_eq!(top4, [4.0, 3.0, 2.0, 2.0, 0.0]);
        assert_eq!(sorted.locate(&m.data, &[3])[0], (2.0, 2));
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
        // half of the seven nonzero entries, not of the nine
        assert_eq!(threshold(&m, Keep::Fraction(0.5), &sorted).csr.nnz(), 4);
        assert_eq!(all.csr.diagonal(2), 4.0);
    }

    #[test]
    fn rank_samples_include_both_ends() {
        assert_eq!(sample_ranks(10, 4), [0, 3, 6, 9]);
        assert_eq!(sample_ranks(10, 1), [0]);
        assert!(sample_ranks(0, 4).is_empty());
    }

    /// The ranking agrees with a full sort on values that share buckets and tie.
    #[test]
    fn ranking_matches_a_full_sort() {
        // below and above the size where the ranking switches from sorting to buckets
        for size in [5_000, 3 * SORT_BELOW] {
            let mut s = 7u64;
            let values: Vec<f64> = (0..size as i32)
                .map(|i| {
                    s = s
                        .wrapping_mul(6364136223846793005)
                        .wrapping_add(1442695040888963407);
                    let x =
                        ((s >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 10f64.powi((i % 17) - 8);
                    if i % 11 == 0 {
                        0.0
                    } else if i % 13 == 0 {
                        0.25
                    } else {
                        x
                    }
                })
                .collect();
            let mut sorted: Vec<f64> = values.iter().map(|v| v.abs()).collect();
            sorted.sort_by(|a, b| b.total_cmp(a));
            let r = Ranking::new(&values, &Silent).unwrap();
            let ranks: Vec<usize> = (0..values.len())
                .step_by(97)
                .chain([values.len() - 1])
                .collect();
            for ((v, first), &rank) in r.locate(&values, &ranks).iter().zip(&ranks) {
                assert_eq!(*v, sorted[rank], "size {size} rank {rank}");
                assert_eq!(*first, sorted.partition_point(|x| x > v));
            }
        }
    }
}
