//! Stage 2b, what is left: the structure no library candidate explains. Forward selection
//! ([`super::select`]) already took the shapes it could locate; this stage collects them, tests
//! what is left after them (more shapes than [`MAX_SHAPES`], and, with pure error, the final lack
//! of fit), and keeps only what is *sizeable* — at least [`SHAPE_MIN_SIZE`] of the noise floor
//! by a debiased estimate — so that a large effect whose residual after naming is at the floor is
//! never flagged for a mismatch a test over thousands of degrees of freedom finds significant.
//! Anything left makes the report say `unexplained` and where.
//!
//! Units: stacked residuals in mm (3 rows per measurement).

use super::linalg::{hcat, orth_basis, partial_f_ln, visible_basis};
use super::noise::lack_of_fit;
use super::screen::{Screen, ALPHA_PART};
use super::select::{size_ratio, Selection, Shapes, MAX_SHAPES, SHAPE_MIN_SIZE};
use super::Standard;
use nalgebra::DVector;

/// What the named effects leave.
#[derive(Debug, Clone)]
pub struct Leftover {
    /// What explains the rest (a located shape, structure beyond the shapes, or the lack of
    /// fit), with its p-value; empty when nothing does.
    pub unexplained_by: Vec<(String, f64)>,
    /// The residual after geometry, nuisance and the named effects, unweighted (mm): the
    /// structure the shapes describe.
    pub residual_raw: DVector<f64>,
    /// The residual after the shapes too, unweighted (mm).
    pub final_residual_raw: DVector<f64>,
    /// The lack of fit of the final model against pure error, when it is sizeable and
    /// significant: (p-value, size ÷ floor).
    pub lack_of_fit: Option<(f64, f64)>,
}

impl Leftover {
    /// A significant, sizeable structured residual remains that no candidate explains.
    pub fn unexplained(&self) -> bool {
        !self.unexplained_by.is_empty()
    }
}

/// Collects the chosen shapes and tests what the final model of `sel` leaves: further shape
/// bases when [`MAX_SHAPES`] were taken, and the repeatability of the reference poses.
pub fn test_leftover(
    std: &Standard,
    screen: &Screen,
    sel: &Selection,
    shapes: &Shapes,
) -> Leftover {
    let nrows = screen.rows();
    let m = nrows / 3;
    let dof_final = nrows.saturating_sub(sel.basis.ncols());
    let mut unexplained_by: Vec<(String, f64)> =
        sel.shapes.iter().map(|c| (c.spec.label(), c.p)).collect();
    if sel.shapes.len() >= MAX_SHAPES {
        let nb = shapes.testable() as f64;
        for (k, x) in shapes.weighted.iter().enumerate() {
            let Some(x) = x else { continue };
            if sel.shapes.iter().any(|c| c.shape == k) {
                continue;
            }
            let Some((u, _)) = visible_basis(&sel.basis, x) else {
                continue;
            };
            let (p, _, dss) = partial_f_ln(&u, &sel.residual, dof_final);
            let s2 = screen.noise_var().unwrap_or_else(|| {
                (sel.residual.norm_squared() - dss).max(0.0)
                    / dof_final.saturating_sub(u.ncols()).max(1) as f64
            });
            if p < ALPHA_PART / nb && size_ratio(dss, u.ncols(), s2, m) >= SHAPE_MIN_SIZE {
                unexplained_by.push((format!("more structure: {}", shapes.specs[k].label()), p));
                break;
            }
        }
    }
    let raw = |with_shapes: bool| {
        let mut cols = vec![screen.model.clone()];
        cols.extend(sel.chosen.iter().map(|c| c.x.clone()));
        if with_shapes {
            cols.extend(sel.shapes.iter().map(|c| c.x.clone()));
        }
        let q = orth_basis(&hcat(&cols, nrows), 1e-9);
        &std.residual - &q * (q.transpose() * &std.residual)
    };
    let residual_raw = raw(false);
    let final_residual_raw = if sel.shapes.is_empty() {
        residual_raw.clone()
    } else {
        raw(true)
    };
    let lack = final_lack_of_fit(screen, &final_residual_raw, dof_final);
    if let (Some((p, _)), true) = (lack, unexplained_by.is_empty()) {
        unexplained_by.push((
            "structure beyond the repeatability of the reference poses".into(),
            p,
        ));
    }
    Leftover {
        unexplained_by,
        residual_raw,
        final_residual_raw,
        lack_of_fit: lack,
    }
}

/// The final lack-of-fit test against pure error, when it is significant at [`ALPHA_PART`] and
/// sizeable: (p-value, size ÷ floor). The lack-of-fit sum of squares holds dof_lof·σ² of noise
/// and the structure, so its debiased size compares with the floor like a shape's.
fn final_lack_of_fit(screen: &Screen, r: &DVector<f64>, dof: usize) -> Option<(f64, f64)> {
    if !screen.use_pure_error {
        return None;
    }
    let pe = &screen.pure_error;
    let rss = r.norm_squared();
    let p = lack_of_fit(pe, rss, dof, screen.extra_var)?;
    let s2 = pe.sigma().powi(2) + screen.extra_var;
    let dof_lof = dof.saturating_sub(pe.dof);
    let size = size_ratio((rss - pe.ss).max(0.0), dof_lof, s2, r.len() / 3);
    (p < ALPHA_PART && size >= SHAPE_MIN_SIZE).then_some((p, size))
}
