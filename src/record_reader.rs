//! Reading a recording back (split out of `record`): message by message,
//! bounded, every message decoded or an error naming it.

use std::collections::BTreeMap;
use std::path::Path;

use super::*;

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
    /// The chair's pose in `odom` (`/tf`, `odom`→`base_link`).
    Pose(Stamped<crate::msg::Pose2>),
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
    /// channel id → topic and message encoding
    topics: BTreeMap<u16, (String, String)>,
    /// log time − this = the run's stamp (the `opennav` metadata record;
    /// 0 in recordings without it)
    offset_ns: u64,
    /// A colour image waiting for its depth (same log time).
    color: Option<(u64, RgbImage)>,
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
            offset_ns: 0,
            color: None,
            index: 0,
            offset: 0,
            done: false,
        })
    }

    /// The recording's wall-clock offset (its `opennav` metadata), once
    /// read; None for a recording without it (the first format).
    pub fn wall_minus_monotonic(&self) -> Option<std::time::Duration> {
        (self.offset_ns > 0).then(|| std::time::Duration::from_nanos(self.offset_ns))
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
                            self.topics.insert(c.id, (c.topic, c.message_encoding));
                        }
                        Record::Metadata(m) if m.name == METADATA_NAME => {
                            if let Some(v) = m.metadata.get(META_OFFSET) {
                                match v.parse::<u64>() {
                                    Ok(o) => self.offset_ns = o,
                                    Err(e) => {
                                        return Err(self.file_error(format!(
                                            "metadata {META_OFFSET} {v:?}: {e}"
                                        )))
                                    }
                                }
                            }
                        }
                        Record::Message { header, data } => {
                            let Some((topic, encoding)) =
                                self.topics.get(&header.channel_id).cloned()
                            else {
                                let id = header.channel_id;
                                return Err(
                                    self.file_error(format!("message on unknown channel {id}"))
                                );
                            };
                            let index = self.index;
                            self.index += 1;
                            let stamp = Stamp(std::time::Duration::from_nanos(
                                header.log_time.saturating_sub(self.offset_ns),
                            ));
                            let msg = Message {
                                index,
                                topic,
                                encoding,
                                log_time: header.log_time,
                                stamp,
                            };
                            match decode(&self.path, &mut self.color, msg, &data) {
                                Ok(Some(r)) => return Ok(Some(r)),
                                Ok(None) => {}
                                Err(e) => {
                                    self.done = true;
                                    return Err(e);
                                }
                            }
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

/// Where a message sits in the file.
struct Message {
    index: usize,
    topic: String,
    encoding: String,
    log_time: u64,
    stamp: Stamp,
}

/// One message decoded (None: it waits for its pair, or only shows); a
/// bad one is an error naming it. `color`: a colour image waiting for its
/// depth.
fn decode(
    path: &str,
    pending_color: &mut Option<(u64, RgbImage)>,
    m: Message,
    data: &[u8],
) -> Result<Option<Recorded>, RecordError> {
    let path = path.to_string();
    let bad = |reason: String| RecordError::Message {
        path: path.clone(),
        index: m.index,
        topic: m.topic.clone(),
        reason,
    };
    let image = |data: &[u8]| -> Result<foxglove::messages::RawImage, RecordError> {
        use foxglove::Decode;
        let im = foxglove::messages::RawImage::decode(data).map_err(|e| bad(e.to_string()))?;
        let (w, h) = (im.width as usize, im.height as usize);
        let px = match im.encoding.as_str() {
            "rgb8" => 3,
            "32FC1" => 4,
            e => return Err(bad(format!("image encoding {e:?}, expected rgb8 or 32FC1"))),
        };
        let want = w.checked_mul(h).and_then(|n| n.checked_mul(px));
        if want != Some(im.data.len()) || im.step as usize != w.saturating_mul(px) {
            return Err(bad(format!(
                "{} bytes, step {} for {w}×{h} {}",
                im.data.len(),
                im.step,
                im.encoding
            )));
        }
        Ok(im)
    };
    match (m.topic.as_str(), m.encoding.as_str()) {
        (crate::live::TOPIC_COLOR, "protobuf") => {
            let im = image(data)?;
            if im.encoding != "rgb8" {
                return Err(bad(format!("colour as {}", im.encoding)));
            }
            let rgb = RgbImage::new(im.width as usize, im.height as usize, im.data.to_vec())
                .map_err(|e| bad(e.to_string()))?;
            *pending_color = Some((m.log_time, rgb));
            Ok(None)
        }
        (crate::live::TOPIC_DEPTH, "protobuf") => {
            let im = image(data)?;
            if im.encoding != "32FC1" {
                return Err(bad(format!("depth as {}", im.encoding)));
            }
            let Some((t, color)) = pending_color.take() else {
                return Err(bad("a depth image without its colour image".into()));
            };
            if t != m.log_time {
                return Err(bad(format!(
                    "depth at {} ns, its colour at {t} ns",
                    m.log_time
                )));
            }
            let depth: Vec<f32> = im
                .data
                .chunks_exact(4)
                .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
                .collect();
            let depth = DepthImage::new(im.width as usize, im.height as usize, depth)
                .map_err(|e| bad(e.to_string()))?;
            Ok(Some(Recorded::Rgbd(Stamped::new(
                m.stamp,
                RgbdFrame {
                    color,
                    depth,
                    color_stamp: m.stamp,
                    depth_stamp: m.stamp,
                },
            ))))
        }
        (crate::live::TOPIC_TF, "protobuf") => {
            use foxglove::Decode;
            let tf = foxglove::messages::FrameTransforms::decode(data)
                .map_err(|e| bad(e.to_string()))?;
            let pose = tf.transforms.iter().find(|t| {
                t.parent_frame_id == crate::live::FRAME_ODOM
                    && t.child_frame_id == crate::live::FRAME_BASE
            });
            Ok(match pose {
                Some(t) => {
                    let (Some(v), Some(q)) = (t.translation, t.rotation) else {
                        return Err(bad("odom→base_link without translation or rotation".into()));
                    };
                    let yaw =
                        (2.0 * (q.w * q.z + q.x * q.y)).atan2(1.0 - 2.0 * (q.y * q.y + q.z * q.z));
                    if !(v.x.is_finite() && v.y.is_finite() && yaw.is_finite()) {
                        return Err(bad(format!("odom→base_link not finite: {v:?} {q:?}")));
                    }
                    Some(Recorded::Pose(Stamped::new(
                        m.stamp,
                        crate::msg::Pose2 {
                            x_m: v.x,
                            y_m: v.y,
                            theta_rad: yaw,
                        },
                    )))
                }
                // the sensors' mounting
                None => Some(Recorded::Other {
                    topic: m.topic.clone(),
                    stamp: m.stamp,
                }),
            })
        }
        // the scans as Foxglove shows them: the codes beside them are
        // what replays exactly
        (TOPIC_LASER_LEFT | TOPIC_LASER_RIGHT, "protobuf") => Ok(None),
        (topic, "protobuf" | "json") if !is_replayed(topic) => Ok(Some(Recorded::Other {
            topic: m.topic.clone(),
            stamp: m.stamp,
        })),
        _ => decode_message(&path, m.index, m.topic.clone(), m.stamp, data).map(Some),
    }
}

/// Topics whose messages replay (the rest only show).
fn is_replayed(topic: &str) -> bool {
    [
        TOPIC_LASER_LEFT,
        TOPIC_LASER_RIGHT,
        TOPIC_LASER_LEFT_CODES,
        TOPIC_LASER_RIGHT_CODES,
        TOPIC_TICKS,
        TOPIC_RGBD,
        TOPIC_CALIBRATION,
        TOPIC_DETECTIONS,
        TOPIC_OBJECTS,
    ]
    .contains(&topic)
}

/// One message of the JSON topics (and the first format's `/camera/rgbd`)
/// decoded; a bad one is an error naming it.
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
        TOPIC_LASER_LEFT | TOPIC_LASER_RIGHT | TOPIC_LASER_LEFT_CODES | TOPIC_LASER_RIGHT_CODES => {
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
                left: topic == TOPIC_LASER_LEFT || topic == TOPIC_LASER_LEFT_CODES,
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
