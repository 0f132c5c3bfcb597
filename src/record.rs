//! Recordings in MCAP (the `mcap` crate, zstd chunks) that open in
//! Foxglove and replay exactly through the real pipeline. Every channel has
//! a schema: the live view's topics in Foxglove's (protobuf) schemas, and
//! JSON with a JSON schema for what exact replay needs beside them.
//!
//! Topics (schema):
//! - `/laser/left`, `/laser/right` (`foxglove.LaserScan`), and
//!   `/laser/left/codes`, `/laser/right/codes` (`opennav.ScanCodes`): the
//!   sensor clock, angles, per step the reading code (mm, or the URG's code
//!   below 20) and the range in metres (null: no return);
//! - `/odometry/ticks` (`opennav.WheelTicks`): the encoder board's frame;
//! - `/camera/color`, `/camera/depth` (`foxglove.RawImage`, `rgb8` and
//!   `32FC1` metres — exact, not re-quantised), one log time per pair;
//! - `/camera/calibration` (`opennav.Calibration`): the calibration file
//!   (`opennav-calibration/1`) as the run used it, once;
//! - `/camera/detections` (`foxglove.ImageAnnotations`), `/objects`
//!   (`foxglove.SceneUpdate`), and `/perception/detections`,
//!   `/perception/objects` (`opennav.Detections`, `opennav.Objects`): the
//!   2D detections of a frame and the 3D objects made of them;
//! - from each control step, as the live view (`crate::live`): `/tf`,
//!   `/tracks`, `/plan`, `/camera/obstacles`, `/said`, `/input` (the
//!   person's words and presses), `/supervisor` (with the motor
//!   interface's state and last joystick output).
//!
//! Log time = the data's stamp plus the wall-clock offset kept in the
//! metadata record `opennav` (`wall_minus_monotonic_ns`, with `version`
//! and the `config` as given), so Foxglove shows the real date and the
//! reader gives the run's stamps back. The first format (JSON scans on
//! `/laser/*`, `/camera/rgbd` as `opennav.rgbd/1`, log time = stamp) is
//! still read.

use std::collections::BTreeMap;
use std::io::BufWriter;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::msg::LaserScan;
use crate::msg::RgbdFrame;
use crate::msg::WheelTicks;
use crate::msg::{DepthImage, RgbImage};
use crate::msg::{NoReturn, Reading};
use crate::msg::{Stamp, Stamped};
use crate::perception::detector::Detection;

#[derive(Debug, thiserror::Error)]
pub enum RecordError {
    #[error("{path}: {reason}")]
    File { path: String, reason: String },
    #[error("{path}: message {index} on {topic}: {reason}")]
    Message {
        path: String,
        index: usize,
        topic: String,
        reason: String,
    },
}

pub const TOPIC_LASER_LEFT: &str = "/laser/left";
pub const TOPIC_LASER_RIGHT: &str = "/laser/right";
pub const TOPIC_TICKS: &str = "/odometry/ticks";
pub const TOPIC_RGBD: &str = "/camera/rgbd";
pub const TOPIC_CALIBRATION: &str = "/camera/calibration";
pub const TOPIC_DETECTIONS: &str = "/perception/detections";
pub const TOPIC_OBJECTS: &str = "/perception/objects";

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ScanRecord {
    pub sensor_ms: u32,
    pub angle_min_rad: f64,
    pub angle_increment_rad: f64,
    /// Per step: mm, or the URG's code below 20 (no return).
    pub codes: Vec<u32>,
    pub ranges_m: Vec<Option<f32>>,
}

fn code_of(r: &Reading) -> u32 {
    match r {
        Reading::RangeMm(v) => *v,
        Reading::NoReturn(NoReturn::NoObject) => 0,
        Reading::NoReturn(NoReturn::LowIntensity) => 1,
        Reading::NoReturn(NoReturn::StrongReflector) => 18,
        Reading::NoReturn(NoReturn::NonMeasurable) => 19,
        Reading::NoReturn(NoReturn::Other(c)) => *c as u32,
    }
}

impl ScanRecord {
    pub fn from_scan(s: &LaserScan) -> ScanRecord {
        ScanRecord {
            sensor_ms: s.sensor_ms,
            angle_min_rad: s.angle_min_rad,
            angle_increment_rad: s.angle_increment_rad,
            codes: s.readings.iter().map(code_of).collect(),
            ranges_m: s.ranges_m.clone(),
        }
    }

    pub fn to_scan(&self) -> LaserScan {
        LaserScan {
            sensor_ms: self.sensor_ms,
            angle_min_rad: self.angle_min_rad,
            angle_increment_rad: self.angle_increment_rad,
            ranges_m: self.ranges_m.clone(),
            readings: self
                .codes
                .iter()
                .map(|&c| crate::sensors::scip::classify(c))
                .collect(),
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct TicksRecord {
    pub seq: u16,
    pub mcu_time_us: u64,
    pub left: i32,
    pub right: i32,
    pub left_illegal: u16,
    pub right_illegal: u16,
    pub gap: u16,
}

impl From<&WheelTicks> for TicksRecord {
    fn from(t: &WheelTicks) -> Self {
        TicksRecord {
            seq: t.seq,
            mcu_time_us: t.mcu_time_us,
            left: t.left,
            right: t.right,
            left_illegal: t.left_illegal,
            right_illegal: t.right_illegal,
            gap: t.gap,
        }
    }
}

impl From<&TicksRecord> for WheelTicks {
    fn from(t: &TicksRecord) -> Self {
        WheelTicks {
            seq: t.seq,
            mcu_time_us: t.mcu_time_us,
            left: t.left,
            right: t.right,
            left_illegal: t.left_illegal,
            right_illegal: t.right_illegal,
            gap: t.gap,
        }
    }
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DetectionRecord {
    pub label: String,
    pub class: String,
    pub score: f32,
    pub box_xyxy: [f32; 4],
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ObjectRecord {
    pub label: String,
    pub score: f32,
    pub min_m: [f64; 3],
    pub max_m: [f64; 3],
    pub points: usize,
}

fn decode_rgbd(b: &[u8], stamp: Stamp) -> Result<RgbdFrame, String> {
    if b.len() < 12 || &b[..4] != b"RGBD" {
        return Err("not an opennav.rgbd/1 frame (no RGBD header)".into());
    }
    let w = u32::from_le_bytes([b[4], b[5], b[6], b[7]]) as usize;
    let h = u32::from_le_bytes([b[8], b[9], b[10], b[11]]) as usize;
    let n = w
        .checked_mul(h)
        .ok_or_else(|| format!("size {w}×{h} overflows"))?;
    let want = n
        .checked_mul(7)
        .and_then(|v| v.checked_add(12))
        .ok_or_else(|| format!("size {w}×{h} overflows"))?;
    if b.len() != want {
        return Err(format!("{} bytes for {w}×{h}, expected {want}", b.len()));
    }
    let rgb = b[12..12 + n * 3].to_vec();
    let depth: Vec<f32> = b[12 + n * 3..]
        .chunks_exact(4)
        .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect();
    Ok(RgbdFrame {
        color: RgbImage::new(w, h, rgb).map_err(|e| e.to_string())?,
        depth: DepthImage::new(w, h, depth).map_err(|e| e.to_string())?,
        color_stamp: stamp,
        depth_stamp: stamp,
    })
}

/// What a recording says about itself (an MCAP metadata record named
/// `opennav`, before any message).
#[derive(Debug, Clone, Default)]
pub struct RecordingInfo {
    /// Wall-clock time minus the run's monotonic clock, ns: log times are
    /// wall-clock (Foxglove shows the date); a stamp is log time − this.
    pub wall_minus_monotonic_ns: u64,
    /// The configuration the run was given (file text, overrides).
    pub config: String,
    /// Where the sensors sit (`base_link`), for the static transforms.
    pub mounting: Option<crate::live::Mounting>,
}

/// The metadata record's name and keys.
pub const METADATA_NAME: &str = "opennav";
pub const META_OFFSET: &str = "wall_minus_monotonic_ns";

/// JSON schemas of the JSON channels (`jsonschema`, draft 2020-12 subset).
mod json_schemas {
    pub const SCAN_CODES: &str = r#"{"title":"opennav.ScanCodes","type":"object","required":["sensor_ms","angle_min_rad","angle_increment_rad","codes","ranges_m"],"properties":{"sensor_ms":{"type":"integer"},"angle_min_rad":{"type":"number"},"angle_increment_rad":{"type":"number"},"codes":{"type":"array","items":{"type":"integer"}},"ranges_m":{"type":"array","items":{"type":["number","null"]}}}}"#;
    pub const TICKS: &str = r#"{"title":"opennav.WheelTicks","type":"object","required":["seq","mcu_time_us","left","right","left_illegal","right_illegal","gap"],"properties":{"seq":{"type":"integer"},"mcu_time_us":{"type":"integer"},"left":{"type":"integer"},"right":{"type":"integer"},"left_illegal":{"type":"integer"},"right_illegal":{"type":"integer"},"gap":{"type":"integer"}}}"#;
    pub const CALIBRATION: &str = r#"{"title":"opennav.Calibration","type":"object","required":["format","color","depth_scale_m","base_from_camera"],"properties":{"format":{"type":"string"},"color":{"type":"object"},"depth":{"type":"object"},"depth_scale_m":{"type":"number"},"color_from_depth":{"type":"object"},"base_from_camera":{"type":"object"},"source":{"type":"string"}}}"#;
    pub const DETECTIONS: &str = r#"{"title":"opennav.Detections","type":"array","items":{"type":"object","required":["label","class","score","box_xyxy"],"properties":{"label":{"type":"string"},"class":{"type":"string"},"score":{"type":"number"},"box_xyxy":{"type":"array","items":{"type":"number"}}}}}"#;
    pub const OBJECTS: &str = r#"{"title":"opennav.Objects","type":"array","items":{"type":"object","required":["label","score","min_m","max_m","points"],"properties":{"label":{"type":"string"},"score":{"type":"number"},"min_m":{"type":"array","items":{"type":"number"}},"max_m":{"type":"array","items":{"type":"number"}},"points":{"type":"integer"}}}}"#;
}

/// The raw laser codes (exact replay) beside each `foxglove.LaserScan`.
pub const TOPIC_LASER_LEFT_CODES: &str = "/laser/left/codes";
pub const TOPIC_LASER_RIGHT_CODES: &str = "/laser/right/codes";

/// Writes a recording: every channel has a schema — Foxglove's
/// (protobuf) where one fits, the live view's topics; JSON with a JSON
/// schema for what exact replay needs beside them.
pub struct Recorder {
    path: PathBuf,
    writer: mcap::Writer<BufWriter<std::fs::File>>,
    /// topic → channel id (made when first written)
    channels: BTreeMap<&'static str, u16>,
    sequence: u32,
    offset_ns: u64,
    mounting: Option<crate::live::Mounting>,
    static_sent: Option<Stamp>,
}

fn ns(s: Stamp) -> u64 {
    s.0.as_nanos().min(u64::MAX as u128) as u64
}

impl Recorder {
    /// A recording whose log times are the stamps (no wall-clock offset).
    pub fn create(path: &Path) -> Result<Recorder, RecordError> {
        Recorder::create_with(path, &RecordingInfo::default())
    }

    pub fn create_with(path: &Path, info: &RecordingInfo) -> Result<Recorder, RecordError> {
        let ferr = |e: &dyn std::fmt::Display| RecordError::File {
            path: path.display().to_string(),
            reason: e.to_string(),
        };
        let file = std::fs::File::create(path).map_err(|e| ferr(&e))?;
        let mut writer = mcap::WriteOptions::new()
            .profile("")
            .library(concat!("opennav ", env!("CARGO_PKG_VERSION")))
            .create(BufWriter::new(file))
            .map_err(|e| ferr(&e))?;
        let mut metadata = BTreeMap::new();
        metadata.insert(
            "version".to_string(),
            format!(
                "{} (git {})",
                env!("CARGO_PKG_VERSION"),
                env!("OPENNAV_GIT_REV")
            ),
        );
        metadata.insert(
            META_OFFSET.to_string(),
            info.wall_minus_monotonic_ns.to_string(),
        );
        metadata.insert("config".to_string(), info.config.clone());
        writer
            .write_metadata(&mcap::records::Metadata {
                name: METADATA_NAME.to_string(),
                metadata,
            })
            .map_err(|e| ferr(&e))?;
        Ok(Recorder {
            path: path.to_path_buf(),
            writer,
            channels: BTreeMap::new(),
            sequence: 0,
            offset_ns: info.wall_minus_monotonic_ns,
            mounting: info.mounting,
            static_sent: None,
        })
    }

    fn err(&self, e: &dyn std::fmt::Display) -> RecordError {
        RecordError::File {
            path: self.path.display().to_string(),
            reason: e.to_string(),
        }
    }

    /// The channel of `topic`, made with its schema the first time.
    fn channel(
        &mut self,
        topic: &'static str,
        encoding: &str,
        schema: (&str, &str, &[u8]),
    ) -> Result<u16, RecordError> {
        if let Some(id) = self.channels.get(topic) {
            return Ok(*id);
        }
        let (name, schema_encoding, data) = schema;
        let schema_id = self
            .writer
            .add_schema(name, schema_encoding, data)
            .map_err(|e| self.err(&e))?;
        let id = self
            .writer
            .add_channel(schema_id, topic, encoding, &BTreeMap::new())
            .map_err(|e| self.err(&e))?;
        self.channels.insert(topic, id);
        Ok(id)
    }

    fn put(&mut self, channel_id: u16, stamp: Stamp, data: &[u8]) -> Result<(), RecordError> {
        self.sequence = self.sequence.wrapping_add(1);
        let t = ns(stamp).saturating_add(self.offset_ns);
        self.writer
            .write_to_known_channel(
                &mcap::records::MessageHeader {
                    channel_id,
                    sequence: self.sequence,
                    log_time: t,
                    publish_time: t,
                },
                data,
            )
            .map_err(|e| self.err(&e))
    }

    /// A Foxglove message (protobuf) on `topic`.
    fn write_fg<T: foxglove::Encode>(
        &mut self,
        topic: &'static str,
        stamp: Stamp,
        msg: &T,
    ) -> Result<(), RecordError> {
        let schema = T::get_schema().ok_or_else(|| self.err(&format!("{topic}: no schema")))?;
        let id = self.channel(
            topic,
            &T::get_message_encoding(),
            (&schema.name, &schema.encoding, &schema.data),
        )?;
        let mut buf = Vec::new();
        msg.encode(&mut buf).map_err(|e| self.err(&e))?;
        self.put(id, stamp, &buf)
    }

    /// A JSON message on `topic`, its JSON schema `schema` named `name`.
    fn write_json<T: Serialize>(
        &mut self,
        topic: &'static str,
        name: &str,
        schema: &str,
        stamp: Stamp,
        v: &T,
    ) -> Result<(), RecordError> {
        let id = self.channel(topic, "json", (name, "jsonschema", schema.as_bytes()))?;
        let data = serde_json::to_vec(v).map_err(|e| self.err(&e))?;
        self.put(id, stamp, &data)
    }

    /// The wall-clock Foxglove timestamp of a stamp.
    fn ts(&self, stamp: Stamp) -> foxglove::messages::Timestamp {
        let t = ns(stamp).saturating_add(self.offset_ns);
        foxglove::messages::Timestamp::new((t / 1_000_000_000) as u32, (t % 1_000_000_000) as u32)
    }

    pub fn scan(&mut self, left: bool, s: &Stamped<LaserScan>) -> Result<(), RecordError> {
        let (topic, codes, frame) = if left {
            (
                TOPIC_LASER_LEFT,
                TOPIC_LASER_LEFT_CODES,
                crate::live::FRAME_LASER_LEFT,
            )
        } else {
            (
                TOPIC_LASER_RIGHT,
                TOPIC_LASER_RIGHT_CODES,
                crate::live::FRAME_LASER_RIGHT,
            )
        };
        let ts = self.ts(s.stamp);
        self.write_fg(
            topic,
            s.stamp,
            &crate::live::laser_scan(&s.value, frame, ts),
        )?;
        self.write_json(
            codes,
            "opennav.ScanCodes",
            json_schemas::SCAN_CODES,
            s.stamp,
            &ScanRecord::from_scan(&s.value),
        )
    }

    pub fn ticks(&mut self, t: &Stamped<WheelTicks>) -> Result<(), RecordError> {
        self.write_json(
            TOPIC_TICKS,
            "opennav.WheelTicks",
            json_schemas::TICKS,
            t.stamp,
            &TicksRecord::from(&t.value),
        )
    }

    pub fn calibration(
        &mut self,
        stamp: Stamp,
        c: &crate::msg::calibration::CalibrationFile,
    ) -> Result<(), RecordError> {
        self.write_json(
            TOPIC_CALIBRATION,
            "opennav.Calibration",
            json_schemas::CALIBRATION,
            stamp,
            c,
        )
    }

    /// Colour (`rgb8`) and depth (`32FC1`, metres: exact) with one stamp.
    pub fn rgbd(&mut self, f: &Stamped<RgbdFrame>) -> Result<(), RecordError> {
        let (color, depth) = crate::live::images(&f.value, self.ts(f.stamp));
        self.write_fg(crate::live::TOPIC_COLOR, f.stamp, &color)?;
        self.write_fg(crate::live::TOPIC_DEPTH, f.stamp, &depth)
    }

    pub fn detections(&mut self, stamp: Stamp, d: &[Detection]) -> Result<(), RecordError> {
        let v: Vec<DetectionRecord> = d
            .iter()
            .map(|d| DetectionRecord {
                label: d.label.clone(),
                class: d.class.clone(),
                score: d.score,
                box_xyxy: d.box_xyxy,
            })
            .collect();
        let ts = self.ts(stamp);
        self.write_fg(
            crate::live::TOPIC_DETECTIONS,
            stamp,
            &crate::live::image_annotations(d, ts),
        )?;
        self.write_json(
            TOPIC_DETECTIONS,
            "opennav.Detections",
            json_schemas::DETECTIONS,
            stamp,
            &v,
        )
    }

    pub fn objects(
        &mut self,
        stamp: Stamp,
        objects: &[crate::perception::boxes::Object3D],
    ) -> Result<(), RecordError> {
        let v: Vec<ObjectRecord> = objects.iter().map(object_record).collect();
        let ts = self.ts(stamp);
        self.write_fg(
            crate::live::TOPIC_OBJECTS,
            stamp,
            &crate::live::objects_scene(objects, ts),
        )?;
        self.write_json(
            TOPIC_OBJECTS,
            "opennav.Objects",
            json_schemas::OBJECTS,
            stamp,
            &v,
        )
    }

    /// A control step: the pose and the sensors' mounting (`/tf`), the
    /// tracks and approach, the MPC's path, the camera's obstacles, the
    /// sentences and the supervisor's state — as the live view shows them.
    pub fn step(&mut self, s: &crate::live::StepView) -> Result<(), RecordError> {
        use crate::live as lv;
        let ts = self.ts(s.stamp);
        if let Some(m) = self.mounting {
            if self
                .static_sent
                .is_none_or(|at| at.age_at(s.stamp) >= std::time::Duration::from_secs(1))
            {
                self.static_sent = Some(s.stamp);
                self.write_fg(lv::TOPIC_TF, s.stamp, &lv::mounting_transforms(&m, ts))?;
            }
        }
        for (topic, msg) in lv::step_messages(s, ts) {
            match msg {
                lv::StepMessage::Tf(m) => self.write_fg(topic, s.stamp, &m)?,
                lv::StepMessage::Scene(m) => self.write_fg(topic, s.stamp, &m)?,
                lv::StepMessage::Path(m) => self.write_fg(topic, s.stamp, &m)?,
                lv::StepMessage::Cloud(m) => self.write_fg(topic, s.stamp, &m)?,
                lv::StepMessage::Log(m) => self.write_fg(topic, s.stamp, &m)?,
                lv::StepMessage::Supervisor(json) => {
                    let id = self.channel(
                        lv::TOPIC_SUPERVISOR,
                        "json",
                        (
                            "opennav.Supervisor",
                            "jsonschema",
                            lv::SUPERVISOR_SCHEMA.as_bytes(),
                        ),
                    )?;
                    self.put(id, s.stamp, &json)?
                }
            }
        }
        Ok(())
    }

    pub fn finish(mut self) -> Result<(), RecordError> {
        self.writer.finish().map_err(|e| RecordError::File {
            path: self.path.display().to_string(),
            reason: e.to_string(),
        })?;
        Ok(())
    }
}

pub fn object_record(o: &crate::perception::boxes::Object3D) -> ObjectRecord {
    ObjectRecord {
        label: o.label.clone(),
        score: o.score,
        min_m: o.aabb.min_m,
        max_m: o.aabb.max_m,
        points: o.points.len(),
    }
}

#[path = "record_reader.rs"]
mod reader;
pub use reader::{read_all, RecordReader, Recorded};
