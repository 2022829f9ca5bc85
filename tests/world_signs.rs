//! The sign search behind `sim/paper-sim.toml` (conventions §3): which of the 2^15 sign patterns
//! of ±0.4 mm / ±0.05° keep the uncalibrated error along the Fig. 6 path within 0.4–1.2 mm.
//! Run with `cargo test --release --test world_signs -- --ignored --nocapture`.

use rigcal_core::kinematics::{ErrorParams, Robot};
use rigcal_core::rig::Rig;
use rigcal_sim::world::{fig6_path, identifiable};
use std::path::Path;

#[test]
#[ignore = "a search (about 3 s in release), run by hand to pin the paper scenario's signs"]
fn search_paper_sign_patterns() {
    let rig = Rig::load(Path::new("rigs/rv-m2-ideal.toml")).unwrap();
    let chain = &rig.chain;
    let layout = chain.layout();
    let basis = identifiable(&rig);
    assert_eq!(basis.len(), 15);
    let path = fig6_path(101, chain.dof());
    let nominal = ErrorParams::zeros(layout);
    let targets: Vec<_> = path.iter().map(|q| chain.position(q, &nominal)).collect();
    let mut inside = 0;
    let mut comfortable = Vec::new();
    for pattern in 0u32..(1 << 15) {
        let mut e = ErrorParams::zeros(layout);
        for (k, &i) in basis.iter().enumerate() {
            let size = if layout.ids()[i].kind.is_angle() {
                0.05f64.to_radians()
            } else {
                0.4
            };
            e.set(i, if pattern >> k & 1 == 1 { size } else { -size });
        }
        let errs: Vec<f64> = path
            .iter()
            .zip(&targets)
            .map(|(q, t)| (chain.position(q, &e) - t).norm())
            .collect();
        let lo = errs.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = errs.iter().copied().fold(0.0, f64::max);
        if lo >= 0.4 && hi <= 1.2 {
            inside += 1;
            if lo >= 0.5 && hi <= 1.05 {
                comfortable.push((pattern, lo, hi));
            }
        }
    }
    println!(
        "{inside} of 32768 patterns ({:.1} %) lie within 0.4–1.2 mm; {} with margin",
        100.0 * inside as f64 / 32768.0,
        comfortable.len()
    );
    for (pattern, lo, hi) in comfortable.iter().take(5) {
        let names: Vec<String> = basis
            .iter()
            .enumerate()
            .map(|(k, &i)| {
                let id = layout.ids()[i];
                let size = if id.kind.is_angle() { 0.05 } else { 0.4 };
                let v = if pattern >> k & 1 == 1 { size } else { -size };
                format!("{} = {v}", layout.name(id))
            })
            .collect();
        println!(
            "pattern {pattern:#06x}: {lo:.3}–{hi:.3} mm: {{ {} }}",
            names.join(", ")
        );
    }
}
