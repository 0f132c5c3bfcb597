//! The recorder task: sensor streams and perception's output to an MCAP
//! file on its own thread. It never blocks the tasks that feed it: what
//! it cannot take is counted and logged. Last in the shutdown order.

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;

use serde::Serialize;

use crate::msg::{LaserScan, Object3D, RgbdFrame, Stamp, Stamped, WheelTicks};
use crate::perception::detector::Detection;

/// What the recorder writes.
pub enum RecordItem {
    /// A laser's scan (`true`: the left one).
    Scan(bool, Stamped<LaserScan>),
    Ticks(Stamped<WheelTicks>),
    View {
        frame: Stamped<RgbdFrame>,
        detections: Vec<Detection>,
        objects: Vec<Object3D>,
    },
    /// The camera's calibration, once it is open.
    Calibration(Stamp, Box<crate::msg::calibration::CalibrationFile>),
    /// A control step (pose, tracks, plan, sentences, supervisor).
    Step(Box<crate::live::StepView>),
}

/// The tasks' handle on the recording (cheap to clone; never waits).
pub type RecordSink = crate::sink::DropSink<RecordItem>;

/// Records when a sink is given.
pub fn record(sink: &Option<RecordSink>, item: impl FnOnce() -> RecordItem) {
    if let Some(s) = sink {
        s.put(item());
    }
}

#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct RecordReport {
    pub path: String,
    pub written: u64,
    pub dropped: u64,
    pub error: Option<String>,
}

/// A recording in progress.
pub struct Recorder {
    path: String,
    dropped: Arc<AtomicU64>,
    handle: std::thread::JoinHandle<(u64, Option<String>)>,
}

impl Recorder {
    /// Creates the file and starts the writer thread.
    pub fn start(
        path: &std::path::Path,
        info: &crate::record::RecordingInfo,
    ) -> Result<(Recorder, RecordSink), String> {
        let mut rec =
            crate::record::Recorder::create_with(path, info).map_err(|e| e.to_string())?;
        let (sink, rx, dropped) = RecordSink::channel(512, "recording: the writer");
        let handle = std::thread::Builder::new()
            .name("recorder".into())
            .spawn(move || {
                let mut written = 0u64;
                let mut error = None;
                for item in rx {
                    let r = match item {
                        RecordItem::Scan(left, s) => rec.scan(left, &s),
                        RecordItem::Ticks(t) => rec.ticks(&t),
                        RecordItem::View {
                            frame,
                            detections,
                            objects,
                        } => rec
                            .rgbd(&frame)
                            .and_then(|_| rec.detections(frame.stamp, &detections))
                            .and_then(|_| rec.objects(frame.stamp, &objects)),
                        RecordItem::Calibration(stamp, c) => rec.calibration(stamp, &c),
                        RecordItem::Step(s) => rec.step(&s),
                    };
                    match r {
                        Ok(()) => written += 1,
                        Err(e) => {
                            tracing::error!(error = %e, "recording stopped");
                            error = Some(e.to_string());
                            break;
                        }
                    }
                }
                if let Err(e) = rec.finish() {
                    error.get_or_insert(e.to_string());
                }
                (written, error)
            })
            .map_err(|e| format!("recorder thread: {e}"))?;
        Ok((
            Recorder {
                path: path.display().to_string(),
                dropped,
                handle,
            },
            sink,
        ))
    }

    /// Waits for the file to be finished; every sink must be gone (the
    /// writer thread ends when the channel closes).
    pub fn finish(self) -> RecordReport {
        let (written, error) = match self.handle.join() {
            Ok(r) => r,
            Err(_) => (0, Some("the recorder thread panicked".into())),
        };
        RecordReport {
            path: self.path,
            written,
            dropped: self.dropped.load(Ordering::SeqCst),
            error,
        }
    }
}
