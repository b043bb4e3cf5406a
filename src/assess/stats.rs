//! The statistics of a construct-validity table: does a metric separate an expert group of
//! surgical trainees from a novice group? Each group is summarised by its median and
//! quartiles ([`Spread`]), and the two are compared by the Mann-Whitney U test
//! ([`mann_whitney`]), which assumes nothing about the shape of the distributions and copes
//! with the small samples (typically 5 to 30 per group) and the ties (error counts that are
//! all 0, say) such studies have.
//!
//! With no ties and at most [`EXACT_LIMIT`] values in each group the two-sided p value is
//! exact, counted from the distribution of U under the null hypothesis; otherwise it comes
//! from the normal approximation with the variance corrected for ties and a continuity
//! correction of one half. Two effect sizes go with it: the rank-biserial correlation (equal
//! to Cliff's delta) and the common-language effect size (the probability that a random
//! value of the first group exceeds a random value of the second, ties counting one half).

/// The significance level a table uses unless told otherwise: a metric separates the groups
/// when the two-sided p value is below it.
pub const ALPHA: f64 = 0.05;

/// The largest group size (in both groups) for which the p value is exact when there are no
/// ties. The distribution's counts stay below C(40, 20), about 1.4e11, so an `f64` holds
/// them exactly, and the table costs a few hundred thousand additions at most.
pub const EXACT_LIMIT: usize = 20;

/// The `p` quantile of `sorted` (ascending, finite; not checked), by linear interpolation
/// between order statistics: Hyndman and Fan's type 7, the default of R and of numpy.
/// With `h = (n - 1) p`, the value is `x[floor h] + (h - floor h) (x[floor h + 1] - x[floor h])`
/// (indices from 0). `None` when `sorted` is empty or `p` is outside [0, 1].
pub fn quantile(sorted: &[f64], p: f64) -> Option<f64> {
    if sorted.is_empty() || !(0.0..=1.0).contains(&p) {
        return None;
    }
    let last = sorted.len() - 1;
    let h = last as f64 * p;
    let lo = (h.floor() as usize).min(last);
    if lo == last {
        return Some(sorted[last]);
    }
    let frac = h - lo as f64;
    Some(sorted[lo] + frac * (sorted[lo + 1] - sorted[lo]))
}

/// A group's centre and spread: how many values it has, its median and its quartiles
/// (type 7, see [`quantile`]), and the interquartile range `q3 - q1`.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Spread {
    /// The number of finite values summarised.
    pub n: usize,
    /// The median (the 0.5 quantile).
    pub median: f64,
    /// The first quartile (the 0.25 quantile).
    pub q1: f64,
    /// The third quartile (the 0.75 quantile).
    pub q3: f64,
    /// The interquartile range, `q3 - q1`.
    pub iqr: f64,
}

impl Spread {
    /// The spread of `values`, in any order; values that are not finite (NaN, infinities) are
    /// left out. `None` when no finite value remains.
    pub fn of(values: &[f64]) -> Option<Spread> {
        let sorted = finite_sorted(values);
        let median = quantile(&sorted, 0.5)?;
        let q1 = quantile(&sorted, 0.25)?;
        let q3 = quantile(&sorted, 0.75)?;
        Some(Spread {
            n: sorted.len(),
            median,
            q1,
            q3,
            iqr: q3 - q1,
        })
    }
}

/// The result of comparing two groups, `a` and `b`, by the Mann-Whitney U test.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct MannWhitney {
    /// The U of group `a`: the number of pairs (x from `a`, y from `b`) with x > y, a tie
    /// counting one half. It runs from 0 to `n_a n_b` and is large when `a`'s values are
    /// larger; `b`'s U is `n_a n_b - u`.
    pub u: f64,
    /// The standard normal deviate of `u`, with the tie-corrected variance and a continuity
    /// correction of one half toward the mean; 0 when all values are equal or `u` lies within
    /// one half of its mean. Always given, even when `p` is exact. Positive when `a` tends
    /// larger.
    pub z: f64,
    /// The two-sided p value, in [0, 1] (0 only where the normal approximation's tail
    /// underflows, |z| beyond about 38).
    pub p: f64,
    /// Whether `p` is exact (no ties, at most [`EXACT_LIMIT`] values in each group) rather
    /// than from the normal approximation.
    pub exact: bool,
    /// The rank-biserial correlation, `2 u / (n_a n_b) - 1`, equal to Cliff's delta: from -1
    /// (every value of `a` below every value of `b`) to 1 (every one above).
    pub rank_biserial: f64,
    /// The common-language effect size, `u / (n_a n_b)`: the probability that a random value
    /// of `a` exceeds a random value of `b`, a tie counting one half.
    pub common_language: f64,
}

/// Compares groups `a` and `b` (in any order) by the Mann-Whitney U test; see
/// [`MannWhitney`] for what is reported. Values that are not finite are left out. `None`
/// when either group has no finite value.
///
/// The pooled values are ranked from 1, tied values sharing the mean of their ranks (their
/// midrank); `u = R_a - n_a (n_a + 1) / 2`, where `R_a` is the sum of `a`'s ranks. When
/// there are no ties and both groups have at most [`EXACT_LIMIT`] values, the p value is
/// `min(1, 2 min(P(U <= u), P(U >= u)))` under the exact null distribution
/// ([`u_distribution`]). Otherwise it is `2 (1 - Phi(|z|))`, capped at 1, with mean
/// `mu = n_a n_b / 2`, variance `n_a n_b / 12 ((N + 1) - sum(t^3 - t) / (N (N - 1)))` (`N`
/// the pooled count, `t` the size of each group of tied values) and
/// `z = (u - mu - sign(u - mu) / 2) / sigma`.
pub fn mann_whitney(a: &[f64], b: &[f64]) -> Option<MannWhitney> {
    let a = finite_sorted(a);
    let b = finite_sorted(b);
    if a.is_empty() || b.is_empty() {
        return None;
    }
    let (na, nb) = (a.len(), b.len());
    let total = na + nb;

    // Pool, with a flag for membership of `a`, and sort by value.
    let mut pooled: Vec<(f64, bool)> = a
        .iter()
        .map(|&x| (x, true))
        .chain(b.iter().map(|&y| (y, false)))
        .collect();
    pooled.sort_by(|l, r| l.0.total_cmp(&r.0));

    // Midranks: the run of equal values at positions i..j (from 0) holds ranks i+1 ..= j,
    // whose mean is (i + 1 + j) / 2.
    let mut rank_sum_a = 0.0;
    let mut tie_sum = 0.0;
    let mut i = 0;
    while i < total {
        let mut j = i + 1;
        while j < total && pooled[j].0 == pooled[i].0 {
            j += 1;
        }
        let midrank = (i + 1 + j) as f64 / 2.0;
        let in_a = pooled[i..j].iter().filter(|v| v.1).count();
        rank_sum_a += midrank * in_a as f64;
        let t = (j - i) as f64;
        tie_sum += t * t * t - t;
        i = j;
    }

    let (fa, fb, fnn) = (na as f64, nb as f64, total as f64);
    let pairs = fa * fb;
    let u = rank_sum_a - fa * (fa + 1.0) / 2.0;

    // Normal approximation, tie-corrected. With all values equal the bracket is exactly 0:
    // sum(t^3 - t) = N^3 - N, and (N^3 - N) / (N (N - 1)) = N + 1 exactly in f64 for any
    // sample that fits in memory.
    let mu = pairs / 2.0;
    let variance = pairs / 12.0 * ((fnn + 1.0) - tie_sum / (fnn * (fnn - 1.0)));
    let diff = u - mu;
    let z = if variance <= 0.0 || diff.abs() <= 0.5 {
        0.0
    } else {
        (diff - diff.signum() * 0.5) / variance.sqrt()
    };

    let exact = tie_sum == 0.0 && na <= EXACT_LIMIT && nb <= EXACT_LIMIT;
    let p = if exact {
        exact_p(na, nb, u)
    } else if variance <= 0.0 {
        1.0
    } else {
        // 2 (1 - Phi(|z|)) = erfc(|z| / sqrt 2), without the cancellation of 1 - Phi.
        erfc(z.abs() * std::f64::consts::FRAC_1_SQRT_2).min(1.0)
    };

    Some(MannWhitney {
        u,
        z,
        p,
        exact,
        rank_biserial: 2.0 * u / pairs - 1.0,
        common_language: u / pairs,
    })
}

/// Whether the comparison separates the groups at significance level `alpha`: `p < alpha`.
/// [`ALPHA`] is the usual level.
pub fn separates(mw: &MannWhitney, alpha: f64) -> bool {
    mw.p < alpha
}

/// The null distribution of the Mann-Whitney U for groups of `m` and `n` values with no
/// ties: element `k` (for `k` in `0 ..= m n`) is the number of the C(m + n, m) equally likely
/// orderings of the pooled values in which exactly `k` pairs (x from the first group, y from
/// the second) have x > y. Meant for small groups (see [`EXACT_LIMIT`]): the work grows as
/// `(m n)^2` and the counts are exact only while below 2^53.
///
/// Built from the recurrence on the largest value: it belongs to the first group (beating
/// all `n` of the second) or to the second (beating none), so
/// `f(m, n, k) = f(m - 1, n, k - n) + f(m, n - 1, k)`, with `f(0, n, k) = f(m, 0, k) = [k = 0]`.
pub fn u_distribution(m: usize, n: usize) -> Vec<f64> {
    // `row[j]` is the distribution f(i, j, .) for the current `i`; it has i j + 1 entries.
    let mut row: Vec<Vec<f64>> = vec![vec![1.0]; n + 1];
    for i in 1..=m {
        let mut next: Vec<Vec<f64>> = Vec::with_capacity(n + 1);
        next.push(vec![1.0]);
        for j in 1..=n {
            let mut counts = vec![0.0; i * j + 1];
            // Largest value in the second group: f(i, j - 1, k), for k up to i (j - 1).
            for (c, &v) in counts.iter_mut().zip(&next[j - 1]) {
                *c += v;
            }
            // Largest value in the first group: f(i - 1, j, k - j).
            for (c, &v) in counts.iter_mut().skip(j).zip(&row[j]) {
                *c += v;
            }
            next.push(counts);
        }
        row = next;
    }
    row.pop().unwrap_or_else(|| vec![1.0])
}

/// The exact two-sided p value of `u` (a whole number, there being no ties) for groups of
/// `m` and `n` values: `min(1, 2 min(P(U <= u), P(U >= u)))`.
fn exact_p(m: usize, n: usize, u: f64) -> f64 {
    let counts = u_distribution(m, n);
    let total: f64 = counts.iter().sum();
    let k = u.round().max(0.0) as usize;
    let below: f64 = counts.iter().take(k + 1).sum();
    let above: f64 = counts.iter().skip(k).sum();
    (2.0 * below.min(above) / total).min(1.0)
}

/// The standard normal distribution function, Phi(x) = erfc(-x / sqrt 2) / 2.
pub fn normal_cdf(x: f64) -> f64 {
    0.5 * erfc(-x * std::f64::consts::FRAC_1_SQRT_2)
}

/// The complementary error function, erfc(x) = 1 - erf(x), to a relative error of about
/// 1e-12 or better (checked against a reference over -8 to 27). NaN gives NaN.
///
/// Below |x| = 2, the series erf(x) = 2/sqrt(pi) e^(-x^2) sum 2^k x^(2k+1) / (1 3 5 .. (2k+1)),
/// whose terms are all positive (no cancellation); at 2 and above, the continued fraction
/// erfc(x) = e^(-x^2)/sqrt(pi) / (x + (1/2) / (x + 1 / (x + (3/2) / (x + 2 / (x + ..))))),
/// summed from 60 levels down. Negative x uses erfc(-x) = 2 - erfc(x).
pub fn erfc(x: f64) -> f64 {
    if x.is_nan() {
        return f64::NAN;
    }
    let z = x.abs();
    let scale = (-z * z).exp() / std::f64::consts::PI.sqrt();
    let tail = if z < 2.0 {
        let mut term = z;
        let mut sum = z;
        let mut k = 0.0;
        // The ratio of terms, 2 z^2 / (2k + 3), falls below 1/2 once k > 6 (z < 2), so some
        // 60 terms reach 1e-17 of the sum; 200 is only a guard.
        while term > sum * 1e-17 && k < 200.0 {
            term *= 2.0 * z * z / (2.0 * k + 3.0);
            sum += term;
            k += 1.0;
        }
        1.0 - 2.0 * scale * sum
    } else {
        let mut f = z;
        for k in (1..=60).rev() {
            f = z + f64::from(k) / 2.0 / f;
        }
        scale / f
    };
    if x >= 0.0 { tail } else { 2.0 - tail }
}

/// The finite values of `values`, ascending.
fn finite_sorted(values: &[f64]) -> Vec<f64> {
    let mut out: Vec<f64> = values.iter().copied().filter(|v| v.is_finite()).collect();
    out.sort_by(f64::total_cmp);
    out
}

#[cfg(test)]
#[path = "stats_tests.rs"]
mod tests;
