//! Evaluation along paths and plots a person can look at (SVG).
//!
//! A path is a list of nominal joint solutions; its targets are their nominal positions. For each
//! error model the arm is commanded with compensation and the position error is |truth(command) −
//! target| (mm), the truth coming from a simulated world. CEP traces and the largest jump of each
//! CEP between consecutive path points measure smoothness.

pub mod html;
pub mod svg;

use crate::compensation::{compensate_from, CompensationOptions};
use crate::identification::ResidualStats;
use nalgebra::Vector3;
use plotters::prelude::*;
use rigcal_core::kinematics::{
    solve_position_ik, ErrorModel, ErrorParams, IkOptions, Robot, Spherical, SphericalFrame,
};
use rigcal_core::rig::Rig;
use std::path::Path;

/// A path: nominal joint solutions, one per point.
#[derive(Debug, Clone)]
pub struct PathSpec {
    /// Title for reports.
    pub name: String,
    /// Nominal joint values per point (rad, mm).
    pub points: Vec<Vec<f64>>,
}

/// Why a path could not be made.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum PathError {
    /// A point of the path has no nominal joint solution.
    #[error("path point {index} has no joint solution: {source}")]
    Unreachable {
        /// Point index.
        index: usize,
        /// The inverse-kinematics error.
        source: rigcal_core::kinematics::IkError,
    },
    /// Writing a plot failed.
    #[error("cannot write plot {path}: {reason}")]
    Plot {
        /// The file.
        path: String,
        /// Why.
        reason: String,
    },
}

/// A straight line in joint space between two sets of the moving joints' values (deg or mm),
/// held joints at their calibration values.
pub fn joint_path(rig: &Rig, name: &str, a: &[f64], b: &[f64], n: usize) -> PathSpec {
    let moving = rig.moving_joints();
    let joints = rig.chain.joints();
    let points = (0..n)
        .map(|k| {
            let t = k as f64 / (n.max(2) - 1) as f64;
            let mut q: Vec<f64> = rig.held().iter().map(|h| h.unwrap_or(0.0)).collect();
            for (m, &j) in moving.iter().enumerate().take(a.len().min(b.len())) {
                q[j] = joints[j].kind.from_file_units(a[m] + t * (b[m] - a[m]));
            }
            q
        })
        .collect();
    PathSpec {
        name: name.into(),
        points,
    }
}

/// A straight line in spherical coordinates (R mm, azimuth deg, elevation deg).
pub fn spherical_path(
    rig: &Rig,
    name: &str,
    a: [f64; 3],
    b: [f64; 3],
    n: usize,
) -> Result<PathSpec, PathError> {
    let sf = SphericalFrame::of(&rig.chain);
    let e = ErrorParams::zeros(rig.chain.layout());
    let mut points = Vec::with_capacity(n);
    let mut seed: Option<Vec<f64>> = None;
    for k in 0..n {
        let t = k as f64 / (n.max(2) - 1) as f64;
        let s = Spherical {
            r: a[0] + t * (b[0] - a[0]),
            azimuth: (a[1] + t * (b[1] - a[1])).to_radians(),
            elevation: (a[2] + t * (b[2] - a[2])).to_radians(),
        };
        let p = sf.to_world(&s);
        let q = solve_position_ik(
            &rig.chain,
            &e,
            &p,
            rig.held(),
            seed.as_deref(),
            &IkOptions::default(),
        )
        .map_err(|source| PathError::Unreachable { index: k, source })?;
        seed = Some(q.clone());
        points.push(q);
    }
    Ok(PathSpec {
        name: name.into(),
        points,
    })
}

/// One model's performance along a path.
#[derive(Debug, Clone)]
pub struct PathResult {
    /// Model name (`uncalibrated`, `conventional`, `regions`, `fcmac`, …).
    pub model: String,
    /// Position error per point (mm); NaN where compensation failed.
    pub errors: Vec<f64>,
    /// Traced CEPs per point (file units), in the order of the requested names.
    pub traces: Vec<Vec<f64>>,
    /// Points where compensation failed.
    pub failures: usize,
}

impl PathResult {
    /// Statistics of the errors where compensation succeeded.
    pub fn stats(&self) -> ResidualStats {
        let v: Vec<Vector3<f64>> = self
            .errors
            .iter()
            .filter(|e| e.is_finite())
            .map(|&e| Vector3::new(e, 0.0, 0.0))
            .collect();
        ResidualStats::of(&v)
    }

    /// Largest jump of each traced CEP between consecutive points (file units).
    pub fn largest_jumps(&self) -> Vec<f64> {
        self.traces
            .iter()
            .map(|t| {
                t.windows(2)
                    .map(|w| (w[1] - w[0]).abs())
                    .fold(0.0, f64::max)
            })
            .collect()
    }
}

/// Evaluates models along a path against `truth` (the simulated arm's true position for a
/// command). `trace` names CEPs to trace (`theta1`, `d1`, …).
pub fn evaluate_path(
    rig: &Rig,
    path: &PathSpec,
    models: &[(String, &dyn ErrorModel)],
    truth: &dyn Fn(&[f64]) -> Vector3<f64>,
    trace: &[&str],
) -> Vec<PathResult> {
    let layout = rig.chain.layout();
    let nominal = ErrorParams::zeros(layout);
    let idx: Vec<Option<usize>> = trace
        .iter()
        .map(|n| layout.find(n).and_then(|id| layout.index_of(id)))
        .collect();
    let targets: Vec<Vector3<f64>> = path
        .points
        .iter()
        .map(|q| rig.chain.position(q, &nominal))
        .collect();
    let mut out = vec![PathResult {
        model: "uncalibrated".into(),
        errors: path
            .points
            .iter()
            .zip(&targets)
            .map(|(q, t)| (truth(q) - t).norm())
            .collect(),
        traces: Vec::new(),
        failures: 0,
    }];
    let opts = CompensationOptions::default();
    for (name, model) in models {
        let mut r = PathResult {
            model: name.clone(),
            errors: Vec::with_capacity(path.points.len()),
            traces: vec![Vec::with_capacity(path.points.len()); trace.len()],
            failures: 0,
        };
        for (q, t) in path.points.iter().zip(&targets) {
            let e = model.params_at(q);
            for (k, i) in idx.iter().enumerate() {
                let v = i
                    .map(|i| layout.ids()[i].kind.to_file_units(e.get(i)))
                    .unwrap_or(f64::NAN);
                r.traces[k].push(v);
            }
            match compensate_from(&rig.chain, *model, t, rig.held(), q.clone(), &opts) {
                Ok(c) => r.errors.push((truth(&c.command) - t).norm()),
                Err(_) => {
                    r.failures += 1;
                    r.errors.push(f64::NAN);
                }
            }
        }
        out.push(r);
    }
    out
}

/// A path's name and, on the next line, every model's mean / max error (mm).
pub fn mean_max_rows(path: &str, results: &[PathResult]) -> String {
    let mut s = format!("  {path}\n   ");
    for r in results {
        let st = r.stats();
        s.push_str(&format!(
            "  {} {:.4} / {:.4}",
            r.model, st.mean_mm, st.max_mm
        ));
    }
    s.push('\n');
    s
}

/// Okabe–Ito, colour-blind safe (black first: the uncalibrated curve).
const COLOURS: [RGBColor; 7] = [
    RGBColor(0, 0, 0),
    RGBColor(230, 159, 0),
    RGBColor(86, 180, 233),
    RGBColor(0, 158, 115),
    RGBColor(213, 94, 0),
    RGBColor(0, 114, 178),
    RGBColor(204, 121, 167),
];

/// Curves whose largest and smallest positive values differ by more than this factor are
/// drawn on a log axis, so calibrated curves are not squashed onto zero.
const LOG_SCALE_RATIO: f64 = 20.0;

fn plot_err(path: &Path, e: impl std::fmt::Display) -> PathError {
    PathError::Plot {
        path: path.display().to_string(),
        reason: e.to_string(),
    }
}

/// Plots the position error along the path for every model (SVG).
pub fn plot_errors(file: &Path, title: &str, results: &[PathResult]) -> Result<(), PathError> {
    let root = SVGBackend::new(file, (1000, 480)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| plot_err(file, e))?;
    // The legend lives in its own strip right of the data, so it never hides a curve.
    let (plot_area, legend_area) = root.split_horizontally(800);
    let n = results.first().map_or(1, |r| r.errors.len()).max(2);
    let positive = || {
        results
            .iter()
            .flat_map(|r| r.errors.iter().copied())
            .filter(|v| v.is_finite() && *v > 0.0)
    };
    let ymax = positive().fold(0.0f64, f64::max) * 1.1 + 1e-6;
    let ymin = positive().fold(f64::INFINITY, f64::min);
    let series = |r: &PathResult| -> Vec<(f64, f64)> {
        r.errors
            .iter()
            .enumerate()
            .filter(|(_, v)| v.is_finite())
            .map(|(i, &v)| (i as f64, v))
            .collect()
    };
    let builder = |area| {
        let mut b = ChartBuilder::on(area);
        b.caption(title, ("sans-serif", 20))
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(70);
        b
    };
    if ymin.is_finite() && ymax / ymin > LOG_SCALE_RATIO {
        let lo = ymin / 1.5;
        let mut chart = builder(&plot_area)
            .build_cartesian_2d(0f64..(n - 1) as f64, (lo..ymax).log_scale())
            .map_err(|e| plot_err(file, e))?;
        chart
            .configure_mesh()
            .x_desc("point on the path")
            .y_desc("position error (mm, log scale)")
            .y_label_formatter(&|v| tick_label(*v))
            .x_label_formatter(&|v| tick_label(*v))
            .draw()
            .map_err(|e| plot_err(file, e))?;
        for (k, r) in results.iter().enumerate() {
            let c = COLOURS[k % COLOURS.len()];
            let pts = series(r).into_iter().map(|(x, y)| (x, y.max(lo)));
            chart
                .draw_series(LineSeries::new(pts, c.stroke_width(2)))
                .map_err(|e| plot_err(file, e))?;
        }
    } else {
        let mut chart = builder(&plot_area)
            .build_cartesian_2d(0f64..(n - 1) as f64, 0f64..ymax)
            .map_err(|e| plot_err(file, e))?;
        chart
            .configure_mesh()
            .x_desc("point on the path")
            .y_desc("position error (mm)")
            .y_label_formatter(&|v| tick_label(*v))
            .x_label_formatter(&|v| tick_label(*v))
            .draw()
            .map_err(|e| plot_err(file, e))?;
        for (k, r) in results.iter().enumerate() {
            let c = COLOURS[k % COLOURS.len()];
            chart
                .draw_series(LineSeries::new(series(r), c.stroke_width(2)))
                .map_err(|e| plot_err(file, e))?;
        }
    }
    draw_legend(&legend_area, results.iter().map(|r| r.model.as_str()))
        .map_err(|e| plot_err(file, e))?;
    root.present().map_err(|e| plot_err(file, e))
}

/// A tick label without "-0" and without trailing zeros.
fn tick_label(v: f64) -> String {
    crate::report::svg::tick(v)
}

/// One line and name per curve, top to bottom, in the strip beside the chart.
fn draw_legend<'a, DB: DrawingBackend>(
    area: &DrawingArea<DB, plotters::coord::Shift>,
    names: impl Iterator<Item = &'a str>,
) -> Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
    for (k, name) in names.enumerate() {
        let c = COLOURS[k % COLOURS.len()];
        let y = 60 + 24 * k as i32;
        area.draw(&PathElement::new(vec![(8, y), (34, y)], c.stroke_width(3)))?;
        area.draw(&Text::new(
            name.to_string(),
            (42, y - 8),
            ("sans-serif", 15),
        ))?;
    }
    Ok(())
}

/// Plots traced CEPs along the path, one panel per CEP (SVG).
pub fn plot_traces(
    file: &Path,
    title: &str,
    names: &[&str],
    units: &[&str],
    results: &[PathResult],
) -> Result<(), PathError> {
    let root =
        SVGBackend::new(file, (900, 220 * names.len().max(1) as u32 + 40)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| plot_err(file, e))?;
    let root = root
        .titled(title, ("sans-serif", 20))
        .map_err(|e| plot_err(file, e))?;
    let panels = root.split_evenly((names.len().max(1), 1));
    for (k, panel) in panels.iter().enumerate() {
        let series: Vec<&PathResult> = results.iter().filter(|r| r.traces.len() > k).collect();
        let vals: Vec<f64> = series
            .iter()
            .flat_map(|r| r.traces[k].iter().copied())
            .filter(|v| v.is_finite())
            .collect();
        if vals.is_empty() {
            continue;
        }
        let lo = vals.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = vals.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        let pad = ((hi - lo) * 0.1).max(1e-4);
        let n = series[0].traces[k].len().max(2);
        let mut chart = ChartBuilder::on(panel)
            .margin(8)
            .x_label_area_size(30)
            .y_label_area_size(70)
            .build_cartesian_2d(0f64..(n - 1) as f64, (lo - pad)..(hi + pad))
            .map_err(|e| plot_err(file, e))?;
        chart
            .configure_mesh()
            .y_desc(format!("Δ{} ({})", names[k], units.get(k).unwrap_or(&"")))
            .draw()
            .map_err(|e| plot_err(file, e))?;
        for (s, r) in series.iter().enumerate() {
            let c = COLOURS[(s + 1) % COLOURS.len()];
            chart
                .draw_series(LineSeries::new(
                    r.traces[k].iter().enumerate().map(|(i, &v)| (i as f64, v)),
                    c.stroke_width(2),
                ))
                .map_err(|e| plot_err(file, e))?
                .label(r.model.clone())
                .legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 18, y)], c.stroke_width(2))
                });
        }
        if k == 0 {
            chart
                .configure_series_labels()
                .background_style(WHITE.mix(0.8))
                .border_style(BLACK)
                .draw()
                .map_err(|e| plot_err(file, e))?;
        }
    }
    root.present().map_err(|e| plot_err(file, e))
}

/// One panel of [`plot_log_curves`]: a title and named curves of (x, y) points.
#[derive(Debug, Clone, PartialEq)]
pub struct CurvePanel {
    /// Panel title.
    pub title: String,
    /// (name, points); points with a non-positive or non-finite coordinate are skipped.
    pub curves: Vec<(String, Vec<(f64, f64)>)>,
}

/// Plots panels side by side on logarithmic axes (SVG): learning curves and the like.
pub fn plot_log_curves(
    file: &Path,
    title: &str,
    x_desc: &str,
    y_desc: &str,
    panels: &[CurvePanel],
) -> Result<(), PathError> {
    let positive = |&(x, y): &(f64, f64)| x > 0.0 && y > 0.0 && x.is_finite() && y.is_finite();
    let points = || {
        panels
            .iter()
            .flat_map(|p| p.curves.iter().flat_map(|(_, c)| c.iter().copied()))
            .filter(positive)
    };
    let fold = |f: fn(f64, f64) -> f64, init: f64, pick: fn((f64, f64)) -> f64| {
        points().map(pick).fold(init, f)
    };
    let (x0, x1) = (
        fold(f64::min, f64::INFINITY, |p| p.0),
        fold(f64::max, 0.0, |p| p.0),
    );
    let (y0, y1) = (
        fold(f64::min, f64::INFINITY, |p| p.1),
        fold(f64::max, 0.0, |p| p.1),
    );
    if !(x0.is_finite() && y0.is_finite()) {
        return Err(plot_err(file, "no positive points to plot"));
    }
    let root = SVGBackend::new(file, (420 * panels.len().max(1) as u32, 480)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| plot_err(file, e))?;
    let root = root
        .titled(title, ("sans-serif", 20))
        .map_err(|e| plot_err(file, e))?;
    for (k, (area, panel)) in root
        .split_evenly((1, panels.len().max(1)))
        .iter()
        .zip(panels)
        .enumerate()
    {
        let mut chart = ChartBuilder::on(area)
            .caption(&panel.title, ("sans-serif", 16))
            .margin(10)
            .x_label_area_size(40)
            .y_label_area_size(70)
            .build_cartesian_2d(
                (x0..x1.max(x0 * 1.01)).log_scale(),
                (y0 / 1.5..y1 * 1.5).log_scale(),
            )
            .map_err(|e| plot_err(file, e))?;
        chart
            .configure_mesh()
            .x_desc(x_desc)
            .y_desc(y_desc)
            .x_label_formatter(&|v| format!("{v:.0}"))
            .y_label_formatter(&|v| format!("{v:.0e}"))
            .draw()
            .map_err(|e| plot_err(file, e))?;
        for (s, (name, curve)) in panel.curves.iter().enumerate() {
            let c = Palette99::pick(s).to_rgba();
            chart
                .draw_series(LineSeries::new(
                    curve.iter().copied().filter(positive),
                    c.stroke_width(2),
                ))
                .map_err(|e| plot_err(file, e))?
                .label(name.clone())
                .legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 18, y)], c.stroke_width(2))
                });
        }
        if k == 0 {
            chart
                .configure_series_labels()
                .position(SeriesLabelPosition::LowerLeft)
                .background_style(WHITE.mix(0.8))
                .border_style(BLACK)
                .draw()
                .map_err(|e| plot_err(file, e))?;
        }
    }
    root.present().map_err(|e| plot_err(file, e))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn curve(model: &str, scale: f64) -> PathResult {
        PathResult {
            model: model.into(),
            errors: (0..50)
                .map(|i| scale * (1.0 + (i as f64 * 0.2).sin().abs()))
                .collect(),
            traces: Vec::new(),
            failures: 0,
        }
    }

    #[test]
    fn curves_orders_of_magnitude_apart_get_a_log_axis_and_a_legend_beside_the_data() {
        let dir = tempfile::tempdir().unwrap();
        let file = dir.path().join("errors.svg");
        plot_errors(
            &file,
            "t",
            &[curve("uncalibrated", 1.0), curve("fcmac", 0.005)],
        )
        .unwrap();
        let svg = std::fs::read_to_string(&file).unwrap();
        assert!(svg.contains("log scale"), "{svg}");
        assert!(svg.contains("fcmac") && svg.contains("uncalibrated"));
        assert!(!svg.contains(">-0<"));
        // Similar curves stay on a linear axis.
        plot_errors(&file, "t", &[curve("a", 1.0), curve("b", 0.5)]).unwrap();
        let svg = std::fs::read_to_string(&file).unwrap();
        assert!(!svg.contains("log scale") && svg.contains("position error (mm)"));
    }
}
