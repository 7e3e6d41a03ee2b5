//! B over one surface, as the piecewise polynomials that a solve produces: leaves in the
//! parameter domain [0,1] (flatland, fredholm) or [0,1]² (3d), each with its local expansion in
//! orthonormal shifted Legendre polynomials (tensor products in 2D). Uniform grids and the
//! quadtrees of the hierarchical method are both such fields. Evaluating one is the sum
//! B_p(x) = Σ_i b_i N_i(x) of the slides' eq. (7).

use crate::math::basis::legendre;
use crate::math::quadrature::Rule;
use crate::math::triangle::{cell_halves, local_in_half, TriangleBasis};

/// One leaf: B(s,t) = Σ c[q][p] φ_p(ŝ) φ_q(t̂) with ŝ, t̂ the local coordinates in the leaf.
#[derive(Debug, Clone, PartialEq)]
pub struct Leaf {
    pub s: [f64; 2],
    /// `[0, 1]` in 1D.
    pub t: [f64; 2],
    /// `k` (1D) or `k·k` (2D, `[q][p]`, p along s) coefficients per channel. On a triangle
    /// field, the first (m+1)(m+2)/2 are those of [`TriangleBasis`] (normalised by the mean,
    /// as here) and the rest zero.
    pub coeffs: Vec<[f64; 3]>,
    /// On a triangle field: the leaf is the upper-right half of its square rather than the
    /// lower-left ([`crate::three_d::geometry::Piece`]).
    pub upper: bool,
}

#[derive(Debug, Clone, PartialEq)]
pub struct Field {
    /// 1 or 2.
    pub(crate) dims: usize,
    pub(crate) order: usize,
    /// Finest cells per side; every leaf is a union of these.
    pub(crate) res: usize,
    pub leaves: Vec<Leaf>,
    /// B over the triangle s + t ≤ 1 (a triangle patch), whose leaves are the triangles of
    /// the midpoint split.
    pub(crate) tri: bool,
    /// The basis of a triangle field's leaves.
    basis: Option<&'static TriangleBasis>,
    /// For each finest cell (`[t][s]`), the leaf that holds it; on a triangle field, for each
    /// half of each finest cell (`[t][s][upper]`).
    lookup: Vec<u32>,
}

impl Field {
    /// A field from leaves that tile the domain, all aligned to a `res` grid.
    pub fn from_leaves(dims: usize, order: usize, res: usize, leaves: Vec<Leaf>) -> Field {
        let rows = if dims == 2 { res } else { 1 };
        let mut lookup = vec![u32::MAX; res * rows];
        for (i, l) in leaves.iter().enumerate() {
            let s0 = (l.s[0] * res as f64).round() as usize;
            let s1 = (l.s[1] * res as f64).round() as usize;
            let (t0, t1) = if dims == 2 {
                (
                    (l.t[0] * res as f64).round() as usize,
                    (l.t[1] * res as f64).round() as usize,
                )
            } else {
                (0, 1)
            };
            for t in t0..t1 {
                for s in s0..s1 {
                    lookup[t * res + s] = i as u32;
                }
            }
        }
        debug_assert!(lookup.iter().all(|&l| l != u32::MAX), "leaves do not tile");
        Field {
            dims,
            order,
            res,
            leaves,
            tri: false,
            basis: None,
            lookup,
        }
    }

    /// A field over the triangle s + t ≤ 1 from the leaves of its midpoint split, aligned to a
    /// `res` grid (a power of two).
    pub(crate) fn triangle(order: usize, res: usize, leaves: Vec<Leaf>) -> Field {
        let mut lookup = vec![u32::MAX; 2 * res * res];
        for (i, l) in leaves.iter().enumerate() {
            let s0 = (l.s[0] * res as f64).round() as usize;
            let t0 = (l.t[0] * res as f64).round() as usize;
            let n = ((l.s[1] - l.s[0]) * res as f64).round() as usize;
            for (k, j, upper) in cell_halves(n, l.upper) {
                lookup[2 * ((t0 + j) * res + s0 + k) + usize::from(upper)] = i as u32;
            }
        }
        Field {
            dims: 2,
            order,
            res,
            leaves,
            tri: true,
            basis: Some(TriangleBasis::of_order(order)),
            lookup,
        }
    }

    /// A uniform 1D field of `cells` cells from local coefficients `[cell][p]`.
    pub(crate) fn uniform_line(order: usize, cells: usize, local: &[[f64; 3]]) -> Field {
        let k = order + 1;
        let h = 1.0 / cells as f64;
        let leaves = (0..cells)
            .map(|c| Leaf {
                s: [c as f64 * h, (c + 1) as f64 * h],
                t: [0.0, 1.0],
                coeffs: local[c * k..(c + 1) * k].to_vec(),
                upper: false,
            })
            .collect();
        Field::from_leaves(1, order, cells, leaves)
    }

    /// A uniform 2D field of `cells × cells` cells from local coefficients
    /// `[cell_t][cell_s][q][p]`.
    pub fn uniform_square(order: usize, cells: usize, local: &[[f64; 3]]) -> Field {
        let kk = (order + 1) * (order + 1);
        let h = 1.0 / cells as f64;
        let mut leaves = Vec::with_capacity(cells * cells);
        for ct in 0..cells {
            for cs in 0..cells {
                let at = (ct * cells + cs) * kk;
                leaves.push(Leaf {
                    s: [cs as f64 * h, (cs + 1) as f64 * h],
                    t: [ct as f64 * h, (ct + 1) as f64 * h],
                    coeffs: local[at..at + kk].to_vec(),
                    upper: false,
                });
            }
        }
        Field::from_leaves(2, order, cells, leaves)
    }

    /// The leaf that holds (s, t).
    pub(crate) fn leaf_at(&self, s: f64, t: f64) -> &Leaf {
        let cell = |x: f64| ((x * self.res as f64) as usize).min(self.res - 1);
        if self.tri {
            // a point outside the triangle is taken at its nearest point on the diagonal
            let (s, t) = if s + t > 1.0 {
                let d = 0.5 * (s + t - 1.0);
                ((s - d).max(0.0), (t - d).max(0.0))
            } else {
                (s, t)
            };
            let (cs, ct) = (cell(s), cell(t));
            let (fs, ft) = (
                s * self.res as f64 - cs as f64,
                t * self.res as f64 - ct as f64,
            );
            let upper = fs + ft > 1.0 && cs + ct + 1 < self.res;
            let at = 2 * (ct * self.res + cs) + usize::from(upper);
            return &self.leaves[self.lookup[at] as usize];
        }
        let row = if self.dims == 2 { cell(t) } else { 0 };
        &self.leaves[self.lookup[row * self.res + cell(s)] as usize]
    }

    /// B at (s, t) (t is ignored in 1D).
    pub fn eval(&self, s: f64, t: f64) -> [f64; 3] {
        let leaf = self.leaf_at(s.clamp(0.0, 1.0), t.clamp(0.0, 1.0));
        self.eval_leaf(leaf, s, t)
    }

    /// The expansion of `leaf` at (s, t), also outside the leaf (a polynomial).
    pub fn eval_leaf(&self, leaf: &Leaf, s: f64, t: f64) -> [f64; 3] {
        let k = self.order + 1;
        if let Some(basis) = self.basis {
            let (u, v) = local_in_half(leaf.s, leaf.t, leaf.upper, s, t);
            let n = crate::math::triangle::dimension(self.order);
            let mut phi = [0.0; 64];
            basis.eval(u, v, &mut phi[..n]);
            let mut out = [0.0; 3];
            for (c, p) in leaf.coeffs[..n].iter().zip(&phi[..n]) {
                (0..3).for_each(|ch| out[ch] += c[ch] * p);
            }
            return out;
        }
        let mut ps = [0.0; 16];
        let mut pt = [0.0; 16];
        legendre((s - leaf.s[0]) / (leaf.s[1] - leaf.s[0]), &mut ps[..k]);
        let mut out = [0.0; 3];
        if self.dims == 1 {
            for p in 0..k {
                for c in 0..3 {
                    out[c] += leaf.coeffs[p][c] * ps[p];
                }
            }
            return out;
        }
        legendre((t - leaf.t[0]) / (leaf.t[1] - leaf.t[0]), &mut pt[..k]);
        for q in 0..k {
            for p in 0..k {
                let b = ps[p] * pt[q];
                for c in 0..3 {
                    out[c] += leaf.coeffs[q * k + p][c] * b;
                }
            }
        }
        out
    }

    /// ∫ B over the parameter rectangle `[s0,s1] × [t0,t1]` (in 1D only `s` counts), exactly:
    /// a Gauss rule of ⌈(m+1)/2⌉ points on each leaf piece integrates the polynomial exactly.
    fn integral(&self, s: [f64; 2], t: [f64; 2]) -> [f64; 3] {
        if self.tri {
            // over a triangle only the whole is asked for (its mean times its measure, ½)
            debug_assert!(s == [0.0, 1.0] && t == [0.0, 1.0]);
            return self.mean().map(|x| 0.5 * x);
        }
        let rule = Rule::for_degree(self.order);
        let mut out = [0.0; 3];
        let cell_range = |x: [f64; 2]| {
            let lo = ((x[0] * self.res as f64).floor() as usize).min(self.res - 1);
            let hi = ((x[1] * self.res as f64).ceil() as usize).clamp(lo + 1, self.res);
            lo..hi
        };
        let rows = if self.dims == 2 { cell_range(t) } else { 0..1 };
        let mut seen: Vec<u32> = Vec::new();
        for row in rows {
            for col in cell_range(s) {
                let l = self.lookup[row * self.res + col];
                if seen.contains(&l) {
                    continue;
                }
                seen.push(l);
                let leaf = &self.leaves[l as usize];
                let ps = [s[0].max(leaf.s[0]), s[1].min(leaf.s[1])];
                let pt = if self.dims == 2 {
                    [t[0].max(leaf.t[0]), t[1].min(leaf.t[1])]
                } else {
                    [0.0, 1.0]
                };
                if ps[1] <= ps[0] || pt[1] <= pt[0] {
                    continue;
                }
                if self.dims == 1 {
                    for (x, w) in rule.mapped(ps[0], ps[1]) {
                        let v = self.eval_leaf(leaf, x, 0.0);
                        (0..3).for_each(|c| out[c] += w * v[c]);
                    }
                } else {
                    for (x, wx) in rule.mapped(ps[0], ps[1]) {
                        for (y, wy) in rule.mapped(pt[0], pt[1]) {
                            let v = self.eval_leaf(leaf, x, y);
                            (0..3).for_each(|c| out[c] += wx * wy * v[c]);
                        }
                    }
                }
            }
        }
        out
    }

    /// Mean of B over the whole surface.
    pub(crate) fn mean(&self) -> [f64; 3] {
        if self.tri {
            // each leaf's share of the triangle is h², its mean the first coefficient
            let mut out = [0.0; 3];
            for l in &self.leaves {
                let h = l.s[1] - l.s[0];
                (0..3).for_each(|c| out[c] += h * h * l.coeffs[0][c]);
            }
            return out;
        }
        self.integral([0.0, 1.0], [0.0, 1.0])
    }

    /// Cell means on a `grid` (1D) or `grid × grid` (2D, rows by t then s) split.
    pub(crate) fn cell_means(&self, grid: usize) -> Vec<[f64; 3]> {
        if self.tri {
            // a triangle is one cell (scene.md)
            return vec![self.mean()];
        }
        let g = grid as f64;
        let span = |i: usize| [i as f64 / g, (i + 1) as f64 / g];
        let area = if self.dims == 2 {
            1.0 / (g * g)
        } else {
            1.0 / g
        };
        let rows = if self.dims == 2 { grid } else { 1 };
        let mut out = Vec::with_capacity(grid * rows);
        for r in 0..rows {
            for c in 0..grid {
                let t = if self.dims == 2 { span(r) } else { [0.0, 1.0] };
                let v = self.integral(span(c), t);
                out.push([v[0] / area, v[1] / area, v[2] / area]);
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exact_cell_means_of_a_linear_field() {
        // B(s) = s on 4 cells (order 1): local coefficients [mean, slope / (2√3)]
        let n = 4;
        let h = 0.25;
        let local: Vec<[f64; 3]> = (0..n)
            .flat_map(|c| {
                let mid = (c as f64 + 0.5) * h;
                [[mid; 3], [h / (2.0 * 3f64.sqrt()); 3]]
            })
            .collect();
        let f = Field::uniform_line(1, n, &local);
        assert!((f.eval(0.3, 0.0)[0] - 0.3).abs() < 1e-15);
        let means = f.cell_means(3);
        for (i, m) in means.iter().enumerate() {
            let want = (i as f64 + 0.5) / 3.0;
            assert!((m[1] - want).abs() < 1e-15, "{i}: {m:?}");
        }
        assert!((f.mean()[2] - 0.5).abs() < 1e-15);
    }

    #[test]
    fn square_fields_and_uneven_leaves() {
        // B(s,t) = 1 + t on a 2×2 grid of order 1: coefficient [q=1][p=0] = slope·h/(2√3)
        let h = 0.5;
        let mut local = Vec::new();
        for ct in 0..2 {
            for _cs in 0..2 {
                let mid_t = (ct as f64 + 0.5) * h;
                local.extend([
                    [1.0 + mid_t; 3],
                    [0.0; 3],
                    [h / (2.0 * 3f64.sqrt()); 3],
                    [0.0; 3],
                ]);
            }
        }
        let f = Field::uniform_square(1, 2, &local);
        assert!((f.eval(0.1, 0.7)[0] - 1.7).abs() < 1e-15);
        let means = f.cell_means(4);
        assert_eq!(means.len(), 16);
        // row 3 (t ∈ [0.75, 1]) has mean 1.875
        assert!((means[3 * 4 + 2][0] - 1.875).abs() < 1e-14);
    }
}
