//! The calibrating commands' shared options: the command-line side of
//! [`CalibrationOptions`] and the library's enums, converted with `From`. The defaults that
//! are the paper's come from [`PAPER`] (`rigcal_paper::preset`).

use rigcal_calibration::{CalibrationOptions, NeuralOptions};
use rigcal_model::division::{Selection, Space};
use rigcal_model::learners::{FcmacInit, FcmacTraining, LearnerKind, LearnerSettings};
use rigcal_paper::preset::SEED_000 as PAPER;

/// A library enum on the command line: the same variants, with the help `--help` shows.
macro_rules! value_enum {
    ($(#[$m:meta])* $name:ident => $lib:ident { $($(#[$vm:meta])* $v:ident,)+ }) => {
        $(#[$m])*
        #[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
        pub(crate) enum $name { $($(#[$vm])* $v,)+ }

        impl From<$name> for $lib {
            fn from(v: $name) -> Self {
                match v { $($name::$v => Self::$v,)+ }
            }
        }
    };
}

/// A library options struct on the command line: a `clap::Args` struct with the fields given
/// (their flags and help), converted field by field into the library's (`..` the rest).
macro_rules! args {
    ($(#[$m:meta])* $name:ident => $lib:ident { $($(#[$fm:meta])* $f:ident: $t:ty,)+ } $(.. $rest:expr)?) => {
        $(#[$m])*
        #[derive(Debug, Clone, clap::Args)]
        pub(crate) struct $name { $($(#[$fm])* pub $f: $t,)+ }

        impl From<$name> for $lib {
            fn from(a: $name) -> Self {
                Self { $($f: a.$f.into(),)+ $(..$rest)? }
            }
        }
    };
}

pub(crate) use value_enum;

value_enum! {
    /// Which space the workspace is divided in.
    SpaceArg => Space {
        /// The major joints (q1, q2, q3 for the RV-M2).
        Joint,
        /// Spherical workspace coordinates (R, azimuth, elevation).
        Cartesian,
    }
}

value_enum! {
    /// How a region's measurement locations are chosen.
    SelectionArg => Selection {
        /// κ of eq. (4) made small by random exchanges (the paper's rule).
        Kappa,
        /// det(MᵀM) made large: greedy choice, then exchange passes.
        DOptimal,
    }
}

value_enum! {
    /// Which learner generalises the region-wise CEPs.
    LearnerArg => LearnerKind {
        /// None: compensation uses the CEPs of the region a target falls in.
        None,
        /// Albus's CMAC.
        Cmac,
        /// The fuzzy CMAC of seed 000 (default).
        Fcmac,
        /// Not a CEP learner: a neural network learns the direct kinematics' correction
        /// (seed 001); `rigcal calibrate` writes a neural model instead.
        NnDirect,
        /// Not a CEP learner: a neural network learns the inverse kinematics' correction.
        NnInverse,
    }
}

value_enum! {
    /// What the FCMAC's training reproduces.
    TrainingArg => FcmacTraining {
        /// The regions' CEPs, pattern by pattern (seed 000's appendix, (A5)).
        Ceps,
        /// The CEPs, then the measured points: conjugate gradients on the position error, stopped
        /// where a held-out fifth of the measurements is predicted best (the default).
        Positions,
    }
}

value_enum! {
    /// Where the FCMAC's association cells start before training (seed 000 does not say).
    InitArg => FcmacInit {
        /// Each cell at the CEPs of the region at its centre, an unmeasurable region's borrowed
        /// ones included (rigcal's default).
        Ceps,
        /// Every cell at the conventional calibration's CEPs.
        Conventional,
        /// Every cell at zero (Albus's usual start; cells no pattern reaches give the nominal arm).
        Zero,
    }
}

args! {
    /// The settings every calibrating command shares ([`CalibrationOptions`] less the demanded
    /// accuracy, the learner and the unmeasurable point, which are each command's own).
    CalibrationArgs => CalibrationOptions {
        /// Division space.
        #[arg(long = "division", value_name = "DIVISION", value_enum, default_value_t = SpaceArg::Joint)]
        space: SpaceArg,
        /// Most regions [default: the paper's 110 for joint, 130 for Cartesian division].
        #[arg(long)]
        max_regions: Option<usize>,
        /// Measurements per region.
        #[arg(long, default_value_t = PAPER.per_region)]
        per_region: usize,
        /// Test points per region (planning mode): the 27 points of a 3 × 3 × 3 grid over the
        /// region (corners, edge midpoints, face centres, centre), then a Halton set; fewer take
        /// the corners first.
        #[arg(long, default_value_t = 27)]
        test_points: usize,
        /// How each region's measurement locations are chosen from its candidates: `kappa` (the
        /// paper's: κ of eq. (4) lowered by random exchanges) or `d-optimal` (det of MᵀM raised by
        /// greedy choice and exchange passes). Either way a region keeps its parent's measurements
        /// that fall in it and measures only the missing ones.
        #[arg(long, value_enum, default_value_t = SelectionArg::Kappa)]
        selection: SelectionArg,
        /// Planning mode: a half keeps its parent's measurements that fall in it and measures only
        /// the missing ones (true); `--no-reuse` measures every region afresh (each region's fit
        /// uses only its own), for comparison.
        #[arg(long = "no-reuse", action = clap::ArgAction::SetFalse)]
        reuse_parent: bool,
        /// Random poses the identifiable basis (the CEPs) is chosen on.
        #[arg(long, default_value_t = PAPER.design_poses)]
        design_poses: usize,
        /// Sizes of the FCMAC and CMAC.
        #[command(flatten)]
        learner_settings: LearnerArgs,
        /// Train the learner on each region's CEPs with the part of their deviation from its
        /// parent's that the region's own measurements cannot see put back to the parent's, the
        /// predicted points moving by at most this fraction of the demanded accuracy (RMS over the
        /// region's measurements). Small regions are ill-conditioned and their least-squares CEPs
        /// wander along directions that cancel inside them but not in the learner's blend of
        /// neighbours. 0 (the paper's) trains on the CEPs as fitted; the regions' own CEPs are
        /// never changed. [default: 0.5 for an FCMAC with position training, whose measured points
        /// the position training then puts right, so the tolerance only sets what the network
        /// carries where no measurement reaches; 0, the paper's, otherwise]
        #[arg(long, value_name = "FRACTION")]
        learner_tolerance: Option<f64>,
        /// Settings of a neural learner.
        #[command(flatten)]
        neural: NeuralArgs,
        /// Seed of every random choice.
        #[arg(long, default_value_t = 1)]
        seed: u64,
    } ..Default::default()
}

args! {
    /// The learners' sizes ([`LearnerSettings`]).
    LearnerArgs => LearnerSettings {
        /// FCMAC sensors per input (the CMAC's cells too) [default: 17 on the first joint's
        /// coordinate, 11 on the others: 17,11,11 for joint, 11,17,11 for Cartesian division].
        #[arg(long = "fcmac-sensors", value_name = "A,B,C", value_parser = three_counts)]
        sensors: Option<[usize; 3]>,
        /// FCMAC sensors an input excites per dimension (the paper's c).
        #[arg(long = "fcmac-c", value_name = "A,B,C", value_parser = three_counts, default_value = "3,3,3")]
        c: [usize; 3],
        /// CMAC layers (its generalisation width, as c is the FCMAC's).
        #[arg(long, default_value_t = 3)]
        cmac_layers: usize,
        /// What the FCMAC is trained to reproduce: the regions' CEPs (the paper's (A5)), or, after
        /// that, the measured points themselves (the same network made right where the instrument
        /// measured; see `learners::positions`).
        #[arg(long = "fcmac-training", value_enum, default_value_t = TrainingArg::Positions)]
        training: TrainingArg,
        /// Where the FCMAC's association cells start before training (seed 000 does not say;
        /// docs/paper-reproduction.md measures the choice).
        #[arg(long = "fcmac-init", value_enum, default_value_t = InitArg::Ceps)]
        init: InitArg,
    }
}

args! {
    /// Settings of a neural learner ([`NeuralOptions`]).
    NeuralArgs => NeuralOptions {
        /// Neural learners: the scheme of seed 001, 2 (joint correction) or 4 (position
        /// correction). 4 is the default for arms: a joint correction computed by inverse
        /// kinematics blows up near singular poses (the stretched RV-M2).
        #[arg(long, default_value_t = 4, value_parser = clap::value_parser!(u8).range(2..=4))]
        scheme: u8,
        /// Neural learners: hidden neurons.
        #[arg(long, default_value_t = 20)]
        hidden: usize,
        /// Neural learners: most epochs of batch back-propagation.
        #[arg(long, default_value_t = 3000)]
        epochs: usize,
        /// Neural learners: learning rate η on the batch-summed gradient [default: 0.46 / number
        /// of training poses, the paper's η = 0.01 at its 46 poses].
        #[arg(long)]
        learning_rate: Option<f64>,
        /// Random poses measured on a scenario when no recording is given (the paper's 110
        /// regions × 20): by a neural learner, and by `compare` for every method.
        #[arg(long, default_value_t = 2200)]
        measurements: usize,
    }
}

/// Three values separated by commas (`17,11,11`), `what` naming them in the error.
fn three<T: std::str::FromStr>(text: &str, what: &str) -> Result<[T; 3], String> {
    let bad = || format!("`{text}`: give three {what} separated by commas");
    let v: Vec<T> = text
        .split(',')
        .map(|v| v.trim().parse().map_err(|_| bad()))
        .collect::<Result<_, _>>()?;
    v.try_into().map_err(|_| bad())
}

/// Three counts separated by commas.
fn three_counts(text: &str) -> Result<[usize; 3], String> {
    three(text, "whole numbers")
}

/// Three numbers separated by commas.
pub(crate) fn three_numbers(text: &str) -> Result<[f64; 3], String> {
    three(text, "numbers")
}

/// The seeds of `--seeds`, as one value.
#[derive(Debug, Clone)]
pub(crate) struct SeedList(pub(crate) Vec<u64>);

/// Seeds one sweep may run: a typo such as `1-20000000` is refused rather than run for a year.
const MAX_SEEDS: u64 = 10_000;

/// `A-B` (inclusive) or a comma-separated list.
pub(crate) fn parse_seeds(s: &str) -> Result<SeedList, String> {
    let bad = |e: std::num::ParseIntError| format!("{s}: {e} (give `1-20` or `3,8,10`)");
    let seeds: Vec<u64> = match s.split_once('-') {
        Some((a, b)) => {
            let (a, b): (u64, u64) = (
                a.trim().parse().map_err(bad)?,
                b.trim().parse().map_err(bad)?,
            );
            if b.saturating_sub(a) >= MAX_SEEDS {
                return Err(format!("{s}: more than {MAX_SEEDS} seeds"));
            }
            (a..=b).collect()
        }
        None => s
            .split(',')
            .map(|x| x.trim().parse().map_err(bad))
            .collect::<Result<_, _>>()?,
    };
    if seeds.is_empty() {
        return Err(format!("{s}: no seed (give `1-20` or `3,8,10`)"));
    }
    Ok(SeedList(seeds))
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;

    #[derive(clap::Parser)]
    struct Cli {
        #[command(flatten)]
        opts: CalibrationArgs,
    }

    fn parse(args: &[&str]) -> Result<CalibrationOptions, clap::Error> {
        Cli::try_parse_from(args).map(|c| CalibrationOptions::from(c.opts))
    }

    #[test]
    fn the_command_line_defaults_are_the_library_defaults() {
        assert_eq!(parse(&["rigcal"]).ok(), Some(CalibrationOptions::default()));
        let given = parse(&[
            "rigcal",
            "--division",
            "cartesian",
            "--fcmac-sensors",
            "9,7,5",
            "--fcmac-c",
            "2,2,2",
            "--max-regions",
            "40",
            "--design-poses",
            "50",
            "--scheme",
            "2",
        ])
        .expect("parses");
        assert_eq!(given.space, Space::Cartesian);
        assert_eq!(given.learner_settings.sensors, Some([9, 7, 5]));
        assert_eq!(given.learner_settings.c, [2, 2, 2]);
        assert_eq!((given.region_cap(), given.design_poses), (40, 50));
        assert_eq!(given.neural.scheme, 2);
        assert!(parse(&["rigcal", "--fcmac-c", "3,3"]).is_err());
    }
}
