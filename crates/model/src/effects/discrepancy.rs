//! `discrepancy`: a fitted smooth term that is NOT physics from the library. When the diagnosis
//! finds structure no library effect explains, it locates it in flexible shape bases
//! ([`crate::diagnosis::shapes`], described in [`crate::diagnosis::discrepancy`]: the
//! discrepancy's diagnosis side); the twin (`rigcal_sim::twin::learn`) refits it in the same
//! bases ([`rigcal_core::basis`]) and writes it here, flagged, so the updated scenario
//! re-simulates the recording it learned from; it describes a residual and explains nothing, and
//! a scenario that carries one says so in its `note`. A model file does not carry it.
//!
//! Each term is one located variable and one basis:
//! - joint-space (`own_joint_angle`, `other_joint_angle`, `approach_direction`): joint `joint`'s
//!   error Δq = Σ c_k f_k(x), x the commanded angle of `driver_joint` (its own for the first and
//!   the last), times the joint's approach direction (±1, the sign of its last change) for
//!   `approach_direction`;
//! - Cartesian (`time`, `position`): a tip displacement along each world axis, Σ c_k f_k(x), x
//!   the time since the session started or the true tip position before the displacement.
//!
//! Scenario units: `range_deg` (`range_mm` for a prismatic driver, `range_s` for time) for a
//! spline's range, `coefficients_deg` (`coefficients_mm` for a prismatic joint) for joint-space
//! terms, `x_mm`, `y_mm`, `z_mm` for Cartesian ones, `centres_mm` and `width_mm` for radial
//! functions; radians inside.

use super::entry::{float, one_based, EntryError, KindEntry, NewEffect, ParseCtx};
use super::kind::EffectKind;
use super::truth::{Effect, JointContext};
use nalgebra::Vector3;
use rigcal_core::basis::Form;
use rigcal_core::kinematics::{JointKind, Robot, SerialChain};
use serde::Deserialize;
use std::sync::Arc;

/// What a discrepancy term varies along (joints 0-based).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Driver {
    /// Joint `acted`'s error as a function of joint `driver`'s commanded angle, flipped with
    /// `acted`'s approach direction when `flips`.
    Joint {
        /// The joint whose error it is.
        acted: usize,
        /// The joint whose angle it varies along.
        driver: usize,
        /// Multiplied by the approach direction (±1) of `acted`.
        flips: bool,
    },
    /// A tip displacement that changes with time.
    Time,
    /// A tip displacement that changes with the position in the workspace.
    Position,
}

/// One term: a driver, a basis and its coefficients (rad or mm for a joint term, `functions`
/// of them; mm for a Cartesian term, `functions` per world axis, x first).
#[derive(Debug, Clone, PartialEq)]
pub struct DiscrepancyTerm {
    /// What it varies along.
    pub driver: Driver,
    /// The basis.
    pub form: Form,
    /// The coefficients.
    pub coefficients: Vec<f64>,
}

impl DiscrepancyTerm {
    /// How many coefficients the term has.
    pub fn width(&self) -> usize {
        match self.driver {
            Driver::Joint { .. } => self.form.functions(),
            Driver::Time | Driver::Position => 3 * self.form.functions(),
        }
    }

    /// The basis values of a joint term at commanded joints `q` with approach directions
    /// `direction` (already multiplied by the direction when the term flips); empty for a
    /// Cartesian term.
    pub fn joint_values(&self, q: &[f64], direction: &[i8]) -> Vec<f64> {
        let Driver::Joint {
            acted,
            driver,
            flips,
        } = self.driver
        else {
            return Vec::new();
        };
        let x = q.get(driver).copied().unwrap_or(0.0);
        let s = if flips {
            f64::from(direction.get(acted).copied().unwrap_or(0))
        } else {
            1.0
        };
        self.form.values(x).into_iter().map(|v| s * v).collect()
    }

    /// The basis values of a Cartesian term at time `t_s` with the tip at `tip` (mm); empty for
    /// a joint term.
    pub fn tip_values(&self, t_s: f64, tip: &Vector3<f64>) -> Vec<f64> {
        match self.driver {
            Driver::Time => self.form.values(t_s),
            Driver::Position => self.form.values_at(tip),
            Driver::Joint { .. } => Vec::new(),
        }
    }

    fn joint_error(&self, q: &[f64], direction: &[i8]) -> f64 {
        dot(&self.joint_values(q, direction), &self.coefficients)
    }

    fn tip_error(&self, t_s: f64, tip: &Vector3<f64>) -> Vector3<f64> {
        let v = self.tip_values(t_s, tip);
        let k = v.len();
        if k == 0 || self.coefficients.len() < 3 * k {
            return Vector3::zeros();
        }
        Vector3::from_fn(|a, _| dot(&v, &self.coefficients[a * k..(a + 1) * k]))
    }
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// A fitted discrepancy: its terms and the note that flags it.
#[derive(Debug, Clone, PartialEq)]
pub struct Discrepancy {
    /// The terms, summed.
    pub terms: Vec<DiscrepancyTerm>,
    /// What it is (written by the twin: "FLAGGED: …").
    pub note: String,
}

impl Effect for Discrepancy {
    fn kind(&self) -> EffectKind {
        EffectKind::Discrepancy
    }

    fn joint_offsets(&self, ctx: &JointContext<'_>, dq: &mut [f64]) {
        for t in &self.terms {
            if let Driver::Joint { acted, .. } = t.driver {
                if let Some(d) = dq.get_mut(acted) {
                    *d += t.joint_error(ctx.commanded, ctx.direction);
                }
            }
        }
    }

    fn tip_offset(&self, t_s: f64, tip: &Vector3<f64>) -> Vector3<f64> {
        self.terms.iter().map(|t| t.tip_error(t_s, tip)).sum()
    }
}

/// The flag every written discrepancy carries in its `note`.
pub const FLAG: &str = "FLAGGED: a fitted smooth term, not physics from the library";

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct Raw {
    #[serde(default)]
    note: Option<String>,
    terms: Vec<RawTerm>,
}

/// One `[[effects.terms]]` table (16 fields: one per key a term may have, so serde rejects any
/// other; the parser takes those its `depends_on` and `basis` need).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawTerm {
    depends_on: String,
    joint: Option<i64>,
    driver_joint: Option<i64>,
    basis: String,
    range_deg: Option<[f64; 2]>,
    range_mm: Option<[f64; 2]>,
    range_s: Option<[f64; 2]>,
    intervals: Option<usize>,
    orders: Option<[u32; 2]>,
    centres_mm: Option<Vec<[f64; 3]>>,
    width_mm: Option<f64>,
    coefficients_deg: Option<Vec<f64>>,
    coefficients_mm: Option<Vec<f64>>,
    x_mm: Option<Vec<f64>>,
    y_mm: Option<Vec<f64>>,
    z_mm: Option<Vec<f64>>,
}

/// The registry's entry of `discrepancy`.
pub(crate) struct Entry;

impl KindEntry for Entry {
    /// `note`, and `[[effects.terms]]` tables (see the module documentation).
    fn parse(&self, ctx: &ParseCtx<'_>, t: &toml::Table) -> Result<Arc<dyn Effect>, EntryError> {
        Ok(Arc::new(parse_discrepancy(ctx, t)?))
    }
}

fn parse_discrepancy(ctx: &ParseCtx<'_>, t: &toml::Table) -> Result<Discrepancy, EntryError> {
    let raw: Raw = ctx.raw(t)?;
    if raw.terms.is_empty() {
        return Err(ctx.invalid(".terms", "a discrepancy needs at least one term"));
    }
    let terms = raw
        .terms
        .iter()
        .enumerate()
        .map(|(i, r)| parse_term(ctx, &format!(".terms[{i}]"), r))
        .collect::<Result<Vec<_>, _>>()?;
    Ok(Discrepancy {
        terms,
        note: raw.note.unwrap_or_else(|| FLAG.into()),
    })
}

fn parse_term(ctx: &ParseCtx<'_>, key: &str, r: &RawTerm) -> Result<DiscrepancyTerm, EntryError> {
    let sub = |s: &str| format!("{key}.{s}");
    let joint = |name: &str, v: Option<i64>| -> Result<usize, EntryError> {
        let v = v.ok_or_else(|| ctx.invalid(&sub(name), "missing"))?;
        ctx.joint(&sub(name), v)
    };
    let driver = match r.depends_on.as_str() {
        "own_joint_angle" | "approach_direction" => {
            let j = joint("joint", r.joint)?;
            Driver::Joint {
                acted: j,
                driver: j,
                flips: r.depends_on == "approach_direction",
            }
        }
        "other_joint_angle" => Driver::Joint {
            acted: joint("joint", r.joint)?,
            driver: joint("driver_joint", r.driver_joint)?,
            flips: false,
        },
        "time" => Driver::Time,
        "position" => Driver::Position,
        other => {
            return Err(ctx.invalid(
                &sub("depends_on"),
                format!("`{other}` is not one of own_joint_angle, other_joint_angle, approach_direction, time, position"),
            ))
        }
    };
    let form = parse_form(ctx, key, r, driver)?;
    let coefficients = parse_coefficients(ctx, key, r, driver, form.functions())?;
    Ok(DiscrepancyTerm {
        driver,
        form,
        coefficients,
    })
}

fn joint_kind(chain: &SerialChain, j: usize) -> JointKind {
    Robot::joints(chain)[j].kind
}

fn parse_form(
    ctx: &ParseCtx<'_>,
    key: &str,
    r: &RawTerm,
    driver: Driver,
) -> Result<Form, EntryError> {
    let sub = |s: &str| format!("{key}.{s}");
    match (r.basis.as_str(), driver) {
        ("spline", _) => {
            // The driver's file unit: degrees (mm for a prismatic joint), seconds for time.
            let (range, name, kind) = match driver {
                Driver::Time => (r.range_s, "range_s", None),
                Driver::Joint { driver, .. } => match joint_kind(ctx.chain, driver) {
                    JointKind::Revolute => (r.range_deg, "range_deg", Some(JointKind::Revolute)),
                    JointKind::Prismatic => (r.range_mm, "range_mm", Some(JointKind::Prismatic)),
                },
                Driver::Position => {
                    return Err(ctx.invalid(
                        &sub("basis"),
                        "a position term takes basis = \"radial\"",
                    ))
                }
            };
            let to_internal = |v: f64| kind.map_or(v, |k| k.from_file_units(v));
            let [lo, hi] = range.ok_or_else(|| ctx.invalid(&sub(name), "missing"))?;
            let (lo, hi) = (ctx.finite(&sub(name), lo)?, ctx.finite(&sub(name), hi)?);
            if hi <= lo {
                return Err(ctx.invalid(&sub(name), "the range's upper end must exceed its lower"));
            }
            let intervals = r
                .intervals
                .filter(|n| *n > 0)
                .ok_or_else(|| ctx.invalid(&sub("intervals"), "missing or zero"))?;
            Ok(Form::Spline {
                lo: to_internal(lo),
                hi: to_internal(hi),
                intervals,
            })
        }
        ("harmonics", Driver::Joint { driver, .. })
            if joint_kind(ctx.chain, driver) == JointKind::Revolute =>
        {
            let orders = r
                .orders
                .filter(|o| o[0] >= 1 && o[1] >= o[0])
                .ok_or_else(|| ctx.invalid(&sub("orders"), "missing, or not [lowest, highest] ≥ 1"))?;
            Ok(Form::Harmonics { orders })
        }
        ("radial", Driver::Position) => {
            let centres = r
                .centres_mm
                .clone()
                .filter(|c| !c.is_empty())
                .ok_or_else(|| ctx.invalid(&sub("centres_mm"), "missing or empty"))?;
            let w = r
                .width_mm
                .ok_or_else(|| ctx.invalid(&sub("width_mm"), "missing"))?;
            Ok(Form::Radial {
                centres,
                width_mm: ctx.positive(&sub("width_mm"), w)?,
            })
        }
        (other, _) => Err(ctx.invalid(
            &sub("basis"),
            format!("`{other}` does not fit this term: splines for joint angles and time, harmonics for a revolute joint's angle, radial for position"),
        )),
    }
}

fn parse_coefficients(
    ctx: &ParseCtx<'_>,
    key: &str,
    r: &RawTerm,
    driver: Driver,
    k: usize,
) -> Result<Vec<f64>, EntryError> {
    let sub = |s: &str| format!("{key}.{s}");
    let checked = |name: &str, v: &Option<Vec<f64>>| -> Result<Vec<f64>, EntryError> {
        let v = v
            .clone()
            .ok_or_else(|| ctx.invalid(&sub(name), "missing"))?;
        if v.len() != k {
            return Err(ctx.invalid(
                &sub(name),
                format!("has {} values; the basis has {k} functions", v.len()),
            ));
        }
        v.iter().map(|x| ctx.finite(&sub(name), *x)).collect()
    };
    match driver {
        Driver::Joint { acted, .. } => {
            let kind = joint_kind(ctx.chain, acted);
            let (name, v) = match kind {
                JointKind::Revolute => ("coefficients_deg", &r.coefficients_deg),
                JointKind::Prismatic => ("coefficients_mm", &r.coefficients_mm),
            };
            Ok(checked(name, v)?
                .into_iter()
                .map(|c| kind.from_file_units(c))
                .collect())
        }
        Driver::Time | Driver::Position => {
            let mut out = checked("x_mm", &r.x_mm)?;
            out.extend(checked("y_mm", &r.y_mm)?);
            out.extend(checked("z_mm", &r.z_mm)?);
            Ok(out)
        }
    }
}

/// The scenario entry of a fitted discrepancy: its `[[effects]]` table in file units, `kind`
/// first, and how many terms and coefficients it has.
pub fn scenario_entry(chain: &SerialChain, d: &Discrepancy) -> NewEffect {
    let mut t = toml::Table::new();
    t.insert("kind".into(), EffectKind::Discrepancy.name().into());
    t.insert("note".into(), d.note.clone().into());
    let terms = d
        .terms
        .iter()
        .map(|x| toml::Value::Table(term_table(chain, x)));
    t.insert("terms".into(), toml::Value::Array(terms.collect()));
    let coefficients: usize = d.terms.iter().map(DiscrepancyTerm::width).sum();
    NewEffect {
        table: t,
        summary: format!("{} term(s), {coefficients} coefficients", d.terms.len()),
    }
}

/// Exact values: a basis's range and centres place its functions, so they are written as
/// computed (the fitted coefficients belong to those functions).
fn exact(v: impl IntoIterator<Item = f64>) -> toml::Value {
    toml::Value::Array(v.into_iter().map(toml::Value::Float).collect())
}

/// Seven significant digits: coefficients, well under the noise and readable.
fn floats(v: impl IntoIterator<Item = f64>) -> toml::Value {
    toml::Value::Array(v.into_iter().map(float).collect())
}

fn term_table(chain: &SerialChain, x: &DiscrepancyTerm) -> toml::Table {
    let mut t = toml::Table::new();
    let depends_on = match x.driver {
        Driver::Joint { flips: true, .. } => "approach_direction",
        Driver::Joint { acted, driver, .. } if acted == driver => "own_joint_angle",
        Driver::Joint { .. } => "other_joint_angle",
        Driver::Time => "time",
        Driver::Position => "position",
    };
    t.insert("depends_on".into(), depends_on.into());
    if let Driver::Joint { acted, driver, .. } = x.driver {
        t.insert("joint".into(), one_based(acted));
        if acted != driver {
            t.insert("driver_joint".into(), one_based(driver));
        }
    }
    match &x.form {
        Form::Spline { lo, hi, intervals } => {
            t.insert("basis".into(), "spline".into());
            let (name, f): (&str, Box<dyn Fn(f64) -> f64>) = match x.driver {
                Driver::Joint { driver, .. } => {
                    let kind = joint_kind(chain, driver);
                    let name = match kind {
                        JointKind::Revolute => "range_deg",
                        JointKind::Prismatic => "range_mm",
                    };
                    (name, Box::new(move |v| kind.to_file_units(v)))
                }
                _ => ("range_s", Box::new(|v| v)),
            };
            t.insert(name.into(), exact([f(*lo), f(*hi)]));
            t.insert("intervals".into(), toml::Value::Integer(*intervals as i64));
        }
        Form::Harmonics { orders } => {
            t.insert("basis".into(), "harmonics".into());
            let o = orders.iter().map(|n| toml::Value::Integer(i64::from(*n)));
            t.insert("orders".into(), toml::Value::Array(o.collect()));
        }
        Form::Radial { centres, width_mm } => {
            t.insert("basis".into(), "radial".into());
            let c = centres.iter().map(|c| exact(*c));
            t.insert("centres_mm".into(), toml::Value::Array(c.collect()));
            t.insert("width_mm".into(), toml::Value::Float(*width_mm));
        }
    }
    match x.driver {
        Driver::Joint { acted, .. } => {
            let kind = joint_kind(chain, acted);
            let name = match kind {
                JointKind::Revolute => "coefficients_deg",
                JointKind::Prismatic => "coefficients_mm",
            };
            t.insert(
                name.into(),
                floats(x.coefficients.iter().map(|c| kind.to_file_units(*c))),
            );
        }
        Driver::Time | Driver::Position => {
            let k = x.form.functions();
            for (a, name) in ["x_mm", "y_mm", "z_mm"].iter().enumerate() {
                let c = x.coefficients.get(a * k..(a + 1) * k).unwrap_or(&[]);
                t.insert((*name).into(), floats(c.iter().copied()));
            }
        }
    }
    t
}

#[cfg(test)]
mod tests {
    use super::*;
    use rigcal_core::kinematics::ErrorParams;
    use rigcal_core::rig::Rig;
    use std::path::Path;

    #[test]
    fn a_written_discrepancy_reads_back_the_same() {
        let rig = Rig::load(Path::new(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../rigs/rv-m2-ideal.toml"
        )))
        .expect("rig");
        let truth = ErrorParams::zeros(rig.chain.layout());
        let d = Discrepancy {
            terms: vec![
                DiscrepancyTerm {
                    driver: Driver::Joint {
                        acted: 2,
                        driver: 2,
                        flips: true,
                    },
                    form: Form::Harmonics { orders: [5, 6] },
                    coefficients: vec![1e-4, 0.0, -3e-4, 2e-5],
                },
                DiscrepancyTerm {
                    driver: Driver::Joint {
                        acted: 1,
                        driver: 0,
                        flips: false,
                    },
                    form: Form::Spline {
                        lo: -2.0,
                        hi: 2.5,
                        intervals: 2,
                    },
                    coefficients: vec![1e-4, -2e-4, 3e-4, 0.0, 5e-5],
                },
                DiscrepancyTerm {
                    driver: Driver::Position,
                    form: Form::Radial {
                        centres: vec![[10.0, -20.0, 300.0], [0.0, 5.0, 450.0]],
                        width_mm: 120.0,
                    },
                    coefficients: (0..6).map(|i| f64::from(i) * 0.01).collect(),
                },
            ],
            note: FLAG.into(),
        };
        let ctx = ParseCtx {
            key: "effects[0]",
            chain: &rig.chain,
            truth: &truth,
            instrument: &rig.instrument,
            seed: 1,
            index: 0,
        };
        let written = scenario_entry(&rig.chain, &d);
        assert_eq!(written.summary, "3 term(s), 15 coefficients");
        let back = parse_discrepancy(&ctx, &written.table).expect("reads back");
        assert_eq!(back.note, d.note);
        assert_eq!(back.terms.len(), d.terms.len());
        for (a, b) in back.terms.iter().zip(&d.terms) {
            assert_eq!(a.driver, b.driver);
            assert_eq!(a.coefficients.len(), b.coefficients.len());
            for (x, y) in a.coefficients.iter().zip(&b.coefficients) {
                assert!((x - y).abs() <= 1e-6 * y.abs() + 1e-15, "{x} vs {y}");
            }
            match (&a.form, &b.form) {
                (
                    Form::Spline { lo, hi, intervals },
                    Form::Spline {
                        lo: l,
                        hi: h,
                        intervals: n,
                    },
                ) => {
                    assert!((lo - l).abs() < 1e-9 && (hi - h).abs() < 1e-9 && intervals == n);
                }
                (x, y) => assert_eq!(x, y),
            }
        }
    }
}
