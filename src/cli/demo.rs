//! `rigcal demo`: the whole job on simulated devices at seed 000's settings
//! ([`rigcal_paper::demo`], which says what it runs): the flags, the progress and the printing.

use super::options::TrainingArg;
use anyhow::Result;
use rigcal_paper::demo::{DemoEvent, DemoOptions};
use rigcal_paper::preset::SEED_000;
use rigcal_paper::sec7::Sec7Stage;
use std::path::PathBuf;

/// Arguments of `rigcal demo`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Directory for the recordings, models, reports and plots (the demo's own subdirectories
    /// there are replaced on a new run).
    #[arg(long, default_value = "out/demo")]
    out: PathBuf,
    /// Accuracy the section 7 division demands on the real rig (mm; the paper's 0.5).
    #[arg(long, default_value_t = SEED_000.section7.accuracy_mm)]
    rig_accuracy_mm: f64,
    /// Points of the section 7 path, measured once per method and command path.
    #[arg(long, default_value_t = 101)]
    path_points: usize,
    /// Accuracy the variable D-H model must reach in every region (mm; the paper's 0.1).
    #[arg(long, default_value_t = SEED_000.accuracy_mm)]
    accuracy_mm: f64,
    /// Seed of the divisions, the plans and the learner.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Train every FCMAC and CMAC on the regions' CEPs with what each region's measurements
    /// cannot see put back to its parent's, moving predicted points by at most this fraction
    /// of the demanded accuracy (`rigcal calibrate --learner-tolerance`; 0: the paper's)
    /// [default: 0.5 with position training, 0 with `--fcmac-training ceps`].
    #[arg(long, value_name = "FRACTION")]
    learner_tolerance: Option<f64>,
    /// What every FCMAC is trained to reproduce (`rigcal calibrate --fcmac-training`).
    #[arg(long, value_enum, default_value_t = TrainingArg::Positions)]
    fcmac_training: TrainingArg,
}

pub fn run(a: Args) -> Result<()> {
    let mut preset = SEED_000;
    preset.accuracy_mm = a.accuracy_mm;
    preset.section7.accuracy_mm = a.rig_accuracy_mm;
    let opts = DemoOptions {
        out: a.out,
        preset,
        path_points: a.path_points,
        seed: a.seed,
        learner_tolerance: a.learner_tolerance,
        fcmac_training: a.fcmac_training.into(),
    };
    rigcal_paper::demo::run(&opts, &mut |event| match event {
        DemoEvent::Text(text) => print!("{text}"),
        DemoEvent::Sec7(Sec7Stage::Division(n, cap)) if n % 10 == 0 => {
            eprintln!("dividing: {n} regions (cap {cap})")
        }
        DemoEvent::Sec7(Sec7Stage::Division(..)) => {}
        DemoEvent::Sec7(Sec7Stage::Path(cp)) => {
            eprintln!("measuring the path through the {cp} command path")
        }
    })?;
    Ok(())
}
