//! SVG residual plots: the residual of the geometric fit (x, y, z, mm) against each moving
//! joint's angle (degrees) and against time (s).

use super::{residual_of, standard_fit, DiagnoseError};
use plotters::prelude::*;
use rigcal_core::kinematics::Robot;
use rigcal_core::recording::Recording;
use rigcal_core::rig::Rig;
use std::path::Path;

/// The residual of the geometric fit against one variable, per axis (for evidence plots).
#[derive(Debug, Clone)]
pub struct ResidualSeries {
    /// What the x axis is (`joint 2 (deg)`, `time (s)`).
    pub label: String,
    /// The joint (1-based), when it is a joint.
    pub joint: Option<usize>,
    /// x values.
    pub x: Vec<f64>,
    /// Residual (x, y, z) per point (mm).
    pub residual: Vec<[f64; 3]>,
}

/// The residual of the geometric fit against each moving joint (degrees, or mm) and time,
/// for the HTML report's evidence plots.
pub fn residual_series(rig: &Rig, rec: &Recording) -> Result<Vec<ResidualSeries>, DiagnoseError> {
    let std = standard_fit(rig, rec)?;
    let d = &std.data;
    let r = residual_of(d);
    let residual: Vec<[f64; 3]> = (0..d.obs.len())
        .map(|i| [r[3 * i], r[3 * i + 1], r[3 * i + 2]])
        .collect();
    let joints = d.chain.joints();
    let mut out: Vec<_> = d
        .moving
        .iter()
        .map(|&j| ResidualSeries {
            label: format!("joint {} ({})", j + 1, joints[j].kind.unit()),
            joint: Some(j + 1),
            x: d.obs
                .iter()
                .map(|o| joints[j].kind.to_file_units(o.q[j]))
                .collect(),
            residual: residual.clone(),
        })
        .collect();
    if let Some(t) = &d.t_s {
        out.push(ResidualSeries {
            label: "time (s)".into(),
            joint: None,
            x: t.clone(),
            residual,
        });
    }
    Ok(out)
}

/// Writes `residual_vs_q{j}.svg` per moving joint and `residual_vs_time.svg` into `dir`;
/// returns how many files were written.
pub fn write(rig: &Rig, rec: &Recording, dir: &Path) -> Result<usize, DiagnoseError> {
    let std = standard_fit(rig, rec)?;
    let d = &std.data;
    let r = residual_of(d);
    std::fs::create_dir_all(dir)
        .map_err(|e| DiagnoseError::Plot(format!("{}: {e}", dir.display())))?;
    let mut series: Vec<(String, String, Vec<f64>)> = d
        .moving
        .iter()
        .map(|&j| {
            (
                format!("residual_vs_q{}.svg", j + 1),
                format!("joint {} (deg)", j + 1),
                d.obs.iter().map(|o| o.q[j].to_degrees()).collect(),
            )
        })
        .collect();
    if let Some(t) = &d.t_s {
        series.push(("residual_vs_time.svg".into(), "time (s)".into(), t.clone()));
    }
    let lim = r.iter().fold(1e-6f64, |a, v| a.max(v.abs())) * 1.05;
    for (file, label, xs) in &series {
        let path = dir.join(file);
        let err = |e: String| DiagnoseError::Plot(format!("{}: {e}", path.display()));
        let lo = xs.iter().copied().fold(f64::MAX, f64::min);
        let hi = xs.iter().copied().fold(f64::MIN, f64::max).max(lo + 1e-9);
        let root = SVGBackend::new(&path, (900, 600)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| err(e.to_string()))?;
        let mut chart = ChartBuilder::on(&root)
            .caption(
                format!("residual of the geometric fit vs {label}"),
                ("sans-serif", 20),
            )
            .margin(10)
            .x_label_area_size(40)
            .y_label_area_size(60)
            .build_cartesian_2d(lo..hi, -lim..lim)
            .map_err(|e| err(e.to_string()))?;
        chart
            .configure_mesh()
            .x_desc(label.as_str())
            .y_desc("residual (mm)")
            .draw()
            .map_err(|e| err(e.to_string()))?;
        for (a, colour) in [(0usize, RED), (1, GREEN), (2, BLUE)] {
            chart
                .draw_series(
                    xs.iter()
                        .enumerate()
                        .map(|(i, x)| Circle::new((*x, r[3 * i + a]), 2, colour.filled())),
                )
                .map_err(|e| err(e.to_string()))?
                .label(super::AXES[a])
                .legend(move |(x, y)| Circle::new((x, y), 3, colour.filled()));
        }
        chart
            .configure_series_labels()
            .border_style(BLACK)
            .draw()
            .map_err(|e| err(e.to_string()))?;
        root.present().map_err(|e| err(e.to_string()))?;
    }
    Ok(series.len())
}
