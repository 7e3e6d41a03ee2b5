//! Gauss–Legendre rules on [0, 1] and their tensor products.
//!
//! Nodes and weights come from the `gauss-quad` crate (Bogaert's O(n) algorithm, accurate to
//! machine precision for any n). A q-point rule integrates polynomials of degree ≤ 2q − 1
//! exactly; `Rule::for_degree` picks the smallest such rule.

use std::num::NonZeroUsize;
use std::sync::OnceLock;

/// A Gauss–Legendre rule mapped to [0, 1]: nodes in increasing order, weights summing to 1.
#[derive(Debug, Clone, PartialEq)]
pub struct Rule {
    pub(crate) nodes: Vec<f64>,
    pub(crate) weights: Vec<f64>,
}

/// Rules with 1 to this many points are cached.
pub(crate) const MAX_CACHED: usize = 128;

impl Rule {
    /// The q-point rule on [0, 1] (q ≥ 1), exact for degree ≤ 2q − 1.
    pub(crate) fn gauss(q: usize) -> &'static Rule {
        static CACHE: OnceLock<Vec<Rule>> = OnceLock::new();
        let cache = CACHE.get_or_init(|| (1..=MAX_CACHED).map(Rule::compute).collect());
        assert!((1..=MAX_CACHED).contains(&q), "Gauss rule with {q} points");
        &cache[q - 1]
    }

    /// The smallest Gauss rule exact for polynomials of degree `d`.
    pub(crate) fn for_degree(d: usize) -> &'static Rule {
        Rule::gauss(d / 2 + 1)
    }

    fn compute(q: usize) -> Rule {
        let gl = gauss_quad::legendre::GaussLegendre::new(NonZeroUsize::new(q).expect("q ≥ 1"));
        let mut pairs: Vec<(f64, f64)> = gl
            .as_node_weight_pairs()
            .iter()
            .map(|&(x, w)| (0.5 * (x + 1.0), 0.5 * w))
            .collect();
        pairs.sort_by(|a, b| a.0.total_cmp(&b.0));
        Rule {
            nodes: pairs.iter().map(|p| p.0).collect(),
            weights: pairs.iter().map(|p| p.1).collect(),
        }
    }

    pub(crate) fn len(&self) -> usize {
        self.nodes.len()
    }

    /// ∫_a^b f.
    #[cfg(test)]
    pub(crate) fn integrate(&self, a: f64, b: f64, mut f: impl FnMut(f64) -> f64) -> f64 {
        let h = b - a;
        let mut sum = 0.0;
        for (x, w) in self.nodes.iter().zip(&self.weights) {
            sum += w * f(a + h * x);
        }
        sum * h
    }

    /// Points and weights of the rule mapped to [a, b].
    pub(crate) fn mapped(&self, a: f64, b: f64) -> impl Iterator<Item = (f64, f64)> + '_ {
        let h = b - a;
        self.nodes
            .iter()
            .zip(&self.weights)
            .map(move |(x, w)| (a + h * x, w * h))
    }

    /// The tensor rule on [a0,b0]×[a1,b1]: ∫∫ f(s, t) ds dt.
    pub(crate) fn integrate2(
        &self,
        s: [f64; 2],
        t: [f64; 2],
        mut f: impl FnMut(f64, f64) -> f64,
    ) -> f64 {
        let mut sum = 0.0;
        for (x, wx) in self.mapped(s[0], s[1]) {
            for (y, wy) in self.mapped(t[0], t[1]) {
                sum += wx * wy * f(x, y);
            }
        }
        sum
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// ∫_0^1 x^k = 1/(k+1).
    #[test]
    fn exact_on_the_degrees_it_must_integrate() {
        for q in 1..=64 {
            let r = Rule::gauss(q);
            assert_eq!(r.len(), q);
            for k in 0..2 * q {
                let got = r.integrate(0.0, 1.0, |x| x.powi(k as i32));
                let want = 1.0 / (k as f64 + 1.0);
                assert!((got - want).abs() < 1e-14, "q={q} k={k}: {got} vs {want}");
            }
            // and not beyond: x^{2q} is integrated with a visible error
            if q <= 8 {
                let over = r.integrate(0.0, 1.0, |x| x.powi(2 * q as i32));
                assert!((over - 1.0 / (2.0 * q as f64 + 1.0)).abs() > 1e-12);
            }
        }
    }

    #[test]
    fn shifted_polynomials_on_other_intervals() {
        // ∫_{-1}^{3} (x - 1)^6 dx = 2 · 2^7 / 7
        let r = Rule::for_degree(6);
        assert_eq!(r.len(), 4);
        let got = r.integrate(-1.0, 3.0, |x| (x - 1.0).powi(6));
        assert!((got - 256.0 / 7.0).abs() < 1e-12);
    }

    #[test]
    fn tensor_rule_is_exact_for_products() {
        let r = Rule::gauss(3);
        // ∫_0^2 ∫_1^2 s^5 t^4 dt ds = (64/6)(31/5)
        let got = r.integrate2([0.0, 2.0], [1.0, 2.0], |s, t| s.powi(5) * t.powi(4));
        assert!((got - 64.0 / 6.0 * 31.0 / 5.0).abs() < 1e-12);
    }

    #[test]
    fn known_nodes() {
        // The 2-point rule on [0,1]: ½ ∓ 1/(2√3).
        let r = Rule::gauss(2);
        assert!((r.nodes[0] - (0.5 - 0.5 / 3f64.sqrt())).abs() < 1e-16);
        assert!((r.weights[1] - 0.5).abs() < 1e-16);
        let w: f64 = Rule::gauss(64).weights.iter().sum();
        assert!((w - 1.0).abs() < 1e-14);
    }
}
