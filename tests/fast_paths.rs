//! The fast identification paths against the dense implementation they replaced: the fit
//! (normal equations accumulated per pose on the chain multiplied out, κ through a QR), the
//! identifiability analysis (decisions on the triangular factor of [M]) and `identify`'s outlier
//! search (refits starting from the last fit with the removed rows downdated) give the same
//! parameters, σ, κ, residuals, basis and outliers as the reference code below — the code
//! rigcal ran before, kept here verbatim in its numerics: [M] and J stacked in full, SVDs of
//! the tall matrices, every refit from the nominal parameters. Units: mm and rad.

use nalgebra::{DMatrix, DVector, Vector3};
use rand::rngs::ChaCha8Rng;
use rand::{RngExt, SeedableRng};
use rigcal_core::kinematics::{ErrorParams, Robot};
use rigcal_core::recording::Recording;
use rigcal_core::rig::{FrameMode, Rig};
use rigcal_model::identification::outliers::{remove_outliers, OutlierSettings};
use rigcal_model::identification::{
    analyse, candidate_order, errors, fit, identify, random_poses, FitOptions, FitResult, Level,
    Observation, Prior, ResidualStats,
};
use rigcal_sim::world::{paper_geometric_errors, World};
use std::path::Path;

fn rig() -> Rig {
    Rig::load(Path::new("rigs/rv-m2-ideal.toml")).expect("rig file")
}

/// A world with the paper's error sizes and 0.02 mm noise, and `n` random poses in it.
fn world_and_poses(rig: &Rig, n: usize, seed: u64) -> (World, Vec<Vec<f64>>) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let design = random_poses(rig.chain.joints(), rig.held(), 60, &mut rng);
    let ident = reference::analyse(&rig.chain, &design, &candidate_order(rig));
    let truth = paper_geometric_errors(&rig.chain, &ident, seed);
    let world = World::new(rig.chain.clone(), truth, 0.02, seed + 7);
    let poses = random_poses(rig.chain.joints(), rig.held(), n, &mut rng);
    (world, poses)
}

fn observe(world: &World, poses: &[Vec<f64>]) -> Vec<Observation> {
    poses
        .iter()
        .enumerate()
        .map(|(k, q)| Observation {
            q: q.clone(),
            p: world.measure(q, k as u64, 0),
        })
        .collect()
}

fn close(a: f64, b: f64, rel: f64, abs: f64) -> bool {
    (a - b).abs() <= abs + rel * a.abs().max(b.abs())
}

fn assert_stats_equal(a: &ResidualStats, b: &ResidualStats, what: &str) {
    assert_eq!(a.n, b.n, "{what}");
    for (x, y) in [
        (a.rms_mm, b.rms_mm),
        (a.mean_mm, b.mean_mm),
        (a.max_mm, b.max_mm),
    ] {
        assert!(close(x, y, 0.0, 1e-8), "{what}: {x} vs {y} mm");
    }
}

/// Parameters within 1e-4 of their σ, σ and κ to 1e-8, residuals to 1e-7 mm. Two fits of the
/// same data agree only as far as the iteration resolves the minimum: it stops when a step no
/// longer lowers the cost in double precision, some 1e-6 σ from the exact minimum.
fn assert_fits_equal(fast: &FitResult, slow: &FitResult, what: &str) {
    assert_eq!(fast.free, slow.free, "{what}: fitted parameters");
    for (k, &i) in fast.free.iter().enumerate() {
        let (a, b) = (fast.params.get(i), slow.params.get(i));
        assert!(
            (a - b).abs() <= 1e-4 * slow.sigma[k] + 1e-15,
            "{what}: parameter {i}: {a:e} vs {b:e} (σ {:e})",
            slow.sigma[k]
        );
        assert!(
            close(fast.sigma[k], slow.sigma[k], 1e-8, 0.0),
            "{what}: σ {k}: {:e} vs {:e}",
            fast.sigma[k],
            slow.sigma[k]
        );
    }
    assert!(
        close(fast.kappa, slow.kappa, 1e-8, 0.0),
        "{what}: κ {} vs {}",
        fast.kappa,
        slow.kappa
    );
    assert!(close(fast.sigma0_mm, slow.sigma0_mm, 1e-9, 0.0), "{what}");
    assert_eq!(fast.residuals.len(), slow.residuals.len(), "{what}");
    for (a, b) in fast.residuals.iter().zip(&slow.residuals) {
        assert!((a - b).norm() < 1e-7, "{what}: residual {a} vs {b}");
    }
    assert_stats_equal(&fast.before, &slow.before, what);
    assert_stats_equal(&fast.after, &slow.after, what);
}

#[test]
fn the_fit_of_2200_measurements_equals_the_dense_reference() {
    let rig = rig();
    let (world, poses) = world_and_poses(&rig, 2200, 1);
    let obs = observe(&world, &poses);
    let zero = ErrorParams::zeros(rig.chain.layout());
    let basis = reference::analyse(&rig.chain, &poses, &candidate_order(&rig)).basis;
    let fast = fit(&rig.chain, &obs, &zero, &basis, &FitOptions::default()).expect("fit");
    let slow = reference::fit(&rig.chain, &obs, &zero, &basis, &FitOptions::default());
    assert_fits_equal(&fast, &slow, "2200 measurements");
    assert!(
        fast.iterations.abs_diff(slow.iterations) <= 2,
        "iterations {} vs {}",
        fast.iterations,
        slow.iterations
    );
    // And the fit found the truth: every parameter within 4σ.
    for (k, &i) in fast.free.iter().enumerate() {
        let d = fast.params.get(i) - world.truth().get(i);
        assert!(d.abs() < 4.0 * fast.sigma[k], "parameter {i}: {d:e}");
    }
}

#[test]
fn a_fit_with_a_prior_equals_the_dense_reference() {
    let rig = rig();
    let (world, poses) = world_and_poses(&rig, 40, 2);
    let obs = observe(&world, &poses);
    let zero = ErrorParams::zeros(rig.chain.layout());
    let basis = reference::analyse(&rig.chain, &poses, &candidate_order(&rig)).basis;
    let mut mean = zero.clone();
    for (k, &i) in basis.iter().enumerate() {
        mean.set(i, 1e-3 * (k as f64 - 7.0));
    }
    let opts = FitOptions {
        prior: Some(Prior {
            mean,
            weight: (0..basis.len()).map(|k| 0.5 + 0.1 * k as f64).collect(),
        }),
        ..FitOptions::default()
    };
    let fast = fit(&rig.chain, &obs, &zero, &basis, &opts).expect("fit");
    let slow = reference::fit(&rig.chain, &obs, &zero, &basis, &opts);
    assert_fits_equal(&fast, &slow, "with a prior");
}

#[test]
fn the_analysis_equals_the_dense_reference_with_fixed_and_free_frames() {
    let mut rig = rig();
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let poses = random_poses(rig.chain.joints(), rig.held(), 2200, &mut rng);
    for frame in [FrameMode::Fixed, FrameMode::Free] {
        rig.calibration.measurement_frame = frame;
        rig.calibration.marker = frame;
        let cands = candidate_order(&rig);
        let fast = analyse(&rig.chain, &poses, &cands);
        let slow = reference::analyse(&rig.chain, &poses, &cands);
        assert_eq!(fast.rank, slow.rank, "{frame:?}");
        assert_eq!(fast.basis, slow.basis, "{frame:?}");
        assert_eq!(fast.no_effect, slow.no_effect, "{frame:?}");
        assert_eq!(fast.poses, slow.poses);
        assert!(close(fast.kappa, slow.kappa, 1e-8, 0.0), "{frame:?}");
        let smax = slow.singular_values[0];
        assert_eq!(fast.singular_values.len(), slow.singular_values.len());
        for (a, b) in fast.singular_values.iter().zip(&slow.singular_values) {
            assert!((a - b).abs() <= 1e-12 * smax, "{frame:?}: σ {a:e} vs {b:e}");
        }
        assert_eq!(fast.confounded.len(), slow.confounded.len());
        for ((p, ft), (q, st)) in fast.confounded.iter().zip(&slow.confounded) {
            assert_eq!(p, q);
            // Terms come sorted by size; compare them by parameter.
            for (b, c) in st {
                let f = ft.iter().find(|t| t.0 == *b).map_or(f64::NAN, |t| t.1);
                assert!(
                    close(f, *c, 1e-7, 1e-9),
                    "{frame:?}: {p} on {b}: {f:e} vs {c:e}"
                );
            }
        }
    }
}

/// A 2200-row recording with gross errors planted at `planted` (row, mm).
fn recording_with_outliers(rig: &Rig, planted: &[(usize, f64)]) -> Recording {
    let (world, poses) = world_and_poses(rig, 2200, 4);
    let mut rec = world.record(&poses, 1);
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    for &(k, size) in planted {
        let d = Vector3::new(
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
        )
        .normalize();
        if let Some(p) = rec.rows[k].position.as_mut() {
            *p += d * size;
        }
    }
    rec
}

#[test]
fn identify_with_outliers_equals_refitting_from_scratch() {
    let rig = rig();
    let planted = [
        (17, 0.4),
        (400, 3.0),
        (1001, 0.25),
        (1500, 1.0),
        (2100, 0.5),
    ];
    let rec = recording_with_outliers(&rig, &planted);
    let fast = identify(
        &rig,
        &rec,
        Level::Full,
        &rigcal_model::diagnosis::outliers::identify_options(),
    )
    .expect("identify");

    // The search as it ran before: every refit analyses and fits the kept rows from nominal.
    let obs = rec.observations();
    let ids: Vec<(u64, Option<u64>)> = rec.rows.iter().map(|m| (m.seq, None)).collect();
    let cands = Level::Full.candidates(&rig);
    let zero = ErrorParams::zeros(rig.chain.layout());
    let mut last = None;
    let (outliers, _) = remove_outliers(&ids, &OutlierSettings::default(), |kept| {
        let fitted: Vec<Observation> = kept.iter().map(|&i| obs[i].clone()).collect();
        let poses: Vec<Vec<f64>> = fitted.iter().map(|o| o.q.clone()).collect();
        let basis = reference::analyse(&rig.chain, &poses, &cands).basis;
        let r = reference::fit(&rig.chain, &fitted, &zero, &basis, &FitOptions::default());
        let res = errors(&rig.chain, &obs, &r.params);
        let p = r.free.len();
        last = Some(r);
        Ok::<_, std::io::Error>((res, p))
    })
    .expect("search");
    let slow = last.expect("one refit at least");

    let mut found: Vec<usize> = fast.outliers.iter().map(|o| o.index).collect();
    found.sort_unstable();
    assert_eq!(
        found,
        planted.map(|p| p.0),
        "every planted row, nothing else"
    );
    assert_eq!(fast.outliers.len(), outliers.len());
    for (a, b) in fast.outliers.iter().zip(&outliers) {
        assert_eq!((a.index, a.seq), (b.index, b.seq), "same order");
        assert!(close(a.size_mm, b.size_mm, 0.0, 1e-7));
        assert!(close(a.sigmas, b.sigmas, 1e-6, 0.0));
        // Far tails: compare log p (its relative error grows with the test statistic).
        let (la, lb) = (a.p_value.max(1e-300).ln(), b.p_value.max(1e-300).ln());
        assert!(
            close(la, lb, 1e-5, 1e-6),
            "p {:e} vs {:e}",
            a.p_value,
            b.p_value
        );
    }
    assert_fits_equal(&fast.fit, &slow, "after the outlier search");
}

/// The dense implementation the fast paths replaced (numerics unchanged).
mod reference {
    use super::*;
    use rigcal_model::identification::Identifiability;

    const RANK_TOL: f64 = 1e-9;
    const NO_EFFECT_TOL: f64 = 1e-9;

    pub fn stacked_jacobian(
        robot: &dyn Robot,
        e: &ErrorParams,
        poses: &[Vec<f64>],
        columns: &[usize],
    ) -> DMatrix<f64> {
        let mut m = DMatrix::zeros(3 * poses.len(), columns.len());
        for (k, q) in poses.iter().enumerate() {
            let (_, j) = robot.position_and_param_jacobian(q, e);
            for (c, &col) in columns.iter().enumerate() {
                for r in 0..3 {
                    m[(3 * k + r, c)] = j[(r, col)];
                }
            }
        }
        m
    }

    pub fn kappa_eq4(m: &DMatrix<f64>) -> f64 {
        if m.ncols() == 0 {
            return 1.0;
        }
        let norms: Vec<f64> = m.column_iter().map(|c| c.norm()).collect();
        let scaled = DMatrix::from_fn(m.nrows(), m.ncols(), |r, c| {
            if norms[c] > 0.0 {
                m[(r, c)] / norms[c]
            } else {
                0.0
            }
        });
        let sv = scaled.svd(false, false).singular_values;
        let (smax, smin) = (sv.max(), sv.min());
        if smin <= 0.0 {
            f64::INFINITY
        } else {
            (smax / smin).powi(2)
        }
    }

    pub fn analyse(robot: &dyn Robot, poses: &[Vec<f64>], candidates: &[usize]) -> Identifiability {
        let e = ErrorParams::zeros(robot.layout());
        let m = stacked_jacobian(robot, &e, poses, candidates);
        let norms: Vec<f64> = (0..m.ncols()).map(|c| m.column(c).norm()).collect();
        let scale = (3 * poses.len()) as f64;
        let mut no_effect = Vec::new();
        let mut effective = Vec::new();
        for (c, &n) in norms.iter().enumerate() {
            if n < NO_EFFECT_TOL * scale.sqrt() {
                no_effect.push(candidates[c]);
            } else {
                effective.push(c);
            }
        }
        let scaled = DMatrix::from_fn(m.nrows(), effective.len(), |r, k| {
            m[(r, effective[k])] / norms[effective[k]]
        });
        let mut singular_values: Vec<f64> = scaled
            .clone()
            .svd(false, false)
            .singular_values
            .iter()
            .copied()
            .collect();
        singular_values.sort_by(|a, b| b.total_cmp(a));
        let smax = singular_values.first().copied().unwrap_or(0.0);
        let rank = singular_values
            .iter()
            .filter(|&&s| s > RANK_TOL * smax)
            .count();
        let gs_tol = RANK_TOL.sqrt();
        let mut q_basis: Vec<DVector<f64>> = Vec::new();
        let mut chosen: Vec<usize> = Vec::new();
        for k in 0..effective.len() {
            let mut v = scaled.column(k).clone_owned();
            for _ in 0..2 {
                for b in &q_basis {
                    let d = b.dot(&v);
                    v -= b * d;
                }
            }
            let n = v.norm();
            if n > gs_tol && chosen.len() < rank {
                q_basis.push(v / n);
                chosen.push(k);
            }
        }
        let basis: Vec<usize> = chosen.iter().map(|&k| candidates[effective[k]]).collect();
        let b_cols: Vec<usize> = chosen.iter().map(|&k| effective[k]).collect();
        let mb = DMatrix::from_fn(m.nrows(), b_cols.len(), |r, c| m[(r, b_cols[c])]);
        let kappa = kappa_eq4(&mb);
        let svd_b = mb.clone().svd(true, true);
        let mut confounded = Vec::new();
        for k in 0..effective.len() {
            if chosen.contains(&k) {
                continue;
            }
            let col = m.column(effective[k]).clone_owned();
            let coef = svd_b
                .solve(&col, 1e-12)
                .unwrap_or_else(|_| DVector::zeros(b_cols.len()));
            let mut terms: Vec<(usize, f64)> = coef
                .iter()
                .enumerate()
                .map(|(i, &c)| (candidates[b_cols[i]], c))
                .collect();
            terms.sort_by(|a, b| b.1.abs().total_cmp(&a.1.abs()));
            confounded.push((candidates[effective[k]], terms));
        }
        Identifiability {
            rank,
            basis,
            no_effect,
            confounded,
            kappa,
            singular_values,
            poses: poses.len(),
            undetermined: Vec::new(),
        }
    }

    fn residual_and_jacobian(
        robot: &dyn Robot,
        obs: &[Observation],
        e: &ErrorParams,
        free: &[usize],
        prior: Option<&Prior>,
    ) -> (DVector<f64>, DMatrix<f64>) {
        let extra = prior.map_or(0, |_| free.len());
        let mut r = DVector::zeros(3 * obs.len() + extra);
        let mut j = DMatrix::zeros(3 * obs.len() + extra, free.len());
        for (k, o) in obs.iter().enumerate() {
            let (p, m) = robot.position_and_param_jacobian(&o.q, e);
            r.fixed_rows_mut::<3>(3 * k).copy_from(&(o.p - p));
            for (c, &i) in free.iter().enumerate() {
                for row in 0..3 {
                    j[(3 * k + row, c)] = m[(row, i)];
                }
            }
        }
        if let Some(prior) = prior {
            for (k, &i) in free.iter().enumerate() {
                let w = prior.weight[k];
                r[3 * obs.len() + k] = w * (prior.mean.get(i) - e.get(i));
                j[(3 * obs.len() + k, k)] = w;
            }
        }
        (r, j)
    }

    pub fn fit(
        robot: &dyn Robot,
        obs: &[Observation],
        start: &ErrorParams,
        free: &[usize],
        opts: &FitOptions,
    ) -> FitResult {
        let p = free.len();
        let rows = 3 * obs.len();
        let prior = opts.prior.as_ref();
        let mut e = start.clone();
        let (mut r, mut j) = residual_and_jacobian(robot, obs, &e, free, prior);
        let start_errors: Vec<Vector3<f64>> =
            obs.iter().map(|o| o.p - robot.position(&o.q, &e)).collect();
        let before = ResidualStats::of(&start_errors);
        let mut cost = r.norm_squared();
        let mut lambda = 1e-4;
        let mut iterations = 0;
        for _ in 0..opts.max_iterations {
            iterations += 1;
            let d: Vec<f64> = (0..p).map(|c| j.column(c).norm().max(1e-300)).collect();
            let mut js = j.clone();
            for (c, s) in d.iter().enumerate() {
                js.column_mut(c).scale_mut(1.0 / s);
            }
            let a = js.transpose() * &js;
            let g = js.transpose() * &r;
            let mut improved = false;
            let mut step_norm = 0.0;
            for _ in 0..12 {
                let mut damped = a.clone();
                for k in 0..p {
                    damped[(k, k)] += lambda * a[(k, k)].max(1e-12);
                }
                let Some(chol) = damped.cholesky() else {
                    lambda *= 10.0;
                    continue;
                };
                let ds = chol.solve(&g);
                step_norm = ds.norm();
                let mut trial = e.clone();
                for (k, &i) in free.iter().enumerate() {
                    trial.set(i, trial.get(i) + ds[k] / d[k]);
                }
                let (r_trial, _) = residual_and_jacobian(robot, obs, &trial, free, prior);
                let c_trial = r_trial.norm_squared();
                if c_trial <= cost {
                    e = trial;
                    cost = c_trial;
                    lambda = (lambda * 0.2).max(1e-12);
                    improved = true;
                    break;
                }
                lambda *= 10.0;
            }
            if !improved || step_norm < opts.step_tolerance {
                break;
            }
            (r, j) = residual_and_jacobian(robot, obs, &e, free, prior);
        }
        let (r, j) = residual_and_jacobian(robot, obs, &e, free, prior);
        let kappa = kappa_eq4(&j.rows(0, rows).clone_owned());
        let inv = (j.transpose() * &j).try_inverse().expect("regular");
        let dof = (rows - p).max(1) as f64;
        let s2 = r.rows(0, rows).norm_squared() / dof;
        let covariance = inv * s2;
        let sigma = (0..p).map(|k| covariance[(k, k)].max(0.0).sqrt()).collect();
        let residuals: Vec<Vector3<f64>> = (0..obs.len())
            .map(|k| Vector3::new(r[3 * k], r[3 * k + 1], r[3 * k + 2]))
            .collect();
        FitResult {
            params: e,
            free: free.to_vec(),
            sigma,
            covariance,
            kappa,
            before,
            after: ResidualStats::of(&residuals),
            sigma0_mm: s2.sqrt(),
            iterations,
            residuals,
            undetermined: Vec::new(),
        }
    }
}
