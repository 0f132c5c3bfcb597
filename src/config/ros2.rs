//! The ROS 2 bridge's configuration (`[ros2]`): whether it runs, the DDS
//! domain, the sensors' reliability, the history depth and the topic names
//! (checked as absolute ROS names).

use serde::Deserialize;

use super::ConfigError;

/// The ROS 2 bridge (config `[ros2]`).
#[derive(Debug, Clone, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Ros2Section {
    /// Bridge with `opennav run` (also `--ros2`).
    pub enabled: bool,
    /// The DDS domain (`ROS_DOMAIN_ID` overrides it).
    pub domain_id: u16,
    /// Reliability of the scans and the odometry.
    pub sensor_reliability: Reliability,
    /// History depth of each published topic.
    pub depth: u32,
    pub topics: Ros2Topics,
}

/// A DDS reliability.
#[derive(Debug, Clone, Copy, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
pub enum Reliability {
    BestEffort,
    Reliable,
}

/// The bridge's topic names (absolute ROS names).
#[derive(Debug, Clone, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Ros2Topics {
    pub said: String,
    pub state: String,
    pub prompt: String,
    pub stop: String,
    pub scan_left: String,
    pub scan_right: String,
    pub odom: String,
    pub tf: String,
    pub tf_static: String,
    pub objects: String,
    pub tracks: String,
}

impl Ros2Topics {
    /// Each topic with its key's last part.
    pub fn all(&self) -> [(&'static str, &str); 11] {
        [
            ("said", &self.said),
            ("state", &self.state),
            ("prompt", &self.prompt),
            ("stop", &self.stop),
            ("scan_left", &self.scan_left),
            ("scan_right", &self.scan_right),
            ("odom", &self.odom),
            ("tf", &self.tf),
            ("tf_static", &self.tf_static),
            ("objects", &self.objects),
            ("tracks", &self.tracks),
        ]
    }
}

/// The highest DDS domain id (its port mapping ends there).
pub const MAX_DOMAIN_ID: u16 = 232;

impl Ros2Section {
    /// The domain: `ROS_DOMAIN_ID` when the environment sets it (`env`),
    /// else the configured one; a bad value is an error naming it.
    pub fn domain(&self, env: Option<&str>) -> Result<u16, ConfigError> {
        let Some(v) = env.map(str::trim).filter(|v| !v.is_empty()) else {
            return Ok(self.domain_id);
        };
        match v.parse::<u16>() {
            Ok(d) if d <= MAX_DOMAIN_ID => Ok(d),
            _ => Err(ConfigError::Range {
                key: "ROS_DOMAIN_ID (environment)".into(),
                value: format!("{v:?}"),
                reason: format!("not a DDS domain id (0–{MAX_DOMAIN_ID})"),
            }),
        }
    }
}

/// Whether `name` is an absolute ROS topic name: `/`, then tokens of
/// letters, digits and underscores (not starting with a digit, no `__`)
/// joined by single `/`; no trailing `/`. Says what is wrong otherwise.
pub fn check_ros_topic(name: &str) -> Result<(), String> {
    let Some(rest) = name.strip_prefix('/') else {
        return Err("must be absolute (start with /)".into());
    };
    if rest.is_empty() {
        return Err("has no name after /".into());
    }
    for token in rest.split('/') {
        let mut chars = token.chars();
        match chars.next() {
            None => return Err("has an empty part (// or a trailing /)".into()),
            Some(c) if c.is_ascii_digit() => {
                return Err(format!("part {token:?} starts with a digit"))
            }
            _ => {}
        }
        if let Some(c) = token
            .chars()
            .find(|c| !(c.is_ascii_alphanumeric() || *c == '_'))
        {
            return Err(format!("has {c:?}: only letters, digits, _ and /"));
        }
        if token.contains("__") {
            return Err(format!("part {token:?} has a double underscore"));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::tests::env;
    use crate::config::Settings;

    #[test]
    fn ros2_topics_are_absolute_ros_names_each_once_and_the_domain_is_checked() {
        let s = Settings::defaults();
        assert_eq!(s.ros2.topics.odom, "/odom");
        assert_eq!(s.ros2.sensor_reliability, Reliability::BestEffort);
        for ok in ["/scan", "/opennav/said", "/a_1/b2"] {
            assert!(check_ros_topic(ok).is_ok(), "{ok}");
        }
        for bad in ["scan", "/", "/a//b", "/a/", "/1a", "/a-b", "/a__b", "/a b"] {
            assert!(check_ros_topic(bad).is_err(), "{bad}");
        }
        for (k, v, key) in [
            ("OPENNAV_ROS2__TOPICS__ODOM", "odom", "ros2.topics.odom"),
            ("OPENNAV_ROS2__TOPICS__TF", "/odom", "ros2.topics.odom"),
            ("OPENNAV_ROS2__DEPTH", "0", "ros2.depth"),
            ("OPENNAV_ROS2__DOMAIN_ID", "233", "ros2.domain_id"),
            (
                "OPENNAV_ROS2__SENSOR_RELIABILITY",
                "sometimes",
                "sensor_reliability",
            ),
        ] {
            let e = Settings::load_with_env(None, env(&[(k, v)])).unwrap_err();
            assert!(e.to_string().contains(key), "{k}={v}: {e}");
        }
        assert_eq!(s.ros2.domain(None).ok(), Some(0));
        assert_eq!(s.ros2.domain(Some("42")).ok(), Some(42));
        assert_eq!(s.ros2.domain(Some(" ")).ok(), Some(0));
        for bad in ["233", "x", "-1"] {
            let e = s.ros2.domain(Some(bad)).unwrap_err();
            assert!(e.to_string().contains("ROS_DOMAIN_ID"), "{e}");
        }
    }
}
