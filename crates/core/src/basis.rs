//! Smooth function bases, linear in their coefficients: cubic B-splines on equal intervals,
//! harmonics of chosen orders, Gaussian radial functions. The diagnosis fits located residuals
//! in them (`rigcal_model::diagnosis::shapes`); the simulated world evaluates a fitted
//! discrepancy term with the same functions (`rigcal_model::effects::discrepancy`), so what the
//! twin fits is what it simulates.
//!
//! Units: the scalar variable in its own internal unit (rad, mm or s; harmonics take radians),
//! positions in mm.

use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

/// A flexible form: a family of functions of one scalar or of a position.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "form", rename_all = "snake_case")]
pub enum Form {
    /// Cubic B-splines on `intervals` equal intervals of [lo, hi] (intervals + 3 functions).
    Spline {
        /// Lower end of the fitted range (rad, mm or s).
        lo: f64,
        /// Upper end.
        hi: f64,
        /// Number of intervals.
        intervals: usize,
    },
    /// sin(n·q), cos(n·q) for n in orders[0]..=orders[1].
    Harmonics {
        /// Lowest and highest order (cycles per 360°).
        orders: [u32; 2],
    },
    /// exp(−|p − c|²/2w²) for each centre c (mm), on each world axis.
    Radial {
        /// The centres (world, mm).
        centres: Vec<[f64; 3]>,
        /// The width w (mm).
        width_mm: f64,
    },
}

/// The cardinal cubic B-spline on [0, 4].
fn cubic_bspline(s: f64) -> f64 {
    if !(0.0..4.0).contains(&s) {
        0.0
    } else if s < 1.0 {
        s * s * s / 6.0
    } else if s < 2.0 {
        (-3.0 * s * s * s + 12.0 * s * s - 12.0 * s + 4.0) / 6.0
    } else if s < 3.0 {
        (3.0 * s * s * s - 24.0 * s * s + 60.0 * s - 44.0) / 6.0
    } else {
        (4.0 - s).powi(3) / 6.0
    }
}

/// The `intervals` + 3 cubic B-splines on equal intervals of [lo, hi] at x (clamped to the
/// range); they sum to 1.
pub fn spline_values(x: f64, lo: f64, hi: f64, intervals: usize) -> Vec<f64> {
    let h = (hi - lo).max(1e-300) / intervals as f64;
    let u = ((x - lo) / h).clamp(0.0, intervals as f64);
    (0..intervals + 3)
        .map(|i| cubic_bspline(u - i as f64 + 3.0))
        .collect()
}

impl Form {
    /// Number of functions (per axis for Cartesian shapes).
    pub fn functions(&self) -> usize {
        match self {
            Form::Spline { intervals, .. } => intervals + 3,
            Form::Harmonics { orders } => 2 * (orders[1] - orders[0] + 1) as usize,
            Form::Radial { centres, .. } => centres.len(),
        }
    }

    /// The functions at a scalar value (splines and harmonics).
    pub fn values(&self, x: f64) -> Vec<f64> {
        match self {
            Form::Spline { lo, hi, intervals } => spline_values(x, *lo, *hi, *intervals),
            Form::Harmonics { orders } => (orders[0]..=orders[1])
                .flat_map(|n| {
                    let a = f64::from(n) * x;
                    [a.sin(), a.cos()]
                })
                .collect(),
            Form::Radial { .. } => Vec::new(),
        }
    }

    /// The functions at a position (radial bases).
    pub fn values_at(&self, p: &Vector3<f64>) -> Vec<f64> {
        match self {
            Form::Radial { centres, width_mm } => centres
                .iter()
                .map(|c| {
                    let d2 = (p - Vector3::from(*c)).norm_squared();
                    (-d2 / (2.0 * width_mm * width_mm)).exp()
                })
                .collect(),
            _ => Vec::new(),
        }
    }

    /// Plain language: "cubic B-splines, 20 intervals".
    pub fn label(&self) -> String {
        match self {
            Form::Spline { intervals, .. } => format!("cubic B-splines on {intervals} intervals"),
            Form::Harmonics { orders } => {
                format!("harmonics of orders {}–{}", orders[0], orders[1])
            }
            Form::Radial { centres, width_mm } => format!(
                "{} Gaussian radial functions of width {width_mm:.0} mm",
                centres.len()
            ),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cubic_b_splines_are_a_partition_of_unity_with_local_support() {
        for &x in &[0.0, 0.13, 0.5, 0.77, 1.0] {
            let v = spline_values(x, 0.0, 1.0, 10);
            assert_eq!(v.len(), 13);
            assert!((v.iter().sum::<f64>() - 1.0).abs() < 1e-12, "{x}: {v:?}");
            // At most four functions are non-zero anywhere.
            assert!(v.iter().filter(|a| **a > 0.0).count() <= 4);
        }
        // At a knot the three neighbouring functions are 1/6, 2/3, 1/6.
        let v = spline_values(0.3, 0.0, 1.0, 10);
        let nz: Vec<f64> = v.iter().copied().filter(|a| *a > 1e-12).collect();
        assert_eq!(nz.len(), 3);
        assert!((nz[0] - 1.0 / 6.0).abs() < 1e-12 && (nz[1] - 2.0 / 3.0).abs() < 1e-12);
        // Outside the range the values are those at its end.
        assert_eq!(
            spline_values(-5.0, 0.0, 1.0, 10),
            spline_values(0.0, 0.0, 1.0, 10)
        );
    }

    #[test]
    fn harmonics_have_two_functions_per_order() {
        let f = Form::Harmonics { orders: [5, 12] };
        assert_eq!(f.functions(), 16);
        let v = f.values(0.3);
        assert!((v[0] - (1.5f64).sin()).abs() < 1e-15 && (v[15] - (3.6f64).cos()).abs() < 1e-15);
    }
}
