//! `rigcal identify`: conventional calibration of a recording.

use crate::identification::registration::kabsch;
use crate::identification::{analyse, candidate_order, fit, FitOptions, FitResult};
use crate::kinematics::{ErrorParams, Robot, SerialChain};
use crate::model::{ModelFile, Provenance};
use crate::recording::Recording;
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
}

pub fn run(a: Args) -> Result<()> {
    let rig = Rig::load(&a.rig)?;
    let rec = Recording::read(&a.recording, rig.chain.joints())?;
    let (chain, result) = identify(&rig, &rec)?;
    println!(
        "recording {}: {} rows, {} measurements used",
        a.recording.display(),
        rec.rows.len(),
        result.after.n
    );
    print!("{}", super::parameter_table(chain.layout(), &result, None));
    print_fit_summary(&result);
    let file = ModelFile::constant(
        &rig,
        &result,
        Provenance {
            recording: Some(a.recording.display().to_string()),
            measurements: result.after.n,
            notes: None,
        },
    );
    file.save(&a.out)?;
    println!("model written to {}", a.out.display());
    Ok(())
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

/// Identifies the parameters a recording can separate. With a free measurement frame the
/// chain's nominal frame starts at the closed-form registration of the nominal arm.
pub(crate) fn identify(rig: &Rig, rec: &Recording) -> Result<(SerialChain, FitResult)> {
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
    let ident = analyse(&chain, &poses, &candidate_order(rig));
    let result = fit(&chain, &obs, &nominal, &ident.basis, &FitOptions::default())
        .context("identification failed")?;
    Ok((chain, result))
}

/// Reads a recording for a rig, with the path in the error.
pub(crate) fn read_recording(rig: &Rig, path: &Path) -> Result<Recording> {
    Ok(Recording::read(path, rig.chain.joints())?)
}
