//! The noise floor from the data itself: pure error of repeated poses.
//!
//! Measurements at the same joint values within [`SAME_POSE_TOL`] (the `ref` drift-reference
//! pose, or any replicate: a real arm reads a repeated pose a few thousandths of a degree apart)
//! form groups, so the floor is the robot's repeatability with the instrument's noise, not the
//! instrument's alone (issue 35); the pure-error sum of squares is Σ_groups Σ ‖p − p̄_group‖² with
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

/// Two measurements are at the same pose when every joint value agrees within this (rad, or mm
/// for a prismatic joint): 0.01°. A real arm's encoders read a repeated commanded pose to a few
/// thousandths of a degree (the UR10's series B repeats 255 configurations so), and distinct
/// poses of a calibration plan differ by degrees.
pub const SAME_POSE_TOL: f64 = 1.745_329_251_994_33e-4;

/// Indices of measurements grouped by the same joint vector within [`SAME_POSE_TOL`] (groups of
/// two or more, each in row order). Single linkage over a sweep sorted by the first joint: a
/// pair closer than the tolerance in every joint joins their groups.
fn replicate_groups(d: &Data) -> Vec<Vec<usize>> {
    let qs: Vec<&[f64]> = d.obs.iter().map(|o| o.q.as_slice()).collect();
    same_pose_groups(&qs)
}

/// [`replicate_groups`] over joint vectors.
fn same_pose_groups(qs: &[&[f64]]) -> Vec<Vec<usize>> {
    let n = qs.len();
    let mut order: Vec<usize> = (0..n).collect();
    let first = |i: usize| qs[i].first().copied().unwrap_or(0.0);
    order.sort_by(|&a, &b| first(a).total_cmp(&first(b)));
    let mut parent: Vec<usize> = (0..n).collect();
    fn root(parent: &mut [usize], mut i: usize) -> usize {
        while parent[i] != i {
            parent[i] = parent[parent[i]];
            i = parent[i];
        }
        i
    }
    for (k, &i) in order.iter().enumerate() {
        for &j in &order[k + 1..] {
            if first(j) - first(i) > SAME_POSE_TOL {
                break;
            }
            let same = qs[i]
                .iter()
                .zip(qs[j])
                .all(|(a, b)| (a - b).abs() <= SAME_POSE_TOL);
            if same {
                let (ri, rj) = (root(&mut parent, i), root(&mut parent, j));
                if ri != rj {
                    parent[ri.max(rj)] = ri.min(rj);
                }
            }
        }
    }
    let mut map: BTreeMap<usize, Vec<usize>> = BTreeMap::new();
    for i in 0..n {
        let r = root(&mut parent, i);
        map.entry(r).or_default().push(i);
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

#[cfg(test)]
mod tests {
    use super::*;

    /// Readings 0.002° apart are one pose, 0.05° apart are two; a chain of close readings joins.
    #[test]
    fn poses_within_the_tolerance_group_and_others_do_not() {
        let deg = 1f64.to_radians();
        let q = [
            vec![0.0, 0.0],
            vec![1.0, 1.0],
            vec![0.002 * deg, -0.001 * deg],
            vec![0.05 * deg, 0.0],
            vec![1.0 + 0.003 * deg, 1.0],
        ];
        let qs: Vec<&[f64]> = q.iter().map(Vec::as_slice).collect();
        assert_eq!(same_pose_groups(&qs), vec![vec![0, 2], vec![1, 4]]);
    }
}
