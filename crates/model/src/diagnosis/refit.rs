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
