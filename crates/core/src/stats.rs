//! Distribution functions and robust scales for the significance tests of identification and
//! diagnosis: the upper tail of the F distribution (through the regularised incomplete beta
//! function, Lentz's continued fraction), the χ² distribution with 3 degrees of freedom (one
//! 3-D residual), the complementary error function, the median and the MAD scale.
//!
//! Low level on purpose: it depends on std and nalgebra only, so `identification` and
//! `diagnosis` both use it without importing each other.

use nalgebra::Vector3;

/// ln Γ(x) for x > 0 (Lanczos, g = 7, n = 9; relative error below 1e-13).
pub fn ln_gamma(x: f64) -> f64 {
    const C: [f64; 9] = [
        0.999_999_999_999_809_9,
        676.520_368_121_885_1,
        -1_259.139_216_722_402_8,
        771.323_428_777_653_1,
        -176.615_029_162_140_6,
        12.507_343_278_686_905,
        -0.138_571_095_265_720_12,
        9.984_369_578_019_572e-6,
        1.505_632_735_149_311_6e-7,
    ];
    if x < 0.5 {
        let pi = std::f64::consts::PI;
        return (pi / (pi * x).sin()).ln() - ln_gamma(1.0 - x);
    }
    let x = x - 1.0;
    let mut a = C[0];
    let t = x + 7.5;
    for (i, c) in C.iter().enumerate().skip(1) {
        a += c / (x + i as f64);
    }
    0.5 * (2.0 * std::f64::consts::PI).ln() + (x + 0.5) * t.ln() - t + a.ln()
}

/// The regularised incomplete beta function I_x(a, b) for a, b > 0 (0 at x ≤ 0, 1 at x ≥ 1).
pub fn inc_beta(a: f64, b: f64, x: f64) -> f64 {
    if x <= 0.0 {
        return 0.0;
    }
    if x >= 1.0 {
        return 1.0;
    }
    let ln_front = ln_gamma(a + b) - ln_gamma(a) - ln_gamma(b) + a * x.ln() + b * (1.0 - x).ln();
    if x < (a + 1.0) / (a + b + 2.0) {
        (ln_front.exp() * beta_cf(a, b, x) / a).clamp(0.0, 1.0)
    } else {
        (1.0 - ln_front.exp() * beta_cf(b, a, 1.0 - x) / b).clamp(0.0, 1.0)
    }
}

/// The continued fraction of I_x(a, b) (modified Lentz), which converges quickly for
/// x < (a + 1)/(a + b + 2); [`inc_beta`] uses the symmetry I_x(a, b) = 1 − I_(1−x)(b, a) otherwise.
fn beta_cf(a: f64, b: f64, x: f64) -> f64 {
    const TINY: f64 = 1e-300;
    let (qab, qap, qam) = (a + b, a + 1.0, a - 1.0);
    let mut c = 1.0;
    let mut d = 1.0 - qab * x / qap;
    if d.abs() < TINY {
        d = TINY;
    }
    d = 1.0 / d;
    let mut h = d;
    for m in 1..500 {
        let m = m as f64;
        let m2 = 2.0 * m;
        let aa = m * (b - m) * x / ((qam + m2) * (a + m2));
        d = 1.0 + aa * d;
        d = if d.abs() < TINY { TINY } else { d };
        c = 1.0 + aa / c;
        c = if c.abs() < TINY { TINY } else { c };
        d = 1.0 / d;
        h *= d * c;
        let aa = -(a + m) * (qab + m) * x / ((a + m2) * (qap + m2));
        d = 1.0 + aa * d;
        d = if d.abs() < TINY { TINY } else { d };
        c = 1.0 + aa / c;
        c = if c.abs() < TINY { TINY } else { c };
        d = 1.0 / d;
        let del = d * c;
        h *= del;
        if (del - 1.0).abs() < 1e-15 {
            break;
        }
    }
    h
}

/// P(F > f) for an F distribution with (d1, d2) degrees of freedom.
pub fn f_sf(f: f64, d1: f64, d2: f64) -> f64 {
    if !f.is_finite() {
        return if f > 0.0 { 0.0 } else { 1.0 };
    }
    if f <= 0.0 || d1 <= 0.0 || d2 <= 0.0 {
        return 1.0;
    }
    inc_beta(d2 / 2.0, d1 / 2.0, d2 / (d2 + d1 * f))
}

/// ln P(F > f) for an F distribution with (d1, d2) degrees of freedom, accurate where the
/// tail itself underflows (a 10× effect over thousands of rows has p far below 1e-308): the
/// diagnosis ranks terms by it, and ties at p = 0 would rank by library order instead.
pub fn ln_f_sf(f: f64, d1: f64, d2: f64) -> f64 {
    if !f.is_finite() {
        return if f > 0.0 { f64::NEG_INFINITY } else { 0.0 };
    }
    if f <= 0.0 || d1 <= 0.0 || d2 <= 0.0 {
        return 0.0;
    }
    let (a, b) = (d2 / 2.0, d1 / 2.0);
    let x = d2 / (d2 + d1 * f);
    if x <= 0.0 {
        return f64::NEG_INFINITY;
    }
    if x >= 1.0 {
        return 0.0;
    }
    let ln_front = ln_gamma(a + b) - ln_gamma(a) - ln_gamma(b) + a * x.ln() + b * (1.0 - x).ln();
    if x < (a + 1.0) / (a + b + 2.0) {
        ln_front + beta_cf(a, b, x).ln() - a.ln()
    } else {
        (1.0 - ln_front.exp() * beta_cf(b, a, 1.0 - x) / b)
            .clamp(f64::MIN_POSITIVE, 1.0)
            .ln()
    }
}

/// Upper tail of χ² with 3 degrees of freedom: erfc(√(x/2)) + √(2x/π)·e^(−x/2).
pub fn chi2_3_sf(x: f64) -> f64 {
    if x <= 0.0 {
        return 1.0;
    }
    erfc((x / 2.0).sqrt()) + (2.0 * x / std::f64::consts::PI).sqrt() * (-x / 2.0).exp()
}

/// Complementary error function (Numerical Recipes' erfcc; relative error below 1.2e-7).
pub fn erfc(x: f64) -> f64 {
    let z = x.abs();
    let t = 1.0 / (1.0 + 0.5 * z);
    let r = t
        * (-z * z - 1.265_512_23
            + t * (1.000_023_68
                + t * (0.374_091_96
                    + t * (0.096_784_18
                        + t * (-0.186_288_06
                            + t * (0.278_868_07
                                + t * (-1.135_203_98
                                    + t * (1.488_515_87
                                        + t * (-0.822_152_23 + t * 0.170_872_77)))))))))
            .exp();
    if x >= 0.0 {
        r
    } else {
        2.0 - r
    }
}

/// The χ²(3) quantile with upper tail `p` (bisection on [0, 1000]).
pub fn chi2_3_isf(p: f64) -> f64 {
    let (mut lo, mut hi) = (0.0, 1000.0);
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if chi2_3_sf(mid) > p {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

/// σ per coordinate from the median absolute deviation of every coordinate of `r` (mm); the
/// factor 1.4826 = 1/Φ⁻¹(3/4) makes it σ for Gaussian noise, and half the coordinates may be
/// gross errors before it moves. 0 for no residuals.
pub fn mad_sigma(r: &[Vector3<f64>]) -> f64 {
    let mut v: Vec<f64> = r.iter().flat_map(|x| x.iter().copied()).collect();
    if v.is_empty() {
        return 0.0;
    }
    let med = median_unordered(&mut v);
    let mut dev: Vec<f64> = v.iter().map(|x| (x - med).abs()).collect();
    1.4826 * median_unordered(&mut dev)
}

/// [`median`] by selection, leaving `v` unordered: the same value in O(n) rather than a sort
/// (the outlier searches take it once per removal).
fn median_unordered(v: &mut [f64]) -> f64 {
    let n = v.len();
    if n == 0 {
        return f64::NAN;
    }
    let (below, mid, _) = v.select_nth_unstable_by(n / 2, f64::total_cmp);
    let mid = *mid;
    if n % 2 == 1 {
        mid
    } else {
        let lower = below.iter().copied().max_by(f64::total_cmp).unwrap_or(mid);
        0.5 * (lower + mid)
    }
}

/// The median of `v`, sorted in place (by `f64::total_cmp`); NaN for an empty slice.
pub fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n == 0 {
        f64::NAN
    } else if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    fn close(got: f64, want: f64, tol: f64) {
        assert!(
            (got - want).abs() <= tol,
            "got {got}, want {want} (tolerance {tol})"
        );
    }

    #[test]
    fn ln_gamma_matches_factorials_and_half_integers() {
        // Γ(n) = (n − 1)!, Γ(1/2) = √π, Γ(3/2) = √π/2, Γ(0.1) = 9.513507698668732 (reflection
        // branch below 1/2).
        close(ln_gamma(1.0), 0.0, 1e-13);
        close(ln_gamma(2.0), 0.0, 1e-13);
        close(ln_gamma(5.0), 24f64.ln(), 1e-12);
        close(ln_gamma(10.0), 362_880f64.ln(), 1e-11);
        close(ln_gamma(0.5), PI.sqrt().ln(), 1e-13);
        close(ln_gamma(1.5), (PI.sqrt() / 2.0).ln(), 1e-13);
        close(ln_gamma(0.1), 9.513_507_698_668_732f64.ln(), 1e-12);
        // ln Γ(101) = ln 100! = 363.73937555556347.
        close(ln_gamma(101.0), 363.739_375_555_563_47, 1e-9);
    }

    #[test]
    fn ln_f_sf_is_the_log_tail_even_where_the_tail_underflows() {
        // F(2, d2): P(F > f) = (1 + 2f/d2)^(−d2/2), so ln P = −(d2/2)·ln(1 + 2f/d2).
        for &(f, d2) in &[
            (0.5f64, 10.0f64),
            (3.0, 40.0),
            (50.0, 200.0),
            (1e6, 1000.0),
            (1e9, 1800.0),
        ] {
            let want = -(d2 / 2.0) * (1.0 + 2.0 * f / d2).ln();
            close(ln_f_sf(f, 2.0, d2), want, 1e-9 * want.abs().max(1.0));
        }
        // Where the tail is representable it is ln of f_sf; 0 at f ≤ 0.
        for &(f, d1, d2) in &[(1.3, 3.0, 50.0), (8.0, 20.0, 1500.0), (0.2, 7.0, 90.0)] {
            close(ln_f_sf(f, d1, d2), f_sf(f, d1, d2).ln(), 1e-9);
        }
        assert_eq!(ln_f_sf(0.0, 3.0, 10.0), 0.0);
        assert!(f_sf(1e9, 2.0, 1800.0) == 0.0 && ln_f_sf(1e9, 2.0, 1800.0) < -1e4);
    }

    #[test]
    fn inc_beta_matches_closed_forms() {
        for &x in &[0.01, 0.2, 0.5, 0.7, 0.99] {
            // I_x(1, 1) = x, I_x(a, 1) = x^a, I_x(1, b) = 1 − (1 − x)^b, I_x(2, 2) = 3x² − 2x³.
            close(inc_beta(1.0, 1.0, x), x, 1e-12);
            close(inc_beta(3.5, 1.0, x), x.powf(3.5), 1e-12);
            close(inc_beta(1.0, 4.0, x), 1.0 - (1.0 - x).powi(4), 1e-12);
            close(inc_beta(2.0, 2.0, x), 3.0 * x * x - 2.0 * x.powi(3), 1e-12);
            // Symmetry: I_x(a, b) = 1 − I_(1−x)(b, a).
            close(
                inc_beta(2.5, 7.0, x),
                1.0 - inc_beta(7.0, 2.5, 1.0 - x),
                1e-12,
            );
        }
        close(inc_beta(6.0, 6.0, 0.5), 0.5, 1e-12);
        assert_eq!(inc_beta(2.0, 3.0, 0.0), 0.0);
        assert_eq!(inc_beta(2.0, 3.0, 1.0), 1.0);
    }

    #[test]
    fn f_tail_matches_closed_forms() {
        for &f in &[0.1, 0.5, 1.0, 2.0, 10.0, 100.0] {
            // F(1, 1): P(F > f) = 1 − (2/π)·atan √f.
            close(f_sf(f, 1.0, 1.0), 1.0 - 2.0 / PI * f.sqrt().atan(), 1e-12);
            // F(2, d2): P(F > f) = (1 + 2f/d2)^(−d2/2).
            for &d2 in &[2.0, 7.0, 60.0] {
                close(
                    f_sf(f, 2.0, d2),
                    (1.0 + 2.0 * f / d2).powf(-d2 / 2.0),
                    1e-12,
                );
            }
        }
        // Degenerate arguments: nothing to reject.
        assert_eq!(f_sf(0.0, 3.0, 10.0), 1.0);
        assert_eq!(f_sf(-1.0, 3.0, 10.0), 1.0);
        assert_eq!(f_sf(f64::INFINITY, 3.0, 10.0), 0.0);
        assert_eq!(f_sf(f64::NAN, 3.0, 10.0), 1.0);
        assert_eq!(f_sf(2.0, 0.0, 10.0), 1.0);
    }

    #[test]
    fn f_tail_matches_tables() {
        // Upper critical values of F (NIST/SEMATECH e-Handbook, tables 1.3.6.7.2):
        // F(0.95; 3, 100) = 2.696, F(0.95; 5, 10) = 3.326, F(0.99; 1, 10) = 10.044,
        // F(0.99; 10, 1000) = 2.334 (interpolated), F(0.5; 1, 1) = 1.
        close(f_sf(2.696, 3.0, 100.0), 0.05, 5e-4);
        close(f_sf(3.326, 5.0, 10.0), 0.05, 2e-4);
        close(f_sf(10.044, 1.0, 10.0), 0.01, 1e-4);
        close(f_sf(2.334, 10.0, 1000.0), 0.01, 2e-4);
        close(f_sf(1.0, 1.0, 1.0), 0.5, 1e-9);
    }

    #[test]
    fn erfc_matches_reference_values() {
        // erfc(0) = 1, erfc(0.5) = 0.4795001221869535, erfc(1) = 0.15729920705028513,
        // erfc(2) = 0.004677734981047266, erfc(3) = 2.209049699858544e-5; erfc(−x) = 2 − erfc(x).
        let table = [
            (0.0, 1.0),
            (0.5, 0.479_500_122_186_953_5),
            (1.0, 0.157_299_207_050_285_13),
            (2.0, 0.004_677_734_981_047_266),
            (3.0, 2.209_049_699_858_544e-5),
        ];
        for (x, want) in table {
            close(erfc(x), want, 1.2e-7 * want);
            close(erfc(-x), 2.0 - want, 1.2e-7 * 2.0);
        }
    }

    #[test]
    fn chi2_3_tail_matches_tables() {
        // χ²₃: P(X > 7.815) = 0.05, P(X > 11.345) = 0.01, P(X > 16.266) = 0.001, and the
        // median 2.366 (NIST/SEMATECH table 1.3.6.7.4).
        close(chi2_3_sf(7.815), 0.05, 1e-4);
        close(chi2_3_sf(11.345), 0.01, 1e-5);
        close(chi2_3_sf(16.266), 0.001, 1e-6);
        close(chi2_3_sf(2.366), 0.5, 2e-4);
        assert_eq!(chi2_3_sf(0.0), 1.0);
        close(chi2_3_isf(0.01), 11.345, 1e-2);
        close(chi2_3_isf(0.05), 7.815, 1e-2);
    }

    #[test]
    fn chi2_3_tail_is_the_f_tail_with_infinite_denominator() {
        // χ²₃/3 is F(3, ∞): a large d2 approaches it.
        for &x in &[1.0, 5.0, 12.0] {
            close(f_sf(x / 3.0, 3.0, 1e7), chi2_3_sf(x), 1e-5);
        }
    }

    #[test]
    fn median_of_odd_even_and_unsorted_sets() {
        assert_eq!(median(&mut [3.0, -1.0, 2.0]), 2.0);
        assert_eq!(median(&mut [4.0, 1.0, 3.0, 2.0]), 2.5);
        assert_eq!(median(&mut [7.0]), 7.0);
        assert!(median(&mut []).is_nan());
    }

    #[test]
    fn the_median_by_selection_equals_the_sorted_median() {
        for n in 1..40usize {
            let v: Vec<f64> = (0..n)
                .map(|i| ((i * 37 + 11) % 17) as f64 - 0.5 * i as f64)
                .collect();
            assert_eq!(
                median_unordered(&mut v.clone()),
                median(&mut v.clone()),
                "n = {n}"
            );
        }
    }

    #[test]
    fn mad_sigma_scales_the_median_absolute_deviation() {
        // Coordinates 1..9: median 5, absolute deviations 4 3 2 1 0 1 2 3 4, their median 2.
        let r = [
            Vector3::new(1.0, 2.0, 3.0),
            Vector3::new(4.0, 5.0, 6.0),
            Vector3::new(7.0, 8.0, 9.0),
        ];
        close(mad_sigma(&r), 1.4826 * 2.0, 1e-12);
        // A gross error does not move it: replace 9 by 1000.
        let mut gross = r;
        gross[2].z = 1000.0;
        close(mad_sigma(&gross), 1.4826 * 2.0, 1e-12);
        assert_eq!(mad_sigma(&[]), 0.0);
    }
}
