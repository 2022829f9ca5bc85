//! Planning a measurement session: which poses, in which order, and how long the rig will take.
//!
//! - Points are drawn at random within the joint limits (held joints at their values, seeded),
//!   each checked with [`Rig::measurable`]; an infeasible point is dropped and kept in
//!   [`Plan::dropped`] with its reason (the CLI prints them, never silently).
//! - Regions: the joint space of the first three moving joints split into boxes by the division
//!   rule (halve the widest dimension, conventions §5); each point belongs to one box.
//! - Order within a region, [`Ordering`]: the paper's ascending table z in layers of
//!   [`PlanOptions::layer_mm`], then x, then y ([`Ordering::ZThenXY`]); or the default
//!   [`Ordering::Optimised`]: no point more than the z window ([`z_window_mm`]) below any earlier
//!   point of its region (so the table's ascending-z rule, `pass_retract_mm`, holds between
//!   approaches with the approach margin of [`ContactSettings`] and room for the via pose),
//!   ordered inside that window to cut the move time ([`MoveTime`]: the slower of the table's
//!   x-y profiles and the arm's largest joint change) by a greedy start and Or-opt/2-opt passes.
//!   Regions are visited in a seeded random order so
//!   that time is decorrelated from position, and a drift-reference pose (region `ref`) is
//!   measured first and then every [`PlanOptions::reference_every`] points (in the optimised
//!   order as often, each time within a fifth of the interval where its detour is least).
//! - Approach directions: each moving joint reaches its target from alternating sides
//!   ([`approach_signs`]), so backlash is seen from both directions.
//!
//! Units: radians inside, degrees in `plan.csv`; table positions in mm (table frame, the panel
//! centre under the nominal tip at contact height).

use std::path::{Path, PathBuf};

use rand::rngs::ChaCha8Rng;
use rand::seq::SliceRandom;
use rand::SeedableRng;

use crate::devices::profile::Profile;
use crate::session::procedure::{ContactProcedure, BASELINE_BACKOFF_MM};
use crate::session::speeds::{largest_joint_change_deg, MoveTime, RigSpeeds};
use rigcal_core::kinematics::{ErrorParams, Robot};
use rigcal_core::rig::{Instrument, Rig, Unmeasurable};
use rigcal_model::division::{Bounds, DivisionSpace, Space};
use rigcal_model::identification::random_poses;

/// The region id of the drift-reference pose.
pub const REFERENCE_REGION: &str = "ref";

/// The most measurement points one plan may ask for: far beyond any session a rig can run
/// (at seconds per point, a million points is weeks of rig time), and small enough that the
/// planner's candidate draws stay within memory. Larger counts are refused before any work.
pub const MAX_PLAN_POINTS: usize = 1_000_000;

/// What went wrong planning or reading a plan.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum PlanError {
    /// Too few measurable points were found.
    #[error("found only {found} measurable points of {wanted} after {drawn} random poses; lower --points or use a rig with a larger measurable workspace")]
    TooFewPoints {
        /// Found.
        found: usize,
        /// Wanted.
        wanted: usize,
        /// Candidates drawn.
        drawn: usize,
    },
    /// The division space could not be set up.
    #[error("cannot divide the workspace into regions: {0}")]
    Space(String),
    /// A plan file could not be read or written.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// A file beside the plan (its dropped candidates) could not be written.
    #[error("writing {}", path.display())]
    Write {
        /// The file.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// The number of points asked for is zero or above [`MAX_PLAN_POINTS`].
    #[error("cannot plan {wanted} points: ask for 1 to {MAX_PLAN_POINTS} (split a larger campaign into several sessions)")]
    PointCount {
        /// Points asked for.
        wanted: usize,
    },
    /// A plan file has no header line: its first line is data, which would be lost.
    #[error("{path}: line 1 is not a header (`{first}`); add the header line `{expected}` above the points (as `rigcal plan` writes it)")]
    MissingHeader {
        /// The file.
        path: PathBuf,
        /// The first line as found.
        first: String,
        /// The header this rig's plans have.
        expected: String,
    },
    /// A plan file's header lacks a column this rig's plans need.
    #[error("{path}: line 1: missing column `{column}`; the header needs `{expected}` (as `rigcal plan` writes it for this rig)")]
    MissingColumn {
        /// The file.
        path: PathBuf,
        /// The missing column.
        column: String,
        /// The header this rig's plans have.
        expected: String,
    },
    /// A plan file's header names a column twice: which one holds the value is ambiguous.
    #[error("{path}: line 1: column `{column}` appears more than once; keep one")]
    DuplicateColumn {
        /// The file.
        path: PathBuf,
        /// The repeated column.
        column: String,
    },
    /// A plan file has a header but no point: a session on it would measure nothing.
    #[error("{path}: the plan has no points; write one with `rigcal plan --points N` (or pass `--points N` to `rigcal session`)")]
    EmptyPlan {
        /// The file.
        path: PathBuf,
    },
    /// A plan file is malformed.
    #[error("{path}: line {line}: {reason}; expected columns point,region,q1_deg..qN_deg,table_x_mm,table_y_mm,table_z_mm")]
    Malformed {
        /// The file.
        path: PathBuf,
        /// 1-based line.
        line: usize,
        /// What is wrong.
        reason: String,
    },
}

/// How to plan.
#[derive(Debug, Clone, PartialEq)]
pub struct PlanOptions {
    /// Measurement points wanted (reference re-measurements not included).
    pub points: usize,
    /// Number of regions (rounded up to a power of two).
    pub regions: usize,
    /// Re-measure the drift reference every this many points (0: never; in
    /// [`Ordering::Optimised`] as often, each time within a fifth of this where its detour is
    /// least).
    pub reference_every: usize,
    /// Seed of the random draws.
    pub seed: u64,
    /// Height of a z layer within a region (mm), for [`Ordering::ZThenXY`] and
    /// [`Ordering::NearestNeighbour`].
    pub layer_mm: f64,
    /// Order within a region.
    pub order: Ordering,
    /// The z window of [`Ordering::Optimised`] (mm): how far a point may lie below an earlier
    /// point of its region; `None`: [`z_window_mm`] of the rig.
    pub window_mm: Option<f64>,
    /// Room the contact needs below and above the nominal contact height in the table's z
    /// travel (approach margin + travel clearance, mm); points with less are dropped.
    pub z_room_mm: f64,
    /// Room kept inside the table's x and y travel (mm); points with less are dropped. The
    /// session moves the table through the *fitted* registration, which differs from the rig
    /// file's nominal table pose by the set-up's offset and the arm's own errors (on
    /// `sim/rig-realistic.toml` by up to about 3 mm across the travel): a point planned at the
    /// edge of the travel would be refused there.
    pub xy_room_mm: f64,
}

impl Default for PlanOptions {
    fn default() -> Self {
        PlanOptions {
            points: 100,
            regions: 8,
            reference_every: 50,
            seed: 1,
            layer_mm: 2.0,
            order: Ordering::Optimised,
            window_mm: None,
            z_room_mm: 5.0,
            xy_room_mm: 5.0,
        }
    }
}

/// Order of the points within a region.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Ordering {
    /// Ascending z layers, nearest neighbour in x-y within a layer.
    NearestNeighbour,
    /// The paper's order: z layers, then x, then y.
    ZThenXY,
    /// Inside the z window of the ascending-z rule, the order of least move time (the
    /// default; see the module docs).
    Optimised,
}

impl Ordering {
    /// The name on the command line (`z-then-xy`, `nearest-neighbour`, `optimised`).
    pub fn name(self) -> &'static str {
        match self {
            Ordering::NearestNeighbour => "nearest-neighbour",
            Ordering::ZThenXY => "z-then-xy",
            Ordering::Optimised => "optimised",
        }
    }
}

impl std::str::FromStr for Ordering {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "z-then-xy" => Ok(Ordering::ZThenXY),
            "nearest-neighbour" => Ok(Ordering::NearestNeighbour),
            "optimised" | "optimized" => Ok(Ordering::Optimised),
            _ => Err(format!(
                "unknown order `{s}`: z-then-xy, nearest-neighbour or optimised"
            )),
        }
    }
}

/// The z window of [`Ordering::Optimised`] on `rig` (mm): how far below an earlier point's
/// nominal contact of its region a point's nominal contact may lie so that the table's pass
/// rule holds. A point's locating approach ends `margin` above its nominal contact (the pass's
/// top); the table then travels a `clearance` below the contact it found, which the arm's
/// errors put up to a `margin` below the nominal one: so `pass_retract − 2·margin −
/// clearance` (never negative). Where the rig's errors or a via pose's lower tip still take
/// the table lower, the contact procedure starts a new pass (counted in the session report).
pub fn z_window_mm(rig: &Rig) -> f64 {
    let c = ContactSettings::of(rig);
    let retract = crate::devices::config::DevicesConfig::read(rig)
        .table
        .pass_retract_mm;
    (retract - 2.0 * c.margin_mm - c.clearance_mm).max(0.0)
}

/// One planned measurement.
#[derive(Debug, Clone, PartialEq)]
pub struct PlannedPoint {
    /// Point number, 1-based, in measurement order.
    pub point: usize,
    /// Region id (`r1`…, or `ref`).
    pub region: String,
    /// Joint values (rad).
    pub q: Vec<f64>,
    /// Table position at nominal contact (mm, table frame); on a point-sensor rig (tracker,
    /// ideal instrument), the nominal marker position (mm, world frame), which orders the points.
    pub table_mm: [f64; 3],
}

/// A pose dropped while planning, and why.
#[derive(Debug, Clone, PartialEq)]
pub struct Dropped {
    /// Joint values (rad).
    pub q: Vec<f64>,
    /// Why it cannot be measured.
    pub reason: Unmeasurable,
}

/// A session plan.
#[derive(Debug, Clone)]
pub struct Plan {
    /// Points in measurement order.
    pub points: Vec<PlannedPoint>,
    /// Candidates dropped as unmeasurable.
    pub dropped: Vec<Dropped>,
}

/// The table position (mm) that brings the panel centre under the nominal tip at contact.
pub fn table_target(rig: &Rig, q: &[f64]) -> Option<[f64; 3]> {
    let Instrument::TablePanel(tp) = &rig.instrument else {
        return None;
    };
    let tip = rig
        .chain
        .position(q, &ErrorParams::zeros(rig.chain.layout()));
    let t = tip - tp.table_to_world_mm;
    Some([t.x, t.y, t.z])
}

/// Random draws allowed per registration pose before the search gives up.
const REGISTRATION_DRAWS_PER_POSE: usize = 500;

/// The registration step's candidate poses (table rig), in the order a session measures them:
/// uniform random joint values, seeded from the session seed, kept when the rig can measure
/// them. The session takes candidates until it has its registration observations; the rig-time
/// estimate takes as many as the session asks for. Ends early when no measurable pose turns up
/// within `REGISTRATION_DRAWS_PER_POSE` draws.
pub fn registration_candidates(
    rig: &Rig,
    session_seed: u64,
) -> impl Iterator<Item = Vec<f64>> + '_ {
    let mut rng = ChaCha8Rng::seed_from_u64(session_seed ^ 0x7265_6769_7374);
    std::iter::from_fn(move || {
        for _ in 0..REGISTRATION_DRAWS_PER_POSE {
            let q = random_poses(rig.chain.joints(), rig.held(), 1, &mut rng).pop()?;
            if rig.measurable(&q).is_ok() {
                table_target(rig, &q)?;
                return Some(q);
            }
        }
        None
    })
}

/// The registration poses a session with `count` registration points would measure first,
/// as planned points (region `reg`, numbered 0) for [`estimate`]; none on a point-sensor rig.
pub fn registration_points(rig: &Rig, count: usize, session_seed: u64) -> Vec<PlannedPoint> {
    registration_candidates(rig, session_seed)
        .take(count)
        .filter_map(|q| {
            Some(PlannedPoint {
                point: 0,
                region: "reg".into(),
                table_mm: table_target(rig, &q)?,
                q,
            })
        })
        .collect()
}

/// Where a point is planned: [`table_target`] on the table rig, the nominal marker position
/// (world mm) on a point-sensor rig.
pub fn target_point(rig: &Rig, q: &[f64]) -> [f64; 3] {
    table_target(rig, q).unwrap_or_else(|| {
        let tip = rig
            .chain
            .position(q, &ErrorParams::zeros(rig.chain.layout()));
        [tip.x, tip.y, tip.z]
    })
}

/// Joint-space region boxes (the division rule applied until there are `n`).
fn region_boxes(space: &DivisionSpace, n: usize) -> Vec<Bounds> {
    let mut boxes = vec![space.full];
    while boxes.len() < n.max(1) {
        let mut next = Vec::with_capacity(boxes.len() * 2);
        for b in &boxes {
            let (lo, hi) = b.halves(b.widest(&space.full));
            next.push(lo);
            next.push(hi);
        }
        boxes = next;
    }
    boxes
}

/// Plans a session on `rig`.
pub fn plan(rig: &Rig, opts: &PlanOptions) -> Result<Plan, PlanError> {
    if opts.points == 0 || opts.points > MAX_PLAN_POINTS {
        return Err(PlanError::PointCount {
            wanted: opts.points,
        });
    }
    let space =
        DivisionSpace::new(rig, Space::Joint).map_err(|e| PlanError::Space(e.to_string()))?;
    let boxes = region_boxes(&space, opts.regions);
    let mut rng = ChaCha8Rng::seed_from_u64(opts.seed ^ 0x706c_616e);
    let mut dropped = Vec::new();
    let mut found: Vec<(usize, Vec<f64>, [f64; 3])> = Vec::new();
    let max_draws = opts.points.max(1) * 200;
    let mut drawn = 0;
    while found.len() < opts.points && drawn < max_draws {
        let q = random_poses(rig.chain.joints(), rig.held(), 1, &mut rng)
            .pop()
            .unwrap_or_default();
        drawn += 1;
        match rig.measurable(&q) {
            Err(reason) => dropped.push(Dropped { q, reason }),
            Ok(()) => {
                let t = target_point(rig, &q);
                if let Instrument::TablePanel(tp) = &rig.instrument {
                    // The approach starts below the contact and ends above it: that room must
                    // lie within the z travel, or the pin is already on the panel at the start.
                    let room = [opts.xy_room_mm, opts.xy_room_mm, opts.z_room_mm];
                    let short =
                        (0..3).find(|&k| t[k] < room[k] || t[k] > tp.travel_mm[k] - room[k]);
                    if let Some(k) = short {
                        dropped.push(Dropped {
                            q,
                            reason: Unmeasurable::TableTravel {
                                axis: ['x', 'y', 'z'][k],
                                position_mm: t[k],
                                travel_mm: tp.travel_mm[k],
                            },
                        });
                        continue;
                    }
                }
                let c = space.coords(&q);
                let region = boxes
                    .iter()
                    .position(|b| b.contains(&c, &space.full))
                    .unwrap_or(0);
                found.push((region, q, t));
            }
        }
    }
    if found.len() < opts.points {
        return Err(PlanError::TooFewPoints {
            found: found.len(),
            wanted: opts.points,
            drawn,
        });
    }
    // The reference: the point nearest the middle of the table's travel (of the planned points,
    // on a point-sensor rig).
    let middle: [f64; 3] = match &rig.instrument {
        Instrument::TablePanel(tp) => std::array::from_fn(|k| tp.travel_mm[k] / 2.0),
        _ => std::array::from_fn(|k| {
            found.iter().map(|f| f.2[k]).sum::<f64>() / found.len().max(1) as f64
        }),
    };
    let from_middle = |t: &[f64; 3]| (0..3).map(|k| (t[k] - middle[k]).powi(2)).sum::<f64>();
    let reference = found
        .iter()
        .min_by(|a, b| from_middle(&a.2).total_cmp(&from_middle(&b.2)))
        .map(|(_, q, t)| (q.clone(), *t));
    let mut order: Vec<usize> = (0..boxes.len()).collect();
    order.shuffle(&mut rng);
    let mut points: Vec<PlannedPoint> = Vec::with_capacity(found.len() + 8);
    let push = |region: String, q: Vec<f64>, t: [f64; 3], points: &mut Vec<PlannedPoint>| {
        points.push(PlannedPoint {
            point: points.len() + 1,
            region,
            q,
            table_mm: t,
        });
    };
    let metric = MoveTime::of(rig);
    let window = opts.window_mm.unwrap_or_else(|| z_window_mm(rig));
    let mut seq: Vec<(String, Vec<f64>, [f64; 3])> = Vec::with_capacity(found.len());
    for r in order {
        let mine: Vec<(Vec<f64>, [f64; 3])> = found
            .iter()
            .filter(|(reg, _, _)| *reg == r)
            .map(|(_, q, t)| (q.clone(), *t))
            .collect();
        let layer_mm = match opts.order {
            Ordering::Optimised => window,
            _ => opts.layer_mm,
        };
        let ordered = order_region_by(mine, layer_mm, opts.order, &metric);
        seq.extend(
            ordered
                .into_iter()
                .map(|(q, t)| (format!("r{}", r + 1), q, t)),
        );
    }
    let refs_before = match (&reference, opts.reference_every) {
        (None, _) | (_, 0) => Vec::new(),
        (Some(reference), every) => {
            let flex = if opts.order == Ordering::Optimised {
                every / REFERENCE_FLEX_DIVISOR
            } else {
                0
            };
            let contact = ContactSettings::of(rig);
            let cost = |a: &(Vec<f64>, [f64; 3]), b: &(Vec<f64>, [f64; 3])| {
                transition_s(&metric, &contact, a, b)
            };
            reference_places(&seq, reference, every, flex, &cost)
        }
    };
    if let (Some((q, t)), true) = (&reference, opts.reference_every > 0) {
        push(REFERENCE_REGION.into(), q.clone(), *t, &mut points);
    }
    let mut next_ref = refs_before.iter().peekable();
    for (k, (region, q, t)) in seq.into_iter().enumerate() {
        if next_ref.next_if(|&&j| j == k).is_some() {
            if let Some((rq, rt)) = &reference {
                push(REFERENCE_REGION.into(), rq.clone(), *rt, &mut points);
            }
        }
        push(region, q, t, &mut points);
    }
    Ok(Plan { points, dropped })
}

/// The drift reference's re-measurements may move this fraction of the interval (1/5: within
/// ±10 of every 50th point) to where the detour is least, in the optimised order.
const REFERENCE_FLEX_DIVISOR: usize = 5;

/// The places (indices into `seq`, ascending) before which the drift reference is measured
/// again: one near every `every`-th point, as many as the fixed schedule (before points
/// `every`, `2·every`, …), each within `flex` places of its schedule where its detour — to the
/// reference and back, against the move it interrupts, by `cost` — is least (ties: the
/// schedule's).
fn reference_places(
    seq: &[(String, Vec<f64>, [f64; 3])],
    reference: &(Vec<f64>, [f64; 3]),
    every: usize,
    flex: usize,
    cost: &impl Fn(&(Vec<f64>, [f64; 3]), &(Vec<f64>, [f64; 3])) -> f64,
) -> Vec<usize> {
    let point = |k: usize| (seq[k].1.clone(), seq[k].2);
    let detour = |k: usize| {
        if k == 0 {
            return cost(reference, &point(0));
        }
        let (a, b) = (point(k - 1), point(k));
        cost(&a, reference) + cost(reference, &b) - cost(&a, &b)
    };
    let mut places: Vec<usize> = Vec::new();
    for nominal in (1..).map(|m| m * every).take_while(|&k| k < seq.len()) {
        let lo = nominal
            .saturating_sub(flex)
            .max(places.last().map_or(0, |&p| p + 1));
        let hi = (nominal + flex).min(seq.len() - 1).max(lo);
        let best = (lo..=hi)
            .map(|k| (detour(k) - if k == nominal { 1e-9 } else { 0.0 }, k))
            .min_by(|a, b| a.0.total_cmp(&b.0))
            .map_or(nominal, |(_, k)| k);
        places.push(best);
    }
    places
}

/// The rig's time from the contact at `a` to the one at `b` as rigcal's contact procedure
/// moves (s, nominal heights): the table down to its travel height, the x-y travel beside the
/// arm ([`MoveTime::between`]), the table up to the approach start.
fn transition_s(
    metric: &MoveTime,
    c: &ContactSettings,
    a: &(Vec<f64>, [f64; 3]),
    b: &(Vec<f64>, [f64; 3]),
) -> f64 {
    let start = (b.1[2] - c.margin_mm).max(0.0);
    let h = c.travel_z(a.1[2], start);
    metric.axis_s(a.1[2] - h) + metric.between(&a.0, &a.1, &b.0, &b.1) + metric.axis_s(start - h)
}

/// Orders one region's points: ascending z layers, then x-y within a layer; for
/// [`Ordering::Optimised`], `layer_mm` is the z window and the metric the table's alone
/// ([`order_region_by`] with the arm's too).
pub fn order_region(
    pts: Vec<(Vec<f64>, [f64; 3])>,
    layer_mm: f64,
    order: Ordering,
) -> Vec<(Vec<f64>, [f64; 3])> {
    order_region_by(pts, layer_mm, order, &MoveTime::table_only())
}

/// [`order_region`] with `metric` the move time the optimised order minimises.
pub fn order_region_by(
    pts: Vec<(Vec<f64>, [f64; 3])>,
    layer_mm: f64,
    order: Ordering,
    metric: &MoveTime,
) -> Vec<(Vec<f64>, [f64; 3])> {
    if order != Ordering::Optimised {
        return layered(pts, layer_mm, order);
    }
    let items = pts
        .into_iter()
        .map(|point| crate::session::order::Item {
            lows: vec![point.1[2]],
            point,
        })
        .collect();
    let rule = crate::session::order::Rule {
        window_mm: layer_mm,
        strand_mm: layer_mm,
        slots: &[],
    };
    crate::session::order::optimised(items, &rule, metric)
}

/// The layered orders: ascending z layers of `layer_mm`, then x-y within a layer.
fn layered(
    mut pts: Vec<(Vec<f64>, [f64; 3])>,
    layer_mm: f64,
    order: Ordering,
) -> Vec<(Vec<f64>, [f64; 3])> {
    pts.sort_by(|a, b| a.1[2].total_cmp(&b.1[2]));
    let layer_mm = if layer_mm > 0.0 { layer_mm } else { f64::MAX };
    let z0 = pts.first().map_or(0.0, |p| p.1[2]);
    let layer = |p: &[f64; 3]| ((p[2] - z0) / layer_mm).floor() as i64;
    let mut out = Vec::with_capacity(pts.len());
    let mut at: Option<[f64; 2]> = None;
    let mut i = 0;
    while i < pts.len() {
        let l = layer(&pts[i].1);
        let mut j = i;
        while j < pts.len() && layer(&pts[j].1) == l {
            j += 1;
        }
        let mut group: Vec<(Vec<f64>, [f64; 3])> = pts[i..j].to_vec();
        match order {
            Ordering::ZThenXY => {
                group.sort_by(|a, b| a.1[0].total_cmp(&b.1[0]).then(a.1[1].total_cmp(&b.1[1])));
                out.extend(group);
            }
            Ordering::NearestNeighbour | Ordering::Optimised => {
                while !group.is_empty() {
                    let from = at.unwrap_or([group[0].1[0], group[0].1[1]]);
                    let k = (0..group.len())
                        .min_by(|&a, &b| {
                            let d = |p: &[f64; 3]| (p[0] - from[0]).hypot(p[1] - from[1]);
                            d(&group[a].1).total_cmp(&d(&group[b].1))
                        })
                        .unwrap_or(0);
                    let p = group.swap_remove(k);
                    at = Some([p.1[0], p.1[1]]);
                    out.push(p);
                }
            }
        }
        if let Some(p) = out.last() {
            at = Some([p.1[0], p.1[1]]);
        }
        i = j;
    }
    out
}

/// The side each joint approaches point `point` from: +1 (moving up to it) or −1, alternating
/// per point for the first moving joint, every second point for the next, and so on; 0 for a
/// held joint.
pub fn approach_signs(rig: &Rig, point: usize) -> Vec<i8> {
    let held = rig.held();
    let mut k = 0;
    (0..rig.chain.joints().len())
        .map(|j| {
            if held.get(j).copied().flatten().is_some() {
                0
            } else {
                let s = if (point >> k) & 1 == 1 { 1 } else { -1 };
                k += 1;
                s
            }
        })
        .collect()
}

/// The pre-approach (via) pose for `q`: each moving joint `delta` (rad) on the side opposite to
/// its approach sign, flipped where that would leave the joint limits.
pub fn via_pose(rig: &Rig, q: &[f64], signs: &[i8], delta: f64) -> Vec<f64> {
    q.iter()
        .zip(rig.chain.joints())
        .zip(signs)
        .map(|((&v, spec), &s)| {
            if s == 0 {
                return v;
            }
            let a = v - f64::from(s) * delta;
            if spec.within(a) {
                a
            } else {
                v + f64::from(s) * delta
            }
        })
        .collect()
}

/// How the contact is made; the session and the time estimate share it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ContactSettings {
    /// The approach starts this far below the nominal contact and ends as far above (mm).
    pub margin_mm: f64,
    /// Speed of the first, locating approach (mm/s).
    pub fast_mm_s: f64,
    /// How far the table backs off below the located contact before the final approach (mm).
    pub backoff_mm: f64,
    /// Joint offset of the pre-approach (via) pose (rad).
    pub via_delta: f64,
    /// Before travelling in x-y the table drops this far below both the current and the next
    /// approach height, so the panel does not sweep into the pin (mm).
    pub clearance_mm: f64,
    /// A touch farther than this from the panel centre is rejected as a bad reading and the
    /// contact repeated (mm; the table stands under the nominal tip).
    pub max_offset_mm: f64,
    /// The final touch may differ from the locating touch by this much in u and in v (mm);
    /// more, and the contact is repeated.
    pub max_disagreement_mm: f64,
    /// Tolerance of the z checks (mm): a locating touch within it of the approach start means
    /// the pin was already on the panel; a final touch more than it below the final approach's
    /// start cannot be right.
    pub z_tolerance_mm: f64,
    /// The final approach starts this far below the located contact (mm), reached at travel
    /// speed after the back-off: the locating touch reads at most `locate speed × (panel + bus
    /// latency)` above the true contact, so twice that (at least [`MIN_STANDOFF_MM`], at most
    /// the back-off) leaves the pin clear while only the last fraction of a millimetre is
    /// crept at the latency-rule speed. The baseline procedure creeps the whole back-off:
    /// its standoff is the back-off.
    pub standoff_mm: f64,
    /// The procedure these settings are for: the session runs it and the estimate walks it.
    pub procedure: ContactProcedure,
}

/// The least standoff of the final approach (mm).
pub const MIN_STANDOFF_MM: f64 = 0.05;

/// The final approach's standoff for a locating approach at `locate_mm_s` with the touch read
/// `latency_s` after contact, within `backoff_mm` (see [`ContactSettings::standoff_mm`]).
fn final_standoff_mm(locate_mm_s: f64, latency_s: f64, backoff_mm: f64) -> f64 {
    (2.0 * locate_mm_s * latency_s)
        .max(MIN_STANDOFF_MM)
        .min(backoff_mm)
}

impl Default for ContactSettings {
    fn default() -> Self {
        ContactSettings::from_config(&crate::devices::config::ContactConfig::default())
    }
}

impl ContactSettings {
    /// The rig file's `[devices.contact]` (its defaults when the file has none), the standoff
    /// from its panel and bus latencies: rigcal's procedure.
    pub fn of(rig: &Rig) -> Self {
        let cfg = crate::devices::config::DevicesConfig::read(rig);
        let latency_s = (cfg.panel.latency_ms + cfg.table.bus_latency_ms).max(0.0) / 1000.0;
        let mut s = ContactSettings::from_config(&cfg.contact);
        s.standoff_mm = final_standoff_mm(s.fast_mm_s, latency_s, s.backoff_mm);
        s
    }

    /// The settings of `procedure` on `rig`: [`ContactSettings::of`] for rigcal's; for the
    /// baseline, the back-off at least [`BASELINE_BACKOFF_MM`] and crept whole (the standoff
    /// at the back-off), every other threshold the rig file's.
    pub fn for_procedure(rig: &Rig, procedure: ContactProcedure) -> Self {
        let s = ContactSettings::of(rig);
        match procedure {
            ContactProcedure::Rigcal => s,
            ContactProcedure::Baseline => {
                let backoff_mm = s.backoff_mm.max(BASELINE_BACKOFF_MM);
                ContactSettings {
                    backoff_mm,
                    standoff_mm: backoff_mm,
                    procedure,
                    ..s
                }
            }
        }
    }

    /// The height the table travels in x-y at (mm) from a contact at `here_z` to a point whose
    /// lower approach start (its own or its via pose's) is `start_z`: rigcal's
    /// [`travel_height`]; the baseline's a clearance below both.
    pub fn travel_z(&self, here_z: f64, start_z: f64) -> f64 {
        match self.procedure {
            ContactProcedure::Rigcal => travel_height(here_z, start_z, self.clearance_mm),
            ContactProcedure::Baseline => (here_z.min(start_z) - self.clearance_mm).max(0.0),
        }
    }

    /// From the `[devices.contact]` section (the standoff from the default latencies).
    pub fn from_config(c: &crate::devices::config::ContactConfig) -> Self {
        let d = crate::devices::config::DevicesConfig::default();
        let latency_s = (d.panel.latency_ms + d.table.bus_latency_ms) / 1000.0;
        ContactSettings {
            standoff_mm: final_standoff_mm(c.locate_speed_mm_s, latency_s, c.backoff_mm),
            margin_mm: c.margin_mm,
            fast_mm_s: c.locate_speed_mm_s,
            backoff_mm: c.backoff_mm,
            via_delta: c.via_delta_deg.to_radians(),
            clearance_mm: c.clearance_mm,
            max_offset_mm: c.max_offset_mm,
            max_disagreement_mm: c.max_disagreement_mm,
            z_tolerance_mm: c.z_tolerance_mm,
            procedure: ContactProcedure::Rigcal,
        }
    }
}

/// Where the rig time of a session goes (s); the parts add up to the total.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct TimeBreakdown {
    /// Arm moves the table does not hide: the arm's part of the travel between points where it
    /// is the slower, and the short move from the via pose onto the target.
    pub arm_s: f64,
    /// Table travel in x-y where the table is the slower (arm and table move together).
    pub table_s: f64,
    /// The table's clearance moves: down before travelling, back up to the approach start.
    pub clearance_s: f64,
    /// Contact approaches: locating, back-off, final (on a point-sensor rig: the reading).
    pub approach_s: f64,
    /// Device exchanges and reply latencies (serial, CAN, touch packets).
    pub settling_s: f64,
    /// The registration poses, all their parts.
    pub registration_s: f64,
    /// The drift-reference poses, all their parts.
    pub reference_s: f64,
}

impl TimeBreakdown {
    /// The sum of the parts (s).
    pub fn total_s(&self) -> f64 {
        self.arm_s
            + self.table_s
            + self.clearance_s
            + self.approach_s
            + self.settling_s
            + self.registration_s
            + self.reference_s
    }

    fn add(&mut self, o: &TimeBreakdown) {
        self.arm_s += o.arm_s;
        self.table_s += o.table_s;
        self.clearance_s += o.clearance_s;
        self.approach_s += o.approach_s;
        self.settling_s += o.settling_s;
    }

    /// The parts with their names, in the order [`TimeBreakdown::describe`] gives them (s).
    pub fn parts(&self) -> [(&'static str, f64); 7] {
        [
            ("arm moves", self.arm_s),
            ("table moves", self.table_s),
            ("clearance moves", self.clearance_s),
            ("approaches", self.approach_s),
            ("settling", self.settling_s),
            ("registration", self.registration_s),
            ("drift references", self.reference_s),
        ]
    }

    /// One line: each part in s and as a share of the total.
    pub fn describe(&self) -> String {
        let t = self.total_s().max(1e-9);
        self.parts()
            .iter()
            .map(|(name, v)| format!("{name} {v:.0} s ({:.0} %)", 100.0 * v / t))
            .collect::<Vec<_>>()
            .join(", ")
    }
}

/// A rig-time estimate.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct RigTimeEstimate {
    /// Total (s).
    pub total_s: f64,
    /// Of which arm/table motion between points (arm, table and clearance moves, s).
    pub motion_s: f64,
    /// Of which contact approaches and device exchanges (s).
    pub contact_s: f64,
    /// Points, registration poses included.
    pub points: usize,
    /// Of which registration poses (region `reg`).
    pub registration_points: usize,
    /// Where the time goes.
    pub breakdown: TimeBreakdown,
}

/// The height the table travels in x-y at (mm): a clearance below the current contact `here_z`
/// (the pin there must not drag over the panel), or lower, at the next approach start
/// `start_z`, when that is lower still (already a margin below the next pin and its via pose).
pub fn travel_height(here_z: f64, start_z: f64, clearance_mm: f64) -> f64 {
    (here_z - clearance_mm).min(start_z).max(0.0)
}

/// Device exchanges of one point whose latencies the session waits out (counted from the
/// contact procedure): arm replies (move, pose check) for the via and the target moves, and
/// CAN rounds (speed, start, position, halt) plus touch latencies for the table's moves.
const ARM_REPLIES_PER_POINT: f64 = 4.0;
/// CAN exchanges per point whose bus latency the session waits out.
const CAN_ROUNDS_PER_POINT: f64 = 6.0;

/// The session's walk through the points, timed step by step as the contact procedure makes
/// them (the same moves, in the same order, on the same profiles).
struct Walk<'a> {
    rig: &'a Rig,
    speeds: &'a RigSpeeds,
    contact: &'a ContactSettings,
    q_at: Option<Vec<f64>>,
    table_at: [f64; 3],
}

impl Walk<'_> {
    fn arm_s(&self, from: &[f64], to: &[f64]) -> f64 {
        largest_joint_change_deg(from, to) / self.speeds.arm_deg_s.max(1e-9)
    }

    fn axis_s(&self, from: f64, to: f64, v: f64) -> f64 {
        let s = self.speeds;
        Profile::new(
            std::time::Duration::ZERO,
            from,
            to,
            v,
            s.table_acc,
            s.table_dec,
        )
        .duration_s()
    }

    fn table_s(&self, from: [f64; 3], to: [f64; 3]) -> f64 {
        (0..3)
            .map(|k| self.axis_s(from[k], to[k], self.speeds.table_mm_s))
            .fold(0.0, f64::max)
    }

    /// One point of the table-and-panel rig, as [`crate::session`]'s contact procedure makes
    /// it: the table down to its travel height (a clearance below the current contact, or the
    /// approach start when that is lower still), x-y beside the arm's move to the via pose, up
    /// to the approach start beside the arm's move onto the target, the locating approach, the
    /// back-off, the quick rise to the standoff, the final approach; or as the baseline
    /// procedure makes it ([`ContactProcedure::Baseline`]: a clearance below both heights, the
    /// rise after the arm's move, the whole back-off crept).
    fn contact_point(&mut self, p: &PlannedPoint) -> TimeBreakdown {
        let (c, s) = (self.contact, self.speeds);
        let mut t = TimeBreakdown::default();
        let signs = approach_signs(self.rig, p.point);
        let via = via_pose(self.rig, &p.q, &signs, c.via_delta);
        let start_z = (p.table_mm[2] - c.margin_mm).max(0.0);
        let via_z = table_target(self.rig, &via).map_or(start_z, |v| v[2] - c.margin_mm);
        let rise_z = start_z.min(via_z).max(0.0);
        let here = self.table_at;
        let clear = c.travel_z(here[2], rise_z);
        if here[2] > clear + 1e-3 {
            t.clearance_s += self.axis_s(here[2], clear, s.table_mm_s);
        }
        let arm = self.q_at.as_deref().map_or(0.0, |q| self.arm_s(q, &via));
        let table = self.table_s(
            [here[0], here[1], clear],
            [p.table_mm[0], p.table_mm[1], clear],
        );
        if arm >= table {
            t.arm_s += arm;
        } else {
            t.table_s += table;
        }
        let onto = self.arm_s(&via, &p.q);
        match c.procedure {
            // The arm onto the target, then the table up to the approach start.
            ContactProcedure::Baseline => {
                t.arm_s += onto;
                t.clearance_s += self.axis_s(clear, start_z, s.table_mm_s);
            }
            // The arm onto the target while the table rises to the lower of both approach
            // starts.
            ContactProcedure::Rigcal => {
                let rise = if rise_z > clear + 1e-3 {
                    self.axis_s(clear, rise_z, s.table_mm_s)
                } else {
                    0.0
                };
                if onto >= rise {
                    t.arm_s += onto;
                } else {
                    t.clearance_s += rise;
                }
                if start_z > rise_z + 1e-3 {
                    t.clearance_s += self.axis_s(rise_z, start_z, s.table_mm_s);
                }
            }
        }
        let contact_z = p.table_mm[2];
        let back = contact_z - c.backoff_mm;
        let standoff = contact_z - c.standoff_mm;
        t.approach_s += self.axis_s(start_z, contact_z, c.fast_mm_s)
            + self.axis_s(contact_z, back, s.table_mm_s)
            + self.axis_s(back, standoff, s.table_mm_s)
            + self.axis_s(standoff, contact_z, s.approach_mm_s);
        t.settling_s += 2.0 * s.touch_latency_s
            + ARM_REPLIES_PER_POINT * s.arm_reply_s
            + CAN_ROUNDS_PER_POINT * s.bus_latency_s;
        self.table_at = p.table_mm;
        t
    }

    /// One point of a point-sensor rig.
    fn sensor_point(&mut self, p: &PlannedPoint) -> TimeBreakdown {
        let signs = approach_signs(self.rig, p.point);
        let via = via_pose(self.rig, &p.q, &signs, self.contact.via_delta);
        let mut t = TimeBreakdown::default();
        t.arm_s +=
            self.q_at.as_deref().map_or(0.0, |q| self.arm_s(q, &via)) + self.arm_s(&via, &p.q);
        t.approach_s += crate::devices::emulators::sensor::SENSOR_LATENCY.as_secs_f64();
        t.settling_s += ARM_REPLIES_PER_POINT * self.speeds.arm_reply_s;
        t
    }
}

/// Estimates the rig time of `points` from the device speeds, walking the session's own
/// sequence per point (the contact procedure's moves on the drives' profiles): the table down
/// to its clearance height, arm and table together to the via pose and the approach start (the
/// slower counts), the arm onto the target, the table up to the approach start, the locating
/// approach, the back-off, the final approach; a sensor reading on a point-sensor rig; the
/// device exchanges' latencies besides. Registration and drift-reference poses are counted
/// apart in the breakdown.
pub fn estimate(
    rig: &Rig,
    points: &[PlannedPoint],
    speeds: &RigSpeeds,
    contact: &ContactSettings,
) -> RigTimeEstimate {
    let table_rig = matches!(rig.instrument, Instrument::TablePanel(_));
    // From the arm's nest, the table centred in x-y at the bottom of z (where it powers up).
    let cfg = crate::devices::config::DevicesConfig::read(rig);
    let nest = (cfg.arm.nest_deg.len() == rig.chain.joints().len())
        .then(|| cfg.arm.nest_deg.iter().map(|d| d.to_radians()).collect());
    let table_start = match &rig.instrument {
        Instrument::TablePanel(tp) => [tp.travel_mm.x / 2.0, tp.travel_mm.y / 2.0, 0.0],
        _ => [0.0; 3],
    };
    let mut walk = Walk {
        rig,
        speeds,
        contact,
        q_at: nest,
        table_at: table_start,
    };
    let mut est = RigTimeEstimate {
        points: points.len(),
        registration_points: points.iter().filter(|p| p.region == "reg").count(),
        ..Default::default()
    };
    let b = &mut est.breakdown;
    for p in points {
        let t = if table_rig {
            walk.contact_point(p)
        } else {
            walk.sensor_point(p)
        };
        walk.q_at = Some(p.q.clone());
        est.motion_s += t.arm_s + t.table_s + t.clearance_s;
        est.contact_s += t.approach_s + t.settling_s;
        match p.region.as_str() {
            "reg" => b.registration_s += t.total_s(),
            REFERENCE_REGION => b.reference_s += t.total_s(),
            _ => b.add(&t),
        }
    }
    est.total_s = est.motion_s + est.contact_s;
    est
}

/// Writes `plan.csv`: `point,region,q1_deg..qN_deg,table_x_mm,table_y_mm,table_z_mm` (on a
/// point-sensor rig `tip_x_mm,tip_y_mm,tip_z_mm`, the nominal marker position in the world).
pub fn write_plan(path: &Path, rig: &Rig, points: &[PlannedPoint]) -> Result<(), PlanError> {
    use std::fmt::Write;
    let joints = rig.chain.joints();
    let mut s = plan_columns(rig).join(",");
    s.push('\n');
    for p in points {
        let _ = write!(s, "{},{}", p.point, p.region);
        for (spec, v) in joints.iter().zip(&p.q) {
            let _ = write!(s, ",{}", spec.kind.to_file_units(*v));
        }
        let _ = writeln!(s, ",{},{},{}", p.table_mm[0], p.table_mm[1], p.table_mm[2]);
    }
    std::fs::write(path, s).map_err(|source| PlanError::Io {
        path: path.to_path_buf(),
        source,
    })
}

/// The columns of this rig's `plan.csv`, in the order [`write_plan`] writes them: `point`,
/// `region`, the joint columns (`q1_deg`…), then the target (`table_x_mm`… on a table-panel
/// rig, `tip_x_mm`… otherwise).
fn plan_columns(rig: &Rig) -> Vec<String> {
    let target = match rig.instrument {
        Instrument::TablePanel(_) => ["table_x_mm", "table_y_mm", "table_z_mm"],
        _ => ["tip_x_mm", "tip_y_mm", "tip_z_mm"],
    };
    let joints = rig.chain.joints().iter().enumerate();
    ["point".to_string(), "region".to_string()]
        .into_iter()
        .chain(joints.map(|(i, j)| j.kind.column(i + 1)))
        .chain(target.iter().map(|c| c.to_string()))
        .collect()
}

/// Reads a `plan.csv` written by [`write_plan`] (or by hand, same columns).
///
/// Columns are found by their header names (in any order; unknown columns are ignored), so a
/// file without a header, with a column twice, or without a needed column is refused rather
/// than read wrongly; so is a plan with no point. A byte-order mark is accepted.
pub fn read_plan(path: &Path, rig: &Rig) -> Result<Vec<PlannedPoint>, PlanError> {
    let text = std::fs::read_to_string(path).map_err(|source| PlanError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    let text = text.strip_prefix('\u{feff}').unwrap_or(&text);
    if text.trim().is_empty() {
        return Err(PlanError::EmptyPlan {
            path: path.to_path_buf(),
        });
    }
    let joints = rig.chain.joints();
    let columns = plan_columns(rig);
    let expected = columns.join(",");
    let bad = |line: usize, reason: String| PlanError::Malformed {
        path: path.to_path_buf(),
        line,
        reason,
    };
    let mut lines = text.lines().enumerate();
    let header: Vec<&str> = match lines.next() {
        Some((_, l)) => l.split(',').map(str::trim).collect(),
        None => Vec::new(),
    };
    // A first line whose first field is a number is a point, not a header: reading on would
    // lose it (or read the next point's values under wrong names).
    let first = header.first().copied().unwrap_or("");
    if !header.contains(&"point") && first.parse::<f64>().is_ok() {
        return Err(PlanError::MissingHeader {
            path: path.to_path_buf(),
            first: header.join(","),
            expected,
        });
    }
    for (k, h) in header.iter().enumerate() {
        if header[..k].contains(h) {
            return Err(PlanError::DuplicateColumn {
                path: path.to_path_buf(),
                column: (*h).to_string(),
            });
        }
    }
    let at = columns
        .iter()
        .map(|c| {
            header
                .iter()
                .position(|h| h == c)
                .ok_or_else(|| PlanError::MissingColumn {
                    path: path.to_path_buf(),
                    column: c.clone(),
                    expected: expected.clone(),
                })
        })
        .collect::<Result<Vec<usize>, _>>()?;
    let n = header.len();
    let mut out = Vec::new();
    for (i, l) in lines {
        if l.trim().is_empty() {
            continue;
        }
        let f: Vec<&str> = l.split(',').map(str::trim).collect();
        if f.len() != n {
            return Err(bad(i + 1, format!("{} fields, expected {n}", f.len())));
        }
        let num = |k: usize| -> Result<f64, PlanError> {
            f[k].parse::<f64>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or_else(|| {
                    bad(
                        i + 1,
                        format!(
                            "field {} (`{}`, column `{}`) is not a number",
                            k + 1,
                            f[k],
                            header[k]
                        ),
                    )
                })
        };
        let point = f[at[0]]
            .parse::<usize>()
            .map_err(|_| bad(i + 1, format!("point `{}` is not a whole number", f[at[0]])))?;
        let q = (0..joints.len())
            .map(|j| num(at[2 + j]).map(|v| joints[j].kind.from_file_units(v)))
            .collect::<Result<Vec<_>, _>>()?;
        if let Some((j, v)) = q.iter().enumerate().find(|(j, v)| !joints[*j].within(**v)) {
            let spec = &joints[j];
            let unit = |x: f64| spec.kind.to_file_units(x);
            return Err(bad(
                i + 1,
                format!(
                    "joint {} at {:.4} is outside its limits [{:.4}, {:.4}] ({}): the plan was \
                     made for another rig or edited; make it again with `rigcal plan`",
                    spec.name,
                    unit(*v),
                    unit(spec.min),
                    unit(spec.max),
                    spec.kind.unit()
                ),
            ));
        }
        let t0 = 2 + joints.len();
        let t = [num(at[t0])?, num(at[t0 + 1])?, num(at[t0 + 2])?];
        out.push(PlannedPoint {
            point,
            region: f[at[1]].to_string(),
            q,
            table_mm: t,
        });
    }
    if out.is_empty() {
        return Err(PlanError::EmptyPlan {
            path: path.to_path_buf(),
        });
    }
    Ok(out)
}
