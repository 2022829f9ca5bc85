//! Measurement-location selection inside a region (seed 000 section 4.1): which of a region's
//! candidate locations to measure, given the ones it already holds (its parent's points that
//! fall in it).
//!
//! Each location contributes a 3-row block J of the identification matrix [M] (the position
//! Jacobian of the CEPs at that pose); a set's information matrix is Σ JᵀJ.
//! - [`Selection::Kappa`] (the paper's): a random start, then random exchanges that lower κ of
//!   eq. (4) (columns scaled to unit norm).
//! - [`Selection::DOptimal`]: greedy forward choice of the location that most increases
//!   det(MᵀM), then exchange passes (Fedorov's) until no single swap increases it. The
//!   determinant is the volume of the parameters' confidence ellipsoid's inverse, so it favours
//!   sets that pin down *every* CEP, and is invariant to how the columns are scaled.

use crate::identification::identifiability::kappa_eq4;
use nalgebra::DMatrix;
use rand::rngs::ChaCha8Rng;
use rand::RngExt;
use serde::{Deserialize, Serialize};

/// How a region's measurement locations are chosen.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Selection {
    /// κ of eq. (4) made small by random exchanges (the paper's rule).
    #[default]
    Kappa,
    /// det(MᵀM) made large: greedy choice, then exchange passes.
    DOptimal,
}

/// Ridge added (relative to the information matrix's mean diagonal) so that the determinant of
/// a set with fewer rows than CEPs still ranks candidates during the greedy start.
const GREEDY_RIDGE: f64 = 1e-6;

/// Most exchange passes of the D-optimal rule (each pass tries every chosen × unchosen swap).
const EXCHANGE_PASSES: usize = 8;

/// Σ JᵀJ over `blocks`.
pub fn information<'a>(
    blocks: impl IntoIterator<Item = &'a DMatrix<f64>>,
    n: usize,
) -> DMatrix<f64> {
    let mut a = DMatrix::zeros(n, n);
    for b in blocks {
        a += b.transpose() * b;
    }
    a
}

/// ln det of a symmetric positive semi-definite matrix; −∞ when it is singular.
pub fn log_det(a: &DMatrix<f64>) -> f64 {
    match a.clone().cholesky() {
        Some(c) => 2.0 * c.l().diagonal().iter().map(|d| d.ln()).sum::<f64>(),
        None => f64::NEG_INFINITY,
    }
}

/// ln det(MᵀM) of `fixed` and the chosen `blocks`.
pub fn log_det_of(fixed: &[DMatrix<f64>], blocks: &[DMatrix<f64>], chosen: &[usize]) -> f64 {
    let n = blocks.first().or(fixed.first()).map_or(0, |b| b.ncols());
    log_det(&information(
        fixed.iter().chain(chosen.iter().map(|&i| &blocks[i])),
        n,
    ))
}

/// κ of eq. (4) of `fixed` and the chosen `blocks` stacked.
pub fn kappa_of(fixed: &[DMatrix<f64>], blocks: &[DMatrix<f64>], chosen: &[usize]) -> f64 {
    let cols = blocks.first().or(fixed.first()).map_or(0, |b| b.ncols());
    let rows = 3 * (fixed.len() + chosen.len());
    let mut m = DMatrix::zeros(rows, cols);
    for (k, bl) in fixed
        .iter()
        .chain(chosen.iter().map(|&i| &blocks[i]))
        .enumerate()
    {
        m.view_mut((3 * k, 0), (bl.nrows(), cols)).copy_from(bl);
    }
    kappa_eq4(&m)
}

/// Chooses `n` of the candidate `blocks` to add to `fixed` by `rule`; indices into `blocks`.
/// The κ rule starts from the first `n` candidates (shuffle them first for a random start) and
/// makes `steps` random exchanges; the D-optimal rule is deterministic.
pub fn choose(
    rule: Selection,
    fixed: &[DMatrix<f64>],
    blocks: &[DMatrix<f64>],
    n: usize,
    steps: usize,
    rng: &mut ChaCha8Rng,
) -> Vec<usize> {
    if blocks.len() <= n {
        return (0..blocks.len()).collect();
    }
    match rule {
        Selection::Kappa => choose_kappa(fixed, blocks, n, steps, rng),
        Selection::DOptimal => choose_d_optimal(fixed, blocks, n),
    }
}

/// The paper's rule: random start, random exchanges kept when they lower κ.
fn choose_kappa(
    fixed: &[DMatrix<f64>],
    blocks: &[DMatrix<f64>],
    n: usize,
    steps: usize,
    rng: &mut ChaCha8Rng,
) -> Vec<usize> {
    let mut chosen: Vec<usize> = (0..n).collect();
    let mut rest: Vec<usize> = (n..blocks.len()).collect();
    let mut best = kappa_of(fixed, blocks, &chosen);
    for _ in 0..steps {
        let i = rng.random_range(0..chosen.len());
        let j = rng.random_range(0..rest.len());
        std::mem::swap(&mut chosen[i], &mut rest[j]);
        let k = kappa_of(fixed, blocks, &chosen);
        if k < best {
            best = k;
        } else {
            std::mem::swap(&mut chosen[i], &mut rest[j]);
        }
    }
    chosen
}

/// Greedy forward choice by det(MᵀM), then Fedorov exchange passes.
fn choose_d_optimal(fixed: &[DMatrix<f64>], blocks: &[DMatrix<f64>], n: usize) -> Vec<usize> {
    let cols = blocks[0].ncols();
    let base = information(fixed, cols);
    let scale = information(blocks.iter(), cols).trace() / (cols as f64 * blocks.len() as f64);
    let ridge = DMatrix::identity(cols, cols) * (GREEDY_RIDGE * scale.max(f64::MIN_POSITIVE));
    let gram: Vec<DMatrix<f64>> = blocks.iter().map(|b| b.transpose() * b).collect();
    let mut chosen: Vec<usize> = Vec::with_capacity(n);
    let mut a = &base + &ridge;
    for _ in 0..n {
        let best = (0..blocks.len())
            .filter(|i| !chosen.contains(i))
            .map(|i| (i, log_det(&(&a + &gram[i]))))
            .max_by(|x, y| x.1.total_cmp(&y.1));
        let Some((i, _)) = best else { break };
        a += &gram[i];
        chosen.push(i);
    }
    // Exchanges on the exact information matrix (no ridge).
    let mut a = &a - &ridge;
    let mut current = log_det(&a);
    for _ in 0..EXCHANGE_PASSES {
        let mut improved = false;
        for k in 0..chosen.len() {
            let without = &a - &gram[chosen[k]];
            let best = (0..blocks.len())
                .filter(|j| !chosen.contains(j))
                .map(|j| (j, log_det(&(&without + &gram[j]))))
                .max_by(|x, y| x.1.total_cmp(&y.1));
            if let Some((j, v)) = best {
                if v > current + 1e-12 * current.abs().max(1.0) {
                    a = &without + &gram[j];
                    chosen[k] = j;
                    current = v;
                    improved = true;
                }
            }
        }
        if !improved {
            break;
        }
    }
    chosen
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    fn random_blocks(n: usize, cols: usize, seed: u64) -> Vec<DMatrix<f64>> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        (0..n)
            .map(|_| DMatrix::from_fn(3, cols, |_, _| rng.random_range(-1.0..1.0)))
            .collect()
    }

    #[test]
    fn log_det_of_a_diagonal_matrix_is_the_sum_of_logs() {
        let a = DMatrix::from_diagonal(&nalgebra::DVector::from_vec(vec![2.0, 3.0, 5.0]));
        assert!((log_det(&a) - 30f64.ln()).abs() < 1e-12);
        assert_eq!(log_det(&DMatrix::zeros(2, 2)), f64::NEG_INFINITY);
    }

    #[test]
    fn d_optimal_beats_every_single_swap_and_the_kappa_rule() {
        let blocks = random_blocks(40, 6, 3);
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        let d = choose(Selection::DOptimal, &[], &blocks, 5, 60, &mut rng);
        let k = choose(Selection::Kappa, &[], &blocks, 5, 60, &mut rng);
        let ld = log_det_of(&[], &blocks, &d);
        assert!(ld >= log_det_of(&[], &blocks, &k), "{ld}");
        // A local optimum of the exchange: no single swap raises the determinant.
        for i in 0..d.len() {
            for j in (0..blocks.len()).filter(|j| !d.contains(j)) {
                let mut s = d.clone();
                s[i] = j;
                assert!(log_det_of(&[], &blocks, &s) <= ld + 1e-9);
            }
        }
    }
}
