//! Every key's range and the checks across keys (a stop distance the chair
//! can stop in, the plan's speeds within the caps, a standoff beyond the
//! stop corridor): a value out of sense is an error naming its key.

use super::{ConfigError, Settings, CONTROL_PERIOD};

fn range<T: PartialOrd + std::fmt::Display + Copy>(
    key: &str,
    v: T,
    lo: T,
    hi: T,
) -> Result<(), ConfigError> {
    if v >= lo && v <= hi {
        Ok(())
    } else {
        Err(ConfigError::Range {
            key: key.into(),
            value: v.to_string(),
            reason: format!("out of range [{lo}, {hi}]"),
        })
    }
}

fn finite_range(key: &str, v: f64, lo: f64, hi: f64) -> Result<(), ConfigError> {
    if !v.is_finite() {
        return Err(ConfigError::Range {
            key: key.into(),
            value: v.to_string(),
            reason: "not a finite number".into(),
        });
    }
    range(key, v, lo, hi)
}

impl Settings {
    pub fn validate(&self) -> Result<(), ConfigError> {
        range("runtime.intra_threads", self.runtime.intra_threads, 0, 64)?;
        range("runtime.inter_threads", self.runtime.inter_threads, 0, 64)?;
        let p = &self.perception;
        finite_range(
            "perception.score_threshold",
            p.score_threshold as f64,
            0.0,
            1.0,
        )?;
        finite_range("perception.nms_iou", p.nms_iou as f64, 0.0, 1.0)?;
        range("perception.max_detections", p.max_detections, 1, 1000)?;
        range("perception.erosion_iterations", p.erosion_iterations, 0, 10)?;
        finite_range("perception.zscore_tau", p.zscore_tau, 0.5, 10.0)?;
        range("perception.min_points", p.min_points, 1, 100_000)?;
        finite_range("perception.min_depth_m", p.min_depth_m as f64, 0.0, 20.0)?;
        finite_range("perception.max_depth_m", p.max_depth_m as f64, 0.0, 20.0)?;
        if p.min_depth_m >= p.max_depth_m {
            return Err(ConfigError::Range {
                key: "perception.min_depth_m".into(),
                value: p.min_depth_m.to_string(),
                reason: format!("must be below perception.max_depth_m ({})", p.max_depth_m),
            });
        }
        finite_range("perception.merge_iou", p.merge_iou, 0.0, 1.0)?;
        let d = &p.depth_segmenter;
        finite_range(
            "perception.depth_segmenter.bin_m",
            d.bin_m as f64,
            0.005,
            0.5,
        )?;
        finite_range(
            "perception.depth_segmenter.center_fraction",
            d.center_fraction as f64,
            0.05,
            1.0,
        )?;
        finite_range(
            "perception.depth_segmenter.mode_tolerance_m",
            d.mode_tolerance_m as f64,
            0.005,
            0.5,
        )?;
        finite_range(
            "perception.depth_segmenter.step_m",
            d.step_m as f64,
            0.001,
            0.5,
        )?;
        finite_range(
            "perception.depth_segmenter.step_per_m",
            d.step_per_m as f64,
            0.0,
            0.2,
        )?;
        finite_range(
            "perception.depth_segmenter.floor_band_m",
            d.floor_band_m as f64,
            0.0,
            0.3,
        )?;
        let sf = &self.safety;
        finite_range("safety.v_forward_max_mps", sf.v_forward_max_mps, 0.01, 2.0)?;
        finite_range("safety.v_reverse_max_mps", sf.v_reverse_max_mps, 0.0, 1.0)?;
        finite_range("safety.omega_max_radps", sf.omega_max_radps, 0.01, 3.0)?;
        finite_range("safety.a_linear_max_mps2", sf.a_linear_max_mps2, 0.01, 3.0)?;
        finite_range(
            "safety.a_angular_max_radps2",
            sf.a_angular_max_radps2,
            0.01,
            6.0,
        )?;
        finite_range("safety.laser_max_age_s", sf.laser_max_age_s, 0.01, 1.0)?;
        finite_range(
            "safety.odometry_max_age_s",
            sf.odometry_max_age_s,
            0.01,
            1.0,
        )?;
        finite_range("safety.command_max_age_s", sf.command_max_age_s, 0.01, 1.0)?;
        finite_range("safety.chair_width_m", sf.chair_width_m, 0.3, 1.5)?;
        finite_range("safety.corridor_margin_m", sf.corridor_margin_m, 0.0, 0.5)?;
        finite_range(
            "safety.corridor_margin_slow_m",
            sf.corridor_margin_slow_m,
            0.0,
            sf.corridor_margin_m,
        )?;
        finite_range("safety.stop_distance_m", sf.stop_distance_m, 0.05, 2.0)?;
        finite_range(
            "safety.stop_distance_slow_m",
            sf.stop_distance_slow_m,
            0.05,
            sf.stop_distance_m,
        )?;
        finite_range("safety.front_offset_m", sf.front_offset_m, 0.0, 2.0)?;
        finite_range("safety.rear_offset_m", sf.rear_offset_m, 0.0, 2.0)?;
        finite_range(
            "safety.overspeed_margin_mps",
            sf.overspeed_margin_mps,
            0.01,
            0.5,
        )?;
        finite_range(
            "safety.overspeed_margin_radps",
            sf.overspeed_margin_radps,
            0.05,
            1.0,
        )?;
        finite_range(
            "safety.overspeed_window_s",
            sf.overspeed_window_s,
            0.05,
            2.0,
        )?;
        finite_range("safety.camera_max_age_s", sf.camera_max_age_s, 0.05, 3.0)?;
        finite_range("safety.max_blind_fraction", sf.max_blind_fraction, 0.0, 0.5)?;
        // the corridor must reach far enough to stop in: what the chair
        // covers at full speed while the newest scan ages to its deadline,
        // the command to its own, one control period and the writer's
        // freshness limit, plus braking at the deceleration limit
        let reaction_s = sf.laser_max_age_s
            + sf.command_max_age_s
            + CONTROL_PERIOD.as_secs_f64()
            + self.actuation.command_max_age_s;
        let needed = sf.v_forward_max_mps * reaction_s
            + sf.v_forward_max_mps.powi(2) / (2.0 * sf.a_linear_max_mps2);
        if sf.stop_distance_m < needed {
            return Err(ConfigError::Range {
                key: "safety.stop_distance_m".into(),
                value: sf.stop_distance_m.to_string(),
                reason: format!(
                    "the chair cannot stop in it: at safety.v_forward_max_mps = {} it covers {:.3} m while \
                     safety.laser_max_age_s + safety.command_max_age_s + the control period ({:?}) + \
                     actuation.command_max_age_s pass ({reaction_s:.3} s), and brakes over {:.3} m at \
                     safety.a_linear_max_mps2 = {}: needs at least {needed:.3} m",
                    sf.v_forward_max_mps,
                    sf.v_forward_max_mps * reaction_s,
                    CONTROL_PERIOD,
                    sf.v_forward_max_mps.powi(2) / (2.0 * sf.a_linear_max_mps2),
                    sf.a_linear_max_mps2,
                ),
            });
        }
        // and the crawl's, the same way at the crawl's top speed (a third
        // of the forward cap)
        let crawl_mps = sf.v_forward_max_mps / 3.0;
        let needed_slow = crawl_mps * reaction_s + crawl_mps.powi(2) / (2.0 * sf.a_linear_max_mps2);
        if sf.stop_distance_slow_m < needed_slow {
            return Err(ConfigError::Range {
                key: "safety.stop_distance_slow_m".into(),
                value: sf.stop_distance_slow_m.to_string(),
                reason: format!(
                    "the chair cannot stop in it at a crawl: at a third of safety.v_forward_max_mps \
                     ({crawl_mps:.3} m/s) it covers {:.3} m in {reaction_s:.3} s of reaction and \
                     brakes over {:.3} m: needs at least {needed_slow:.3} m",
                    crawl_mps * reaction_s,
                    crawl_mps.powi(2) / (2.0 * sf.a_linear_max_mps2),
                ),
            });
        }
        let o = &self.odometry;
        finite_range("odometry.wheel_radius_m", o.wheel_radius_m, 0.02, 1.0)?;
        finite_range("odometry.track_m", o.track_m, 0.1, 2.0)?;
        finite_range("odometry.counts_per_rev", o.counts_per_rev, 1.0, 1.0e7)?;
        finite_range("odometry.left_ratio", o.left_ratio, 1e-3, 100.0)?;
        finite_range("odometry.right_ratio", o.right_ratio, 1e-3, 100.0)?;
        for (key, v) in [
            ("odometry.left_sign", o.left_sign),
            ("odometry.right_sign", o.right_sign),
        ] {
            if v != 1.0 && v != -1.0 {
                return Err(ConfigError::Range {
                    key: key.into(),
                    value: v.to_string(),
                    reason: "must be 1 or -1".into(),
                });
            }
        }
        finite_range(
            "odometry.max_wheel_speed_mps",
            o.max_wheel_speed_mps,
            0.1,
            10.0,
        )?;
        for (side, l) in [("left", &self.lasers.left), ("right", &self.lasers.right)] {
            for (i, v) in l.translation_m.iter().enumerate() {
                finite_range(&format!("lasers.{side}.translation_m[{i}]"), *v, -3.0, 3.0)?;
            }
            finite_range(
                &format!("lasers.{side}.yaw_rad"),
                l.yaw_rad,
                -std::f64::consts::PI,
                std::f64::consts::PI,
            )?;
        }
        let g = &self.goal;
        finite_range("goal.standoff_m", g.standoff_m, 0.2, 3.0)?;
        finite_range("goal.clearance_m", g.clearance_m, 0.1, 1.5)?;
        if g.standoff_m <= self.safety.stop_distance_m {
            return Err(ConfigError::Range {
                key: "goal.standoff_m".into(),
                value: g.standoff_m.to_string(),
                reason: format!(
                    "must exceed safety.stop_distance_m ({}): the stop corridor would halt the chair before it arrives",
                    self.safety.stop_distance_m
                ),
            });
        }
        finite_range("goal.unseen_after_s", g.unseen_after_s, 0.1, 10.0)?;
        finite_range("goal.hold_s", g.hold_s, 0.0, 120.0)?;
        finite_range("goal.reached_within_m", g.reached_within_m, 0.02, 1.0)?;
        finite_range("goal.search_turn_radps", g.search_turn_radps, 0.05, 1.0)?;
        // beyond the moment the person is told (daemon::control::SAY_HELD_AFTER)
        finite_range("goal.give_up_held_s", g.give_up_held_s, 15.0, 600.0)?;
        finite_range("goal.search_at_most_s", g.search_at_most_s, 20.0, 1200.0)?;
        finite_range("goal.search_held_s", g.search_held_s, 30.0, 1200.0)?;
        let m = &self.mpc;
        range("mpc.horizon", m.horizon, 5, 60)?;
        finite_range("mpc.dt_s", m.dt_s, 0.02, 0.5)?;
        finite_range(
            "mpc.v_min_mps",
            m.v_min_mps,
            -self.safety.v_reverse_max_mps,
            0.0,
        )?;
        finite_range(
            "mpc.v_max_mps",
            m.v_max_mps,
            0.01,
            self.safety.v_forward_max_mps,
        )?;
        finite_range(
            "mpc.omega_max_radps",
            m.omega_max_radps,
            0.05,
            self.safety.omega_max_radps,
        )?;
        finite_range("mpc.accel_max_mps2", m.accel_max_mps2, 0.05, 3.0)?;
        finite_range("mpc.alpha_max_radps2", m.alpha_max_radps2, 0.1, 10.0)?;
        for (k, w) in [
            ("mpc.w_position", m.w_position),
            ("mpc.w_terminal", m.w_terminal),
            ("mpc.w_heading", m.w_heading),
            ("mpc.w_speed", m.w_speed),
            ("mpc.w_omega", m.w_omega),
            ("mpc.w_accel", m.w_accel),
            ("mpc.w_alpha", m.w_alpha),
        ] {
            finite_range(k, w, 0.0, 1000.0)?;
        }
        finite_range("mpc.clearance_m", m.clearance_m, 0.2, 2.0)?;
        finite_range("mpc.front_disc_m", m.front_disc_m, 0.0, 1.0)?;
        range("mpc.max_obstacles", m.max_obstacles, 0, 64)?;
        finite_range("mpc.obstacle_range_m", m.obstacle_range_m, 0.5, 10.0)?;
        let f = &self.field;
        finite_range("field.size_m", f.size_m, 0.3, 1.5)?;
        finite_range("field.beta1", f.beta1, 0.0, 100.0)?;
        finite_range("field.beta2_m", f.beta2_m, 0.05, 10.0)?;
        finite_range("field.gamma", f.gamma, 0.0, 10.0)?;
        finite_range("field.d_front_m", f.d_front_m, 0.0, 3.0)?;
        finite_range("field.d_lat_m", f.d_lat_m, 0.0, 3.0)?;
        finite_range(
            "field.v_max_mps",
            f.v_max_mps,
            0.0,
            self.safety.v_forward_max_mps,
        )?;
        finite_range(
            "field.v_close_mps",
            f.v_close_mps,
            -self.safety.v_reverse_max_mps,
            f.v_max_mps,
        )?;
        finite_range("field.decay_m", f.decay_m, 0.05, 10.0)?;
        finite_range(
            "field.omega_max_radps",
            f.omega_max_radps,
            0.05,
            self.safety.omega_max_radps,
        )?;
        let sim = &self.sim;
        finite_range("sim.detector_miss_rate", sim.detector_miss_rate, 0.0, 1.0)?;
        finite_range(
            "sim.detector_false_positive_rate",
            sim.detector_false_positive_rate,
            0.0,
            1.0,
        )?;
        finite_range(
            "sim.detector_box_noise_px",
            sim.detector_box_noise_px,
            0.0,
            100.0,
        )?;
        let m = &self.map;
        finite_range("map.size_m", m.size_m, 5.0, 100.0)?;
        finite_range("map.resolution_m", m.resolution_m, 0.02, 0.2)?;
        finite_range("map.free_range_m", m.free_range_m, 0.5, 5.6)?;
        finite_range("map.half_width_m", m.half_width_m, 0.2, 1.0)?;
        finite_range("map.comfort_m", m.comfort_m, m.half_width_m, 3.0)?;
        finite_range("map.w_comfort", m.w_comfort, 0.0, 100.0)?;
        finite_range("map.w_unknown", m.w_unknown, 0.0, 100.0)?;
        finite_range("map.lookahead_m", m.lookahead_m, 0.3, 5.0)?;
        let t = &self.tracker;
        range("tracker.confirm_hits", t.confirm_hits, 1, 20)?;
        finite_range(
            "tracker.max_center_distance_m",
            t.max_center_distance_m,
            0.05,
            5.0,
        )?;
        finite_range("tracker.merge_iou", t.merge_iou, 0.0, 1.0)?;
        finite_range("tracker.miss_decay", t.miss_decay, 0.0, 1.0)?;
        finite_range("tracker.drop_confidence", t.drop_confidence, 0.0, 1.0)?;
        finite_range(
            "tracker.process_noise_m2ps",
            t.process_noise_m2ps,
            0.0,
            10.0,
        )?;
        finite_range(
            "tracker.measurement_noise_m2",
            t.measurement_noise_m2,
            1e-6,
            10.0,
        )?;
        let sw = &self.input.switch;
        finite_range("input.switch.dwell_s", sw.dwell_s, 0.5, 10.0)?;
        finite_range("input.switch.long_press_s", sw.long_press_s, 0.5, 10.0)?;
        if sw.configured() {
            sw.keys().map_err(|e| ConfigError::Range {
                key: "input.switch".into(),
                value: format!("{:?}", sw.key),
                reason: e.to_string(),
            })?;
        }
        finite_range("voice.min_confidence", self.voice.min_confidence, 0.0, 1.0)?;
        finite_range(
            "voice.max_phone_excess_per_frame",
            self.voice.max_phone_excess_per_frame,
            0.0,
            1000.0,
        )?;
        self.live.socket_addr()?;
        let r = &self.ros2;
        range("ros2.depth", r.depth, 1, 1000)?;
        range("ros2.domain_id", r.domain_id, 0, super::MAX_DOMAIN_ID)?;
        let mut seen = std::collections::BTreeMap::new();
        for (key, topic) in r.topics.all() {
            super::check_ros_topic(topic).map_err(|reason| ConfigError::Range {
                key: format!("ros2.topics.{key}"),
                value: format!("{topic:?}"),
                reason,
            })?;
            if let Some(other) = seen.insert(topic, key) {
                return Err(ConfigError::Range {
                    key: format!("ros2.topics.{key}"),
                    value: format!("{topic:?}"),
                    reason: format!("also ros2.topics.{other}: each topic has one type"),
                });
            }
        }
        let sp = &self.speech;
        range("speech.rate_wpm", sp.rate_wpm, 80, 450)?;
        range("speech.volume", sp.volume, 0, 200)?;
        for (key, v) in [("speech.command", &sp.command), ("speech.voice", &sp.voice)] {
            if v.trim().is_empty() {
                return Err(ConfigError::Range {
                    key: key.into(),
                    value: format!("{v:?}"),
                    reason: "must not be empty".into(),
                });
            }
        }
        let o = &self.depth_obstacles;
        range("depth_obstacles.stride_px", o.stride_px, 1, 16)?;
        finite_range("depth_obstacles.floor_band_m", o.floor_band_m, 0.01, 0.2)?;
        finite_range("depth_obstacles.max_height_m", o.max_height_m, 0.5, 2.5)?;
        finite_range("depth_obstacles.max_range_m", o.max_range_m, 0.5, 6.0)?;
        finite_range("depth_obstacles.drop_min_m", o.drop_min_m, 0.02, 0.5)?;
        finite_range("depth_obstacles.cell_m", o.cell_m, 0.02, 0.2)?;
        range("depth_obstacles.min_hits", o.min_hits, 1, 100)?;
        finite_range(
            "depth_obstacles.memory_radius_m",
            o.memory_radius_m,
            1.0,
            10.0,
        )?;
        let a = &self.actuation;
        // JSMerror silences the chair's own joystick while opennav drives
        // and after it exits: the person needs a stop of their own
        if a.backend == super::ActuationBackend::Rnet
            && a.rnet.mode == crate::actuation::rnet::TakeoverMode::JsmError
            && !self.input.switch.configured()
        {
            return Err(ConfigError::Range {
                key: "actuation.rnet.mode".into(),
                value: "\"jsmerror\"".into(),
                reason:
                    "silences the chair's joystick (also after opennav exits, until the chair is \
                         switched off and on): it needs an independent stop, a switch in \
                         input.switch.device; or use \"followjsm\""
                        .into(),
            });
        }
        range(
            "actuation.rnet.max_speed_percent",
            a.rnet.max_speed_percent,
            0,
            100,
        )?;
        finite_range("actuation.forward_full_mps", a.forward_full_mps, 0.1, 5.0)?;
        finite_range("actuation.reverse_full_mps", a.reverse_full_mps, 0.05, 5.0)?;
        finite_range("actuation.turn_full_radps", a.turn_full_radps, 0.1, 6.0)?;
        range("actuation.deadband", a.deadband, 0, 20)?;
        finite_range(
            "actuation.command_max_age_s",
            a.command_max_age_s,
            0.02,
            0.1,
        )?;
        finite_range("actuation.release_s", a.release_s, 0.0, 2.0)?;
        finite_range(
            "actuation.rebus.ack_timeout_s",
            a.rebus.ack_timeout_s,
            0.005,
            0.5,
        )?;
        if a.rnet.iface.trim().is_empty() {
            return Err(ConfigError::Range {
                key: "actuation.rnet.iface".into(),
                value: a.rnet.iface.clone(),
                reason: "must name a CAN interface (e.g. can0)".into(),
            });
        }
        self.camera
            .base_from_camera
            .to_isometry("camera.base_from_camera")
            .map_err(|e| ConfigError::Range {
                key: "camera.base_from_camera".into(),
                value: format!("{:?}", self.camera.base_from_camera),
                reason: e.to_string(),
            })?;
        Ok(())
    }
}
