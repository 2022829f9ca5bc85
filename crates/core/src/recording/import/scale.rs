//! Whether a recording's scale fits its rig: metres read as millimetres, radians read as degrees
//! (or the other way round), orientations in the wrong angle unit, or a marker kilometres away
//! are refused with the likely cause, before anything is fitted to them.
//!
//! The measurement frame and the marker may be unknown, so absolute positions say little; what
//! does not depend on them is the spread of the measured points about their centre (a rigid
//! frame does not change it, a marker near the last link changes it little) and the angle
//! between the measured orientations of two rows. Both are compared with what the rig's nominal
//! kinematics give at the same joint values. A ratio far from 1 is then explained, where one
//! can be, by the unit change that brings it back to 1.

use super::{AngleUnit, LengthUnit};
use crate::kinematics::{ErrorParams, JointKind, Robot};
use crate::recording::Recording;
use crate::stats::median;
use nalgebra::{UnitQuaternion, Vector3};

/// Spread ratios (measured / nominal) accepted without question.
const ACCEPTED: std::ops::RangeInclusive<f64> = (1.0 / 3.0)..=3.0;
/// A ratio counts as explained by a unit change when it comes within this range after it.
const EXPLAINED: std::ops::RangeInclusive<f64> = (1.0 / 1.6)..=1.6;
/// No instrument rigcal reads measures farther than this (mm): 200 m.
const FARTHEST_MM: f64 = 200_000.0;
/// Rows looked at (evenly spread over the recording): enough for a spread, cheap for 10⁴ rows.
const SAMPLE_ROWS: usize = 2000;

/// One measured row as the check sees it: joint values, position, orientation.
type Row<'a> = (&'a [f64], Vector3<f64>, Option<UnitQuaternion<f64>>);

/// The units a recording was read in, for the hint (None: not known, as for a recording read
/// back from its own files).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct DeclaredUnits {
    /// Lengths.
    pub length: LengthUnit,
    /// Joint angles.
    pub angle: AngleUnit,
    /// Orientation angles.
    pub orientation: AngleUnit,
}

/// What the scale check found wrong.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{what}: {cause}")]
pub struct ScaleMismatch {
    /// The figures that do not fit.
    pub what: String,
    /// The likely cause and what to do.
    pub cause: String,
}

/// Checks that the recording's positions (and orientations, when it has them) are on the scale
/// of `robot`'s nominal kinematics. Recordings too small to tell (fewer than 4 measured rows, or
/// joint values that hardly move the marker) pass.
pub fn check_scale(
    rec: &Recording,
    robot: &dyn Robot,
    declared: Option<DeclaredUnits>,
) -> Result<(), ScaleMismatch> {
    let rows: Vec<Row<'_>> = {
        let all: Vec<_> = rec.measured().collect();
        let step = all.len().div_ceil(SAMPLE_ROWS).max(1);
        all.into_iter()
            .step_by(step)
            .map(|(m, p)| (m.q.as_slice(), p, m.orientation))
            .collect()
    };
    // The median point: one gross cell is an outlier for the fit to name, not a unit error.
    let mut norms: Vec<f64> = rows.iter().map(|(_, p, _)| p.norm()).collect();
    let far = median(&mut norms);
    if far > FARTHEST_MM {
        return Err(ScaleMismatch {
            what: format!(
                "the measured points lie a median {:.1} km from the instrument's origin",
                far / 1e6
            ),
            cause: format!(
                "no tracker or camera measures that far: {}",
                length_hint(declared, 1e-3)
                    .unwrap_or_else(|| "check --length-unit and the point columns".into())
            ),
        });
    }
    if rows.len() < 4 {
        return Ok(());
    }
    positions(&rows, robot, declared)?;
    orientations(&rows, robot, declared)
}

/// Median distance of the points from their coordinate-wise median: a spread that a few gross
/// cells do not move (they are the outlier search's, and must not read as a unit error).
fn spread(points: &[Vector3<f64>]) -> f64 {
    let centre =
        Vector3::from_fn(|i, _| median(&mut points.iter().map(|p| p[i]).collect::<Vec<_>>()));
    median(
        &mut points
            .iter()
            .map(|p| (p - centre).norm())
            .collect::<Vec<_>>(),
    )
}

/// Nominal positions with revolute joints scaled by `ka` and prismatic ones by `kl`.
fn nominal(robot: &dyn Robot, qs: &[&[f64]], ka: f64, kl: f64) -> Vec<Vector3<f64>> {
    let e = ErrorParams::zeros(robot.layout());
    let kinds: Vec<JointKind> = robot.joints().iter().map(|j| j.kind).collect();
    qs.iter()
        .map(|q| {
            let q: Vec<f64> = q
                .iter()
                .zip(&kinds)
                .map(|(v, k)| match k {
                    JointKind::Revolute => v * ka,
                    JointKind::Prismatic => v * kl,
                })
                .collect();
            robot.position(&q, &e)
        })
        .collect()
}

fn positions(
    rows: &[Row<'_>],
    robot: &dyn Robot,
    declared: Option<DeclaredUnits>,
) -> Result<(), ScaleMismatch> {
    let qs: Vec<&[f64]> = rows.iter().map(|r| r.0).collect();
    let measured: Vec<Vector3<f64>> = rows.iter().map(|r| r.1).collect();
    let s_m = spread(&measured);
    let s_p = spread(&nominal(robot, &qs, 1.0, 1.0));
    if s_p < 1.0 || ACCEPTED.contains(&(s_m / s_p)) {
        return Ok(());
    }
    let has_revolute = robot.joints().iter().any(|j| j.kind == JointKind::Revolute);
    let has_prismatic = robot
        .joints()
        .iter()
        .any(|j| j.kind == JointKind::Prismatic);
    let deg = std::f64::consts::PI / 180.0;
    let angle_factors: &[f64] = if has_revolute {
        &[1.0, 1.0 / deg, deg]
    } else {
        &[1.0]
    };
    let length_factors = [1.0, 1000.0, 1e-3];
    // The unit change that brings the ratio closest to 1.
    let mut best: Option<(f64, f64, f64)> = None;
    for &ka in angle_factors {
        let by_angle = (!has_prismatic).then(|| spread(&nominal(robot, &qs, ka, 1.0)));
        for &kl in &length_factors {
            if ka == 1.0 && kl == 1.0 {
                continue;
            }
            let s_p = match by_angle {
                Some(s) => s,
                None => spread(&nominal(robot, &qs, ka, kl)),
            };
            if s_p < 1e-9 {
                continue;
            }
            let r = s_m * kl / s_p;
            if best.is_none_or(|b| r.ln().abs() < b.2.ln().abs()) {
                best = Some((ka, kl, r));
            }
        }
    }
    let what = format!(
        "the measured positions lie a median {} mm from their centre where the rig's \
         nominal kinematics put them {s_p:.0} mm from it at the same joint values",
        short(s_m)
    );
    let explained = best.filter(|b| EXPLAINED.contains(&b.2));
    let cause = match explained {
        Some((ka, kl, _)) => {
            let mut hints = Vec::new();
            if kl != 1.0 {
                hints.extend(length_hint(declared, kl));
            }
            if ka != 1.0 {
                hints.extend(angle_hint(declared, ka, "joint angles", "--angle-unit"));
            }
            hints.join("; and ")
        }
        None => "check --length-unit and --angle-unit, and that --joints names the rig's joints \
                 in the rig's order and --point the measured point"
            .into(),
    };
    Err(ScaleMismatch { what, cause })
}

/// "were they metres? use --length-unit m" for lengths that are `k` times what was read.
fn length_hint(declared: Option<DeclaredUnits>, k: f64) -> Option<String> {
    let truth = if k > 1.0 {
        LengthUnit::M
    } else {
        LengthUnit::Mm
    };
    match declared {
        Some(d) if d.length != truth => Some(format!(
            "they look like {} read as {}: use --length-unit {}",
            truth.name(),
            d.length.name(),
            if truth == LengthUnit::M { "m" } else { "mm" }
        )),
        _ => Some(format!(
            "the lengths look {} times too {}",
            if k > 1.0 { k } else { 1.0 / k },
            if k > 1.0 { "small" } else { "large" }
        )),
    }
}

/// "the joint angles look like radians read as degrees: use --angle-unit rad".
fn angle_hint(declared: Option<DeclaredUnits>, k: f64, what: &str, flag: &str) -> Option<String> {
    let truth = if k > 1.0 {
        AngleUnit::Rad
    } else {
        AngleUnit::Deg
    };
    let read = declared.map(|d| {
        if flag == "--angle-unit" {
            d.angle
        } else {
            d.orientation
        }
    });
    Some(match read {
        Some(r) if r != truth => format!(
            "the {what} look like {} read as {}: use {flag} {}",
            truth.name(),
            r.name(),
            if truth == AngleUnit::Rad {
                "rad"
            } else {
                "deg"
            }
        ),
        _ => format!(
            "the {what} look {:.1} times too {}",
            if k > 1.0 { k } else { 1.0 / k },
            if k > 1.0 { "small" } else { "large" }
        ),
    })
}

/// A length with three significant digits.
fn short(v: f64) -> String {
    if v >= 100.0 {
        format!("{v:.0}")
    } else if v >= 1.0 {
        format!("{v:.2}")
    } else {
        format!("{v:.3}")
    }
}

/// Median angle (rad) between the orientations of successive rows (a median, as for the
/// positions, so that one gross row does not read as a unit error).
fn median_turn(rs: &[UnitQuaternion<f64>]) -> f64 {
    if rs.len() < 2 {
        return 0.0;
    }
    median(
        &mut rs
            .windows(2)
            .map(|w| w[0].angle_to(&w[1]))
            .collect::<Vec<_>>(),
    )
}

fn orientations(
    rows: &[Row<'_>],
    robot: &dyn Robot,
    declared: Option<DeclaredUnits>,
) -> Result<(), ScaleMismatch> {
    let Some(chain) = robot.as_serial_chain() else {
        return Ok(());
    };
    let with: Vec<_> = rows
        .iter()
        .filter_map(|(q, _, o)| o.map(|o| (*q, o)))
        .collect();
    if with.len() < 4 {
        return Ok(());
    }
    let e = ErrorParams::zeros(chain.layout());
    let measured: Vec<_> = with.iter().map(|w| w.1).collect();
    let nominal: Vec<_> = with
        .iter()
        .map(|(q, _)| chain.tool_pose(q, &e).rotation)
        .collect();
    let (t_m, t_p) = (median_turn(&measured), median_turn(&nominal));
    if t_p < 1e-3 || ACCEPTED.contains(&(t_m / t_p)) {
        return Ok(());
    }
    let deg = std::f64::consts::PI / 180.0;
    let k = if t_m < t_p { 1.0 / deg } else { deg };
    Err(ScaleMismatch {
        what: format!(
            "the measured orientations turn by a median {:.3}° from one row to the next where \
             the rig's nominal kinematics turn the last link by {:.1}°",
            t_m.to_degrees(),
            t_p.to_degrees()
        ),
        cause: angle_hint(declared, k, "orientation angles", "--orientation-unit")
            .unwrap_or_default(),
    })
}
