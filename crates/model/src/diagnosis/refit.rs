//! Stage 3, the refit: geometry, the chosen effects and (for the full model) the discrepancy
//! term's shapes together, linear about the geometric fit (unweighted), and the noise floor the
//! report states.
//!
//! Units: stacked residuals in mm (3 rows per measurement).

use super::linalg::{hcat, lstsq, LeastSquares};
use super::screen::Screen;
use super::select::Selection;
use super::Standard;
use nalgebra::{DMatrix, DVector};

/// The refitted model.
#[derive(Debug, Clone)]
pub struct Refit {
    /// Its design matrix: the geometric Jacobian, then each chosen effect's columns in order,
    /// then (the full model) each chosen shape's columns in order.
    pub design: DMatrix<f64>,
    /// The least-squares fit of the geometric residual on `design`.
    pub fit: LeastSquares,
    /// What the refitted model leaves (mm).
    pub residual: DVector<f64>,
    /// Its residual degrees of freedom (at least 1).
    pub dof: usize,
    /// Its residual variance per coordinate (mm²).
    pub s2: f64,
    /// The 3-D RMS of pure noise, √3·σ (mm): σ from pure error plus the instrument's known
    /// variance when pure error is usable, else from the refit's residual.
    pub noise_floor: f64,
}

/// Refits the geometry with the chosen effects and, when `with_shapes`, the chosen shapes.
pub fn refit(std: &Standard, screen: &Screen, sel: &Selection, with_shapes: bool) -> Refit {
    let mut cols: Vec<DMatrix<f64>> = vec![std.jacobian.clone()];
    cols.extend(sel.chosen.iter().map(|c| c.x.clone()));
    if with_shapes {
        cols.extend(sel.shapes.iter().map(|c| c.x.clone()));
    }
    let design = hcat(&cols, screen.rows());
    let fit = lstsq(&design, &std.residual);
    let residual = &std.residual - &design * &fit.solution;
    let dof = screen.rows().saturating_sub(fit.rank).max(1);
    let s2 = residual.norm_squared() / dof as f64;
    let sigma = if screen.use_pure_error {
        (screen.pure_error.sigma().powi(2) + screen.extra_var).sqrt()
    } else {
        s2.sqrt()
    };
    Refit {
        design,
        fit,
        residual,
        dof,
        s2,
        noise_floor: 3f64.sqrt() * sigma,
    }
}

/// The full model with the shapes fitted on what the named model leaves: the geometry and the
/// chosen shapes are refitted on the residual of `named` (geometry and effects, see [`refit`]),
/// the effects' coefficients kept. Why: fitted jointly, a shape and an effect (or the geometry)
/// that the poses can hardly tell apart trade huge coefficients of opposite sign — on the
/// UR10's series B a joint-2 spline "peaked" at 6 497° against the joint-2 compliance — while
/// the effects earned their place without the shapes ([`super::crossval`]). The solution vector
/// has the layout of [`refit`] with shapes (geometry, effects, shapes); its covariance is the
/// effects' from `named` and the geometry's and shapes' from the second fit.
pub fn refit_shapes_on_named(
    std: &Standard,
    screen: &Screen,
    sel: &Selection,
    named: &Refit,
) -> Refit {
    let g = std.jacobian.ncols();
    let ke: usize = sel.chosen.iter().map(|c| c.x.ncols()).sum();
    let mut cols: Vec<DMatrix<f64>> = vec![std.jacobian.clone()];
    cols.extend(sel.shapes.iter().map(|c| c.x.clone()));
    let second = hcat(&cols, screen.rows());
    let fit2 = lstsq(&second, &named.residual);
    let residual = &named.residual - &second * &fit2.solution;
    let ks = second.ncols() - g;
    let p = g + ke + ks;
    let mut solution = DVector::zeros(p);
    let mut normal_inverse = DMatrix::zeros(p, p);
    // Second-stage (geometry, shapes) indices in the full layout.
    let at = |i: usize| if i < g { i } else { i + ke };
    for i in 0..g + ks {
        solution[at(i)] = fit2.solution[i] + if i < g { named.fit.solution[i] } else { 0.0 };
        for j in 0..g + ks {
            normal_inverse[(at(i), at(j))] = fit2.normal_inverse[(i, j)];
        }
    }
    for i in g..g + ke {
        solution[i] = named.fit.solution[i];
        for j in g..g + ke {
            normal_inverse[(i, j)] = named.fit.normal_inverse[(i, j)];
        }
    }
    let mut all: Vec<DMatrix<f64>> = vec![std.jacobian.clone()];
    all.extend(sel.chosen.iter().map(|c| c.x.clone()));
    all.extend(sel.shapes.iter().map(|c| c.x.clone()));
    let rank = fit2.rank + named.fit.rank.saturating_sub(g);
    let dof = screen.rows().saturating_sub(rank).max(1);
    let s2 = residual.norm_squared() / dof as f64;
    Refit {
        design: hcat(&all, screen.rows()),
        fit: LeastSquares {
            solution,
            normal_inverse,
            rank,
        },
        residual,
        dof,
        s2,
        noise_floor: named.noise_floor,
    }
}
