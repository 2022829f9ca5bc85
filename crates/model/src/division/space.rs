//! Division spaces and region boxes. Joint coordinates in rad (or mm for a prismatic major
//! joint); spherical coordinates R in mm, azimuth and elevation in rad.

use rand::RngExt;
use rigcal_core::kinematics::{
    solve_position_ik, ErrorParams, IkOptions, Robot, SerialChain, Spherical, SphericalFrame,
};
use rigcal_core::rig::Rig;
use serde::{Deserialize, Serialize};

/// Which space the workspace is divided in.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Space {
    /// The major joints (q1, q2, q3 for the RV-M2).
    Joint,
    /// Spherical workspace coordinates (R, azimuth, elevation).
    Cartesian,
}

impl Space {
    /// The paper's region cap: 110 regions in joint space, 130 in Cartesian space (seed 000
    /// section 6).
    pub fn paper_region_cap(self) -> usize {
        match self {
            Space::Joint => 110,
            Space::Cartesian => 130,
        }
    }

    /// The paper's figures for a division in this space at its section 6 settings (0.1 mm
    /// demanded, 20 per region), for a printed comparison.
    pub fn paper_figures(self) -> &'static str {
        match self {
            Space::Joint => "110 regions, 2200 measurements at section 6's 0.1 mm",
            Space::Cartesian => "130 regions, 2600 measurements at section 6's 0.1 mm",
        }
    }
}

/// An axis-aligned box in a division space.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Bounds {
    /// Lower corner.
    pub lo: [f64; 3],
    /// Upper corner.
    pub hi: [f64; 3],
}

impl Bounds {
    /// True when `x` lies in the box (lower faces closed, upper faces open, except at the
    /// workspace's own upper faces, which `full` closes).
    pub fn contains(&self, x: &[f64; 3], full: &Bounds) -> bool {
        (0..3).all(|k| {
            x[k] >= self.lo[k]
                && (x[k] < self.hi[k] || (self.hi[k] >= full.hi[k] && x[k] <= self.hi[k]))
        })
    }

    /// The dimension to split: the widest as a fraction of the full range, ties to the first.
    pub fn widest(&self, full: &Bounds) -> usize {
        let frac = |k: usize| (self.hi[k] - self.lo[k]) / (full.hi[k] - full.lo[k]);
        let mut best = 0;
        for k in 1..3 {
            if frac(k) > frac(best) + 1e-12 {
                best = k;
            }
        }
        best
    }

    /// The two equal halves across dimension `k`.
    pub fn halves(&self, k: usize) -> (Bounds, Bounds) {
        let mid = 0.5 * (self.lo[k] + self.hi[k]);
        let mut a = *self;
        let mut b = *self;
        a.hi[k] = mid;
        b.lo[k] = mid;
        (a, b)
    }

    /// The box's share of `full`'s volume (in the division space's own coordinates).
    pub fn volume_share(&self, full: &Bounds) -> f64 {
        (0..3)
            .map(|k| {
                let w = full.hi[k] - full.lo[k];
                if w > 0.0 {
                    (self.hi[k] - self.lo[k]) / w
                } else {
                    1.0
                }
            })
            .product()
    }

    /// Smallest width as a fraction of the full range.
    pub fn min_fraction(&self, full: &Bounds) -> f64 {
        (0..3)
            .map(|k| (self.hi[k] - self.lo[k]) / (full.hi[k] - full.lo[k]))
            .fold(f64::INFINITY, f64::min)
    }

    /// The region of depth `depth` of a division of `full` that contains `x`, with its id (`r`,
    /// `r0`, `r01`, …): every split halves its region across the widest dimension, so the
    /// regions containing a point depend on the geometry alone, not on the measurements.
    pub fn region_at(full: &Bounds, x: &[f64; 3], depth: usize) -> (Bounds, String) {
        let mut b = *full;
        let mut id = String::from("r");
        for _ in 0..depth {
            let (lo, hi) = b.halves(b.widest(full));
            if lo.contains(x, full) {
                b = lo;
                id.push('0');
            } else {
                b = hi;
                id.push('1');
            }
        }
        (b, id)
    }

    /// True when `other` lies inside this box (faces may coincide).
    pub fn encloses(&self, other: &Bounds) -> bool {
        (0..3).all(|k| self.lo[k] <= other.lo[k] + 1e-12 && other.hi[k] <= self.hi[k] + 1e-12)
    }

    /// True when the two boxes share part of a face: they touch across one dimension and
    /// overlap (with positive width) in the other two.
    pub fn shares_face(&self, other: &Bounds) -> bool {
        let touch = |k: usize| {
            (self.hi[k] - other.lo[k]).abs() < 1e-12 || (other.hi[k] - self.lo[k]).abs() < 1e-12
        };
        let overlap = |k: usize| self.lo[k].max(other.lo[k]) < self.hi[k].min(other.hi[k]) - 1e-12;
        (0..3).any(|k| touch(k) && (0..3).filter(|&j| j != k).all(overlap))
    }

    /// True when `x` lies in the box, every face closed.
    pub fn holds(&self, x: &[f64; 3]) -> bool {
        (0..3).all(|k| x[k] >= self.lo[k] && x[k] <= self.hi[k])
    }

    /// The point at unit-cube coordinates `u` (each in 0..=1) of the box.
    pub fn at_unit(&self, u: &[f64; 3]) -> [f64; 3] {
        std::array::from_fn(|k| self.lo[k] + u[k] * (self.hi[k] - self.lo[k]))
    }

    /// The centre.
    pub fn centre(&self) -> [f64; 3] {
        [
            0.5 * (self.lo[0] + self.hi[0]),
            0.5 * (self.lo[1] + self.hi[1]),
            0.5 * (self.lo[2] + self.hi[2]),
        ]
    }
}

/// A division space for one rig: maps poses to coordinates and samples poses in boxes.
#[derive(Debug, Clone)]
pub struct DivisionSpace {
    /// The space.
    pub space: Space,
    /// The whole workspace.
    pub full: Bounds,
    major: [usize; 3],
    spherical: SphericalFrame,
    rig: Rig,
    /// The chain in world coordinates (measurement frame left out), built once: coordinates
    /// are asked for on every compensation and learner query.
    world: SerialChain,
    nominal: ErrorParams,
}

/// Why a division space cannot be set up for a rig.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum SpaceError {
    /// Joint-space division needs three moving joints.
    #[error("joint-space division needs at least three moving joints; this rig moves {moving}")]
    TooFewJoints {
        /// Moving joints.
        moving: usize,
    },
}

impl DivisionSpace {
    /// The division space of a rig. Joint space uses the first three moving joints; Cartesian
    /// space uses the rig's `[workspace]` bounds, or bounds sampled from random poses when the
    /// rig file gives none.
    pub fn new(rig: &Rig, space: Space) -> Result<Self, SpaceError> {
        let moving = rig.moving_joints();
        let spherical = SphericalFrame::of(&rig.chain);
        let (major, full) = match space {
            Space::Joint => {
                if moving.len() < 3 {
                    return Err(SpaceError::TooFewJoints {
                        moving: moving.len(),
                    });
                }
                let j = rig.chain.joints();
                let major = [moving[0], moving[1], moving[2]];
                (
                    major,
                    Bounds {
                        lo: major.map(|m| j[m].min),
                        hi: major.map(|m| j[m].max),
                    },
                )
            }
            Space::Cartesian => {
                let full = match rig.spherical_bounds {
                    Some(b) => Bounds {
                        lo: [b[0][0], b[1][0], b[2][0]],
                        hi: [b[0][1], b[1][1], b[2][1]],
                    },
                    None => sampled_spherical_bounds(rig, &spherical),
                };
                ([0, 1, 2], full)
            }
        };
        let world = rig.chain.with_frame(nalgebra::Isometry3::identity());
        let nominal = ErrorParams::zeros(world.layout());
        Ok(Self {
            space,
            full,
            major,
            spherical,
            rig: rig.clone(),
            world,
            nominal,
        })
    }

    /// Coordinates of a pose in this space.
    pub fn coords(&self, q: &[f64]) -> [f64; 3] {
        match self.space {
            Space::Joint => self.major.map(|m| q[m]),
            Space::Cartesian => {
                let p = self.world.position(q, &self.nominal);
                let s = self.spherical.to_spherical(&p);
                [s.r, s.azimuth, s.elevation]
            }
        }
    }

    /// A pose in box `b` drawn at random, measurable on the rig, or None after `tries` attempts;
    /// `seed` as for [`Self::pose_at`].
    pub fn sample<R: RngExt + ?Sized>(
        &self,
        b: &Bounds,
        rng: &mut R,
        tries: usize,
        seed: Option<&[f64]>,
    ) -> Option<Vec<f64>> {
        (0..tries).find_map(|_| {
            let x: [f64; 3] = std::array::from_fn(|k| rng.random_range(b.lo[k]..=b.hi[k]));
            self.pose_at(b, &x, rng, seed)
        })
    }

    /// A measurable pose whose coordinates are `x`, inside box `b`, or None (no inverse
    /// kinematics for a Cartesian point, not measurable on the rig, or outside `b`). Joints that
    /// are neither major nor held are drawn from `rng`. In Cartesian space the inverse
    /// kinematics starts from `seed` (a pose of the same region), so a region's poses share one
    /// arm configuration (seed 000 section 4.2: one configuration per Cartesian division) and
    /// few starts are needed.
    pub fn pose_at<R: RngExt + ?Sized>(
        &self,
        b: &Bounds,
        x: &[f64; 3],
        rng: &mut R,
        seed: Option<&[f64]>,
    ) -> Option<Vec<f64>> {
        let joints = self.rig.chain.joints();
        let held = self.rig.held();
        let q = match self.space {
            Space::Joint => {
                let mut q: Vec<f64> = joints
                    .iter()
                    .enumerate()
                    .map(|(j, s)| held[j].unwrap_or_else(|| rng.random_range(s.min..=s.max)))
                    .collect();
                for (k, &m) in self.major.iter().enumerate() {
                    q[m] = x[k];
                }
                q
            }
            Space::Cartesian => {
                let p = self.spherical.to_world(&Spherical {
                    r: x[0],
                    azimuth: x[1],
                    elevation: x[2],
                });
                // From a seed in the region a reachable point converges in a few steps; an
                // unreachable one (a spherical box reaches beyond the arm) is given up early.
                let opts = match seed {
                    Some(_) => IkOptions {
                        max_starts: 3,
                        max_iterations: 25,
                        ..IkOptions::default()
                    },
                    None => IkOptions {
                        max_starts: 8,
                        ..IkOptions::default()
                    },
                };
                solve_position_ik(&self.world, &self.nominal, &p, held, seed, &opts).ok()?
            }
        };
        (self.rig.measurable(&q).is_ok() && b.contains(&self.coords(&q), &self.full)).then_some(q)
    }
}

fn sampled_spherical_bounds(rig: &Rig, sf: &SphericalFrame) -> Bounds {
    use rand::SeedableRng;
    let mut rng = rand::rngs::ChaCha8Rng::seed_from_u64(0x5eed);
    let poses = crate::identification::random_poses(rig.chain.joints(), rig.held(), 4000, &mut rng);
    let world = rig.chain.with_frame(nalgebra::Isometry3::identity());
    let e = ErrorParams::zeros(world.layout());
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for q in poses {
        let s = sf.to_spherical(&world.position(&q, &e));
        for (k, v) in [s.r, s.azimuth, s.elevation].into_iter().enumerate() {
            lo[k] = lo[k].min(v);
            hi[k] = hi[k].max(v);
        }
    }
    Bounds { lo, hi }
}
