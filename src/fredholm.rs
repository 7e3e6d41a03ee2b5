//! The Galerkin system of a plain Fredholm equation of the second kind on [a, b]
//! (the slides' analytic test case, eq. (13)): K_ij = ∫∫ K(x,y) N_j(y) N_i(x), E_i = ∫ E N_i.

use crate::math::basis::legendre;
use crate::math::quadrature::Rule;
use crate::methods::projection::{Dense, Discretization, Layout, System};
use crate::progress::{Cancelled, Phase, Progress};
use crate::scene::Fredholm;
use rayon::prelude::*;

pub(crate) fn build(
    f: &Fredholm,
    disc: Discretization,
    progress: &dyn Progress,
) -> Result<System, Cancelled> {
    let k = disc.order + 1;
    let n = disc.cells;
    let [lo, hi] = f.domain;
    let len = hi - lo;
    let h = len / n as f64;
    let rule = Rule::gauss(disc.quadrature.max(1));
    // Nodes and weighted basis values of every cell, shared by all cell pairs.
    let q = rule.len();
    let mut xs = vec![0.0; n * q];
    let mut phi = vec![0.0; n * q * k];
    for c in 0..n {
        for (a, (x, w)) in rule.mapped(0.0, 1.0).enumerate() {
            xs[c * q + a] = lo + (c as f64 + x) * h;
            legendre(x, &mut phi[(c * q + a) * k..(c * q + a + 1) * k]);
            // N = φ/√h, dx = h dx̂: weight √h w
            phi[(c * q + a) * k..(c * q + a + 1) * k]
                .iter_mut()
                .for_each(|v| *v *= w * h.sqrt());
        }
    }
    let size = n * k;
    let mut m = Dense::zeros(size);
    progress.report(Phase::Projection, 0.0);
    m.data
        .par_chunks_mut(k * size)
        .enumerate()
        .try_for_each(|(a, rows)| {
            progress.check()?;
            let mut kv = vec![0.0; q * q];
            for b in 0..n {
                for i in 0..q {
                    for j in 0..q {
                        kv[i * q + j] = f.kernel.eval(xs[a * q + i], xs[b * q + j]);
                    }
                }
                for p in 0..k {
                    for r in 0..k {
                        let mut sum = 0.0;
                        for i in 0..q {
                            let pa = phi[(a * q + i) * k + p];
                            for j in 0..q {
                                sum += pa * kv[i * q + j] * phi[(b * q + j) * k + r];
                            }
                        }
                        rows[p * size + b * k + r] = sum;
                    }
                }
            }
            Ok::<(), Cancelled>(())
        })?;
    progress.report(Phase::Projection, 1.0);
    // E with a rule a few points finer: E need not be a polynomial.
    let erule = Rule::gauss((disc.quadrature + 4).min(crate::math::quadrature::MAX_CACHED));
    let mut emission = vec![[0.0; 3]; size];
    let mut v = vec![0.0; k];
    for c in 0..n {
        for (x, w) in erule.mapped(0.0, 1.0) {
            legendre(x, &mut v);
            let e = f.source.eval(lo + (c as f64 + x) * h, 0.0);
            for p in 0..k {
                let val = w * h.sqrt() * e * v[p];
                emission[c * k + p] = [emission[c * k + p][0] + val; 3];
            }
        }
    }
    Ok(System {
        layout: Layout::Line { cells: n, k },
        surfaces: 1,
        matrix: m,
        emission,
        reflectance: vec![[1.0; 3]],
        measure: vec![len],
        touching: Vec::new(),
        kernel_evaluations: Some((n * n * q * q) as u64),
    })
}
