//! The covered part of a surface: where a closed solid rests on it (a box on a floor), the
//! surface sees only the inside of the solid. No light arrives there and none leaves, so
//! B = E on it, and the radiosity just outside jumps from that to the lit floor in front of
//! the box's foot.
//!
//! One polynomial on an element that straddles the foot's outline fits both sides at once:
//! it darkens the floor next to the box, and with it the box's faces, which see mostly that
//! strip of floor. The hierarchy ([`crate::three_d::hierarchy`]) instead fits each such
//! element on its exposed part only, as in a cut-cell (fictitious domain) Galerkin method:
//! with χ the exposed part's indicator, the element's masked Gram matrix
//! G_ac = ∫ χ φ_a φ_c (here, over the element's unit square) turns the irradiance that
//! arrives, h_a = ∫ χ φ_a H, into the polynomial that matches H on the exposed part,
//! p = G⁺ h, and a polynomial p on the exposed part back into the projection of χ p, G p.
//!
//! The mask is found by probing, not from a list of solids: a point is covered when every
//! one of five rays from it over its hemisphere first meets the back of a surface. That is
//! the inside of a closed solid: a ray from the floor in front of a box meets the ceiling
//! or the front of the box. Surfaces are probed only where another surface stands on them,
//! away from their edges (the walls of a room meet only at edges), or where a surface lies
//! flat against them a little in front, facing the same way (a light hung just below a
//! ceiling: the ceiling behind it sees only its back). Each cell of the hierarchy's finest
//! level is probed at its corners and centre; the cells where the outline passes, and their
//! neighbours, are resolved on a [`SUB`] × [`SUB`] grid.
//!
//! Such an element sends its polynomial over the whole of it, and the rays between it and a
//! receiver, which start inside the solid where they start on the covered part, take that
//! part out as a visible fraction; what it sends is the part of the polynomial that the
//! exposed part determines ([`Rules::sending_share`]).
//!
//! A triangle patch is masked on the same grid of its (s, t) square, of which it is the half
//! s + t ≤ 1; its elements' Gram matrices are those of the orthonormal polynomials on
//! triangles (`Mask::exposure_triangle`).

use crate::math::basis::legendre::interval_gram;
use crate::math::triangle::{TriangleBasis, TriangleRule};
use crate::three_d::bvh::Bvh;
use crate::three_d::geometry::{
    add, covariance, cross, dot, normalize, scale, Parallelogram, Piece, Sym, V3,
};
use crate::three_d::rules::Rules;
use crate::three_d::steps::STEP;
use rayon::prelude::*;

/// Sub-cells per side of a finest cell that the outline of a covered part crosses.
pub(super) const SUB: usize = 16;

/// Relative size below which an eigenvalue of a masked Gram matrix counts as zero.
const CUTOFF: f64 = 1e-3;

/// The relative eigenvalue below which an element of `k` × `k` functions does not send an
/// eigenvector ([`Rules::sending_share`], `share`): the least relative eigenvalue of the Gram
/// matrix of k Legendre polynomials on half of their interval (and so of a square half
/// covered, their tensor product) times that share, and no less than [`CUTOFF`].
fn sending_cutoff(k: usize, share: f64) -> f64 {
    if k < 2 {
        return CUTOFF;
    }
    let g = interval_gram([0.5, 1.0], k);
    let eig = nalgebra::SymmetricEigen::new(nalgebra::DMatrix::from_row_slice(k, k, &g));
    (share * eig.eigenvalues.min() / eig.eigenvalues.max()).max(CUTOFF)
}

/// What lies under one finest cell.
#[derive(Debug, Clone, PartialEq)]
enum Cell {
    Open,
    Covered,
    /// Covered sub-cells, bit `j * SUB + i` for sub-cell (i along s, j along t).
    Cut(Box<[u64; SUB * SUB / 64]>),
}

/// The covered part of one surface on a `res × res` grid of its (s, t) square.
#[derive(Debug, Clone)]
pub struct Mask {
    res: usize,
    /// [`Rules::sending_share`] of the elements' exposures.
    sending_share: f64,
    /// `[t][s]`.
    cells: Vec<Cell>,
}

/// How much of an element is exposed, and the masked matrices of its polynomials.
#[derive(Debug, Clone, PartialEq)]
pub enum Exposure {
    Open,
    Covered,
    Partial(Box<Partial>),
}

/// The masked matrices of an element that is partly covered (tensor Legendre, `k² × k²`,
/// row-major, on the element's unit square).
#[derive(Debug, Clone, PartialEq)]
pub struct Partial {
    /// G = ∫ χ φ_a φ_c.
    pub(super) gram: Vec<f64>,
    /// G⁺, its pseudo-inverse (eigenvalues below [`CUTOFF`] of the largest left out: the
    /// polynomials that nearly vanish on a thin exposed sliver are not determined by it).
    pub(super) inverse: Vec<f64>,
    /// The projection onto the eigenvectors of G above [`sending_cutoff`] of the largest:
    /// what of the element's polynomial it sends ([`Exposure::sent`]).
    pub(super) sending: Vec<f64>,
    /// ∫_cell χ φ_a φ_c for the [`STEP`] × [`STEP`] cells of the element (index `i + STEP j`
    /// by their s and t positions): G split by those cells, for a visible fraction that is
    /// a step over them ([`crate::three_d::visibility::Seen`]).
    pub(super) steps: Vec<Vec<f64>>,
}

impl Partial {
    /// The exposed share of the area: G_00, as φ_0 = 1 on the unit square.
    #[cfg(test)]
    pub(crate) fn fraction(&self) -> f64 {
        self.gram[0]
    }

    /// y = M x for one of the `k² × k²` matrices, per channel.
    pub(super) fn apply(m: &[f64], x: &[[f64; 3]], y: &mut [[f64; 3]]) {
        let kk = x.len();
        for (a, out) in y.iter_mut().enumerate() {
            *out = [0.0; 3];
            for (c, v) in x.iter().enumerate() {
                let w = m[a * kk + c];
                (0..3).for_each(|ch| out[ch] += w * v[ch]);
            }
        }
    }
}

impl Mask {
    /// The masks of every surface of the scene that something stands on or lies flat against
    /// (`None` for the rest, and where nothing turned out covered), at `res` finest cells per
    /// side.
    ///
    /// `bvh` holds the occluders ([`Bvh::occluders`]; its box queries over every surface,
    /// [`Bvh::any_in_scene_box`], find the lids), `contacts` each surface's [`contacts`].
    /// `groups` lists the patches of each of the document's surfaces (a mesh is one): a lid
    /// is measured by its whole surface ([`widths`]).
    pub(super) fn of_scene(
        bvh: &Bvh,
        contacts: &[Vec<[[f64; 2]; 2]>],
        groups: &[Vec<u32>],
        rules: &Rules,
        res: impl Fn(usize) -> usize + Sync,
    ) -> Vec<Option<Mask>> {
        let quads = bvh.quads();
        let lidded = lids(bvh, &widths(quads, groups), rules.lid_gap);
        (0..quads.len())
            .into_par_iter()
            .map(|i| {
                (lidded[i] || !contacts[i].is_empty())
                    .then(|| Mask::probe(quads, bvh, i, res(i), rules.sending_share))
                    .filter(|m| m.cells.iter().any(|c| *c != Cell::Open))
            })
            .collect()
    }

    fn probe(
        quads: &[Parallelogram],
        bvh: &Bvh,
        surface: usize,
        res: usize,
        sending_share: f64,
    ) -> Mask {
        let covered = |s: f64, t: f64| covered_at(quads, bvh, surface, s, t);
        let h = 1.0 / res as f64;
        let corners: Vec<bool> = (0..(res + 1) * (res + 1))
            .into_par_iter()
            .map(|i| covered((i % (res + 1)) as f64 * h, (i / (res + 1)) as f64 * h))
            .collect();
        let centres: Vec<bool> = (0..res * res)
            .into_par_iter()
            .map(|i| covered(((i % res) as f64 + 0.5) * h, ((i / res) as f64 + 0.5) * h))
            .collect();
        let mixed = |cs: usize, ct: usize| {
            let c = centres[ct * res + cs];
            [(0, 0), (1, 0), (0, 1), (1, 1)]
                .iter()
                .any(|&(a, b)| corners[(ct + b) * (res + 1) + cs + a] != c)
        };
        // the cells the outline crosses, and their neighbours (an outline may clip a cell
        // between its probes)
        let mut resolve = vec![false; res * res];
        for ct in 0..res {
            for cs in 0..res {
                if mixed(cs, ct) {
                    for dt in ct.saturating_sub(1)..(ct + 2).min(res) {
                        for ds in cs.saturating_sub(1)..(cs + 2).min(res) {
                            resolve[dt * res + ds] = true;
                        }
                    }
                }
            }
        }
        let cells = (0..res * res)
            .into_par_iter()
            .map(|i| {
                let (cs, ct) = (i % res, i / res);
                if !resolve[i] {
                    return if centres[i] {
                        Cell::Covered
                    } else {
                        Cell::Open
                    };
                }
                let mut bits = [0u64; SUB * SUB / 64];
                let mut n = 0;
                for j in 0..SUB {
                    for k in 0..SUB {
                        let s = (cs as f64 + (k as f64 + 0.5) / SUB as f64) * h;
                        let t = (ct as f64 + (j as f64 + 0.5) / SUB as f64) * h;
                        if covered(s, t) {
                            let b = j * SUB + k;
                            bits[b / 64] |= 1 << (b % 64);
                            n += 1;
                        }
                    }
                }
                match n {
                    0 => Cell::Open,
                    n if n == SUB * SUB => Cell::Covered,
                    _ => Cell::Cut(Box::new(bits)),
                }
            })
            .collect();
        Mask {
            res,
            sending_share,
            cells,
        }
    }

    /// Whether the point (s, t) of the surface is covered (to the sub-cell grid).
    pub(super) fn covered(&self, s: f64, t: f64) -> bool {
        let r = self.res as f64;
        let (fs, ft) = ((s * r).clamp(0.0, r - 1e-9), (t * r).clamp(0.0, r - 1e-9));
        let (cs, ct) = (fs as usize, ft as usize);
        match &self.cells[ct * self.res + cs] {
            Cell::Open => false,
            Cell::Covered => true,
            Cell::Cut(bits) => {
                let i = (((fs - cs as f64) * SUB as f64) as usize).min(SUB - 1);
                let j = (((ft - ct as f64) * SUB as f64) as usize).min(SUB - 1);
                is_set(bits, j * SUB + i)
            }
        }
    }

    /// Whether the piece `[s0, s1] × [t0, t1]`, aligned to the grid of sub-cells ([`SUB`] per
    /// finest cell), is wholly covered (`Some(true)`), wholly exposed (`Some(false)`) or both.
    pub(super) fn coverage(&self, s: [f64; 2], t: [f64; 2]) -> Option<bool> {
        let n = (self.res * SUB) as f64;
        let idx = |x: f64| ((x * n).round() as usize).min(self.res * SUB);
        let (mut open, mut covered) = (false, false);
        for j in idx(t[0])..idx(t[1]) {
            for i in idx(s[0])..idx(s[1]) {
                let here = match &self.cells[(j / SUB) * self.res + i / SUB] {
                    Cell::Open => false,
                    Cell::Covered => true,
                    Cell::Cut(bits) => is_set(bits, (j % SUB) * SUB + i % SUB),
                };
                open |= !here;
                covered |= here;
                if open && covered {
                    return None;
                }
            }
        }
        Some(covered)
    }

    /// Whether every covered point of the piece `[s0, s1] × [t0, t1]` (aligned to the grid)
    /// of `surface` lies behind the plane of `source`, to within a sub-cell. The kernel from
    /// `source` vanishes there (cos θ < 0 at the source), so what `source` sends to the whole
    /// piece is what it sends to the exposed part: true for the faces of the solid that
    /// covers it, whose planes run along the outline.
    pub(super) fn covered_behind(
        &self,
        surface: &Parallelogram,
        s: [f64; 2],
        t: [f64; 2],
        source: &Parallelogram,
    ) -> bool {
        let r = self.res as f64;
        let idx = |x: f64| (x * r).round() as usize;
        let tol = surface.diameter() / (r * SUB as f64);
        let behind = |u: f64, v: f64| source.side(surface.at(u / r, v / r)) <= tol;
        let sub = 1.0 / SUB as f64;
        (idx(t[0])..idx(t[1])).all(|ct| {
            (idx(s[0])..idx(s[1])).all(|cs| {
                let (u, v) = (cs as f64, ct as f64);
                match &self.cells[ct * self.res + cs] {
                    Cell::Open => true,
                    Cell::Covered => [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0)]
                        .iter()
                        .all(|&(du, dv)| behind(u + du, v + dv)),
                    Cell::Cut(bits) => (0..SUB * SUB).all(|b| {
                        let (i, j) = ((b % SUB) as f64, (b / SUB) as f64);
                        !is_set(bits, b) || behind(u + (i + 0.5) * sub, v + (j + 0.5) * sub)
                    }),
                }
            })
        })
    }

    /// The exposure of the piece `[s0, s1] × [t0, t1]` (aligned to the grid) for tensor
    /// Legendre polynomials of `k` terms per direction.
    fn exposure(&self, s: [f64; 2], t: [f64; 2], k: usize) -> Exposure {
        let r = self.res as f64;
        let idx = |x: f64| (x * r).round() as usize;
        let (s0, s1, t0, t1) = (idx(s[0]), idx(s[1]), idx(t[0]), idx(t[1]));
        let (mut open, mut covered) = (0, 0);
        for ct in t0..t1 {
            for cs in s0..s1 {
                match self.cells[ct * self.res + cs] {
                    Cell::Open => open += 1,
                    Cell::Covered => covered += 1,
                    Cell::Cut(_) => {}
                }
            }
        }
        let total = (s1 - s0) * (t1 - t0);
        if open == total {
            return Exposure::Open;
        }
        if covered == total {
            return Exposure::Covered;
        }
        // ∫ χ φ_a φ_c over the piece's unit square: a sum of exact integrals over the open
        // cells and runs of open sub-cells, each a rectangle u × v of that square
        let kk = k * k;
        let mut steps: Vec<Vec<f64>> = vec![vec![0.0; kk * kk]; STEP * STEP];
        let (ws, wt) = ((s1 - s0) as f64, (t1 - t0) as f64);
        let mut add_rect = |u: [f64; 2], v: [f64; 2]| {
            let (u, v) = ([u[0] / ws, u[1] / ws], [v[0] / wt, v[1] / wt]);
            // the rectangle's part in each step cell it meets
            let clip = |x: [f64; 2], i: usize| {
                let (lo, hi) = (i as f64 / STEP as f64, (i + 1) as f64 / STEP as f64);
                let c = [x[0].max(lo), x[1].min(hi)];
                (c[1] - c[0] > 1e-15).then_some(c)
            };
            for j in 0..STEP {
                let Some(v) = clip(v, j) else { continue };
                let mt = interval_gram(v, k);
                for i in 0..STEP {
                    let Some(u) = clip(u, i) else { continue };
                    let ms = interval_gram(u, k);
                    let m = &mut steps[i + STEP * j];
                    for a in 0..kk {
                        for c in 0..kk {
                            m[a * kk + c] += mt[(a / k) * k + c / k] * ms[(a % k) * k + c % k];
                        }
                    }
                }
            }
        };
        let sub = 1.0 / SUB as f64;
        for ct in t0..t1 {
            for cs in s0..s1 {
                let (u0, v0) = ((cs - s0) as f64, (ct - t0) as f64);
                match &self.cells[ct * self.res + cs] {
                    Cell::Open => add_rect([u0, u0 + 1.0], [v0, v0 + 1.0]),
                    Cell::Covered => {}
                    Cell::Cut(bits) => {
                        for j in 0..SUB {
                            let open = |i: usize| !is_set(bits, j * SUB + i);
                            let mut i = 0;
                            while i < SUB {
                                if !open(i) {
                                    i += 1;
                                    continue;
                                }
                                let start = i;
                                while i < SUB && open(i) {
                                    i += 1;
                                }
                                add_rect(
                                    [u0 + start as f64 * sub, u0 + i as f64 * sub],
                                    [v0 + j as f64 * sub, v0 + (j + 1) as f64 * sub],
                                );
                            }
                        }
                    }
                }
            }
        }
        let mut gram = vec![0.0; kk * kk];
        for m in &steps {
            gram.iter_mut().zip(m).for_each(|(g, m)| *g += m);
        }
        // φ_0 = 1 on the unit square: G_00 is the exposed area
        if gram[0] <= 0.0 {
            return Exposure::Covered;
        }
        let (inverse, sending) = pseudo_inverse(&gram, kk, self.sending_share);
        Exposure::Partial(Box::new(Partial {
            inverse,
            sending,
            gram,
            steps,
        }))
    }
}

impl Mask {
    /// The exposure of `piece` of this mask's patch, in the basis of its elements: the
    /// triangle basis on a triangle patch (`tri`), tensor Legendre otherwise. Every element,
    /// the root included, takes its exposure from here: a triangle's measured by the tensor
    /// matrices of its (s, t) square, half of which lies outside it, came out half covered.
    pub(super) fn exposure_of(&self, piece: &Piece, tri: bool, k: usize) -> Exposure {
        if tri {
            self.exposure_triangle(piece, k)
        } else {
            self.exposure(piece.s, piece.t, k)
        }
    }

    /// The exposure of a triangle piece of a triangle patch ([`Piece`]: half of a square
    /// aligned to the grid) for the orthonormal polynomials of order `k − 1` on it
    /// ([`TriangleBasis`]), in `k² × k²` matrices whose first (m+1)(m+2)/2 rows and columns
    /// are used. The piece is the union of halves of finest cells, each open, covered or cut;
    /// a cut half is the union of halves of its sub-cells (each half of a sub-cell lies in one
    /// half of the cell). G = (1 / area(T̂)) ∫ χ φ_a φ_c, exact on every open part by a triangle
    /// rule of degree 2m, so that G = I on an open piece.
    fn exposure_triangle(&self, piece: &Piece, k: usize) -> Exposure {
        let r = self.res as f64;
        let idx = |x: f64| (x * r).round() as usize;
        let (s0, t0) = (idx(piece.s[0]), idx(piece.t[0]));
        let n = idx(piece.s[1]) - s0;
        // the halves of finest cells in the piece: (cell s, cell t, upper half)
        let halves: Vec<(usize, usize, bool)> = crate::math::triangle::cell_halves(n, piece.upper)
            .map(|(i, j, upper)| (s0 + i, t0 + j, upper))
            .collect();
        let state = |h: &(usize, usize, bool)| &self.cells[h.1 * self.res + h.0];
        if halves.iter().all(|h| *state(h) == Cell::Open) {
            return Exposure::Open;
        }
        if halves.iter().all(|h| *state(h) == Cell::Covered) {
            return Exposure::Covered;
        }
        let basis = TriangleBasis::of_order(k - 1);
        let nb = crate::math::triangle::dimension(k - 1);
        let rule = TriangleRule::for_degree(2 * (k - 1));
        let kk = k * k;
        let mut gram = vec![0.0; kk * kk];
        let h = 1.0 / r;
        let mut phi = vec![0.0; nb];
        // adds the open triangle with corner (s, t) and legs ±w (upper: the half turned)
        let mut add = |s: f64, t: f64, w: f64, upper: bool| {
            // its share of the piece's reference triangle: (w / size)², of area ½ each
            let size = piece.s[1] - piece.s[0];
            let share = (w / size).powi(2);
            for (x, wt) in rule.points.iter().zip(&rule.weights) {
                let (ps, pt) = if upper {
                    (s - x[0] * w, t - x[1] * w)
                } else {
                    (s + x[0] * w, t + x[1] * w)
                };
                let (u, v) = piece.local(ps, pt);
                basis.eval(u, v, &mut phi);
                for a in 0..nb {
                    for c in 0..nb {
                        gram[a * kk + c] += share * wt * phi[a] * phi[c];
                    }
                }
            }
        };
        let sub = h / SUB as f64;
        for cell in &halves {
            let (cs, ct, upper) = *cell;
            let (x0, y0) = (cs as f64 * h, ct as f64 * h);
            match state(cell) {
                Cell::Open if upper => add(x0 + h, y0 + h, h, true),
                Cell::Open => add(x0, y0, h, false),
                Cell::Covered => {}
                Cell::Cut(bits) => {
                    for j in 0..SUB {
                        for i in 0..SUB {
                            if is_set(bits, j * SUB + i) {
                                continue;
                            }
                            let (x, y) = (x0 + i as f64 * sub, y0 + j as f64 * sub);
                            // the sub-cell's lower half lies in the cell's lower half when
                            // i + j + 1 ≤ SUB, its upper half when i + j + 2 ≤ SUB
                            if (i + j < SUB) != upper {
                                add(x, y, sub, false);
                            }
                            if (i + j + 2 <= SUB) != upper {
                                add(x + sub, y + sub, sub, true);
                            }
                        }
                    }
                }
            }
        }
        // φ_0 = 1: G_00 is the exposed share of the area
        if gram[0] <= 1e-12 {
            return Exposure::Covered;
        }
        let (inverse, sending) = pseudo_inverse(&gram, kk, self.sending_share);
        Exposure::Partial(Box::new(Partial {
            inverse,
            sending,
            gram,
            // no masked Gram matrices of a triangle's step cells: a partly covered triangle
            // takes a link's whole visible fraction ([`crate::three_d::visibility::Seen`])
            steps: Vec::new(),
        }))
    }
}

fn is_set(bits: &[u64; SUB * SUB / 64], b: usize) -> bool {
    bits[b / 64] >> (b % 64) & 1 == 1
}

/// The pseudo-inverse of a symmetric positive semi-definite `n × n` matrix.
fn pseudo_inverse(g: &[f64], n: usize, sending_share: f64) -> (Vec<f64>, Vec<f64>) {
    let eig = nalgebra::SymmetricEigen::new(nalgebra::DMatrix::from_row_slice(n, n, g));
    let top = eig.eigenvalues.iter().copied().fold(0.0, f64::max);
    let mut out = vec![0.0; n * n];
    let mut sending = vec![0.0; n * n];
    let send = sending_cutoff((n as f64).sqrt().round() as usize, sending_share);
    for (l, v) in eig.eigenvalues.iter().zip(eig.eigenvectors.column_iter()) {
        if *l <= CUTOFF * top {
            continue;
        }
        for a in 0..n {
            for c in 0..n {
                out[a * n + c] += v[a] * v[c] / l;
                if *l > send * top {
                    sending[a * n + c] += v[a] * v[c];
                }
            }
        }
    }
    (out, sending)
}

/// [`contacts`] of every surface of the scene, a box query each (0.24 s of 10⁵ triangles on
/// one thread).
pub(super) fn scene_contacts(all: &Bvh) -> Vec<Vec<[[f64; 2]; 2]>> {
    (0..all.quads().len())
        .into_par_iter()
        .map(|i| contacts(all, i))
        .collect()
}

/// The lines where other surfaces stand on surface `i`: the part inside i of each edge of
/// another surface that lies in i's plane, unless that part runs along i's own edges, as its
/// two ends' (s, t). Across such a line the radiosity of i may jump: the surface standing
/// there hides half of the hemisphere from the points next to it, and may shade one side of
/// it. The part inside i, not the whole edge: a box's foot on a meshed floor crosses many of
/// the floor's triangles, and each of them must know it is stood on (with only the triangle
/// that held the edge's midpoint, the box's faces next to the foot came out 0.2 % dark in a
/// furnace, where every face has B = E / (1 − ρ)).
///
/// `all` answers box queries over every surface of the scene ([`Bvh::any_in_scene_box`]);
/// only those whose box meets i's are looked at (such an edge passes through i).
pub(super) fn contacts(all: &Bvh, i: usize) -> Vec<[[f64; 2]; 2]> {
    let quads = all.quads();
    let q = &quads[i];
    let tol = 1e-9 * q.diameter();
    let mut lines = Vec::new();
    let (lo, hi) = padded_box(q, tol);
    let mut near = Vec::new();
    all.any_in_scene_box(lo, hi, |j| {
        near.push(j);
        false
    });
    // in the order of the surfaces, as the scan of all of them had it
    near.sort_unstable();
    for j in near {
        if j == i {
            continue;
        }
        let o = &quads[j];
        let c = o.outline();
        for e in 0..4 {
            let (a, b) = (c[e], c[(e + 1) % 4]);
            if a == b {
                continue;
            }
            if q.side(a).abs() < tol && q.side(b).abs() < tol {
                let (pa, pb) = (q.params(a), q.params(b));
                lines.extend(clip_inside([pa.0, pa.1], [pb.0, pb.1], q.tri));
            }
        }
    }
    lines
}

/// The part of the segment from `a` to `b` (in a patch's (s, t)) inside the patch: the unit
/// square, or its half s + t ≤ 1 for a `tri`angle (Liang–Barsky clipping); `None` when that
/// part is a point, or its midpoint lies on the patch's edges (a surface meeting the patch
/// only along its border does not stand on it).
fn clip_inside(a: [f64; 2], b: [f64; 2], tri: bool) -> Option<[[f64; 2]; 2]> {
    let d = [b[0] - a[0], b[1] - a[1]];
    // each side as p λ ≤ q along the segment a + λ d
    let sides = [
        (-d[0], a[0]),
        (d[0], 1.0 - a[0]),
        (-d[1], a[1]),
        (d[1], 1.0 - a[1]),
    ]
    .into_iter()
    .chain(tri.then_some((d[0] + d[1], 1.0 - a[0] - a[1])));
    let (lo, hi) = clip(sides).filter(|(lo, hi)| lo < hi)?;
    // (the ends themselves when inside: an edge wholly within the patch is kept as it is)
    let at = |l: f64| match l {
        0.0 => a,
        1.0 => b,
        _ => [a[0] + l * d[0], a[1] + l * d[1]],
    };
    let m = at(0.5 * (lo + hi));
    let inside = |x: f64| (1e-6..1.0 - 1e-6).contains(&x);
    (inside(m[0]) && inside(m[1]) && (!tri || m[0] + m[1] < 1.0 - 1e-6)).then(|| [at(lo), at(hi)])
}

/// For each patch i, whether another surface lies flat against it, facing the same way,
/// closer to it than `gap` ([`Rules::lid_gap`]) of its own width ([`widths`]), over part of
/// it: a ceiling light hung a little below the ceiling, a rug on a floor. The ceiling behind the light sees
/// only the light's back through a sliver at grazing angles, so it is dark up to the light's
/// outline, where one polynomial over both sides would smear it (on the Cornell box without
/// its blocks, the light 1 unit below the ceiling: the four cells above it 40 % bright, those
/// around it 8 % dark). Worse, the smeared element sends light from a polynomial darkened by
/// its dark part through a visible fraction lowered by the same part: the light is taken out
/// twice (a rug of 260 triangles 5 mm above a room's floor left the room 1–2 % dark).
///
/// Over part of it: a corner of the lid over i, or a corner of i under the lid (a triangle of
/// a meshed ceiling wholly under a light holds none of the light's corners).
///
/// `all` answers box queries over every surface ([`Bvh::any_in_scene_box`]). Each lid j is
/// looked for over the patches within `gap` of its own width of its box; looking around each patch i instead, as far as the
/// widest surface's gap (a wall's, 0.2 units in a 10-unit room), held thousands of others
/// around each of 10⁶ small triangles: 85 % of such a job's first minutes, on one core.
fn lids(all: &Bvh, widths: &[f64], gap: f64) -> Vec<bool> {
    let quads = all.quads();
    let under: Vec<Vec<u32>> = (0..quads.len())
        .into_par_iter()
        .map(|j| {
            let (lo, hi) = padded_box(&quads[j], gap * widths[j]);
            let mut under = Vec::new();
            all.any_in_scene_box(lo, hi, |i| {
                if lies_over(quads, j, i, widths, gap) {
                    under.push(i as u32);
                }
                false
            });
            under
        })
        .collect();
    let mut lidded = vec![false; quads.len()];
    under
        .iter()
        .flatten()
        .for_each(|&i| lidded[i as usize] = true);
    lidded
}

/// [`lids`] of one patch, looked for around it as far as the widest surface's gap: the
/// direct form, which the tests hold [`lids`] to.
#[cfg(test)]
fn lidded(all: &Bvh, i: usize, widths: &[f64]) -> bool {
    let gap = Rules::DEFAULT.lid_gap;
    let quads = all.quads();
    let widest = widths.iter().copied().fold(0.0, f64::max);
    let (lo, hi) = padded_box(&quads[i], gap * widest);
    all.any_in_scene_box(lo, hi, |j| lies_over(quads, j, i, widths, gap))
}

/// Whether patch `j` lies flat over patch `i` as a lid: facing the same way, in front of it by
/// less than `gap` of j's surface's width, over part of it.
fn lies_over(quads: &[Parallelogram], j: usize, i: usize, widths: &[f64], gap: f64) -> bool {
    let (q, o) = (&quads[i], &quads[j]);
    let side = q.side(o.p0);
    j != i
        && dot(q.n, o.n) > 1.0 - 1e-9
        && side > 0.0
        && side < gap * widths[j]
        && (o.outline().iter().any(|&c| inside(q, c)) || q.outline().iter().any(|&c| inside(o, c)))
}

/// The width of each patch's document surface (`groups` lists each surface's patches): the
/// smaller side of the rectangle with the surface's second moments of area, √(12 λ₂) with
/// λ₂ the middle eigenvalue of the covariance of a point uniform on the surface. That is the
/// smaller side of a rectangle, and of a rectangle made of any number of triangles: a lid
/// made of small triangles hides what is under it as the one rectangle would.
fn widths(quads: &[Parallelogram], groups: &[Vec<u32>]) -> Vec<f64> {
    use nalgebra::{Matrix3, Vector3};
    let matrix = |m: Sym| Matrix3::new(m[0], m[3], m[4], m[3], m[1], m[5], m[4], m[5], m[2]);
    let mut out = vec![0.0; quads.len()];
    for g in groups {
        // the area, first and second moments of the surface, patch by patch
        let (mut area, mut first, mut second) = (0.0, Vector3::zeros(), Matrix3::zeros());
        for &p in g {
            let q = &quads[p as usize];
            let c = Piece::whole(p as usize).corners(quads);
            let n = if q.tri { 3 } else { 4 };
            let centre = c[..n]
                .iter()
                .map(|&v| Vector3::from(v))
                .sum::<Vector3<f64>>()
                / n as f64;
            area += q.area;
            first += q.area * centre;
            second += q.area * (matrix(covariance(&c, q.tri)) + centre * centre.transpose());
        }
        let mean = first / area;
        let cov = second / area - mean * mean.transpose();
        let mut l = cov.symmetric_eigenvalues();
        l.as_mut_slice().sort_by(|a, b| b.total_cmp(a));
        let width = (12.0 * l[1].max(0.0)).sqrt();
        for &p in g {
            out[p as usize] = width;
        }
    }
    out
}

/// Whether the projection of `c` along `q`'s normal falls inside `q` (its triangle, for a
/// triangle patch).
fn inside(q: &Parallelogram, c: V3) -> bool {
    let (s, t) = q.params(c);
    (0.0..=1.0).contains(&s) && (0.0..=1.0).contains(&t) && (!q.tri || s + t <= 1.0)
}

/// The bounding box of `q`, `pad` wider on every side.
fn padded_box(q: &Parallelogram, pad: f64) -> (V3, V3) {
    let (mut lo, mut hi) = (q.p0, q.p0);
    for c in q.outline() {
        for a in 0..3 {
            lo[a] = lo[a].min(c[a] - pad);
            hi[a] = hi[a].max(c[a] + pad);
        }
    }
    (lo, hi)
}

/// How far outside a piece, in its surface's (s, t), a contact line still touches it.
const MEET_SLACK: f64 = 1e-9;

/// Whether the segment `line` of (s, t) meets the closed piece `[s0, s1] × [t0, t1]`
/// (Liang–Barsky clipping), widened by [`MEET_SLACK`]: a line along the border of two pieces,
/// whose ends are rounded, touches both.
pub(super) fn meets(line: &[[f64; 2]; 2], s: [f64; 2], t: [f64; 2]) -> bool {
    let [a, b] = *line;
    let d = [b[0] - a[0], b[1] - a[1]];
    let s = [s[0] - MEET_SLACK, s[1] + MEET_SLACK];
    let t = [t[0] - MEET_SLACK, t[1] + MEET_SLACK];
    let sides = [(0, s), (1, t)].into_iter().flat_map(|(axis, range)| {
        [
            (-d[axis], a[axis] - range[0]),
            (d[axis], range[1] - a[axis]),
        ]
    });
    clip(sides).is_some_and(|(lo, hi)| lo <= hi)
}

/// Liang–Barsky clipping of the segment λ ∈ [0, 1] by the `sides` p λ ≤ q: the range of λ
/// left, (lo, hi), empty when lo > hi; `None` when a side parallel to the segment (p = 0)
/// leaves it all out.
fn clip(sides: impl IntoIterator<Item = (f64, f64)>) -> Option<(f64, f64)> {
    let (mut lo, mut hi) = (0.0_f64, 1.0_f64);
    for (p, q) in sides {
        if p == 0.0 {
            if q < 0.0 {
                return None;
            }
        } else if p < 0.0 {
            lo = lo.max(q / p);
        } else {
            hi = hi.min(q / p);
        }
    }
    Some((lo, hi))
}

/// Whether the point (s, t) of surface `i` is covered: five rays over its hemisphere all
/// meet the back of a surface first.
pub(crate) fn covered_at(quads: &[Parallelogram], bvh: &Bvh, i: usize, s: f64, t: f64) -> bool {
    let q = &quads[i];
    let n = q.n;
    let a = normalize(q.e1);
    let b = cross(n, a);
    let x = add(q.at(s, t), scale(n, 1e-7 * q.diameter()));
    let dirs = [
        n,
        normalize(add(n, scale(a, 0.7))),
        normalize(add(n, scale(a, -0.7))),
        normalize(add(n, scale(b, 0.7))),
        normalize(add(n, scale(b, -0.7))),
    ];
    dirs.iter().all(|&d| {
        bvh.first_hit(x, d, 0.0, f64::INFINITY, [i, usize::MAX])
            .is_some_and(|h| dot(d, quads[h.surface].n) > 0.0)
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// On a triangle piece, the masked Gram matrix of the open piece is the identity (the
    /// basis is orthonormal), and G_00 is the exposed share of its area: the corner cell of a
    /// 2 × 2 grid covered leaves half the root triangle (its two halves are half of it);
    /// a cell cut along a column of sub-cells leaves the share those sub-cells make.
    #[test]
    fn masked_gram_matrices_of_triangle_pieces() {
        let root = Piece::whole(0);
        for k in 1..=3 {
            let n = crate::math::triangle::dimension(k - 1);
            let open = Mask {
                res: 2,
                sending_share: Rules::DEFAULT.sending_share,
                cells: vec![Cell::Open; 4],
            };
            assert_eq!(open.exposure_triangle(&root, k), Exposure::Open);
            let mut cells = vec![Cell::Open; 4];
            cells[0] = Cell::Covered;
            let corner = Mask {
                res: 2,
                sending_share: Rules::DEFAULT.sending_share,
                cells,
            };
            let Exposure::Partial(p) = corner.exposure_triangle(&root, k) else {
                panic!("partly covered")
            };
            assert!((p.fraction() - 0.5).abs() < 1e-12, "{}", p.fraction());
            // the open part is the three other quarter triangles: G restricted to them is
            // the sum of the children's H Hᵀ blocks, which the two-scale relation gives
            let basis = TriangleBasis::of_order(k - 1);
            let kk = k * k;
            for a in 0..n {
                let mut e = vec![[0.0; 1]; n];
                e[a][0] = 1.0;
                let mut want = vec![[0.0; 1]; n];
                for child in [1, 2] {
                    let mut c = vec![[0.0; 1]; n];
                    basis.push(&e, child, &mut c);
                    basis.pull(&c, child, &mut want);
                }
                for c in 0..n {
                    let got = p.gram[a * kk + c];
                    // the centre child (3) lies in the covered corner cell too
                    assert!(
                        (got - want[c][0]).abs() < 1e-12,
                        "k={k} G[{a}][{c}] = {got}"
                    );
                }
            }
            // a column of sub-cells of the corner cell open: its share of the root
            let mut bits = [u64::MAX; SUB * SUB / 64];
            for j in 0..SUB {
                let b = j * SUB;
                bits[b / 64] &= !(1 << (b % 64));
            }
            let mut cells = vec![Cell::Covered; 4];
            cells[0] = Cell::Cut(Box::new(bits));
            let cut = Mask {
                res: 2,
                sending_share: Rules::DEFAULT.sending_share,
                cells,
            };
            let Exposure::Partial(p) = cut.exposure_triangle(&root, k) else {
                panic!("partly covered")
            };
            // SUB sub-cells of (1/2SUB)² each, over the root's ½
            let share = SUB as f64 * (0.5 / SUB as f64).powi(2) / 0.5;
            assert!(
                (p.fraction() - share).abs() < 1e-12,
                "{} {share}",
                p.fraction()
            );
        }
    }

    /// A floor [0, 8]² with an axis-aligned box (five faces, no bottom, 1 high) on it.
    fn floor_with_box(lo: [f64; 2], hi: [f64; 2]) -> Vec<Parallelogram> {
        let (x0, x1, z0, z1, y) = (lo[0], hi[0], lo[1], hi[1], 1.0);
        let p = |c: [[f64; 3]; 4]| Parallelogram::new(&c);
        vec![
            // floor, normal +y: s along z, t along x
            p([
                [0.0, 0.0, 0.0],
                [0.0, 0.0, 8.0],
                [8.0, 0.0, 8.0],
                [8.0, 0.0, 0.0],
            ]),
            p([[x0, y, z0], [x0, y, z1], [x1, y, z1], [x1, y, z0]]),
            p([[x0, 0.0, z0], [x0, y, z0], [x1, y, z0], [x1, 0.0, z0]]),
            p([[x0, 0.0, z1], [x1, 0.0, z1], [x1, y, z1], [x0, y, z1]]),
            p([[x0, 0.0, z0], [x0, 0.0, z1], [x0, y, z1], [x0, y, z0]]),
            p([[x1, 0.0, z0], [x1, y, z0], [x1, y, z1], [x1, 0.0, z1]]),
        ]
    }

    #[test]
    fn the_foot_of_a_box_is_covered_and_nothing_else() {
        // the foot [2, 5] × [3, 4.5] (x × z) of an [0, 8]² floor
        let quads = floor_with_box([2.0, 3.0], [5.0, 4.5]);
        for q in &quads[1..] {
            let out = crate::three_d::geometry::sub(q.at(0.5, 0.5), [3.5, 0.5, 3.75]);
            assert!(dot(q.n, out) > 0.0, "the box's faces point out");
        }
        let masks = masks_alone(&quads);
        assert!(masks[1..].iter().all(Option::is_none));
        let m = masks[0].as_ref().expect("the floor is stood on");
        assert!(m.covered(3.5 / 8.0, 3.0 / 8.0));
        assert!(!m.covered(2.9 / 8.0, 3.0 / 8.0));
        assert!(!m.covered(3.5 / 8.0, 5.1 / 8.0));
        match m.exposure([0.0, 1.0], [0.0, 1.0], 1) {
            Exposure::Partial(p) => {
                assert!(
                    (p.fraction() - (1.0 - 4.5 / 64.0)).abs() < 1e-12,
                    "{}",
                    p.fraction()
                )
            }
            e => panic!("{e:?}"),
        }
        assert_eq!(m.exposure([0.375, 0.5], [0.25, 0.5], 2), Exposure::Covered);
        assert_eq!(m.exposure([0.0, 0.25], [0.0, 0.25], 2), Exposure::Open);
        // the same pieces' coverage, and down to one sub-cell either side of the outline
        // (s = 3 / 8 along z, a multiple of the sub-cells)
        assert_eq!(m.coverage([0.0, 1.0], [0.0, 1.0]), None);
        assert_eq!(m.coverage([0.375, 0.5], [0.25, 0.5]), Some(true));
        assert_eq!(m.coverage([0.0, 0.25], [0.0, 0.25]), Some(false));
        let sub = 1.0 / (m.res * SUB) as f64;
        assert_eq!(
            m.coverage([0.375 - sub, 0.375], [0.5, 0.5 + sub]),
            Some(false)
        );
        assert_eq!(
            m.coverage([0.375, 0.375 + sub], [0.5, 0.5 + sub]),
            Some(true)
        );
        assert_eq!(
            m.coverage([0.375 - sub, 0.375 + sub], [0.5, 0.5 + sub]),
            None
        );
    }

    #[test]
    fn the_lines_where_a_box_stands_are_its_feet() {
        // the foot [2, 5] × [3, 4.5] (x × z); the floor's s runs along z and t along x
        let quads = floor_with_box([2.0, 3.0], [5.0, 4.5]);
        let lines = contacts(&Bvh::new(&quads), 0);
        assert_eq!(lines.len(), 4, "{lines:?}");
        // four different edges
        for (i, a) in lines.iter().enumerate() {
            for b in &lines[i + 1..] {
                let same =
                    |p: [f64; 2], q: [f64; 2]| (p[0] - q[0]).abs() + (p[1] - q[1]).abs() < 1e-12;
                assert!(
                    !(same(a[0], b[0]) && same(a[1], b[1]) || same(a[0], b[1]) && same(a[1], b[0])),
                    "{a:?} twice"
                );
            }
        }
        let (s0, s1, t0, t1) = (3.0 / 8.0, 4.5 / 8.0, 2.0 / 8.0, 5.0 / 8.0);
        for [a, b] in &lines {
            for p in [a, b] {
                let on_s = (p[0] - s0).abs() < 1e-12 || (p[0] - s1).abs() < 1e-12;
                let on_t = (p[1] - t0).abs() < 1e-12 || (p[1] - t1).abs() < 1e-12;
                assert!(on_s && on_t, "{p:?} is a corner of the foot");
            }
        }
        // no face stands on another, nor on the top
        assert!((1..quads.len()).all(|i| contacts(&Bvh::new(&quads), i).is_empty()));
        // a piece touches a line when the line crosses it, runs along its edge or ends in it
        let line = [[0.25, 0.25], [0.75, 0.5]];
        assert!(meets(&line, [0.0, 0.5], [0.0, 0.5]));
        assert!(meets(&line, [0.7, 0.8], [0.4, 0.6]));
        assert!(!meets(&line, [0.0, 0.2], [0.0, 1.0]));
        assert!(!meets(&line, [0.5, 1.0], [0.0, 0.3]));
        assert!(meets(&[[0.5, 0.0], [0.5, 1.0]], [0.0, 0.5], [0.2, 0.3]));
        assert!(meets(&[[0.5, 0.0], [0.5, 1.0]], [0.5, 1.0], [0.2, 0.3]));
        assert!(!meets(&[[0.5, 0.0], [0.5, 1.0]], [0.6, 1.0], [0.2, 0.3]));
        // a line along a border, its ends rounded a little to one side, touches both pieces
        let border = [[0.5 - 1e-15, 0.0], [0.5 - 1e-15, 1.0]];
        assert!(meets(&border, [0.5, 1.0], [0.2, 0.3]) && meets(&border, [0.0, 0.5], [0.2, 0.3]));
    }

    #[test]
    fn a_panel_hung_just_below_a_ceiling_covers_it() {
        // a ceiling [0, 8]² at y = 4 facing down, and a panel [3, 5]² facing down at `gap`
        // below it
        let ceiling = |gap: f64| {
            let p = |c: [[f64; 3]; 4]| Parallelogram::new(&c);
            let y = 4.0 - gap;
            vec![
                p([
                    [0.0, 4.0, 0.0],
                    [8.0, 4.0, 0.0],
                    [8.0, 4.0, 8.0],
                    [0.0, 4.0, 8.0],
                ]),
                p([[3.0, y, 3.0], [5.0, y, 3.0], [5.0, y, 5.0], [3.0, y, 5.0]]),
            ]
        };
        let lidded = |all: &Bvh, i| lidded(all, i, &widths(all.quads(), &each_alone(2)));
        let quads = ceiling(0.01);
        assert!(quads[0].n[1] < 0.0 && quads[1].n[1] < 0.0, "both face down");
        assert!(lidded(&Bvh::new(&quads), 0) && !lidded(&Bvh::new(&quads), 1));
        let m = masks_alone(&quads).remove(0).expect("covered");
        // the ceiling's s runs along x and t along z: the panel is [0.375, 0.625]²
        assert!(m.covered(0.5, 0.5) && m.covered(0.4, 0.6));
        assert!(!m.covered(0.3, 0.5) && !m.covered(0.5, 0.7) && !m.covered(0.1, 0.1));
        // a panel further than 2 % of its side, or facing the other way, is no lid
        assert!(!lidded(&Bvh::new(&ceiling(0.05)), 0));
        let mut flipped = ceiling(0.01);
        flipped[1] = Parallelogram::new(&[
            [3.0, 3.99, 3.0],
            [3.0, 3.99, 5.0],
            [5.0, 3.99, 5.0],
            [5.0, 3.99, 3.0],
        ]);
        assert!(flipped[1].n[1] > 0.0);
        assert!(!lidded(&Bvh::new(&flipped), 0));
    }

    /// Each patch its own surface.
    fn each_alone(n: usize) -> Vec<Vec<u32>> {
        (0..n as u32).map(|p| vec![p]).collect()
    }

    /// The masks of `quads`, each patch a surface of its own, on an 8 × 8 grid, by the
    /// default rules.
    fn masks_alone(quads: &[Parallelogram]) -> Vec<Option<Mask>> {
        let bvh = Bvh::occluders(quads);
        let contacts = scene_contacts(&bvh);
        let groups = each_alone(quads.len());
        Mask::of_scene(&bvh, &contacts, &groups, &Rules::DEFAULT, |_| 8)
    }

    /// A `w × h` grid over parallelogram `c`, two triangles a cell, facing as `c` does.
    fn triangles(c: [V3; 4], w: usize, h: usize) -> Vec<Parallelogram> {
        let at = |i: usize, j: usize| {
            let (s, t) = (i as f64 / w as f64, j as f64 / h as f64);
            [0, 1, 2].map(|k| c[0][k] + s * (c[1][k] - c[0][k]) + t * (c[3][k] - c[0][k]))
        };
        let tri = |a: V3, b: V3, c: V3| {
            let far = add(b, crate::three_d::geometry::sub(c, a));
            let mut p = Parallelogram::new(&[a, b, far, c]);
            p.tri = true;
            p.area = 0.5 * p.jac;
            p
        };
        let mut out = Vec::new();
        for j in 0..h {
            for i in 0..w {
                out.push(tri(at(i, j), at(i + 1, j), at(i + 1, j + 1)));
                out.push(tri(at(i, j), at(i + 1, j + 1), at(i, j + 1)));
            }
        }
        out
    }

    #[test]
    fn a_surface_is_as_wide_as_the_smaller_side_of_its_rectangle() {
        let c = [
            [0.0, 0.0, 0.0],
            [2.6, 0.0, 0.0],
            [2.6, 1.0, 1.0],
            [0.0, 1.0, 1.0],
        ];
        let whole = widths(&[Parallelogram::new(&c)], &each_alone(1));
        assert!((whole[0] - 2f64.sqrt()).abs() < 1e-12, "{whole:?}");
        for (w, h) in [(1, 1), (13, 10), (3, 17)] {
            let parts = triangles(c, w, h);
            let one: Vec<u32> = (0..parts.len() as u32).collect();
            let got = widths(&parts, &[one]);
            assert!(
                got.iter().all(|x| (x - 2f64.sqrt()).abs() < 1e-12),
                "{got:?}"
            );
        }
    }

    #[test]
    fn a_foot_across_a_meshed_floor_stands_on_every_triangle_it_crosses() {
        // the floor [0, 8]² as 8 × 8 cells of triangles, the box's foot [2.5, 5.5] × [3.5, 4.5]
        // (x × z): its outline runs through the middle of cells
        let with_box = floor_with_box([2.5, 3.5], [5.5, 4.5]);
        let mut quads = triangles(
            [
                [0.0, 0.0, 0.0],
                [0.0, 0.0, 8.0],
                [8.0, 0.0, 8.0],
                [8.0, 0.0, 0.0],
            ],
            8,
            8,
        );
        let floor = quads.len();
        quads.extend_from_slice(&with_box[1..]);
        let all = Bvh::new(&quads);
        let (mut crossed, mut stood_on) = (0, 0);
        for (i, q) in quads[..floor].iter().enumerate() {
            // whether the outline passes through the triangle's inside: some of its points
            // on either side of the foot's edge, on the edge's stretch
            let pts: Vec<V3> = (0..=20)
                .flat_map(|a| (0..=20 - a).map(move |b| (a as f64 / 20.0, b as f64 / 20.0)))
                .map(|(s, t)| q.at(s, t))
                .collect();
            let within = |x: f64, lo: f64, hi: f64| x > lo + 1e-9 && x < hi - 1e-9;
            let across = |axis: usize, at: f64, other: usize, lo: f64, hi: f64| {
                let near: Vec<&V3> = pts.iter().filter(|p| within(p[other], lo, hi)).collect();
                near.iter().any(|p| p[axis] < at - 1e-9) && near.iter().any(|p| p[axis] > at + 1e-9)
            };
            let crosses = across(2, 3.5, 0, 2.5, 5.5)
                || across(2, 4.5, 0, 2.5, 5.5)
                || across(0, 2.5, 2, 3.5, 4.5)
                || across(0, 5.5, 2, 3.5, 4.5);
            let lines = contacts(&all, i);
            crossed += usize::from(crosses);
            stood_on += usize::from(!lines.is_empty());
            assert_eq!(!lines.is_empty(), crosses, "triangle {i}: {lines:?}");
            for [a, b] in &lines {
                for p in [a, b] {
                    assert!(p[0] >= 0.0 && p[1] >= 0.0 && p[0] + p[1] <= 1.0 + 1e-12);
                }
            }
        }
        // before, only the triangles that held an edge's midpoint: at most 4
        assert_eq!(crossed, stood_on);
        assert!(stood_on > 4, "{stood_on}");
    }

    #[test]
    fn a_lid_of_many_triangles_covers_as_one_rectangle_does() {
        // a floor [0, 8]² facing up, and a rug [3, 5]² of 8 × 8 cells of triangles 1 cm above
        // it: 2 % of a triangle's side is 5 mm, of the rug's 4 cm
        let mut quads = vec![Parallelogram::new(&[
            [0.0, 0.0, 0.0],
            [0.0, 0.0, 8.0],
            [8.0, 0.0, 8.0],
            [8.0, 0.0, 0.0],
        ])];
        let y = 0.01;
        quads.extend(triangles(
            [[3.0, y, 3.0], [3.0, y, 5.0], [5.0, y, 5.0], [5.0, y, 3.0]],
            8,
            8,
        ));
        assert!(quads.iter().all(|q| q.n[1] > 0.0), "all face up");
        let rug: Vec<u32> = (1..quads.len() as u32).collect();
        let groups = [vec![0], rug];
        let all = Bvh::new(&quads);
        assert!(lidded(&all, 0, &widths(&quads, &groups)));
        assert!(!lidded(&all, 0, &widths(&quads, &each_alone(quads.len()))));
        // from the side of the lids, the same for every patch: the floor under the rug, and
        // no triangle of the rug
        for g in [&groups[..], &each_alone(quads.len())] {
            let w = widths(&quads, g);
            let direct: Vec<bool> = (0..quads.len()).map(|i| lidded(&all, i, &w)).collect();
            assert_eq!(lids(&all, &w, Rules::DEFAULT.lid_gap), direct);
        }
        let bvh = Bvh::occluders(&quads);
        let contacts = scene_contacts(&bvh);
        let m = Mask::of_scene(&bvh, &contacts, &groups, &Rules::DEFAULT, |_| 8)
            .remove(0)
            .expect("the floor under the rug is covered");
        // the floor's s runs along z and t along x: the rug is [0.375, 0.625]²
        assert!(m.covered(0.5, 0.5) && m.covered(0.45, 0.55));
        assert!(!m.covered(0.3, 0.5) && !m.covered(0.5, 0.7));
    }

    #[test]
    fn masked_grams_are_the_integrals_over_the_exposed_part() {
        // the foot's edge z = 4.5 halves the finest cell z ∈ [4, 5], x ∈ [3, 4]
        let quads = floor_with_box([2.0, 3.0], [5.0, 4.5]);
        let m = masks_alone(&quads).remove(0).expect("mask");
        for k in 1..=4 {
            let Exposure::Partial(p) = m.exposure([0.5, 0.625], [0.375, 0.5], k) else {
                panic!("cut")
            };
            // covered for s < ½ of the cell: G = (∫_½¹ φ_p φ_q ds) ⊗ I
            let half = interval_gram([0.5, 1.0], k);
            let kk = k * k;
            for a in 0..kk {
                for c in 0..kk {
                    let same_t = f64::from(u8::from(a / k == c / k));
                    let want = half[(a % k) * k + c % k] * same_t;
                    assert!((p.gram[a * kk + c] - want).abs() < 1e-13, "k={k}");
                }
            }
            assert!((p.fraction() - 0.5).abs() < 1e-14);
            // the step cells: nothing on the covered half, the plain Gram matrices of the
            // cells on the exposed one
            let plain = crate::three_d::steps::Steps::new(k);
            for (c, (masked, plain)) in p.steps.iter().zip(&plain.m).enumerate() {
                let exposed = c % STEP >= STEP / 2;
                for (g, w) in masked.iter().zip(plain) {
                    let want = if exposed { *w } else { 0.0 };
                    assert!((g - want).abs() < 1e-14, "k={k}, cell {c}");
                }
            }
            // a polynomial on the exposed half is recovered from its masked moments: exactly
            // while G is well conditioned (k ≤ 3), else up to what the pseudo-inverse leaves
            // out, whose norm on the exposed part is below √CUTOFF of the whole
            let poly: Vec<[f64; 3]> = (0..kk).map(|i| [1.0 - 0.3 * i as f64; 3]).collect();
            let mut moments = vec![[0.0; 3]; kk];
            let mut back = vec![[0.0; 3]; kk];
            Partial::apply(&p.gram, &poly, &mut moments);
            Partial::apply(&p.inverse, &moments, &mut back);
            let diff: Vec<[f64; 3]> = back
                .iter()
                .zip(&poly)
                .map(|(a, b)| [a[0] - b[0]; 3])
                .collect();
            if k <= 3 {
                assert!(diff.iter().all(|d| d[0].abs() < 1e-9), "k={k}: {diff:?}");
            }
            let mut g_diff = vec![[0.0; 3]; kk];
            Partial::apply(&p.gram, &diff, &mut g_diff);
            let on_exposed: f64 = diff.iter().zip(&g_diff).map(|(a, b)| a[0] * b[0]).sum();
            let norm: f64 = poly.iter().map(|v| v[0] * v[0]).sum();
            assert!(on_exposed.sqrt() < CUTOFF.sqrt() * norm.sqrt(), "k={k}");
        }
    }

    /// A partly covered element sends its polynomial where its exposed part determines it,
    /// and all of it where that part does: on the foot's edge at z = 4.5, a cell half covered,
    /// `sending` is the identity at orders 0–2; at z = 4.9 the cell z ∈ [4, 5] is exposed on a
    /// sliver of an eighth (two of its [`SUB`] rows), whose masked Gram matrix at order 1 has
    /// an eigenvalue of 1.4e-3 of the largest, which the fit B = G⁺ h keeps (above
    /// [`CUTOFF`]) and sending leaves out. Whatever is sent is then no larger over the whole
    /// element than [`sending_cutoff`]^(−½) = 17 times its size on the exposed part, where
    /// that eigenvector alone was 26 times.
    #[test]
    fn a_sliver_sends_what_its_exposed_part_determines() {
        let exposure = |edge: f64, k: usize| {
            let quads = floor_with_box([2.0, 3.0], [5.0, edge]);
            let m = masks_alone(&quads).remove(0).expect("mask");
            match m.exposure([0.5, 0.625], [0.375, 0.5], k) {
                Exposure::Partial(p) => p,
                other => panic!("{other:?}"),
            }
        };
        for k in 1..=3 {
            let p = exposure(4.5, k);
            let kk = k * k;
            for a in 0..kk {
                for c in 0..kk {
                    let want = f64::from(u8::from(a == c));
                    assert!((p.sending[a * kk + c] - want).abs() < 1e-12, "k={k}");
                }
            }
        }
        let p = exposure(4.9, 2);
        assert!((p.fraction() - 0.125).abs() < 1e-12, "{}", p.fraction());
        let eig = nalgebra::SymmetricEigen::new(nalgebra::DMatrix::from_row_slice(4, 4, &p.gram));
        let top = eig.eigenvalues.max();
        let (low, v) = eig
            .eigenvalues
            .iter()
            .zip(eig.eigenvectors.column_iter())
            .min_by(|a, b| a.0.total_cmp(b.0))
            .expect("eigenvalues");
        let send = sending_cutoff(2, Rules::DEFAULT.sending_share);
        assert!((send - 3.59e-3).abs() < 1e-5, "{send}");
        assert!(low / top > CUTOFF && low / top < send, "{}", low / top);
        let on_exposed = |b: &[[f64; 3]]| {
            let mut g = vec![[0.0; 3]; 4];
            Partial::apply(&p.gram, b, &mut g);
            b.iter()
                .zip(&g)
                .map(|(x, y)| x[0] * y[0])
                .sum::<f64>()
                .sqrt()
        };
        let whole = |b: &[[f64; 3]]| b.iter().map(|x| x[0] * x[0]).sum::<f64>().sqrt();
        let mode: Vec<[f64; 3]> = v.iter().map(|&x| [x; 3]).collect();
        assert!(whole(&mode) > 25.0 * on_exposed(&mode));
        let mut sent = vec![[0.0; 3]; 4];
        Partial::apply(&p.sending, &mode, &mut sent);
        assert!(whole(&sent) < 1e-12, "{sent:?}");
        for seed in 0..20u64 {
            let mut rng = crate::three_d::visibility::SplitMix(seed);
            let b: Vec<[f64; 3]> = (0..4).map(|_| [rng.next_f64() - 0.5; 3]).collect();
            Partial::apply(&p.sending, &b, &mut sent);
            let bound = on_exposed(&sent) / (send * top).sqrt();
            assert!(whole(&sent) <= bound * (1.0 + 1e-12), "seed {seed}");
        }
    }
}
