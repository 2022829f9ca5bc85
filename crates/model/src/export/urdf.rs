//! The calibrated URDF: a model's fitted parameters folded back into the joint `<origin>`s of
//! the URDF its rig came from.
//!
//! Every moving joint of the chain keeps its axis and its `<limit>`; its origin is rewritten so
//! that, at every joint value, its frame is the calibrated one. A joint offset (θ or d error)
//! therefore goes into the origin's rotation (or translation, for a prismatic joint): the
//! commanded joint value is unchanged, and robot_state_publisher, MoveIt and every other URDF
//! consumer see the calibrated robot. (The `<calibration>` element is not used: it names
//! homing switch positions, and URDF consumers ignore it for forward kinematics.)
//!
//! The fitted tool transform goes into the last fixed joint before the tip link when there is
//! one, or else into the marker link. Two fixed links are added: `<base>_tracker` (the
//! instrument's frame; the parent of `<base>` when that is the URDF's root, a child of it
//! otherwise, since a URDF link has one parent) and `<tip>_marker` (the measured point). The
//! chain from tracker to marker is the model's; nothing else in the file changes: only the text
//! spans of the rewritten origins are replaced.

use super::xml;
use super::ExportError;
use nalgebra::{Isometry3, Point3, Translation3, Unit, UnitQuaternion, Vector3};
use rigcal_core::kinematics::{
    ErrorParams, JointKind, ParamId, ParamKind, Robot, SerialChain, TransformId,
};
use std::collections::HashMap;

/// Which links bound the chain; `None` picks them (see [`export_urdf`]).
#[derive(Debug, Clone, Default)]
pub struct ExportOptions {
    /// The base link: the rig's world frame.
    pub base: Option<String>,
    /// The tip link: the rig's tool frame.
    pub tip: Option<String>,
}

/// One moving joint of the export: its offset and its origin before and after.
#[derive(Debug, Clone)]
pub struct ExportedJoint {
    /// Joint name (URDF and rig).
    pub name: String,
    /// Revolute or prismatic.
    pub kind: JointKind,
    /// The fitted joint offset (deg or mm), folded into the origin.
    pub offset: f64,
    /// The URDF's origin (mm, relative to the parent link).
    pub nominal: Isometry3<f64>,
    /// The calibrated origin (mm, relative to the parent link).
    pub calibrated: Isometry3<f64>,
}

/// A calibrated URDF and what went into it.
#[derive(Debug, Clone)]
pub struct UrdfExport {
    /// The calibrated URDF text.
    pub text: String,
    /// The base link used.
    pub base: String,
    /// The tip link used.
    pub tip: String,
    /// The moving joints in chain order.
    pub joints: Vec<ExportedJoint>,
    /// The base link's pose in the instrument frame (mm): the fitted measurement frame.
    pub tracker: Isometry3<f64>,
    /// The marker point in the tip link's frame (mm).
    pub marker_mm: Vector3<f64>,
    /// The tool correction's joint (the last fixed joint before the tip), if there is one.
    pub tool_joint: Option<String>,
}

/// How far the model's nominal joint frames may sit from the URDF's before the URDF is taken
/// not to describe the rig: a URDF edited by hand or rounded differs by far less, a different
/// robot or base link by far more.
const MATCH_MM: f64 = 0.01;
const MATCH_RAD: f64 = 1e-4;

/// The calibrated URDF of `urdf` (text) for a chain with fitted errors `e`.
///
/// The rig's joints must be the URDF's moving joints between base and tip, by name and in
/// order, and its nominal chain the URDF's (as `rigcal rig from-urdf` writes it). Without
/// `options.base` the base is the ancestor link of the first joint whose frame is the rig's
/// world; without `options.tip` the tip is the link below the last joint (through fixed joints)
/// whose frame is the rig's nominal tool frame, or the last joint's child.
pub fn export_urdf(
    urdf: &str,
    chain: &SerialChain,
    e: &ErrorParams,
    options: &ExportOptions,
) -> Result<UrdfExport, ExportError> {
    let robot = urdf_rs::read_from_string(urdf).map_err(|e| ExportError::Urdf(e.to_string()))?;
    let tree = Tree::new(&robot);
    let first = chain
        .joints()
        .first()
        .ok_or(ExportError::NoJoints)?
        .name
        .clone();
    let last = chain
        .joints()
        .last()
        .map(|j| j.name.clone())
        .unwrap_or_default();
    let first_j = tree.joint(&first)?;
    let last_j = tree.joint(&last)?;
    let nominal = Frames::of(chain, &ErrorParams::zeros(chain.layout()));
    let base = match &options.base {
        Some(b) => b.clone(),
        None => tree.find_base(&first_j.parent.link, chain, &nominal)?,
    };
    let tip = match &options.tip {
        Some(t) => t.clone(),
        None => tree.find_tip(&base, &last_j.child.link, &nominal.tool),
    };
    let path = tree.path(&base, &tip)?;
    check_moving_joints(chain, &path)?;
    let calibrated = Frames::of(chain, e);
    let plan = plan_origins(chain, e, &path, &nominal, &calibrated)?;
    let text = edit(urdf, &tree, &base, &tip, &plan)?;
    Ok(UrdfExport {
        text,
        base,
        tip,
        joints: plan.joints,
        tracker: calibrated.frame,
        marker_mm: plan.marker_in_tip,
        tool_joint: plan.tool_joint,
    })
}

/// The joints of a URDF by name and by child link.
struct Tree<'a> {
    by_name: HashMap<&'a str, &'a urdf_rs::Joint>,
    by_child: HashMap<&'a str, &'a urdf_rs::Joint>,
    links: Vec<&'a str>,
    joints: &'a [urdf_rs::Joint],
}

impl<'a> Tree<'a> {
    fn new(robot: &'a urdf_rs::Robot) -> Self {
        Self {
            by_name: robot.joints.iter().map(|j| (j.name.as_str(), j)).collect(),
            by_child: robot
                .joints
                .iter()
                .map(|j| (j.child.link.as_str(), j))
                .collect(),
            links: robot.links.iter().map(|l| l.name.as_str()).collect(),
            joints: &robot.joints,
        }
    }

    fn joint(&self, name: &str) -> Result<&'a urdf_rs::Joint, ExportError> {
        self.by_name
            .get(name)
            .copied()
            .ok_or_else(|| ExportError::NoJoint(name.to_string()))
    }

    fn has_link(&self, name: &str) -> bool {
        self.links.contains(&name)
    }

    /// Joints from `base` down to `tip`, in order.
    fn path(&self, base: &str, tip: &str) -> Result<Vec<&'a urdf_rs::Joint>, ExportError> {
        for l in [base, tip] {
            if !self.has_link(l) {
                return Err(ExportError::NoLink(l.to_string()));
            }
        }
        let mut path = Vec::new();
        let mut link = tip;
        while link != base {
            let j = self
                .by_child
                .get(link)
                .ok_or_else(|| ExportError::NotAChain {
                    base: base.into(),
                    tip: tip.into(),
                })?;
            path.push(*j);
            link = &j.parent.link;
        }
        path.reverse();
        Ok(path)
    }

    /// The ancestor of `link` (itself included) whose frame is the rig's world.
    fn find_base(
        &self,
        link: &str,
        chain: &SerialChain,
        nominal: &Frames,
    ) -> Result<String, ExportError> {
        let mut candidate = link.to_string();
        let mut best = f64::INFINITY;
        loop {
            if let Ok(path) = self.path(&candidate, &link_below(self, chain)) {
                if let Ok(frames) = path_frames(chain, &path) {
                    // Every joint, not the first alone: a link above the base that is offset
                    // along the first axis puts that axis on the same line.
                    let worst = frames
                        .iter()
                        .zip(&nominal.joints)
                        .enumerate()
                        .map(|(k, (j, n))| axis_mismatch(j, n, axis_of(&path, k)))
                        .fold((0.0f64, 0.0f64), |(a, b), (mm, rad)| {
                            (a.max(mm), b.max(rad))
                        });
                    best = best.min(worst.0 + worst.1 * 1000.0);
                    if worst.0 < MATCH_MM && worst.1 < MATCH_RAD {
                        return Ok(candidate);
                    }
                }
            }
            match self.by_child.get(candidate.as_str()) {
                Some(j) => candidate = j.parent.link.clone(),
                None => {
                    return Err(ExportError::NoBase {
                        joint: chain.joints()[0].name.clone(),
                        mismatch: best,
                    })
                }
            }
        }
    }

    /// The link at or below `start` through fixed joints whose frame is the rig's tool frame,
    /// or `start`.
    fn find_tip(&self, base: &str, start: &str, tool: &Isometry3<f64>) -> String {
        let mut queue = vec![start.to_string()];
        while let Some(link) = queue.pop() {
            if let Ok(path) = self.path(base, &link) {
                let j = pose_at_zero(&path);
                let d = j.inverse() * tool;
                if d.translation.vector.norm() < MATCH_MM && d.rotation.angle() < MATCH_RAD {
                    return link;
                }
            }
            queue.extend(
                self.joints
                    .iter()
                    .filter(|j| j.parent.link == link)
                    .filter(|j| matches!(j.joint_type, urdf_rs::JointType::Fixed))
                    .map(|j| j.child.link.clone()),
            );
        }
        start.to_string()
    }
}

/// The child link of the rig's last joint (for the base search's path).
fn link_below(tree: &Tree<'_>, chain: &SerialChain) -> String {
    chain
        .joints()
        .last()
        .and_then(|j| tree.by_name.get(j.name.as_str()))
        .map(|j| j.child.link.clone())
        .unwrap_or_default()
}

/// A URDF origin in mm.
fn origin(p: &urdf_rs::Pose) -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::new(p.xyz[0] * 1000.0, p.xyz[1] * 1000.0, p.xyz[2] * 1000.0),
        UnitQuaternion::from_euler_angles(p.rpy[0], p.rpy[1], p.rpy[2]),
    )
}

fn is_moving(j: &urdf_rs::Joint) -> bool {
    !matches!(j.joint_type, urdf_rs::JointType::Fixed)
}

/// The pose of the path's last link in its first link's frame at q = 0.
fn pose_at_zero(path: &[&urdf_rs::Joint]) -> Isometry3<f64> {
    path.iter()
        .fold(Isometry3::identity(), |t, j| t * origin(&j.origin))
}

/// Each moving joint's frame at q = 0 in the base link's frame (mm).
fn path_frames(
    chain: &SerialChain,
    path: &[&urdf_rs::Joint],
) -> Result<Vec<Isometry3<f64>>, ExportError> {
    let mut t = Isometry3::identity();
    let mut out = Vec::new();
    for j in path {
        t *= origin(&j.origin);
        if is_moving(j) {
            out.push(t);
        }
    }
    if out.len() != chain.dof() {
        return Err(ExportError::JointCount {
            rig: chain.dof(),
            urdf: out.len(),
        });
    }
    Ok(out)
}

/// The unit axis of the `k`-th moving joint of the path, in its frame.
fn axis_of(path: &[&urdf_rs::Joint], k: usize) -> Vector3<f64> {
    path.iter()
        .filter(|j| is_moving(j))
        .nth(k)
        .map(|j| Vector3::new(j.axis.xyz[0], j.axis.xyz[1], j.axis.xyz[2]))
        .and_then(|a| a.try_normalize(1e-12))
        .unwrap_or_else(Vector3::z)
}

/// The rig's joints are the path's moving joints, by name, kind and order.
fn check_moving_joints(chain: &SerialChain, path: &[&urdf_rs::Joint]) -> Result<(), ExportError> {
    let moving: Vec<_> = path.iter().filter(|j| is_moving(j)).collect();
    if moving.len() != chain.dof() {
        return Err(ExportError::JointCount {
            rig: chain.dof(),
            urdf: moving.len(),
        });
    }
    for (spec, j) in chain.joints().iter().zip(moving) {
        let kind = match j.joint_type {
            urdf_rs::JointType::Revolute | urdf_rs::JointType::Continuous => JointKind::Revolute,
            urdf_rs::JointType::Prismatic => JointKind::Prismatic,
            _ => {
                return Err(ExportError::Unsupported(j.name.clone()));
            }
        };
        if spec.name != j.name || spec.kind != kind {
            return Err(ExportError::JointOrder {
                rig: spec.name.clone(),
                urdf: j.name.clone(),
            });
        }
    }
    Ok(())
}

/// The model's frames at q = 0 in its world frame (mm): each joint's five-parameter frame with
/// its constant θ (or d) applied, so the joint moves about (along) its z; the tool frame; the
/// marker point in the tool frame; and the measurement frame.
struct Frames {
    joints: Vec<Isometry3<f64>>,
    tool: Isometry3<f64>,
    marker: Vector3<f64>,
    frame: Isometry3<f64>,
}

impl Frames {
    fn of(chain: &SerialChain, e: &ErrorParams) -> Self {
        let q0 = vec![0.0; chain.dof()];
        let frame = chain.frame_pose(e);
        let world = frame.inverse();
        let layout = chain.layout();
        let value = |i: usize, kind: ParamKind, nominal: f64| {
            let id = ParamId {
                transform: TransformId::Link(i + 1),
                kind,
            };
            nominal + layout.index_of(id).map_or(0.0, |k| e.get(k))
        };
        let joints = chain
            .joints()
            .iter()
            .enumerate()
            .map(|(i, j)| {
                let before = chain.frame_before_joint(&q0, e, i);
                let link = &chain.links()[i];
                let constant = match j.kind {
                    JointKind::Revolute => {
                        Isometry3::rotation(Vector3::z() * value(i, ParamKind::Theta, link.theta))
                    }
                    JointKind::Prismatic => {
                        Isometry3::translation(0.0, 0.0, value(i, ParamKind::D, link.d))
                    }
                };
                world * before * constant
            })
            .collect();
        let tool_pose = chain.tool_pose(&q0, e);
        let marker = tool_pose
            .inverse_transform_point(&Point3::from(chain.position(&q0, e)))
            .coords;
        Self {
            joints,
            tool: world * tool_pose,
            marker,
            frame,
        }
    }
}

/// Distance (mm) of `c`'s origin from the URDF joint line and angle (rad) between `c`'s z and
/// the URDF axis, with `c` the model's joint frame seen from the URDF's joint frame `j`.
fn axis_mismatch(j: &Isometry3<f64>, model: &Isometry3<f64>, axis: Vector3<f64>) -> (f64, f64) {
    let c = j.inverse() * model;
    let t = c.translation.vector;
    let off_line = (t - axis * axis.dot(&t)).norm();
    let z = c.rotation * Vector3::z();
    (off_line, z.angle(&axis))
}

/// The model's joint frame in the URDF joint's frame, made exact: z along the axis, origin on
/// it (rounding in a rig file moves them by far less than [`MATCH_MM`]).
fn joint_to_model(
    j: &Isometry3<f64>,
    model: &Isometry3<f64>,
    axis: Vector3<f64>,
) -> Isometry3<f64> {
    let c = j.inverse() * model;
    let z = c.rotation * Vector3::z();
    let turn = UnitQuaternion::rotation_between(&z, &axis).unwrap_or_else(|| {
        UnitQuaternion::from_axis_angle(
            &Unit::new_normalize(z.cross(&Vector3::x())),
            std::f64::consts::PI,
        )
    });
    let t = axis * axis.dot(&c.translation.vector);
    Isometry3::from_parts(Translation3::from(t), turn * c.rotation)
}

/// The new origins by joint name, and what goes into the added links.
struct Plan {
    origins: Vec<(String, Isometry3<f64>)>,
    joints: Vec<ExportedJoint>,
    marker_origin: Isometry3<f64>,
    marker_in_tip: Vector3<f64>,
    tool_joint: Option<String>,
    tracker: Isometry3<f64>,
}

fn plan_origins(
    chain: &SerialChain,
    e: &ErrorParams,
    path: &[&urdf_rs::Joint],
    nominal: &Frames,
    calibrated: &Frames,
) -> Result<Plan, ExportError> {
    let urdf_frames = path_frames(chain, path)?;
    let mut targets = Vec::with_capacity(chain.dof());
    for (k, j) in urdf_frames.iter().enumerate() {
        let axis = axis_of(path, k);
        let (mm, rad) = axis_mismatch(j, &nominal.joints[k], axis);
        if mm > MATCH_MM || rad > MATCH_RAD {
            return Err(ExportError::Mismatch {
                joint: chain.joints()[k].name.clone(),
                mm,
                deg: rad.to_degrees(),
            });
        }
        let c = joint_to_model(j, &nominal.joints[k], axis);
        targets.push(calibrated.joints[k] * c.inverse());
    }
    let tip_nominal = pose_at_zero(path);
    let c_tip = tip_nominal.inverse() * nominal.tool;
    let tip_target = calibrated.tool * c_tip.inverse();
    let last_moving = path.iter().rposition(|j| is_moving(j)).unwrap_or(0);
    let tool_joint = (last_moving + 1 < path.len()).then(|| path[path.len() - 1].name.clone());
    let mut at = Isometry3::identity();
    let mut origins = Vec::new();
    let mut joints = Vec::new();
    let mut k = 0;
    for (n, j) in path.iter().enumerate() {
        let new = if is_moving(j) {
            let o = at.inverse() * targets[k];
            joints.push(exported(chain, e, k, j, o));
            k += 1;
            Some(o)
        } else if n + 1 == path.len() && tool_joint.is_some() {
            Some(at.inverse() * tip_target)
        } else {
            None
        };
        // An origin the calibration leaves where it was keeps its text.
        let new = new.filter(|o| !same_pose(o, &origin(&j.origin)));
        match new {
            Some(o) => {
                origins.push((j.name.clone(), o));
                at *= o;
            }
            None => at *= origin(&j.origin),
        }
    }
    let marker_in_tip = c_tip * Point3::from(calibrated.marker);
    let marker_origin = at.inverse() * tip_target * Translation3::from(marker_in_tip.coords);
    Ok(Plan {
        origins,
        joints,
        marker_in_tip: (at.inverse() * tip_target * marker_in_tip).coords,
        marker_origin,
        tool_joint,
        tracker: calibrated.frame,
    })
}

fn exported(
    chain: &SerialChain,
    e: &ErrorParams,
    k: usize,
    j: &urdf_rs::Joint,
    calibrated_origin: Isometry3<f64>,
) -> ExportedJoint {
    let spec = &chain.joints()[k];
    let kind = match spec.kind {
        JointKind::Revolute => ParamKind::Theta,
        JointKind::Prismatic => ParamKind::D,
    };
    let id = ParamId {
        transform: TransformId::Link(k + 1),
        kind,
    };
    ExportedJoint {
        name: spec.name.clone(),
        kind: spec.kind,
        offset: chain
            .layout()
            .index_of(id)
            .map_or(0.0, |i| kind.to_file_units(e.get(i))),
        nominal: origin(&j.origin),
        calibrated: calibrated_origin,
    }
}

/// Equal to well below what a URDF's numbers can say (1e-9 mm, 1e-12 rad).
fn same_pose(a: &Isometry3<f64>, b: &Isometry3<f64>) -> bool {
    let d = a.inverse() * b;
    d.translation.vector.norm() < 1e-9 && d.rotation.angle() < 1e-12
}

/// A number for a URDF attribute: 12 decimals (1e-9 mm, 1e-12 rad; a metre-long arm of ten
/// joints moves by 1e-8 mm at most), trailing zeros and the sign of zero dropped.
pub(crate) fn number(v: f64) -> String {
    let s = format!("{v:.12}");
    let s = s.trim_end_matches('0').trim_end_matches('.');
    match s {
        "-0" | "" => "0".to_string(),
        _ => s.to_string(),
    }
}

/// `<origin xyz=… rpy=…/>` of a pose in mm (URDF: metres, fixed-axis roll-pitch-yaw).
pub(crate) fn origin_tag(p: &Isometry3<f64>) -> String {
    let t = p.translation.vector / 1000.0;
    let (r, pi, y) = p.rotation.euler_angles();
    let n = number;
    format!(
        "<origin xyz=\"{} {} {}\" rpy=\"{} {} {}\"/>",
        n(t.x),
        n(t.y),
        n(t.z),
        n(r),
        n(pi),
        n(y)
    )
}

/// The URDF text with the planned origins replaced and the tracker and marker links added.
fn edit(
    urdf: &str,
    tree: &Tree<'_>,
    base: &str,
    tip: &str,
    plan: &Plan,
) -> Result<String, ExportError> {
    let (spans, robot_end) = xml::joints(urdf).ok_or(ExportError::Scan)?;
    let mut edits: Vec<(std::ops::Range<usize>, String)> = Vec::new();
    for (name, o) in &plan.origins {
        let s = spans
            .iter()
            .find(|s| &s.name == name)
            .ok_or(ExportError::Scan)?;
        match &s.origin {
            Some(r) => edits.push((r.clone(), origin_tag(o))),
            None => edits.push((s.start_tag.end..s.start_tag.end, origin_tag(o))),
        }
    }
    let tracker = format!("{base}_tracker");
    let marker = format!("{tip}_marker");
    for name in [&tracker, &marker] {
        if tree.has_link(name) {
            return Err(ExportError::NameTaken(name.clone()));
        }
    }
    let base_is_root = !tree.by_child.contains_key(base);
    let (parent, child, frame) = if base_is_root {
        (tracker.as_str(), base, plan_frame(plan))
    } else {
        (base, tracker.as_str(), plan_frame(plan).inverse())
    };
    let mut added = String::new();
    added.push_str("  <!-- rigcal: the fitted measurement frame and marker -->\n");
    added.push_str(&fixed_link(&tracker, parent, child, &frame));
    added.push_str(&fixed_link(&marker, tip, &marker, &plan.marker_origin));
    edits.push((robot_end..robot_end, added));
    edits.sort_by_key(|(r, _)| std::cmp::Reverse(r.start));
    let mut text = urdf.to_string();
    for (r, s) in edits {
        text.replace_range(r, &s);
    }
    Ok(text)
}

fn plan_frame(plan: &Plan) -> Isometry3<f64> {
    plan.tracker
}

/// A `<link>` and the fixed `<joint>` (named `<link>_joint`) that attaches it.
fn fixed_link(link: &str, parent: &str, child: &str, o: &Isometry3<f64>) -> String {
    let e = xml::escape;
    format!(
        "  <link name=\"{}\"/>\n  <joint name=\"{}_joint\" type=\"fixed\">\n    <parent link=\"{}\"/>\n    <child link=\"{}\"/>\n    {}\n  </joint>\n",
        e(link),
        e(link),
        e(parent),
        e(child),
        origin_tag(o)
    )
}
