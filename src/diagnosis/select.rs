//! Stage 2, naming: each candidate projected onto the orthogonal complement of the standard
//! model (what geometry cannot already show), then forward selection (orthogonal matching
//! pursuit) with partial F-tests, Bonferroni over the candidates remaining at each step, at
//! [`ALPHA_PART`]. A candidate too close to one already chosen (not separable from it) is
//! skipped: its coefficients would fight the chosen one's in the refit.
//!
//! Units: stacked regressors in mm per unit coefficient (3 rows per measurement).

use super::linalg::{orth_basis, partial_f, visible_basis};
use super::screen::{Screen, ALPHA_PART};
use super::{Candidate, Data, SEPARABLE_CORRELATION};
use nalgebra::{DMatrix, DVector};

/// The candidate library over one recording, seen past the standard model.
#[derive(Debug, Clone)]
pub struct Candidates {
    /// Each candidate's regressor columns, unweighted; None when the recording cannot show it.
    pub regressors: Vec<Option<DMatrix<f64>>>,
    /// The same with the tests' row weights.
    pub weighted: Vec<Option<DMatrix<f64>>>,
    /// Each candidate's visible fraction past the standard model (0 when absorbed or absent).
    pub visible: Vec<f64>,
    /// Orthonormal basis of each candidate's visible part (None when absorbed or absent).
    pub visible_basis: Vec<Option<DMatrix<f64>>>,
    /// Indices of the candidates with a visible part, in library order.
    pub testable: Vec<usize>,
    /// Labels of the candidates the geometry absorbs entirely.
    pub absorbed: Vec<String>,
}

/// Projects every candidate of `lib` past the standard model of `screen`.
pub fn project_candidates(screen: &Screen, lib: &[Box<dyn Candidate>], d: &Data) -> Candidates {
    let regressors: Vec<Option<DMatrix<f64>>> = lib.iter().map(|c| c.regressors(d)).collect();
    let weighted: Vec<Option<DMatrix<f64>>> = regressors
        .iter()
        .map(|x| x.as_ref().map(|x| screen.weigh(x)))
        .collect();
    let mut absorbed = Vec::new();
    let mut testable = Vec::new();
    let mut visible = vec![0.0; lib.len()];
    let mut bases: Vec<Option<DMatrix<f64>>> = vec![None; lib.len()];
    for (k, x) in weighted.iter().enumerate() {
        let Some(x) = x else { continue };
        match visible_basis(&screen.basis, x) {
            Some((u, v)) => {
                visible[k] = v;
                bases[k] = Some(u);
                testable.push(k);
            }
            None => absorbed.push(lib[k].label()),
        }
    }
    Candidates {
        regressors,
        weighted,
        visible,
        visible_basis: bases,
        testable,
        absorbed,
    }
}

/// One effect forward selection chose.
#[derive(Debug, Clone)]
pub struct Chosen {
    /// Its index in the library.
    pub cand: usize,
    /// Its regressor columns, unweighted.
    pub x: DMatrix<f64>,
    /// Its partial F-test p-value when chosen (before Bonferroni).
    pub p: f64,
    /// Its visible fraction past the standard model.
    pub visible: f64,
}

/// What forward selection found.
#[derive(Debug, Clone)]
pub struct Selection {
    /// The chosen effects, in the order chosen.
    pub chosen: Vec<Chosen>,
    /// The best candidate of the first step and its p-value, chosen or not.
    pub first_best: Option<(usize, f64)>,
    /// Orthonormal basis of the weighted standard model and the chosen effects.
    pub basis: DMatrix<f64>,
    /// What that model leaves of the weighted residual.
    pub residual: DVector<f64>,
}

/// Forward selection: at each step the remaining candidate with the smallest partial F-test
/// p-value joins the model while that p-value is below [`ALPHA_PART`] ÷ (candidates remaining).
pub fn forward_selection(screen: &Screen, cands: &Candidates) -> Selection {
    let nrows = screen.rows();
    let mut remaining = cands.testable.clone();
    let mut sel = Selection {
        chosen: Vec::new(),
        first_best: None,
        basis: screen.basis.clone(),
        residual: screen.residual.clone(),
    };
    // Orthonormal basis of the chosen effects' visible parts, for the separability check.
    let mut chosen_visible = DMatrix::zeros(nrows, 0);
    while !remaining.is_empty() {
        let kk = remaining.len() as f64;
        let Some((k, p, u)) = best_step(&sel, cands, &remaining, &chosen_visible) else {
            break;
        };
        if sel.first_best.is_none() {
            sel.first_best = Some((k, p));
        }
        if p >= ALPHA_PART / kk {
            break;
        }
        sel.residual = &sel.residual - &u * (u.transpose() * &sel.residual);
        sel.basis = DMatrix::from_columns(
            &sel.basis
                .column_iter()
                .chain(u.column_iter())
                .collect::<Vec<_>>(),
        );
        if let Some(bk) = &cands.visible_basis[k] {
            let cols: Vec<_> = chosen_visible
                .column_iter()
                .chain(bk.column_iter())
                .collect();
            chosen_visible = orth_basis(&DMatrix::from_columns(&cols), 1e-6);
        }
        remaining.retain(|&c| c != k);
        sel.chosen.push(Chosen {
            cand: k,
            x: cands.regressors[k]
                .clone()
                .unwrap_or_else(|| DMatrix::zeros(nrows, 0)),
            p,
            visible: cands.visible[k],
        });
    }
    sel
}

/// The remaining candidate that best explains what the model of `sel` leaves: (index, p-value,
/// orthonormal basis of its part past the model). Candidates not separable from the chosen
/// ones (`chosen_visible`) are skipped.
fn best_step(
    sel: &Selection,
    cands: &Candidates,
    remaining: &[usize],
    chosen_visible: &DMatrix<f64>,
) -> Option<(usize, f64, DMatrix<f64>)> {
    let dof = sel.residual.len() - sel.basis.ncols();
    let mut best: Option<(usize, f64, DMatrix<f64>)> = None;
    for &k in remaining {
        let Some(x) = &cands.weighted[k] else {
            continue;
        };
        let Some((u, _)) = visible_basis(&sel.basis, x) else {
            continue;
        };
        // Some combination of it is (nearly) one of the chosen effects: not separable, and
        // its coefficients would fight theirs in the refit.
        if let (Some(bk), true) = (&cands.visible_basis[k], chosen_visible.ncols() > 0) {
            if max_correlation(bk, chosen_visible) > SEPARABLE_CORRELATION {
                continue;
            }
        }
        let (p, _) = partial_f(&u, &sel.residual, dof);
        if best.as_ref().is_none_or(|b| p < b.1) {
            best = Some((k, p, u));
        }
    }
    best
}

/// The largest canonical correlation between the spans of two orthonormal bases.
fn max_correlation(a: &DMatrix<f64>, b: &DMatrix<f64>) -> f64 {
    (a.transpose() * b).svd(false, false).singular_values.max()
}

/// Labels of the candidates whose visible part correlates with candidate `k`'s above
/// [`SEPARABLE_CORRELATION`]: the data cannot tell them apart.
pub fn not_separable_from(k: usize, cands: &Candidates, lib: &[Box<dyn Candidate>]) -> Vec<String> {
    let basis = &cands.visible_basis;
    let Some(uk) = &basis[k] else {
        return Vec::new();
    };
    basis
        .iter()
        .enumerate()
        .filter(|(i, _)| *i != k)
        .filter_map(|(i, b)| {
            let b = b.as_ref()?;
            (max_correlation(uk, b) > SEPARABLE_CORRELATION).then(|| lib[i].label())
        })
        .collect()
}
