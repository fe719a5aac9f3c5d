//! The sparse solve of the reduced system `G M^-1 G^T lambda = b` against the dense reference
//! ([`Model::accelerations_dense`]) on states along a run of each scene.

mod common;

use std::path::PathBuf;

use jointplay_solver::dynamics::Workspace;
use jointplay_solver::model::Model;
use jointplay_solver::scene::SceneSpec;

/// Largest difference between the two solves relative to the scale of the quantity. Both paths
/// solve the same system by backward-stable factorisations in different elimination orders, so
/// they differ by rounding amplified by the conditioning of S; measured at up to 3e-12 of the
/// scale on the redundant ideal 4-UPS/RPU (its multipliers) and about 1e-14 on the others. 1e-9
/// leaves room for other compilers and FMA while staying many orders below what a wrong solve
/// gives: any other consistent set of multipliers on the redundant 4-UPS/RPU (say, one redundant
/// drive carrying nothing) differs from the minimum-norm one by a sizeable fraction of the forces.
const TOL: f64 = 1e-9;

fn max_abs<'a>(v: impl IntoIterator<Item = &'a f64>) -> f64 {
    v.into_iter().fold(0.0, |m, x| m.max(x.abs()))
}

/// Compares the two paths at `n` + 1 states of a run of `name` up to `t_end`; returns the largest
/// relative differences of accelerations, multipliers and joint reactions.
fn compare(name: &str, t_end: f64, rank: usize) -> [f64; 3] {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../data/scenes")
        .join(name);
    let file = SceneSpec::load(&path).unwrap();
    let (model, mut state) = Model::compile(&file).unwrap();
    model.assemble(&mut state).unwrap();
    let n = 40;
    let t0 = state.t;
    let samples: Vec<f64> = (0..=n)
        .map(|k| t0 + k as f64 * (t_end - t0) / n as f64)
        .collect();
    let traj = common::run_samples(&model, &mut state, model.settings.method, t_end, &samples);
    let mut sparse = Workspace::new(&model);
    let mut dense = Workspace::new(&model);
    let mut err = [0.0f64; 3];
    for (t, y) in &traj {
        model.accelerations(*t, y, &mut sparse);
        model.accelerations_dense(*t, y, &mut dense);
        assert!(
            !sparse.solved_densely(),
            "{name}: sparse path not taken at t = {t}"
        );
        assert_eq!(sparse.rank, rank, "{name} at t = {t}");
        assert_eq!(dense.rank, rank, "{name} at t = {t}");
        // Accelerations against the larger of the terms that cancel in a = M^-1 (Q - G^T lambda).
        let a_scale =
            max_abs(dense.acc.iter().flatten()).max(max_abs(dense.minv_q.iter().flatten()));
        let a_err = max_abs(
            &sparse
                .acc
                .iter()
                .flatten()
                .zip(dense.acc.iter().flatten())
                .map(|(a, b)| a - b)
                .collect::<Vec<_>>(),
        );
        let l_scale = max_abs(&dense.lambda);
        let l_err = max_abs(
            &sparse
                .lambda
                .iter()
                .zip(&dense.lambda)
                .map(|(a, b)| a - b)
                .collect::<Vec<_>>(),
        );
        let (mut r_scale, mut r_err) = (0.0f64, 0.0f64);
        for j in 0..model.joints.len() {
            let (fs, ns) = model.reaction(j, &sparse);
            let (fd, nd) = model.reaction(j, &dense);
            r_scale = r_scale.max(fd.amax()).max(nd.amax());
            r_err = r_err.max((fs - fd).amax()).max((ns - nd).amax());
        }
        for (e, v) in err.iter_mut().zip([
            a_err / a_scale,
            l_err / l_scale.max(f64::MIN_POSITIVE),
            r_err / r_scale.max(f64::MIN_POSITIVE),
        ]) {
            *e = e.max(v);
        }
    }
    for (what, e) in ["accelerations", "multipliers", "reactions"]
        .iter()
        .zip(err)
    {
        assert!(e < TOL, "{name}: {what} differ by {e:.3e} of their scale");
    }
    err
}

#[test]
fn ideal_4ups_rpu_with_its_redundant_drive_matches_the_dense_minimum_norm_solve() {
    // 67 rows of rank 66: the minimum-norm multipliers are unique, so they must agree too.
    compare("4ups-rpu.toml", 0.3, 66);
}

#[test]
fn spherical_and_mixed_clearance_4ups_rpu_match_the_dense_solve() {
    compare("4ups-rpu-spherical.toml", 0.3, 61);
    compare("4ups-rpu-mixed.toml", 0.3, 56);
}

#[test]
fn planar_slider_cranks_with_redundant_rows_match_the_dense_solve() {
    compare("slider-crank.toml", 0.2, 18);
    compare("slider-crank-clearance.toml", 0.05, 16);
}
