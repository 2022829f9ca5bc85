//! The variable D-H model from a recording in an instrument's own frame (a laser tracker's, a
//! motion-capture system's: the rig's `measurement_frame = "free"`), as on a real 6-DOF arm.
//!
//! Three things stop seed 000's division from working on such a recording as it is:
//! * **The frame is far from nominal.** A tracker stands metres away, turned any way; a region's
//!   fit started from the nominal parameters does not converge (on the UR10's Series A it stops
//!   at 33 mm RMS where the conventional fit reaches 0.44 mm).
//! * **The frame is no region's business.** Each region would fit its own measurement frame, a
//!   rigid transform that absorbs the region's local error; a held-out series measured from
//!   another tracker set-up refits the frame once for all its points and so throws every
//!   region's frame away, and with it part of every region's correction.
//! * **The workspace box is the joint limits.** A UR10's joints turn ±360°; the first split
//!   already halves empty space and a half with too few points stops the whole division.
//!
//! So the recording is first *registered*: the full conventional fit (frame and marker free,
//! the parameters the poses determine, [`identify_at`]) gives the measurement frame F; every
//! measured point is taken back into the rig's world frame (p_world = F⁻¹ · p_instrument) and
//! the division runs on a rig whose frame is fixed at the identity, so each region fits the
//! kinematic parameters (the base transform's among them, which the frame had absorbed) and
//! the marker. The division's box is the recording's extent in the division space. Afterwards
//! F is put back into the model as constant CEPs of every region and constant outputs of the
//! learner ([`Registration::restore`]), so the model predicts in the instrument's frame of
//! the training recording and a frame refit of another recording replaces exactly F.
//!
//! Units: internal (rad, mm) throughout; file units (deg, mm) only in the model's entries.

use nalgebra::Isometry3;
use rigcal_core::kinematics::{ErrorParams, ParamKind, Robot, SerialChain, TransformId};
use rigcal_core::recording::Observation;
use rigcal_core::rig::{FrameMode, Rig};
use rigcal_model::division::{Bounds, DivisionError, DivisionSpace, RegionNode, Space};
use rigcal_model::identification::{identify_at, Level};
use rigcal_model::learners::Learner;
use rigcal_model::model::{ModelBody, ModelFile, ParamEntry};

/// Which error parameters each region of a registered recording fits.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum RegionParams {
    /// Every parameter of the identifiable basis (seed 000's CEPs): on a 6-DOF arm the wrist
    /// joints' and the marker's too.
    #[default]
    All,
    /// Only those of the base and the positioning joints (the first three moving joints, the
    /// ones divided on); the wrist joints', the tool's and the marker's are held in every
    /// region at the conventional fit's values. Seed 000's arm has no wrist to speak of; on a
    /// 6-DOF arm a region sees only the wrist orientations its recording happened to take.
    Positioning,
}

/// A recording registered into the rig's world frame, and what puts its frame back.
#[derive(Debug, Clone)]
pub(crate) struct Registration {
    /// The rig the division runs on: the caller's with its measurement frame fixed at the
    /// identity (the marker stays as the caller's rig has it).
    pub rig: Rig,
    /// The measured points in the rig's world frame.
    pub observations: Vec<Observation>,
    /// The box divided: the recording's extent in the division space.
    pub bounds: Bounds,
    /// The measurement frame F of the conventional fit (world → instrument).
    pub frame: Isometry3<f64>,
    /// F's parameters, then those held at the conventional fit's values in every region
    /// ([`RegionParams::Positioning`]): layout index, value (internal units), σ (internal
    /// units).
    frame_params: Vec<(usize, f64, f64)>,
    /// RMS of the conventional fit that gave F (mm).
    pub fit_rms_mm: f64,
    /// Whether the regions fit only the base's and the positioning joints' parameters.
    holds_wrist: bool,
}

/// True when `rig`'s recordings are in an instrument frame the division must register first.
pub(crate) fn needs_registration(rig: &Rig) -> bool {
    rig.calibration.measurement_frame == FrameMode::Free
}

impl Registration {
    /// Registers `obs` (instrument frame) for a division of `rig` in `space`, each region to
    /// fit `params`.
    pub fn of(
        rig: &Rig,
        obs: &[Observation],
        space: Space,
        params: RegionParams,
    ) -> Result<Self, DivisionError> {
        let failed = |reason: String| {
            DivisionError::Root {
            measurements: obs.len(),
            reason: format!(
                "registering the instrument's frame by the conventional fit (frame and marker free) failed: {reason}"
            ),
        }
        };
        let (chain, fit) = identify_at(rig, obs, Level::Full).map_err(|e| failed(e.to_string()))?;
        let frame = chain.frame_pose(&fit.params);
        let layout = chain.layout();
        let sigma_of = |i: usize| {
            fit.free
                .iter()
                .position(|&f| f == i)
                .map_or(0.0, |k| fit.sigma[k])
        };
        let mut frame_params: Vec<(usize, f64, f64)> = layout
            .ids()
            .iter()
            .enumerate()
            .filter(|(_, id)| id.transform == TransformId::Frame)
            .map(|(i, _)| (i, fit.params.get(i), sigma_of(i)))
            .collect();
        let held: Vec<(usize, f64, f64)> = match params {
            RegionParams::All => Vec::new(),
            RegionParams::Positioning => fit
                .free
                .iter()
                .copied()
                .filter(|&i| !region_fits(rig, layout.ids()[i].transform))
                .filter(|&i| layout.ids()[i].transform != TransformId::Frame)
                .map(|i| (i, fit.params.get(i), sigma_of(i)))
                .collect(),
        };
        let back = frame.inverse();
        let observations: Vec<Observation> = obs
            .iter()
            .map(|o| Observation {
                q: o.q.clone(),
                p: back.transform_point(&o.p.into()).coords,
            })
            .collect();
        let mut fixed = rig.clone();
        fixed.calibration.measurement_frame = FrameMode::Fixed;
        fixed.chain = with_nominal(&chain, &held);
        frame_params.extend(held);
        let bounds = extent(&fixed, &observations, space).map_err(failed)?;
        Ok(Self {
            rig: fixed,
            observations,
            bounds,
            frame,
            frame_params,
            fit_rms_mm: fit.after.rms_mm,
            holds_wrist: params == RegionParams::Positioning,
        })
    }

    /// The parameters of `basis` (layout indices) each region fits: without those held at the
    /// conventional fit's values.
    pub fn region_basis(&self, basis: &[usize]) -> Vec<usize> {
        basis
            .iter()
            .copied()
            .filter(|i| self.frame_params.iter().all(|(h, _, _)| h != i))
            .filter(|&i| {
                let t = self.rig.chain.layout().ids()[i].transform;
                !self.holds_wrist || region_fits(&self.rig, t)
            })
            .collect()
    }

    /// What `rigcal calibrate` says about the registration (file units).
    pub fn text(&self, space: Space) -> String {
        let t = self.frame.translation.vector;
        let (r, p, y) = self.frame.rotation.euler_angles();
        let unit = |k: usize| match (space, k) {
            (Space::Cartesian, 0) => ("R", "mm", 1.0),
            (Space::Cartesian, 1) => ("azimuth", "°", 1f64.to_degrees()),
            (Space::Cartesian, _) => ("elevation", "°", 1f64.to_degrees()),
            (Space::Joint, k) => (["q1", "q2", "q3"][k], "°", 1f64.to_degrees()),
        };
        let extent: Vec<String> = (0..3)
            .map(|k| {
                let (name, u, s) = unit(k);
                format!(
                    "{name} {:.1}…{:.1} {u}",
                    self.bounds.lo[k] * s,
                    self.bounds.hi[k] * s
                )
            })
            .collect();
        format!(
            "instrument frame registered by the conventional fit ({:.4} mm RMS over {} points): t = ({:.2}, {:.2}, {:.2}) mm, rpy = ({:.4}, {:.4}, {:.4})°; regions are fitted in the rig's world frame with the frame held there, and it is put back as a constant of every region; divided box = the recording's extent: {}",
            self.fit_rms_mm,
            self.observations.len(),
            t.x,
            t.y,
            t.z,
            r.to_degrees(),
            p.to_degrees(),
            y.to_degrees(),
            extent.join(", ")
        )
    }

    /// Puts the frame F back into a model divided on the registered recording: F's parameters
    /// become constant CEPs of every region (appended to the basis), constant outputs of the
    /// learner, and entries of the conventional parameters.
    pub fn restore(&self, model: &mut ModelFile) {
        let layout = self.rig.chain.layout();
        let ModelBody::Variable {
            conventional,
            tree,
            learner,
            ..
        } = &mut model.model
        else {
            return;
        };
        let values: Vec<f64> = self.frame_params.iter().map(|&(_, v, _)| v).collect();
        for &(i, v, sigma) in &self.frame_params {
            let id = layout.ids()[i];
            tree.basis.push(layout.name(id));
            conventional.retain(|e| e.name != layout.name(id));
            conventional.push(ParamEntry {
                name: layout.name(id),
                value: id.kind.to_file_units(v),
                unit: id.kind.unit().to_string(),
                sigma: Some(id.kind.to_file_units(sigma)),
            });
        }
        append_to_tree(&mut tree.root, &values);
        let scaled: Vec<f64> = self
            .frame_params
            .iter()
            .map(|&(i, v, _)| learner_units(layout.ids()[i].kind, v))
            .collect();
        if let Some(l) = learner {
            append_constant_outputs(l, &scaled);
        }
    }
}

/// True for what a region fits with [`RegionParams::Positioning`]: the base transform, the
/// links of the rig's positioning joints (its first three moving joints, the ones a joint-space
/// division divides on), and the tool transform (which [`with_nominal`] cannot hold; its
/// position is the marker's on a tracker rig, so it is rarely in a basis).
fn region_fits(rig: &Rig, t: TransformId) -> bool {
    match t {
        TransformId::Base | TransformId::Tool => true,
        TransformId::Link(j) => rig.moving_joints().iter().take(3).any(|&m| m + 1 == j),
        _ => false,
    }
}

/// `chain` with each parameter of `held` (layout index, value) added to its nominal value:
/// every parameter enters the chain as nominal + error of one elementary motion, so this is
/// exact. `held` holds link and marker parameters only ([`region_fits`]).
fn with_nominal(chain: &SerialChain, held: &[(usize, f64, f64)]) -> SerialChain {
    let layout = chain.layout();
    let mut links = chain.links().to_vec();
    let nominal = ErrorParams::zeros(layout);
    let q0 = vec![0.0; chain.joints().len()];
    // The marker's nominal point in the tool frame (the chain gives no getter for it).
    let tool = chain.tool_pose(&q0, &nominal);
    let mut marker = tool
        .inverse_transform_point(&chain.position(&q0, &nominal).into())
        .coords;
    for &(i, v, _) in held {
        let id = layout.ids()[i];
        match (id.transform, id.kind) {
            (TransformId::Link(j), kind) => {
                let l = &mut links[j - 1];
                match kind {
                    ParamKind::Theta => l.theta += v,
                    ParamKind::D => l.d += v,
                    ParamKind::A => l.a += v,
                    ParamKind::Alpha => l.alpha += v,
                    ParamKind::Beta => l.beta += v,
                    _ => {}
                }
            }
            (TransformId::Marker, ParamKind::X) => marker.x += v,
            (TransformId::Marker, ParamKind::Y) => marker.y += v,
            (TransformId::Marker, ParamKind::Z) => marker.z += v,
            _ => {}
        }
    }
    SerialChain::new(
        chain.joints().to_vec(),
        chain.base().clone(),
        links,
        chain.tool().clone(),
        *chain.frame(),
        marker,
    )
}

/// The value of a parameter as the learners hold it ([`rigcal_model::model::cep_scale`]: angles
/// in degrees, lengths in mm).
fn learner_units(kind: ParamKind, v: f64) -> f64 {
    if kind.is_angle() {
        v.to_degrees()
    } else {
        v
    }
}

/// Appends `values` to the CEPs (and the learner's CEPs) of every region below `node`.
fn append_to_tree(node: &mut RegionNode, values: &[f64]) {
    if let Some(c) = &mut node.cep {
        c.extend_from_slice(values);
    }
    if let Some(c) = &mut node.learner_cep {
        c.extend_from_slice(values);
    }
    for child in &mut node.children {
        append_to_tree(child, values);
    }
}

/// Adds outputs that answer `values` everywhere: every association cell's weights for them
/// are the values. Both learners answer a membership-weighted *mean* of their excited cells'
/// weights (the FCMAC's (A4) divides by the summed membership, the CMAC by its layer count), so
/// equal weights give the value exactly, wherever the input.
fn append_constant_outputs(learner: &mut Learner, values: &[f64]) {
    let (outputs, weights) = match learner {
        Learner::Fcmac(f) => (&mut f.outputs, &mut f.weights),
        Learner::Cmac(c) => (&mut c.outputs, &mut c.weights),
    };
    let old = *outputs;
    let cells = weights.len() / old.max(1);
    let mut out = Vec::with_capacity(cells * (old + values.len()));
    for cell in weights.chunks(old.max(1)).take(cells) {
        out.extend_from_slice(cell);
        out.extend_from_slice(values);
    }
    *weights = out;
    *outputs = old + values.len();
}

/// The recording's extent in the division space of `rig` (a box no narrower than 1° or 1 mm in
/// any dimension, so every dimension can be split).
fn extent(rig: &Rig, obs: &[Observation], space: Space) -> Result<Bounds, String> {
    let s = DivisionSpace::new(rig, space).map_err(|e| e.to_string())?;
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for o in obs {
        let x = s.coords(&o.q);
        for k in 0..3 {
            lo[k] = lo[k].min(x[k]);
            hi[k] = hi[k].max(x[k]);
        }
    }
    let least = |k: usize| match (space, k) {
        (Space::Cartesian, 0) => 1.0,
        _ => 1f64.to_radians(),
    };
    for k in 0..3 {
        let w = least(k);
        if hi[k] - lo[k] < w {
            let mid = 0.5 * (hi[k] + lo[k]);
            lo[k] = mid - 0.5 * w;
            hi[k] = mid + 0.5 * w;
        }
    }
    Ok(Bounds { lo, hi })
}

#[cfg(test)]
#[allow(clippy::unwrap_used)] // a failing test says where
mod tests {
    use super::*;
    use rigcal_model::learners::{Fcmac, FcmacConfig};

    /// The chain with held wrist and marker parameters baked into its nominal values predicts,
    /// with no errors, what the original chain predicts with those errors.
    #[test]
    fn held_parameters_baked_into_the_chain_are_exact() {
        let rig = rigcal_core::rig::Rig::load(std::path::Path::new(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../rigs/rv-m2-ideal.toml"
        )))
        .unwrap();
        let chain = &rig.chain;
        let layout = chain.layout();
        let mut e = ErrorParams::zeros(layout);
        let mut held = Vec::new();
        for (i, id) in layout.ids().iter().enumerate() {
            let wrist = matches!(id.transform, TransformId::Link(j) if j > 3);
            if wrist || id.transform == TransformId::Marker {
                let v = 0.3 + 0.01 * i as f64;
                e.set(i, v);
                held.push((i, v, 0.0));
            }
        }
        assert!(held.len() > 5, "the rig has wrist and marker parameters");
        let baked = with_nominal(chain, &held);
        let zero = ErrorParams::zeros(layout);
        for k in 0..8 {
            let q: Vec<f64> = (0..chain.joints().len())
                .map(|j| (0.7 * k as f64 + 0.3 * j as f64).sin())
                .collect();
            let d = (baked.position(&q, &zero) - chain.position(&q, &e)).norm();
            assert!(d < 1e-9, "{d} mm at {q:?}");
        }
    }

    /// An FCMAC given constant outputs answers them exactly, and its old outputs unchanged.
    #[test]
    fn constant_outputs_are_exact_and_keep_the_others() {
        let range = Bounds {
            lo: [0.0, -1.0, 2.0],
            hi: [1.0, 1.0, 3.0],
        };
        let mut f = Fcmac::new(FcmacConfig::paper(0), range, &[0.0, 0.0]);
        // Different weights per cell, so the old outputs vary with the input.
        for (k, w) in f.weights.iter_mut().enumerate() {
            *w = (k as f64 * 0.37).sin();
        }
        let at = [[0.3, 0.2, 2.5], [0.95, -0.8, 2.1], [0.0, 1.0, 3.0]];
        let before: Vec<Vec<f64>> = at.iter().map(|x| f.predict(x)).collect();
        let mut l = Learner::Fcmac(f);
        append_constant_outputs(&mut l, &[12.5, -3.25, 170.0]);
        for (x, b) in at.iter().zip(&before) {
            let y = l.predict(x);
            assert_eq!(y.len(), 5);
            assert!((y[0] - b[0]).abs() < 1e-12 && (y[1] - b[1]).abs() < 1e-12);
            for (got, want) in y[2..].iter().zip([12.5, -3.25, 170.0]) {
                assert!((got - want).abs() < 1e-9, "{got} against {want}");
            }
        }
    }
}
