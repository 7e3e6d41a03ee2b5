//! The element quadtrees of hierarchical wavelet radiosity (Gortler, Schröder, Cohen and
//! Hanrahan 1993, §4): every surface is the root of a tree of pieces, each piece carrying the
//! k² tensor Legendre coefficients (orthonormal in its area) of E, B and the gathered H.
//!
//! Push and pull are the two-scale relation of the multiwavelet basis (Alpert's filters h):
//! a parent's coefficients are H⊗H applied to its four children's ("pull", the projection of
//! the children's B onto the parent's space), and a parent's polynomial restricted to a child
//! is the transpose ("push", exact).

use crate::math::basis::Filters;
use crate::scene::Rgb;
use crate::three_d::cover::Exposure;
use crate::three_d::geometry::Piece;

pub(super) const NONE: u32 = u32::MAX;

#[derive(Debug, Clone)]
pub(super) struct Element {
    pub(super) piece: Piece,
    pub(super) level: u32,
    /// Cell indices (s, t) at its level.
    pub(super) cell: [u32; 2],
    /// First of four children (`[t][s]` order), or [`NONE`].
    pub(super) children: u32,
    /// World area.
    pub(super) area: f64,
    pub(super) e: Vec<Rgb>,
    /// The largest emission inside the element (a light patch may cover only part of it).
    pub(super) peak: f64,
    pub(super) b: Vec<Rgb>,
    pub(super) h: Vec<Rgb>,
    /// The root mean square of B minus its polynomial on this element over the element
    /// (largest channel), from the leaves below: what a link that uses this element as a
    /// source leaves out.
    pub(super) detail: f64,
    /// How much of it a solid standing on the surface leaves exposed ([`crate::three_d::cover`]).
    /// On a partly covered element, `b` and `h` are the polynomials of the exposed part
    /// (see [`Element::reported`]).
    pub(super) exposure: Exposure,
}

impl Element {
    pub(super) fn is_leaf(&self) -> bool {
        self.children == NONE
    }

    /// Whether light reaches it: not wholly covered ([`crate::three_d::cover`]).
    pub(super) fn receives(&self) -> bool {
        self.exposure != Exposure::Covered
    }

    /// Writes into `out` the coefficients of the polynomial it sends. A partly covered element's B is fitted
    /// to its exposed part (B = G⁺ h, [`crate::three_d::cover`]) and sent over the whole
    /// element, the rays taking the covered part back out; of it only what the exposed part
    /// determines goes out ([`crate::three_d::cover::Partial`]'s `sending`), so that its
    /// continuation under the solid stays of the size it has where it is seen.
    pub(super) fn sent(&self, out: &mut [Rgb]) {
        match &self.exposure {
            Exposure::Partial(p) => {
                crate::three_d::cover::Partial::apply(&p.sending, &self.b, out);
            }
            _ => out.copy_from_slice(&self.b),
        }
    }

    /// The first coefficient of [`Element::sent`]: its mean times √A.
    pub(super) fn sent0(&self) -> Rgb {
        match &self.exposure {
            Exposure::Partial(p) => {
                let mut out = [0.0; 3];
                for (g, b) in p.sending.iter().zip(&self.b) {
                    (0..3).for_each(|ch| out[ch] += g * b[ch]);
                }
                out
            }
            _ => self.b[0],
        }
    }

    /// Whether it sends light: not wholly covered, or emitting (a covered part keeps B = E).
    pub(super) fn sends(&self) -> bool {
        self.receives() || self.peak > 0.0
    }

    /// The projection of the whole element's B (or H, with `e` = 0) from the exposed part's
    /// polynomial `v`: E on the covered part, `v` on the rest, i.e. e + G (v − e).
    pub(super) fn reported(&self, v: &[Rgb], e: &[Rgb]) -> Vec<Rgb> {
        match &self.exposure {
            Exposure::Open => v.to_vec(),
            Exposure::Covered => e.to_vec(),
            Exposure::Partial(p) => {
                let d: Vec<Rgb> = v
                    .iter()
                    .zip(e)
                    .map(|(v, e)| [v[0] - e[0], v[1] - e[1], v[2] - e[2]])
                    .collect();
                let mut out = vec![[0.0; 3]; v.len()];
                crate::three_d::cover::Partial::apply(&p.gram, &d, &mut out);
                out.iter_mut().zip(e).for_each(|(o, e)| {
                    (0..3).for_each(|c| o[c] += e[c]);
                });
                out
            }
        }
    }
    /// The mean over the element and the channels of the polynomial with coefficients `c`
    /// (its constant coefficient over √area, in the orthonormal basis).
    pub(super) fn mean_of(&self, c: &[Rgb]) -> f64 {
        c[0].iter().sum::<f64>() / 3.0 / self.area.sqrt()
    }

    /// The brightness the oracle weighs a transfer by: the mean of B (largest channel) plus
    /// the peak emission inside, so that a small light on a large surface is not averaged away.
    pub(super) fn brightness(&self) -> f64 {
        let c = self.b[0];
        c[0].max(c[1]).max(c[2]) / self.area.sqrt() + self.peak
    }
}

/// The coefficients of child (dt, ds) of a parent polynomial `parent` (k² each).
pub(super) fn push(filters: &Filters, parent: &[Rgb], dt: usize, ds: usize, out: &mut [Rgb]) {
    let k = filters.k;
    let h = &filters.h;
    out.fill([0.0; 3]);
    for a in 0..k {
        for b in 0..k {
            let mut acc = [0.0; 3];
            for qt in 0..k {
                let ht = h[qt * 2 * k + dt * k + a];
                for ps in 0..k {
                    let w = ht * h[ps * 2 * k + ds * k + b];
                    let p = parent[qt * k + ps];
                    for c in 0..3 {
                        acc[c] += w * p[c];
                    }
                }
            }
            out[a * k + b] = acc;
        }
    }
}

/// Adds the projection of child (dt, ds)'s coefficients onto the parent's space to `parent`.
pub(super) fn pull(filters: &Filters, child: &[Rgb], dt: usize, ds: usize, parent: &mut [Rgb]) {
    let k = filters.k;
    let h = &filters.h;
    for qt in 0..k {
        for ps in 0..k {
            let mut acc = [0.0; 3];
            for a in 0..k {
                let ht = h[qt * 2 * k + dt * k + a];
                for b in 0..k {
                    let w = ht * h[ps * 2 * k + ds * k + b];
                    let v = child[a * k + b];
                    for c in 0..3 {
                        acc[c] += w * v[c];
                    }
                }
            }
            for c in 0..3 {
                parent[qt * k + ps][c] += acc[c];
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::basis::legendre;

    /// A polynomial of degree m on the parent, pushed to a child, evaluates to the same values;
    /// pulling the four children back gives the parent again (m = 0 … 3).
    #[test]
    fn push_is_exact_and_pull_inverts_it() {
        for m in 0..=3 {
            let f = Filters::of_order(m);
            let k = m + 1;
            let parent: Vec<Rgb> = (0..k * k)
                .map(|i| [1.0 + i as f64, -0.5 * i as f64, 0.25])
                .collect();
            let mut back = vec![[0.0; 3]; k * k];
            let mut child = vec![[0.0; 3]; k * k];
            let eval = |c: &[Rgb], s: f64, t: f64, area: f64| {
                let mut ps = vec![0.0; k];
                let mut pt = vec![0.0; k];
                legendre(s, &mut ps);
                legendre(t, &mut pt);
                let mut v = 0.0;
                for a in 0..k {
                    for b in 0..k {
                        v += c[a * k + b][0] * pt[a] * ps[b];
                    }
                }
                v / area.sqrt()
            };
            for dt in 0..2 {
                for ds in 0..2 {
                    push(f, &parent, dt, ds, &mut child);
                    // the point (0.3, 0.6) of the child is ((ds + 0.3)/2, (dt + 0.6)/2) of the parent
                    let pv = eval(
                        &parent,
                        (ds as f64 + 0.3) / 2.0,
                        (dt as f64 + 0.6) / 2.0,
                        1.0,
                    );
                    let cv = eval(&child, 0.3, 0.6, 0.25);
                    assert!((pv - cv).abs() < 1e-12, "m={m}: {pv} vs {cv}");
                    pull(f, &child, dt, ds, &mut back);
                }
            }
            for (a, b) in back.iter().zip(&parent) {
                for c in 0..3 {
                    assert!((a[c] - b[c]).abs() < 1e-12);
                }
            }
        }
    }
}
