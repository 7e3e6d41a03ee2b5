//! Lyusternik's extrapolation of a linear fixed-point iteration x ← E + M x (Faddeev and
//! Faddeeva, *Computational Methods of Linear Algebra*, 1963, on accelerating simple
//! iteration).
//!
//! Once one eigenvalue λ of M dominates, the error of the iterate x_k is nearly its
//! eigenvector, and each sweep changes x by Δ_k = x_k − x_{k−1} ≈ λ Δ_{k−1}. The geometric
//! series then sums to the fixed point: x ≈ x_k + λ / (1 − λ) · Δ_k. For radiosity M = ρK is
//! non-negative, so its largest eigenvalue is real and positive (Perron–Frobenius): it is the
//! mode that Jacobi sweeps take longest to remove, about 0.6 per sweep in a room of ρ ≈ 0.7.
//!
//! λ is taken as the least-squares ratio ⟨Δ_k, Δ_{k−1}⟩ / ⟨Δ_{k−1}, Δ_{k−1}⟩. The step is taken
//! only when that is safe ([`Lyusternik::step`]): two successive ratios agree and the last two
//! changes point the same way. Where they do, an error λ̂ − λ leaves (λ̂ − λ) / (1 − λ̂) of the
//! dominant mode, and the other modes (at most `sin` of the change) grow by at most
//! 2λ / (1 − λ): the step never does worse than about one sweep, and usually as well as
//! several. A negative eigenvalue as large as λ (two facing plates alone) makes the changes
//! alternate, and no step is taken.
//!
//! Written here: it is a few dot products over the caller's coefficients, which no crate
//! holds in this form.

/// How closely two successive ratios must agree.
const AGREE: f64 = 0.02;
/// The least cosine between two successive changes: the change is one mode to within
/// sin = 0.14 of it.
const SAME_WAY: f64 = 0.99;
/// The largest ratio extrapolated: the step λ / (1 − λ) stays below 19.
const LARGEST: f64 = 0.95;

/// The state of the extrapolation over the sweeps of one fixed operator M.
#[derive(Debug, Clone, Default)]
pub(crate) struct Lyusternik {
    /// x_{k−1}, or nothing before the first sweep.
    previous: Vec<f64>,
    /// Δ_{k−1}, or nothing after a step.
    change: Vec<f64>,
    /// The last ratio, when it was taken from two changes of plain sweeps.
    ratio: Option<f64>,
    /// The steps taken.
    pub(crate) steps: usize,
}

impl Lyusternik {
    /// Takes the iterate `x` after a sweep. Where the last changes show one dominant mode,
    /// moves `x` to the sum of its geometric series and returns the ratio λ it used; the
    /// next two sweeps are then plain again, to measure λ afresh.
    pub(crate) fn step(&mut self, x: &mut [f64]) -> Option<f64> {
        if self.previous.len() != x.len() {
            self.previous = x.to_vec();
            self.change.clear();
            self.ratio = None;
            return None;
        }
        let change: Vec<f64> = x.iter().zip(&self.previous).map(|(a, b)| a - b).collect();
        let mut taken = None;
        if self.change.len() == x.len() {
            let (mut cross, mut last, mut now) = (0.0, 0.0, 0.0);
            for (d, p) in change.iter().zip(&self.change) {
                cross += d * p;
                last += p * p;
                now += d * d;
            }
            let ratio = (last > 0.0).then(|| cross / last);
            let same_way = last > 0.0 && now > 0.0 && cross / (last * now).sqrt() >= SAME_WAY;
            if let (Some(r), Some(before)) = (ratio, self.ratio) {
                if same_way && r > 0.0 && r <= LARGEST && (r - before).abs() <= AGREE {
                    taken = Some(r);
                }
            }
            self.ratio = ratio;
        }
        match taken {
            Some(r) => {
                let c = r / (1.0 - r);
                for (v, d) in x.iter_mut().zip(&change) {
                    *v += c * d;
                }
                self.previous.copy_from_slice(x);
                self.change.clear();
                self.ratio = None;
                self.steps += 1;
            }
            None => {
                self.previous.copy_from_slice(x);
                self.change = change;
            }
        }
        taken
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Sweeps x ← e + M x from zero until the change falls below 1e-12, with or without the
    /// extrapolation: the sweeps taken, the steps taken and the last iterate.
    fn iterate(m: &[[f64; 3]; 3], e: [f64; 3], extrapolate: bool) -> (usize, usize, [f64; 3]) {
        let mut x = [0.0; 3];
        let mut l = Lyusternik::default();
        for sweep in 1..1000 {
            let next: Vec<f64> = (0..3)
                .map(|i| e[i] + (0..3).map(|j| m[i][j] * x[j]).sum::<f64>())
                .collect();
            let change = (0..3).map(|i| (next[i] - x[i]).abs()).fold(0.0, f64::max);
            x.copy_from_slice(&next);
            if change < 1e-12 {
                return (sweep, l.steps, x);
            }
            if extrapolate {
                l.step(&mut x);
            }
        }
        panic!("no convergence")
    }

    /// The exact fixed point of x = e + M x, by Cramer's rule on (I − M) x = e.
    fn exact(m: &[[f64; 3]; 3], e: [f64; 3]) -> [f64; 3] {
        let a: Vec<[f64; 3]> = (0..3)
            .map(|i| std::array::from_fn(|j| f64::from(i == j) - m[i][j]))
            .collect();
        let det = |c: &[[f64; 3]]| {
            c[0][0] * (c[1][1] * c[2][2] - c[1][2] * c[2][1])
                - c[0][1] * (c[1][0] * c[2][2] - c[1][2] * c[2][0])
                + c[0][2] * (c[1][0] * c[2][1] - c[1][1] * c[2][0])
        };
        let d = det(&a);
        std::array::from_fn(|k| {
            let c: Vec<[f64; 3]> = (0..3)
                .map(|i| std::array::from_fn(|j| if j == k { e[i] } else { a[i][j] }))
                .collect();
            det(&c) / d
        })
    }

    #[test]
    fn one_mode_is_summed_exactly_in_one_step() {
        // M = 0.6 I: every change is 0.6 times the last. Three changes give two ratios
        // that agree, so the fourth sweep's step lands on the fixed point e / 0.4 (to
        // rounding), and the fifth changes nothing
        let m = [[0.6, 0.0, 0.0], [0.0, 0.6, 0.0], [0.0, 0.0, 0.6]];
        let e = [1.0, 2.0, 0.5];
        let (sweeps, steps, x) = iterate(&m, e, true);
        assert_eq!((sweeps, steps), (5, 1));
        for i in 0..3 {
            assert!((x[i] - e[i] / 0.4).abs() < 1e-14 * x[i], "{x:?}");
        }
    }

    #[test]
    fn a_dominant_mode_is_removed_and_the_fixed_point_kept() {
        // a non-negative M (a room's three patches, ρ = 0.7) with eigenvalues 0.658, −0.308
        // and −0.210 (the roots of det(M − λI), checked below). Plain sweeps converge at
        // 0.658 a sweep; the steps remove that mode, so that the sweeps converge at the
        // second mode's rate, 0.308, but for the three sweeps each step takes to measure λ
        let m = [[0.0, 0.35, 0.35], [0.3, 0.07, 0.28], [0.28, 0.28, 0.07]];
        let (first, second) = (0.65834, 0.30835);
        for l in [first, -second, -0.21] {
            let a: Vec<[f64; 3]> = (0..3)
                .map(|i| std::array::from_fn(|j| m[i][j] - if i == j { l } else { 0.0 }))
                .collect();
            let det = a[0][0] * (a[1][1] * a[2][2] - a[1][2] * a[2][1])
                - a[0][1] * (a[1][0] * a[2][2] - a[1][2] * a[2][0])
                + a[0][2] * (a[1][0] * a[2][1] - a[1][1] * a[2][0]);
            assert!(det.abs() < 1e-5, "{l}: {det}");
        }
        let e = [1.0, 0.0, 0.0];
        let (plain, none, a) = iterate(&m, e, false);
        let (fast, steps, b) = iterate(&m, e, true);
        let x = exact(&m, e);
        assert_eq!(none, 0);
        for i in 0..3 {
            assert!((a[i] - x[i]).abs() < 1e-10 * x[i] && (b[i] - x[i]).abs() < 1e-10 * x[i]);
        }
        // sweeps to 1e-12 at a rate r: ln 1e-12 / ln r
        let at = |r: f64| (1e-12f64.ln() / r.ln()).ceil() as usize;
        assert!(plain <= at(first) + 1, "{plain} plain sweeps");
        assert!(
            steps >= 1 && fast <= at(second) + 3 * steps,
            "{fast} sweeps, {steps} steps"
        );
    }

    #[test]
    fn alternating_modes_are_not_extrapolated() {
        // two facing plates and a dim third: eigenvalues ±0.6 (and one near 0), so the changes
        // alternate between two directions: no step is ever taken and the sweeps are plain
        let m = [[0.0, 0.6, 0.0], [0.6, 0.0, 0.0], [0.0, 0.0, 0.1]];
        let e = [1.0, 0.2, 1.0];
        let (plain, _, _) = iterate(&m, e, false);
        let (sweeps, steps, x) = iterate(&m, e, true);
        assert_eq!((sweeps, steps), (plain, 0));
        let exact = exact(&m, e);
        for i in 0..3 {
            assert!((x[i] - exact[i]).abs() < 1e-10 * exact[i]);
        }
    }
}
