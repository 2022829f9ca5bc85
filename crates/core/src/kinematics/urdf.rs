//! A serial chain from a URDF, in the five-parameter convention (see [`crate::kinematics`]).
//!
//! The URDF is read with `urdf-rs`; the chain from the base link to the tip link is followed
//! joint by joint (fixed joints fold into the next transform). At q = 0 every moving joint is a
//! line in the base frame (a point and a direction). Frame i sits on joint i's line with z along
//! it; link i maps frame i to frame i+1 with Rz(θ)·Tz(d)·Tx(a)·Rx(α)·Ry(β):
//! * skew or intersecting axes: x along their common normal, a its length, d the offset along
//!   axis i to its foot, α the twist between the axes, β = 0;
//! * parallel axes (Hayati, as the RV-M2's J2-J3): d = 0, x along the perpendicular from frame
//!   i's origin to axis i+1, α = 0 (or 180° when anti-parallel), β = 0 nominally but kept as the
//!   error parameter that a d would be ill-conditioned for.
//!
//! The base transform (base link to frame 1) and the tool transform (frame N, turned by q_N, to
//! the tip link) are poses. URDF lengths are metres and angles radians; the result is mm and rad.
//!
//! [`rig_file`] writes the rig file of a converted chain (`rigcal rig from-urdf`).

use super::{ErrorParams, JointKind, LinkParams, Robot, SerialChain};
use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};
use std::fmt::Write as _;

/// Why a URDF chain cannot be converted.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum UrdfError {
    /// The file is not a valid URDF.
    #[error("{0}")]
    Parse(String),
    /// A link is not in the file.
    #[error("no link named `{0}` in the URDF")]
    NoLink(String),
    /// The tip does not descend from the base.
    #[error("link `{tip}` is not below `{base}` in the URDF's tree")]
    NotAChain {
        /// Base link.
        base: String,
        /// Tip link.
        tip: String,
    },
    /// A joint type rigcal cannot model as one serial joint.
    #[error("joint `{joint}` is {kind}: only revolute, continuous, prismatic and fixed joints form a serial chain")]
    Unsupported {
        /// Joint name.
        joint: String,
        /// Its type.
        kind: String,
    },
    /// A moving joint has a zero axis.
    #[error("joint `{0}` has a zero axis")]
    ZeroAxis(String),
}

/// One moving joint of the converted chain.
#[derive(Debug, Clone)]
pub struct UrdfJoint {
    /// Name from the URDF.
    pub name: String,
    /// Revolute (continuous included) or prismatic.
    pub kind: JointKind,
    /// Limits (rad or mm); continuous joints get ±180°.
    pub limits: [f64; 2],
    /// The link transform from this joint's frame to the next.
    pub link: LinkParams,
}

/// A URDF chain in the five-parameter convention.
#[derive(Debug, Clone)]
pub struct UrdfChain {
    /// Base link to frame 1 (mm).
    pub base: Isometry3<f64>,
    /// The moving joints in order.
    pub joints: Vec<UrdfJoint>,
    /// Frame after the last link to the tip link (mm).
    pub tool: Isometry3<f64>,
    /// Per moving joint, from the URDF's `<inertial>`: the mass (kg) of the links it moves (up
    /// to the next moving joint) and their centre of mass in the base frame at q = 0 (mm); None
    /// without mass.
    pub masses: Vec<Option<(f64, Vector3<f64>)>>,
}

struct RawJoint {
    name: String,
    kind: JointKind,
    limits: [f64; 2],
    /// Pose of the joint frame in the base link frame at q = 0 (mm).
    frame: Isometry3<f64>,
    /// Axis in the joint frame.
    axis: Vector3<f64>,
}

fn pose(p: &urdf_rs::Pose) -> Isometry3<f64> {
    let t = Translation3::new(p.xyz[0] * 1000.0, p.xyz[1] * 1000.0, p.xyz[2] * 1000.0);
    Isometry3::from_parts(
        t,
        UnitQuaternion::from_euler_angles(p.rpy[0], p.rpy[1], p.rpy[2]),
    )
}

/// The joints from link `base` down to link `tip`, in order.
fn joint_path<'r>(
    robot: &'r urdf_rs::Robot,
    base: &str,
    tip: &str,
) -> Result<Vec<&'r urdf_rs::Joint>, UrdfError> {
    for l in [base, tip] {
        if !robot.links.iter().any(|k| k.name == l) {
            return Err(UrdfError::NoLink(l.to_string()));
        }
    }
    let mut path = Vec::new();
    let mut link = tip.to_string();
    while link != base {
        // A loop in a malformed tree would never reach the base: a chain has at most one joint
        // per link.
        let found = robot.joints.iter().find(|j| j.child.link == link);
        let (Some(j), true) = (found, path.len() <= robot.joints.len()) else {
            return Err(UrdfError::NotAChain {
                base: base.into(),
                tip: tip.into(),
            });
        };
        path.push(j);
        link = j.parent.link.clone();
    }
    path.reverse();
    Ok(path)
}

/// How a joint on a [`UrdfPath`] moves.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum StepMotion {
    /// Does not move.
    Fixed,
    /// Turns about this unit axis (joint frame) by q rad.
    Revolute(Vector3<f64>),
    /// Slides along this unit axis (joint frame) by q mm.
    Prismatic(Vector3<f64>),
}

/// One joint of a URDF chain as the file gives it: its origin (parent link to joint frame, mm)
/// and its motion.
#[derive(Debug, Clone)]
pub struct UrdfStep {
    /// Joint name.
    pub name: String,
    /// Parent link frame to joint frame at q = 0 (mm).
    pub origin: Isometry3<f64>,
    /// The motion.
    pub motion: StepMotion,
}

/// A URDF chain exactly as written (origins and axes, fixed joints included): its forward
/// kinematics is the reference a converted rig is checked against.
#[derive(Debug, Clone)]
pub struct UrdfPath {
    /// The joints from the base link to the tip link.
    pub steps: Vec<UrdfStep>,
}

impl UrdfPath {
    /// Pose of the tip link in the base link (mm) for the moving joints' values `q` (rad or
    /// mm, in chain order).
    pub fn tip_pose(&self, q: &[f64]) -> Isometry3<f64> {
        let mut t = Isometry3::identity();
        let mut k = 0;
        for s in &self.steps {
            t *= s.origin;
            match s.motion {
                StepMotion::Fixed => {}
                StepMotion::Revolute(axis) => {
                    let v = q.get(k).copied().unwrap_or(0.0);
                    k += 1;
                    t *= UnitQuaternion::from_axis_angle(&nalgebra::Unit::new_unchecked(axis), v);
                }
                StepMotion::Prismatic(axis) => {
                    let v = q.get(k).copied().unwrap_or(0.0);
                    k += 1;
                    t *= Translation3::from(axis * v);
                }
            }
        }
        t
    }
}

/// The chain of a URDF (text) from `base` link to `tip` link, as written.
pub fn urdf_path(text: &str, base: &str, tip: &str) -> Result<UrdfPath, UrdfError> {
    let robot = urdf_rs::read_from_string(text).map_err(|e| UrdfError::Parse(e.to_string()))?;
    let steps = joint_path(&robot, base, tip)?
        .into_iter()
        .map(|j| {
            let axis = Vector3::new(j.axis.xyz[0], j.axis.xyz[1], j.axis.xyz[2]);
            let moving = !matches!(j.joint_type, urdf_rs::JointType::Fixed);
            if moving && axis.norm() < 1e-12 {
                return Err(UrdfError::ZeroAxis(j.name.clone()));
            }
            let motion = match j.joint_type {
                urdf_rs::JointType::Fixed => StepMotion::Fixed,
                urdf_rs::JointType::Revolute | urdf_rs::JointType::Continuous => {
                    StepMotion::Revolute(axis.normalize())
                }
                urdf_rs::JointType::Prismatic => StepMotion::Prismatic(axis.normalize()),
                ref other => {
                    return Err(UrdfError::Unsupported {
                        joint: j.name.clone(),
                        kind: format!("{other:?}").to_lowercase(),
                    })
                }
            };
            Ok(UrdfStep {
                name: j.name.clone(),
                origin: pose(&j.origin),
                motion,
            })
        })
        .collect::<Result<Vec<_>, _>>()?;
    Ok(UrdfPath { steps })
}

/// The largest distance (mm) between the tip frames of `chain` (measurement frame and marker
/// left out) and of the URDF `path` over `samples` joint vectors drawn uniformly within the
/// chain's limits (a fixed seed, so a run is repeatable), with the worst joint vector. Each tip
/// frame is compared by its origin and by points 100 mm out along each of its axes, so a
/// turned tip shows as well as a moved one.
pub fn max_tip_deviation(path: &UrdfPath, chain: &SerialChain, samples: usize) -> (f64, Vec<f64>) {
    use rand::{RngExt, SeedableRng};
    let mut rng = rand::rngs::ChaCha8Rng::seed_from_u64(2021);
    let e = ErrorParams::zeros(chain.layout());
    let probes = [
        Point3::origin(),
        Point3::new(100.0, 0.0, 0.0),
        Point3::new(0.0, 100.0, 0.0),
        Point3::new(0.0, 0.0, 100.0),
    ];
    let mut worst = (0.0, Vec::new());
    // q = 0 first: the conversion is built there, every other sample tests the joint axes.
    for k in 0..samples.max(1) {
        let q: Vec<f64> = chain
            .joints()
            .iter()
            .map(|j| match k {
                0 if j.min <= 0.0 && j.max >= 0.0 => 0.0,
                0 => j.min,
                _ if j.max > j.min => rng.random_range(j.min..=j.max),
                _ => j.min,
            })
            .collect();
        let rig = chain.frame().inverse() * chain.tool_pose(&q, &e);
        let urdf = path.tip_pose(&q);
        let dev = probes
            .iter()
            .map(|p| (rig * p - urdf * p).norm())
            .fold(0.0, f64::max);
        if dev.is_nan() {
            return (f64::NAN, q);
        }
        if dev > worst.0 || worst.1.is_empty() {
            worst = (dev, q);
        }
    }
    worst
}

/// Converts the chain of a URDF (text) from `base` link to `tip` link.
pub fn chain_from_urdf(text: &str, base: &str, tip: &str) -> Result<UrdfChain, UrdfError> {
    let robot = urdf_rs::read_from_string(text).map_err(|e| UrdfError::Parse(e.to_string()))?;
    let path = joint_path(&robot, base, tip)?;
    let mut t = Isometry3::identity();
    let mut moving = Vec::new();
    // Per moving joint: (Σ m, Σ m·c) of the links it carries up to the next moving joint, with c
    // the centre of mass in the base frame at q = 0 (mm).
    let mut mass: Vec<(f64, Vector3<f64>)> = Vec::new();
    for j in path {
        t *= pose(&j.origin);
        let inertial = robot
            .links
            .iter()
            .find(|l| l.name == j.child.link)
            .map(|l| &l.inertial);
        let add = |mass: &mut Vec<(f64, Vector3<f64>)>, t: &Isometry3<f64>| {
            if let (Some(last), Some(i)) = (mass.last_mut(), inertial) {
                let c = t * nalgebra::Point3::from(pose(&i.origin).translation.vector);
                last.0 += i.mass.value;
                last.1 += c.coords * i.mass.value;
            }
        };
        if matches!(j.joint_type, urdf_rs::JointType::Fixed) {
            add(&mut mass, &t);
        }
        let kind = match j.joint_type {
            urdf_rs::JointType::Revolute | urdf_rs::JointType::Continuous => JointKind::Revolute,
            urdf_rs::JointType::Prismatic => JointKind::Prismatic,
            urdf_rs::JointType::Fixed => continue,
            ref other => {
                return Err(UrdfError::Unsupported {
                    joint: j.name.clone(),
                    kind: format!("{other:?}").to_lowercase(),
                })
            }
        };
        let axis = Vector3::new(j.axis.xyz[0], j.axis.xyz[1], j.axis.xyz[2]);
        if axis.norm() < 1e-12 {
            return Err(UrdfError::ZeroAxis(j.name.clone()));
        }
        let limits = match (j.joint_type.clone(), kind) {
            (urdf_rs::JointType::Continuous, _) => [-std::f64::consts::PI, std::f64::consts::PI],
            (_, JointKind::Revolute) => [j.limit.lower, j.limit.upper],
            (_, JointKind::Prismatic) => [j.limit.lower * 1000.0, j.limit.upper * 1000.0],
        };
        moving.push(RawJoint {
            name: j.name.clone(),
            kind,
            limits,
            frame: t,
            axis: axis.normalize(),
        });
        mass.push((0.0, Vector3::zeros()));
        add(&mut mass, &t);
    }
    let tip_pose = t;
    let mut chain = convert(moving, tip_pose);
    chain.masses = mass
        .into_iter()
        .map(|(m, mc)| (m > 0.0).then(|| (m, mc / m)))
        .collect();
    Ok(chain)
}

/// The frame with origin `o`, z along `z`, x along `x` (made orthogonal).
///
/// The columns are orthonormal by construction, so the rotation is read off them directly.
/// (`UnitQuaternion::from_matrix` is an iterative polar decomposition started at the
/// identity: for a frame turned by 180°, such as UR's `base_link` yaw of π, it stalls on a
/// saddle and returns a rotation off by up to a few hundredths of a degree.)
fn frame(o: Vector3<f64>, z: Vector3<f64>, x: Vector3<f64>) -> Isometry3<f64> {
    let z = z.normalize();
    let x = (x - z * z.dot(&x)).normalize();
    let y = z.cross(&x);
    let m = nalgebra::Matrix3::from_columns(&[x, y, z]);
    let r = nalgebra::Rotation3::from_matrix_unchecked(m);
    Isometry3::from_parts(
        Translation3::from(o),
        UnitQuaternion::from_rotation_matrix(&r),
    )
}

fn any_perpendicular(z: &Vector3<f64>) -> Vector3<f64> {
    let c = if z.x.abs() < 0.9 {
        Vector3::x()
    } else {
        Vector3::y()
    };
    z.cross(&c).normalize()
}

fn signed_angle(from: &Vector3<f64>, to: &Vector3<f64>, about: &Vector3<f64>) -> f64 {
    from.cross(to).dot(about).atan2(from.dot(to))
}

fn convert(joints: Vec<RawJoint>, tip: Isometry3<f64>) -> UrdfChain {
    // Joint lines in the base frame at q = 0.
    let lines: Vec<(Vector3<f64>, Vector3<f64>)> = joints
        .iter()
        .map(|j| (j.frame.translation.vector, j.frame.rotation * j.axis))
        .collect();
    let n = lines.len();
    let first_x = if n > 1 {
        common_normal(&lines[0], &lines[1]).map(|(_, _, d)| d)
    } else {
        None
    };
    let z0 = lines.first().map(|l| l.1).unwrap_or_else(Vector3::z);
    let x0 = first_x.unwrap_or_else(|| any_perpendicular(&z0));
    let mut current = frame(lines.first().map(|l| l.0).unwrap_or_default(), z0, x0);
    let base = current;
    let mut out = Vec::with_capacity(n);
    for i in 0..n {
        let zi = current.rotation * Vector3::z();
        let xi = current.rotation * Vector3::x();
        let oi = current.translation.vector;
        let (link, next) = if i + 1 < n {
            let (p2, z2) = lines[i + 1];
            link_to(oi, zi, xi, p2, z2)
        } else {
            (LinkParams::default(), current)
        };
        out.push(UrdfJoint {
            name: joints[i].name.clone(),
            kind: joints[i].kind,
            limits: joints[i].limits,
            link,
        });
        current = next;
    }
    UrdfChain {
        base,
        joints: out,
        tool: current.inverse() * tip,
        masses: Vec::new(),
    }
}

/// Common normal of two skew or intersecting lines: foot on the first, foot on the second, and
/// the unit direction from first to second (z1 × z2 when they intersect). None when parallel.
fn common_normal(
    l1: &(Vector3<f64>, Vector3<f64>),
    l2: &(Vector3<f64>, Vector3<f64>),
) -> Option<(Vector3<f64>, Vector3<f64>, Vector3<f64>)> {
    let (p1, z1) = l1;
    let (p2, z2) = l2;
    let c = z1.cross(z2);
    if c.norm() < 1e-9 {
        return None;
    }
    let w = p1 - p2;
    let b = z1.dot(z2);
    let d = z1.dot(&w);
    let e = z2.dot(&w);
    let den = 1.0 - b * b;
    let s = (b * e - d) / den;
    let t = (e - b * d) / den;
    let f1 = p1 + z1 * s;
    let f2 = p2 + z2 * t;
    // The common normal lies along z1 × z2; its sign comes from the feet when they are apart.
    // Taking the direction from the feet themselves would let rounding in them tilt it off the
    // axes' normal, and the twist and the next frame with it.
    let n = c.normalize();
    let dir = if (f2 - f1).dot(&n) < -1e-9 { -n } else { n };
    Some((f1, f2, dir))
}

/// The link from frame (o, z, x) to the joint line (p2, z2), and the next frame.
fn link_to(
    o: Vector3<f64>,
    z: Vector3<f64>,
    x: Vector3<f64>,
    p2: Vector3<f64>,
    z2: Vector3<f64>,
) -> (LinkParams, Isometry3<f64>) {
    match common_normal(&(o, z), &(p2, z2)) {
        Some((f1, f2, nx)) => {
            let theta = signed_angle(&x, &nx, &z);
            let d = (f1 - o).dot(&z);
            let a = (f2 - f1).dot(&nx);
            let alpha = signed_angle(&z, &z2, &nx);
            (
                LinkParams {
                    theta,
                    d,
                    a,
                    alpha,
                    beta: 0.0,
                },
                frame(f2, z2, nx),
            )
        }
        None => {
            let v = p2 - o;
            let perp = v - z * z.dot(&v);
            let nx = if perp.norm() > 1e-9 {
                perp.normalize()
            } else {
                x
            };
            let theta = signed_angle(&x, &nx, &z);
            let a = perp.dot(&nx);
            let alpha = if z.dot(&z2) < 0.0 {
                std::f64::consts::PI
            } else {
                0.0
            };
            let origin = o + nx * a;
            (
                LinkParams {
                    theta,
                    d: 0.0,
                    a,
                    alpha,
                    beta: 0.0,
                },
                frame(origin, z2, nx),
            )
        }
    }
}

/// A link's mass (kg) and centre of mass in the frame at the end of the link (mm); None
/// without mass.
type LinkCom = Option<(f64, Vector3<f64>)>;

/// What a generated rig file is called and where it came from.
#[derive(Debug, Clone, Copy)]
pub struct RigFileNames<'a> {
    /// The rig's (and robot's) name.
    pub name: &'a str,
    /// The URDF it was converted from (a path, say).
    pub source: &'a str,
    /// Base link of the chain.
    pub base: &'a str,
    /// Tip link of the chain.
    pub tip: &'a str,
}

/// The rig file (TOML text) of a converted chain, with the link masses of the URDF's
/// `<inertial>` elements: each centre of mass (base frame, q = 0) is moved into its link's end
/// frame of the five-parameter chain, which is rigid with the same link. `chain_of` turns rig
/// file text into its chain (the rig file parser): the centres are placed on the chain the file
/// will load as, read back from the file's own (rounded) numbers.
pub fn rig_file<E>(
    names: &RigFileNames<'_>,
    c: &UrdfChain,
    chain_of: impl FnOnce(&str) -> Result<SerialChain, E>,
) -> Result<String, E> {
    let without_masses = chain_of(&rig_toml(names, c, &[]))?;
    Ok(rig_toml(names, c, &link_coms(&without_masses, c)))
}

/// Each link's mass and centre of mass in its end frame of `five` (the chain's five-parameter
/// form), from the URDF's base-frame centres at q = 0.
fn link_coms(five: &SerialChain, c: &UrdfChain) -> Vec<LinkCom> {
    let e = ErrorParams::zeros(five.layout());
    let q0 = vec![0.0; five.dof()];
    c.masses
        .iter()
        .enumerate()
        .map(|(i, m)| {
            m.map(|(kg, com)| {
                let end = five.frame_before_joint(&q0, &e, i + 1);
                (kg, end.inverse_transform_point(&Point3::from(com)).coords)
            })
        })
        .collect()
}

/// `{ xyz_mm = […], rpy_deg = […] }` of a pose.
fn pose_fields(p: &Isometry3<f64>) -> String {
    let (r, pi, y) = p.rotation.euler_angles();
    let t = p.translation.vector;
    format!(
        "{{ xyz_mm = [{}, {}, {}], rpy_deg = [{}, {}, {}] }}",
        t.x,
        t.y,
        t.z,
        r.to_degrees(),
        pi.to_degrees(),
        y.to_degrees()
    )
}

/// The rig file text of a converted chain with the given link masses (none: `&[]`). The
/// measurement frame and the marker are free, as for a laser tracker or motion capture.
fn rig_toml(names: &RigFileNames<'_>, c: &UrdfChain, coms: &[LinkCom]) -> String {
    let RigFileNames {
        name,
        source,
        base,
        tip,
    } = *names;
    let mut s = String::new();
    let _ = writeln!(
        s,
        "# Generated by `rigcal rig from-urdf` from {source}, chain {base} → {tip}."
    );
    let _ = writeln!(
        s,
        "# Five-parameter convention A = Rz(θ)·Tz(d)·Tx(a)·Rx(α)·Ry(β); mm and degrees."
    );
    let _ = writeln!(
        s,
        "name = {}\ndescription = {}\n\n[robot]\nname = {}",
        toml_string(name),
        toml_string(&format!("{name} from URDF ({base} to {tip})")),
        toml_string(name)
    );
    let _ = writeln!(s, "base = {}", pose_fields(&c.base));
    let _ = writeln!(s, "tool = {}", pose_fields(&c.tool));
    for (i, j) in c.joints.iter().enumerate() {
        joint_toml(&mut s, j, coms.get(i).copied().flatten());
    }
    let _ = writeln!(s, "\n[calibration]\n# Seen by a tracker: its frame and the marker on the last link are unknown and fitted.\nmeasurement_frame = \"free\"\nmarker = \"free\"\n\n[instrument]\nkind = \"tracker\"");
    s
}

/// `text` as a TOML string, quoted and escaped by the serializer (a URDF name may hold quotes
/// or backslashes).
fn toml_string(text: &str) -> String {
    toml::Value::String(text.to_string()).to_string()
}

/// One `[[robot.joints]]` table.
fn joint_toml(s: &mut String, j: &UrdfJoint, com: LinkCom) {
    let l = &j.link;
    let _ = writeln!(s, "\n[[robot.joints]]\nname = {}", toml_string(&j.name));
    match j.kind {
        JointKind::Revolute => {
            let _ = writeln!(
                s,
                "type = \"revolute\"\nlimits_deg = [{}, {}]",
                j.limits[0].to_degrees(),
                j.limits[1].to_degrees()
            );
        }
        JointKind::Prismatic => {
            let _ = writeln!(
                s,
                "type = \"prismatic\"\nlimits_mm = [{}, {}]",
                j.limits[0], j.limits[1]
            );
        }
    }
    let _ = writeln!(
        s,
        "theta_deg = {}\nd_mm = {}\na_mm = {}\nalpha_deg = {}\nbeta_deg = {}",
        l.theta.to_degrees(),
        l.d,
        l.a,
        l.alpha.to_degrees(),
        l.beta.to_degrees()
    );
    if let Some((kg, c)) = com {
        let _ = writeln!(
            s,
            "mass_kg = {kg}   # from <inertial>\ncom_mm = [{}, {}, {}]   # in the frame at the end of this link",
            c.x, c.y, c.z
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn two_joints() -> UrdfChain {
        UrdfChain {
            base: Isometry3::translation(100.0, 0.0, 200.0),
            joints: vec![
                UrdfJoint {
                    name: "lift".into(),
                    kind: JointKind::Prismatic,
                    limits: [0.0, 500.0],
                    link: LinkParams {
                        theta: 0.0,
                        d: 0.0,
                        a: 0.0,
                        alpha: 0.0,
                        beta: 0.0,
                    },
                },
                UrdfJoint {
                    name: "j1".into(),
                    kind: JointKind::Revolute,
                    limits: [-std::f64::consts::FRAC_PI_2, std::f64::consts::FRAC_PI_2],
                    link: LinkParams {
                        theta: 0.0,
                        d: 0.0,
                        a: 250.0,
                        alpha: std::f64::consts::FRAC_PI_2,
                        beta: 0.0,
                    },
                },
            ],
            tool: Isometry3::identity(),
            masses: vec![None, Some((2.0, Vector3::new(225.0, 0.0, 200.0)))],
        }
    }

    const TWO_LINK: &str = r#"<robot name="t">
  <link name="b"/><link name="l1"/><link name="l2"/><link name="tip"/>
  <joint name="j1" type="revolute"><parent link="b"/><child link="l1"/>
    <origin xyz="0 0 0.1" rpy="0 0 3.141592653589793"/><axis xyz="0 0 1"/>
    <limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
  <joint name="j2" type="revolute"><parent link="l1"/><child link="l2"/>
    <origin xyz="0.3 0 0" rpy="1.5707963267948966 0 0"/><axis xyz="0 0 1"/>
    <limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
  <joint name="t" type="fixed"><parent link="l2"/><child link="tip"/>
    <origin xyz="0.2 0 0" rpy="0 0 -3.141592653589793"/></joint>
</robot>"#;

    fn converted(text: &str) -> String {
        let c = chain_from_urdf(text, "b", "tip").expect("converts");
        let names = RigFileNames {
            name: "t",
            source: "t.urdf",
            base: "b",
            tip: "tip",
        };
        rig_toml(&names, &c, &[])
    }

    #[test]
    fn the_tip_check_sees_a_wrong_rig() {
        let path = urdf_path(TWO_LINK, "b", "tip").expect("path");
        let text = converted(TWO_LINK);
        let rig = crate::rig::Rig::parse(&text, None).expect("loads");
        let (dev, _) = max_tip_deviation(&path, &rig.chain, 16);
        assert!(dev < 1e-9, "{dev}");
        // One length 1 mm off: the check must see it.
        let wrong = text.replacen("a_mm = 300", "a_mm = 301", 1);
        assert_ne!(wrong, text, "{text}");
        let rig = crate::rig::Rig::parse(&wrong, None).expect("loads");
        let (dev, q) = max_tip_deviation(&path, &rig.chain, 16);
        assert!(dev > 0.5 && q.len() == 2, "{dev}");
    }

    #[test]
    fn frames_turned_half_a_turn_are_exact() {
        // nalgebra's iterative `from_matrix` is 0.0155° off on such frames.
        let f = frame(Vector3::zeros(), -Vector3::z(), -Vector3::x());
        let m = f.rotation.to_rotation_matrix();
        let want = nalgebra::Matrix3::new(-1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, -1.0);
        assert!((m.matrix() - want).abs().max() < 1e-15, "{m}");
    }

    #[test]
    fn names_with_quotes_and_backslashes_read_back() {
        let mut chain = two_joints();
        chain.joints[1].name = "j\"1\\x".into();
        let names = RigFileNames {
            name: "my \"arm\"",
            source: "two.urdf",
            base: "base",
            tip: "tip",
        };
        let text = rig_toml(&names, &chain, &[]);
        let v: toml::Value = toml::from_str(&text).expect("valid TOML");
        assert_eq!(v["name"].as_str(), Some("my \"arm\""));
        assert_eq!(v["robot"]["joints"][1]["name"].as_str(), Some("j\"1\\x"));
    }

    #[test]
    fn the_rig_file_text_is_literal() {
        let names = RigFileNames {
            name: "two",
            source: "two.urdf",
            base: "base",
            tip: "tip",
        };
        let coms = [None, Some((2.0, Vector3::new(-125.0, 0.0, 0.0)))];
        // Numbers as Rust prints them (the pitch of an identity rotation comes out as −0).
        assert_eq!(
            rig_toml(&names, &two_joints(), &coms),
            r#"# Generated by `rigcal rig from-urdf` from two.urdf, chain base → tip.
# Five-parameter convention A = Rz(θ)·Tz(d)·Tx(a)·Rx(α)·Ry(β); mm and degrees.
name = "two"
description = "two from URDF (base to tip)"

[robot]
name = "two"
base = { xyz_mm = [100, 0, 200], rpy_deg = [0, -0, 0] }
tool = { xyz_mm = [0, 0, 0], rpy_deg = [0, -0, 0] }

[[robot.joints]]
name = "lift"
type = "prismatic"
limits_mm = [0, 500]
theta_deg = 0
d_mm = 0
a_mm = 0
alpha_deg = 0
beta_deg = 0

[[robot.joints]]
name = "j1"
type = "revolute"
limits_deg = [-90, 90]
theta_deg = 0
d_mm = 0
a_mm = 250
alpha_deg = 90
beta_deg = 0
mass_kg = 2   # from <inertial>
com_mm = [-125, 0, 0]   # in the frame at the end of this link

[calibration]
# Seen by a tracker: its frame and the marker on the last link are unknown and fitted.
measurement_frame = "free"
marker = "free"

[instrument]
kind = "tracker"
"#
        );
    }

    #[test]
    fn link_masses_are_placed_in_the_end_frame_of_the_chain_the_file_loads_as() {
        let c = two_joints();
        let names = RigFileNames {
            name: "two",
            source: "two.urdf",
            base: "base",
            tip: "tip",
        };
        let mut seen = String::new();
        let text = rig_file(&names, &c, |t| {
            seen = t.to_string();
            let rig = crate::rig::Rig::parse(t, None)?;
            Ok::<_, crate::rig::RigError>(rig.chain)
        })
        .expect("the generated file loads");
        assert!(!seen.contains("mass_kg"), "the draft has no masses");
        assert!(text.contains("mass_kg = 2   # from <inertial>"), "{text}");
        let rig = crate::rig::Rig::parse(&text, None).expect("the final file loads");
        let com = rig.link_masses[1]
            .as_ref()
            .expect("j1 carries a mass")
            .com_mm;
        // The centre lies 125 mm out along the link from j1's axis, whose end frame sits at
        // its far end, 250 mm out.
        assert!(
            (com - Vector3::new(-125.0, 0.0, 0.0)).norm() < 1e-9,
            "{com}"
        );
    }
}
