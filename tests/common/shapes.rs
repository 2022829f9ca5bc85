//! A generator of diagnosis recordings with hidden physics in and out of the library, at a
//! chosen *visible* size (conventions §9: the RMS of what the geometric parameters cannot
//! absorb) in multiples of the noise floor √3·σ.
//!
//! Out-of-library classes (none is a candidate of `rigcal_model::diagnosis`):
//! - `Dent`: a localised dent in one joint's transmission, Δq_j = A·exp(−(q_j − c)²/2w²), w 5–8 %
//!   of the joint's range, c inside it;
//! - `Coupling`: one joint's error driven by another joint's angle, Δq_j = A·sin(n·q_k + φ),
//!   n 1 or 2;
//! - `Harmonic`: a transmission error of an order above the library's (5 and up, at least two
//!   cycles over the joint's range);
//! - `Deformation`: a local Cartesian deformation, the measured point moved by
//!   A·u·exp(−|p − c|²/2w²) around a point c of the workspace (w a third of the workspace's RMS
//!   spread, u a random direction): an instrument or fixture that bends in one place.
//!
//! Recordings are those of `tests/diagnose.rs`: 600 measurements, random measurable poses, one
//! in eight at one of two repeated `ref` poses, 5 s apart, noise σ = 0.02 mm per coordinate, on
//! `rigs/rv-m2-ideal.toml` with random geometric errors (0.4 mm / 0.05°, signs). The world makes
//! the effect; the diagnosis sees only the recording and the rig. Units: mm, radians inside.
#![allow(dead_code)]

use nalgebra::Vector3;
use rand::rngs::ChaCha8Rng;
use rand::{RngExt, SeedableRng};
use rigcal_core::kinematics::{ErrorParams, Robot};
use rigcal_core::recording::Recording;
use rigcal_model::diagnosis::{linalg::rms3, standard_fit, Report};
use rigcal_model::effects::EffectKind;
use rigcal_model::identification::random_poses;
use rigcal_sim::world::{
    Backlash, DriftTarget, Effect, JointCompliance, JointContext, PointMass, Scenario, TableScale,
    TableSquareness, ThermalDrift, TransmissionError,
};
use std::path::Path;
use std::sync::Arc;

/// Noise per coordinate (mm).
pub const NOISE_MM: f64 = 0.02;
/// Measurements per recording.
pub const MEASUREMENTS: usize = 600;

/// The 3-D RMS of pure noise (mm).
pub fn floor() -> f64 {
    3f64.sqrt() * NOISE_MM
}

/// The out-of-library classes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Class {
    /// A localised dent in one joint's transmission.
    Dent,
    /// One joint's error driven by another joint's angle.
    Coupling,
    /// A transmission error of an order outside the library's.
    Harmonic,
    /// A local Cartesian deformation.
    Deformation,
}

impl Class {
    /// Every class.
    pub const ALL: [Class; 4] = [
        Class::Dent,
        Class::Coupling,
        Class::Harmonic,
        Class::Deformation,
    ];

    /// Short name.
    pub fn name(self) -> &'static str {
        match self {
            Class::Dent => "joint dent",
            Class::Coupling => "cross-joint coupling",
            Class::Harmonic => "higher harmonic",
            Class::Deformation => "Cartesian deformation",
        }
    }
}

/// What the hidden shape depends on (joints 0-based), for checking the diagnosis's description.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Truth {
    /// Joint `joint`'s error as a function of its own angle; `periodic` for a harmonic.
    OwnAngle {
        /// The joint.
        joint: usize,
        /// A harmonic (else localised).
        periodic: bool,
    },
    /// Joint `acted`'s error as a function of joint `driver`'s angle.
    OtherAngle {
        /// The joint whose error it is.
        acted: usize,
        /// The joint whose angle drives it.
        driver: usize,
    },
    /// A function of the position around `centre_mm`.
    Position {
        /// Centre of the deformation (world, mm).
        centre_mm: Vector3<f64>,
    },
    /// A library effect, `kind:index` as `tests/diagnose.rs` names it.
    Library {
        /// `backlash:1`, `table_squareness:xy`, …
        name: &'static str,
    },
    /// Nothing beyond the geometry.
    Null,
}

/// A generated recording and what was hidden in it.
#[derive(Debug, Clone)]
pub struct Case {
    /// The scenario (rig, geometry, instrument; effects as made).
    pub scenario: Scenario,
    /// The recording.
    pub recording: Recording,
    /// What the hidden shape depends on.
    pub truth: Truth,
    /// Its visible size (mm, 3-D RMS past the geometry).
    pub visible_mm: f64,
    /// A label.
    pub label: String,
}

/// Scenario on `rig` (`rv-m2-ideal` or the table rig `rv-m2` without quantisation or table
/// noise) with random geometric errors, `effects` (TOML `[[effects]]` blocks) and noise.
pub fn scenario(rig: &str, seed: u64, effects: &str, noise_mm: f64) -> Scenario {
    let extra = if rig == "rv-m2" {
        "quantise = false\ntable_accuracy_mm = 0.0\n"
    } else {
        ""
    };
    let text = format!(
        "description = \"diagnosis test\"\nseed = {seed}\nrig = \"../rigs/{rig}.toml\"\n\
         [geometric]\nrandom = {{ length_mm = 0.4, angle_deg = 0.05, distribution = \"signs\" }}\n\
         {effects}\n[measurement]\nnoise_mm = {noise_mm}\nseconds_per_point = 5.0\n{extra}"
    );
    Scenario::parse(&text, Path::new("sim/diagnose-test.toml"), None).expect("scenario")
}

/// `n` poses: random measurable ones, every 8th at one of two repeated reference poses; and
/// which are references.
pub fn poses(sc: &Scenario, n: usize, seed: u64) -> (Vec<Vec<f64>>, Vec<bool>) {
    let rig = &sc.rig;
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x5eed);
    let draw = |rng: &mut ChaCha8Rng| loop {
        let q = random_poses(rig.chain.joints(), rig.held(), 1, rng).remove(0);
        if rig.measurable(&q).is_ok() {
            return q;
        }
    };
    let refs = [draw(&mut rng), draw(&mut rng)];
    let mut out = Vec::with_capacity(n);
    let mut is_ref = Vec::with_capacity(n);
    for k in 0..n {
        if k % 8 == 0 {
            out.push(refs[(k / 8) % 2].clone());
            is_ref.push(true);
        } else {
            out.push(draw(&mut rng));
            is_ref.push(false);
        }
    }
    (out, is_ref)
}

/// The scenario's world recording `poses`, regions `ref` / `w`.
pub fn record(sc: &Scenario, poses: &[Vec<f64>], is_ref: &[bool]) -> Recording {
    let mut rec = sc.world().record(poses, 1);
    for (row, r) in rec.rows.iter_mut().zip(is_ref) {
        row.region = Some(if *r { "ref".into() } else { "w".into() });
    }
    rec
}

/// A recording of `n` measurements of the scenario (the poses of [`poses`]).
pub fn recording(sc: &Scenario, n: usize, seed: u64) -> Recording {
    let (p, r) = poses(sc, n, seed);
    record(sc, &p, &r)
}

/// A joint error that is a function of one joint's angle: Δq_acted = f(q_driver).
#[derive(Debug, Clone)]
pub struct AngleFunction {
    /// The joint whose error it is (0-based).
    pub acted: usize,
    /// The joint whose angle drives it (0-based).
    pub driver: usize,
    /// The shape.
    pub shape: Shape,
    /// Amplitude (rad).
    pub amplitude: f64,
}

/// A one-dimensional shape.
#[derive(Debug, Clone, Copy)]
pub enum Shape {
    /// exp(−(q − c)²/2w²).
    Bump {
        /// Centre (rad).
        centre: f64,
        /// Width (rad).
        width: f64,
    },
    /// sin(n·q + φ).
    Sine {
        /// Order.
        order: f64,
        /// Phase (rad).
        phase: f64,
    },
}

impl Shape {
    fn at(&self, q: f64) -> f64 {
        match *self {
            Shape::Bump { centre, width } => (-(q - centre).powi(2) / (2.0 * width * width)).exp(),
            Shape::Sine { order, phase } => (order * q + phase).sin(),
        }
    }
}

impl Effect for AngleFunction {
    fn kind(&self) -> EffectKind {
        // Out of the library: a smooth joint error the diagnosis can only fit as a discrepancy.
        EffectKind::Discrepancy
    }

    fn joint_offsets(&self, ctx: &JointContext<'_>, dq: &mut [f64]) {
        dq[self.acted] += self.amplitude * self.shape.at(ctx.commanded[self.driver]);
    }
}

/// A local deformation of the measured points: p += A·u·exp(−|p − c|²/2w²).
#[derive(Debug, Clone, Copy)]
pub struct Deformation {
    /// Centre (mm).
    pub centre: Vector3<f64>,
    /// Width (mm).
    pub width: f64,
    /// Direction (unit).
    pub direction: Vector3<f64>,
    /// Amplitude (mm).
    pub amplitude: f64,
}

impl Deformation {
    /// Moves every measured point of `rec`.
    pub fn apply(&self, rec: &mut Recording) {
        for row in &mut rec.rows {
            if let Some(p) = row.position.as_mut() {
                let g =
                    (-(*p - self.centre).norm_squared() / (2.0 * self.width * self.width)).exp();
                *p += self.direction * (self.amplitude * g);
            }
        }
    }
}

/// The visible size (mm) of the effect `make(1.0)` on `poses`: a noise-free world with nominal
/// geometry and only this effect, fitted by the diagnosis's standard model.
fn visible_size(
    sc: &Scenario,
    poses: &[Vec<f64>],
    is_ref: &[bool],
    effect: Option<Arc<dyn Effect>>,
    deformation: Option<Deformation>,
) -> f64 {
    let mut clean = sc.clone();
    clean.truth = ErrorParams::zeros(clean.rig.chain.layout());
    clean.measurement.noise_mm = 0.0;
    clean.effects = effect.into_iter().collect();
    let mut rec = record(&clean, poses, is_ref);
    if let Some(d) = deformation {
        d.apply(&mut rec);
    }
    let std = standard_fit(&clean.rig, &rec).expect("standard fit");
    rms3(&std.residual)
}

/// Range (min, max) of joint `j` over `poses`.
fn range(poses: &[Vec<f64>], j: usize) -> (f64, f64) {
    poses
        .iter()
        .fold((f64::MAX, f64::MIN), |(a, b), q| (a.min(q[j]), b.max(q[j])))
}

/// An out-of-library case of `class` at `size` × the floor (visible), seed `seed`.
pub fn out_of_library(class: Class, seed: u64, size: f64) -> Case {
    out_of_library_n(class, seed, size, MEASUREMENTS)
}

/// [`out_of_library`] with `n` measurements.
pub fn out_of_library_n(class: Class, seed: u64, size: f64, n: usize) -> Case {
    let mut sc = scenario("rv-m2-ideal", 20_000 + seed, "", NOISE_MM);
    let (p, r) = poses(&sc, n, 20_000 + seed);
    let mut rng = ChaCha8Rng::seed_from_u64(seed.wrapping_mul(7919) ^ class as u64);
    let moving: Vec<usize> = (0..sc.rig.chain.dof())
        .filter(|&j| {
            let (lo, hi) = range(&p, j);
            hi - lo > 1e-6
        })
        .collect();
    let pick = |rng: &mut ChaCha8Rng| moving[rng.random_range(0..moving.len())];
    let sign = if rng.random_bool(0.5) { 1.0 } else { -1.0 };
    let target = size * floor();
    match class {
        Class::Dent | Class::Harmonic | Class::Coupling => {
            let acted = pick(&mut rng);
            let driver = if class == Class::Coupling {
                loop {
                    let k = pick(&mut rng);
                    if k != acted {
                        break k;
                    }
                }
            } else {
                acted
            };
            let (lo, hi) = range(&p, driver);
            let w = hi - lo;
            let shape = match class {
                Class::Dent => Shape::Bump {
                    centre: lo + w * rng.random_range(0.15..0.85),
                    width: w * rng.random_range(0.05..0.08),
                },
                Class::Harmonic => {
                    let min_order = (5.0f64).max((2.0 * std::f64::consts::TAU / w).ceil());
                    Shape::Sine {
                        order: min_order + f64::from(rng.random_range(0..4u8)),
                        phase: rng.random_range(0.0..std::f64::consts::TAU),
                    }
                }
                Class::Coupling | Class::Deformation => Shape::Sine {
                    order: f64::from(rng.random_range(1..=2u8)),
                    phase: rng.random_range(0.0..std::f64::consts::TAU),
                },
            };
            let unit = 1e-4;
            let make = |a: f64| -> Arc<dyn Effect> {
                match (class, shape) {
                    (Class::Harmonic, Shape::Sine { order, phase }) => {
                        Arc::new(TransmissionError {
                            joint: acted,
                            harmonics: vec![rigcal_sim::world::Harmonic {
                                order: order as u32,
                                amplitude: a,
                                phase,
                            }],
                        })
                    }
                    _ => Arc::new(AngleFunction {
                        acted,
                        driver,
                        shape,
                        amplitude: a,
                    }),
                }
            };
            let v = visible_size(&sc, &p, &r, Some(make(unit)), None);
            let amplitude = sign * unit * target / v;
            sc.effects.push(make(amplitude));
            let truth = if class == Class::Coupling {
                Truth::OtherAngle { acted, driver }
            } else {
                Truth::OwnAngle {
                    joint: acted,
                    periodic: class == Class::Harmonic,
                }
            };
            let recording = record(&sc, &p, &r);
            Case {
                label: format!(
                    "{} {shape:?} on joint {} by joint {}, {:.4}°",
                    class.name(),
                    acted + 1,
                    driver + 1,
                    amplitude.to_degrees()
                ),
                scenario: sc,
                recording,
                truth,
                visible_mm: target,
            }
        }
        Class::Deformation => {
            let positions: Vec<Vector3<f64>> = p
                .iter()
                .map(|q| {
                    sc.rig
                        .chain
                        .position(q, &ErrorParams::zeros(sc.rig.chain.layout()))
                })
                .collect();
            let mean = positions.iter().sum::<Vector3<f64>>() / positions.len() as f64;
            let spread = (positions
                .iter()
                .map(|x| (x - mean).norm_squared())
                .sum::<f64>()
                / positions.len() as f64)
                .sqrt();
            let centre = positions[rng.random_range(0..positions.len())];
            let direction = Vector3::new(
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
            )
            .normalize();
            let mut d = Deformation {
                centre,
                width: spread * rng.random_range(0.25..0.35),
                direction,
                amplitude: 0.1,
            };
            let v = visible_size(&sc, &p, &r, None, Some(d));
            d.amplitude *= target / v;
            let mut recording = record(&sc, &p, &r);
            d.apply(&mut recording);
            Case {
                label: format!(
                    "{} at ({:.0}, {:.0}, {:.0}) mm, width {:.0} mm, {:.3} mm",
                    class.name(),
                    centre.x,
                    centre.y,
                    centre.z,
                    d.width,
                    d.amplitude
                ),
                scenario: sc,
                recording,
                truth: Truth::Position { centre_mm: centre },
                visible_mm: target,
            }
        }
    }
}

/// One in-library case: the rig, the name the diagnosis must give, and the effect at a factor
/// of the size `tests/diagnose.rs` hides it at.
pub struct LibraryCase {
    /// `rv-m2-ideal` or `rv-m2` (table effects).
    pub rig: &'static str,
    /// `kind:index`.
    pub name: &'static str,
    /// The effect at `factor` × the size of `tests/diagnose.rs`.
    pub make: fn(f64) -> Arc<dyn Effect>,
}

/// The arm's link masses of `sim/rig-realistic.toml` (links 2, 3 and 5).
fn masses() -> Vec<PointMass> {
    [(1, 3.5, -125.0), (2, 2.5, -130.0), (4, 1.0, -150.0)]
        .into_iter()
        .map(|(link, kg, x)| PointMass {
            link,
            kg,
            at_mm: Vector3::new(x, 0.0, 0.0),
        })
        .collect()
}

/// Every kind of the library once or twice (the cases of `tests/diagnose.rs`).
pub fn library_cases() -> Vec<LibraryCase> {
    fn compliance(joint: usize, deg_per_nm: f64) -> Arc<dyn Effect> {
        Arc::new(JointCompliance {
            masses: masses(),
            stiffness: vec![(joint, 1.0 / deg_per_nm.to_radians())],
        })
    }
    fn harmonic(joint: usize, order: u32, deg: f64, phase_deg: f64) -> Arc<dyn Effect> {
        Arc::new(TransmissionError {
            joint,
            harmonics: vec![rigcal_sim::world::Harmonic {
                order,
                amplitude: deg.to_radians(),
                phase: phase_deg.to_radians(),
            }],
        })
    }
    vec![
        LibraryCase {
            rig: "rv-m2-ideal",
            name: "joint_compliance:2",
            make: |a| compliance(1, 0.0005 * a),
        },
        LibraryCase {
            rig: "rv-m2-ideal",
            name: "joint_compliance:3",
            make: |a| compliance(2, 0.001 * a),
        },
        LibraryCase {
            rig: "rv-m2-ideal",
            name: "backlash:1",
            make: |a| {
                Arc::new(Backlash {
                    joint: 0,
                    lost_motion: (0.01 * a).to_radians(),
                })
            },
        },
        LibraryCase {
            rig: "rv-m2-ideal",
            name: "backlash:3",
            make: |a| {
                Arc::new(Backlash {
                    joint: 2,
                    lost_motion: (0.01 * a).to_radians(),
                })
            },
        },
        LibraryCase {
            rig: "rv-m2-ideal",
            name: "transmission_error:1",
            make: |a| harmonic(0, 2, 0.005 * a, 30.0),
        },
        LibraryCase {
            rig: "rv-m2-ideal",
            name: "transmission_error:2",
            make: |a| harmonic(1, 3, 0.005 * a, -60.0),
        },
        LibraryCase {
            rig: "rv-m2-ideal",
            name: "thermal_drift:z",
            make: |a| {
                Arc::new(ThermalDrift {
                    target: DriftTarget::Axis(2),
                    amplitude: 0.05 * a,
                    tau_s: 1800.0,
                })
            },
        },
        LibraryCase {
            rig: "rv-m2-ideal",
            name: "thermal_drift:2",
            make: |a| {
                Arc::new(ThermalDrift {
                    target: DriftTarget::Joint(1),
                    amplitude: (0.008 * a).to_radians(),
                    tau_s: 1800.0,
                })
            },
        },
        LibraryCase {
            rig: "rv-m2",
            name: "table_scale:x",
            make: |a| {
                Arc::new(TableScale {
                    axis: 0,
                    scale: 150e-6 * a,
                })
            },
        },
        LibraryCase {
            rig: "rv-m2",
            name: "table_squareness:xy",
            make: |a| {
                Arc::new(TableSquareness {
                    first: 0,
                    second: 1,
                    angle: (0.01 * a).to_radians(),
                })
            },
        },
    ]
}

/// An in-library case at `size` × the floor (visible), or at the size of `tests/diagnose.rs`
/// when `size` is None.
pub fn in_library(case: &LibraryCase, seed: u64, size: Option<f64>) -> Case {
    in_library_n(case, seed, size, MEASUREMENTS)
}

/// [`in_library`] with `n` measurements.
pub fn in_library_n(case: &LibraryCase, seed: u64, size: Option<f64>, n: usize) -> Case {
    let mut sc = scenario(case.rig, 30_000 + seed, "", NOISE_MM);
    let (p, r) = poses(&sc, n, 30_000 + seed);
    let factor = match size {
        None => 1.0,
        Some(x) => x * floor() / visible_size(&sc, &p, &r, Some((case.make)(1.0)), None),
    };
    let effect = (case.make)(factor);
    let visible_mm = visible_size(&sc, &p, &r, Some(effect.clone()), None);
    sc.effects.push(effect);
    let recording = record(&sc, &p, &r);
    Case {
        label: format!("{} ×{factor:.2}", case.name),
        scenario: sc,
        recording,
        truth: Truth::Library { name: case.name },
        visible_mm,
    }
}

/// A null recording: geometry and noise `noise_mm` only.
pub fn null(seed: u64, noise_mm: f64) -> Case {
    null_n(seed, noise_mm, MEASUREMENTS)
}

/// [`null`] with `n` measurements.
pub fn null_n(seed: u64, noise_mm: f64, n: usize) -> Case {
    let sc = scenario("rv-m2-ideal", 40_000 + seed, "", noise_mm);
    let recording = recording(&sc, n, 40_000 + seed);
    Case {
        label: format!("null σ {noise_mm}"),
        scenario: sc,
        recording,
        truth: Truth::Null,
        visible_mm: 0.0,
    }
}

/// `kind:index` of each effect a report names (`backlash:3`, `table_squareness:xy`), as
/// [`LibraryCase::name`] spells them.
pub fn library_names(r: &Report) -> Vec<String> {
    r.effects
        .iter()
        .map(|e| {
            let idx = e
                .joint
                .map(|j| j.to_string())
                .or(e.axis.clone())
                .or(e.axes.as_ref().map(|a| a.join("")))
                .unwrap_or_default();
            format!("{}:{idx}", e.kind)
        })
        .collect()
}
