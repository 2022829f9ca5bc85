//! Outliers: measurements no model of the arm explains (a marker seen through a reflection, a
//! touch on dirt), found robustly and removed from the fit — each named with its row and size,
//! never silently.
//!
//! Method (one measurement = one 3-D residual r_i = measured − modelled, mm):
//! 1. fit on the rows kept so far;
//! 2. robust scale: σ_MAD = 1.4826 · median |r − median r| over every coordinate of the kept
//!    rows; rows with ‖r_i‖² / σ_MAD² above the χ²(3) quantile at 1 − α/m (Bonferroni over the
//!    m kept rows) are *suspects*;
//! 3. the worst suspect is tested against the variance of the rows that are not suspects
//!    (s² = their RSS / (3·m_clean − p), p fitted parameters): F = ‖r_i‖² / (3 s²) against the
//!    F(3, 3·m_clean − p) tail, again at α/m. This calibrates the test on clean data (the MAD
//!    alone is too noisy on 50 postures) while gross errors cannot inflate the scale;
//! 4. a row that fails is removed, the model refitted, and the search repeats until no row
//!    fails. Removing one at a time keeps a large outlier from hiding a smaller one.
//!
//! More than [`OutlierSettings::max_fraction`] of the rows failing means the data (or the model)
//! are bad, not a few rows: that is an error, never a silent cut — unless every row found past
//! that share is *gross beyond doubt*: against the fit without it, its ‖r_i‖² / σ_MAD² (σ_MAD
//! of the rows kept then, a scale half the rows can be bad without moving) exceeds the χ²(3)
//! quantile at 1 − α_gross/m, α_gross = [`OutlierSettings::gross_alpha`] = 1e-6 family-wise.
//! Gaussian rows cross that gate once in a million recordings, so such a row is not a tail of
//! the noise nor of a structure the model lacks (which raises σ_MAD with it); up to
//! [`OutlierSettings::gross_max_fraction`] = 20 % of the rows may go that way, each named as
//! every removed row is. Why this matters: three bad rows of 30 are 10 %, and left in they
//! raise the residual-variance floor five-fold and hide every effect at the floor. The first
//! row past the share that is only a suspect ends the search with the error, as before.
//!
//! Leverage is ignored: a row's residual variance is at most σ², so the test is conservative
//! for rows the fit leans on.
//!
//! The caller decides what "the model" is: `rigcal identify` refits the kinematics, `rigcal
//! diagnose` refits the kinematics with the effects it has named (diagnose first, then judge
//! outliers: a row a diagnosed effect explains is never one).

use nalgebra::Vector3;
use rigcal_core::stats::{chi2_3_isf, f_sf, mad_sigma};
use serde::{Deserialize, Serialize};

/// Below this robust σ (mm) the residuals are rounding, not noise (a noise-free simulation):
/// nothing is judged.
const NUMERICAL_FLOOR_MM: f64 = 1e-6;

/// Settings of the outlier search.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OutlierSettings {
    /// Family-wise false-flag rate over the rows (Bonferroni).
    pub alpha: f64,
    /// Largest fraction of rows that may be removed before the data are declared bad.
    pub max_fraction: f64,
    /// Family-wise rate at which a Gaussian row would be judged gross beyond doubt (see the
    /// module documentation).
    pub gross_alpha: f64,
    /// Largest fraction of rows that may be removed when every row past `max_fraction` is
    /// gross beyond doubt.
    pub gross_max_fraction: f64,
}

impl Default for OutlierSettings {
    fn default() -> Self {
        Self {
            alpha: 0.01,
            max_fraction: 0.05,
            gross_alpha: 1e-6,
            gross_max_fraction: 0.2,
        }
    }
}

/// One removed measurement.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Outlier {
    /// Index among the fitted measurements (0-based, before removal).
    pub index: usize,
    /// The row's `seq`.
    pub seq: u64,
    /// The row's line in the CSV file (1-based, header = line 1), when read from a file.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub line: Option<u64>,
    /// Residual (measured − modelled) against the model fitted without it (mm).
    pub residual_mm: [f64; 3],
    /// Its length (mm).
    pub size_mm: f64,
    /// Size in units of the clean rows' σ per coordinate.
    pub sigmas: f64,
    /// p-value of its test (before Bonferroni).
    pub p_value: f64,
}

/// Why the outlier search failed.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum OutlierError<E: std::error::Error + 'static> {
    /// Too many rows fail: the data or the model are bad.
    #[error("{found} of {rows} measurements are outliers (more than {:.0} %): the recording or the model is bad, not a few rows (worst: seq {worst_seq}, {worst_mm:.3} mm)", 100.0 * max_fraction)]
    TooMany {
        /// Rows failing so far.
        found: usize,
        /// Rows in all.
        rows: usize,
        /// The cap.
        max_fraction: f64,
        /// The worst row's seq.
        worst_seq: u64,
        /// Its size (mm).
        worst_mm: f64,
    },
    /// The refit failed.
    #[error(transparent)]
    Fit(E),
}

/// Finds and removes outliers. `refit(kept)` fits the model on the rows `kept` (indices into
/// 0..n, increasing) and returns the residual of *every* row (removed ones predicted by the fit
/// without them) and the number of parameters fitted. `ids[i]` = (seq, file line) of row i.
/// Returns the removed rows, in the order found, and the kept indices.
pub fn remove_outliers<E, F>(
    ids: &[(u64, Option<u64>)],
    settings: &OutlierSettings,
    mut refit: F,
) -> Result<(Vec<Outlier>, Vec<usize>), OutlierError<E>>
where
    E: std::error::Error + 'static,
    F: FnMut(&[usize]) -> Result<(Vec<Vector3<f64>>, usize), E>,
{
    let n = ids.len();
    let mut kept: Vec<usize> = (0..n).collect();
    let mut found: Vec<Outlier> = Vec::new();
    let too_many = |found: &[Outlier], max_fraction: f64| OutlierError::TooMany {
        found: found.len(),
        rows: n,
        max_fraction,
        worst_seq: found[0].seq,
        worst_mm: found[0].size_mm,
    };
    // A row found past `max_fraction`, judged gross or not once refitted without it.
    let mut past_share = false;
    loop {
        let (res, p) = refit(&kept).map_err(OutlierError::Fit)?;
        // Rows removed earlier: their size against the latest fit.
        for o in &mut found {
            let r = res[o.index];
            o.residual_mm = [r.x, r.y, r.z];
            o.size_mm = r.norm();
        }
        let m = kept.len();
        let kept_res: Vec<Vector3<f64>> = kept.iter().map(|&i| res[i]).collect();
        let s_mad = mad_sigma(&kept_res);
        if past_share {
            let last = found.last().expect("a row was found");
            if !gross_beyond_doubt(last.size_mm, s_mad, m, settings.gross_alpha) {
                return Err(too_many(&found, settings.max_fraction));
            }
        }
        if m < 4 || s_mad <= NUMERICAL_FLOOR_MM {
            return Ok((found, kept));
        }
        let bonf = settings.alpha / m as f64;
        let gate = chi2_3_isf(bonf) * s_mad * s_mad;
        let suspect: Vec<bool> = kept_res.iter().map(|r| r.norm_squared() > gate).collect();
        let Some(worst) = (0..m).filter(|&k| suspect[k]).max_by(|&a, &b| {
            kept_res[a]
                .norm_squared()
                .total_cmp(&kept_res[b].norm_squared())
        }) else {
            return Ok((found, kept));
        };
        let clean: Vec<usize> = (0..m).filter(|&k| !suspect[k]).collect();
        let dof = (3 * clean.len()).saturating_sub(p);
        if dof < 3 {
            return Ok((found, kept));
        }
        let s2 = clean
            .iter()
            .map(|&k| kept_res[k].norm_squared())
            .sum::<f64>()
            / dof as f64;
        let f = kept_res[worst].norm_squared() / (3.0 * s2.max(1e-300));
        let pval = f_sf(f, 3.0, dof as f64);
        if pval >= bonf {
            return Ok((found, kept));
        }
        let i = kept[worst];
        let r = res[i];
        found.push(Outlier {
            index: i,
            seq: ids[i].0,
            line: ids[i].1,
            residual_mm: [r.x, r.y, r.z],
            size_mm: r.norm(),
            sigmas: r.norm() / s2.sqrt(),
            p_value: pval,
        });
        kept.remove(worst);
        if found.len() as f64 > settings.gross_max_fraction.max(settings.max_fraction) * n as f64 {
            return Err(too_many(&found, settings.gross_max_fraction));
        }
        past_share = found.len() as f64 > settings.max_fraction * n as f64;
    }
}

/// True when a row of size `size_mm` (against the fit without it) is beyond the χ²(3) gate at
/// 1 − `alpha`/`m` in units of the robust σ `s_mad` (mm per coordinate) of the `m` rows kept.
fn gross_beyond_doubt(size_mm: f64, s_mad: f64, m: usize, alpha: f64) -> bool {
    m > 0 && size_mm * size_mm > chi2_3_isf(alpha / m as f64) * s_mad * s_mad
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_mean_model_finds_the_planted_rows() {
        // Model: a constant 3-vector (3 parameters); 60 rows of deterministic ±0.1 "noise",
        // rows 7 and 40 off by 3 mm.
        let mut data: Vec<Vector3<f64>> = (0..60)
            .map(|i| {
                let s = |k: usize| (((i * 7 + k * 13) % 11) as f64 - 5.0) / 50.0;
                Vector3::new(s(0), s(1), s(2))
            })
            .collect();
        data[7] += Vector3::new(3.0, 0.0, 0.0);
        data[40] += Vector3::new(0.0, -2.0, 2.0);
        let ids: Vec<(u64, Option<u64>)> = (0..60).map(|i| (i as u64 + 1, None)).collect();
        let (found, kept) = remove_outliers(&ids, &OutlierSettings::default(), |kept| {
            let mean: Vector3<f64> =
                kept.iter().map(|&i| data[i]).sum::<Vector3<f64>>() / kept.len() as f64;
            Ok::<_, std::io::Error>((data.iter().map(|d| d - mean).collect(), 3))
        })
        .expect("search");
        let mut seqs: Vec<u64> = found.iter().map(|o| o.seq).collect();
        seqs.sort_unstable();
        assert_eq!(seqs, vec![8, 41]);
        assert_eq!(kept.len(), 58);
    }

    /// 30 rows of deterministic ±0.1 mm "noise" about a constant.
    fn thirty_rows() -> Vec<Vector3<f64>> {
        (0..30)
            .map(|i| {
                let s = |k: usize| (((i * 7 + k * 13) % 11) as f64 - 5.0) / 50.0;
                Vector3::new(s(0), s(1), s(2))
            })
            .collect()
    }

    /// The search on `data` with the model "a constant" (3 parameters) refitted on the rows kept.
    fn search_about_the_mean(
        data: &[Vector3<f64>],
    ) -> Result<(Vec<Outlier>, Vec<usize>), OutlierError<std::io::Error>> {
        let ids: Vec<(u64, Option<u64>)> = (0..data.len()).map(|i| (i as u64 + 1, None)).collect();
        remove_outliers(&ids, &OutlierSettings::default(), |kept| {
            let mean: Vector3<f64> =
                kept.iter().map(|&i| data[i]).sum::<Vector3<f64>>() / kept.len() as f64;
            Ok::<_, std::io::Error>((data.iter().map(|d| d - mean).collect(), 3))
        })
    }

    /// [`thirty_rows`] with `off` added to rows 3, 14 and 25: three rows of 30 are 10 %,
    /// twice the suspect share.
    fn three_of_thirty(
        off: f64,
    ) -> Result<(Vec<Outlier>, Vec<usize>), OutlierError<std::io::Error>> {
        let mut data = thirty_rows();
        for i in [3, 14, 25] {
            data[i] += Vector3::new(off, -off, off) / 3f64.sqrt();
        }
        search_about_the_mean(&data)
    }

    #[test]
    fn gross_rows_past_the_share_are_removed_and_named() {
        // 3 mm on a noise of σ ≈ 0.065 mm per coordinate: ~46 σ, far past the gate (~6 σ).
        let (found, kept) = three_of_thirty(3.0).expect("gross rows are removed");
        let mut seqs: Vec<u64> = found.iter().map(|o| o.seq).collect();
        seqs.sort_unstable();
        assert_eq!(seqs, vec![4, 15, 26]);
        assert_eq!(kept.len(), 27);
        assert!(found.iter().all(|o| (o.size_mm - 3.0).abs() < 0.2));
    }

    #[test]
    fn suspects_past_the_share_are_still_refused() {
        // 0.4 mm on the clean rows' σ ≈ 0.058 mm per coordinate: past the suspect test at
        // α = 0.01 but, with the other two raising σ_MAD, within the gross gate (√χ²₃ at
        // 1 − 1e-6/m ≈ 6.1 σ_MAD): the second row of 30 is past 5 % and not beyond doubt.
        // (At 0.45 mm and above the rows are gross and removed; at 0.3 mm none is flagged.)
        let err = three_of_thirty(0.4).expect_err("only suspects: the data are declared bad");
        assert!(
            matches!(err, OutlierError::TooMany { rows: 30, .. }),
            "{err}"
        );
    }

    #[test]
    fn more_than_a_fifth_gross_is_refused() {
        // 7 of 30 rows (23 %) 3 mm off along ±x, ±y, ±z: gross, but more than a fifth.
        let mut data = thirty_rows();
        for i in 0..7 {
            let mut off = Vector3::zeros();
            off[i % 3] = if i % 2 == 0 { 3.0 } else { -3.0 } + 0.1 * i as f64;
            data[4 * i + 1] += off;
        }
        let err = search_about_the_mean(&data).expect_err("more than a fifth");
        assert!(err.to_string().contains("more than 20 %"), "{err}");
    }
}
