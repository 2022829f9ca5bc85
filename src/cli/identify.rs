//! `rigcal identify`: conventional calibration of a recording.

use crate::identification::outliers::{remove_outliers, Outlier, OutlierError, OutlierSettings};
use crate::identification::registration::kabsch;
use crate::identification::{analyse, candidate_order, fit, FitOptions, FitResult};
use crate::kinematics::{ErrorParams, JointKind, ParamKind, Robot, SerialChain, TransformId};
use crate::model::{ModelFile, Provenance};
use crate::recording::{Recording, Status};
use crate::rig::{FrameMode, Rig};
use anyhow::{bail, Context, Result};
use std::path::{Path, PathBuf};

/// Arguments of `rigcal identify`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Rig file (TOML).
    #[arg(long)]
    rig: PathBuf,
    /// Recording: a directory with measurements.csv, or a CSV file.
    #[arg(long)]
    recording: PathBuf,
    /// Where to write the model (JSON).
    #[arg(long)]
    out: PathBuf,
    /// What to fit: `frames` (the free measurement frame and marker only), `offsets` (plus the
    /// joint offsets that stay identifiable after them), `full` (every identifiable parameter).
    #[arg(long, value_enum, default_value_t = Level::Full)]
    level: Level,
    /// Held-out recordings (another day's session, say): RMS and max position error of the
    /// fitted model on each.
    #[arg(long, num_args = 1..)]
    heldout: Vec<PathBuf>,
}

/// How much of the model to fit.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Level {
    /// Measurement frame and marker only.
    Frames,
    /// Frames plus joint offsets.
    Offsets,
    /// Every identifiable parameter.
    Full,
}

pub fn run(a: Args) -> Result<()> {
    let rig = Rig::load(&a.rig)?;
    let rec = read_recording(&rig, &a.recording)?;
    let (chain, result, outliers, warning) = identify_robust(&rig, &rec, a.level)?;
    println!(
        "recording {}: {} rows, {} measurements used",
        a.recording.display(),
        rec.rows.len(),
        result.after.n
    );
    print_outliers(&outliers);
    print!("{}", super::parameter_table(chain.layout(), &result, None));
    print_fit_summary(&result);
    for dir in &a.heldout {
        let held = read_recording(&rig, dir)?;
        let obs = super::observations(&held);
        if obs.is_empty() {
            bail!("held-out recording {}: no measured rows", dir.display());
        }
        // "Nominal" keeps the fitted frame and marker, so it compares kinematics, not frames.
        let mut nominal = result.params.clone();
        for (k, id) in chain.layout().ids().iter().enumerate() {
            if !matches!(id.transform, TransformId::Frame | TransformId::Marker) {
                nominal.set(k, 0.0);
            }
        }
        let before = crate::identification::ResidualStats::of(&crate::identification::errors(
            &chain, &obs, &nominal,
        ));
        let after = crate::identification::ResidualStats::of(&crate::identification::errors(
            &chain,
            &obs,
            &result.params,
        ));
        println!(
            "held-out {} ({} points): nominal kinematics RMS {:.4} mm, max {:.4} mm → fitted RMS {:.4} mm, max {:.4} mm",
            dir.display(),
            obs.len(),
            before.rms_mm,
            before.max_mm,
            after.rms_mm,
            after.max_mm
        );
    }
    let mut file = ModelFile::constant(
        &rig,
        &result,
        Provenance {
            recording: Some(a.recording.display().to_string()),
            measurements: result.after.n,
            notes: warning,
        },
    );
    file.outliers = outliers;
    file.save(&a.out)?;
    println!("model written to {}", a.out.display());
    Ok(())
}

/// Prints the outliers removed from a fit (or that there were none).
pub(crate) fn print_outliers(outliers: &[Outlier]) {
    if outliers.is_empty() {
        println!("outliers: none");
    }
    for o in outliers {
        let line = o.line.map(|l| format!(", line {l}")).unwrap_or_default();
        println!(
            "outlier removed from the fit: seq {}{line}, {:.4} mm off ({:.1} σ; residual x {:.4}, y {:.4}, z {:.4} mm)",
            o.seq, o.size_mm, o.sigmas, o.residual_mm[0], o.residual_mm[1], o.residual_mm[2]
        );
    }
}

/// A refit that failed inside the outlier search.
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub(crate) struct RefitFailed(String);

/// Identifies at a level with outliers found robustly and removed
/// ([`crate::identification::outliers`]): each removal refits the model without the row. More
/// than 5 % of the rows failing means the data or the model are bad: nothing is removed and the
/// warning is returned (and printed).
pub(crate) fn identify_robust(
    rig: &Rig,
    rec: &Recording,
    level: Level,
) -> Result<(SerialChain, FitResult, Vec<Outlier>, Option<String>)> {
    let measured: Vec<usize> = (0..rec.rows.len())
        .filter(|&k| rec.rows[k].status == Status::Ok && rec.rows[k].position.is_some())
        .collect();
    let ids: Vec<(u64, Option<u64>)> = measured
        .iter()
        .map(|&k| (rec.rows[k].seq, rec.lines.get(k).copied()))
        .collect();
    let obs = super::observations(rec);
    let mut last = None;
    let outliers = remove_outliers(&ids, &OutlierSettings::default(), |kept| {
        let mut sub = rec.clone();
        let mut keep = vec![false; measured.len()];
        for &i in kept {
            keep[i] = true;
        }
        for (i, &k) in measured.iter().enumerate() {
            if !keep[i] {
                // Kept as a row (joints, order) but not fitted.
                sub.rows[k].status = Status::Via;
            }
        }
        let (chain, result) =
            identify_at(rig, &sub, level).map_err(|e| RefitFailed(format!("{e:#}")))?;
        let res = crate::identification::errors(&chain, &obs, &result.params);
        let p = result.free.len();
        last = Some((chain, result));
        Ok::<_, RefitFailed>((res, p))
    });
    let outliers = match outliers {
        Ok((found, _)) => found,
        Err(e @ OutlierError::TooMany { .. }) => {
            // The data (or the geometric model) are bad: say so loudly and remove nothing.
            eprintln!("warning: {e}; no rows removed");
            let (chain, result) = identify_at(rig, rec, level)?;
            return Ok((chain, result, Vec::new(), Some(e.to_string())));
        }
        Err(e) => return Err(anyhow::anyhow!("outlier search: {e}")),
    };
    let (chain, result) = last.context("identification did not run")?;
    Ok((chain, result, outliers, None))
}

/// Prints κ and the residual statistics of a fit.
pub(crate) fn print_fit_summary(r: &FitResult) {
    println!(
        "κ (eq. 4): {:.1}   σ̂ per coordinate: {:.4} mm   iterations: {}",
        r.kappa, r.sigma0_mm, r.iterations
    );
    println!(
        "residual before: RMS {:.4} mm, mean {:.4} mm, max {:.4} mm",
        r.before.rms_mm, r.before.mean_mm, r.before.max_mm
    );
    println!(
        "residual after:  RMS {:.4} mm, mean {:.4} mm, max {:.4} mm  (x {:.4}, y {:.4}, z {:.4})",
        r.after.rms_mm,
        r.after.mean_mm,
        r.after.max_mm,
        r.after.axis_rms_mm[0],
        r.after.axis_rms_mm[1],
        r.after.axis_rms_mm[2]
    );
}

/// Identifies at a level. With a free measurement frame the fit starts from the closed-form
/// registration of the nominal arm, and the frame parameters are returned as absolute values
/// (the rig's nominal frame is the identity), so the model file stands alone.
pub(crate) fn identify_at(
    rig: &Rig,
    rec: &Recording,
    level: Level,
) -> Result<(SerialChain, FitResult)> {
    let obs = super::observations(rec);
    if obs.is_empty() {
        bail!("the recording has no measured rows (status ok with x_mm, y_mm, z_mm)");
    }
    let nominal = ErrorParams::zeros(rig.chain.layout());
    let chain = if rig.calibration.measurement_frame == FrameMode::Free {
        let world = rig.chain.clone();
        let model: Vec<_> = obs.iter().map(|o| world.position(&o.q, &nominal)).collect();
        let measured: Vec<_> = obs.iter().map(|o| o.p).collect();
        rig.chain.with_frame(kabsch(&model, &measured))
    } else {
        rig.chain.clone()
    };
    let poses: Vec<Vec<f64>> = obs.iter().map(|o| o.q.clone()).collect();
    let layout = chain.layout();
    let candidates: Vec<usize> = candidate_order(rig)
        .into_iter()
        .filter(|&i| {
            let id = layout.ids()[i];
            match (level, id.transform) {
                (_, TransformId::Frame | TransformId::Marker) | (Level::Full, _) => true,
                (Level::Offsets, TransformId::Link(j)) => {
                    let kind = rig.chain.joints()[j - 1].kind;
                    (kind == JointKind::Revolute && id.kind == ParamKind::Theta)
                        || (kind == JointKind::Prismatic && id.kind == ParamKind::D)
                }
                _ => false,
            }
        })
        .collect();
    if candidates.is_empty() {
        bail!("nothing to fit at level {level:?}: the rig's measurement frame and marker are fixed (set them free in [calibration] or use --level full)");
    }
    let ident = analyse(&chain, &poses, &candidates);
    let mut result = fit(&chain, &obs, &nominal, &ident.basis, &FitOptions::default())
        .context("identification failed")?;
    if rig.calibration.measurement_frame == FrameMode::Free {
        absolute_frame(&chain, &mut result);
        return Ok((rig.chain.clone(), result));
    }
    Ok((chain, result))
}

/// Reads a recording for a rig, with the path in the error.
pub(crate) fn read_recording(rig: &Rig, path: &Path) -> Result<Recording> {
    Recording::read(path, rig.chain.joints()).with_context(|| {
        format!(
            "reading the recording {} for rig `{}` ({} joints)",
            path.display(),
            rig.name,
            rig.chain.joints().len()
        )
    })
}

/// Rewrites the fitted frame parameters of a chain whose nominal frame was a start value as
/// absolute values for the identity nominal frame: F = Trans(x, y, z) · Rz(rz) · Ry(ry) · Rx(rx).
fn absolute_frame(started: &SerialChain, result: &mut FitResult) {
    let f = started.frame_pose(&result.params);
    let (roll, pitch, yaw) = f.rotation.euler_angles();
    let t = f.translation.vector;
    let layout = started.layout();
    for (i, id) in layout.ids().iter().enumerate() {
        if id.transform != TransformId::Frame {
            continue;
        }
        let v = match id.kind {
            ParamKind::X => t.x,
            ParamKind::Y => t.y,
            ParamKind::Z => t.z,
            ParamKind::Rx => roll,
            ParamKind::Ry => pitch,
            ParamKind::Rz => yaw,
            _ => continue,
        };
        result.params.set(i, v);
    }
}
