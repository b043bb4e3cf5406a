//! Quantiles, spreads, the normal distribution and the Mann-Whitney test against values worked
//! out by hand (the arithmetic in the comments).

use super::{
    ALPHA, EXACT_LIMIT, Spread, erfc, mann_whitney, normal_cdf, quantile, separates, u_distribution,
};

fn close(got: f64, want: f64, tol: f64) {
    assert!(
        (got - want).abs() <= tol,
        "got {got}, want {want} (within {tol})"
    );
}

#[test]
fn quantile_is_type_7() {
    let x = [1.0, 2.0, 3.0, 4.0];
    // n = 4, h = 3p. p = 0.25: h = 0.75, x[0] + 0.75 (x[1] - x[0]) = 1 + 0.75 = 1.75.
    close(quantile(&x, 0.25).unwrap(), 1.75, 1e-12);
    // p = 0.5: h = 1.5, 2 + 0.5 (3 - 2) = 2.5.
    close(quantile(&x, 0.5).unwrap(), 2.5, 1e-12);
    // p = 0.75: h = 2.25, 3 + 0.25 (4 - 3) = 3.25.
    close(quantile(&x, 0.75).unwrap(), 3.25, 1e-12);
    // The ends are the extremes.
    close(quantile(&x, 0.0).unwrap(), 1.0, 0.0);
    close(quantile(&x, 1.0).unwrap(), 4.0, 0.0);
    // One value is every quantile.
    for p in [0.0, 0.1, 0.5, 0.9, 1.0] {
        close(quantile(&[7.0], p).unwrap(), 7.0, 0.0);
    }
}

#[test]
fn quantile_refuses_empty_input_and_p_outside_0_1() {
    assert_eq!(quantile(&[], 0.5), None);
    assert_eq!(quantile(&[1.0, 2.0], -0.01), None);
    assert_eq!(quantile(&[1.0, 2.0], 1.01), None);
    assert_eq!(quantile(&[1.0, 2.0], f64::NAN), None);
}

#[test]
fn spread_of_five_values() {
    // Sorted: 1 2 3 4 5, h = 4p: median at h = 2 (3), q1 at h = 1 (2), q3 at h = 3 (4).
    let s = Spread::of(&[3.0, 1.0, 2.0, 5.0, 4.0]).unwrap();
    assert_eq!(s.n, 5);
    close(s.median, 3.0, 1e-12);
    close(s.q1, 2.0, 1e-12);
    close(s.q3, 4.0, 1e-12);
    close(s.iqr, 2.0, 1e-12);
}

#[test]
fn spread_ignores_values_that_are_not_finite() {
    let s = Spread::of(&[
        3.0,
        f64::NAN,
        1.0,
        2.0,
        f64::INFINITY,
        5.0,
        4.0,
        f64::NEG_INFINITY,
    ]);
    assert_eq!(s, Spread::of(&[1.0, 2.0, 3.0, 4.0, 5.0]));
    assert_eq!(Spread::of(&[]), None);
    assert_eq!(Spread::of(&[f64::NAN, f64::INFINITY]), None);
}

#[test]
fn u_distribution_counts_by_hand() {
    // m = n = 1: a above b or below: U = 0 or 1, once each.
    assert_eq!(u_distribution(1, 1), vec![1.0, 1.0]);
    // m = n = 2, the 6 orderings (a's positions among 4): {1,2} U=0, {1,3} 1, {1,4} 2,
    // {2,3} 2, {2,4} 3, {3,4} 4.
    assert_eq!(u_distribution(2, 2), vec![1.0, 1.0, 2.0, 1.0, 1.0]);
    // m = n = 3, the 20 orderings: U = (sum of a's positions among 6) - 6; the number of
    // 3-subsets of 1..6 with each sum 6..15 is 1 1 2 3 3 3 3 2 1 1.
    let three = u_distribution(3, 3);
    assert_eq!(
        three,
        vec![1.0, 1.0, 2.0, 3.0, 3.0, 3.0, 3.0, 2.0, 1.0, 1.0]
    );
    assert_eq!(three.iter().sum::<f64>(), 20.0);
    // An empty group leaves one ordering, with U = 0.
    assert_eq!(u_distribution(0, 4), vec![1.0]);
    assert_eq!(u_distribution(4, 0), vec![1.0]);
    // Uneven groups: m = 1, n = 3: a's one value beats 0, 1, 2 or 3 of b's, once each.
    assert_eq!(u_distribution(1, 3), vec![1.0; 4]);
}

#[test]
fn u_distribution_is_exact_at_the_limit() {
    let counts = u_distribution(EXACT_LIMIT, EXACT_LIMIT);
    assert_eq!(counts.len(), EXACT_LIMIT * EXACT_LIMIT + 1);
    // C(40, 20) = 137846528820, held exactly.
    assert_eq!(counts.iter().sum::<f64>(), 137_846_528_820.0);
    // Symmetric about the mean, 200.
    assert!(counts.iter().eq(counts.iter().rev()));
}

#[test]
fn normal_distribution_function() {
    close(normal_cdf(0.0), 0.5, 1e-9);
    close(normal_cdf(1.959_963_985), 0.975, 1e-7);
    // Phi(-3) = erfc(3 / sqrt 2) / 2 = 0.0013498980316...
    close(normal_cdf(-3.0), 0.001_349_898_0, 1e-8);
    close(normal_cdf(3.0), 1.0 - 0.001_349_898_0, 1e-8);
    close(erfc(0.0), 1.0, 1e-7);
    // Reference values from python's math.erfc, to a relative 1e-11, on both sides of the
    // switch from series to continued fraction at 2.
    for (x, want) in [
        (0.5, 0.479_500_122_186_953_5),
        (1.0, 0.157_299_207_050_285_13),
        (1.999, 0.004_698_443_348_629_488),
        (2.0, 0.004_677_734_981_047_266),
        (3.0, 2.209_049_699_858_544e-5),
        (5.0, 1.537_459_794_428_035e-12),
    ] {
        close(erfc(x), want, want * 1e-11);
        close(erfc(-x), 2.0 - want, want * 1e-11 + 1e-15);
    }
    assert_eq!(erfc(f64::INFINITY), 0.0);
    assert_eq!(erfc(f64::NEG_INFINITY), 2.0);
    assert!(erfc(f64::NAN).is_nan());
}

#[test]
fn all_of_a_below_b_exactly() {
    // a = 1 2 3 take ranks 1 2 3: R_a = 6, U_a = 6 - 3 * 4 / 2 = 0 (no a beats any b).
    let mw = mann_whitney(&[1.0, 2.0, 3.0], &[4.0, 5.0, 6.0]).unwrap();
    close(mw.u, 0.0, 1e-12);
    assert!(mw.exact);
    // Only 1 of the C(6, 3) = 20 orderings gives U = 0: P(U <= 0) = 1/20, p = 2/20 = 0.1.
    close(mw.p, 0.1, 1e-12);
    close(mw.rank_biserial, -1.0, 1e-12);
    close(mw.common_language, 0.0, 1e-12);
    // z is still reported: mu = 9/2 = 4.5, sigma^2 = 9/12 * 7 = 5.25, sigma = 2.2912878...,
    // z = (0 - 4.5 + 0.5) / 2.2912878 = -1.7457431...
    close(mw.z, -1.745_743_121_887_939, 1e-9);
    assert!(!separates(&mw, ALPHA));
}

#[test]
fn all_of_a_above_b_exactly() {
    // a takes ranks 6..10: R_a = 40, U_a = 40 - 5 * 6 / 2 = 25 = n_a n_b.
    let mw = mann_whitney(&[6.0, 7.0, 8.0, 9.0, 10.0], &[1.0, 2.0, 3.0, 4.0, 5.0]).unwrap();
    close(mw.u, 25.0, 1e-12);
    assert!(mw.exact);
    // P(U >= 25) = 1/C(10, 5) = 1/252; p = 2/252 = 0.0079365079...
    close(mw.p, 2.0 / 252.0, 1e-12);
    close(mw.p, 0.007_936_507_936_507_936, 1e-15);
    close(mw.rank_biserial, 1.0, 1e-12);
    close(mw.common_language, 1.0, 1e-12);
    // mu = 12.5, sigma^2 = 25/12 * 11 = 22.9166..., sigma = 4.7871355...,
    // z = (25 - 12.5 - 0.5) / 4.7871355 = 2.5067182...
    close(mw.z, 2.506_718_245_762_049, 1e-9);
    assert!(separates(&mw, ALPHA));
    assert!(!separates(&mw, 0.005));
}

#[test]
fn interleaved_groups_exactly() {
    // Pairs with a > b: 1 beats none (0), 4 beats 2 and 3 (2), 6 beats 2, 3 and 5 (3): U_a = 5.
    // From the ranks: pooled 1 2 3 4 5 6, a holds ranks 1 4 6, R_a = 11, U_a = 11 - 6 = 5.
    let mw = mann_whitney(&[1.0, 4.0, 6.0], &[2.0, 3.0, 5.0]).unwrap();
    close(mw.u, 5.0, 1e-12);
    assert!(mw.exact);
    // Counts for U = 0..9: 1 1 2 3 3 3 3 2 1 1 (sum 20).
    // P(U >= 5) = (3+3+2+1+1)/20 = 0.5, P(U <= 5) = (1+1+2+3+3+3)/20 = 0.65, p = min(1, 1.0).
    close(mw.p, 1.0, 1e-12);
    // mu = 4.5, |U - mu| = 0.5: within the continuity correction, z = 0.
    close(mw.z, 0.0, 0.0);
    // 2 * 5 / 9 - 1 = 1/9; 5/9.
    close(mw.rank_biserial, 1.0 / 9.0, 1e-12);
    close(mw.common_language, 5.0 / 9.0, 1e-12);
}

#[test]
fn the_order_of_the_groups_flips_u() {
    let ab = mann_whitney(&[1.0, 4.0, 6.0, 7.0], &[2.0, 3.0, 5.0]).unwrap();
    let ba = mann_whitney(&[2.0, 3.0, 5.0], &[1.0, 4.0, 6.0, 7.0]).unwrap();
    close(ab.u + ba.u, 12.0, 1e-12);
    close(ab.p, ba.p, 1e-12);
    close(ab.z, -ba.z, 1e-12);
    close(ab.rank_biserial, -ba.rank_biserial, 1e-12);
}

#[test]
fn ties_take_the_normal_approximation() {
    // a = 0 0 0 1 2, b = 1 2 3 3 4. Pooled and sorted, with positions and midranks:
    //   value    0 0 0 | 1 1 | 2 2 | 3 3 | 4
    //   position 1 2 3 | 4 5 | 6 7 | 8 9 | 10
    //   midrank  2 2 2 | 4.5 4.5 | 6.5 6.5 | 8.5 8.5 | 10
    // a holds 0 0 0 (2 each), one 1 (4.5) and one 2 (6.5): R_a = 6 + 4.5 + 6.5 = 17,
    // U_a = 17 - 5 * 6 / 2 = 2. (Pairs: the 0s beat nothing, 1 ties b's 1 (0.5),
    // 2 beats b's 1 and ties its 2 (1.5): 2.)
    // Tie groups t = 3, 2, 2, 2: sum(t^3 - t) = 24 + 6 + 6 + 6 = 42.
    // mu = 25 / 2 = 12.5; N = 10, sigma^2 = 25/12 * (11 - 42/90) = 25/12 * 10.5333... = 21.9444...,
    // sigma = 4.6844897741850655.
    // z = (2 - 12.5 + 0.5) / sigma = -10 / 4.68448977 = -2.13470420089446.
    // p = 2 (1 - Phi(2.1347042)) = erfc(2.1347042 / sqrt 2) = 0.032785179644154665
    // (python: math.erfc(2.13470420089446 / math.sqrt(2))).
    let mw = mann_whitney(&[0.0, 0.0, 0.0, 1.0, 2.0], &[1.0, 2.0, 3.0, 3.0, 4.0]).unwrap();
    close(mw.u, 2.0, 1e-12);
    assert!(!mw.exact);
    close(mw.z, -2.134_704_200_894_46, 1e-9);
    close(mw.p, 0.032_785_179_644_154_665, 1e-6);
    // 2 * 2 / 25 - 1 = -0.84; 2 / 25 = 0.08.
    close(mw.rank_biserial, -0.84, 1e-12);
    close(mw.common_language, 0.08, 1e-12);
    assert!(separates(&mw, ALPHA));
    assert!(!separates(&mw, 0.01));
}

#[test]
fn equal_groups_do_not_separate() {
    // Every value ties: U = n_a n_b / 2 = 6 = mu, the tie-corrected variance is 0: z = 0, p = 1.
    let mw = mann_whitney(&[0.0, 0.0, 0.0], &[0.0, 0.0, 0.0, 0.0]).unwrap();
    close(mw.u, 6.0, 1e-12);
    close(mw.z, 0.0, 0.0);
    close(mw.p, 1.0, 0.0);
    assert!(!mw.exact);
    close(mw.rank_biserial, 0.0, 1e-12);
    close(mw.common_language, 0.5, 1e-12);
    assert!(!separates(&mw, ALPHA));
    // One value each, equal.
    let one = mann_whitney(&[3.0], &[3.0]).unwrap();
    close(one.p, 1.0, 0.0);
    close(one.z, 0.0, 0.0);
}

#[test]
fn empty_groups_give_nothing_and_nan_is_ignored() {
    assert_eq!(mann_whitney(&[], &[1.0]), None);
    assert_eq!(mann_whitney(&[1.0], &[]), None);
    assert_eq!(mann_whitney(&[f64::NAN, f64::NAN], &[1.0, 2.0]), None);
    assert_eq!(mann_whitney(&[1.0, 2.0], &[f64::INFINITY]), None);
    let with_nan = mann_whitney(&[f64::NAN, 1.0, 2.0, 3.0], &[4.0, f64::NAN, 5.0, 6.0]);
    assert_eq!(with_nan, mann_whitney(&[1.0, 2.0, 3.0], &[4.0, 5.0, 6.0]));
}

#[test]
fn large_groups_take_the_normal_approximation() {
    // a = 0..25, b = 25..50, no ties, 25 > EXACT_LIMIT each: U_a = 0, normal path.
    // mu = 625/2 = 312.5, sigma^2 = 625/12 * 51 = 2656.25, sigma = 51.53882032022076,
    // z = (0 - 312.5 + 0.5) / sigma = -6.053689200906871, p = erfc(6.0536892 / sqrt 2)
    // = 1.4156562248495634e-09 (python).
    let a: Vec<f64> = (0..25).map(f64::from).collect();
    let b: Vec<f64> = (25..50).map(f64::from).collect();
    let mw = mann_whitney(&a, &b).unwrap();
    assert!(!mw.exact);
    close(mw.u, 0.0, 1e-12);
    close(mw.z, -6.053_689_200_906_871, 1e-9);
    close(mw.p, 1.415_656_224_849_563_4e-9, 1.5e-9 * 1.2e-7);
    close(mw.rank_biserial, -1.0, 1e-12);
    // Interleaved evens and odds: a = 0 2 .. 48, b = 1 3 .. 49. Each a = 2i beats the
    // b values 1 .. 2i - 1, i of them: U_a = 0 + 1 + .. + 24 = 300.
    // z = (300 - 312.5 + 0.5) / 51.53882 = -12 / 51.53882 = -0.2328323...
    let evens: Vec<f64> = (0..25).map(|i| f64::from(2 * i)).collect();
    let odds: Vec<f64> = (0..25).map(|i| f64::from(2 * i + 1)).collect();
    let mw = mann_whitney(&evens, &odds).unwrap();
    assert!(!mw.exact);
    close(mw.u, 300.0, 1e-12);
    close(mw.z, -12.0 / 51.538_820_320_220_76, 1e-12);
    assert!(mw.p > 0.8 && mw.p < 0.85);
}

#[test]
fn the_exact_limit_is_inclusive() {
    let a: Vec<f64> = (0..EXACT_LIMIT).map(|i| i as f64).collect();
    let b: Vec<f64> = (0..EXACT_LIMIT).map(|i| (i + EXACT_LIMIT) as f64).collect();
    let mw = mann_whitney(&a, &b).unwrap();
    assert!(mw.exact);
    // One ordering in C(40, 20) gives U = 0: p = 2 / 137846528820.
    close(mw.p, 2.0 / 137_846_528_820.0, 1e-22);
}
