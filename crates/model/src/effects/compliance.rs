//! `joint_compliance`: joints deflect under the gravity torque of the links they carry,
//! Δq_j = c_j · τ_j(q), c_j = 1/k_j the compliance.
//!
//! **Truth** ([`JointCompliance`]) — physics, not a fitted formula: every link carries point
//! masses at stated positions in its own frame; gravity pulls along world −z with
//! g = 9.81 m/s². The torque about joint j's axis (world axis z_j through origin o_j) is
//! τ_j = Σ_{masses beyond j} ((p − o_j) × m·g) · z_j, and the joint deflects by Δq_j = τ_j / k_j
//! in the direction of the torque. A mass on link i (1-based: the body joint i moves) is given in
//! the frame at the end of that link, i.e. the frame of joint i+1's axis (D-H frame i), or the
//! tool frame for the last link. Scenario entry: `masses = [{ link, kg, at_mm }]`,
//! `joints = [{ joint, stiffness_nm_per_rad | deg_per_nm }]`.
//!
//! **Diagnosis candidate** — two models, chosen by what the rig file knows (the report says
//! which):
//! * *Masses known* — every link from the joint to the tip has `mass_kg` (and `com_mm`) in the
//!   rig file (`rig from-urdf` copies them from the URDF's `<inertial>`). The gravity torque
//!   ([`gravity_torque`]) is then known, the column is τ_j(q) · (joint j's column of the joint
//!   Jacobian) and its coefficient is the compliance itself, rad/(N·m): reported as
//!   `deg_per_nm` with its σ (spec/recordings.md).
//! * *Masses unknown* — the torque comes from a generic model: a unit mass (1 kg) at each point
//!   along the links beyond the joint (the origin of every later joint's axis frame, the tool
//!   frame and the measured tip; [`unit_torques`]). A mass anywhere on the straight segments
//!   between those points is a non-negative combination of them, so the fitted combination is
//!   the effective mass distribution. Column k = τ_k(q) · J_j with τ_k in N·m per kg;
//!   coefficient k = compliance × the mass effectively at point k. Compliance and mass cannot be
//!   told apart from positions alone, so `deg_per_nm` is *not* reported (an honest figure needs
//!   the masses): instead `compliance_times_mass_deg_kg_per_nm` (Σ_k of the coefficients ± σ)
//!   and the deflection it causes (RMS and max, degrees), and the explanation says why.
//!
//! **Model term** — basis τ_j(q) from the rig's link masses plus a payload at the tool frame's
//! origin ([`gravity_torque`]), coefficient the compliance (rad/(N·m), `deg_per_nm` in files).
//!
//! Gravity in the candidate and the model term is along the robot base's −z (for a free tracker
//! frame, rotated into the tracker's coordinates with the fitted frame); the truth's is the
//! world's −z. Units: kg, mm in files (metres in torques), N·m; degrees in files and reports,
//! radians inside.

use super::candidate::{Candidate, Data, Index, Param};
use super::entry::{float, one_based, EntryError, KindEntry, Masses, NewEffect, ParseCtx};
use super::kind::EffectKind;
use super::term::EffectContext;
use super::truth::{Effect, JointContext};
use nalgebra::{DMatrix, Vector3};
use rigcal_core::kinematics::{ErrorParams, JointKind, Robot, SerialChain};
use rigcal_core::rig::LinkMass;
use serde::Deserialize;
use std::sync::Arc;

/// Standard gravity (m/s²).
const G: f64 = 9.81;

/// A point mass on a link.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PointMass {
    /// The link (0-based joint index whose motion carries it).
    pub link: usize,
    /// Mass (kg).
    pub kg: f64,
    /// Position in the link's end frame (mm).
    pub at_mm: Vector3<f64>,
}

/// Gravity compliance of the arm (the truth).
#[derive(Debug, Clone, PartialEq)]
pub struct JointCompliance {
    /// The link masses.
    pub masses: Vec<PointMass>,
    /// (joint 0-based, stiffness N·m/rad) of every compliant joint.
    pub stiffness: Vec<(usize, f64)>,
}

impl JointCompliance {
    /// Gravity torque (N·m) about joint `j`'s axis at joint values `q`, with the geometry `e`.
    fn gravity_torque(&self, chain: &SerialChain, e: &ErrorParams, q: &[f64], j: usize) -> f64 {
        let axis_frame = chain.frame_before_joint(q, e, j);
        let z = axis_frame.rotation * Vector3::z();
        let o = axis_frame.translation.vector;
        let weight = |kg: f64| Vector3::new(0.0, 0.0, -kg * G);
        self.masses
            .iter()
            .filter(|m| m.link >= j)
            .map(|m| {
                let end = chain.frame_before_joint(q, e, m.link + 1);
                let p = end * nalgebra::Point3::from(m.at_mm);
                let lever_m = (p.coords - o) / 1000.0;
                lever_m.cross(&weight(m.kg)).dot(&z)
            })
            .sum()
    }

    /// Deflection (rad) of every compliant joint at `q`.
    pub fn deflections(
        &self,
        chain: &SerialChain,
        e: &ErrorParams,
        q: &[f64],
    ) -> Vec<(usize, f64)> {
        self.stiffness
            .iter()
            .map(|&(j, k)| (j, self.gravity_torque(chain, e, q, j) / k))
            .collect()
    }
}

impl Effect for JointCompliance {
    fn kind(&self) -> EffectKind {
        EffectKind::JointCompliance
    }

    fn joint_offsets(&self, ctx: &JointContext<'_>, dq: &mut [f64]) {
        for (j, d) in self.deflections(ctx.chain, ctx.truth, ctx.commanded) {
            dq[j] += d;
        }
    }
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawMass {
    link: i64,
    kg: f64,
    at_mm: [f64; 3],
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawJoint {
    joint: i64,
    stiffness_nm_per_rad: Option<f64>,
    deg_per_nm: Option<f64>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct Raw {
    masses: Vec<RawMass>,
    joints: Vec<RawJoint>,
}

/// The registry's entry of `joint_compliance`.
pub(crate) struct Entry;

impl KindEntry for Entry {
    /// `masses = [{ link, kg, at_mm }]`, `joints = [{ joint, stiffness_nm_per_rad | deg_per_nm }]`.
    fn parse(&self, ctx: &ParseCtx<'_>, t: &toml::Table) -> Result<Arc<dyn Effect>, EntryError> {
        let raw: Raw = ctx.raw(t)?;
        let mut masses = Vec::new();
        for (k, m) in raw.masses.iter().enumerate() {
            let key = |f: &str| format!(".masses[{k}].{f}");
            let link = ctx.joint(&key("link"), m.link)?;
            let kg = ctx.positive(&key("kg"), m.kg)?;
            for (c, v) in m.at_mm.iter().enumerate() {
                ctx.finite(&format!("{}[{c}]", key("at_mm")), *v)?;
            }
            masses.push(PointMass {
                link,
                kg,
                at_mm: Vector3::from(m.at_mm),
            });
        }
        if masses.is_empty() {
            return Err(ctx.invalid(".masses", "needs at least one link mass"));
        }
        let mut stiffness = Vec::new();
        for (k, r) in raw.joints.iter().enumerate() {
            let key = |f: &str| format!(".joints[{k}].{f}");
            let j = ctx.joint(&key("joint"), r.joint)?;
            if ctx.chain.joints()[j].kind != JointKind::Revolute {
                return Err(ctx.invalid(&key("joint"), "compliance is modelled on revolute joints"));
            }
            let k_nm = match (r.stiffness_nm_per_rad, r.deg_per_nm) {
                (Some(s), None) => ctx.positive(&key("stiffness_nm_per_rad"), s)?,
                (None, Some(c)) => 1.0 / ctx.positive(&key("deg_per_nm"), c)?.to_radians(),
                _ => {
                    return Err(ctx.invalid(
                        &format!(".joints[{k}]"),
                        "give exactly one of `stiffness_nm_per_rad` and `deg_per_nm`",
                    ))
                }
            };
            if stiffness.iter().any(|&(s, _)| s == j) {
                return Err(ctx.invalid(&key("joint"), "joint listed twice"));
            }
            stiffness.push((j, k_nm));
        }
        if stiffness.is_empty() {
            return Err(ctx.invalid(".joints", "needs at least one compliant joint"));
        }
        Ok(Arc::new(JointCompliance { masses, stiffness }))
    }

    fn candidates(&self, on: Index, masses: &Masses) -> Vec<Box<dyn Candidate>> {
        match on {
            Index::Joint(joint) => vec![Box::new(ComplianceCandidate {
                joint,
                masses: masses.clone(),
            })],
            _ => Vec::new(),
        }
    }
}

/// The scenario entry of a fitted compliance `c` (rad/(N·m)) of joint `joint` (0-based) with the
/// rig's link `masses`; an error says why it cannot be written (a compliance must be positive).
pub fn scenario_entry(
    masses: &[Option<LinkMass>],
    joint: usize,
    c: f64,
) -> Result<NewEffect, String> {
    let per_nm = c.to_degrees();
    if per_nm <= 0.0 {
        return Err(format!(
            "the fitted compliance is not positive ({per_nm:.6} deg/(N·m))"
        ));
    }
    let masses: Vec<toml::Value> = masses
        .iter()
        .enumerate()
        .filter_map(|(k, m)| {
            let m = (*m)?;
            (m.kg > 0.0).then(|| {
                let mut mt = toml::Table::new();
                mt.insert("link".into(), one_based(k));
                mt.insert("kg".into(), float(m.kg));
                mt.insert(
                    "at_mm".into(),
                    toml::Value::Array(m.com_mm.iter().map(|v| float(*v)).collect()),
                );
                toml::Value::Table(mt)
            })
        })
        .collect();
    let mut jt = toml::Table::new();
    jt.insert("joint".into(), one_based(joint));
    jt.insert("deg_per_nm".into(), float(per_nm));
    let mut t = toml::Table::new();
    t.insert("kind".into(), EffectKind::JointCompliance.name().into());
    t.insert("masses".into(), toml::Value::Array(masses));
    t.insert(
        "joints".into(),
        toml::Value::Array(vec![toml::Value::Table(jt)]),
    );
    Ok(NewEffect {
        table: t,
        summary: format!("deg_per_nm = {per_nm:.6} (the rig's link masses)"),
    })
}

/// True when the rig's `masses` cover every link from joint `joint` on, of `dof` joints: what
/// the model term and the known-mass candidate need.
pub fn masses_cover(masses: &[Option<LinkMass>], joint: usize, dof: usize) -> bool {
    (joint..dof).all(|k| masses.get(k).is_some_and(Option::is_some))
}

/// Gravity torque (N·m) about joint `j` at `q`: the rig's link masses from `j` on and the
/// payload at the tool frame's origin, gravity along the base's −z (turned by the measurement
/// frame). A link without a mass adds nothing (the model refuses compliance then, see
/// [`masses_cover`]). The model term's basis, and the known-mass candidate's torque.
pub fn gravity_torque(ctx: &EffectContext<'_>, q: &[f64], j: usize) -> f64 {
    let chain = ctx.chain;
    let n = chain.joints().len();
    let axis = chain.frame_before_joint(q, ctx.e, j);
    let z = axis.rotation * Vector3::z();
    let o = axis.translation.vector;
    let g = gravity(chain, ctx.e);
    let mut points: Vec<(f64, Vector3<f64>)> = (j..n)
        .filter_map(|k| {
            let m = ctx.masses.get(k).copied().flatten()?;
            let end = chain.frame_before_joint(q, ctx.e, k + 1);
            Some((m.kg, (end * nalgebra::Point3::from(m.com_mm)).coords))
        })
        .collect();
    if ctx.payload_kg != 0.0 {
        let tool = chain.frame_before_joint(q, ctx.e, n);
        points.push((ctx.payload_kg, tool.translation.vector));
    }
    points
        .iter()
        .map(|(kg, p)| ((p - o) / 1000.0).cross(&(g * *kg)).dot(&z))
        .sum()
}

/// Gravity (N per kg) in the coordinates the chain's points are in: the robot base's −z, turned
/// by the measurement frame when it is fitted.
fn gravity(chain: &SerialChain, e: &ErrorParams) -> Vector3<f64> {
    chain.frame_pose(e).rotation * Vector3::new(0.0, 0.0, -G)
}

/// Torques (N·m per kg) about joint `j` at `q` of a unit mass at each generic point beyond it.
pub fn unit_torques(d: &Data, q: &[f64], j: usize) -> Vec<f64> {
    let chain = &d.chain;
    // Every joint's frame in one pass (the diagnosis asks this for every pose, joint and
    // candidate: one pass per joint made it quadratic in the joints).
    let frames = chain.frames_before_joints(q, &d.e);
    torques_about(&frames, j, &chain.position(q, &d.e), &gravity(chain, &d.e))
}

/// [`unit_torques`] of every joint at `q` (entry j: joint j's), from one pass over the chain's
/// frames and one tip position: the same numbers as asking joint by joint.
pub fn unit_torques_all(d: &Data, q: &[f64]) -> Vec<Vec<f64>> {
    let chain = &d.chain;
    let frames = chain.frames_before_joints(q, &d.e);
    let tip = chain.position(q, &d.e);
    let weight = gravity(chain, &d.e);
    (0..chain.joints().len())
        .map(|j| torques_about(&frames, j, &tip, &weight))
        .collect()
}

/// Torques (N·m per kg) about joint `j` of a unit mass at each point beyond it: the origins of
/// the later joints' frames (`frames`, one per joint) and the tip (mm), under `weight` (N/kg).
fn torques_about(
    frames: &[nalgebra::Isometry3<f64>],
    j: usize,
    tip: &Vector3<f64>,
    weight: &Vector3<f64>,
) -> Vec<f64> {
    let axis = frames[j];
    let z = axis.rotation * Vector3::z();
    let o = axis.translation.vector;
    let mut points: Vec<Vector3<f64>> = frames[j + 1..]
        .iter()
        .map(|f| f.translation.vector)
        .collect();
    points.push(*tip);
    points
        .iter()
        .map(|p| ((p - o) / 1000.0).cross(weight).dot(&z))
        .collect()
}

/// The diagnosis candidate: gravity compliance of one joint.
#[derive(Debug, Clone)]
struct ComplianceCandidate {
    /// The joint (0-based).
    joint: usize,
    /// The rig's link masses, per joint (see [`rigcal_core::rig::Rig::link_masses`]); the mass
    /// model is used when every link from this joint on has one.
    masses: Masses,
}

impl ComplianceCandidate {
    /// The rig's masses when they cover every link from this joint on.
    fn known_masses(&self, n: usize) -> Option<&[Option<LinkMass>]> {
        let m = self.masses.as_deref()?;
        masses_cover(m, self.joint, n).then_some(m.as_slice())
    }

    /// The known-mass torque (N·m) at each measurement.
    fn mass_torques(&self, d: &Data, masses: &[Option<LinkMass>]) -> Vec<f64> {
        let ctx = EffectContext {
            chain: &d.chain,
            e: &d.e,
            masses,
            payload_kg: 0.0,
        };
        d.obs
            .iter()
            .map(|o| gravity_torque(&ctx, &o.q, self.joint))
            .collect()
    }

    /// The deflection (rad) of the generic model with coefficients `coef` at each measurement.
    fn deflections(&self, coef: &[f64], d: &Data) -> Vec<f64> {
        d.obs
            .iter()
            .map(|o| {
                unit_torques(d, &o.q, self.joint)
                    .iter()
                    .zip(coef)
                    .map(|(t, c)| t * c)
                    .sum()
            })
            .collect()
    }
}

impl Candidate for ComplianceCandidate {
    fn kind(&self) -> EffectKind {
        EffectKind::JointCompliance
    }

    fn index(&self) -> Index {
        Index::Joint(self.joint)
    }

    fn regressors(&self, d: &Data) -> Option<DMatrix<f64>> {
        if !d.moving.contains(&self.joint) {
            return None;
        }
        let torques: Vec<Vec<f64>> = match self.known_masses(d.chain.joints().len()) {
            Some(m) => self
                .mass_torques(d, m)
                .into_iter()
                .map(|t| vec![t])
                .collect(),
            None => d
                .obs
                .iter()
                .map(|o| unit_torques(d, &o.q, self.joint))
                .collect(),
        };
        // A joint whose axis is (nearly) vertical carries no gravity torque: its columns would be
        // numerical dust that column scaling blows up, so it is not a candidate.
        let max_torque = torques.iter().flatten().fold(0.0f64, |a, t| a.max(t.abs()));
        let max_lever_m = d
            .obs
            .iter()
            .map(|o| {
                let axis = d.chain.frame_before_joint(&o.q, &d.e, self.joint);
                (d.chain.position(&o.q, &d.e) - axis.translation.vector).norm() / 1000.0
            })
            .fold(0.0f64, f64::max);
        if max_torque < 0.01 * G * max_lever_m {
            return None;
        }
        let k = torques.first().map_or(0, Vec::len);
        let mut m = DMatrix::zeros(3 * d.len(), k);
        for (i, t) in torques.iter().enumerate() {
            for (c, tc) in t.iter().enumerate() {
                for r in 0..3 {
                    m[(3 * i + r, c)] = tc * d.joint_jacobian[i][(r, self.joint)];
                }
            }
        }
        Some(m)
    }

    fn explanation(&self) -> String {
        let base = format!(
            "joint {} deflects in proportion to the gravity torque it carries",
            self.joint + 1
        );
        if self
            .masses
            .as_deref()
            .is_some_and(|m| self.known_masses(m.len()).is_some())
        {
            format!("{base} (torque from the rig's link masses)")
        } else {
            format!("{base}; deg_per_nm is not available: the rig file gives no mass for every link from this joint on (mass_kg/com_mm, or a URDF with <inertial>), and positions alone cannot tell compliance from the mass it carries — reported are compliance × carried mass and the deflection")
        }
    }

    fn params(&self, coef: &[f64], cov: &DMatrix<f64>, d: &Data) -> Vec<Param> {
        let unit = |v: f64| match d.chain.joints()[self.joint].kind {
            JointKind::Revolute => v.to_degrees(),
            JointKind::Prismatic => v,
        };
        let (per_nm, times_mass) = match d.chain.joints()[self.joint].kind {
            JointKind::Revolute => ("deg_per_nm", "compliance_times_mass_deg_kg_per_nm"),
            JointKind::Prismatic => ("mm_per_n", "compliance_times_mass_mm_kg_per_n"),
        };
        let mut out = Vec::new();
        if let Some(m) = self.known_masses(d.chain.joints().len()) {
            let torques = self.mass_torques(d, m);
            out.push(Param {
                name: per_nm.into(),
                value: unit(coef[0]),
                sigma: unit(cov[(0, 0)].max(0.0).sqrt()),
            });
            let defl: Vec<f64> = torques.iter().map(|t| t * coef[0]).collect();
            let n = defl.len().max(1) as f64;
            out.push(Param {
                name: "deflection_rms_deg".into(),
                value: unit((defl.iter().map(|v| v * v).sum::<f64>() / n).sqrt()),
                sigma: f64::NAN,
            });
            return out;
        }
        let k = coef.len();
        let sum: f64 = coef.iter().sum();
        let var: f64 = (0..k)
            .flat_map(|a| (0..k).map(move |b| (a, b)))
            .map(|(a, b)| cov[(a, b)])
            .sum();
        out.push(Param {
            name: times_mass.into(),
            value: unit(sum),
            sigma: unit(var.max(0.0).sqrt()),
        });
        let defl = self.deflections(coef, d);
        let n = defl.len().max(1) as f64;
        let rms = (defl.iter().map(|v| v * v).sum::<f64>() / n).sqrt();
        let max = defl.iter().fold(0.0f64, |a, v| a.max(v.abs()));
        out.extend([
            Param {
                name: "deflection_rms_deg".into(),
                value: unit(rms),
                sigma: f64::NAN,
            },
            Param {
                name: "deflection_max_deg".into(),
                value: unit(max),
                sigma: f64::NAN,
            },
        ]);
        out
    }
}
