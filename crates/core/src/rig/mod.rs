//! Rig files: a robot's kinematic chain, its joint limits, how it is calibrated and what measures
//! it. TOML, millimetres and degrees, unknown keys rejected. Parsed raw, then validated into a
//! [`Rig`]; every error names the file and the key.
//!
//! ```toml
//! name = "rv-m2"
//! [robot]
//! name = "Mitsubishi RV-M2"
//! base = { theta_deg = 90, d_mm = 400, a_mm = -80, alpha_deg = 180, beta_deg = 0 }
//! tool = { a_mm = 170 }                       # or xyz_mm + rpy_deg, or matrix (4x4, mm)
//! payload = { kg = 0.4, com_mm = [0, 0, 30] }  # carried while recorded, in the tool frame
//! [[robot.joints]]
//! name = "J1"
//! type = "revolute"                          # or "prismatic" (limits_mm)
//! a_mm = 120
//! alpha_deg = -90
//! limits_deg = [-150, 150]
//! [calibration]
//! held_joints = { J4 = 0, J5 = 0 }           # joints not moved while calibrating
//! basis_priority = ["theta0", "a0"]          # preferred identifiable basis, in order
//! measurement_frame = "fixed"                # "free" for an outside tracker
//! marker = "fixed"
//! max_angle_correction_deg = 90              # a fit beyond these is refused as diverged
//! max_length_correction_mm = 130             # (defaults: 90°, a tenth of the reach)
//! [instrument]
//! kind = "ideal"                             # "table_panel" or "tracker"
//! ```
//!
//! Every length is finite and at most [`MAX_LENGTH_MM`] (100 m) in size: nothing larger is an
//! arm, and values near the float range would make every later computation overflow (an SVD
//! of infinities never ends). A `nest_deg` in `[devices.arm]` with one value per joint must lie
//! within the joint limits: the arm stands there after homing.
//!
//! The `[devices]` section (how each device is reached, and the numbers its driver, emulator
//! and the session's procedures need) is kept as written; the devices layer reads it
//! (`rigcal_devices::config::DevicesConfig::of_rig`).

use crate::kinematics::{JointKind, JointSpec, LinkParams, ParamId, SerialChain, Transform};
use nalgebra::{Isometry3, Matrix3, Rotation3, Translation3, UnitQuaternion, Vector3};
use serde::Deserialize;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// What went wrong with a rig file.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum RigError {
    /// The file could not be read.
    #[error("cannot read rig file {path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// The file is not valid TOML or has an unknown, missing or mistyped key.
    #[error("rig file {path}: {message}")]
    Parse {
        /// The file.
        path: PathBuf,
        /// The parser's message, with line and column.
        message: String,
    },
    /// A value is out of range or inconsistent.
    #[error("rig file {path}: `{key}`: {reason}")]
    Invalid {
        /// The file.
        path: PathBuf,
        /// The key, as a TOML path.
        key: String,
        /// What is wrong and what is expected.
        reason: String,
    },
}

/// Why a pose cannot be measured on a rig.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum Unmeasurable {
    /// A joint is outside its limits.
    #[error("joint {joint} is outside its limits")]
    JointLimit {
        /// Joint number (1-based).
        joint: usize,
    },
    /// The pin meets the panel too flat (or from below).
    #[error(
        "the pin meets the panel at {angle_deg:.1}°, less than the {min_deg:.0}° a contact needs"
    )]
    PinAngle {
        /// Angle between pin and panel plane (deg; negative when pointing up).
        angle_deg: f64,
        /// The rig's minimum (deg).
        min_deg: f64,
    },
    /// The table cannot bring the panel there.
    #[error(
        "table {axis} would need {position_mm:.1} mm, outside its travel 0..{travel_mm:.0} mm"
    )]
    TableTravel {
        /// Axis.
        axis: char,
        /// Needed position (mm).
        position_mm: f64,
        /// Travel (mm).
        travel_mm: f64,
    },
}

/// Whether a measurement frame (or marker) is known and held, or fitted.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, serde::Serialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum FrameMode {
    /// Known (a registration was applied); held at its nominal value.
    #[default]
    Fixed,
    /// Unknown; fitted with the kinematic parameters that stay identifiable after it.
    Free,
}

/// How the robot is calibrated.
#[derive(Debug, Clone, PartialEq)]
pub struct CalibrationSettings {
    /// Per joint: `Some(value)` (internal units) when the joint is held during calibration.
    pub held: Vec<Option<f64>>,
    /// Preferred identifiable basis, in order.
    pub basis_priority: Vec<ParamId>,
    /// The measurement frame.
    pub measurement_frame: FrameMode,
    /// The marker point.
    pub marker: FrameMode,
    /// Largest angle correction (rad) a fit may give a kinematic parameter before it is
    /// refused as diverged (`max_angle_correction_deg`, default [`DEFAULT_MAX_ANGLE_CORRECTION_DEG`]).
    pub max_angle_correction: f64,
    /// Largest length correction (mm) a fit may give a kinematic or marker parameter before it
    /// is refused as diverged (`max_length_correction_mm`, default
    /// [`DEFAULT_LENGTH_CORRECTION_SHARE`] of the reach).
    pub max_length_correction_mm: f64,
}

/// The largest length (mm) a rig file may state: 100 m. Nothing larger is an arm or a table,
/// and lengths near the float range overflow every later computation.
pub const MAX_LENGTH_MM: f64 = 100_000.0;

/// Default largest angle correction of a fit (deg): a quarter turn. Joint offsets and twists of
/// a built arm are off by hundredths to tenths of a degree, yet a parameter the data barely
/// determine may move far (the TIAGo Pro's wrist offset fits at +50° with a free marker); a
/// fit that describes a joint half a turn round (θ ±180° with its link negated) or a full turn
/// (360°), or one that chased a gross row, is beyond it.
pub const DEFAULT_MAX_ANGLE_CORRECTION_DEG: f64 = 90.0;

/// Default largest length correction of a fit, as a share of the arm's reach
/// ([`Rig::reach_mm`]): a tenth (about 130 mm on the RV-M2, whose errors are tenths of a mm).
pub const DEFAULT_LENGTH_CORRECTION_SHARE: f64 = 0.1;

/// The x-y-z table with the touch panel on its z arm (seed 000 section 7).
#[derive(Debug, Clone, PartialEq)]
pub struct TablePanel {
    /// Travel of each table axis from its zero (mm).
    pub travel_mm: Vector3<f64>,
    /// Nominal registration: world = table + this (mm).
    pub table_to_world_mm: Vector3<f64>,
    /// Positioning accuracy of each axis (mm, 1σ).
    pub accuracy_mm: f64,
    /// Effective panel area (u along table x, v along table y), mm.
    pub panel_size_mm: [f64; 2],
    /// Panel counts over that area.
    pub panel_counts: [u32; 2],
    /// Smallest angle between pin and panel plane for a valid contact (rad).
    pub min_pin_angle: f64,
    /// The pin's direction in the tool frame (unit).
    pub pin_axis: Vector3<f64>,
}

/// What measures the robot.
#[derive(Debug, Clone, PartialEq)]
pub enum Instrument {
    /// Measures anywhere in the joint limits, exactly (the papers' simulations).
    Ideal,
    /// The table and touch panel of the RV-M2 rig.
    TablePanel(TablePanel),
    /// A laser tracker or motion capture: a marker seen in the tracker's own frame.
    Tracker,
}

/// The original text of a rig file, kept so a model file can carry the rig it was fitted on.
#[derive(Debug, Clone, PartialEq)]
pub struct RigSource {
    /// Where it was read from, when it was a file.
    pub path: Option<PathBuf>,
    /// The TOML text.
    pub text: String,
}

/// A validated rig.
#[derive(Debug, Clone)]
pub struct Rig {
    /// Short name (`rv-m2`).
    pub name: String,
    /// Free text.
    pub description: String,
    /// The robot's name.
    pub robot_name: String,
    /// The kinematic chain with its nominal values.
    pub chain: SerialChain,
    /// How it is calibrated.
    pub calibration: CalibrationSettings,
    /// What measures it.
    pub instrument: Instrument,
    /// Workspace bounds for division in spherical coordinates (R mm, azimuth rad, elevation rad),
    /// when the rig file states them.
    pub spherical_bounds: Option<[[f64; 2]; 3]>,
    /// How the devices are reached (`[devices]`), when the rig file says: the section as
    /// written, read and checked by the devices layer (`rigcal_devices::config`), which alone
    /// knows the drivers' settings.
    pub devices: Option<toml::Table>,
    /// The file it came from.
    pub source: RigSource,
    /// Per joint, the mass of the link it moves and its centre of mass, when the rig file
    /// states them (`mass_kg`, `com_mm` in `[[robot.joints]]`; `rig from-urdf` fills them from
    /// the URDF's `<inertial>`).
    pub link_masses: Vec<Option<LinkMass>>,
    /// What the arm carries at the tool while it is recorded (`payload` in `[robot]`: a
    /// tracker's reflector and its adapter, a gripper), its centre of mass in the tool frame;
    /// None when the rig file states none. It loads every joint's gravity torque.
    pub payload: Option<LinkMass>,
}

impl Rig {
    /// The link masses with the payload added to the last link's (their combined mass at
    /// their combined centre, both in the tool frame): gravity torques are linear in mass ×
    /// position, so the combination loads every joint exactly as the two do. The last link
    /// must have a mass of its own for the combination (else the links' masses stay as they
    /// are: a model that knows the payload but not the link it sits on knows too little).
    pub fn masses_with_payload(&self) -> Vec<Option<LinkMass>> {
        let mut m = self.link_masses.clone();
        if let (Some(p), Some(Some(last))) = (self.payload, m.last_mut()) {
            let kg = last.kg + p.kg;
            if kg > 0.0 {
                last.com_mm = (last.com_mm * last.kg + p.com_mm * p.kg) / kg;
                last.kg = kg;
            }
        }
        m
    }
}

/// A link's mass and centre of mass.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LinkMass {
    /// Mass (kg).
    pub kg: f64,
    /// Centre of mass in the frame at the end of the link (mm): the frame of the next joint's
    /// axis ([`SerialChain::frame_before_joint`] of the next joint), the tool frame for the last
    /// link.
    pub com_mm: Vector3<f64>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawRig {
    name: String,
    #[serde(default)]
    description: String,
    robot: RawRobot,
    #[serde(default)]
    calibration: RawCalibration,
    #[serde(default)]
    instrument: RawInstrument,
    #[serde(default)]
    workspace: RawWorkspace,
    #[serde(default)]
    devices: Option<toml::Table>,
}

#[derive(Debug, Deserialize, Default)]
#[serde(deny_unknown_fields)]
struct RawWorkspace {
    r_mm: Option<[f64; 2]>,
    azimuth_deg: Option<[f64; 2]>,
    elevation_deg: Option<[f64; 2]>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawRobot {
    #[serde(default)]
    name: String,
    base: RawFixed,
    joints: Vec<RawJoint>,
    tool: RawFixed,
    #[serde(default)]
    marker_mm: Option<[f64; 3]>,
    /// What the arm carries at the tool while recorded.
    #[serde(default)]
    payload: Option<RawPayload>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawPayload {
    kg: f64,
    /// In the tool frame (mm); the tool frame's origin when absent.
    #[serde(default)]
    com_mm: Option<[f64; 3]>,
}

#[derive(Debug, Deserialize, Default)]
#[serde(deny_unknown_fields)]
struct RawFixed {
    theta_deg: Option<f64>,
    d_mm: Option<f64>,
    a_mm: Option<f64>,
    alpha_deg: Option<f64>,
    beta_deg: Option<f64>,
    xyz_mm: Option<[f64; 3]>,
    rpy_deg: Option<[f64; 3]>,
    matrix: Option<[[f64; 4]; 4]>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawJoint {
    name: String,
    #[serde(rename = "type")]
    kind: JointKind,
    #[serde(default)]
    theta_deg: f64,
    #[serde(default)]
    d_mm: f64,
    #[serde(default)]
    a_mm: f64,
    #[serde(default)]
    alpha_deg: f64,
    #[serde(default)]
    beta_deg: f64,
    limits_deg: Option<[f64; 2]>,
    limits_mm: Option<[f64; 2]>,
    /// Mass of the link this joint moves (kg), optional.
    #[serde(default)]
    mass_kg: Option<f64>,
    /// Its centre of mass in the frame at the end of the link (the next joint's axis frame, or
    /// the tool frame for the last joint), mm; needs `mass_kg`.
    #[serde(default)]
    com_mm: Option<[f64; 3]>,
}

#[derive(Debug, Deserialize, Default)]
#[serde(deny_unknown_fields)]
struct RawCalibration {
    #[serde(default)]
    held_joints: BTreeMap<String, f64>,
    #[serde(default)]
    basis_priority: Vec<String>,
    #[serde(default)]
    measurement_frame: FrameMode,
    #[serde(default)]
    marker: FrameMode,
    #[serde(default)]
    max_angle_correction_deg: Option<f64>,
    #[serde(default)]
    max_length_correction_mm: Option<f64>,
}

#[derive(Debug, Deserialize, Default, Clone, Copy, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
enum RawInstrumentKind {
    #[default]
    Ideal,
    TablePanel,
    Tracker,
}

#[derive(Debug, Deserialize, Default)]
#[serde(deny_unknown_fields)]
struct RawInstrument {
    #[serde(default)]
    kind: RawInstrumentKind,
    table_travel_mm: Option<[f64; 3]>,
    table_to_world_mm: Option<[f64; 3]>,
    table_accuracy_mm: Option<f64>,
    panel_size_mm: Option<[f64; 2]>,
    panel_counts: Option<[u32; 2]>,
    min_pin_angle_deg: Option<f64>,
    pin_axis: Option<[f64; 3]>,
}

impl Rig {
    /// Reads and validates a rig file.
    pub fn load(path: &Path) -> Result<Rig, RigError> {
        let text = std::fs::read_to_string(path).map_err(|source| RigError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        Self::parse(&text, Some(path))
    }

    /// Parses and validates rig text; `path` names it in errors.
    pub fn parse(text: &str, path: Option<&Path>) -> Result<Rig, RigError> {
        let shown = path
            .map(Path::to_path_buf)
            .unwrap_or_else(|| PathBuf::from("<rig>"));
        let raw: RawRig = toml::from_str(text).map_err(|e| RigError::Parse {
            path: shown.clone(),
            message: e.to_string().trim_end().to_string(),
        })?;
        let v = Validator { path: shown };
        let mut rig = v.rig(raw)?;
        rig.source = RigSource {
            path: path.map(Path::to_path_buf),
            text: text.to_string(),
        };
        Ok(rig)
    }

    /// The joints held during calibration, as `Some(value)` per joint.
    pub fn held(&self) -> &[Option<f64>] {
        &self.calibration.held
    }

    /// Whether the instrument can measure the arm at joint values `q` with the nominal
    /// kinematics: within the joint limits, and for the table-and-panel rig, within the table's
    /// travel and with the pin at least the minimum angle to the panel plane.
    pub fn measurable(&self, q: &[f64]) -> Result<(), Unmeasurable> {
        use crate::kinematics::{ErrorParams, Robot};
        for (j, (spec, v)) in self.chain.joints().iter().zip(q).enumerate() {
            if !spec.within(*v) {
                return Err(Unmeasurable::JointLimit { joint: j + 1 });
            }
        }
        let Instrument::TablePanel(t) = &self.instrument else {
            return Ok(());
        };
        let e = ErrorParams::zeros(self.chain.layout());
        let pose = self.chain.tool_pose(q, &e);
        let pin = pose.rotation * t.pin_axis;
        if pin.z > -t.min_pin_angle.sin() {
            return Err(Unmeasurable::PinAngle {
                angle_deg: (-pin.z).clamp(-1.0, 1.0).asin().to_degrees(),
                min_deg: t.min_pin_angle.to_degrees(),
            });
        }
        let tip = self.chain.position(q, &e);
        let table = tip - t.table_to_world_mm;
        for k in 0..3 {
            if table[k] < 0.0 || table[k] > t.travel_mm[k] {
                return Err(Unmeasurable::TableTravel {
                    axis: ['x', 'y', 'z'][k],
                    position_mm: table[k],
                    travel_mm: t.travel_mm[k],
                });
            }
        }
        Ok(())
    }

    /// An upper bound on the distance (mm) of the measured point from the world origin over
    /// every pose: the sum of the chain's translations (base, links with their prismatic
    /// travel, tool, marker). The scale against which absurd values are judged.
    pub fn reach_mm(&self) -> f64 {
        chain_reach_mm(&self.chain)
    }

    /// The joints that move during calibration (0-based).
    pub fn moving_joints(&self) -> Vec<usize> {
        (0..self.calibration.held.len())
            .filter(|&j| self.calibration.held[j].is_none())
            .collect()
    }
}

/// [`Rig::reach_mm`] of a chain.
pub fn chain_reach_mm(chain: &SerialChain) -> f64 {
    use crate::kinematics::{ErrorParams, Robot};
    let transform = |t: &Transform| match t {
        Transform::FivePar(l) => l.a.abs() + l.d.abs(),
        Transform::Pose(p) => p.translation.vector.norm(),
    };
    let links: f64 = chain
        .links()
        .iter()
        .zip(chain.joints())
        .map(|(l, j)| {
            let travel = match j.kind {
                JointKind::Prismatic => j.min.abs().max(j.max.abs()),
                JointKind::Revolute => 0.0,
            };
            l.a.abs() + l.d.abs() + travel
        })
        .sum();
    // The marker in the tool frame: the measured point seen from the tool pose.
    let e = ErrorParams::zeros(chain.layout());
    let q = vec![0.0; chain.dof()];
    let marker = (chain.tool_pose(&q, &e).inverse()
        * nalgebra::Point3::from(chain.position(&q, &e)))
    .coords
    .norm();
    chain.frame().translation.vector.norm()
        + transform(chain.base())
        + links
        + transform(chain.tool())
        + marker
}

struct Validator {
    path: PathBuf,
}

impl Validator {
    fn invalid(&self, key: impl Into<String>, reason: impl Into<String>) -> RigError {
        RigError::Invalid {
            path: self.path.clone(),
            key: key.into(),
            reason: reason.into(),
        }
    }

    fn finite(&self, key: &str, v: f64) -> Result<f64, RigError> {
        if v.is_finite() {
            Ok(v)
        } else {
            Err(self.invalid(key, "must be a finite number"))
        }
    }

    /// A finite length within [`MAX_LENGTH_MM`].
    fn length(&self, key: &str, v: f64) -> Result<f64, RigError> {
        self.finite(key, v)?;
        if v.abs() > MAX_LENGTH_MM {
            return Err(self.invalid(
                key,
                format!(
                    "{v:e} mm is beyond the {MAX_LENGTH_MM:.0} mm (100 m) any arm or table spans: check the value and its unit (millimetres)"
                ),
            ));
        }
        Ok(v)
    }

    fn rig(&self, raw: RawRig) -> Result<Rig, RigError> {
        if raw.name.trim().is_empty() {
            return Err(self.invalid("name", "must not be empty"));
        }
        if raw.robot.joints.is_empty() {
            return Err(self.invalid("robot.joints", "the chain needs at least one joint"));
        }
        let base = self.fixed("robot.base", &raw.robot.base)?;
        let tool = self.fixed("robot.tool", &raw.robot.tool)?;
        let mut joints = Vec::new();
        let mut links = Vec::new();
        let mut link_masses = Vec::new();
        for (i, j) in raw.robot.joints.iter().enumerate() {
            link_masses.push(self.link_mass(i, j)?);
            let (spec, link) = self.joint(i, j)?;
            if joints.iter().any(|s: &JointSpec| s.name == spec.name) {
                return Err(self.invalid(
                    format!("robot.joints[{i}].name"),
                    format!("joint name `{}` is used twice", spec.name),
                ));
            }
            joints.push(spec);
            links.push(link);
        }
        let marker = match raw.robot.marker_mm {
            Some(m) => {
                for (k, v) in m.iter().enumerate() {
                    self.length(&format!("robot.marker_mm[{k}]"), *v)?;
                }
                Vector3::from(m)
            }
            None => Vector3::zeros(),
        };
        let chain = SerialChain::new(joints, base, links, tool, Isometry3::identity(), marker);
        self.nest_pose(raw.devices.as_ref(), &chain)?;
        let calibration = self.calibration(&raw.calibration, &chain)?;
        let instrument = self.instrument(&raw.instrument)?;
        let spherical_bounds = self.workspace(&raw.workspace)?;
        Ok(Rig {
            name: raw.name,
            description: raw.description,
            robot_name: raw.robot.name,
            chain,
            calibration,
            instrument,
            spherical_bounds,
            devices: raw.devices,
            source: RigSource {
                path: None,
                text: String::new(),
            },
            link_masses,
            payload: self.payload(raw.robot.payload.as_ref())?,
        })
    }

    fn payload(&self, raw: Option<&RawPayload>) -> Result<Option<LinkMass>, RigError> {
        let Some(p) = raw else {
            return Ok(None);
        };
        if !(p.kg.is_finite() && p.kg >= 0.0) {
            return Err(self.invalid("robot.payload.kg", "must be a finite mass ≥ 0 (kg)"));
        }
        let c = p.com_mm.unwrap_or([0.0; 3]);
        for v in c {
            self.length("robot.payload.com_mm", v)?;
        }
        Ok(Some(LinkMass {
            kg: p.kg,
            com_mm: Vector3::from(c),
        }))
    }

    fn link_mass(&self, i: usize, j: &RawJoint) -> Result<Option<LinkMass>, RigError> {
        let key = |k: &str| format!("robot.joints[{i}].{k}");
        match (j.mass_kg, j.com_mm) {
            (None, None) => Ok(None),
            (None, Some(_)) => Err(self.invalid(key("com_mm"), "needs `mass_kg` beside it")),
            (Some(kg), com) => {
                if !(kg.is_finite() && kg >= 0.0) {
                    return Err(self.invalid(key("mass_kg"), "must be a finite mass ≥ 0"));
                }
                let c = com.unwrap_or([0.0; 3]);
                for v in c {
                    self.length(&key("com_mm"), v)?;
                }
                Ok(Some(LinkMass {
                    kg,
                    com_mm: Vector3::from(c),
                }))
            }
        }
    }

    fn joint(&self, i: usize, j: &RawJoint) -> Result<(JointSpec, LinkParams), RigError> {
        let key = |k: &str| format!("robot.joints[{i}].{k}");
        let link = LinkParams {
            theta: self.finite(&key("theta_deg"), j.theta_deg)?.to_radians(),
            d: self.length(&key("d_mm"), j.d_mm)?,
            a: self.length(&key("a_mm"), j.a_mm)?,
            alpha: self.finite(&key("alpha_deg"), j.alpha_deg)?.to_radians(),
            beta: self.finite(&key("beta_deg"), j.beta_deg)?.to_radians(),
        };
        let (limits, field) = match (j.kind, j.limits_deg, j.limits_mm) {
            (JointKind::Revolute, Some(l), None) => {
                ([l[0].to_radians(), l[1].to_radians()], "limits_deg")
            }
            (JointKind::Prismatic, None, Some(l)) => (l, "limits_mm"),
            (JointKind::Revolute, _, _) => {
                return Err(self.invalid(
                    key("limits_deg"),
                    "a revolute joint needs `limits_deg = [min, max]` (and no limits_mm)",
                ));
            }
            (JointKind::Prismatic, _, _) => {
                return Err(self.invalid(
                    key("limits_mm"),
                    "a prismatic joint needs `limits_mm = [min, max]` (and no limits_deg)",
                ));
            }
        };
        if !(limits[0].is_finite() && limits[1].is_finite() && limits[0] < limits[1]) {
            return Err(self.invalid(key(field), "needs finite [min, max] with min < max"));
        }
        if j.kind == JointKind::Prismatic {
            for v in limits {
                self.length(&key(field), v)?;
            }
        }
        if j.name.trim().is_empty() {
            return Err(self.invalid(key("name"), "must not be empty"));
        }
        Ok((
            JointSpec {
                name: j.name.clone(),
                kind: j.kind,
                min: limits[0],
                max: limits[1],
            },
            link,
        ))
    }

    fn fixed(&self, key: &str, f: &RawFixed) -> Result<Transform, RigError> {
        let five = [f.theta_deg, f.d_mm, f.a_mm, f.alpha_deg, f.beta_deg]
            .iter()
            .any(Option::is_some);
        let pose = f.xyz_mm.is_some() || f.rpy_deg.is_some();
        let matrix = f.matrix.is_some();
        match (five, pose, matrix) {
            (_, false, false) => {
                let g = |v: Option<f64>, k: &str| self.finite(&format!("{key}.{k}"), v.unwrap_or(0.0));
                let l = |v: Option<f64>, k: &str| self.length(&format!("{key}.{k}"), v.unwrap_or(0.0));
                Ok(Transform::FivePar(LinkParams {
                    theta: g(f.theta_deg, "theta_deg")?.to_radians(),
                    d: l(f.d_mm, "d_mm")?,
                    a: l(f.a_mm, "a_mm")?,
                    alpha: g(f.alpha_deg, "alpha_deg")?.to_radians(),
                    beta: g(f.beta_deg, "beta_deg")?.to_radians(),
                }))
            }
            (false, true, false) => {
                let xyz = f.xyz_mm.unwrap_or([0.0; 3]);
                let rpy = f.rpy_deg.unwrap_or([0.0; 3]);
                if xyz.iter().chain(&rpy).any(|v| !v.is_finite()) {
                    return Err(self.invalid(key, "xyz_mm and rpy_deg must be finite"));
                }
                for v in xyz {
                    self.length(&format!("{key}.xyz_mm"), v)?;
                }
                Ok(Transform::Pose(pose_from_xyz_rpy(xyz, rpy)))
            }
            (false, false, true) => {
                let m = f.matrix.unwrap_or_default();
                self.matrix_pose(&format!("{key}.matrix"), &m).map(Transform::Pose)
            }
            _ => Err(self.invalid(
                key,
                "give exactly one form: five parameters (theta_deg d_mm a_mm alpha_deg beta_deg), xyz_mm + rpy_deg, or matrix",
            )),
        }
    }

    fn matrix_pose(&self, key: &str, m: &[[f64; 4]; 4]) -> Result<Isometry3<f64>, RigError> {
        if m.iter().flatten().any(|v| !v.is_finite()) {
            return Err(self.invalid(key, "must hold finite numbers"));
        }
        for row in &m[..3] {
            self.length(key, row[3])?;
        }
        if m[3] != [0.0, 0.0, 0.0, 1.0] {
            return Err(self.invalid(
                key,
                "the last row of a homogeneous transform must be [0, 0, 0, 1]",
            ));
        }
        let r = Matrix3::from_fn(|i, j| m[i][j]);
        let err = (r.transpose() * r - Matrix3::identity()).abs().max();
        if err > 1e-6 || r.determinant() < 0.0 {
            return Err(self.invalid(
                key,
                format!(
                    "the rotation part is not a proper rotation (orthonormality error {err:.1e})"
                ),
            ));
        }
        // Read straight off the orthonormal columns: `UnitQuaternion::from_matrix` iterates from
        // the identity and stalls short of a half turn (a frame turned 180° came out slightly off).
        let rot = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(r));
        Ok(Isometry3::from_parts(
            Translation3::new(m[0][3], m[1][3], m[2][3]),
            rot,
        ))
    }

    fn calibration(
        &self,
        c: &RawCalibration,
        chain: &SerialChain,
    ) -> Result<CalibrationSettings, RigError> {
        use crate::kinematics::Robot;
        let joints = chain.joints();
        let mut held = vec![None; joints.len()];
        for (name, v) in &c.held_joints {
            let Some(j) = joints.iter().position(|s| &s.name == name) else {
                let names: Vec<&str> = joints.iter().map(|s| s.name.as_str()).collect();
                return Err(self.invalid(
                    format!("calibration.held_joints.{name}"),
                    format!("no joint of that name; joints are {}", names.join(", ")),
                ));
            };
            let value = joints[j]
                .kind
                .from_file_units(self.finite(&format!("calibration.held_joints.{name}"), *v)?);
            if !joints[j].within(value) {
                return Err(self.invalid(
                    format!("calibration.held_joints.{name}"),
                    "outside the joint's limits",
                ));
            }
            held[j] = Some(value);
        }
        if held.iter().all(Option::is_some) {
            return Err(self.invalid(
                "calibration.held_joints",
                "every joint is held: at least one must move",
            ));
        }
        let mut basis_priority = Vec::new();
        for (k, name) in c.basis_priority.iter().enumerate() {
            let Some(id) = chain.layout().find(name) else {
                return Err(self.invalid(
                    format!("calibration.basis_priority[{k}]"),
                    format!("`{name}` is not a parameter of this chain (names look like theta0, d1, a2, alpha3, beta2, frame.x, marker.z)"),
                ));
            };
            basis_priority.push(id);
        }
        let max_angle_correction = match c.max_angle_correction_deg {
            Some(v) => self.positive("calibration.max_angle_correction_deg", v)?,
            None => DEFAULT_MAX_ANGLE_CORRECTION_DEG,
        }
        .to_radians();
        let max_length_correction_mm = match c.max_length_correction_mm {
            Some(v) => self.length(
                "calibration.max_length_correction_mm",
                self.positive("calibration.max_length_correction_mm", v)?,
            )?,
            None => DEFAULT_LENGTH_CORRECTION_SHARE * chain_reach_mm(chain),
        };
        Ok(CalibrationSettings {
            held,
            basis_priority,
            measurement_frame: c.measurement_frame,
            marker: c.marker,
            max_angle_correction,
            max_length_correction_mm,
        })
    }

    fn positive(&self, key: &str, v: f64) -> Result<f64, RigError> {
        if v.is_finite() && v > 0.0 {
            Ok(v)
        } else {
            Err(self.invalid(key, "must be a positive number"))
        }
    }

    /// The arm's nest pose (`[devices.arm] nest_deg`, where the arm stands after homing), when
    /// the rig file gives one value per joint, must lie within the joint limits. Its other
    /// checks (count, driver) are the devices layer's.
    fn nest_pose(
        &self,
        devices: Option<&toml::Table>,
        chain: &SerialChain,
    ) -> Result<(), RigError> {
        use crate::kinematics::Robot;
        let Some(nest) = devices
            .and_then(|d| d.get("arm"))
            .and_then(|a| a.get("nest_deg"))
            .and_then(toml::Value::as_array)
        else {
            return Ok(());
        };
        let values: Option<Vec<f64>> = nest
            .iter()
            .map(|v| v.as_float().or_else(|| v.as_integer().map(|i| i as f64)))
            .collect();
        let joints = chain.joints();
        let Some(values) = values.filter(|v| v.len() == joints.len()) else {
            return Ok(());
        };
        for (k, (spec, &v)) in joints.iter().zip(&values).enumerate() {
            let q = spec.kind.from_file_units(v);
            if !spec.within(q) {
                let unit = match spec.kind {
                    JointKind::Revolute => "°",
                    JointKind::Prismatic => " mm",
                };
                return Err(self.invalid(
                    format!("devices.arm.nest_deg[{k}]"),
                    format!(
                        "joint {} ({}) stands at {v}{unit} in the nest pose, outside its limits [{:.2}{unit}, {:.2}{unit}]: correct the nest pose or the limits",
                        k + 1,
                        spec.name,
                        spec.kind.to_file_units(spec.min),
                        spec.kind.to_file_units(spec.max),
                    ),
                ));
            }
        }
        Ok(())
    }

    fn workspace(&self, w: &RawWorkspace) -> Result<Option<[[f64; 2]; 3]>, RigError> {
        match (w.r_mm, w.azimuth_deg, w.elevation_deg) {
            (None, None, None) => Ok(None),
            (Some(r), Some(a), Some(e)) => {
                for (key, v) in [
                    ("workspace.r_mm", r),
                    ("workspace.azimuth_deg", a),
                    ("workspace.elevation_deg", e),
                ] {
                    if !(v[0].is_finite() && v[1].is_finite() && v[0] < v[1]) {
                        return Err(self.invalid(key, "needs finite [min, max] with min < max"));
                    }
                }
                if r[0] < 0.0 {
                    return Err(self.invalid("workspace.r_mm", "must not be negative"));
                }
                Ok(Some([
                    r,
                    [a[0].to_radians(), a[1].to_radians()],
                    [e[0].to_radians(), e[1].to_radians()],
                ]))
            }
            _ => Err(self.invalid(
                "workspace",
                "give all of r_mm, azimuth_deg and elevation_deg, or none",
            )),
        }
    }

    fn instrument(&self, i: &RawInstrument) -> Result<Instrument, RigError> {
        match i.kind {
            RawInstrumentKind::Ideal => Ok(Instrument::Ideal),
            RawInstrumentKind::Tracker => Ok(Instrument::Tracker),
            RawInstrumentKind::TablePanel => {
                let need = |v: Option<[f64; 3]>, k: &str| {
                    v.ok_or_else(|| {
                        self.invalid(
                            format!("instrument.{k}"),
                            "required for kind = \"table_panel\"",
                        )
                    })
                };
                let travel = need(i.table_travel_mm, "table_travel_mm")?;
                if travel.iter().any(|v| !(v.is_finite() && *v > 0.0)) {
                    return Err(
                        self.invalid("instrument.table_travel_mm", "each travel must be positive")
                    );
                }
                let offset = need(i.table_to_world_mm, "table_to_world_mm")?;
                for (key, v) in travel
                    .iter()
                    .map(|v| ("instrument.table_travel_mm", *v))
                    .chain(offset.iter().map(|v| ("instrument.table_to_world_mm", *v)))
                {
                    self.length(key, v)?;
                }
                let accuracy = i.table_accuracy_mm.unwrap_or(0.02);
                if !(accuracy.is_finite() && accuracy >= 0.0) {
                    return Err(
                        self.invalid("instrument.table_accuracy_mm", "must be zero or positive")
                    );
                }
                let size = i.panel_size_mm.unwrap_or([133.0, 80.0]);
                if size.iter().any(|v| !(v.is_finite() && *v > 0.0)) {
                    return Err(self.invalid("instrument.panel_size_mm", "must be positive"));
                }
                let counts = i.panel_counts.unwrap_or([512, 256]);
                if counts.contains(&0) {
                    return Err(self.invalid("instrument.panel_counts", "must be positive"));
                }
                let angle = i.min_pin_angle_deg.unwrap_or(15.0);
                if !(0.0..90.0).contains(&angle) {
                    return Err(self.invalid("instrument.min_pin_angle_deg", "must lie in 0..90"));
                }
                let axis = Vector3::from(i.pin_axis.unwrap_or([1.0, 0.0, 0.0]));
                if !(axis.norm() > 1e-9 && axis.iter().all(|v| v.is_finite())) {
                    return Err(self.invalid("instrument.pin_axis", "must be a non-zero direction"));
                }
                Ok(Instrument::TablePanel(TablePanel {
                    travel_mm: Vector3::from(travel),
                    table_to_world_mm: Vector3::from(offset),
                    accuracy_mm: accuracy,
                    panel_size_mm: size,
                    panel_counts: counts,
                    min_pin_angle: angle.to_radians(),
                    pin_axis: axis.normalize(),
                }))
            }
        }
    }
}

/// A pose from a translation (mm) and roll-pitch-yaw (deg, URDF convention R = Rz(y)·Ry(p)·Rx(r)).
pub fn pose_from_xyz_rpy(xyz: [f64; 3], rpy: [f64; 3]) -> Isometry3<f64> {
    let r = Rotation3::from_euler_angles(
        rpy[0].to_radians(),
        rpy[1].to_radians(),
        rpy[2].to_radians(),
    );
    Isometry3::from_parts(
        Translation3::new(xyz[0], xyz[1], xyz[2]),
        UnitQuaternion::from_rotation_matrix(&r),
    )
}
