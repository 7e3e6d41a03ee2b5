//! The fast multiwavelet transform between the scaling basis on n = 2^J cells and the wavelet
//! basis of the same space (Alpert 1993, §3.2; for m = 0 the Haar transform).
//!
//! Layouts of one surface's n·k coefficients (k = m + 1):
//! - scaling: `[cell][p]`, the coefficient of √n φ_p(n x − cell);
//! - wavelet: `[s₀ | d₀ | d₁ | … | d_{J−1}]`, coarse to fine: s₀ the k scaling coefficients on the
//!   whole interval, d_j the 2^j·k wavelet coefficients of level j, `[cell][j]` within a level.
//!
//! Each of the J steps applies the orthogonal two-scale matrix [H; G] to the pairs of children,
//! so the transform is orthogonal and costs O(n k²). Every coefficient may be a row of `w`
//! numbers, which transforms the rows of a matrix block with the same code.

use super::Filters;

/// Scaling → wavelet coefficients, in place. `data.len() == n·k·w`, n a power of two.
pub(crate) fn forward(
    data: &mut [f64],
    n: usize,
    filters: &Filters,
    w: usize,
    scratch: &mut Vec<f64>,
) {
    let k = filters.k;
    assert!(n.is_power_of_two() && data.len() == n * k * w);
    scratch.clear();
    scratch.resize(data.len(), 0.0);
    let mut len = n; // cells at the current level, in data[..len·k·w]
    while len > 1 {
        let half = len / 2;
        // parents into scratch[..half], details into scratch[half..len]
        for c in 0..half {
            let children = &data[2 * c * k * w..(2 * c + 2) * k * w];
            for p in 0..k {
                let hs = &filters.h[p * 2 * k..(p + 1) * 2 * k];
                let gs = &filters.g[p * 2 * k..(p + 1) * 2 * k];
                let s_out = (c * k + p) * w;
                let d_out = ((half + c) * k + p) * w;
                scratch[s_out..s_out + w].fill(0.0);
                scratch[d_out..d_out + w].fill(0.0);
                for q in 0..2 * k {
                    let child = &children[q * w..(q + 1) * w];
                    let (hq, gq) = (hs[q], gs[q]);
                    for i in 0..w {
                        scratch[s_out + i] += hq * child[i];
                        scratch[d_out + i] += gq * child[i];
                    }
                }
            }
        }
        data[..len * k * w].copy_from_slice(&scratch[..len * k * w]);
        len = half;
    }
}

/// Wavelet → scaling coefficients, in place; the inverse (and transpose) of [`forward`].
pub(crate) fn inverse(
    data: &mut [f64],
    n: usize,
    filters: &Filters,
    w: usize,
    scratch: &mut Vec<f64>,
) {
    let k = filters.k;
    assert!(n.is_power_of_two() && data.len() == n * k * w);
    scratch.clear();
    scratch.resize(data.len(), 0.0);
    let mut len = 1;
    while len < n {
        // parents in data[..len], details in data[len..2len] → children in scratch[..2len]
        for c in 0..len {
            let out = &mut scratch[2 * c * k * w..(2 * c + 2) * k * w];
            out.fill(0.0);
            for p in 0..k {
                let hs = &filters.h[p * 2 * k..(p + 1) * 2 * k];
                let gs = &filters.g[p * 2 * k..(p + 1) * 2 * k];
                let s = &data[(c * k + p) * w..(c * k + p + 1) * w];
                let d = &data[((len + c) * k + p) * w..((len + c) * k + p + 1) * w];
                for q in 0..2 * k {
                    let o = &mut out[q * w..(q + 1) * w];
                    for i in 0..w {
                        o[i] += hs[q] * s[i] + gs[q] * d[i];
                    }
                }
            }
        }
        data[..2 * len * k * w].copy_from_slice(&scratch[..2 * len * k * w]);
        len *= 2;
    }
}

/// The 2D (quadtree, "non-standard") transform of a square surface with `n × n` cells and
/// k² tensor coefficients per cell, layout `[cell_t][cell_s][q][p]` (p along s), in place.
///
/// Each step maps 2 × 2 children to their parent: the 1D two-scale matrix along s, then along
/// t, which gives the parent's k² scaling coefficients (H⊗H) and 3k² details (G⊗H, H⊗G, G⊗G),
/// the wavelets of Gortler et al.'s wavelet radiosity for a quadtree. Layout of the result:
/// `[s₀ (k²) | level 0 (3k²) | level 1 (4·3k²) | …]`, within a level `[cell_t][cell_s][type][q][p]`.
pub(crate) fn forward_square(
    data: &mut [f64],
    n: usize,
    filters: &Filters,
    scratch: &mut Vec<f64>,
) {
    let k = filters.k;
    let kk = k * k;
    assert!(n.is_power_of_two() && data.len() == n * n * kk);
    scratch.clear();
    scratch.resize(data.len(), 0.0);
    let mut len = n;
    let mut child = vec![0.0; 4 * kk];
    let mut out = vec![0.0; 4 * kk];
    while len > 1 {
        let half = len / 2;
        let parents = half * half;
        for pt in 0..half {
            for ps in 0..half {
                for dt in 0..2 {
                    for ds in 0..2 {
                        let c = ((2 * pt + dt) * len + 2 * ps + ds) * kk;
                        child[(dt * 2 + ds) * kk..(dt * 2 + ds + 1) * kk]
                            .copy_from_slice(&data[c..c + kk]);
                    }
                }
                two_by_two(&child, &mut out, filters);
                let idx = pt * half + ps;
                scratch[idx * kk..(idx + 1) * kk].copy_from_slice(&out[..kk]);
                let d = parents * kk + idx * 3 * kk;
                scratch[d..d + 3 * kk].copy_from_slice(&out[kk..]);
            }
        }
        data[..len * len * kk].copy_from_slice(&scratch[..len * len * kk]);
        len = half;
    }
}

/// The inverse (and transpose) of [`forward_square`].
pub(crate) fn inverse_square(
    data: &mut [f64],
    n: usize,
    filters: &Filters,
    scratch: &mut Vec<f64>,
) {
    let k = filters.k;
    let kk = k * k;
    assert!(n.is_power_of_two() && data.len() == n * n * kk);
    scratch.clear();
    scratch.resize(data.len(), 0.0);
    let mut half = 1;
    let mut parent = vec![0.0; 4 * kk];
    let mut children = vec![0.0; 4 * kk];
    while half < n {
        let len = 2 * half;
        let parents = half * half;
        for pt in 0..half {
            for ps in 0..half {
                let idx = pt * half + ps;
                parent[..kk].copy_from_slice(&data[idx * kk..(idx + 1) * kk]);
                let d = parents * kk + idx * 3 * kk;
                parent[kk..].copy_from_slice(&data[d..d + 3 * kk]);
                two_by_two_inverse(&parent, &mut children, filters);
                for dt in 0..2 {
                    for ds in 0..2 {
                        let c = ((2 * pt + dt) * len + 2 * ps + ds) * kk;
                        scratch[c..c + kk]
                            .copy_from_slice(&children[(dt * 2 + ds) * kk..(dt * 2 + ds + 1) * kk]);
                    }
                }
            }
        }
        data[..len * len * kk].copy_from_slice(&scratch[..len * len * kk]);
        half = len;
    }
}

/// Four children `[dt][ds][q][p]` → `[HH | GH | HG | GG]`, each `[q][p]` (first letter along s).
fn two_by_two(child: &[f64], out: &mut [f64], f: &Filters) {
    let k = f.k;
    let kk = k * k;
    // along s: for each dt, q: (ds, p) → H and G rows, giving along_s[filter][dt][q][p']
    let mut along_s = vec![0.0; 2 * 2 * kk];
    for dt in 0..2 {
        for q in 0..k {
            for (fi, rows) in [&f.h, &f.g].into_iter().enumerate() {
                for pp in 0..k {
                    let row = &rows[pp * 2 * k..(pp + 1) * 2 * k];
                    let mut sum = 0.0;
                    for ds in 0..2 {
                        for p in 0..k {
                            sum += row[ds * k + p] * child[(dt * 2 + ds) * kk + q * k + p];
                        }
                    }
                    along_s[(fi * 2 + dt) * kk + q * k + pp] = sum;
                }
            }
        }
    }
    // along t: for each s-filter and p': (dt, q) → H and G rows
    for fs in 0..2 {
        for (ft, rows) in [&f.h, &f.g].into_iter().enumerate() {
            let kind = match (fs, ft) {
                (0, 0) => 0,
                (1, 0) => 1,
                (0, 1) => 2,
                _ => 3,
            };
            for qq in 0..k {
                let row = &rows[qq * 2 * k..(qq + 1) * 2 * k];
                for pp in 0..k {
                    let mut sum = 0.0;
                    for dt in 0..2 {
                        for q in 0..k {
                            sum += row[dt * k + q] * along_s[(fs * 2 + dt) * kk + q * k + pp];
                        }
                    }
                    out[kind * kk + qq * k + pp] = sum;
                }
            }
        }
    }
}

fn two_by_two_inverse(parent: &[f64], children: &mut [f64], f: &Filters) {
    let k = f.k;
    let kk = k * k;
    let mut along_s = vec![0.0; 2 * 2 * kk];
    for fs in 0..2 {
        for dt in 0..2 {
            for q in 0..k {
                for pp in 0..k {
                    let mut sum = 0.0;
                    for (ft, rows) in [&f.h, &f.g].into_iter().enumerate() {
                        let kind = [[0, 2], [1, 3]][fs][ft];
                        for qq in 0..k {
                            sum += rows[qq * 2 * k + dt * k + q] * parent[kind * kk + qq * k + pp];
                        }
                    }
                    along_s[(fs * 2 + dt) * kk + q * k + pp] = sum;
                }
            }
        }
    }
    for dt in 0..2 {
        for ds in 0..2 {
            for q in 0..k {
                for p in 0..k {
                    let mut sum = 0.0;
                    for (fs, rows) in [&f.h, &f.g].into_iter().enumerate() {
                        for pp in 0..k {
                            sum += rows[pp * 2 * k + ds * k + p]
                                * along_s[(fs * 2 + dt) * kk + q * k + pp];
                        }
                    }
                    children[(dt * 2 + ds) * kk + q * k + p] = sum;
                }
            }
        }
    }
}

/// (level, index within level) of wavelet-layout position `i / k`: level −1 is s₀.
#[cfg(test)]
pub(crate) fn level_of(i: usize, k: usize) -> i32 {
    let c = i / k;
    if c == 0 {
        -1
    } else {
        (usize::BITS - 1 - c.leading_zeros()) as i32
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::basis::legendre;
    use crate::math::quadrature::Rule;

    fn pseudo_random(len: usize, seed: u64) -> Vec<f64> {
        let mut s = seed;
        (0..len)
            .map(|_| {
                s = s
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                ((s >> 11) as f64 / (1u64 << 53) as f64) - 0.5
            })
            .collect()
    }

    #[test]
    fn round_trip_and_orthogonality() {
        let mut scratch = Vec::new();
        for m in 0..=4 {
            let f = Filters::of_order(m);
            for n in [1, 2, 8, 64, 256] {
                for w in [1, 3] {
                    let x = pseudo_random(n * f.k * w, (m * 1000 + n) as u64);
                    let mut y = x.clone();
                    forward(&mut y, n, f, w, &mut scratch);
                    let nx: f64 = x.iter().map(|v| v * v).sum();
                    let ny: f64 = y.iter().map(|v| v * v).sum();
                    assert!((nx - ny).abs() < 1e-13 * nx, "Parseval m={m} n={n}");
                    inverse(&mut y, n, f, w, &mut scratch);
                    let err = x
                        .iter()
                        .zip(&y)
                        .map(|(a, b)| (a - b).abs())
                        .fold(0.0, f64::max);
                    assert!(err < 1e-13, "round trip m={m} n={n}: {err}");
                }
            }
        }
    }

    /// A wavelet coefficient vector with one 1 is, in scaling coordinates, the sampled wavelet
    /// √(2^j) ψ_p(2^j x − c): check it pointwise, and that a polynomial of degree ≤ m has
    /// only coarse coefficients (the vanishing moments at work).
    #[test]
    fn basis_vectors_are_the_dilated_wavelets() {
        let mut scratch = Vec::new();
        let m = 2;
        let f = Filters::of_order(m);
        let k = f.k;
        let n = 8;
        // level 1, cell 1, wavelet 2: position k·(2 + 1) + 2
        let mut e = vec![0.0; n * k];
        e[k * 3 + 2] = 1.0;
        inverse(&mut e, n, f, 1, &mut scratch);
        let mut v = vec![0.0; k];
        for i in 0..400 {
            let x = (i as f64 + 0.5) / 400.0;
            let cell = (x * n as f64) as usize;
            legendre(x * n as f64 - cell as f64, &mut v);
            let got: f64 = (0..k)
                .map(|p| e[cell * k + p] * v[p] * (n as f64).sqrt())
                .sum();
            let y = 2.0 * x - 1.0;
            let want = if (0.0..1.0).contains(&y) {
                2f64.sqrt() * f.wavelet(2, y)
            } else {
                0.0
            };
            assert!((got - want).abs() < 1e-12, "x={x}: {got} vs {want}");
        }
        // x² projected on 8 cells is exactly in V₀ for m = 2
        let rule = Rule::gauss(4);
        let mut c = vec![0.0; n * k];
        for cell in 0..n {
            for (x, w) in rule.mapped(0.0, 1.0) {
                legendre(x, &mut v);
                let gx = (cell as f64 + x) / n as f64;
                for p in 0..k {
                    c[cell * k + p] += w * gx * gx * v[p] / (n as f64).sqrt();
                }
            }
        }
        forward(&mut c, n, f, 1, &mut scratch);
        assert!(c[k..].iter().all(|d| d.abs() < 1e-14));
        assert!((c[0] - 1.0 / 3.0).abs() < 1e-14);
    }

    #[test]
    fn square_round_trip_and_parseval() {
        let mut scratch = Vec::new();
        for m in 0..=3 {
            let f = Filters::of_order(m);
            for n in [1, 2, 4, 16] {
                let x = pseudo_random(n * n * f.k * f.k, (m * 77 + n) as u64);
                let mut y = x.clone();
                forward_square(&mut y, n, f, &mut scratch);
                let nx: f64 = x.iter().map(|v| v * v).sum();
                let ny: f64 = y.iter().map(|v| v * v).sum();
                assert!((nx - ny).abs() < 1e-13 * nx);
                inverse_square(&mut y, n, f, &mut scratch);
                let err = x
                    .iter()
                    .zip(&y)
                    .map(|(a, b)| (a - b).abs())
                    .fold(0.0, f64::max);
                assert!(err < 1e-13, "m={m} n={n}: {err}");
            }
        }
    }

    /// A constant on the square has only the coarsest coefficient.
    #[test]
    fn square_constant_is_coarse() {
        let mut scratch = Vec::new();
        let f = Filters::of_order(1);
        let n = 8;
        let kk = 4;
        let mut c = vec![0.0; n * n * kk];
        for cell in 0..n * n {
            c[cell * kk] = 1.0 / n as f64; // ∫ 1 · (n φ₀φ₀) over a cell of area 1/n²
        }
        forward_square(&mut c, n, f, &mut scratch);
        assert!((c[0] - 1.0).abs() < 1e-14);
        assert!(c[1..].iter().all(|v| v.abs() < 1e-14));
    }

    #[test]
    fn levels() {
        assert_eq!(level_of(0, 2), -1);
        assert_eq!(level_of(2, 2), 0);
        assert_eq!(level_of(4, 2), 1);
        assert_eq!(level_of(7, 2), 1);
        assert_eq!(level_of(8, 2), 2);
    }
}
