//! Tables 10–12: the Stewart platform before calibration (Table 10) and after inverse
//! calibration with schemes 2 (Table 11) and 4 (Table 12). Positions in mm, orientations in mrad.

use super::poses::stewart_samples;
use super::runs::{fmt_stats, nominal_errors, random_label, random_vecs, run_scheme};
use super::{ReproOptions, Table};
use crate::reproduce::evaluation::{filtering_index, ErrorStats};
use crate::reproduce::robots::stewart::{Stewart, StewartErrors};
use rand::rngs::ChaCha8Rng;
use rand::SeedableRng;
use rigcal_model::neural::{AngularSum, NeuralError, Sample, Scheme};
use std::fmt::Write;

// Paper validation rows: [xyz ap ave, max, ang ap ave, max, xyz ac ave, max, ang ac ave, max]
// for scheme 2 (Table 11) and 4 (Table 12), per (const, random) in order (c, r), (c, r/2),
// (c, 0), (c/2, r), ...; Table 10: [xyz ave, max, ang ave, max] before calibration.
const P11: [[f64; 8]; 6] = [
    [0.133, 1.03, 0.327, 3.40, 0.123, 0.924, 0.304, 3.01],
    [0.112, 1.49, 0.282, 5.15, 0.111, 1.55, 0.280, 5.32],
    [0.087, 0.737, 0.225, 2.47, 0.087, 0.737, 0.225, 2.47],
    [0.096, 0.384, 0.198, 1.19, 0.083, 0.046, 0.173, 1.50],
    [0.045, 0.258, 0.107, 0.755, 0.040, 0.246, 0.097, 0.689],
    [0.032, 0.115, 0.086, 0.465, 0.032, 0.115, 0.086, 0.465],
];
const P12: [[f64; 8]; 6] = [
    [0.115, 0.659, 0.287, 2.01, 0.103, 0.600, 0.264, 1.62],
    [0.068, 0.648, 0.161, 2.24, 0.064, 0.559, 0.153, 1.94],
    [0.081, 0.832, 0.183, 2.41, 0.081, 0.832, 0.183, 2.41],
    [0.073, 0.259, 0.143, 0.750, 0.061, 0.160, 0.113, 0.505],
    [0.071, 0.213, 0.160, 1.28, 0.061, 0.383, 0.149, 1.18],
    [0.041, 0.303, 0.095, 1.05, 0.041, 0.303, 0.095, 1.05],
];
const P10: [[f64; 4]; 6] = [
    [5.99, 28.8, 9.62, 26.0],
    [6.47, 50.0, 9.93, 59.9],
    [6.48, 50.1, 9.96, 60.1],
    [2.93, 9.91, 4.70, 10.5],
    [3.10, 25.3, 4.86, 24.7],
    [2.93, 9.76, 4.70, 10.1],
];

/// Tables 10–12: the Stewart platform before calibration and after inverse calibration with
/// schemes 2 and 4: 50 learning and 100 validation poses, constant errors δL_c or δL_c/2 with
/// random errors δL_r, δL_r/2 or none; E_xyz (mm) and E_ang (mrad).
pub fn table11(o: &ReproOptions, hidden: usize) -> Result<Table, NeuralError> {
    let nominal = Stewart::nominal();
    let mut t = Table {
        title:
            "Tables 10–12: Stewart platform, inverse schemes 2 and 4, validation set (mean / max)"
                .into(),
        ..Table::default()
    };
    let mut text = String::new();
    let _ = writeln!(
        text,
        "  {:<16} {:<8} {:>15} {:>15} {:>15} {:>15} {:>6} {:>6}   paper: {:>11} {:>11} {:>11}",
        "errors",
        "scheme",
        "xyz ap (mm)",
        "ang ap (mrad)",
        "xyz ac (mm)",
        "ang ac (mrad)",
        "FIxyz",
        "FIang",
        "xyz ap",
        "xyz ac",
        "ang ac"
    );
    let mut k = 0;
    for (ci, cscale) in [(0, 1.0), (1, 0.5)] {
        let mut rng = ChaCha8Rng::seed_from_u64(o.seed.wrapping_add(1100 + ci));
        let constant = StewartErrors::table9_constant()
            .scaled(cscale)
            .draw(&mut rng);
        let real = nominal.perturbed(&constant);
        for rscale in [1.0, 0.5, 0.0] {
            let random = StewartErrors::table9_random().scaled(rscale);
            let lea = stewart_samples(&real, &random, 50, &mut rng)?;
            let val = stewart_samples(&real, &random, 100, &mut rng)?;
            let label = format!(
                "{} {}",
                if ci == 0 { "δLc" } else { "δLc/2" },
                random_label(rscale)
            );
            let block = Block {
                label,
                k,
                early: rscale > 0.0,
                lea,
                val,
            };
            block.before_row(&nominal, &mut text);
            block.scheme_rows(o, hidden, &nominal, &mut text, &mut t.values)?;
            k += 1;
        }
    }
    t.text = text;
    t.notes = table11_notes(hidden);
    Ok(t)
}

/// One pair of rows' setting: constant and random errors, and the poses drawn with them.
struct Block {
    /// "δLc δLr", "δLc/2 δLr=0", …
    label: String,
    /// Row index into the paper's tables.
    k: usize,
    /// Early stopping (when there are random errors).
    early: bool,
    lea: Vec<Sample>,
    val: Vec<Sample>,
}

impl Block {
    /// Table 10's row: the nominal platform's errors on the validation poses.
    fn before_row(&self, nominal: &Stewart, text: &mut String) {
        let before = nominal_errors(nominal, &self.val);
        let bx = ErrorStats::of(&before, 0..3, 1.0);
        let ba = ErrorStats::of(&before, 3..6, 1e3);
        let p = P10[self.k];
        let _ = writeln!(
            text,
            "  {:<16} {:<8} {} {} (before calibration; paper {:.2} {:.1} / {:.2} {:.1})",
            self.label,
            "none",
            fmt_stats(bx),
            fmt_stats(ba),
            p[0],
            p[1],
            p[2],
            p[3]
        );
    }

    /// Tables 11's and 12's rows: inverse schemes 2 and 4 trained on the learning poses.
    fn scheme_rows(
        &self,
        o: &ReproOptions,
        hidden: usize,
        nominal: &Stewart,
        text: &mut String,
        values: &mut Vec<(String, f64, f64)>,
    ) -> Result<(), NeuralError> {
        let (k, label) = (self.k, &self.label);
        let rv = random_vecs(&self.val);
        let erx = ErrorStats::of(&rv, 0..3, 1.0);
        let era = ErrorStats::of(&rv, 3..6, 1e3);
        for (scheme, paper) in [(Scheme::Inverse2, P11[k]), (Scheme::Inverse4, P12[k])] {
            let r = run_scheme(
                nominal,
                &self.lea,
                &self.val,
                scheme,
                AngularSum::Plain,
                &o.cfg(hidden, self.early, o.seed + 110 + k as u64),
            )?;
            let apx = ErrorStats::of(&r.val_ap, 0..3, 1.0);
            let apa = ErrorStats::of(&r.val_ap, 3..6, 1e3);
            let acx = ErrorStats::of(&r.val_ac, 0..3, 1.0);
            let aca = ErrorStats::of(&r.val_ac, 3..6, 1e3);
            let fx = filtering_index(acx.mean, erx.mean);
            let fa = filtering_index(aca.mean, era.mean);
            let pct = |f: Option<f64>| f.map_or("-".to_string(), |v| format!("{:.0}%", v * 100.0));
            let _ = writeln!(
                text,
                "  {:<16} {:<8} {} {} {} {} {:>6} {:>6}   paper: {:>5.3} {:>5.3} {:>5.3} {:>5.3} {:>5.3} {:>5.3}",
                label,
                scheme.name(),
                fmt_stats(apx),
                fmt_stats(apa),
                fmt_stats(acx),
                fmt_stats(aca),
                pct(fx),
                pct(fa),
                paper[0],
                paper[1],
                paper[4],
                paper[5],
                paper[6],
                paper[7]
            );
            values.push((
                format!("{label} {} xyz ac mean", scheme.name()),
                acx.mean,
                paper[4],
            ));
            values.push((
                format!("{label} {} ang ac mean", scheme.name()),
                aca.mean,
                paper[6],
            ));
        }
        Ok(())
    }
}

/// What Tables 10–12 chose where the paper is silent.
fn table11_notes(hidden: usize) -> Vec<String> {
    vec![
        "workspace (lost from the text): x, y ±100 mm, z 1000..1200 mm, ψ θ φ ±5°; 6-3 platform, legs 2k, 2k+1 on platform vertex k".into(),
        format!("{hidden} hidden neurons (the paper does not say), leg lengths standardised at the input, plain angular sum on S (angles stay within ±6°, far from θ = ±90°)"),
        "constant errors drawn uniformly within Table 9's ranges (one draw per row pair); random errors per pose".into(),
        "Table 11's FI rows are garbled in the text we have; compare the E_ac columns".into(),
    ]
}
