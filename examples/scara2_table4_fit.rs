//! How the 2-DOF SCARA's working area and force points (which seed 001 does not give) were
//! chosen: the ones whose errors before calibration best match Table 4's six figures.
//!
//! Case 1 has no forces and its errors turn with α, so it depends on the β range alone: that is
//! searched first. Then, with that β range, a symmetric α range and the positions of P1 and P2
//! along their links are searched against cases 2 and 3. The score is the sum of squared log
//! ratios to the paper's mean and max errors. Run with
//! `cargo run --release --example scara2_table4_fit`.

use rigcal_core::kinematics::Robot;
use rigcal_paper::reproduce::robots::scara2::{Scara2, Scara2Errors, Scara2Real, WorkingArea};

/// Table 4, [mean, max] (mm) per case.
const PAPER: [[f64; 2]; 3] = [[6.67, 10.2], [8.93, 17.0], [0.76, 1.26]];

/// Mean and max position error before calibration over a 40 × 40 grid of the area.
fn before(errors: Scara2Errors, area: &WorkingArea) -> (f64, f64) {
    let nominal = Scara2::default();
    let real = Scara2Real { nominal, errors };
    let n = 40;
    let (mut sum, mut max) = (0.0, 0.0f64);
    for i in 0..n {
        for j in 0..n {
            let q = area.at((i as f64 + 0.5) / n as f64, (j as f64 + 0.5) / n as f64);
            let p = real.pose(&q, &[0.0; 6]);
            let s = nominal.forward(&q).expect("closed form");
            let e = (p[0] - s[0]).hypot(p[1] - s[1]);
            sum += e;
            max = max.max(e);
        }
    }
    (sum / (n * n) as f64, max)
}

fn score(case: usize, (mean, max): (f64, f64)) -> f64 {
    (mean / PAPER[case][0]).ln().powi(2) + (max / PAPER[case][1]).ln().powi(2)
}

fn area(alpha_deg: (f64, f64), beta_deg: (f64, f64)) -> WorkingArea {
    WorkingArea {
        alpha: (alpha_deg.0.to_radians(), alpha_deg.1.to_radians()),
        beta: (beta_deg.0.to_radians(), beta_deg.1.to_radians()),
    }
}

fn main() {
    let mut betas = Vec::new();
    for lo in (30..150).step_by(5) {
        for hi in ((lo + 20)..=175).step_by(5) {
            let b = (lo as f64, hi as f64);
            let e = before(Scara2Errors::case(1), &area((0.0, 1.0), b));
            betas.push((score(0, e), b, e));
        }
    }
    betas.sort_by(|a, b| a.0.total_cmp(&b.0));
    println!("β ranges (case 1 only; the score is flat, so several fit):");
    for (s, b, e) in betas.iter().take(5) {
        println!(
            "  β {:>4}…{:<4}  case 1 {:.2} / {:.2} mm  score {s:.4}",
            b.0, b.1, e.0, e.1
        );
    }
    let beta = betas[0].1;
    let mut fits = Vec::new();
    for half_span in (15..=90).step_by(15) {
        let a = area((-(half_span as f64), half_span as f64), beta);
        for i in 0..=20 {
            for j in 0..=20 {
                let (p1, p2) = (i as f64 / 20.0, j as f64 / 20.0);
                let mut total = 0.0;
                let mut errs = Vec::new();
                for case in 1..=3u8 {
                    let errors = Scara2Errors {
                        p1_along: p1,
                        p2_along: p2,
                        ..Scara2Errors::case(case)
                    };
                    let e = before(errors, &a);
                    total += score(case as usize - 1, e);
                    errs.push(e);
                }
                fits.push((total, half_span, p1, p2, errs));
            }
        }
    }
    fits.sort_by(|a, b| a.0.total_cmp(&b.0));
    println!(
        "with β {}…{}: α range and force points (P along its link from its joint):",
        beta.0, beta.1
    );
    for (s, h, p1, p2, e) in fits.iter().take(8) {
        println!(
            "  α ±{h:<3} P1 {p1:.2} P2 {p2:.2}  cases 1/2/3 mean/max {:.2}/{:.2} {:.2}/{:.2} {:.2}/{:.2}  score {s:.4}",
            e[0].0, e[0].1, e[1].0, e[1].1, e[2].0, e[2].1
        );
    }
    println!("paper: 6.67/10.2 8.93/17.0 0.76/1.26");
}
