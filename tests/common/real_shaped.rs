//! Real-shaped recordings for the diagnosis's rates (issue 35, item 5): the recordings of
//! [`super::shapes`] with what real recordings have and white noise does not.
//!
//! - **Pose-dependent repeatability**: besides the instrument's white noise (σ = 0.02 mm per
//!   coordinate), each row gets an arm repeatability of 0–0.02 mm per coordinate that varies
//!   smoothly with joint 2's angle, σ_r(q) = 0.02·(0.5 + 0.5·sin(q₂ + φ)) mm, φ random: the two
//!   repeated `ref` poses see one value of it each, so the floor taken from them is off by up to
//!   ±30 % for the rest of the workspace.
//! - **A smooth un-modelled residual at the floor**: a local Cartesian deformation of the
//!   measured points (the instrument or its fixture bending in one place) whose peak is the
//!   noise floor √3·σ, width a quarter to a third of the workspace's spread, centre and
//!   direction random.
//! - **Outliers**: three rows moved by 0.6 mm (17× the floor) in random directions (none in a
//!   recording of fewer than 30 rows, where three would be a tenth of it).
//! - **Few poses**: [`Realism::poses`] of 20–60 measurements instead of 600.
//! - **Sessions with moved frames**: [`sessions`] records further sessions of the same arm and
//!   effect at other poses, each with its own deformation, noise and outliers, seen through a
//!   measurement frame rotated 2–10° about a random axis and shifted 20–200 mm.
//!
//! Units: mm; radians inside.
#![allow(dead_code)]

use super::shapes::{floor, poses, record, Case, Deformation, NOISE_MM};
use nalgebra::{Rotation3, Unit, Vector3};
use rand::rngs::ChaCha8Rng;
use rand::{RngExt, SeedableRng};
use rigcal_core::recording::Recording;
use rigcal_model::identification::HeldOut;

/// Peak of the extra, pose-dependent repeatability (mm per coordinate).
pub const REPEATABILITY_MM: f64 = NOISE_MM;
/// Size of a gross row (mm).
pub const OUTLIER_MM: f64 = 0.6;
/// Gross rows per recording.
pub const OUTLIERS: usize = 3;

/// A standard normal draw (Box–Muller).
fn normal(rng: &mut ChaCha8Rng) -> f64 {
    let (u1, u2): (f64, f64) = (rng.random::<f64>().max(1e-12), rng.random());
    (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
}

fn random_unit(rng: &mut ChaCha8Rng) -> Vector3<f64> {
    Vector3::new(normal(rng), normal(rng), normal(rng)).normalize()
}

/// Adds the real-shaped parts to `rec` (already holding the instrument's white noise and the
/// hidden physics): the deformation at the floor, pose-dependent repeatability and the gross
/// rows. Deterministic in `seed`.
pub fn roughen(rec: &mut Recording, seed: u64) {
    roughen_with(rec, seed, OUTLIERS);
}

/// [`roughen`] with `outliers` gross rows (none in fewer than 10 rows per gross row).
pub fn roughen_with(rec: &mut Recording, seed: u64, outliers: usize) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x7ea1_5aed);
    let pts: Vec<Vector3<f64>> = rec.rows.iter().filter_map(|r| r.position).collect();
    if pts.is_empty() {
        return;
    }
    let mean = pts.iter().sum::<Vector3<f64>>() / pts.len() as f64;
    let spread =
        (pts.iter().map(|p| (p - mean).norm_squared()).sum::<f64>() / pts.len() as f64).sqrt();
    Deformation {
        centre: pts[rng.random_range(0..pts.len())],
        width: spread * rng.random_range(0.25..0.35),
        direction: random_unit(&mut rng),
        amplitude: floor(),
    }
    .apply(rec);
    let phase = rng.random_range(0.0..std::f64::consts::TAU);
    for row in &mut rec.rows {
        let s = REPEATABILITY_MM * (0.5 + 0.5 * (row.q[1] + phase).sin());
        if let Some(p) = row.position.as_mut() {
            for a in 0..3 {
                p[a] += s * normal(&mut rng);
            }
        }
    }
    let n = rec.rows.len();
    if n >= 10 * outliers {
        for _ in 0..outliers {
            let k = rng.random_range(0..n);
            let u = random_unit(&mut rng);
            if let Some(p) = rec.rows[k].position.as_mut() {
                *p += u * OUTLIER_MM;
            }
        }
    }
}

/// The measured points of `rec` seen through a moved measurement frame: rotated 2–10° about a
/// random axis and shifted 20–200 mm in a random direction.
pub fn move_frame(rec: &mut Recording, seed: u64) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0xf4a3_e000);
    let axis = Unit::new_normalize(random_unit(&mut rng));
    let rot = Rotation3::from_axis_angle(&axis, rng.random_range(2.0f64..10.0).to_radians());
    let shift = random_unit(&mut rng) * rng.random_range(20.0..200.0);
    for row in &mut rec.rows {
        if let Some(p) = row.position.as_mut() {
            *p = rot * *p + shift;
        }
    }
}

/// `count` further sessions of the case's arm and effect (the scenario's world; a deformation
/// applied after recording, as [`Deformation`] cases are, is not in it): `n` new poses each,
/// roughened and seen through a moved frame.
pub fn sessions(case: &Case, count: usize, n: usize, seed: u64) -> Vec<HeldOut> {
    (0..count)
        .map(|k| {
            let s = seed.wrapping_mul(31).wrapping_add(k as u64 + 1);
            let (p, r) = poses(&case.scenario, n, 50_000 + s);
            let mut rec = record(&case.scenario, &p, &r);
            roughen(&mut rec, 60_000 + s);
            move_frame(&mut rec, 70_000 + s);
            HeldOut {
                name: format!("session {}", k + 2),
                recording: rec,
            }
        })
        .collect()
}

/// The realism classes of the rate table.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Realism {
    /// 600 measurements, roughened.
    Rough,
    /// 20–60 measurements, roughened.
    FewPoses,
    /// 600 measurements roughened, judged with two held-out sessions of 200 (frames moved).
    Sessions,
    /// 20–60 measurements, roughened without gross rows: not a target row, it separates the
    /// two causes of [`Realism::FewPoses`]'s misses.
    FewPosesNoGross,
}

impl Realism {
    /// Every class.
    pub const ALL: [Realism; 4] = [
        Realism::Rough,
        Realism::FewPoses,
        Realism::Sessions,
        Realism::FewPosesNoGross,
    ];

    /// In words, for the table.
    pub fn name(self) -> &'static str {
        match self {
            Realism::Rough => "600 poses, rough",
            Realism::FewPoses => "20–60 poses, rough",
            Realism::Sessions => "600 poses + 2 sessions of 200, frames moved",
            Realism::FewPosesNoGross => "20–60 poses, rough but no gross rows (diagnostic)",
        }
    }

    /// A short key (`RIGCAL_REALISM` in `tests/real_shaped.rs` picks classes by it).
    pub fn key(self) -> &'static str {
        match self {
            Realism::Rough => "rough",
            Realism::FewPoses => "few",
            Realism::Sessions => "sessions",
            Realism::FewPosesNoGross => "few-no-gross",
        }
    }

    /// Measurements of the training recording for seed `seed`: 20–60 for [`Realism::FewPoses`]
    /// (spread over the seeds), else 600.
    pub fn poses(self, seed: u64) -> usize {
        match self {
            Realism::FewPoses | Realism::FewPosesNoGross => 20 + (seed % 5) as usize * 10,
            _ => super::shapes::MEASUREMENTS,
        }
    }

    /// Gross rows added to a recording of the class.
    pub fn outliers(self) -> usize {
        match self {
            Realism::FewPosesNoGross => 0,
            _ => OUTLIERS,
        }
    }

    /// Held-out sessions for the case (none but for [`Realism::Sessions`]).
    pub fn sessions(self, case: &Case, seed: u64) -> Vec<HeldOut> {
        match self {
            Realism::Sessions => sessions(case, 2, 200, seed),
            _ => Vec::new(),
        }
    }
}
