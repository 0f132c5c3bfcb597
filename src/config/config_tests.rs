//! The configuration's tests.

use super::*;

/// Environment variables as the loader takes them (also the ROS 2
/// section's tests).
pub(super) fn env(pairs: &[(&str, &str)]) -> Vec<(String, String)> {
    pairs
        .iter()
        .map(|(k, v)| (k.to_string(), v.to_string()))
        .collect()
}

#[test]
fn defaults_load_and_match_the_paper() {
    let s = Settings::load_with_env(None, env(&[])).unwrap();
    assert_eq!(s.perception.zscore_tau, 2.0);
    assert_eq!(s.perception.erosion_iterations, 1);
    assert_eq!(s.perception.merge_iou, 0.8);
    assert_eq!(s.runtime.execution_provider, ExecutionProviderKind::Cpu);
}

#[test]
fn the_controllers_come_from_config_and_out_of_range_values_name_the_key() {
    let s = Settings::defaults();
    assert_eq!(s.mpc.horizon, 20);
    assert_eq!(s.field.beta1, 5.0);
    assert_eq!(s.tracker.confirm_hits, 3);
    let s = Settings::load_with_env(None, env(&[("OPENNAV_MPC__HORIZON", "30")])).unwrap();
    assert_eq!(s.mpc.horizon, 30);
    for (k, v, key) in [
        ("OPENNAV_MPC__V_MAX_MPS", "0.5", "mpc.v_max_mps"),
        (
            "OPENNAV_FIELD__OMEGA_MAX_RADPS",
            "2.0",
            "field.omega_max_radps",
        ),
        ("OPENNAV_TRACKER__MERGE_IOU", "1.5", "tracker.merge_iou"),
    ] {
        let e = Settings::load_with_env(None, env(&[(k, v)])).unwrap_err();
        assert!(e.to_string().contains(key), "{e}");
    }
}

#[test]
fn jsmerror_needs_a_switch_of_the_persons_own() {
    let e = Settings::load_with_env(None, env(&[("OPENNAV_ACTUATION__RNET__MODE", "jsmerror")]))
        .expect_err("no switch")
        .to_string();
    assert!(
        e.contains("actuation.rnet.mode") && e.contains("input.switch.device"),
        "{e}"
    );
    assert!(Settings::load_with_env(
        None,
        env(&[
            ("OPENNAV_ACTUATION__RNET__MODE", "jsmerror"),
            (
                "OPENNAV_INPUT__SWITCH__DEVICE",
                "/dev/input/by-id/usb-switch-event-kbd"
            ),
        ])
    )
    .is_ok());
    // a switch with a key evdev does not know is refused, naming it
    let e = Settings::load_with_env(
        None,
        env(&[
            ("OPENNAV_INPUT__SWITCH__DEVICE", "/dev/input/event3"),
            ("OPENNAV_INPUT__SWITCH__KEY", "KEY_NOPE"),
        ]),
    )
    .expect_err("bad key")
    .to_string();
    assert!(
        e.contains("input.switch.key") && e.contains("KEY_NOPE"),
        "{e}"
    );
}

#[test]
fn a_crawl_stop_distance_too_short_or_beyond_the_full_one_is_refused() {
    // defaults: 0.1 m/s · 0.6 s + 0.01 / 1.0 = 0.07 m ≤ 0.15 m
    for v in ["0.06", "0.31"] {
        let e = Settings::load_with_env(None, env(&[("OPENNAV_SAFETY__STOP_DISTANCE_SLOW_M", v)]))
            .expect_err(v)
            .to_string();
        assert!(e.contains("safety.stop_distance_slow_m"), "{v}: {e}");
    }
    assert!(Settings::load_with_env(
        None,
        env(&[("OPENNAV_SAFETY__STOP_DISTANCE_SLOW_M", "0.08")])
    )
    .is_ok());
}

#[test]
fn a_stop_distance_the_chair_cannot_stop_in_is_refused_naming_the_keys() {
    // defaults: 0.3 m/s · (0.25 + 0.2 + 0.05 + 0.1) s + 0.09 / 1.0 = 0.27 m ≤ 0.30 m
    assert!(Settings::load_with_env(None, env(&[])).is_ok());
    for (k, v) in [
        ("OPENNAV_SAFETY__STOP_DISTANCE_M", "0.25"),
        ("OPENNAV_SAFETY__V_FORWARD_MAX_MPS", "0.5"),
        ("OPENNAV_SAFETY__LASER_MAX_AGE_S", "0.5"),
        ("OPENNAV_SAFETY__A_LINEAR_MAX_MPS2", "0.2"),
    ] {
        let e = Settings::load_with_env(None, env(&[(k, v)]))
            .expect_err(k)
            .to_string();
        assert!(e.contains("safety.stop_distance_m"), "{k}: {e}");
        for key in [
            "safety.v_forward_max_mps",
            "safety.laser_max_age_s",
            "safety.a_linear_max_mps2",
        ] {
            assert!(e.contains(key), "{k}: {e}");
        }
    }
    // a longer corridor makes the faster chair acceptable
    assert!(Settings::load_with_env(
        None,
        env(&[
            ("OPENNAV_SAFETY__V_FORWARD_MAX_MPS", "0.5"),
            ("OPENNAV_SAFETY__STOP_DISTANCE_M", "0.6"),
            ("OPENNAV_GOAL__STANDOFF_M", "0.7"),
        ])
    )
    .is_ok());
}

#[test]
fn safety_defaults_are_the_architectures_and_nonsense_is_refused() {
    let s = Settings::load_with_env(None, env(&[])).unwrap();
    // the architecture's safety contract
    let l = s.safety_limits();
    assert_eq!(
        (l.v_forward_max_mps, l.v_reverse_max_mps, l.omega_max_radps),
        (0.30, 0.15, 0.8)
    );
    let ms = std::time::Duration::from_millis;
    assert_eq!(
        (l.laser_max_age, l.odometry_max_age, l.command_max_age),
        (ms(250), ms(100), ms(200))
    );
    let p = s.drive_params();
    let q = crate::estimation::odometry::DiffDriveParams::paper_chair();
    assert!(
        (p.left_ratio - q.left_ratio).abs() < 1e-6 && (p.right_ratio - q.right_ratio).abs() < 1e-6
    );
    for (k, v, key) in [
        (
            "OPENNAV_SAFETY__V_FORWARD_MAX_MPS",
            "5",
            "safety.v_forward_max_mps",
        ),
        (
            "OPENNAV_SAFETY__LASER_MAX_AGE_S",
            "3",
            "safety.laser_max_age_s",
        ),
        ("OPENNAV_ODOMETRY__LEFT_SIGN", "0.5", "odometry.left_sign"),
        ("OPENNAV_ODOMETRY__TRACK_M", "-1", "odometry.track_m"),
        ("OPENNAV_LIVE__ADDRESS", "localhost", "live.address"),
    ] {
        let e = Settings::load_with_env(None, env(&[(k, v)]))
            .unwrap_err()
            .to_string();
        assert!(e.contains(key), "{e}");
    }
    let l = s.lasers.left.base_from_laser();
    assert!((l.translation.vector.x - 0.33).abs() < 1e-12);
}

#[test]
fn environment_overrides() {
    let s = Settings::load_with_env(
        None,
        env(&[
            ("OPENNAV_PERCEPTION__SCORE_THRESHOLD", "0.15"),
            ("OPENNAV_RUNTIME__EXECUTION_PROVIDER", "cuda"),
            ("OPENNAV_PERCEPTION__DEPTH_SEGMENTER__BIN_M", "0.1"),
        ]),
    )
    .unwrap();
    assert_eq!(s.perception.score_threshold, 0.15);
    assert_eq!(s.runtime.execution_provider, ExecutionProviderKind::Cuda);
    assert_eq!(s.perception.depth_segmenter.bin_m, 0.1);
}

#[test]
fn unknown_key_is_named() {
    let dir = tempfile::tempdir().unwrap();
    let f = dir.path().join("c.toml");
    std::fs::write(&f, "[perception]\nscore_treshold = 0.3\n").unwrap();
    let e = Settings::load_with_env(Some(&f), env(&[]))
        .unwrap_err()
        .to_string();
    assert!(e.contains("score_treshold"), "{e}");
    let e = Settings::load_with_env(None, env(&[("OPENNAV_PERCEPTION__BOGUS", "1")]))
        .unwrap_err()
        .to_string();
    assert!(e.contains("bogus"), "{e}");
    let e = Settings::load_with_env(None, env(&[("OPENNAV_NAVIGATON__SPEED", "1")]))
        .unwrap_err()
        .to_string();
    assert!(e.contains("navigaton"), "{e}");
    // not a config key: no section separator
    assert!(Settings::load_with_env(None, env(&[("OPENNAV_SHARED", "/x")])).is_ok());
}

#[test]
fn out_of_range_is_named() {
    let dir = tempfile::tempdir().unwrap();
    let f = dir.path().join("c.toml");
    std::fs::write(&f, "[perception]\nzscore_tau = 0.0\n").unwrap();
    let e = Settings::load_with_env(Some(&f), env(&[]))
        .unwrap_err()
        .to_string();
    assert!(e.contains("perception.zscore_tau"), "{e}");
    std::fs::write(&f, "[perception]\nmin_depth_m = 5.0\nmax_depth_m = 4.0\n").unwrap();
    let e = Settings::load_with_env(Some(&f), env(&[]))
        .unwrap_err()
        .to_string();
    assert!(e.contains("perception.min_depth_m"), "{e}");
    std::fs::write(
            &f,
            "[camera]\nbase_from_camera = { rotation = [[2.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]], translation_m = [0.0, 0.0, 0.0] }\n",
        )
        .unwrap();
    let e = Settings::load_with_env(Some(&f), env(&[]))
        .unwrap_err()
        .to_string();
    assert!(e.contains("base_from_camera"), "{e}");
    let e = Settings::load_with_env(Some(&dir.path().join("none.toml")), env(&[]))
        .unwrap_err()
        .to_string();
    assert!(e.contains("none.toml"), "{e}");
}
