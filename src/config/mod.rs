//! Typed settings, loaded with the `config` crate from the defaults in
//! `config/opennav.toml` (built in), an optional file, and
//! `OPENNAV_<SECTION>__<KEY>` environment variables
//! (`OPENNAV_PERCEPTION__SCORE_THRESHOLD=0.3`; a variable without `__` is
//! not configuration).
//! Unknown keys and out-of-range values are errors naming the key
//! (`validate.rs`: every range, and the checks across keys).

mod ros2;
mod validate;

pub use ros2::{check_ros_topic, Reliability, Ros2Section, Ros2Topics, MAX_DOMAIN_ID};

use std::path::{Path, PathBuf};

use config::{Config, Environment, File, FileFormat};
use serde::Deserialize;
use thiserror::Error;

use crate::msg::TransformSpec;
use crate::perception::detector::DetectorSettings;
use crate::perception::pipeline::GeometrySettings;
use crate::perception::runtime::{ExecutionProviderKind, SessionSettings};
use crate::perception::segmenter::DepthSegmenterSettings;

pub const DEFAULT_TOML: &str = include_str!("../../config/opennav.toml");

#[derive(Debug, Error)]
pub enum ConfigError {
    #[error("configuration: {0}")]
    Load(String),
    #[error("configuration key `{key}` = {value}: {reason}")]
    Range {
        key: String,
        value: String,
        reason: String,
    },
}

#[derive(Debug, Clone, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Settings {
    pub runtime: RuntimeSection,
    pub models: ModelsSection,
    pub perception: PerceptionSection,
    pub camera: CameraSection,
    pub safety: SafetySection,
    pub odometry: crate::estimation::odometry::DiffDriveParams,
    pub encoders: EncodersSection,
    pub lasers: LasersSection,
    pub actuation: ActuationSection,
    pub goal: GoalSection,
    pub mpc: crate::navigation::mpc::MpcParams,
    pub field: crate::navigation::apf::ApfParams,
    pub map: crate::navigation::map::MapSettings,
    pub tracker: crate::estimation::tracker::TrackerParams,
    pub depth_obstacles: crate::perception::depth_obstacles::DepthObstacleSettings,
    pub input: InputSection,
    pub speech: crate::speech::SpeechSettings,
    pub voice: crate::voice::VoiceSettings,
    pub live: LiveSection,
    pub ros2: Ros2Section,
    pub sim: SimSection,
}

/// The live view (config `[live]`): Foxglove's WebSocket protocol.
#[derive(Debug, Clone, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct LiveSection {
    /// Stream with `opennav run` (also `--live`).
    pub enabled: bool,
    /// host:port to listen on; 127.0.0.1 keeps it on the laptop.
    pub address: String,
}

impl LiveSection {
    /// The address, or an error naming the key.
    pub fn socket_addr(&self) -> Result<std::net::SocketAddr, ConfigError> {
        self.address.parse().map_err(|e| ConfigError::Range {
            key: "live.address".into(),
            value: self.address.clone(),
            reason: format!("not host:port with an IP address ({e})"),
        })
    }
}

/// The simulator's detector (config `[sim]`): the ground truth, with
/// misses, false positives and box noise as a real detector has them.
#[derive(Debug, Clone, Copy, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct SimSection {
    /// Each object in view is missed in a frame with this probability.
    pub detector_miss_rate: f64,
    /// A false box of a prompted word appears in a frame with this
    /// probability.
    pub detector_false_positive_rate: f64,
    /// Each box edge moves by up to this, px (uniform).
    pub detector_box_noise_px: f64,
    /// Seed of the noise (the benchmark sets each scene's).
    pub seed: u64,
    /// What detects in the simulator's frames.
    pub detector: SimDetectorChoice,
}

/// The simulator's detector (`[sim] detector`).
#[derive(Debug, Clone, Copy, Default, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub enum SimDetectorChoice {
    /// The ground truth's boxes, with the faults above: cheap, exact.
    #[default]
    Truth,
    /// The configured `[perception]` detector and segmenter on the
    /// rendered frames, as fast as they go (the camera at 30 Hz): the
    /// chair's perception load, its memory and its timing (with `--clock
    /// realtime`); what it finds in rendered rooms is not a measure of it.
    Model,
}

#[derive(Debug, Clone, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct InputSection {
    pub control_socket: String,
    pub switch: crate::input::switch::SwitchSettings,
}

#[derive(Debug, Clone, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct GoalSection {
    pub standoff_m: f64,
    pub clearance_m: f64,
    pub unseen_after_s: f64,
    pub hold_s: f64,
    pub reached_within_m: f64,
    pub search_turn_radps: f64,
    pub give_up_held_s: f64,
    pub search_at_most_s: f64,
    pub search_held_s: f64,
}

/// The control step's period (the daemon's control task): part of the
/// reaction time the stop distance must cover.
pub const CONTROL_PERIOD: std::time::Duration = std::time::Duration::from_millis(50);

/// Which motor interface drives the chair.
#[derive(Debug, Clone, Copy, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub enum ActuationBackend {
    /// R-Net over SocketCAN.
    Rnet,
    /// The R-Net "Rebus" chipset on USB serial.
    Rebus,
}

#[derive(Debug, Clone, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct ActuationSection {
    pub backend: ActuationBackend,
    pub forward_full_mps: f64,
    pub reverse_full_mps: f64,
    pub turn_full_radps: f64,
    pub deadband: i8,
    pub command_max_age_s: f64,
    pub release_s: f64,
    pub rnet: RnetSection,
    pub rebus: RebusSection,
}

#[derive(Debug, Clone, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct RnetSection {
    pub iface: String,
    pub mode: crate::actuation::rnet::TakeoverMode,
    pub max_speed_percent: u8,
}

#[derive(Debug, Clone, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct RebusSection {
    pub port: String,
    pub ack_timeout_s: f64,
}

#[derive(Debug, Clone, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct SafetySection {
    pub v_forward_max_mps: f64,
    pub v_reverse_max_mps: f64,
    pub omega_max_radps: f64,
    pub a_linear_max_mps2: f64,
    pub a_angular_max_radps2: f64,
    pub laser_max_age_s: f64,
    pub odometry_max_age_s: f64,
    pub command_max_age_s: f64,
    pub chair_width_m: f64,
    pub corridor_margin_m: f64,
    pub corridor_margin_slow_m: f64,
    pub stop_distance_m: f64,
    pub stop_distance_slow_m: f64,
    pub front_offset_m: f64,
    pub rear_offset_m: f64,
    pub overspeed_margin_mps: f64,
    pub overspeed_margin_radps: f64,
    pub overspeed_window_s: f64,
    pub camera_max_age_s: f64,
    pub max_blind_fraction: f64,
    pub turn_needs_seen_rear: bool,
    pub turn_needs_seen_floor: bool,
    pub rear_blind_deg: f64,
    pub rear_memory_s: f64,
    pub rear_confirm_s: f64,
}

#[derive(Debug, Clone, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct EncodersSection {
    pub port: String,
}

#[derive(Debug, Clone, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct LaserSection {
    pub port: String,
    pub translation_m: [f64; 3],
    pub yaw_rad: f64,
}

#[derive(Debug, Clone, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct LasersSection {
    pub left: LaserSection,
    pub right: LaserSection,
}

impl LaserSection {
    /// The scanner's pose in `base_link`.
    pub fn base_from_laser(&self) -> nalgebra::Isometry3<f64> {
        let t = self.translation_m;
        nalgebra::Isometry3::new(
            nalgebra::Vector3::new(t[0], t[1], t[2]),
            nalgebra::Vector3::z() * self.yaw_rad,
        )
    }
}

#[derive(Debug, Clone, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct RuntimeSection {
    pub onnxruntime_library: String,
    pub execution_provider: ExecutionProviderKind,
    pub intra_threads: usize,
    pub inter_threads: usize,
    pub lock_file: String,
    pub state_dir: String,
}

#[derive(Debug, Clone, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct ModelsSection {
    pub dir: PathBuf,
}

#[derive(Debug, Clone, Copy, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub enum SegmenterChoice {
    Auto,
    Sam,
    Depth,
}

#[derive(Debug, Clone, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct PerceptionSection {
    pub detector: String,
    pub segmenter: SegmenterChoice,
    pub score_threshold: f32,
    pub nms_iou: f32,
    pub max_detections: usize,
    pub erosion_iterations: usize,
    pub zscore_tau: f64,
    pub min_points: usize,
    pub min_depth_m: f32,
    pub max_depth_m: f32,
    pub merge_iou: f64,
    pub depth_segmenter: DepthSegmenterSection,
}

#[derive(Debug, Clone, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct DepthSegmenterSection {
    pub bin_m: f32,
    pub center_fraction: f32,
    pub mode_tolerance_m: f32,
    pub step_m: f32,
    pub step_per_m: f32,
    pub floor_band_m: f32,
}

#[derive(Debug, Clone, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct CameraSection {
    pub base_from_camera: TransformSpec,
}

impl Settings {
    /// Defaults, then `file` (when given), then the environment.
    /// The built-in configuration alone (`config/opennav.toml`, no file, no
    /// environment): the one place the defaults live.
    pub fn defaults() -> Settings {
        // the embedded file is checked by the unit tests below
        Self::load_with_env(None, std::iter::empty())
            .expect("the built-in config/opennav.toml is valid")
    }

    pub fn load(file: Option<&Path>) -> Result<Settings, ConfigError> {
        Self::load_with_env(file, std::env::vars())
    }

    /// As [`load`](Self::load) with the environment passed in (tests).
    pub fn load_with_env(
        file: Option<&Path>,
        env: impl IntoIterator<Item = (String, String)>,
    ) -> Result<Settings, ConfigError> {
        let mut b = Config::builder().add_source(File::from_str(DEFAULT_TOML, FileFormat::Toml));
        if let Some(f) = file {
            if !f.is_file() {
                return Err(ConfigError::Load(format!("{}: no such file", f.display())));
            }
            b = b.add_source(File::from(f).format(FileFormat::Toml).required(true));
        }
        // config keys always have a section (`OPENNAV_<SECTION>__<KEY>`);
        // other OPENNAV_ variables (OPENNAV_SHARED for the tests, say) are
        // not configuration
        let env_map: config::Map<String, String> = env
            .into_iter()
            .filter(|(k, _)| k.starts_with("OPENNAV_") && k.contains("__"))
            .collect();
        b = b.add_source(
            Environment::with_prefix("OPENNAV")
                .prefix_separator("_")
                .separator("__")
                .try_parsing(true)
                .source(Some(env_map)),
        );
        let cfg = b.build().map_err(|e| ConfigError::Load(e.to_string()))?;
        let s: Settings = cfg
            .try_deserialize()
            .map_err(|e| ConfigError::Load(e.to_string()))?;
        s.validate()?;
        Ok(s)
    }

    pub fn session_settings(&self) -> SessionSettings {
        SessionSettings {
            provider: self.runtime.execution_provider,
            intra_threads: self.runtime.intra_threads,
            inter_threads: self.runtime.inter_threads,
        }
    }

    pub fn detector_settings(&self) -> DetectorSettings {
        DetectorSettings {
            score_threshold: self.perception.score_threshold,
            nms_iou: self.perception.nms_iou,
            max_detections: self.perception.max_detections,
            session: self.session_settings(),
        }
    }

    pub fn geometry_settings(&self) -> GeometrySettings {
        let p = &self.perception;
        GeometrySettings {
            erosion_iterations: p.erosion_iterations,
            zscore_tau: p.zscore_tau,
            min_points: p.min_points,
            min_depth_m: p.min_depth_m,
            max_depth_m: p.max_depth_m,
        }
    }

    pub fn depth_segmenter_settings(&self) -> DepthSegmenterSettings {
        let d = &self.perception.depth_segmenter;
        DepthSegmenterSettings {
            bin_m: d.bin_m,
            center_fraction: d.center_fraction,
            mode_tolerance_m: d.mode_tolerance_m,
            step_m: d.step_m,
            step_per_m: d.step_per_m,
            floor_band_m: d.floor_band_m,
        }
    }

    pub fn safety_limits(&self) -> crate::safety::SafetyLimits {
        let s = &self.safety;
        let d = std::time::Duration::from_secs_f64;
        crate::safety::SafetyLimits {
            v_forward_max_mps: s.v_forward_max_mps,
            v_reverse_max_mps: s.v_reverse_max_mps,
            omega_max_radps: s.omega_max_radps,
            a_linear_max_mps2: s.a_linear_max_mps2,
            a_angular_max_radps2: s.a_angular_max_radps2,
            laser_max_age: d(s.laser_max_age_s),
            odometry_max_age: d(s.odometry_max_age_s),
            command_max_age: d(s.command_max_age_s),
            chair_width_m: s.chair_width_m,
            corridor_margin_m: s.corridor_margin_m,
            corridor_margin_slow_m: s.corridor_margin_slow_m,
            stop_distance_m: s.stop_distance_m,
            stop_distance_slow_m: s.stop_distance_slow_m,
            front_offset_m: s.front_offset_m,
            rear_offset_m: s.rear_offset_m,
            overspeed_margin_mps: s.overspeed_margin_mps,
            overspeed_margin_radps: s.overspeed_margin_radps,
            overspeed_window: d(s.overspeed_window_s),
            camera_max_age: self.depth_obstacles.enabled.then(|| d(s.camera_max_age_s)),
            max_blind_fraction: s.max_blind_fraction,
            turn_needs_seen_rear: s.turn_needs_seen_rear,
            turn_needs_seen_floor: s.turn_needs_seen_floor,
        }
    }

    pub fn rear_settings(&self) -> crate::safety::rear::RearSettings {
        let s = &self.safety;
        let half = (s.rear_blind_deg / 2.0).to_radians();
        crate::safety::rear::RearSettings {
            blind_half_angle_rad: half,
            seen_half_angle_rad: std::f64::consts::PI - half,
            memory: std::time::Duration::from_secs_f64(s.rear_memory_s),
            confirm_for: std::time::Duration::from_secs_f64(s.rear_confirm_s),
            ..Default::default()
        }
    }

    pub fn goal_settings(&self) -> crate::estimation::goal::GoalSettings {
        let g = &self.goal;
        crate::estimation::goal::GoalSettings {
            standoff_m: g.standoff_m,
            front_offset_m: self.safety.front_offset_m,
            clearance_m: g.clearance_m,
            unseen_after: std::time::Duration::from_secs_f64(g.unseen_after_s),
            hold_for: std::time::Duration::from_secs_f64(g.hold_s),
            reached_within_m: g.reached_within_m,
            search_turn_radps: g.search_turn_radps,
            give_up_held_after: std::time::Duration::from_secs_f64(g.give_up_held_s),
            search_at_most: std::time::Duration::from_secs_f64(g.search_at_most_s),
            search_held_for: std::time::Duration::from_secs_f64(g.search_held_s),
        }
    }

    /// The instance lock's path (`runtime.lock_file`, or the runtime
    /// directory's).
    pub fn lock_path(&self) -> PathBuf {
        if !self.runtime.lock_file.is_empty() {
            return PathBuf::from(&self.runtime.lock_file);
        }
        for var in ["RUNTIME_DIRECTORY", "XDG_RUNTIME_DIR"] {
            if let Some(d) = std::env::var_os(var).filter(|d| !d.is_empty()) {
                return PathBuf::from(d).join("opennav.lock");
            }
        }
        // SAFETY: getuid has no preconditions
        let uid = unsafe { libc::getuid() };
        std::env::temp_dir().join(format!("opennav-{uid}.lock"))
    }

    /// Where latched faults are kept (`runtime.state_dir`, or systemd's
    /// state directory, or the user's); None when no such place is known.
    pub fn state_dir(&self) -> Option<PathBuf> {
        if !self.runtime.state_dir.is_empty() {
            return Some(PathBuf::from(&self.runtime.state_dir));
        }
        let var = |v: &str| {
            std::env::var_os(v)
                .filter(|d| !d.is_empty())
                .map(PathBuf::from)
        };
        var("STATE_DIRECTORY")
            .or_else(|| var("XDG_STATE_HOME").map(|d| d.join("opennav")))
            .or_else(|| var("HOME").map(|h| h.join(".local/state/opennav")))
    }

    /// The chair's joystick calibration.
    pub fn joystick_mapping(&self) -> crate::actuation::rnet::JoystickMapping {
        let a = &self.actuation;
        crate::actuation::rnet::JoystickMapping {
            forward_full_mps: a.forward_full_mps,
            reverse_full_mps: a.reverse_full_mps,
            turn_full_radps: a.turn_full_radps,
            deadband: a.deadband,
        }
    }

    /// The R-Net writer's settings.
    pub fn rnet_settings(&self) -> crate::actuation::writer::RnetSettings {
        let a = &self.actuation;
        let mut s =
            crate::actuation::writer::RnetSettings::new(a.rnet.mode, self.joystick_mapping());
        s.command_max_age = std::time::Duration::from_secs_f64(a.command_max_age_s);
        s.max_speed_percent = Some(a.rnet.max_speed_percent);
        s.release_after = std::time::Duration::from_secs_f64(a.release_s);
        s
    }

    pub fn drive_params(&self) -> crate::estimation::odometry::DiffDriveParams {
        self.odometry
    }

    /// The ONNX Runtime library path from config (None when empty).
    pub fn onnxruntime_library(&self) -> Option<PathBuf> {
        let s = self.runtime.onnxruntime_library.trim();
        (!s.is_empty()).then(|| PathBuf::from(s))
    }
}

#[cfg(test)]
#[path = "config_tests.rs"]
mod tests;
