//! Probe.
mod common;
use common::shapes::*;
use rigcal::diagnosis::{diagnose, Options};

#[test]
#[ignore]
fn probe() {
    let _ = tracing_subscriber::fmt().with_env_filter(tracing_subscriber::EnvFilter::from_default_env()).with_writer(std::io::stderr).try_init();
    let only: Option<String> = std::env::var("CLASS").ok();
    let seeds: u64 = std::env::var("SEEDS").ok().and_then(|s| s.parse().ok()).unwrap_or(3);
    for class in Class::ALL {
        if only.as_ref().is_some_and(|o| !class.name().contains(o.as_str())) { continue; }
        for s in 0..seeds {
            let size = 1.0 + 4.0 * (s as f64) / (seeds.max(2) - 1) as f64;
            let c = out_of_library(class, s, size);
            let t = std::time::Instant::now();
            let r = diagnose(&c.scenario.rig, &c.recording, &Options::default()).expect("diagnose");
            let names: Vec<String> = r.effects.iter().map(|e| format!("{}:{:?}{:?}", e.kind, e.joint, e.axis)).collect();
            eprintln!("{} size {size:.1} ({:.2}s): named {names:?} unexplained {} floor {:.4} before {:.4} after {:.4} outliers {}", c.label, t.elapsed().as_secs_f64(), r.unexplained, r.mismatch.noise_floor_mm, r.mismatch.rms_mm, r.fit.after_rms_mm, r.outliers.len());
            for o in &r.out_of_library { eprintln!("   shape: {}", o.description); }
            if let Some(d) = &r.discrepancy { eprintln!("   discrepancy: fitted {:.4}→{:.4} held {:?}→{:?}", d.rms_without_mm, d.rms_with_mm, d.heldout_rms_without_mm, d.heldout_rms_with_mm); }
            for n in r.notes.iter().filter(|n| n.contains("not claimed")) { eprintln!("   {n}"); }
        }
    }
}

fn names(r: &rigcal::diagnosis::Report) -> Vec<String> {
    r.effects.iter().map(|e| {
        let idx = e.joint.map(|j| j.to_string()).or(e.axis.clone()).or(e.axes.as_ref().map(|a| a.join(""))).unwrap_or_default();
        format!("{}:{idx}", e.kind)
    }).collect()
}

#[test]
#[ignore]
fn probe_lib() {
    let _ = tracing_subscriber::fmt().with_env_filter(tracing_subscriber::EnvFilter::from_default_env()).with_writer(std::io::stderr).try_init();
    let seeds: u64 = std::env::var("SEEDS").ok().and_then(|s| s.parse().ok()).unwrap_or(2);
    let sizes: Vec<Option<f64>> = vec![None, Some(3.0), Some(10.0)];
    for case in library_cases() {
        for size in &sizes {
            for s in 0..seeds {
                let c = in_library(&case, s, *size);
                let r = diagnose(&c.scenario.rig, &c.recording, &Options::default()).expect("diagnose");
                let ok = names(&r) == vec![case.name.to_string()] && !r.unexplained;
                eprintln!("{} {} vis {:.4} ({:.1}×): {} named {:?} unexplained {} {:?}", if ok {"ok "} else {"BAD"}, c.label, c.visible_mm, c.visible_mm / floor(), s, names(&r), r.unexplained, r.out_of_library.iter().map(|o| o.description.clone()).collect::<Vec<_>>());
            }
        }
    }
    for s in 0..5*seeds {
        let c = null(s, if s % 2 == 0 { 0.01 } else { 0.05 });
        let r = diagnose(&c.scenario.rig, &c.recording, &Options::default()).expect("diagnose");
        eprintln!("null {s}: significant {} named {:?} unexplained {}", r.mismatch.significant, names(&r), r.unexplained);
    }
}
