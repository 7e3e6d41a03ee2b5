//! The shadow budget of a receiver: the errors that partly visible links leave on an element
//! and its ancestors, added up where they fall, and held to the element's tolerance.
//!
//! A link whose visible fraction V varies over its receiver delivers the projection of the
//! shadowed transfer onto the receiver's polynomials, P(T V): a step of V smeared over the
//! receiver. The oracle ([`super::refine`]) bounds each link alone by the whole of its
//! transfer, so a partly visible link whose transfer is within the tolerance is kept at any
//! level; but the smear of every such link into an element and its ancestors lies on the same
//! side of the same occluder, and their errors add up with one sign there. Where a ball rests on
//! a floor, 44 links from the walls into the floor's 2.5-unit element that holds the contact
//! point, each within its tolerance, made the floor 1.6 times too bright at that point for its
//! own B (the one-bounce residual in `benches/README.md`).
//!
//! The bound (in the manner of Lischinski, Smits and Greenberg 1994, "Bounds and error
//! estimates for radiosity", and Holzschuch and Sillion 1998, "An exhaustive error-bounding
//! algorithm for hierarchical radiosity", which bound the error gathered at a receiver rather
//! than each link's): with the unoccluded transfer taken as constant over the receiver, a
//! link's error on its step cell c is
//!
//! ```text
//! e_l(c) = ρ_R · T̄_l · (V(c) − (Q V)(c)),
//! ```
//!
//! with Q V the mean over cell c of V's L² projection onto the receiver's basis (V is a step
//! over the cells, [`crate::three_d::steps`]) and T̄_l the mean irradiance the link would
//! deliver unoccluded with the source's B of the last solve (the mean its block delivers over
//! the mean of V). After each solve the errors of the links into a leaf and into each of its
//! ancestors are added, signed, on the leaf's cells (an ancestor's cell holds four of its
//! child's); where the sum exceeds [`Rules::shadow_share`] of the leaf's tolerance
//! ([`super::tolerance`]), every partly visible link that adds to it with its sign and whose
//! receiver can still be split is split on the receiver's side. Each level down, a link's smear covers a quarter of the area,
//! and the links that no longer cross the shadow's edge leave no error: the sum falls to what
//! the finest elements allow. Links with a cluster at an end are not in the sum (their
//! receiving members each take their own V, a constant over the member).
//!
//! Measured at the defaults against the path tracer (`benches/README.md`): the gallery's ball
//! resting on a floor, its bottom triangles 125 % off beyond the noise without the budget, now
//! within 0.8 %; the room with 7 × 7 boxes, the worst cell 2.0 % → 1.0 %; for 4–12 % more links.

use super::links::Links;
use super::Hierarchy;
#[cfg(doc)]
use crate::three_d::rules::Rules;
use crate::three_d::steps::{Steps, CELLS, STEP};
use crate::three_d::visibility::Seen;

/// A link's visible fraction on each step cell of its receiver, in fifteenths, two cells a
/// byte; kept beside a link whose fraction varies over its receiver (none where it is uniform).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) struct Cells([u8; CELLS / 2]);

impl Cells {
    /// The cells of a fraction that varies over its receiver; `None` for one uniform in
    /// fifteenths (whose residual would be rounding of either sign).
    pub(super) fn of(seen: &Seen) -> Option<Cells> {
        let mut packed = [0u8; CELLS / 2];
        for c in 0..CELLS {
            let v = (seen.cell(c).clamp(0.0, 1.0) * 15.0).round() as u8;
            packed[c / 2] |= v << (4 * (c % 2));
        }
        let cells = Cells(packed);
        let first = cells.0[0] & 15;
        (0..CELLS)
            .any(|c| cells.nibble(c) != first)
            .then_some(cells)
    }

    fn nibble(&self, c: usize) -> u8 {
        (self.0[c / 2] >> (4 * (c % 2))) & 15
    }

    fn get(&self, c: usize) -> f64 {
        f64::from(self.nibble(c)) / 15.0
    }
}

/// The maps V ↦ V − Q V of the step cells (row = cell), on a parallelogram and on a triangle,
/// at order k − 1.
pub(super) struct Residual {
    square: [[f64; CELLS]; CELLS],
    triangle: [[f64; CELLS]; CELLS],
}

impl Residual {
    pub(super) fn new(k: usize) -> Residual {
        let steps = Steps::new(k);
        let kk = k * k;
        // Q[c][c'] = CELLS Σ_a (∫_c φ_a)(∫_c' φ_a), with ∫_c φ_a = M_c[a][0] (φ₀ = 1 on the
        // element's unit parameter domain)
        let of = |grams: &[Vec<f64>]| {
            let mut r = [[0.0; CELLS]; CELLS];
            for (c, row) in r.iter_mut().enumerate() {
                for (d, x) in row.iter_mut().enumerate() {
                    let q: f64 = (0..kk)
                        .map(|a| grams[c][a * kk] * grams[d][a * kk])
                        .sum::<f64>()
                        * CELLS as f64;
                    *x = f64::from(u8::from(c == d)) - q;
                }
            }
            r
        };
        Residual {
            square: of(&steps.m),
            triangle: of(&steps.tri),
        }
    }

    /// V − Q V on each cell.
    fn apply(&self, tri: bool, cells: &Cells) -> [f64; CELLS] {
        let r = if tri { &self.triangle } else { &self.square };
        let v: [f64; CELLS] = std::array::from_fn(|c| cells.get(c));
        std::array::from_fn(|c| (0..CELLS).map(|d| r[c][d] * v[d]).sum())
    }
}

/// The cell of a parent that holds cell `c` of its child `q`.
fn parent_cell(tri: bool, q: usize, c: usize) -> usize {
    if tri {
        // the child's cell 4 a + b lies in its child a, the parent's grandchild 4 q + a
        4 * q + c / 4
    } else {
        let (i, j) = (c % STEP, c / STEP);
        let (ds, dt) = (q % 2, q / 2);
        (2 * ds + i / 2) + STEP * (2 * dt + j / 2)
    }
}

impl Hierarchy<'_> {
    /// Which of `links` (sorted by receiver) are to have their receivers split by the shadow
    /// budget, in their order.
    pub(super) fn over_shadow_budget(&self, links: &Links) -> Vec<bool> {
        let mut marked = vec![false; links.len()];
        if !self.rules.shadow_share.is_finite() {
            return marked;
        }
        let budget = Budget {
            residual: Residual::new(self.k),
            links,
            sent: std::cell::RefCell::new(vec![[0.0; 3]; self.k * self.k]),
            errors: Default::default(),
        };
        // the sum of the errors of each receiver's own links on its cells (in single
        // precision: an estimate), a slot for each receiver that has any
        let mut slot = vec![u32::MAX; self.elements.len()];
        let mut sums: Vec<[f32; CELLS]> = Vec::new();
        for (i, l) in links.ends().iter().enumerate() {
            let Some(e) = self.shadow_error(&budget, i) else {
                continue;
            };
            let at = &mut slot[l.recv as usize];
            if *at == u32::MAX {
                *at = sums.len() as u32;
                sums.push([0.0; CELLS]);
            }
            let sum = &mut sums[*at as usize];
            sum.iter_mut().zip(e).for_each(|(s, e)| *s += e as f32);
        }
        if sums.is_empty() {
            return marked;
        }
        let own = |e: u32| {
            let at = slot[e as usize];
            (at != u32::MAX).then(|| &sums[at as usize])
        };
        let mut stack = Vec::new();
        for root in 0..self.quads.len() as u32 {
            self.walk(root, [0.0; CELLS], &own, &budget, &mut stack, &mut marked);
        }
        marked
    }

    /// The error e_l of link `i` on each step cell of its receiver, if it is partly visible
    /// and delivers light.
    fn shadow_error(&self, budget: &Budget, i: usize) -> Option<[f64; CELLS]> {
        let l = &budget.links.ends()[i];
        let cells = l.factors.shadow.as_ref()?;
        let mean = (0..CELLS).map(|c| cells.get(c)).sum::<f64>() / CELLS as f64;
        if mean <= 0.0 {
            return None;
        }
        let (er, es) = (
            &self.elements[l.recv as usize],
            &self.elements[l.src as usize],
        );
        let mut sent = budget.sent.borrow_mut();
        es.sent(&mut sent);
        // the mean of ρ H that the link delivers (row 0 of its block: the receiver's
        // constant, 1 / √A), over the mean visible fraction: the unoccluded transfer
        let block = budget.links.block(i);
        let rho = self.quads[er.piece.surface].material.reflectance;
        let scale = (0..3)
            .map(|ch| {
                let h: f64 = sent
                    .iter()
                    .zip(block)
                    .map(|(b, &t)| f64::from(t) * b[ch])
                    .sum();
                rho[ch] * h
            })
            .fold(0.0, f64::max)
            / er.area.sqrt()
            / mean;
        if scale <= 0.0 {
            return None;
        }
        let tri = self.geo.quads[er.piece.surface].tri;
        Some(budget.residual.apply(tri, cells).map(|x| scale * x))
    }

    /// Adds the errors of the links into `e` to those `inherited` from its ancestors (on `e`'s
    /// cells); at a leaf, marks the links that make a cell's sum exceed its tolerance. `stack`
    /// holds the ancestors with partly visible links and, for each, the map from `e`'s cells
    /// to its own.
    fn walk<'s>(
        &self,
        e: u32,
        inherited: [f64; CELLS],
        own: &impl Fn(u32) -> Option<&'s [f32; CELLS]>,
        budget: &Budget,
        stack: &mut Vec<(u32, [u8; CELLS])>,
        marked: &mut [bool],
    ) {
        let el = &self.elements[e as usize];
        let mut total = inherited;
        let mine = own(e);
        if let Some(sum) = mine {
            total
                .iter_mut()
                .zip(sum)
                .for_each(|(t, s)| *t += f64::from(*s));
            stack.push((e, std::array::from_fn(|c| c as u8)));
        }
        if el.is_leaf() {
            // a covered leaf receives nothing: the errors on it are not errors
            if el.receives() {
                self.mark(e, &total, budget, stack, marked);
            }
        } else {
            let tri = self.geo.quads[el.piece.surface].tri;
            let first = el.children;
            for q in 0..4 {
                let down: [f64; CELLS] = std::array::from_fn(|c| total[parent_cell(tri, q, c)]);
                let mut below: Vec<(u32, [u8; CELLS])> = stack
                    .iter()
                    .map(|&(a, map)| (a, std::array::from_fn(|c| map[parent_cell(tri, q, c)])))
                    .collect();
                self.walk(first + q as u32, down, own, budget, &mut below, marked);
            }
        }
        if mine.is_some() {
            stack.pop();
        }
    }

    /// Marks the links into leaf `e`'s ancestors on `stack` (and `e`) that add to a cell's
    /// sum `total` beyond the leaf's tolerance.
    fn mark(
        &self,
        e: u32,
        total: &[f64; CELLS],
        budget: &Budget,
        stack: &[(u32, [u8; CELLS])],
        marked: &mut [bool],
    ) {
        let tol = self.rules.shadow_share * self.tolerance(e);
        for c in 0..CELLS {
            if total[c].abs() <= tol {
                continue;
            }
            // every link that adds to the excess with its sign: splitting only the
            // largest until the rest is within the tolerance (as if a split link's error
            // were gone, when its children keep part of it) left the small ball on the
            // gallery's floor 128 % off at ε = 4e-3 (32 % this way) and 9.5 % at 1e-3
            // (8.8 %), for 3 % fewer links
            let mut errors = budget.errors.borrow_mut();
            for &(a, map) in stack.iter() {
                if !self.splittable(a) {
                    continue;
                }
                let errors = errors.entry(a).or_insert_with(|| {
                    // a's links, a run of the links sorted by receiver
                    let ends = budget.links.ends();
                    let first = ends.partition_point(|l| l.recv < a);
                    let last = first + ends[first..].partition_point(|l| l.recv == a);
                    (first..last)
                        .filter_map(|i| {
                            let d = self.shadow_error(budget, i)?;
                            Some((i, d.map(|x| x as f32)))
                        })
                        .collect()
                });
                for (i, d) in errors.iter() {
                    if f64::from(d[map[c] as usize]) * total[c] > 0.0 {
                        marked[*i] = true;
                    }
                }
            }
        }
    }
}

/// The errors e_l of a receiver's partly visible links on its cells: (link, e_l).
type Errors = Vec<(usize, [f32; CELLS])>;

/// What the budget reads of the links, a buffer for a source's coefficients, and the errors
/// of the links of each receiver that the marking has looked at.
struct Budget<'a> {
    residual: Residual,
    links: &'a Links,
    sent: std::cell::RefCell<Vec<crate::scene::Rgb>>,
    errors: std::cell::RefCell<rustc_hash::FxHashMap<u32, Errors>>,
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::progress::Silent;
    use crate::three_d::hierarchy::sizing::Sizing;
    use crate::three_d::hierarchy::tests::patches;
    use crate::three_d::projection::Geometry;
    use crate::three_d::rules::Rules;

    /// A 4 × 2 × 4 room (y up) lit by a patch of its ceiling, with a unit cube standing on
    /// its floor: the walls' links into the floor are partly visible around the cube.
    fn room_with_a_cube() -> Vec<crate::scene::Quad> {
        let q = |name: &str, c: [[f64; 3]; 4]| serde_json::json!({"name": name, "corners": c, "reflectance": 0.6});
        let (a, b) = (1.5, 2.5);
        let mut ceiling = q(
            "ceiling",
            [[0., 2., 0.], [4., 2., 0.], [4., 2., 4.], [0., 2., 4.]],
        );
        ceiling["emission"] = serde_json::json!(5.0);
        ceiling["emission_region"] = serde_json::json!({"s": [0.1, 0.3], "t": [0.1, 0.3]});
        patches(&serde_json::json!({"scene": {"kind": "3d", "surfaces": [
            q("floor", [[0., 0., 0.], [0., 0., 4.], [4., 0., 4.], [4., 0., 0.]]),
            ceiling,
            q("south", [[0., 0., 0.], [4., 0., 0.], [4., 2., 0.], [0., 2., 0.]]),
            q("north", [[0., 0., 4.], [0., 2., 4.], [4., 2., 4.], [4., 0., 4.]]),
            q("east", [[4., 0., 0.], [4., 0., 4.], [4., 2., 4.], [4., 2., 0.]]),
            q("west", [[0., 0., 0.], [0., 2., 0.], [0., 2., 4.], [0., 0., 4.]]),
            q("top", [[a, 1., a], [a, 1., b], [b, 1., b], [b, 1., a]]),
            q("cube-south", [[a, 0., a], [a, 1., a], [b, 1., a], [b, 0., a]]),
            q("cube-north", [[a, 0., b], [b, 0., b], [b, 1., b], [a, 1., b]]),
            q("cube-west", [[a, 0., a], [a, 0., b], [a, 1., b], [a, 1., a]]),
            q("cube-east", [[b, 0., a], [b, 1., a], [b, 1., b], [b, 0., b]]),
        ]}}))
    }

    /// The budget's invariant: once the refinement is done, no leaf's summed shadow errors
    /// exceed its tolerance where a link that adds to them can still be split (the budget
    /// asks for no split); after the first solve it asked for some.
    #[test]
    fn after_the_refinement_no_leaf_is_over_its_shadow_budget() {
        let quads = &room_with_a_cube();
        let geo = Geometry::new(quads);
        let sizing = Sizing::new(&geo.quads, Some(0.25), None);
        let mut h = Hierarchy::new(&geo, quads, 1, sizing, 1e-3, &Rules::default());
        h.link_all(&Silent).unwrap();
        let over = |h: &Hierarchy| {
            h.over_shadow_budget(&h.links)
                .iter()
                .filter(|&&m| m)
                .count()
        };
        while h.sweep() > 1e-6 {}
        h.typical = h.typical_radiosity();
        let first = over(&h);
        assert!(first > 0, "the budget asked for nothing");
        let mut passes = 0;
        while h.rerefine(&Silent).unwrap() > 0 {
            while h.sweep() > 1e-6 {}
            passes += 1;
            assert!(passes < 12, "the refinement did not end");
        }
        assert_eq!(
            over(&h),
            0,
            "{first} links over the budget after the first solve"
        );
        // turned off, it asks for nothing
        h.rules = Rules::without_shadow_budget();
        assert_eq!(over(&h), 0);
    }

    /// The residual of a constant is zero at every order. A step that no polynomial follows
    /// (one cell dark) keeps a residual with no mean (Q keeps the mean), exactly the step
    /// minus its mean at order 0, and smaller in norm at each higher order (the spaces nest).
    #[test]
    fn the_residual_keeps_nothing_of_what_the_basis_holds() {
        for tri in [false, true] {
            let mut norms = Vec::new();
            for k in 1..=3 {
                let r = Residual::new(k);
                let one = Cells([0xff; CELLS / 2]);
                let d = r.apply(tri, &one);
                assert!(d.iter().all(|x| x.abs() < 1e-12), "k {k} tri {tri}: {d:?}");
                let mut dark = one;
                dark.0[0] &= 0xf0;
                let d = r.apply(tri, &dark);
                let mean: f64 = d.iter().sum::<f64>() / CELLS as f64;
                assert!(mean.abs() < 1e-12, "k {k}: mean {mean}");
                if k == 1 {
                    assert!((d[0] + 15.0 / 16.0).abs() < 1e-12, "{}", d[0]);
                    assert!(d[1..].iter().all(|x| (x - 1.0 / 16.0).abs() < 1e-12));
                }
                norms.push(d.iter().map(|x| x * x).sum::<f64>().sqrt());
            }
            assert!(
                norms.windows(2).all(|w| w[1] < w[0] && w[1] > 0.0),
                "tri {tri}: {norms:?}"
            );
        }
        // at order 1 a ramp over s in four stairs keeps only its stairs: the line through
        // them is in the basis, and the cells' means of the stairs' offsets from it are
        // ±1/32 and ±1/96
        let r = Residual::new(2);
        let mut ramp = Cells([0; CELLS / 2]);
        for c in 0..CELLS {
            let v = [0u8, 5, 10, 15][c % STEP];
            ramp.0[c / 2] |= v << (4 * (c % 2));
        }
        let d = r.apply(false, &ramp);
        for (c, x) in d.iter().enumerate() {
            let want = [-3.0 / 96.0, -1.0 / 96.0, 1.0 / 96.0, 3.0 / 96.0][c % STEP];
            assert!((x - want).abs() < 1e-12, "cell {c}: {x}");
        }
    }

    /// A child's cell lies in the parent's cell that holds it: on a parallelogram, child
    /// (ds, dt) covers the parent's cells 2ds…2ds+1 by 2dt…2dt+1.
    #[test]
    fn a_childs_cells_lie_in_its_parents() {
        assert_eq!(parent_cell(false, 0, 0), 0);
        assert_eq!(parent_cell(false, 0, 15), 5);
        assert_eq!(parent_cell(false, 3, 0), 10);
        assert_eq!(parent_cell(false, 1, 3), 3);
        assert_eq!(parent_cell(true, 2, 5), 9);
        for tri in [false, true] {
            for q in 0..4 {
                let mut count = [0; CELLS];
                (0..CELLS).for_each(|c| count[parent_cell(tri, q, c)] += 1);
                assert_eq!(count.iter().filter(|&&n| n == 4).count(), 4);
            }
        }
    }
}
