//! Stage 1, the screen: the standard model as the tests see it (geometry and the instrument's
//! nuisance columns, rows weighted by their noise), the noise floor from pure error, and the
//! lack of fit of the geometry alone (which [`super::pipeline`] weighs, once the later stages
//! have run, in deciding whether a mismatch remains).
//!
//! Units: stacked residuals in mm (3 rows per measurement).

use super::linalg::{hcat, orth_basis, scale_rows};
use super::noise::{lack_of_fit, pure_error, PureError};
use super::{DiagnoseError, Standard, ALPHA, MIN_PURE_ERROR_DOF};
use nalgebra::{DMatrix, DVector};

/// Each third of the error budget [`ALPHA`]: the candidate steps, the shape bases and the
/// final lack-of-fit test (module documentation of [`super::select`]).
pub const ALPHA_PART: f64 = ALPHA / 3.0;

/// The standard model in the tests' terms.
#[derive(Debug, Clone)]
pub struct Screen {
    /// Geometry and nuisance columns, unweighted (3 rows per measurement).
    pub model: DMatrix<f64>,
    /// What the geometric model leaves, unweighted (mm).
    pub residual_raw: DVector<f64>,
    /// Pure error of the repeated poses.
    pub pure_error: PureError,
    /// Whether pure error has enough degrees of freedom to be the noise floor.
    pub use_pure_error: bool,
    /// Weight of each row in the tests: 1/σ of its axis, scaled so rows without instrument
    /// variance keep weight 1 (all 1 when the instrument adds nothing).
    pub weights: Vec<f64>,
    /// Orthonormal basis of the weighted model.
    pub basis: DMatrix<f64>,
    /// What the weighted model leaves of the weighted residual.
    pub residual: DVector<f64>,
    /// Known instrument variance per coordinate (mm²) that repeated poses cannot show.
    pub extra_var: f64,
    /// p-value of the lack-of-fit test of the geometric model, when pure error is usable.
    pub lack_of_fit_p: Option<f64>,
}

impl Screen {
    /// Rows of the stacked matrix `m` weighted as the tests weigh them.
    pub fn weigh(&self, m: &DMatrix<f64>) -> DMatrix<f64> {
        scale_rows(m, &self.weights)
    }

    /// The stacked residual after the standard model, weighted as the tests weigh rows (mm).
    pub fn weighted_residual(&self) -> DVector<f64> {
        DVector::from_iterator(
            self.residual_raw.len(),
            self.residual_raw
                .iter()
                .zip(&self.weights)
                .map(|(r, w)| r * w),
        )
    }

    /// Rows of the stacked residual (3 per measurement).
    pub fn rows(&self) -> usize {
        self.residual_raw.len()
    }

    /// The noise variance per coordinate in the tests' weighted units (mm²), when pure error
    /// gives it: the weights scale every axis to the pure-error variance of the unquantised
    /// coordinates, so it is the pure-error σ². None without enough repeated poses (the tests
    /// then use the residual variance of the model at hand).
    pub fn noise_var(&self) -> Option<f64> {
        self.use_pure_error.then(|| {
            self.pure_error.sigma().powi(2) + if self.weighted() { 0.0 } else { self.extra_var }
        })
    }

    /// Whether the rows are weighted (the instrument's known variance differs by axis).
    pub fn weighted(&self) -> bool {
        self.weights.iter().any(|w| *w != 1.0)
    }
}

/// Residual degrees of freedom (equations − unknowns) the tests need at least.
pub const MIN_RESIDUAL_DOF: usize = 20;

/// Screens a standard fit: fails with [`DiagnoseError::TooFew`] when the residual degrees of
/// freedom (3 equations per measurement, less the model's columns) are fewer than
/// [`MIN_RESIDUAL_DOF`].
pub fn screen(std: &Standard) -> Result<Screen, DiagnoseError> {
    let d = &std.data;
    let nrows = 3 * d.len();
    let model = hcat(&[std.jacobian.clone(), std.nuisance.clone()], nrows);
    let basis_raw = orth_basis(&model, 1e-9);
    let residual_raw = &std.residual - &basis_raw * (basis_raw.transpose() * &std.residual);
    let pe = pure_error(d, &std.residual);
    let use_pe = pe.dof >= MIN_PURE_ERROR_DOF;
    // The tests weight each row by 1/σ of its axis (generalised least squares) when the
    // instrument's known variance differs by axis (the panel quantises x and y, not z); an
    // unweighted test would take y's larger variance for structure. All 1 otherwise.
    let weights = row_weights(std, &pe, use_pe, &residual_raw);
    let basis = orth_basis(&scale_rows(&model, &weights), 1e-9);
    let rw = DVector::from_iterator(nrows, std.residual.iter().zip(&weights).map(|(a, b)| a * b));
    let residual = &rw - &basis * (basis.transpose() * &rw);
    // Equations, not points, count: 3 per measurement. The per-term F-tests need the residual
    // variance on enough degrees of freedom; a 22-posture tracker session (66 equations, 31
    // geometric unknowns) has 35 and can be diagnosed.
    let dof = nrows.saturating_sub(basis.ncols());
    if dof < MIN_RESIDUAL_DOF {
        return Err(DiagnoseError::TooFew {
            measurements: d.len(),
            equations: nrows,
            unknowns: basis.ncols(),
            needed: basis.ncols() + MIN_RESIDUAL_DOF,
        });
    }
    let extra_var = std.instrument_var.iter().sum::<f64>() / 3.0;
    let lack_of_fit_p = if use_pe {
        lack_of_fit(&pe, residual_raw.norm_squared(), dof, extra_var)
    } else {
        None
    };
    Ok(Screen {
        model,
        residual_raw,
        pure_error: pe,
        use_pure_error: use_pe,
        weights,
        basis,
        residual,
        extra_var,
        lack_of_fit_p,
    })
}

/// Row weights of the tests: 1/√(σ² + q_a²) for the rows of axis a, scaled so z-like rows keep
/// weight 1, with q_a² the instrument's known variance and σ² the rest of the noise (pure error,
/// else the residual of the unquantised axes). All 1 when the instrument adds nothing.
fn row_weights(std: &Standard, pe: &PureError, use_pe: bool, r0: &DVector<f64>) -> Vec<f64> {
    let n = r0.len();
    let q = std.instrument_var;
    if q.iter().all(|v| *v <= 0.0) {
        return vec![1.0; n];
    }
    let s2 = if use_pe {
        pe.sigma().powi(2)
    } else {
        let plain: Vec<usize> = (0..3).filter(|&a| q[a] <= 0.0).collect();
        let m = (n / 3).max(1) as f64;
        plain
            .iter()
            .map(|&a| (0..n / 3).map(|i| r0[3 * i + a].powi(2)).sum::<f64>() / m)
            .sum::<f64>()
            / plain.len().max(1) as f64
    }
    .max(1e-12);
    (0..n).map(|k| (s2 / (s2 + q[k % 3])).sqrt()).collect()
}
