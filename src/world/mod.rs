//! The simulated truth: what the arm really does and what the instrument really reads.
//!
//! Only emulators and `rigcal simulate`/`demo` read it; identification, division, learners,
//! compensation and diagnosis see recordings and rig files, never the world. Random draws are a
//! function of (seed, seq, attempt), never of a running generator, so a resumed session draws
//! what the uninterrupted one drew (conventions §7). Units: mm and rad inside.

use crate::identification::Identifiability;
use crate::kinematics::{ErrorParams, Robot, SerialChain};
use crate::recording::{Measurement, Recording, Status};
use nalgebra::Vector3;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

/// A simulated arm: the nominal chain with true geometric errors, measured with Gaussian noise.
#[derive(Debug, Clone)]
pub struct World {
    chain: SerialChain,
    truth: ErrorParams,
    noise_mm: f64,
    seed: u64,
}

impl World {
    /// A world whose arm has error parameters `truth`, measured with noise σ = `noise_mm` per
    /// coordinate; `seed` fixes every random draw.
    pub fn new(chain: SerialChain, truth: ErrorParams, noise_mm: f64, seed: u64) -> Self {
        Self {
            chain,
            truth,
            noise_mm,
            seed,
        }
    }

    /// The true error parameters (for tests and reports of simulations only).
    pub fn truth(&self) -> &ErrorParams {
        &self.truth
    }

    /// The chain.
    pub fn chain(&self) -> &SerialChain {
        &self.chain
    }

    /// Where the pin really is at joint values `q` (mm).
    pub fn true_position(&self, q: &[f64]) -> Vector3<f64> {
        self.chain.position(q, &self.truth)
    }

    /// What the instrument reads at `q` for measurement `seq`, attempt `attempt` (mm).
    pub fn measure(&self, q: &[f64], seq: u64, attempt: u32) -> Vector3<f64> {
        let mut rng = draw_rng(self.seed, seq, attempt);
        let noise = Vector3::from_fn(|_, _| {
            let z: f64 = StandardNormal.sample(&mut rng);
            self.noise_mm * z
        });
        self.true_position(q) + noise
    }

    /// A recording of measurements at `poses`, numbered from `first_seq`, one second apart.
    pub fn record(&self, poses: &[Vec<f64>], first_seq: u64) -> Recording {
        let mut rec = Recording::new(self.chain.joints());
        for (k, q) in poses.iter().enumerate() {
            let seq = first_seq + k as u64;
            rec.rows.push(Measurement {
                seq,
                t_s: Some(k as f64),
                q: q.clone(),
                position: Some(self.measure(q, seq, 0)),
                status: Status::Ok,
                ..Default::default()
            });
        }
        rec
    }
}

/// The generator for one measurement's draws: a function of (seed, seq, attempt) only.
pub fn draw_rng(seed: u64, seq: u64, attempt: u32) -> ChaCha8Rng {
    let mut key = [0u8; 32];
    key[..8].copy_from_slice(&seed.to_le_bytes());
    key[8..16].copy_from_slice(&seq.to_le_bytes());
    key[16..20].copy_from_slice(&attempt.to_le_bytes());
    key[20..].copy_from_slice(b"rigcal-world");
    ChaCha8Rng::from_seed(key)
}

/// Seed 000's geometric errors: ±0.4 mm on every identifiable length and ±0.05° on every
/// identifiable angle, with signs drawn from `seed`.
pub fn paper_geometric_errors(
    chain: &SerialChain,
    ident: &Identifiability,
    seed: u64,
) -> ErrorParams {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut e = ErrorParams::zeros(chain.layout());
    for &i in &ident.basis {
        let kind = chain.layout().ids()[i].kind;
        let size = if kind.is_angle() {
            0.05f64.to_radians()
        } else {
            0.4
        };
        let sign = if rng.gen_bool(0.5) { 1.0 } else { -1.0 };
        e.set(i, sign * size);
    }
    e
}
