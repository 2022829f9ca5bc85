//! Tables 6–8: the 2-DOF SCARA with random errors (Table 6): apparent and actual errors and the
//! filtering index FI of direct (Table 7) and inverse (Table 8) schemes 2 and 4. Units: mm.

use super::poses::{scara2_grid, scara2_samples};
use super::runs::{fmt_stats, nominal_errors, norms, random_vecs, run_scheme, SchemeRun};
use super::{ReproOptions, Table};
use crate::reproduce::evaluation::{filtering_index, ErrorStats};
use crate::reproduce::robots::scara2::{Scara2, Scara2Errors, Scara2Random, Scara2Real};
use rand::rngs::ChaCha8Rng;
use rand::SeedableRng;
use rigcal_model::neural::{NeuralError, Scheme};
use std::fmt::Write;

/// Tables 7–8's rows: scheme, the paper's hidden neurons, and the paper's
/// [E_ap mean, max, E_ac mean, max, FI].
const RUNS: [(Scheme, usize, [f64; 5]); 4] = [
    (Scheme::Direct2, 8, [0.21, 0.67, 0.14, 0.43, 0.86]),
    (Scheme::Direct4, 2, [0.17, 0.44, 0.05, 0.17, 0.32]),
    (Scheme::Inverse2, 7, [0.18, 0.54, 0.08, 0.28, 0.49]),
    (Scheme::Inverse4, 5, [0.19, 0.66, 0.10, 0.38, 0.62]),
];

/// Most hidden neurons the rule for neurons of Tables 7–8 tries.
pub const TABLE7_MAX_HIDDEN: usize = 10;

/// The paper's rule for Tables 7–8 ("the number of neurons was experimentally minimised in order
/// to avoid the overfitting risk while keeping good convergence on the corrupted training set"):
/// the fewest hidden neurons whose mean apparent error on the training poses comes down to their
/// mean random error `er_train`; when no count up to [`TABLE7_MAX_HIDDEN`] gets there, the count
/// that came closest.
fn fewest_neurons_reaching_noise(
    train: &dyn Fn(usize) -> Result<SchemeRun, NeuralError>,
    er_train: f64,
) -> Result<(usize, SchemeRun), NeuralError> {
    let first = train(1)?;
    let mut closest = (norms(&first.lea_ap).mean, 1, first);
    for hn in 2..=TABLE7_MAX_HIDDEN {
        if closest.0 <= er_train {
            break;
        }
        let r = train(hn)?;
        let e = norms(&r.lea_ap).mean;
        // A count that reaches the noise is also closer than every count before it.
        if e < closest.0 {
            closest = (e, hn, r);
        }
    }
    Ok((closest.1, closest.2))
}

/// Tables 6–8: random errors on the 2-DOF SCARA (Table 6's constant errors with δβ = −1.3°):
/// 36 training poses (a 6 × 6 grid of the working area), early stopping on a quarter of them, direct (Table 7) and inverse (Table 8)
/// schemes 2 and 4 with the paper's hidden-neuron counts; apparent and actual errors on the
/// validation set and FI.
pub fn table7(o: &ReproOptions) -> Result<Table, NeuralError> {
    let nominal = Scara2::default();
    let real = Scara2Real {
        nominal,
        errors: Scara2Errors::table6(),
    };
    let amp = Scara2Random::table6();
    let mut rng = ChaCha8Rng::seed_from_u64(o.seed.wrapping_add(700));
    let lea = scara2_grid(&real, Some(&amp), 6, 6, &mut rng);
    let val = scara2_samples(&real, Some(&amp), 1244 / o.reduce.max(1), &mut rng);
    let before = norms(&nominal_errors(&nominal, &val));
    let er = norms(&random_vecs(&val));
    let mut t = Table {
        title: "Tables 6–8: 2-DOF SCARA with random errors, validation set (mm)".into(),
        ..Table::default()
    };
    let mut text = String::new();
    let _ = writeln!(
        text,
        "  before calibration: E {} (paper 12.6 20.0), E_r {} (paper 0.17 0.49)   [mean max]",
        fmt_stats(before),
        fmt_stats(er)
    );
    t.values.push(("E mean".into(), before.mean, 12.6));
    t.values.push(("E_r mean".into(), er.mean, 0.17));
    let _ = writeln!(
        text,
        "  {:<10} {:>3}  {:>15} {:>15} {:>6}   {:>15} {:>15} {:>6}  {:>7}",
        "scheme",
        "HN",
        "E_ap mean max",
        "E_ac mean max",
        "FI",
        "paper E_ap",
        "paper E_ac",
        "FI",
        "train s"
    );
    let er_train = norms(&random_vecs(&lea)).mean;
    for (scheme, paper_hn, paper) in RUNS {
        let train = |hn: usize| {
            run_scheme(
                &nominal,
                &lea,
                &val,
                scheme,
                o.angular_sum,
                &o.cfg(hn, true, o.seed + 70),
            )
        };
        let at_paper = train(paper_hn)?;
        let (rule_hn, at_rule) = fewest_neurons_reaching_noise(&train, er_train)?;
        for (hn, r, which) in [
            (paper_hn, &at_paper, "paper's HN"),
            (rule_hn, &at_rule, "HN by rule"),
        ] {
            let row = Row {
                scheme,
                hn,
                which,
                paper,
            };
            row.print(r, er, &mut text, &mut t.values);
        }
    }
    t.text = text;
    t.notes = table7_notes(o);
    Ok(t)
}

/// One row of Table 7 or 8: a scheme at a hidden-neuron count, beside the paper's.
struct Row {
    scheme: Scheme,
    hn: usize,
    /// "paper's HN" or "HN by rule".
    which: &'static str,
    paper: [f64; 5],
}

impl Row {
    /// Prints the row for run `r` (E_r of the validation set `er`) and records its values.
    fn print(
        &self,
        r: &SchemeRun,
        er: ErrorStats,
        text: &mut String,
        values: &mut Vec<(String, f64, f64)>,
    ) {
        let (scheme, paper) = (self.scheme, self.paper);
        let ap = norms(&r.val_ap);
        let ac = norms(&r.val_ac);
        let fi = filtering_index(ac.mean, er.mean).unwrap_or(f64::NAN);
        let table = if scheme.is_direct() { 7 } else { 8 };
        let _ = writeln!(
            text,
            "  {:<10} {:>3}  {} {} {:>5.0}%   {:>7.2} {:>7.2} {:>7.2} {:>7.2} {:>5.0}%  {:>7.2}   (Table {table}, {})",
            scheme.name(),
            self.hn,
            fmt_stats(ap),
            fmt_stats(ac),
            fi * 100.0,
            paper[0],
            paper[1],
            paper[2],
            paper[3],
            paper[4] * 100.0,
            r.train_s,
            self.which
        );
        let suffix = if self.which == "paper's HN" {
            ""
        } else {
            " (HN by rule)"
        };
        values.push((
            format!("{} E_ap mean{suffix}", scheme.name()),
            ap.mean,
            paper[0],
        ));
        values.push((
            format!("{} E_ac mean{suffix}", scheme.name()),
            ac.mean,
            paper[2],
        ));
        values.push((format!("{} FI{suffix}", scheme.name()), fi, paper[4]));
    }
}

/// What Tables 6–8 chose where the paper is silent, and why their numbers differ.
fn table7_notes(o: &ReproOptions) -> Vec<String> {
    vec![
        "Table 6 prints δβ = −6°, an apparent typo; we use −1.3° as in Table 4 (the team's convention for this paper), so E before calibration is about 7 mm, not 12.6 mm".into(),
        format!("early stopping on 9 of the 36 training poses, patience {} epochs, best-validation weights restored", (o.epochs / 5).max(200)),
        "E_ac: against the pose of the robot with its constant errors only; E_r = ‖S_noisy − S_constant‖; FI = mean E_ac / mean E_r".into(),
        format!("HN by rule: the paper's rule for these tables, \"minimise the neurons while keeping good convergence on the corrupted training set\", read as the fewest neurons (1…{TABLE7_MAX_HIDDEN}) whose mean apparent error on the 36 training poses falls to their mean random error; the paper's counts were found on its robot, the rule finds ours"),
        "with the paper's 2 neurons our direct scheme 4 (a pose correction, a function of α and α+β) lacks capacity: on noise-free poses Levenberg–Marquardt leaves a 2-neuron scheme 4 at 0.15 mm over the working area, a 2-neuron scheme 2 at 0.025 mm".into(),
        "early stopping on 9 noisy poses often stops within a few hundred epochs, which keeps E_ac above the paper's".into(),
    ]
}
