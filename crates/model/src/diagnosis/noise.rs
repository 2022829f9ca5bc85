//! The noise floor from the data itself: pure error of repeated poses.
//!
//! Measurements at the same commanded joint values (the `ref` drift-reference pose, or any
//! replicate) form groups; the pure-error sum of squares is Σ_groups Σ ‖p − p̄_group‖² with
//! 3·(n_g − 1) degrees of freedom per group. With at least [`MIN_PURE_ERROR_DOF`] degrees of
//! freedom it estimates σ² per coordinate, and the lack-of-fit F-test compares the residual
//! beyond pure error with it (plus the instrument's known quantisation variance, which a repeated
//! pose reads identically and so cannot show). Otherwise the diagnosis falls back to per-term
//! tests against the residual variance (and says so).
//!
//! [`MIN_PURE_ERROR_DOF`]: super::MIN_PURE_ERROR_DOF

use super::Data;
use nalgebra::{DVector, Vector3};
use rigcal_core::stats::f_sf;
use std::collections::BTreeMap;

/// Pure error of the repeated poses.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PureError {
    /// Sum of squares (mm²).
    pub ss: f64,
    /// Degrees of freedom.
    pub dof: usize,
    /// Groups of repeated poses.
    pub groups: usize,
}

impl PureError {
    /// σ per coordinate (mm).
    pub fn sigma(&self) -> f64 {
        (self.ss / self.dof.max(1) as f64).sqrt()
    }
}

/// Indices of measurements grouped by identical commanded joints (groups of two or more).
fn replicate_groups(d: &Data) -> Vec<Vec<usize>> {
    let mut map: BTreeMap<Vec<u64>, Vec<usize>> = BTreeMap::new();
    for (i, o) in d.obs.iter().enumerate() {
        map.entry(o.q.iter().map(|v| v.to_bits()).collect())
            .or_default()
            .push(i);
    }
    map.into_values().filter(|g| g.len() > 1).collect()
}

/// The pure error of a recording's repeated poses; `residual` is stacked (3 per measurement).
/// Measured points or residuals give the same sum (the model is the same within a group).
pub fn pure_error(d: &Data, residual: &DVector<f64>) -> PureError {
    let groups = replicate_groups(d);
    let mut ss = 0.0;
    let mut dof = 0;
    for g in &groups {
        let v: Vec<Vector3<f64>> = g
            .iter()
            .map(|&i| Vector3::new(residual[3 * i], residual[3 * i + 1], residual[3 * i + 2]))
            .collect();
        let mean: Vector3<f64> = v.iter().sum::<Vector3<f64>>() / v.len() as f64;
        ss += v.iter().map(|x| (x - mean).norm_squared()).sum::<f64>();
        dof += 3 * (g.len() - 1);
    }
    PureError {
        ss,
        dof,
        groups: groups.len(),
    }
}

/// Lack-of-fit F-test: p-value that the residual beyond pure error is noise. `rss` and
/// `dof_residual` are the model's residual sum of squares and degrees of freedom; `extra_var`
/// (mm² per coordinate) is variance the instrument adds that repeated poses cannot show (the
/// panel's quantisation repeats at a repeated pose): it joins the pure-error variance in the
/// denominator. Where a replicate group does change cell, its pure error already holds part of
/// it, so the test errs towards claiming nothing.
pub fn lack_of_fit(pe: &PureError, rss: f64, dof_residual: usize, extra_var: f64) -> Option<f64> {
    if pe.dof == 0 || dof_residual <= pe.dof || pe.ss <= 0.0 {
        return None;
    }
    let dof_lof = (dof_residual - pe.dof) as f64;
    let f = ((rss - pe.ss).max(0.0) / dof_lof) / (pe.ss / pe.dof as f64 + extra_var);
    Some(f_sf(f, dof_lof, pe.dof as f64))
}
