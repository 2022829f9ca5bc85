//! Stage 4b, the unknown modelled: the shapes forward selection located ([`super::select`])
//! form a smooth *discrepancy term* fitted beside the geometry and the named effects. Each shape
//! is described by what it depends on (own joint angle, another joint's angle, approach
//! direction, time, position), its form (localised, periodic with its order, or smooth), where
//! (an interval of the driving variable or a region of the workspace) and its visible size ± σ;
//! the term as a whole by the RMS on the fitted and the held-out data with and without it —
//! reported apart from the named physics, since it describes a residual and explains nothing.
//!
//! The term is a regression spline / radial-basis fit (the columns of [`super::shapes`]), so its
//! fitted coefficients with the bases' knots and centres ([`DiscrepancyModel`]) reproduce it on
//! any recording of the rig. The report types are in [`super::report`]; the simulated truth and
//! scenario entry of the fitted term are [`crate::effects::discrepancy`].
//!
//! Units: mm for sizes, degrees (mm for prismatic joints) for joint errors and intervals,
//! seconds for time.

use super::effects::{size_with_sigma, EffectInputs};
use super::heldout::{heldout_rms, Heldout, HeldoutRecording, Terms};
use super::linalg::{orth_basis, project_out, rms3};
use super::report::{DiscrepancyModel, DiscrepancyReport, Region, ShapeReport};
use super::select::{Chosen, ChosenShape};
use super::shapes::{Form, ShapeSpec, Variable};
use super::{Candidate, Data};
use nalgebra::{DMatrix, DVector, Vector3};
use rigcal_core::kinematics::{JointKind, Robot};
use std::fmt::Write;

/// The shape descriptions and the discrepancy report.
#[derive(Debug, Clone, Default)]
pub struct Described {
    /// One per chosen shape, in the order chosen.
    pub shapes: Vec<ShapeReport>,
    /// The term, when a shape was chosen.
    pub report: Option<DiscrepancyReport>,
}

/// Describes the chosen shapes of `inp.selection` from the full refit `inp.refit` and reports
/// the discrepancy term; `named_rms` is the fitted-data RMS of the geometry with the named
/// effects only.
pub fn describe(
    inp: &EffectInputs<'_>,
    lib: &[Box<dyn Candidate>],
    heldout: &[HeldoutRecording],
    named_rms: f64,
) -> Described {
    let sel = inp.selection;
    if sel.shapes.is_empty() {
        return Described::default();
    }
    let floor = inp.refit.noise_floor;
    let q_raw = orth_basis(&inp.screen.model, 1e-9);
    let mut col = inp.std.jacobian.ncols() + sel.chosen.iter().map(|c| c.x.ncols()).sum::<usize>();
    let mut shapes = Vec::new();
    let mut model = DiscrepancyModel::default();
    for s in &sel.shapes {
        let k = s.x.ncols();
        let fitted: Vec<f64> = (col..col + k).map(|i| inp.refit.fit.solution[i]).collect();
        let beta = seen_coefficients(&s.x, &fitted);
        let cov = DMatrix::from_fn(k, k, |i, j| {
            inp.refit.fit.normal_inverse[(col + i, col + j)] * inp.refit.s2
        });
        shapes.push(describe_shape(&inp.std.data, s, &beta, &cov, &q_raw, floor));
        model.shapes.push(s.spec.clone());
        model.coefficients.push(beta);
        col += k;
    }
    let effects: Vec<&Chosen> = sel.chosen.iter().collect();
    let all: Vec<&ChosenShape> = sel.shapes.iter().collect();
    let held = |shapes: &[&ChosenShape]| -> Heldout {
        heldout_rms(
            inp.std,
            Terms {
                effects: &effects,
                shapes,
            },
            lib,
            heldout,
        )
    };
    let without = held(&[]);
    let with = held(&all);
    let report = DiscrepancyReport {
        terms: sel.shapes.iter().map(|s| s.spec.label()).collect(),
        columns: sel.shapes.iter().map(|s| s.x.ncols()).sum(),
        rms_without_mm: named_rms,
        rms_with_mm: rms3(&inp.refit.residual),
        heldout_rms_without_mm: without.after,
        heldout_rms_with_mm: with.after,
        heldout: with.what,
        model,
    };
    Described {
        shapes,
        report: Some(report),
    }
}

/// Below this share of the largest eigenvalue of XᵀX (a singular value below 1e-6 of the
/// largest), a direction of a shape's coefficients is not seen by the recording.
const SEEN_TOL: f64 = 1e-12;

/// The part of a shape's fitted coefficients `beta` the recording sees: its projection on the
/// eigenvectors of XᵀX (X the shape's columns) above [`SEEN_TOL`]. A spline interval no pose
/// falls in (a grid recording's joint, e.g. the UR10's Series A has one joint 1 angle in
/// [−105°, −65°]) leaves coefficients the fit fixes by rounding alone: astronomically large
/// (a "peak" of 10⁴¹° was printed), cancelling at every pose, and absurd wherever the term is
/// evaluated between them (the description's grid, compensation, the twin). Projected out, the
/// term is unchanged at the recording's poses (to 1e-6 of its largest singular direction) and
/// stays near zero where the recording says nothing.
fn seen_coefficients(x: &DMatrix<f64>, beta: &[f64]) -> Vec<f64> {
    let b = DVector::from_column_slice(beta);
    if x.ncols() != b.len() || x.nrows() == 0 {
        return beta.to_vec();
    }
    let eig = x.tr_mul(x).symmetric_eigen();
    let largest = eig.eigenvalues.max();
    if !(largest.is_finite() && largest > 0.0) {
        return beta.to_vec();
    }
    let mut seen = DVector::zeros(b.len());
    for (i, &l) in eig.eigenvalues.iter().enumerate() {
        if l > SEEN_TOL * largest {
            let v = eig.eigenvectors.column(i);
            seen += v * v.dot(&b);
        }
    }
    seen.as_slice().to_vec()
}

/// Below this many measurements in a localised or smooth joint-space shape's interval, its
/// description says the shape may be no more than those measurements' own errors: so few poses
/// cannot tell a shape of the joint from one bad pose. With none, the interval is the spline's
/// between recorded angles (the UR10's Series A is a grid: on 993 of its rows joint 2's shape
/// is largest in [−151°, −143°], where no row lies).
const FEW_MEASUREMENTS: usize = 10;

/// Points on the grid of a driving variable's range.
const GRID: usize = 241;

/// One shape's report from its coefficients `beta` (covariance `cov`); `q_raw` an orthonormal
/// basis of the standard model (unweighted).
fn describe_shape(
    d: &Data,
    s: &ChosenShape,
    beta: &[f64],
    cov: &DMatrix<f64>,
    q_raw: &DMatrix<f64>,
    floor: f64,
) -> ShapeReport {
    let b = DVector::from_column_slice(beta);
    let c = &s.x * &b;
    let vis = project_out(q_raw, &DMatrix::from_column_slice(c.len(), 1, c.as_slice()));
    let vis = DVector::from_column_slice(vis.as_slice());
    let (size, size_sigma) = size_with_sigma(&s.x, &vis, cov);
    let v = s.spec.variable;
    let mut r = ShapeReport {
        depends_on: v.key().into(),
        joint: v.acted_joint().map(|j| j + 1),
        driver_joint: v.driver_joint().map(|j| j + 1),
        form: "smooth".into(),
        order: None,
        interval: None,
        interval_unit: None,
        measurements_in_interval: None,
        region: None,
        peak: 0.0,
        peak_unit: "mm".into(),
        size_mm: size,
        size_sigma_mm: size_sigma,
        size_over_floor: size / floor.max(1e-300),
        p_value: s.p,
        basis: s.spec.form.label(),
        description: String::new(),
    };
    match v {
        Variable::OwnAngle { .. } | Variable::OtherAngle { .. } | Variable::Direction { .. } => {
            joint_shape(d, &s.spec, beta, &mut r);
        }
        Variable::Time => time_shape(d, &s.spec, beta, &mut r),
        Variable::Position => position_shape(d, &vis, &mut r),
    }
    r.description = shape_text(&s.spec, &r);
    r
}

/// The range of joint `j` over the measurements.
fn range_of(d: &Data, j: usize) -> (f64, f64) {
    d.obs.iter().fold((f64::MAX, f64::MIN), |(a, b), o| {
        (a.min(o.q[j]), b.max(o.q[j]))
    })
}

/// Form, interval and peak of a joint-space shape: its joint error g(q_driver) = f(q)·β on a
/// grid of the driver's range, less its mean over the measurements (a constant is the joint's
/// offset, geometry).
fn joint_shape(d: &Data, spec: &ShapeSpec, beta: &[f64], r: &mut ShapeReport) {
    let (Some(acted), Some(driver)) = (spec.variable.acted_joint(), spec.variable.driver_joint())
    else {
        return;
    };
    let (lo, hi) = match spec.form {
        Form::Spline { lo, hi, .. } => (lo, hi),
        _ => range_of(d, driver),
    };
    let g = |x: f64| -> f64 {
        spec.form
            .values(x)
            .iter()
            .zip(beta)
            .map(|(f, b)| f * b)
            .sum()
    };
    let centre = if matches!(spec.variable, Variable::Direction { .. }) {
        0.0
    } else {
        d.obs.iter().map(|o| g(o.q[driver])).sum::<f64>() / d.len().max(1) as f64
    };
    let xs: Vec<f64> = (0..GRID)
        .map(|i| lo + (hi - lo) * i as f64 / (GRID - 1) as f64)
        .collect();
    let ys: Vec<f64> = xs.iter().map(|&x| g(x) - centre).collect();
    let unit = |j: usize, v: f64| match d.chain.joints()[j].kind {
        JointKind::Revolute => v.to_degrees(),
        JointKind::Prismatic => v,
    };
    let revolute_driver = d.chain.joints()[driver].kind == JointKind::Revolute;
    let (form, interval, order) = classify(&xs, &ys, revolute_driver);
    r.form = form.into();
    r.order = order;
    r.interval = Some([unit(driver, interval[0]), unit(driver, interval[1])]);
    if form != "periodic" {
        r.measurements_in_interval = Some(
            d.obs
                .iter()
                .filter(|o| (interval[0]..=interval[1]).contains(&o.q[driver]))
                .count(),
        );
    }
    r.interval_unit = Some(if revolute_driver { "deg" } else { "mm" }.into());
    r.peak = unit(acted, ys.iter().fold(0.0f64, |a, y| a.max(y.abs())));
    r.peak_unit = match d.chain.joints()[acted].kind {
        JointKind::Revolute => "deg".into(),
        JointKind::Prismatic => "mm".into(),
    };
}

/// Form, interval and peak of a time shape: the 3-D size of its displacement over time.
fn time_shape(d: &Data, spec: &ShapeSpec, beta: &[f64], r: &mut ShapeReport) {
    let Form::Spline { lo, hi, .. } = spec.form else {
        return;
    };
    let k = spec.form.functions();
    let disp = |t: f64| -> Vector3<f64> {
        let f = spec.form.values(t);
        Vector3::from_fn(|a, _| (0..k).map(|c| f[c] * beta[a * k + c]).sum())
    };
    let mean = d
        .t_s
        .as_ref()
        .map(|ts| ts.iter().map(|&t| disp(t)).sum::<Vector3<f64>>() / ts.len().max(1) as f64)
        .unwrap_or_default();
    let xs: Vec<f64> = (0..GRID)
        .map(|i| lo + (hi - lo) * i as f64 / (GRID - 1) as f64)
        .collect();
    let ys: Vec<f64> = xs.iter().map(|&t| (disp(t) - mean).norm()).collect();
    let (form, interval, _) = classify(&xs, &ys, false);
    r.form = form.into();
    r.interval = Some(interval);
    r.interval_unit = Some("s".into());
    r.peak = ys.iter().fold(0.0f64, |a, y| a.max(*y));
}

/// Form, region and peak of a position shape from its visible displacement `vis` (stacked).
fn position_shape(d: &Data, vis: &DVector<f64>, r: &mut ShapeReport) {
    let n = d.len();
    let size: Vec<f64> = (0..n)
        .map(|i| Vector3::new(vis[3 * i], vis[3 * i + 1], vis[3 * i + 2]).norm())
        .collect();
    let peak = size.iter().fold(0.0f64, |a, v| a.max(*v));
    let inside: Vec<usize> = (0..n).filter(|&i| size[i] >= 0.5 * peak).collect();
    let total: f64 = size.iter().map(|v| v * v).sum();
    let energy: f64 = inside.iter().map(|&i| size[i] * size[i]).sum();
    let p: Vec<Vector3<f64>> = d.obs.iter().map(|o| d.chain.position(&o.q, &d.e)).collect();
    let w: f64 = energy.max(1e-300);
    let centre = inside
        .iter()
        .map(|&i| p[i] * size[i] * size[i])
        .sum::<Vector3<f64>>()
        / w;
    let radius = (inside
        .iter()
        .map(|&i| (p[i] - centre).norm_squared() * size[i] * size[i])
        .sum::<f64>()
        / w)
        .sqrt();
    let (mut lo, mut hi) = (Vector3::repeat(f64::MAX), Vector3::repeat(f64::MIN));
    for &i in &inside {
        lo = lo.inf(&p[i]);
        hi = hi.sup(&p[i]);
    }
    let localised = (inside.len() as f64) <= LOCAL_FRACTION * n as f64
        && energy >= LOCAL_ENERGY * total.max(1e-300);
    r.form = if localised { "localised" } else { "smooth" }.into();
    r.peak = peak;
    r.region = Some(Region {
        centre_mm: [centre.x, centre.y, centre.z],
        radius_mm: radius,
        min_mm: [lo.x, lo.y, lo.z],
        max_mm: [hi.x, hi.y, hi.z],
        measurements: inside.len(),
    });
}

/// A shape is localised when where it reaches half its peak covers at most this fraction of the
/// range (of the measurements, for a position shape) …
const LOCAL_FRACTION: f64 = 0.35;
/// … and holds at least this fraction of its energy.
const LOCAL_ENERGY: f64 = 0.6;
/// A shape is periodic when one harmonic explains this fraction of its variance …
const PERIODIC_SHARE: f64 = 0.7;
/// … over at least this many cycles in the range.
const PERIODIC_CYCLES: f64 = 1.5;
/// Highest order tried for a periodic shape.
const MAX_PERIODIC_ORDER: u32 = 16;

/// Form of a 1-D shape `ys` on the grid `xs`: (form, interval, order). The interval is where
/// |y| reaches half its peak around the peak (the whole range for a periodic shape).
fn classify(xs: &[f64], ys: &[f64], angle: bool) -> (&'static str, [f64; 2], Option<u32>) {
    let n = ys.len();
    let abs: Vec<f64> = ys.iter().map(|y| y.abs()).collect();
    let top = (0..n)
        .max_by(|&a, &b| abs[a].total_cmp(&abs[b]))
        .unwrap_or(0);
    let half = 0.5 * abs.get(top).copied().unwrap_or(0.0);
    let (mut a, mut b) = (top, top);
    while a > 0 && abs[a - 1] >= half {
        a -= 1;
    }
    while b + 1 < n && abs[b + 1] >= half {
        b += 1;
    }
    let full = [
        xs.first().copied().unwrap_or(0.0),
        xs.last().copied().unwrap_or(0.0),
    ];
    let span = (full[1] - full[0]).max(1e-300);
    let total: f64 = ys.iter().map(|y| y * y).sum::<f64>().max(1e-300);
    let inside: f64 = ys[a..=b].iter().map(|y| y * y).sum();
    let interval = [xs[a], xs[b]];
    // Localised: it rises and falls back inside the range, within a small part of it.
    let interior = a > 0 && b + 1 < n;
    if interior && (xs[b] - xs[a]) / span <= LOCAL_FRACTION && inside / total >= LOCAL_ENERGY {
        return ("localised", interval, None);
    }
    if angle {
        if let Some(order) = dominant_order(xs, ys, span) {
            return ("periodic", full, Some(order));
        }
    }
    ("smooth", interval, None)
}

/// The harmonic order (cycles per 2π of x) that alone explains [`PERIODIC_SHARE`] of the
/// variance of `ys` over at least [`PERIODIC_CYCLES`] cycles, if one does.
fn dominant_order(xs: &[f64], ys: &[f64], span: f64) -> Option<u32> {
    let n = ys.len() as f64;
    let mean = ys.iter().sum::<f64>() / n;
    let var: f64 = ys.iter().map(|y| (y - mean).powi(2)).sum();
    if var <= 0.0 {
        return None;
    }
    let mut best: Option<(u32, f64)> = None;
    for order in 1..=MAX_PERIODIC_ORDER {
        if f64::from(order) * span / std::f64::consts::TAU < PERIODIC_CYCLES {
            continue;
        }
        let w = f64::from(order);
        let a = DMatrix::from_fn(xs.len(), 3, |i, c| match c {
            0 => 1.0,
            1 => (w * xs[i]).sin(),
            _ => (w * xs[i]).cos(),
        });
        let y = DVector::from_column_slice(ys);
        let fit = super::linalg::lstsq(&a, &y);
        let res = &y - &a * &fit.solution;
        let share = 1.0 - res.norm_squared() / var;
        if best.is_none_or(|b| share > b.1) {
            best = Some((order, share));
        }
    }
    best.filter(|b| b.1 >= PERIODIC_SHARE).map(|b| b.0)
}

/// Plain-language description of a shape.
fn shape_text(spec: &ShapeSpec, r: &ShapeReport) -> String {
    let mut s = spec.variable.label();
    let unit = r.interval_unit.as_deref().unwrap_or("");
    let unit_sym = if unit == "deg" {
        "°".to_string()
    } else {
        format!(" {unit}")
    };
    let span = |i: [f64; 2]| format!("[{:.0}, {:.0}]{unit_sym}", i[0], i[1]);
    match (r.form.as_str(), r.interval, &r.region) {
        ("periodic", Some(i), _) => {
            let _ = write!(
                s,
                ", periodic: {} cycles per revolution over {}",
                r.order.unwrap_or(0),
                span(i)
            );
        }
        ("localised", _, Some(g)) => {
            let _ = write!(
                s,
                ", localised around ({:.0}, {:.0}, {:.0}) mm within {:.0} mm ({} measurements)",
                g.centre_mm[0], g.centre_mm[1], g.centre_mm[2], g.radius_mm, g.measurements
            );
        }
        (form, Some(i), _) => {
            let where_ = if form == "localised" {
                "in"
            } else {
                "largest in"
            };
            let _ = write!(s, ", {form}, {where_} {}", span(i));
            match r.measurements_in_interval {
                Some(0) => s.push_str(
                    " (no measurement there: the spline between the recorded angles, not measured)",
                ),
                Some(n) if n < FEW_MEASUREMENTS => {
                    let _ = write!(
                        s,
                        " (only {n} measurement(s) there: it may be no more than their own errors)"
                    );
                }
                _ => {}
            }
        }
        (form, None, Some(g)) => {
            let _ = write!(
                s,
                ", {form}, largest around ({:.0}, {:.0}, {:.0}) mm",
                g.centre_mm[0], g.centre_mm[1], g.centre_mm[2]
            );
        }
        _ => {}
    }
    let peak_unit = if r.peak_unit == "deg" { "°" } else { " mm" };
    let _ = write!(
        s,
        "; peak {:.4}{peak_unit}, {:.4} ± {:.4} mm RMS past the geometry ({:.1} × the noise floor)",
        r.peak, r.size_mm, r.size_sigma_mm, r.size_over_floor
    );
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grid(lo: f64, hi: f64) -> Vec<f64> {
        (0..GRID)
            .map(|i| lo + (hi - lo) * i as f64 / (GRID - 1) as f64)
            .collect()
    }

    #[test]
    fn coefficients_no_pose_sees_are_dropped_and_the_rest_kept() {
        // Columns: a constant, a ramp, and a basis function no row reaches (a spline interval
        // without poses), whose coefficient rounding made astronomically large.
        let x = DMatrix::from_fn(9, 3, |r, c| match c {
            0 => 1.0,
            1 => r as f64 / 8.0,
            _ => 0.0,
        });
        let seen = seen_coefficients(&x, &[2.0, -3.0, 4.5e41]);
        assert!(
            (seen[0] - 2.0).abs() < 1e-9 && (seen[1] + 3.0).abs() < 1e-9,
            "{seen:?}"
        );
        assert!(seen[2].abs() < 1e-9, "{seen:?}");
        // A well-seen fit is returned as it is.
        let seen = seen_coefficients(&x.columns(0, 2).into_owned(), &[2.0, -3.0]);
        assert!(
            (seen[0] - 2.0).abs() < 1e-9 && (seen[1] + 3.0).abs() < 1e-9,
            "{seen:?}"
        );
    }

    #[test]
    fn a_shape_resting_on_a_few_measurements_says_so() {
        let spec = ShapeSpec {
            variable: Variable::OwnAngle { joint: 0 },
            form: Form::Spline {
                lo: -3.0,
                hi: 0.7,
                intervals: 20,
            },
        };
        let mut r = ShapeReport {
            depends_on: "own_joint_angle".into(),
            joint: Some(1),
            driver_joint: Some(1),
            form: "localised".into(),
            order: None,
            interval: Some([-87.0, -73.0]),
            interval_unit: Some("deg".into()),
            measurements_in_interval: Some(1),
            region: None,
            peak: 2.42,
            peak_unit: "deg".into(),
            size_mm: 0.22,
            size_sigma_mm: 0.0,
            size_over_floor: 0.5,
            p_value: 0.0,
            basis: String::new(),
            description: String::new(),
        };
        assert!(shape_text(&spec, &r).contains("only 1 measurement(s) there"));
        r.measurements_in_interval = Some(0);
        assert!(shape_text(&spec, &r).contains("no measurement there"));
        r.measurements_in_interval = Some(FEW_MEASUREMENTS);
        assert!(!shape_text(&spec, &r).contains("only"));
    }

    #[test]
    fn a_narrow_bump_is_localised_where_it_is() {
        let xs = grid(-1.0, 2.0);
        let ys: Vec<f64> = xs
            .iter()
            .map(|x| (-(x - 0.5f64).powi(2) / (2.0 * 0.1 * 0.1)).exp())
            .collect();
        let (form, i, order) = classify(&xs, &ys, true);
        assert_eq!((form, order), ("localised", None));
        // Half maximum at 0.5 ± 0.1·√(2 ln 2) = 0.5 ± 0.118.
        assert!(
            (i[0] - 0.382).abs() < 0.02 && (i[1] - 0.618).abs() < 0.02,
            "{i:?}"
        );
    }

    #[test]
    fn a_harmonic_is_periodic_with_its_order_and_a_slow_wave_is_smooth() {
        let xs = grid(-2.0, 2.0);
        let ys: Vec<f64> = xs.iter().map(|x| (7.0 * x + 0.3).sin()).collect();
        assert_eq!(classify(&xs, &ys, true).2, Some(7));
        assert_eq!(classify(&xs, &ys, true).0, "periodic");
        // Not an angle: no order.
        assert_eq!(classify(&xs, &ys, false).0, "smooth");
        let slow: Vec<f64> = xs.iter().map(|x| (0.5 * x).sin()).collect();
        assert_eq!(classify(&xs, &slow, true).0, "smooth");
    }
}
