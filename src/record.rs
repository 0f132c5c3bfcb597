//! Recordings in MCAP (the `mcap` crate, zstd chunks): what the chair
//! sensed and what perception made of it, stamped with the acquisition
//! time, for replay through the real pipeline and comparison.
//!
//! Topics (message encodings):
//! - `/laser/left`, `/laser/right` (`json`): a scan — sensor clock, angles,
//!   per step the reading code (mm, or the URG's code below 20) and the
//!   range in metres (null: no return);
//! - `/odometry/ticks` (`json`): the encoder board's frame;
//! - `/camera/rgbd` (`opennav.rgbd/1`): colour and depth of one paired
//!   frame, binary: `"RGBD"`, u32 width, u32 height (little-endian), RGB
//!   bytes, then depth as f32 metres (little-endian) — exact, not
//!   re-quantised;
//! - `/camera/calibration` (`json`): the calibration file
//!   (`opennav-calibration/1`), once;
//! - `/perception/detections`, `/perception/objects` (`json`): the 2D
//!   detections of a frame and the 3D objects made of them.
//!
//! Log time = the data's stamp (ns of the monotonic clock).

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

fn encode_rgbd(f: &RgbdFrame) -> Vec<u8> {
    let (w, h) = (f.color.width(), f.color.height());
    let d = f.depth.data();
    let mut out = Vec::with_capacity(12 + w * h * 3 + d.len() * 4);
    out.extend_from_slice(b"RGBD");
    out.extend_from_slice(&(w as u32).to_le_bytes());
    out.extend_from_slice(&(h as u32).to_le_bytes());
    out.extend_from_slice(f.color.data());
    for z in d {
        out.extend_from_slice(&z.to_le_bytes());
    }
    out
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

/// Writes a recording.
pub struct Recorder {
    path: PathBuf,
    writer: mcap::Writer<BufWriter<std::fs::File>>,
    channels: BTreeMap<&'static str, u16>,
    sequence: u32,
}

fn ns(s: Stamp) -> u64 {
    s.0.as_nanos().min(u64::MAX as u128) as u64
}

impl Recorder {
    pub fn create(path: &Path) -> Result<Recorder, RecordError> {
        let ferr = |e: &dyn std::fmt::Display| RecordError::File {
            path: path.display().to_string(),
            reason: e.to_string(),
        };
        let file = std::fs::File::create(path).map_err(|e| ferr(&e))?;
        let mut writer = mcap::WriteOptions::new()
            .profile("opennav")
            .library("opennav")
            .create(BufWriter::new(file))
            .map_err(|e| ferr(&e))?;
        let mut channels = BTreeMap::new();
        for (topic, enc) in [
            (TOPIC_LASER_LEFT, "json"),
            (TOPIC_LASER_RIGHT, "json"),
            (TOPIC_TICKS, "json"),
            (TOPIC_RGBD, "opennav.rgbd/1"),
            (TOPIC_CALIBRATION, "json"),
            (TOPIC_DETECTIONS, "json"),
            (TOPIC_OBJECTS, "json"),
        ] {
            let id = writer
                .add_channel(0, topic, enc, &BTreeMap::new())
                .map_err(|e| ferr(&e))?;
            channels.insert(topic, id);
        }
        Ok(Recorder {
            path: path.to_path_buf(),
            writer,
            channels,
            sequence: 0,
        })
    }

    fn write(&mut self, topic: &'static str, stamp: Stamp, data: &[u8]) -> Result<(), RecordError> {
        let channel_id = *self.channels.get(topic).ok_or_else(|| RecordError::File {
            path: self.path.display().to_string(),
            reason: format!("no channel {topic}"),
        })?;
        self.sequence = self.sequence.wrapping_add(1);
        self.writer
            .write_to_known_channel(
                &mcap::records::MessageHeader {
                    channel_id,
                    sequence: self.sequence,
                    log_time: ns(stamp),
                    publish_time: ns(stamp),
                },
                data,
            )
            .map_err(|e| RecordError::File {
                path: self.path.display().to_string(),
                reason: e.to_string(),
            })
    }

    fn write_json<T: Serialize>(
        &mut self,
        topic: &'static str,
        stamp: Stamp,
        v: &T,
    ) -> Result<(), RecordError> {
        let data = serde_json::to_vec(v).map_err(|e| RecordError::File {
            path: self.path.display().to_string(),
            reason: e.to_string(),
        })?;
        self.write(topic, stamp, &data)
    }

    pub fn scan(&mut self, left: bool, s: &Stamped<LaserScan>) -> Result<(), RecordError> {
        let topic = if left {
            TOPIC_LASER_LEFT
        } else {
            TOPIC_LASER_RIGHT
        };
        self.write_json(topic, s.stamp, &ScanRecord::from_scan(&s.value))
    }

    pub fn ticks(&mut self, t: &Stamped<WheelTicks>) -> Result<(), RecordError> {
        self.write_json(TOPIC_TICKS, t.stamp, &TicksRecord::from(&t.value))
    }

    pub fn calibration(
        &mut self,
        stamp: Stamp,
        c: &crate::msg::calibration::CalibrationFile,
    ) -> Result<(), RecordError> {
        self.write_json(TOPIC_CALIBRATION, stamp, c)
    }

    pub fn rgbd(&mut self, f: &Stamped<RgbdFrame>) -> Result<(), RecordError> {
        self.write(TOPIC_RGBD, f.stamp, &encode_rgbd(&f.value))
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
        self.write_json(TOPIC_DETECTIONS, stamp, &v)
    }

    pub fn objects(
        &mut self,
        stamp: Stamp,
        objects: &[crate::perception::boxes::Object3D],
    ) -> Result<(), RecordError> {
        let v: Vec<ObjectRecord> = objects.iter().map(object_record).collect();
        self.write_json(TOPIC_OBJECTS, stamp, &v)
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

/// One decoded message of a recording.
#[derive(Debug, Clone)]
pub enum Recorded {
    Scan {
        left: bool,
        scan: Stamped<LaserScan>,
    },
    Ticks(Stamped<WheelTicks>),
    Rgbd(Stamped<RgbdFrame>),
    Calibration(Box<crate::msg::calibration::CalibrationFile>),
    Detections(Stamp, Vec<Detection>),
    Objects(Stamp, Vec<ObjectRecord>),
    /// A topic this version does not know (kept, not dropped silently).
    Other {
        topic: String,
        stamp: Stamp,
    },
}

/// Largest record (or decompressed chunk) accepted: a corrupt length field
/// is an error, not a huge allocation.
const RECORD_LIMIT: usize = 256 << 20;

/// Reads a recording message by message: what is held at once is one
/// record (or one chunk being decompressed), at most [`RECORD_LIMIT`]
/// bytes and never more than 64 times the file's size, checked before
/// allocating; chunk CRCs are checked before decompressing. A bad message
/// or a truncated file is an error naming it, after the good messages
/// before it.
pub struct RecordReader {
    path: String,
    file: std::fs::File,
    reader: mcap::sans_io::linear_reader::LinearReader,
    topics: BTreeMap<u16, String>,
    /// Messages decoded so far.
    index: usize,
    offset: u64,
    done: bool,
}

impl RecordReader {
    pub fn open(path: &Path) -> Result<RecordReader, RecordError> {
        use mcap::sans_io::linear_reader::{LinearReader, LinearReaderOptions};
        let p = path.display().to_string();
        let file_err = |e: std::io::Error| RecordError::File {
            path: p.clone(),
            reason: e.to_string(),
        };
        let file = std::fs::File::open(path).map_err(file_err)?;
        let len = file.metadata().map_err(file_err)?.len();
        let limit = usize::try_from(len)
            .unwrap_or(usize::MAX)
            .max(1)
            .saturating_mul(64)
            .min(RECORD_LIMIT);
        Ok(RecordReader {
            path: p,
            file,
            reader: LinearReader::new_with_options(
                LinearReaderOptions::default()
                    .with_record_length_limit(limit)
                    .with_prevalidate_chunk_crcs(true),
            ),
            topics: BTreeMap::new(),
            index: 0,
            offset: 0,
            done: false,
        })
    }

    fn file_error(&mut self, reason: String) -> RecordError {
        self.done = true;
        RecordError::File {
            path: self.path.clone(),
            reason,
        }
    }

    /// The next message, None at the end of the file.
    fn next_message(&mut self) -> Result<Option<Recorded>, RecordError> {
        use mcap::records::Record;
        use mcap::sans_io::linear_reader::LinearReadEvent;
        use std::io::Read;
        while let Some(event) = self.reader.next_event() {
            let event = match event {
                Ok(e) => e,
                Err(e) => return Err(self.file_error(format!("not a valid MCAP file: {e}"))),
            };
            match event {
                LinearReadEvent::ReadRequest(n) => {
                    let buf = self.reader.insert(n);
                    let got = match self.file.read(buf) {
                        Ok(k) => k,
                        Err(e) => return Err(self.file_error(e.to_string())),
                    };
                    if got == 0 {
                        let at = self.offset;
                        return Err(self.file_error(format!("truncated after {at} bytes")));
                    }
                    self.reader.notify_read(got);
                    self.offset += got as u64;
                }
                LinearReadEvent::Record { data, opcode } => {
                    let record = match mcap::parse_record(opcode, data) {
                        Ok(r) => r,
                        Err(e) => return Err(self.file_error(format!("record {opcode:#04x}: {e}"))),
                    };
                    match record {
                        Record::Channel(c) => {
                            self.topics.insert(c.id, c.topic);
                        }
                        Record::Message { header, data } => {
                            let Some(topic) = self.topics.get(&header.channel_id).cloned() else {
                                let id = header.channel_id;
                                return Err(
                                    self.file_error(format!("message on unknown channel {id}"))
                                );
                            };
                            let index = self.index;
                            self.index += 1;
                            let stamp = Stamp(std::time::Duration::from_nanos(header.log_time));
                            return decode_message(&self.path, index, topic, stamp, &data)
                                .map(Some)
                                .inspect_err(|_| self.done = true);
                        }
                        _ => {}
                    }
                }
            }
        }
        Ok(None)
    }
}

impl Iterator for RecordReader {
    type Item = Result<Recorded, RecordError>;

    fn next(&mut self) -> Option<Self::Item> {
        if self.done {
            return None;
        }
        match self.next_message() {
            Ok(Some(r)) => Some(Ok(r)),
            Ok(None) => {
                self.done = true;
                None
            }
            Err(e) => Some(Err(e)),
        }
    }
}

/// One message decoded; a bad one is an error naming it.
fn decode_message(
    p: &str,
    index: usize,
    topic: String,
    stamp: Stamp,
    data: &[u8],
) -> Result<Recorded, RecordError> {
    let bad = |reason: String| RecordError::Message {
        path: p.to_string(),
        index,
        topic: topic.clone(),
        reason,
    };
    let json = |d: &[u8]| -> Result<serde_json::Value, RecordError> {
        serde_json::from_slice(d).map_err(|e| bad(e.to_string()))
    };
    let rec = match topic.as_str() {
        TOPIC_LASER_LEFT | TOPIC_LASER_RIGHT => {
            let r: ScanRecord =
                serde_json::from_value(json(data)?).map_err(|e| bad(e.to_string()))?;
            if r.codes.len() != r.ranges_m.len() {
                return Err(bad(format!(
                    "{} codes but {} ranges",
                    r.codes.len(),
                    r.ranges_m.len()
                )));
            }
            Recorded::Scan {
                left: topic == TOPIC_LASER_LEFT,
                scan: Stamped::new(stamp, r.to_scan()),
            }
        }
        TOPIC_TICKS => {
            let r: TicksRecord =
                serde_json::from_value(json(data)?).map_err(|e| bad(e.to_string()))?;
            Recorded::Ticks(Stamped::new(stamp, WheelTicks::from(&r)))
        }
        TOPIC_RGBD => Recorded::Rgbd(Stamped::new(stamp, decode_rgbd(data, stamp).map_err(bad)?)),
        TOPIC_CALIBRATION => Recorded::Calibration(Box::new(
            serde_json::from_value(json(data)?).map_err(|e| bad(e.to_string()))?,
        )),
        TOPIC_DETECTIONS => {
            let v: Vec<DetectionRecord> =
                serde_json::from_value(json(data)?).map_err(|e| bad(e.to_string()))?;
            Recorded::Detections(
                stamp,
                v.into_iter()
                    .map(|d| Detection {
                        label: d.label,
                        class: d.class,
                        score: d.score,
                        box_xyxy: d.box_xyxy,
                    })
                    .collect(),
            )
        }
        TOPIC_OBJECTS => Recorded::Objects(
            stamp,
            serde_json::from_value(json(data)?).map_err(|e| bad(e.to_string()))?,
        ),
        _ => Recorded::Other { topic, stamp },
    };
    Ok(rec)
}

/// Reads a whole recording, in file order (for short recordings and
/// tests; [`RecordReader`] streams); a bad message is an error naming it.
pub fn read_all(path: &Path) -> Result<Vec<Recorded>, RecordError> {
    RecordReader::open(path)?.collect()
}
