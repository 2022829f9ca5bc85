//! Stage 2, naming: each candidate projected onto the orthogonal complement of the standard
//! model (what geometry cannot already show), then forward selection (orthogonal matching
//! pursuit) with partial F-tests, Bonferroni over the candidates remaining at each step, at
//! [`ALPHA_PART`]. A candidate too close to one already chosen (not separable from it) is
//! skipped: its coefficients would fight the chosen one's in the refit.
//!
//! The flexible shape bases of [`super::shapes`] compete in the same selection (Bonferroni over
//! the bases, the second part of the budget) and must also be *sizeable*, [`SHAPE_MIN_SIZE`] of
//! the noise floor: a library effect is claimed only when no shape explains the residual better,
//! and a library term that a chosen shape makes redundant is dropped ([`forward_selection`]).
//!
//! Units: stacked regressors in mm per unit coefficient (3 rows per measurement).

use super::linalg::{
    hcat, orth_basis, partial_f_ln_of, project_out, tr_mul, visible_basis, visible_basis_in,
    visible_basis_of_projection, TrackedTerm,
};
use super::screen::{screen, Screen, ALPHA_PART};
use super::shapes::{refine_position, shape_bases, Form, ShapeSpec, Variable};
use super::{Candidate, Data, DiagnoseError, Standard, SEPARABLE_CORRELATION};
use crate::identification::dense::{sub_mul_slice, tall_r, transpose_mul_view};
use nalgebra::{DMatrix, DVector, Matrix3};
use std::collections::HashMap;

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

/// The shape bases of a recording ([`super::shapes`]), with their columns.
#[derive(Debug, Clone)]
pub struct Shapes {
    /// The bases.
    pub specs: Vec<ShapeSpec>,
    /// Their columns, unweighted (None when the recording cannot show one), kept only where
    /// the tests weight rows: empty when every weight is 1, as `weighted` then holds the same
    /// columns (on 12 000 rows one copy of all the bases is a few hundred megabytes). Read
    /// through [`Shapes::unweighted`].
    pub regressors: Vec<Option<DMatrix<f64>>>,
    /// The columns with the tests' row weights; None when the recording cannot show one.
    pub weighted: Vec<Option<DMatrix<f64>>>,
}

impl Shapes {
    /// Bases with columns: the Bonferroni count of the shape tests.
    pub fn testable(&self) -> usize {
        self.weighted.iter().filter(|w| w.is_some()).count().max(1)
    }
}

impl Shapes {
    /// Adds a basis.
    pub fn push(&mut self, spec: ShapeSpec, d: &Data, screen: &Screen) {
        let x = spec.columns(d);
        if screen.weighted() {
            self.weighted.push(x.as_ref().map(|x| screen.weigh(x)));
            self.regressors.push(x);
        } else {
            self.weighted.push(x);
        }
        self.specs.push(spec);
    }

    /// The columns of basis `k` without the row weights.
    pub fn unweighted(&self, k: usize) -> Option<&DMatrix<f64>> {
        if self.regressors.is_empty() {
            self.weighted[k].as_ref()
        } else {
            self.regressors[k].as_ref()
        }
    }
}

/// A finer position basis where the chosen position shape `k` (test `t` against the model
/// leaving `residual`) is largest ([`refine_position`]).
fn refinement(
    screen: &Screen,
    shapes: &Shapes,
    k: usize,
    t: &TermTest,
    residual: &DVector<f64>,
    d: &Data,
) -> Option<ShapeSpec> {
    let Form::Radial { width_mm, .. } = &shapes.specs[k].form else {
        return None;
    };
    let fitted = &t.u * (t.u.transpose() * residual);
    let w = &screen.weights;
    let size: Vec<f64> = (0..d.len())
        .map(|i| {
            (0..3)
                .map(|a| (fitted[3 * i + a] / w[3 * i + a].max(1e-300)).powi(2))
                .sum::<f64>()
                .sqrt()
        })
        .collect();
    refine_position(d, &size, *width_mm)
}

/// Builds the shape bases of `d` and their columns.
pub fn build_shapes(screen: &Screen, d: &Data) -> Shapes {
    let specs = shape_bases(d);
    let columns: Vec<Option<DMatrix<f64>>> = specs.iter().map(|s| s.columns(d)).collect();
    // Unweighted rows: the columns are their own weighted form, held once.
    let (regressors, weighted) = if screen.weighted() {
        let weighted = columns
            .iter()
            .map(|x| x.as_ref().map(|x| screen.weigh(x)))
            .collect();
        (columns, weighted)
    } else {
        (Vec::new(), columns)
    };
    Shapes {
        specs,
        regressors,
        weighted,
    }
}

/// A shape basis forward selection chose: a structured residual no library candidate explains.
#[derive(Debug, Clone)]
pub struct ChosenShape {
    /// Its index in [`Shapes::specs`].
    pub shape: usize,
    /// The basis.
    pub spec: ShapeSpec,
    /// Its columns, unweighted.
    pub x: DMatrix<f64>,
    /// Its partial F-test p-value when chosen (before Bonferroni).
    pub p: f64,
    /// Its debiased size ÷ the noise floor when chosen.
    pub size_ratio: f64,
}

/// What forward selection found.
#[derive(Debug, Clone)]
pub struct Selection {
    /// The chosen effects, in the order chosen.
    pub chosen: Vec<Chosen>,
    /// The chosen shape bases (the discrepancy term), in the order chosen.
    pub shapes: Vec<ChosenShape>,
    /// Library candidates chosen at first and dropped once a shape explained what they did:
    /// they only soaked up part of an unknown shape.
    pub dropped: Vec<usize>,
    /// The best candidate of the first step and its p-value, chosen or not.
    pub first_best: Option<(usize, f64)>,
    /// Orthonormal basis of the weighted standard model, the chosen effects and shapes.
    pub basis: DMatrix<f64>,
    /// What that model leaves of the weighted residual.
    pub residual: DVector<f64>,
}

/// A structured residual is sizeable when its debiased RMS reaches this fraction of the noise
/// floor: below it the model is at the floor whatever a test over thousands of degrees of
/// freedom says (a 10× effect's small mismatch with its candidate is significant and harmless;
/// held-out RMS within 1.2× the floor allows about 0.6×).
pub const SHAPE_MIN_SIZE: f64 = 0.3;

/// At most this many shape bases make up the discrepancy term.
pub const MAX_SHAPES: usize = 4;

/// The debiased size of a term ÷ the noise floor: √(max(0, ΔSS − k·s²) / m) ÷ √(3·s²), with s²
/// the noise variance per coordinate and m the measurements (ΔSS in the tests' weighted units).
pub fn size_ratio(dss: f64, k: usize, s2: f64, measurements: usize) -> f64 {
    let s2 = s2.max(1e-300);
    let excess = (dss - k as f64 * s2).max(0.0);
    (excess / measurements.max(1) as f64).sqrt() / (3.0 * s2).sqrt()
}

/// One term's test against a model: (p, ln p, ΔSS, its part past the model, size ÷ floor).
#[derive(Debug, Clone)]
struct TermTest {
    p: f64,
    ln_p: f64,
    u: DMatrix<f64>,
    size: f64,
}

/// The test of a term whose part past `basis` has the orthonormal basis `u`.
fn test_visible(
    screen: &Screen,
    basis: &DMatrix<f64>,
    residual: &DVector<f64>,
    u: DMatrix<f64>,
) -> Option<TermTest> {
    let dss = (u.transpose() * residual).norm_squared();
    let (p, ln_p, size) = test_figures(screen, basis, residual, u.ncols(), dss);
    Some(TermTest { p, ln_p, u, size })
}

/// (p, ln p, size ÷ floor) of a term adding `k` directions that explain `dss` of `residual`.
fn test_figures(
    screen: &Screen,
    basis: &DMatrix<f64>,
    residual: &DVector<f64>,
    k: usize,
    dss: f64,
) -> (f64, f64, f64) {
    figures(screen, basis.ncols(), residual.len(), residual, k, dss)
}

/// [`test_figures`] against a model of `model_columns` orthonormal columns over `nrows` stacked
/// rows (`residual` may be its compressed form: only its norm is used).
fn figures(
    screen: &Screen,
    model_columns: usize,
    nrows: usize,
    residual: &DVector<f64>,
    k: usize,
    dss: f64,
) -> (f64, f64, f64) {
    let dof = nrows.saturating_sub(model_columns);
    let (p, ln_p, dss) = partial_f_ln_of(k, dss, residual, dof);
    let s2 = screen.noise_var().unwrap_or_else(|| {
        (residual.norm_squared() - dss).max(0.0) / dof.saturating_sub(k).max(1) as f64
    });
    let size = size_ratio(dss, k, s2, nrows / 3);
    (p, ln_p, size)
}

/// The terms' columns past the growing model of [`forward_selection`], made when first
/// tested: library candidates and shape bases by index.
#[derive(Default)]
struct Projections {
    lib: HashMap<usize, TrackedTerm>,
    shapes: HashMap<usize, TrackedTerm>,
    /// Whether each library candidate is separable from the chosen effects: it changes only
    /// when an effect is chosen (then cleared), not at each step.
    separable: HashMap<usize, bool>,
}

/// A term's test figures (its basis is formed only when needed: [`full_test`]).
struct Quick {
    p: f64,
    ln_p: f64,
    /// Directions the term adds.
    k: usize,
    size: f64,
}

/// The test of term `k` (columns `x`) against the model of `sel`, through its kept projection
/// and without forming its basis where the Gram matrix settles its rank
/// ([`TrackedTerm::rank_and_dss`]).
fn quick_test(
    screen: &Screen,
    sel: &Selection,
    cache: &mut HashMap<usize, TrackedTerm>,
    k: usize,
    x: &DMatrix<f64>,
) -> Option<Quick> {
    let term = cache
        .entry(k)
        .or_insert_with(|| TrackedTerm::new(&sel.basis, x));
    term.catch_up(&sel.basis);
    match term.rank_and_dss(&sel.residual)? {
        Some((rank, dss)) => {
            let (p, ln_p, size) = test_figures(screen, &sel.basis, &sel.residual, rank, dss);
            Some(Quick {
                p,
                ln_p,
                k: rank,
                size,
            })
        }
        None => {
            tracing::trace!(term = k, "rank not settled by the Gram matrix");
            let (rank, dss) = term.rank_and_dss_by_qr(&sel.basis, &sel.residual)?;
            let (p, ln_p, size) = test_figures(screen, &sel.basis, &sel.residual, rank, dss);
            Some(Quick {
                p,
                ln_p,
                k: rank,
                size,
            })
        }
    }
}

/// The test of term `k` (columns `x`) against the model of `sel` with its basis, through its
/// kept projection.
fn full_test(
    screen: &Screen,
    sel: &Selection,
    cache: &mut HashMap<usize, TrackedTerm>,
    k: usize,
    x: &DMatrix<f64>,
) -> Option<TermTest> {
    let term = cache
        .entry(k)
        .or_insert_with(|| TrackedTerm::new(&sel.basis, x));
    term.catch_up(&sel.basis);
    let (u, _) = visible_basis_of_projection(&term.norms, &term.past(&sel.basis))?;
    test_visible(screen, &sel.basis, &sel.residual, u)
}

/// Forward selection over the library and the shape bases: at each step the term with the
/// smallest p-value (compared as ln p, so huge effects do not tie at 0) joins the model, among
/// the library candidates whose p-value is below [`ALPHA_PART`] ÷ (candidates remaining) and the
/// shapes whose p-value is below [`ALPHA_PART`] ÷ (shape bases) and whose size reaches
/// [`SHAPE_MIN_SIZE`] of the floor. A library term explains a few columns' worth of a shape, a
/// shape many: a library effect the data show exactly wins on p-value, an unknown shape wins
/// over the library terms that each soak up part of it. When a shape joined, every term is then
/// tested again given all the others and the least significant that fails is dropped, until none
/// fails (`prune`): library terms chosen before the shape that only soaked it up go.
pub fn forward_selection(
    screen: &Screen,
    cands: &Candidates,
    shapes: &mut Shapes,
    d: &Data,
) -> Selection {
    let nrows = screen.rows();
    let mut remaining = cands.testable.clone();
    let mut remaining_shapes: Vec<usize> = (0..shapes.specs.len())
        .filter(|&k| shapes.weighted[k].is_some())
        .collect();
    let nb = shapes.testable() as f64;
    let mut sel = Selection {
        chosen: Vec::new(),
        shapes: Vec::new(),
        dropped: Vec::new(),
        first_best: None,
        basis: screen.basis.clone(),
        residual: screen.residual.clone(),
    };
    // Orthonormal basis of the chosen effects' visible parts, for the separability check.
    let mut chosen_visible = DMatrix::zeros(nrows, 0);
    // Each term's columns past the model so far: the model only grows inside this loop
    // (`add_direction` appends), so each step projects out the new directions only.
    let mut projected = Projections::default();
    let mut first = true;
    loop {
        let kk = remaining.len().max(1) as f64;
        let pick = best_step(
            screen,
            &sel,
            cands,
            &remaining,
            &chosen_visible,
            &mut projected,
        );
        // The library pick's full test (its basis) only where it can matter: the first step's
        // best is reported, and a pick is taken only when it passes and no shape beats it.
        let mut pick_full = None;
        if first {
            let full = full_pick(screen, &sel, cands, &pick, &mut projected.lib);
            sel.first_best = full.as_ref().map(|(k, t)| (*k, t.p));
            pick_full = Some(full);
            first = false;
        }
        let shape = if sel.shapes.len() < MAX_SHAPES {
            best_shape(
                screen,
                &sel,
                shapes,
                &remaining_shapes,
                nb,
                &mut projected.shapes,
            )
        } else {
            None
        };
        let lib = if pick_may_be_taken(&pick, shape.as_ref(), ALPHA_PART / kk) {
            pick_full
                .unwrap_or_else(|| full_pick(screen, &sel, cands, &pick, &mut projected.lib))
                .filter(|(_, t)| t.p < ALPHA_PART / kk)
        } else {
            None
        };
        let take_shape = match (&lib, &shape) {
            (None, None) => break,
            (Some(_), None) => false,
            (None, Some(_)) => true,
            (Some((_, a)), Some((_, b))) => b.ln_p < a.ln_p,
        };
        if take_shape {
            let Some((k, t)) = shape else { break };
            let fine = refinement(screen, shapes, k, &t, &sel.residual, d);
            tracing::debug!(refined = ?fine.as_ref().map(ShapeSpec::label), "refinement");
            if let Some(fine) = fine {
                remaining_shapes.push(shapes.specs.len());
                shapes.push(fine, d, screen);
            }
            add_direction(&mut sel, &t.u);
            remaining_shapes.retain(|&c| c != k);
            tracing::debug!(shape = %shapes.specs[k].label(), p = t.p, ln_p = t.ln_p, size = t.size, "shape chosen");
            sel.shapes.push(ChosenShape {
                shape: k,
                spec: shapes.specs[k].clone(),
                x: shapes
                    .unweighted(k)
                    .cloned()
                    .unwrap_or_else(|| DMatrix::zeros(nrows, 0)),
                p: t.p,
                size_ratio: t.size,
            });
        } else {
            let Some((k, t)) = lib else { break };
            add_direction(&mut sel, &t.u);
            if let Some(bk) = &cands.visible_basis[k] {
                let cols: Vec<_> = chosen_visible
                    .column_iter()
                    .chain(bk.column_iter())
                    .collect();
                chosen_visible = orth_basis(&DMatrix::from_columns(&cols), 1e-6);
                projected.separable.clear();
            }
            remaining.retain(|&c| c != k);
            tracing::debug!(
                candidate = k,
                p = t.p,
                ln_p = t.ln_p,
                size = t.size,
                "candidate chosen"
            );
            sel.chosen.push(Chosen {
                cand: k,
                x: cands.regressors[k]
                    .clone()
                    .unwrap_or_else(|| DMatrix::zeros(nrows, 0)),
                p: t.p,
                visible: cands.visible[k],
            });
        }
    }
    if !sel.shapes.is_empty() {
        prune(screen, &mut sel, cands, shapes);
    }
    sel
}

/// The library effects and shapes forward selection chooses on a standard fit, from the screen
/// on and without the report: what [`super::outliers::outliers_against_structure`] judges rows
/// against.
pub fn select_terms(
    std: &Standard,
    lib: &[Box<dyn Candidate>],
) -> Result<Selection, DiagnoseError> {
    let screen = screen(std)?;
    let candidates = project_candidates(&screen, lib, &std.data);
    let mut shapes = build_shapes(&screen, &std.data);
    Ok(forward_selection(
        &screen,
        &candidates,
        &mut shapes,
        &std.data,
    ))
}

/// Adds the orthonormal direction(s) `u` (orthogonal to the model) to the selection's model.
fn add_direction(sel: &mut Selection, u: &DMatrix<f64>) {
    sel.residual = &sel.residual - u * (u.transpose() * &sel.residual);
    // Appended in place: column-major storage grows at its end, so the model's columns are not
    // copied at every step.
    let at = sel.basis.ncols();
    let basis = std::mem::replace(&mut sel.basis, DMatrix::zeros(0, 0));
    sel.basis = basis.resize_horizontally(at + u.ncols(), 0.0);
    sel.basis.columns_mut(at, u.ncols()).copy_from(u);
}

/// The weighted columns of every chosen term but number `skip` (library terms first, then
/// shapes), beside the standard model.
fn model_without(
    screen: &Screen,
    sel: &Selection,
    cands: &Candidates,
    shapes: &Shapes,
    skip: Option<usize>,
) -> DMatrix<f64> {
    let mut blocks = vec![screen.basis.clone()];
    let lib = sel
        .chosen
        .iter()
        .filter_map(|c| cands.weighted[c.cand].clone());
    let shp = sel
        .shapes
        .iter()
        .filter_map(|c| shapes.weighted[c.shape].clone());
    for (i, b) in lib.chain(shp).enumerate() {
        if Some(i) != skip {
            blocks.push(b);
        }
    }
    orth_basis(&hcat(&blocks, screen.rows()), 1e-9)
}

/// Removes the chosen effects at `idx` (indices into `sel.chosen`) that did not earn their
/// place on held-out data ([`super::crossval`]) and rebuilds the selection's model without
/// them; returns them in the order of `idx`.
pub fn set_aside(
    screen: &Screen,
    sel: &mut Selection,
    cands: &Candidates,
    shapes: &Shapes,
    idx: &[usize],
) -> Vec<Chosen> {
    if idx.is_empty() {
        return Vec::new();
    }
    let out: Vec<Chosen> = idx.iter().map(|&i| sel.chosen[i].clone()).collect();
    let mut k = 0;
    sel.chosen.retain(|_| {
        k += 1;
        !idx.contains(&(k - 1))
    });
    let q = model_without(screen, sel, cands, shapes, None);
    sel.residual = &screen.residual - &q * (q.transpose() * &screen.residual);
    sel.basis = q;
    out
}

/// Tests every chosen term given all the others and drops the least significant one that fails
/// (a library term: p at or above [`ALPHA_PART`] ÷ its candidates; a shape: that or a size
/// below [`SHAPE_MIN_SIZE`]), until none fails; then rebuilds the selection's model.
///
/// How: the model without term i is the standard model's orthonormal basis beside a basis of
/// the other terms' parts past it, and the weighted residual is already orthogonal to the
/// standard model, so every test here is least squares on the terms' parts past the standard
/// model and that residual. Those columns are compressed once into the triangular factor R of
/// their Householder QR ([`compress_columns`]): R has the same inner products (hence the same
/// norms, ranks, ΔSS and residual sums of squares) on (columns + 1) rows instead of 3n, so each
/// leave-one-term-out model costs a factorisation of a small matrix.
fn prune(screen: &Screen, sel: &mut Selection, cands: &Candidates, shapes: &Shapes) {
    let kk = cands.testable.len().max(1) as f64;
    let nb = shapes.testable() as f64;
    let rw = &screen.residual;
    let nrows = screen.rows();
    let columns: Vec<Option<&DMatrix<f64>>> = sel
        .chosen
        .iter()
        .map(|c| cands.weighted[c.cand].as_ref())
        .chain(sel.shapes.iter().map(|c| shapes.weighted[c.shape].as_ref()))
        .collect();
    let norms: Vec<Option<Vec<f64>>> = columns
        .iter()
        .map(|x| x.map(|x| x.column_iter().map(|c| c.norm()).collect()))
        .collect();
    let (small, small_r) = compress_columns(&screen.basis, &columns, rw);
    // Which of the original terms are still chosen (library terms first, then shapes).
    let mut alive: Vec<usize> = (0..columns.len()).collect();
    loop {
        let nlib = sel.chosen.len();
        let mut worst: Option<(usize, f64)> = None;
        for (i, &ti) in alive.iter().enumerate() {
            let others: Vec<DMatrix<f64>> = alive
                .iter()
                .filter(|&&tj| tj != ti)
                .filter_map(|&tj| small[tj].clone())
                .collect();
            let w = orth_basis(&hcat(&others, small_r.len()), 1e-9);
            let r = &small_r - &w * (w.transpose() * &small_r);
            let model_columns = screen.basis.ncols() + w.ncols();
            let tested = match (&norms[ti], &small[ti]) {
                (Some(norms), Some(xs)) => visible_basis_in(norms, &project_out(&w, xs), nrows)
                    .map(|(u, _)| {
                        let dss = (u.transpose() * &r).norm_squared();
                        let (p, ln_p, size) =
                            figures(screen, model_columns, nrows, &r, u.ncols(), dss);
                        (p, ln_p, size)
                    }),
                _ => None,
            };
            let fails = match tested {
                None => Some(0.0),
                Some((p, ln_p, _)) if i < nlib => (p >= ALPHA_PART / kk).then_some(ln_p),
                Some((p, ln_p, size)) => {
                    (p >= ALPHA_PART / nb || size < SHAPE_MIN_SIZE).then_some(ln_p)
                }
            };
            if let Some(lp) = fails {
                if worst.is_none_or(|w| lp > w.1) {
                    worst = Some((i, lp));
                }
            }
        }
        let Some((i, _)) = worst else { break };
        alive.remove(i);
        if i < nlib {
            let c = sel.chosen.remove(i);
            tracing::debug!(candidate = c.cand, "dropped: a shape explains it");
            sel.dropped.push(c.cand);
        } else {
            sel.shapes.remove(i - nlib);
        }
    }
    let q = model_without(screen, sel, cands, shapes, None);
    sel.residual = rw - &q * (q.transpose() * rw);
    sel.basis = q;
}

/// The terms' parts past the standard model's orthonormal basis `q` (`columns`, None where a
/// term has no columns) and the residual `r` beside them, compressed: each term's columns and
/// the residual as columns of the triangular factor R of the Householder QR of [parts | r]
/// (RᵀR = [parts | r]ᵀ[parts | r], so every norm, inner product, rank and sum of squares of
/// least squares among them is R's). Left as they are when there are fewer rows than columns.
/// The parts are made in one matrix, projected past `q` twice in place (as [`project_out`]).
fn compress_columns(
    q: &DMatrix<f64>,
    columns: &[Option<&DMatrix<f64>>],
    r: &DVector<f64>,
) -> (Vec<Option<DMatrix<f64>>>, DVector<f64>) {
    let n = r.len();
    let p: usize = columns.iter().flatten().map(|x| x.ncols()).sum();
    let mut all = DMatrix::zeros(n, p + 1);
    let mut at = 0;
    for x in columns.iter().flatten() {
        all.columns_mut(at, x.ncols()).copy_from(*x);
        at += x.ncols();
    }
    all.set_column(p, r);
    if q.ncols() > 0 {
        let parts = &mut all.as_mut_slice()[..n * p];
        for _ in 0..2 {
            let c = transpose_mul_view(
                q.as_slice(),
                n,
                &nalgebra::DMatrixView::from_slice(parts, n, p),
            );
            sub_mul_slice(parts, p, q.as_slice(), n, &c);
        }
    }
    let m = if all.nrows() > all.ncols() {
        tall_r(&all)
    } else {
        all
    };
    let mut at = 0;
    let terms = columns
        .iter()
        .map(|x| {
            x.map(|x| {
                let k = x.ncols();
                at += k;
                m.columns(at - k, k).into_owned()
            })
        })
        .collect();
    (terms, m.column(m.ncols() - 1).into_owned())
}

/// The remaining shape basis with the smallest p-value against the model of `sel` among the
/// eligible ones: p-value below [`ALPHA_PART`] ÷ `nb`, size at least [`SHAPE_MIN_SIZE`], and
/// a smaller leave-one-measurement-out prediction error ([`press`]) than without it. The last
/// keeps a flexible basis from fitting a few gross rows (they are the outlier judgement's) or
/// the noise of a small recording: a row only its own coefficients explain is predicted no
/// better without it.
fn best_shape(
    screen: &Screen,
    sel: &Selection,
    shapes: &Shapes,
    remaining: &[usize],
    nb: f64,
    cache: &mut HashMap<usize, TrackedTerm>,
) -> Option<(usize, TermTest)> {
    let columns_left = (sel.residual.len().saturating_sub(sel.basis.ncols()) / 3)
        .saturating_sub(sel.shapes.iter().map(|c| c.x.ncols()).sum());
    let mut eligible: Vec<(usize, Quick)> = Vec::new();
    for &k in remaining {
        let Some(x) = &shapes.weighted[k] else {
            continue;
        };
        // One basis per joint variable: a second basis on the same variable (harmonics beside
        // splines of one joint's angle) is nearly collinear with the first, and the two trade
        // huge coefficients. Position shapes are refined on purpose (`refinement`).
        let v = shapes.specs[k].variable;
        if v != Variable::Position && sel.shapes.iter().any(|c| c.spec.variable == v) {
            continue;
        }
        let Some(q) = quick_test(screen, sel, cache, k, x) else {
            continue;
        };
        tracing::trace!(shape = %shapes.specs[k].label(), p = q.p, ln_p = q.ln_p, size = q.size, "shape basis");
        if q.p >= ALPHA_PART / nb || q.size < SHAPE_MIN_SIZE || q.k > columns_left {
            continue;
        }
        eligible.push((k, q));
    }
    // The chosen shape is the eligible one with the smallest p-value among those that lower
    // PRESS (the first in library order on a tie): PRESS, which needs the shape's basis, is
    // taken in order of p-value until one lowers it.
    eligible.sort_by(|a, b| a.1.ln_p.total_cmp(&b.1.ln_p));
    if eligible.is_empty() {
        return None;
    }
    let hat = hat_blocks(&sel.basis);
    let before = press(&hat, &sel.residual);
    for (k, _) in eligible {
        let Some(x) = &shapes.weighted[k] else {
            continue;
        };
        // PRESS needs only the span of the shape's part past the model: from its tracked Gram
        // matrix where that settles the rank, else the basis itself (as the test takes it).
        let (u, full) = match cache
            .get(&k)
            .and_then(|term| term.leverage_basis(&sel.basis))
        {
            Some(u) => (u, None),
            None => match full_test(screen, sel, cache, k, x) {
                Some(t) => (t.u.clone(), Some(t)),
                None => continue,
            },
        };
        let with: Vec<Matrix3<f64>> = hat.iter().zip(hat_blocks(&u)).map(|(a, b)| a + b).collect();
        let r = &sel.residual - &u * (u.transpose() * &sel.residual);
        let after = press(&with, &r);
        tracing::trace!(shape = %shapes.specs[k].label(), before, after, "shape PRESS");
        if after < before {
            let t = match full {
                Some(t) => t,
                None => full_test(screen, sel, cache, k, x)?,
            };
            return Some((k, t));
        }
    }
    None
}

/// The 3 × 3 diagonal blocks H_ii = Q_i Q_iᵀ of the hat matrix of the orthonormal basis `q`,
/// one per measurement (the blocks of orthogonal bases side by side add).
fn hat_blocks(q: &DMatrix<f64>) -> Vec<Matrix3<f64>> {
    let n = q.nrows();
    let mut h = vec![Matrix3::zeros(); n / 3];
    // Column by column (contiguous reads), each entry summed over the columns in order as
    // nalgebra's product of the 3-row block and its transpose sums it: the same numbers,
    // without two temporaries per measurement.
    for (j, col) in q.as_slice().chunks_exact(n.max(1)).enumerate() {
        for (i, hi) in h.iter_mut().enumerate() {
            let b = &col[3 * i..3 * i + 3];
            for r in 0..3 {
                for c in 0..3 {
                    let v = b[r] * b[c];
                    hi[(r, c)] = if j == 0 { v } else { v + hi[(r, c)] };
                }
            }
        }
    }
    h
}

/// The leave-one-measurement-out prediction error (PRESS) of a model with hat blocks `hat`
/// ([`hat_blocks`]) and residual `r`: Σ_i ‖(I − H_ii)⁻¹ r_i‖². A measurement the model can only
/// fit with its own coefficients (leverage near 1) counts as unpredicted.
fn press(hat: &[Matrix3<f64>], r: &DVector<f64>) -> f64 {
    let mut total = 0.0;
    for (i, h) in hat.iter().enumerate() {
        let m = Matrix3::identity() - h;
        let e = nalgebra::Vector3::new(r[3 * i], r[3 * i + 1], r[3 * i + 2]);
        total += match m.try_inverse() {
            Some(inv) if inv.norm() < 1e6 => (inv * e).norm_squared(),
            _ => 1e12 * e.norm_squared(),
        };
    }
    total
}

/// The remaining candidate that best explains what the model of `sel` leaves (smallest p-value,
/// compared as ln p, by its quick test). Candidates not separable from the chosen ones
/// (`chosen_visible`) are skipped.
fn best_step(
    screen: &Screen,
    sel: &Selection,
    cands: &Candidates,
    remaining: &[usize],
    chosen_visible: &DMatrix<f64>,
    projected: &mut Projections,
) -> Option<(usize, Quick)> {
    let mut best: Option<(usize, Quick)> = None;
    for &k in remaining {
        let Some(x) = &cands.weighted[k] else {
            continue;
        };
        // Some combination of it is (nearly) one of the chosen effects: not separable, and
        // its coefficients would fight theirs in the refit.
        if let (Some(bk), true) = (&cands.visible_basis[k], chosen_visible.ncols() > 0) {
            let separable = *projected
                .separable
                .entry(k)
                .or_insert_with(|| max_correlation(bk, chosen_visible) <= SEPARABLE_CORRELATION);
            if !separable {
                continue;
            }
        }
        let Some(q) = quick_test(screen, sel, &mut projected.lib, k, x) else {
            continue;
        };
        if best.as_ref().is_none_or(|b| q.ln_p < b.1.ln_p) {
            best = Some((k, q));
        }
    }
    best
}

/// The full test (with its basis) of the library pick of [`best_step`].
fn full_pick(
    screen: &Screen,
    sel: &Selection,
    cands: &Candidates,
    pick: &Option<(usize, Quick)>,
    cache: &mut HashMap<usize, TrackedTerm>,
) -> Option<(usize, TermTest)> {
    let (k, _) = pick.as_ref()?;
    let t = full_test(screen, sel, cache, *k, cands.weighted[*k].as_ref()?)?;
    Some((*k, t))
}

/// Whether the library pick (by its quick test) could be taken at this step, as its full test
/// would decide: its p-value below `threshold` and no shape with a smaller ln p. The quick and
/// the full test differ by rounding only (the same rank, ΔSS to about 10⁻¹² relative), so a
/// pick at twice the threshold, or a shape ahead by more than 10⁻⁶ of ln p, settles it without
/// the full test; anything closer is left to the full test.
fn pick_may_be_taken(
    pick: &Option<(usize, Quick)>,
    shape: Option<&(usize, TermTest)>,
    threshold: f64,
) -> bool {
    let Some((_, q)) = pick else {
        return false;
    };
    if q.p >= 2.0 * threshold {
        return false;
    }
    match shape {
        Some((_, t)) => t.ln_p >= q.ln_p - 1e-6 * (1.0 + q.ln_p.abs()),
        None => true,
    }
}

/// The largest canonical correlation between the spans of two orthonormal bases.
fn max_correlation(a: &DMatrix<f64>, b: &DMatrix<f64>) -> f64 {
    // Not finite (never on bounded data): no correlation can be told, so call it total.
    // A candidate's basis has a few columns: one dot product per entry then (nalgebra's kernel
    // does not take such shapes, and its own loop is scalar).
    let c = if a.ncols() <= 5 || b.ncols() <= 5 {
        crate::identification::dense::transpose_mul_dots(a.as_slice(), a.nrows(), b)
    } else {
        tr_mul(a, b)
    };
    crate::identification::dense::bounded_svd(c, false, false)
        .map_or(1.0, |svd| svd.singular_values.max())
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hat_blocks_are_the_blocks_of_the_basis_times_its_transpose_to_the_bit() {
        // The product nalgebra forms for each measurement's 3-row block, against the
        // column-by-column sums, on a basis of 12 columns and on none.
        let q = crate::diagnosis::linalg::orth_basis(
            &DMatrix::from_fn(60, 12, |r, c| {
                ((r * (c + 3)) as f64 * 0.05).sin() + c as f64
            }),
            1e-9,
        );
        for q in [q, DMatrix::zeros(60, 0)] {
            let got = hat_blocks(&q);
            assert_eq!(got.len(), 20);
            for (i, h) in got.iter().enumerate() {
                let b = q.rows(3 * i, 3);
                let want = b * b.transpose();
                assert_eq!(*h, Matrix3::from_fn(|r, c| want[(r, c)]), "measurement {i}");
            }
        }
    }
}
