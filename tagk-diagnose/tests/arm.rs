//! Joint-torque diagnosis on logs of prescribed Fourier motion (`tagk_sim::arm::prescribed_log`):
//! every single hidden effect and every pair is found with its coefficients inside their
//! 95 % intervals, nothing is found on clean logs, and the base-parameter reduction agrees
//! with an SVD of the stacked regressor.
//!
//! The statistical tests run `TAGK_ARM_SEEDS` seeds per configuration (default 6; the
//! figures of docs/ARM_LOG.md were measured with 50).

use nalgebra::{DMatrix, DVector, Vector3};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use tagk_diagnose::arm::{ArmEffect, ArmOptions, BaseReduction, diagnose_arm, stacked_regressor};
use tagk_dynamics::{InertialParams, JointEffectKind, JointEffects, JointLog, KinematicTree};
use tagk_sim::arm::{FourierTrajectory, JointSensing, prescribed_log};

/// A test robot: its tree, torque noise [N m] and effect scales.
struct Robot {
    tree: KinematicTree,
    noise: f64,
    /// Scale of the joint effects (1 for the UR5).
    scale: f64,
    /// Where a payload sits in the payload body's frame [m].
    payload_at: Vector3<f64>,
    /// Scale of a prismatic joint's excitation against a revolute joint's (m per rad).
    prismatic_motion: f64,
    /// Velocity noise [rad/s] instead of the realistic sensing's.
    velocity_noise: Option<f64>,
}

fn ur5() -> Robot {
    let urdf = tagk_dynamics::robots::shipped_urdf("ur5").unwrap();
    Robot {
        tree: KinematicTree::from_urdf_str(urdf).unwrap(),
        noise: 0.2,
        scale: 1.0,
        payload_at: Vector3::new(0.0, 0.0, 0.08),
        prismatic_motion: 0.01,
        velocity_noise: None,
    }
}

fn planar() -> Robot {
    let urdf = tagk_dynamics::robots::shipped_urdf("planar_2link").unwrap();
    Robot {
        tree: KinematicTree::from_urdf_str(urdf)
            .unwrap()
            .with_gravity(Vector3::new(0.0, -9.81, 0.0)),
        noise: 0.05,
        scale: 0.3,
        payload_at: Vector3::new(0.7, 0.0, 0.0),
        prismatic_motion: 0.01,
        velocity_noise: None,
    }
}

/// The Panda with its hand: 7 revolute joints and the two prismatic fingers (9 joints). The
/// payload body is `panda_link7`, which carries the hand; a payload sits in the hand, 15 cm
/// along link 7's z axis.
fn panda() -> Robot {
    let urdf = tagk_dynamics::robots::shipped_urdf("panda").unwrap();
    Robot {
        tree: KinematicTree::from_urdf_str(urdf).unwrap(),
        noise: 0.1,
        scale: 0.5,
        payload_at: Vector3::new(0.0, 0.0, 0.15),
        // Fingers within their 0–4 cm travel: 2 ± 1 cm.
        prismatic_motion: 0.01,
        velocity_noise: None,
    }
}

/// What was hidden in a log.
struct Truth {
    effects: JointEffects,
    payload: Option<InertialParams>,
}

fn seeds() -> u64 {
    std::env::var("TAGK_ARM_SEEDS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(6)
}

/// A log of `robot` with `hidden` effects, every draw from `seed`.
fn log_with(robot: &Robot, hidden: &[ArmEffect], seed: u64) -> (JointLog, Truth) {
    let dof = robot.tree.dof();
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut u = |lo: f64, hi: f64| lo + (hi - lo) * rng.random::<f64>();
    let mut effects = JointEffects::none(dof);
    let mut payload = None;
    let s = robot.scale;
    for e in hidden {
        match e {
            ArmEffect::Joint(k) => {
                for j in 0..dof {
                    effects.coefficients_mut(*k)[j] = match k {
                        JointEffectKind::ViscousFriction => s * u(0.5, 2.0),
                        JointEffectKind::CoulombFriction => s * u(0.5, 3.0),
                        JointEffectKind::Armature => s * u(0.05, 0.3),
                        _ => s * u(0.3, 1.5) * if u(0.0, 1.0) < 0.5 { -1.0 } else { 1.0 },
                    };
                }
            }
            ArmEffect::Payload => {
                payload = Some(InertialParams::point_mass(
                    u(0.5, 1.5) * s.max(0.5),
                    robot.payload_at * u(0.8, 1.2),
                ));
            }
        }
    }
    let mut motion = FourierTrajectory::random_with_speed(dof, 5, 0.1, 1.0, seed ^ 0xf0);
    // A prismatic joint (a gripper's finger) moves centimetres about 2 cm, not radians.
    for (j, body) in robot.tree.bodies().iter().enumerate() {
        if !body.kind().is_rotational() {
            motion.q0[j] = 0.02;
            for c in motion.a[j].iter_mut().chain(motion.b[j].iter_mut()) {
                *c *= robot.prismatic_motion;
            }
        }
    }
    let sensing = JointSensing {
        torque_noise: robot.noise,
        torque_offset: 0.0,
        velocity_noise: robot
            .velocity_noise
            .unwrap_or(JointSensing::REALISTIC.velocity_noise),
        ..JointSensing::REALISTIC
    };
    let log_accelerations = std::env::var("TAGK_ARM_QDD").is_ok();
    let rate: f64 = std::env::var("TAGK_ARM_RATE")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(100.0);
    let log = prescribed_log(
        &robot.tree,
        payload.as_ref(),
        &effects,
        &motion,
        &sensing,
        log_accelerations,
        rate,
        20.0,
        seed ^ 0x0b,
    )
    .unwrap();
    (log, Truth { effects, payload })
}

fn options() -> ArmOptions {
    ArmOptions {
        base_parameters: false,
        // TAGK_ARM_H overrides the derivative's half-width (exploration only).
        half_width: std::env::var("TAGK_ARM_H")
            .ok()
            .and_then(|s| s.parse::<usize>().ok()),
        ..ArmOptions::default()
    }
}

/// Counts over many logs.
#[derive(Default, Debug)]
struct Score {
    logs: usize,
    found_exactly: usize,
    intervals: usize,
    covered: usize,
}

/// Diagnoses the logs of one configuration and scores them.
fn score(robot: &Robot, hidden: &[ArmEffect], score: &mut Score, base_seed: u64) {
    for s in 0..seeds() {
        let seed = base_seed * 1000 + s;
        let (log, truth) = log_with(robot, hidden, seed);
        let report = diagnose_arm(&robot.tree, &log, &options()).unwrap();
        score.logs += 1;
        let mut found = report.found();
        found.sort();
        let mut want = hidden.to_vec();
        want.sort();
        if found != want {
            eprintln!(
                "seed {seed}: hidden {:?}, found {:?}",
                want.iter().map(|e| e.name()).collect::<Vec<_>>(),
                found.iter().map(|e| e.name()).collect::<Vec<_>>()
            );
            continue;
        }
        score.found_exactly += 1;
        let joints = robot.tree.joint_names();
        let truth_of = |name: &str| -> Option<f64> {
            for k in JointEffectKind::ALL {
                for (j, jn) in joints.iter().enumerate() {
                    if name == format!("{}[{jn}]", k.name()) {
                        return Some(truth.effects.coefficients(k)[j]);
                    }
                }
            }
            None
        };
        let mut payload_truth = match (&truth.payload, &report.payload) {
            (Some(p), Some(b)) => b.coefficients_of(p),
            (None, Some(b)) => vec![0.0; b.reduction.rank],
            _ => Vec::new(),
        }
        .into_iter();
        for c in &report.final_model.coefficients {
            let t = if c.name.starts_with("payload") {
                payload_truth.next()
            } else {
                truth_of(&c.name)
            };
            let (Some(t), Some([lo, hi])) = (t, c.confidence_interval) else {
                panic!("coefficient {} without truth or interval", c.name);
            };
            score.intervals += 1;
            if (lo..=hi).contains(&t) {
                score.covered += 1;
            } else if std::env::var("TAGK_ARM_VERBOSE").is_ok() {
                eprintln!("seed {seed}: {} = {t} outside [{lo}, {hi}]", c.name);
            }
        }
    }
}

fn configurations() -> Vec<Vec<ArmEffect>> {
    let all = ArmEffect::ALL;
    let mut out: Vec<Vec<ArmEffect>> = all.iter().map(|e| vec![*e]).collect();
    for a in 0..all.len() {
        for b in a + 1..all.len() {
            out.push(vec![all[a], all[b]]);
        }
    }
    out
}

fn hidden_effects_are_found(robot: &Robot, label: &str) {
    let mut total = Score::default();
    for (k, hidden) in configurations().iter().enumerate() {
        let mut s = Score::default();
        score(robot, hidden, &mut s, 1 + k as u64);
        eprintln!(
            "{label} {:<40} found {}/{}  covered {}/{}",
            hidden
                .iter()
                .map(|e| e.name())
                .collect::<Vec<_>>()
                .join("+"),
            s.found_exactly,
            s.logs,
            s.covered,
            s.intervals
        );
        total.logs += s.logs;
        total.found_exactly += s.found_exactly;
        total.intervals += s.intervals;
        total.covered += s.covered;
    }
    let found = total.found_exactly as f64 / total.logs as f64;
    let coverage = total.covered as f64 / total.intervals as f64;
    eprintln!(
        "{label}: found rate {found:.3} of {} logs, coverage {coverage:.3} of {} intervals",
        total.logs, total.intervals
    );
    assert!(found >= 0.95, "{label}: found rate {found}");
    assert!(
        (0.90..=0.99).contains(&coverage),
        "{label}: coverage {coverage}"
    );
}

fn clean_logs_find_nothing(robot: &Robot, label: &str) {
    let n = seeds() * 3;
    let mut false_logs = 0;
    for seed in 0..n {
        let (log, _) = log_with(robot, &[], 77_000 + seed);
        let report = diagnose_arm(&robot.tree, &log, &options()).unwrap();
        if !report.final_model.effects.is_empty() {
            eprintln!(
                "{label} clean seed {seed}: found {:?}",
                report.final_model.effects
            );
            false_logs += 1;
        }
        assert_eq!(
            report.recommended.is_some(),
            !report.final_model.effects.is_empty()
        );
    }
    eprintln!("{label}: {false_logs} of {n} clean logs with a false effect");
    assert!(
        false_logs as f64 <= 0.05 * n as f64,
        "{label}: {false_logs} false of {n}"
    );
}

#[test]
fn ur5_hidden_effects_and_pairs_are_found_within_their_intervals() {
    hidden_effects_are_found(&ur5(), "ur5");
}

#[test]
fn planar_hidden_effects_and_pairs_are_found_within_their_intervals() {
    hidden_effects_are_found(&planar(), "planar");
}

#[test]
fn panda_hidden_effects_and_pairs_are_found_within_their_intervals() {
    hidden_effects_are_found(&panda(), "panda");
}

#[test]
fn panda_clean_logs_find_nothing() {
    clean_logs_find_nothing(&panda(), "panda");
}

/// A Panda log whose fingers stand still (a gripper held open) and whose velocities are exact:
/// the fingers' friction and armature columns are exactly zero. The diagnosis still finds the
/// arm's friction within its intervals, with finite numbers and no error.
#[test]
fn panda_with_still_fingers_is_diagnosed() {
    let robot = Robot {
        prismatic_motion: 0.0,
        velocity_noise: Some(0.0),
        ..panda()
    };
    let hidden = [ArmEffect::Joint(JointEffectKind::ViscousFriction)];
    let joints = robot.tree.joint_names();
    let (mut covered, mut arm) = (0, 0);
    for seed in 0..3 {
        let (log, truth) = log_with(&robot, &hidden, 4242 + seed);
        assert!(log.qd.iter().all(|v| v[7] == 0.0 && v[8] == 0.0));
        let report = diagnose_arm(&robot.tree, &log, &options()).unwrap();
        assert_eq!(report.found(), hidden.to_vec(), "{}", report.table());
        for c in &report.final_model.coefficients {
            assert!(c.value.is_finite(), "{}: {}", c.name, c.value);
            let j = joints
                .iter()
                .position(|jn| c.name == format!("viscous-friction[{jn}]"))
                .unwrap();
            let Some([lo, hi]) = c.confidence_interval else {
                continue;
            };
            let t = truth.effects.coefficients(JointEffectKind::ViscousFriction)[j];
            if j < 7 {
                arm += 1;
                covered += usize::from((lo..=hi).contains(&t));
            }
        }
    }
    assert_eq!(arm, 21);
    assert!(covered >= 18, "{covered} of 21 arm coefficients covered");
}

#[test]
fn ur5_clean_logs_find_nothing() {
    clean_logs_find_nothing(&ur5(), "ur5");
}

#[test]
fn planar_clean_logs_find_nothing() {
    clean_logs_find_nothing(&planar(), "planar");
}

/// The rank of the reduction is the SVD's: a clear gap in the singular values at it.
/// The dependent columns are the stated combinations of the independent ones.
#[test]
fn base_reduction_agrees_with_the_svd() {
    for robot in [ur5(), planar()] {
        let (log, _) = log_with(&robot, &[], 5);
        let w = stacked_regressor(&robot.tree, &log, None).unwrap();
        let red = BaseReduction::of(&w, tagk_diagnose::arm::BASE_TOLERANCE).unwrap();
        let sv = w.clone().svd(false, false).singular_values;
        let mut sv: Vec<f64> = sv.iter().copied().collect();
        sv.sort_by(|a, b| b.total_cmp(a));
        let svd_rank = sv.iter().filter(|s| **s > 1e-8 * sv[0]).count();
        assert_eq!(
            red.rank,
            svd_rank,
            "{}: QR {} vs SVD {}",
            robot.tree.name(),
            red.rank,
            svd_rank
        );
        // A gap of many orders of magnitude: the rank does not hang on the tolerance.
        assert!(sv[svd_rank - 1] / sv[0] > 1e-6, "{:?}", &sv);
        if svd_rank < sv.len() {
            assert!(sv[svd_rank] / sv[0] < 1e-11, "{:?}", &sv);
        }
        // W_dep = W_ind K.
        let wi = DMatrix::from_fn(w.nrows(), red.rank, |r, c| w[(r, red.independent[c])]);
        let k = DMatrix::from_fn(red.rank, red.dependent.len(), |r, c| red.combination[r][c]);
        for (c, &d) in red.dependent.iter().enumerate() {
            let err = (w.column(d) - &wi * k.column(c)).norm();
            assert!(err <= 1e-8 * w.norm(), "column {d}: {err}");
        }
        eprintln!(
            "{}: {} parameters, {} base",
            robot.tree.name(),
            red.n_params,
            red.rank
        );
    }
}

/// Fitted on the first 70 % of a log, the base parameters predict the last 30 % as well as
/// the full parameters fitted by the SVD pseudo-inverse (minimum-norm least squares).
#[test]
fn base_fit_predicts_held_out_torques_like_the_pseudo_inverse_fit() {
    let robot = ur5();
    let (log, _) = log_with(&robot, &[], 9);
    let w = stacked_regressor(&robot.tree, &log, None).unwrap();
    let dof = robot.tree.dof();
    let tau = DVector::from_iterator(w.nrows(), log.tau.iter().flatten().copied());
    let split = (log.len() * 7 / 10) * dof;
    let (wt, tt) = (
        w.rows(0, split).into_owned(),
        tau.rows(0, split).into_owned(),
    );
    let (wv, tv) = (
        w.rows(split, w.nrows() - split).into_owned(),
        tau.rows(split, w.nrows() - split).into_owned(),
    );
    let red = BaseReduction::of(&wt, tagk_diagnose::arm::BASE_TOLERANCE).unwrap();
    let sel =
        |m: &DMatrix<f64>| DMatrix::from_fn(m.nrows(), red.rank, |r, c| m[(r, red.independent[c])]);
    let beta = sel(&wt).svd(true, true).solve(&tt, 0.0).unwrap();
    let base_err = (&tv - sel(&wv) * beta).norm();
    let full = wt.clone().svd(true, true);
    let theta = full.solve(&tt, 1e-8 * full.singular_values.max()).unwrap();
    let full_err = (&tv - &wv * theta).norm();
    eprintln!("held-out error: base {base_err:.4}, pseudo-inverse {full_err:.4}");
    assert!(
        (base_err / full_err - 1.0).abs() < 0.01,
        "{base_err} vs {full_err}"
    );
    // And the base values of the URDF's parameters predict the URDF's torques exactly.
    let theta_urdf = robot.tree.params_vector();
    let b = DVector::from_vec(red.base_values(theta_urdf.as_slice()));
    let e = (&wt * &theta_urdf - sel(&wt) * b).norm() / (&wt * &theta_urdf).norm();
    assert!(e < 1e-9, "{e}");
}

#[test]
fn wrong_joint_count_and_elasticity_are_typed_errors() {
    let robot = ur5();
    let (log, _) = log_with(&planar(), &[], 1);
    let e = diagnose_arm(&robot.tree, &log, &options()).unwrap_err();
    assert!(e.to_string().contains("2 joints"), "{e}");
    let e = ArmEffect::from_name("joint-elasticity").unwrap_err();
    assert!(e.to_string().contains("motor-side"), "{e}");
    assert!(ArmEffect::from_name("stiction").is_err());
}

/// The report's JSON has the quadrotor's shape.
#[test]
fn report_json_has_the_quadrotor_shape() {
    let robot = ur5();
    let (log, _) = log_with(
        &robot,
        &[ArmEffect::Joint(JointEffectKind::ViscousFriction)],
        3,
    );
    let report = diagnose_arm(&robot.tree, &log, &ArmOptions::default()).unwrap();
    let json: serde_json::Value = serde_json::from_str(&report.to_json().unwrap()).unwrap();
    assert_eq!(json["recommended"], "viscous-friction");
    assert_eq!(json["steps"][1]["effect"], "viscous-friction");
    assert_eq!(json["final_model"]["effects"][0], "viscous-friction");
    let base = &json["base_parameters"];
    assert!(base["rank"].as_u64().unwrap() > 0);
    // The residual falls to the noise.
    let last = report.steps.last().unwrap();
    assert!(last.joints.iter().all(|j| j.adequate), "{}", report.table());
    assert!(report.steps[0].joints.iter().any(|j| !j.adequate));
}
