//! The links between elements as one store: each link's ends and oracle factors in one array,
//! and its k² × k² block of eq. (11)'s Galerkin coefficients (Gortler et al. 1993: the
//! transfer T_RS of the link, rows by receiver coefficient) in a second array, in the same
//! order, k⁴ numbers a link.
//!
//! A link kept its block in a vector of its own: 24 bytes of vector and about 16 of the
//! allocator's beside the 128 bytes of coefficients at order 1, and a separate allocation
//! for each of millions. Side by side, the sweep's gather also reads the blocks of one
//! receiver's run in order, one after the other.
//!
//! The blocks are kept in single precision: they are integrated to about 1e-13 and rounded to
//! seven significant digits, a relative error of 6e-8 in each coefficient, four orders of
//! magnitude below the error that the oracle lets a link make (ε = 1e-3 of the brightest
//! emission at the defaults); it halves what the links hold (64 bytes a block at order 1).

use super::refine::Link;

/// Links (ends and factors) with their blocks, in one order.
#[derive(Debug, Default)]
pub(super) struct Links {
    /// Coefficients in a block: k⁴.
    size: usize,
    ends: Vec<Link>,
    blocks: Vec<f32>,
}

impl Links {
    /// No links, of blocks of `size` coefficients.
    pub(super) fn new(size: usize) -> Links {
        Links {
            size,
            ends: Vec::new(),
            blocks: Vec::new(),
        }
    }

    pub(super) fn len(&self) -> usize {
        self.ends.len()
    }

    /// Room for `more` links, so that a known number of them grows the arrays once.
    pub(super) fn reserve(&mut self, more: usize) {
        self.ends.reserve_exact(more);
        self.blocks.reserve_exact(more * self.size);
    }

    pub(super) fn push(&mut self, link: Link, block: &[f32]) {
        debug_assert_eq!(block.len(), self.size);
        self.ends.push(link);
        self.blocks.extend_from_slice(block);
    }

    /// Appends `n` links from `make`, which fills each one's block (in double precision) and
    /// returns its ends; the blocks are made in parallel.
    pub(super) fn extend_with<F>(&mut self, n: usize, make: F)
    where
        F: Fn(usize, &mut [f64]) -> Link + Sync,
    {
        use rayon::prelude::*;
        let (start, size) = (self.blocks.len(), self.size);
        self.blocks.resize(start + n * size, 0.0);
        let ends: Vec<Link> = self.blocks[start..]
            .par_chunks_exact_mut(size)
            .enumerate()
            .map_init(
                || vec![0.0; size],
                |full, (i, block)| {
                    let link = make(i, full);
                    block
                        .iter_mut()
                        .zip(full.iter())
                        .for_each(|(b, v)| *b = *v as f32);
                    link
                },
            )
            .collect();
        self.ends.extend(ends);
    }

    /// The ends and factors of every link.
    pub(super) fn ends(&self) -> &[Link] {
        &self.ends
    }

    /// Link `i`'s block.
    pub(super) fn block(&self, i: usize) -> &[f32] {
        &self.blocks[i * self.size..(i + 1) * self.size]
    }

    /// Every block's coefficients, one block after another.
    pub(super) fn coefficients(&self) -> &[f32] {
        &self.blocks
    }

    /// Each link with its block.
    pub(super) fn iter(&self) -> impl Iterator<Item = (&Link, &[f32])> {
        self.run(0..self.len())
    }

    /// The links `run` with their blocks.
    pub(super) fn run(&self, run: std::ops::Range<usize>) -> impl Iterator<Item = (&Link, &[f32])> {
        let blocks = &self.blocks[run.start * self.size..run.end * self.size];
        self.ends[run]
            .iter()
            .zip(blocks.chunks_exact(self.size.max(1)))
    }

    /// Takes out the links for which `take` holds, in order, and returns them; the others
    /// keep their order.
    pub(super) fn extract_if(&mut self, mut take: impl FnMut(&Link) -> bool) -> Links {
        let mut out = Links::new(self.size);
        let mut kept = 0;
        for i in 0..self.ends.len() {
            let (from, to) = (i * self.size, (i + 1) * self.size);
            if take(&self.ends[i]) {
                out.push(self.ends[i], &self.blocks[from..to]);
            } else {
                if kept != i {
                    self.ends[kept] = self.ends[i];
                    self.blocks.copy_within(from..to, kept * self.size);
                }
                kept += 1;
            }
        }
        self.ends.truncate(kept);
        self.blocks.truncate(kept * self.size);
        out
    }

    /// Sorts the links by (receiver, source), their blocks with them, in place: a second copy
    /// of the blocks would be the job's peak.
    pub(super) fn sort(&mut self) {
        let mut order: Vec<u32> = (0..self.ends.len() as u32).collect();
        order.sort_by_key(|&i| (self.ends[i as usize].recv, self.ends[i as usize].src));
        // position p takes the link at order[p], one cycle of the permutation at a time
        let mut done = vec![false; order.len()];
        for start in 0..order.len() {
            if done[start] {
                continue;
            }
            let mut p = start;
            loop {
                done[p] = true;
                let q = order[p] as usize;
                if q == start {
                    break;
                }
                self.swap(p, q);
                p = q;
            }
        }
    }

    fn swap(&mut self, a: usize, b: usize) {
        self.ends.swap(a, b);
        let (lo, hi) = (a.min(b), a.max(b));
        let (head, tail) = self.blocks.split_at_mut(hi * self.size);
        head[lo * self.size..(lo + 1) * self.size].swap_with_slice(&mut tail[..self.size]);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::three_d::hierarchy::refine::Factors;

    fn link(recv: u32, src: u32) -> Link {
        Link {
            recv,
            src,
            factors: Factors::default(),
        }
    }

    fn store(pairs: &[(u32, u32)]) -> Links {
        let mut links = Links::new(3);
        for &(r, s) in pairs {
            links.push(link(r, s), &[r as f32, s as f32, (10 * r + s) as f32]);
        }
        links
    }

    fn listed(links: &Links) -> Vec<(u32, u32, Vec<f32>)> {
        links
            .iter()
            .map(|(l, b)| (l.recv, l.src, b.to_vec()))
            .collect()
    }

    /// Sorting moves each block with its link: every permutation of four links, and a
    /// longer one with cycles of several lengths, come out in (receiver, source) order with
    /// their own blocks.
    #[test]
    fn sorting_keeps_each_block_with_its_link() {
        let pairs = [
            (3, 1),
            (0, 2),
            (2, 2),
            (1, 0),
            (0, 1),
            (3, 0),
            (2, 1),
            (1, 1),
        ];
        let mut want: Vec<(u32, u32)> = pairs.to_vec();
        want.sort();
        let mut links = store(&pairs);
        links.sort();
        let got = listed(&links);
        for ((r, s, b), w) in got.iter().zip(&want) {
            assert_eq!((*r, *s), *w);
            assert_eq!(*b, vec![*r as f32, *s as f32, (10 * r + s) as f32]);
        }
        // every order of four links
        let four = [(0, 0), (1, 0), (2, 0), (3, 0)];
        for a in 0..4 {
            for b in 0..4 {
                for c in 0..4 {
                    for d in 0..4 {
                        let idx = [a, b, c, d];
                        let mut seen = idx;
                        seen.sort();
                        if seen != [0, 1, 2, 3] {
                            continue;
                        }
                        let mut links = store(&idx.map(|i| four[i]));
                        links.sort();
                        let got: Vec<u32> = listed(&links).iter().map(|x| x.0).collect();
                        assert_eq!(got, vec![0, 1, 2, 3]);
                        for (r, _, b) in listed(&links) {
                            assert_eq!(b[0], r as f32);
                        }
                    }
                }
            }
        }
    }

    /// Taking links out keeps the others' order and blocks, and returns the taken ones in
    /// theirs; pushed back and sorted, every link is as it was.
    #[test]
    fn taking_out_and_appending_keep_the_blocks() {
        let pairs = [(0, 1), (1, 2), (2, 3), (3, 4), (4, 5)];
        let mut links = store(&pairs);
        let taken = links.extract_if(|l| l.recv % 2 == 1);
        assert_eq!(
            listed(&links),
            vec![
                (0, 1, vec![0.0, 1.0, 1.0]),
                (2, 3, vec![2.0, 3.0, 23.0]),
                (4, 5, vec![4.0, 5.0, 45.0])
            ]
        );
        assert_eq!(
            listed(&taken),
            vec![(1, 2, vec![1.0, 2.0, 12.0]), (3, 4, vec![3.0, 4.0, 34.0])]
        );
        for (l, b) in taken.iter() {
            links.push(*l, b);
        }
        links.sort();
        assert_eq!(listed(&links), listed(&store(&pairs)));
        assert_eq!(links.run(1..3).count(), 2);
        assert_eq!(links.block(4), &[4.0, 5.0, 45.0]);
    }
}
