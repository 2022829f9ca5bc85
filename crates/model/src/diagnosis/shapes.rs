//! Flexible shape bases: what an error outside the library may depend on, as linear models the
//! tests can weigh against the library's candidates and the discrepancy term can be fitted in.
//!
//! Each basis is one *located variable* with one flexible form:
//! - a joint's error as a function of its **own angle** (cubic B-splines; for a revolute joint
//!   also harmonics of orders above the library's, 5 and 12): columns f_k(q_j)·J_j;
//! - a joint's error as a function of **another joint's angle** (cubic B-splines in q_k):
//!   columns f_m(q_k)·J_j;
//! - a joint's error that flips with its **approach direction** and varies along its angle
//!   (s_j·f_k(q_j)·J_j, s_j = ±1 the direction, backlash being the constant case);
//! - a Cartesian error along each world axis as a function of **time** (B-splines in t) or of the
//!   **position** (Gaussian radial basis functions centred on measured points).
//!
//! J_j is joint j's column of the joint Jacobian (mm/rad), so joint-space coefficients are in
//! radians (mm for a prismatic joint) and Cartesian ones in mm. The knots, orders and centres
//! are fixed by the recording the basis was built on ([`ShapeSpec`]), so the same columns can be
//! built on held-out recordings (values outside the fitted range are clamped to it).
//!
//! Why these forms: a regression spline is linear in its coefficients, so the same partial
//! F-tests, sizes and σ's serve the library's candidates and the shapes, and the discrepancy term
//! is an ordinary least-squares fit; its local support shows a dent where it is (a few
//! coefficients move) and does not smear it over the range as a global polynomial would; a
//! harmonic basis covers periodic errors of high order, which a spline of affordable size cannot
//! follow over a long range. Radial functions do the same in three dimensions, where a tensor
//! spline would need thousands of columns. A Gaussian process would give similar fits at O(n³)
//! with hyper-parameters to choose, and a marginal likelihood that does not compare with the
//! F-tests of the library. Sizes (intervals, centres) grow with the number of measurements so
//! small tracker recordings keep enough degrees of freedom.
//!
//! Units: joint values in rad (mm for prismatic joints), time in s, positions in mm.

pub use rigcal_core::basis::{spline_values, Form};

use super::Data;
use nalgebra::{DMatrix, Vector3};
use rigcal_core::kinematics::{JointKind, Robot};
use serde::{Deserialize, Serialize};

/// Harmonic orders of the periodic own-angle basis: above the library's transmission errors
/// (orders 1 to [`crate::effects::transmission::MAX_ORDER`]).
const PERIODIC_ORDERS: [u32; 2] = [5, 12];

/// What a shape depends on (joints 0-based inside, 1-based in reports).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Variable {
    /// Joint `joint`'s error as a function of its own angle.
    OwnAngle {
        /// The joint.
        joint: usize,
    },
    /// Joint `acted`'s error as a function of joint `driver`'s angle.
    OtherAngle {
        /// The joint whose error it is.
        acted: usize,
        /// The joint whose angle drives it.
        driver: usize,
    },
    /// Joint `joint`'s error that flips with its approach direction, varying along its angle.
    Direction {
        /// The joint.
        joint: usize,
    },
    /// A Cartesian error that changes with time.
    Time,
    /// A Cartesian error that changes with the position in the workspace.
    Position,
}

impl Variable {
    /// The report's name of the variable kind: `own_joint_angle`, `other_joint_angle`,
    /// `approach_direction`, `time`, `position`.
    pub fn key(&self) -> &'static str {
        match self {
            Variable::OwnAngle { .. } => "own_joint_angle",
            Variable::OtherAngle { .. } => "other_joint_angle",
            Variable::Direction { .. } => "approach_direction",
            Variable::Time => "time",
            Variable::Position => "position",
        }
    }

    /// Plain language: "joint 2's error as a function of its own angle".
    pub fn label(&self) -> String {
        match *self {
            Variable::OwnAngle { joint } => {
                format!("joint {}'s error as a function of its own angle", joint + 1)
            }
            Variable::OtherAngle { acted, driver } => format!(
                "joint {}'s error as a function of joint {}'s angle",
                acted + 1,
                driver + 1
            ),
            Variable::Direction { joint } => format!(
                "joint {}'s error flipping with its approach direction, varying along its angle",
                joint + 1
            ),
            Variable::Time => "a Cartesian error that changes with time".into(),
            Variable::Position => {
                "a Cartesian error that changes with the position in the workspace".into()
            }
        }
    }

    /// The joint whose error it is, for joint-space shapes.
    pub fn acted_joint(&self) -> Option<usize> {
        match *self {
            Variable::OwnAngle { joint } | Variable::Direction { joint } => Some(joint),
            Variable::OtherAngle { acted, .. } => Some(acted),
            Variable::Time | Variable::Position => None,
        }
    }

    /// The joint whose angle it varies along, for joint-space shapes.
    pub fn driver_joint(&self) -> Option<usize> {
        match *self {
            Variable::OwnAngle { joint } | Variable::Direction { joint } => Some(joint),
            Variable::OtherAngle { driver, .. } => Some(driver),
            Variable::Time | Variable::Position => None,
        }
    }
}

/// One shape basis: a located variable and a flexible form, with everything needed to build its
/// columns on any recording of the same rig.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ShapeSpec {
    /// What it depends on.
    pub variable: Variable,
    /// How.
    pub form: Form,
}

impl ShapeSpec {
    /// "joint 2's error as a function of its own angle (cubic B-splines on 20 intervals)".
    pub fn label(&self) -> String {
        format!("{} ({})", self.variable.label(), self.form.label())
    }

    /// Columns on the measurements of `d` (3 rows per measurement), or None when the recording
    /// cannot show this shape (no time, a joint that does not move).
    pub fn columns(&self, d: &Data) -> Option<DMatrix<f64>> {
        let n = d.len();
        let k = self.form.functions();
        match self.variable {
            Variable::OwnAngle { joint } => {
                joint_columns(d, joint, |i| self.form.values(d.obs[i].q[joint]))
            }
            Variable::OtherAngle { acted, driver } => {
                if !d.moving.contains(&driver) {
                    return None;
                }
                joint_columns(d, acted, |i| self.form.values(d.obs[i].q[driver]))
            }
            Variable::Direction { joint } => joint_columns(d, joint, |i| {
                let s = f64::from(d.direction[i][joint]);
                self.form
                    .values(d.obs[i].q[joint])
                    .into_iter()
                    .map(|v| s * v)
                    .collect()
            }),
            Variable::Time => {
                let t = d.t_s.as_ref()?;
                Some(axis_columns(n, k, |i| self.form.values(t[i])))
            }
            Variable::Position => {
                let p = modelled_positions(d);
                Some(axis_columns(n, k, |i| self.form.values_at(&p[i])))
            }
        }
    }
}

/// Columns f_k(i)·J_joint(i) (3 rows per measurement), or None when the joint does not move.
fn joint_columns(d: &Data, joint: usize, f: impl Fn(usize) -> Vec<f64>) -> Option<DMatrix<f64>> {
    if !d.moving.contains(&joint) {
        return None;
    }
    let n = d.len();
    let rows: Vec<Vec<f64>> = (0..n).map(&f).collect();
    let k = rows.first().map_or(0, Vec::len);
    let mut m = DMatrix::zeros(3 * n, k);
    for (i, v) in rows.iter().enumerate() {
        for (c, val) in v.iter().enumerate() {
            for r in 0..3 {
                m[(3 * i + r, c)] = val * d.joint_jacobian[i][(r, joint)];
            }
        }
    }
    Some(m)
}

/// Columns f_k(i) on each world axis: column a·k + c is function c on axis a.
fn axis_columns(n: usize, k: usize, f: impl Fn(usize) -> Vec<f64>) -> DMatrix<f64> {
    let mut m = DMatrix::zeros(3 * n, 3 * k);
    for i in 0..n {
        for (c, v) in f(i).iter().enumerate().take(k) {
            for a in 0..3 {
                m[(3 * i + a, a * k + c)] = *v;
            }
        }
    }
    m
}

/// Range of joint `j` over the measurements.
fn joint_range(d: &Data, j: usize) -> (f64, f64) {
    d.obs.iter().fold((f64::MAX, f64::MIN), |(a, b), o| {
        (a.min(o.q[j]), b.max(o.q[j]))
    })
}

/// Spline intervals for `m` measurements: one per `per` measurements, within [lo, hi].
fn intervals(m: usize, per: usize, lo: usize, hi: usize) -> usize {
    (m / per).clamp(lo, hi)
}

/// The shape bases of a recording: per moving joint its own angle (splines, and harmonics for a
/// revolute joint whose range holds at least one cycle of the lowest order), its approach
/// direction, every other moving joint's angle; then time (when the recording has it) and
/// position.
pub fn shape_bases(d: &Data) -> Vec<ShapeSpec> {
    let m = d.len();
    let mut out = Vec::new();
    let spline = |j: usize, per: usize, lo: usize, hi: usize| {
        let (a, b) = joint_range(d, j);
        Form::Spline {
            lo: a,
            hi: b,
            intervals: intervals(m, per, lo, hi),
        }
    };
    for &j in &d.moving {
        out.push(ShapeSpec {
            variable: Variable::OwnAngle { joint: j },
            form: spline(j, 30, 4, 20),
        });
        let (a, b) = joint_range(d, j);
        let revolute = d.chain.joints()[j].kind == JointKind::Revolute;
        if revolute && (b - a) * f64::from(PERIODIC_ORDERS[0]) >= std::f64::consts::TAU {
            out.push(ShapeSpec {
                variable: Variable::OwnAngle { joint: j },
                form: Form::Harmonics {
                    orders: PERIODIC_ORDERS,
                },
            });
        }
        let both = d.direction.iter().any(|s| s[j] > 0) && d.direction.iter().any(|s| s[j] < 0);
        if both {
            out.push(ShapeSpec {
                variable: Variable::Direction { joint: j },
                form: spline(j, 75, 1, 8),
            });
        }
    }
    for &acted in &d.moving {
        for &driver in &d.moving {
            if driver != acted {
                out.push(ShapeSpec {
                    variable: Variable::OtherAngle { acted, driver },
                    form: spline(driver, 50, 3, 12),
                });
            }
        }
    }
    if let Some(t) = &d.t_s {
        let lo = t.iter().copied().fold(f64::MAX, f64::min);
        let hi = t.iter().copied().fold(f64::MIN, f64::max);
        if hi > lo {
            out.push(ShapeSpec {
                variable: Variable::Time,
                form: Form::Spline {
                    lo,
                    hi,
                    intervals: intervals(m, 60, 3, 10),
                },
            });
        }
    }
    out.push(ShapeSpec {
        variable: Variable::Position,
        form: radial_form(d, (m / 15).clamp(8, 40)),
    });
    out
}

/// Radial functions centred on `k` measured (modelled) positions spread by farthest-point
/// sampling; the width is the mean distance from a centre to its nearest neighbour, so
/// neighbouring functions overlap and the span is smooth.
fn radial_form(d: &Data, k: usize) -> Form {
    // Modelled, not measured, positions: measured ones carry the residual itself.
    let p = modelled_positions(d);
    radial_on(&p, k)
}

/// The modelled tip position of each measurement (mm).
fn modelled_positions(d: &Data) -> Vec<Vector3<f64>> {
    d.obs.iter().map(|o| d.chain.position(&o.q, &d.e)).collect()
}

/// Radial functions on `k` of the points `p` spread by farthest-point sampling from the point
/// nearest their mean (so the choice does not depend on row order), of width the mean distance
/// from a centre to its nearest neighbour.
fn radial_on(p: &[Vector3<f64>], k: usize) -> Form {
    let centres = farthest_points(p, k, 0.0);
    let nearest: Vec<f64> = centres
        .iter()
        .enumerate()
        .map(|(i, c)| {
            centres
                .iter()
                .enumerate()
                .filter(|(k, _)| *k != i)
                .map(|(_, o)| (c - o).norm())
                .fold(f64::MAX, f64::min)
        })
        .filter(|v| *v < f64::MAX)
        .collect();
    let width_mm = if nearest.is_empty() {
        1.0
    } else {
        (nearest.iter().sum::<f64>() / nearest.len() as f64).max(1e-6)
    };
    Form::Radial {
        centres: centres.iter().map(|c| [c.x, c.y, c.z]).collect(),
        width_mm,
    }
}

/// A finer position basis where a located position shape is largest: radial functions of half
/// the coarse width on the measured points within 1.5 coarse widths of the shape's centre (the
/// mean position where its share `size` of each measurement reaches half its peak, weighted by
/// its square), spread by farthest-point sampling down to 0.4 coarse widths apart (at most 30).
/// A global basis of three dimensions cannot be made fine everywhere (halving its spacing takes
/// eight times the columns), so it is made fine where the coarse one found something. None when
/// too few measurements are there.
pub fn refine_position(d: &Data, size: &[f64], coarse_width_mm: f64) -> Option<ShapeSpec> {
    let p = modelled_positions(d);
    let peak = size.iter().fold(0.0f64, |a, v| a.max(*v));
    if peak <= 0.0 {
        return None;
    }
    let (mut sum, mut w) = (Vector3::zeros(), 0.0);
    for (x, s) in p.iter().zip(size) {
        if *s >= 0.5 * peak {
            sum += x * (s * s);
            w += s * s;
        }
    }
    let centre = sum / w.max(1e-300);
    let region: Vec<Vector3<f64>> = p
        .iter()
        .copied()
        .filter(|x| (x - centre).norm() <= 1.5 * coarse_width_mm)
        .collect();
    let spacing = 0.4 * coarse_width_mm;
    let centres = farthest_points(&region, 30, spacing);
    tracing::debug!(
        points = region.len(),
        centres = centres.len(),
        coarse_width_mm,
        "refinement"
    );
    if region.len() < 12 || centres.len() < 4 {
        return None;
    }
    Some(ShapeSpec {
        variable: Variable::Position,
        form: Form::Radial {
            centres: centres.iter().map(|c| [c.x, c.y, c.z]).collect(),
            width_mm: 0.5 * coarse_width_mm,
        },
    })
}

/// Up to `k` of the points `p` by farthest-point sampling from the point nearest their mean,
/// stopping when the next would be closer than `min_spacing` to one already taken.
fn farthest_points(p: &[Vector3<f64>], k: usize, min_spacing: f64) -> Vec<Vector3<f64>> {
    let Some(first) = p.first() else {
        return Vec::new();
    };
    let mean = p.iter().sum::<Vector3<f64>>() / p.len() as f64;
    let start = p
        .iter()
        .min_by(|a, b| (*a - mean).norm().total_cmp(&(*b - mean).norm()))
        .unwrap_or(first);
    let mut centres = vec![*start];
    let mut dist: Vec<f64> = p.iter().map(|x| (x - start).norm()).collect();
    while centres.len() < k.min(p.len()) {
        let Some((far, &dmax)) = dist.iter().enumerate().max_by(|a, b| a.1.total_cmp(b.1)) else {
            break;
        };
        if dmax < min_spacing {
            break;
        }
        let c = p[far];
        centres.push(c);
        for (dv, x) in dist.iter_mut().zip(p) {
            *dv = dv.min((x - c).norm());
        }
    }
    centres
}
