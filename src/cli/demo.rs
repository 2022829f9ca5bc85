//! `rigcal demo`: the whole job on simulated devices at seed 000's settings
//! ([`rigcal_paper::demo`], which says what it runs): the flags, the progress and the printing.

use super::options::{parse_seeds, InitArg, SeedList, TrainingArg};
use anyhow::{Context, Result};
use rigcal_paper::demo::{DemoEvent, DemoOptions, PathSet};
use rigcal_paper::extras::Extras;
use rigcal_paper::preset::SEED_000;
use rigcal_paper::sec7::Sec7Stage;
use rigcal_paper::seeds::{SweepEvent, SweepOptions, SweepPart};
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
    /// Accept a division's region when the upper confidence bound of its largest error, this
    /// many standard deviations above its test points' Gaussian-process fit, meets the demand
    /// (docs/seeds.md); 0: on the test points' maximum, the paper's rule [default: 1]
    #[arg(long, value_name = "Z")]
    confidence_z: Option<f64>,
    /// Fit every region's CEPs by plain least squares, the paper's, instead of rigcal's MAP
    /// estimate around its parent's CEPs (docs/seeds.md: the departure's measured effect).
    #[arg(long)]
    plain_least_squares: bool,
    /// Where every FCMAC's association cells start before training: each at its region's
    /// CEPs (rigcal's default), all at the conventional CEPs, or all at zero (the paper does
    /// not say; docs/paper-reproduction.md measures the choice).
    #[arg(long, value_enum, default_value_t = InitArg::Ceps)]
    fcmac_init: InitArg,
    /// Section 6 with Gaussian measurement noise whose mean length is this percentage of the
    /// mean uncalibrated error on the Fig. 6 path (the paper's further run: about 3); the
    /// evaluation stays against the true arm [default: no noise, the scenario's].
    #[arg(long, value_name = "PERCENT", value_parser = parse_percent)]
    noise_percent: Option<f64>,
    /// With --seeds: train a CMAC and an FCMAC on the same CEPs of each seed's Fig. 6 division
    /// (the demo's FCMAC also learns the measured positions, which a CMAC cannot) and report
    /// both along the Fig. 6 path and their CEP jumps; into extras.md.
    #[arg(long, requires = "seeds", conflicts_with = "rig")]
    equal_training: bool,
    /// With --seeds: evaluate each seed's Fig. 6 and Fig. 7 models along ten joint-space
    /// lines drawn by a fixed rule (seed 32, inside the measurable workspace; the paper's
    /// "several different paths"), or with --rig measure section 7's model along ten
    /// Cartesian lines by the rig (each a path session of its own), and report the
    /// distribution over paths × seeds; into extras.md and ten-paths.csv.
    #[arg(long, requires = "seeds")]
    ten_paths: bool,
    /// Run section 6 alone at each of these seeds (`1-20`, or `3,8,10`) and print, per claim,
    /// the pass rate, the median and the worst seed (docs/seeds.md); writes `seeds.md` and
    /// `seeds.csv` to --out (default out/seeds then).
    #[arg(long, value_name = "SEEDS", value_parser = parse_seeds)]
    seeds: Option<SeedList>,
    /// With --seeds: worker threads, one seed each at a time.
    #[arg(long, default_value_t = 2, requires = "seeds")]
    threads: usize,
    /// With --seeds: evaluate along the tuning paths (docs/seeds.md), which no reported figure
    /// uses, instead of the paper's.
    #[arg(long, requires = "seeds")]
    tuning_paths: bool,
    /// With --seeds: run section 7 (the rig experiment through `MP`, without the `MJ` pass)
    /// at each seed instead of section 6; out/seeds-rig by default.
    #[arg(long, requires = "seeds")]
    rig: bool,
}

pub fn run(a: Args) -> Result<()> {
    let mut preset = SEED_000;
    preset.accuracy_mm = a.accuracy_mm;
    preset.section7.accuracy_mm = a.rig_accuracy_mm;
    if let Some(SeedList(seeds)) = a.seeds {
        let out = if a.out == std::path::Path::new("out/demo") {
            let out = rigcal_paper::seeds::default_out();
            if a.rig {
                out.with_file_name("seeds-rig")
            } else {
                out
            }
        } else {
            a.out
        };
        let demo = DemoOptions {
            out,
            preset,
            path_points: a.path_points,
            seed: 1,
            learner_tolerance: a.learner_tolerance,
            fcmac_training: a.fcmac_training.into(),
            confidence_z: a.confidence_z,
            plain_least_squares: a.plain_least_squares,
            fcmac_init: a.fcmac_init.into(),
            noise_share: a.noise_percent.map(|p| p / 100.0),
        };
        let extras = Extras {
            equal_training: a.equal_training,
            ten_paths: a.ten_paths,
            rig: a.rig,
        };
        let part = if a.rig {
            SweepPart::Section7
        } else {
            SweepPart::Section6
        };
        return sweep(demo, seeds, a.threads, a.tuning_paths, part, extras);
    }
    let opts = DemoOptions {
        out: a.out,
        preset,
        path_points: a.path_points,
        seed: a.seed,
        learner_tolerance: a.learner_tolerance,
        fcmac_training: a.fcmac_training.into(),
        confidence_z: a.confidence_z,
        plain_least_squares: a.plain_least_squares,
        fcmac_init: a.fcmac_init.into(),
        noise_share: a.noise_percent.map(|p| p / 100.0),
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

/// `rigcal demo --seeds`: the sweep, a line per finished seed, then the table (also written to
/// `seeds.md` and `seeds.csv`).
fn sweep(
    demo: DemoOptions,
    seeds: Vec<u64>,
    threads: usize,
    tuning: bool,
    part: SweepPart,
    extras: Extras,
) -> Result<()> {
    let opts = SweepOptions {
        paths: if tuning {
            PathSet::Tuning
        } else {
            PathSet::Paper
        },
        demo,
        seeds,
        threads,
        part,
    };
    let out = opts.demo.out.clone();
    eprintln!(
        "{} at {} seeds on {} thread(s), into {}",
        match part {
            SweepPart::Section6 => "section 6",
            SweepPart::Section7 => "section 7",
        },
        opts.seeds.len(),
        opts.threads,
        out.display()
    );
    let started = std::time::Instant::now();
    let table = rigcal_paper::seeds::sweep(&opts, &|event| match event {
        SweepEvent::Finished {
            seed,
            done,
            total,
            wall_s,
        } => {
            let elapsed = started.elapsed().as_secs_f64();
            let left = elapsed / done as f64 * (total - done) as f64;
            eprintln!(
                "seed {seed} done in {wall_s:.0} s ({done}/{total}; {elapsed:.0} s so far, about {left:.0} s left)"
            );
        }
    })?;
    let text = table.text();
    print!("{text}");
    std::fs::create_dir_all(&out).with_context(|| format!("creating {}", out.display()))?;
    for (name, body) in [("seeds.md", text), ("seeds.csv", table.csv())] {
        let file = out.join(name);
        std::fs::write(&file, body).with_context(|| format!("writing {}", file.display()))?;
    }
    eprintln!("table written to {}", out.join("seeds.md").display());
    if extras != Extras::default() {
        eprintln!("the extras on every seed's models (equal training, ten paths)");
        let t = rigcal_paper::extras::measure(&opts.demo, &opts.seeds, extras)?;
        let text = t.text();
        print!("\n{text}");
        let [md, csv] = rigcal_paper::extras::files(&out);
        std::fs::write(&md, text).with_context(|| format!("writing {}", md.display()))?;
        if extras.ten_paths {
            std::fs::write(&csv, t.paths_csv())
                .with_context(|| format!("writing {}", csv.display()))?;
        }
        eprintln!("extras written to {}", md.display());
    }
    Ok(())
}

/// A percentage from 0 to 100.
fn parse_percent(s: &str) -> Result<f64, String> {
    let v: f64 = s
        .parse()
        .map_err(|_| format!("{s:?} is not a number: give a percentage such as 3"))?;
    if (0.0..=100.0).contains(&v) {
        Ok(v)
    } else {
        Err(format!("{v} is not a percentage from 0 to 100"))
    }
}
