//! The instrument's truth: Gaussian measurement noise, arm repeatability scatter, table accuracy
//! and the touch panel (its area, the 15° pin rule and the quantisation of its counts).
//!
//! Panel counts (conventions §8): cx = ⌊(u + W/2) · Nx / W⌋, reported back as
//! u = (cx + 0.5) · W/Nx − W/2 along table +x; likewise v along table +y (W × H = 133 × 80 mm,
//! Nx × Ny = 512 × 256). Rounding to a cell centre leaves an error uniform over one count, RMS
//! count/√12 ≈ 0.075 / 0.090 mm.
//!
//! Units: mm; angles in radians inside.

use nalgebra::{Isometry3, Vector3};
use rand::rngs::ChaCha8Rng;
use rand::SeedableRng;
use rand_distr::{Distribution, StandardNormal};
use rigcal_core::rig::TablePanel;

/// Random-error settings of a simulated measurement (mm, 1σ per coordinate).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MeasurementSettings {
    /// Gaussian noise added to the measured point.
    pub noise_mm: f64,
    /// Scatter of the pin tip from move to move (the arm's repeatability).
    pub arm_repeatability_mm: f64,
    /// Noise of each table axis reading (table_panel rigs).
    pub table_accuracy_mm: f64,
    /// Whether the panel reports quantised counts (table_panel rigs).
    pub quantise: bool,
    /// Seconds between measurements in `rigcal simulate`.
    pub seconds_per_point: f64,
}

impl MeasurementSettings {
    /// Only Gaussian noise of σ `noise_mm`, one second per point.
    pub fn noise_only(noise_mm: f64) -> Self {
        Self {
            noise_mm,
            arm_repeatability_mm: 0.0,
            table_accuracy_mm: 0.0,
            quantise: false,
            seconds_per_point: 1.0,
        }
    }
}

/// Standard-normal draws of one measurement, in a fixed order so they depend on
/// (seed, seq, attempt) alone whatever the settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Draws {
    /// For the Gaussian noise of the measured point.
    pub noise: Vector3<f64>,
    /// For the arm's repeatability scatter.
    pub arm: Vector3<f64>,
    /// For the table's reading noise.
    pub table: Vector3<f64>,
}

impl Draws {
    /// The draws of measurement `seq`, attempt `attempt`.
    pub fn new(seed: u64, seq: u64, attempt: u32) -> Self {
        let mut rng = draw_rng(seed, seq, attempt);
        let mut v = || {
            Vector3::from_fn(|_, _| {
                let z: f64 = StandardNormal.sample(&mut rng);
                z
            })
        };
        let noise = v();
        let arm = v();
        let table = v();
        Self { noise, arm, table }
    }
}

/// The generator for one measurement's draws: a function of (seed, seq, attempt) only.
fn draw_rng(seed: u64, seq: u64, attempt: u32) -> ChaCha8Rng {
    let mut key = [0u8; 32];
    key[..8].copy_from_slice(&seed.to_le_bytes());
    key[8..16].copy_from_slice(&seq.to_le_bytes());
    key[16..20].copy_from_slice(&attempt.to_le_bytes());
    key[20..].copy_from_slice(b"rigcal-world");
    ChaCha8Rng::from_seed(key)
}

/// Why the panel did not register a touch.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum MissReason {
    /// The pin tip is outside the panel's effective area.
    NotOverPanel,
    /// The pin makes less than the minimum angle with the panel plane.
    PinAngle,
    /// The table cannot reach the position.
    OutOfTravel,
}

impl MissReason {
    /// Short text for a recording's `skipped: REASON`.
    pub fn as_text(self) -> &'static str {
        match self {
            MissReason::NotOverPanel => "pin not over the panel",
            MissReason::PinAngle => "pin angle below the panel minimum",
            MissReason::OutOfTravel => "outside table travel",
        }
    }
}

/// What the panel reports for a touch.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Touch {
    /// A valid contact: the counts and the (u, v) offset they stand for (mm).
    Contact {
        /// (cx, cy).
        counts: [u32; 2],
        /// (u, v) in mm, from the counts (or exact when quantisation is off).
        uv_mm: [f64; 2],
    },
    /// No valid contact.
    Missed(MissReason),
}

/// True when the pin (tool pose `tool`, pin direction `pin_axis` in the tool frame) points down
/// onto a level panel by at least `min_angle` (rad): world z of the pin ≤ −sin(min_angle).
pub fn pin_angle_ok(tool: &Isometry3<f64>, pin_axis: &Vector3<f64>, min_angle: f64) -> bool {
    (tool.rotation * pin_axis).z <= -min_angle.sin()
}

/// The count of an exact offset `x` (mm) on an axis of width `w` (mm) with `n` counts centred on
/// zero; None outside the area.
fn count_of(x: f64, w: f64, n: u32) -> Option<u32> {
    let c = ((x + w / 2.0) * f64::from(n) / w).floor();
    if c >= 0.0 && c < f64::from(n) {
        Some(c as u32)
    } else {
        None
    }
}

/// The offset (mm) a count stands for: (c + 0.5) · w/n − w/2.
fn offset_of(c: u32, w: f64, n: u32) -> f64 {
    (f64::from(c) + 0.5) * w / f64::from(n) - w / 2.0
}

/// The panel's report for an exact offset (u, v) (mm) of the pin tip from the panel centre.
pub fn panel_report(panel: &TablePanel, uv: [f64; 2], quantise: bool) -> Touch {
    let [w, h] = panel.panel_size_mm;
    let [nx, ny] = panel.panel_counts;
    match (count_of(uv[0], w, nx), count_of(uv[1], h, ny)) {
        (Some(cx), Some(cy)) => Touch::Contact {
            counts: [cx, cy],
            uv_mm: if quantise {
                [offset_of(cx, w, nx), offset_of(cy, h, ny)]
            } else {
                uv
            },
        },
        _ => Touch::Missed(MissReason::NotOverPanel),
    }
}

/// True when a table reading lies within the travel (0..travel on each axis).
pub(crate) fn within_travel(panel: &TablePanel, reading: &Vector3<f64>) -> bool {
    (0..3).all(|k| reading[k] >= 0.0 && reading[k] <= panel.travel_mm[k])
}
