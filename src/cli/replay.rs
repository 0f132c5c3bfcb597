//! `opennav replay FILE.mcap [--live [ADDR]]`: a recording played back
//! through perception (the recorded detections, the depth-guided
//! segmenter, erosion, z-score, back-projection) and the tracker (placed
//! with the recorded pose), one JSON line per view — its objects and
//! whether they are the recorded ones — then a summary with the tracks;
//! with `--live`, streamed to Foxglove at the recording's pace.

use std::path::PathBuf;

use clap::Args;
use serde_json::json;

use opennav::config::Settings;
use opennav::estimation::tracker::Tracker;
use opennav::msg::calibration::RgbdCalibration;
use opennav::msg::{Frame, Object3D, Pose2, RgbdFrame, Stamp, Stamped};
use opennav::perception::detector::Detection;
use opennav::perception::pipeline::{depth_in_color, lift_detections};
use opennav::perception::segmenter::DepthBoxSegmenter;
use opennav::record::{object_record, RecordReader, Recorded};

use super::{bad_input, failed, Failure};

#[derive(Args, Debug)]
pub struct ReplayArgs {
    /// The recording (`opennav run --record FILE.mcap`).
    pub file: PathBuf,
    /// The camera's calibration, for a recording that has none (the first
    /// format did not write it); else the recorded one.
    #[arg(long)]
    pub calibration: Option<PathBuf>,
    /// Stream the replay to Foxglove (WebSocket) on ADDR, default
    /// `[live] address`, at the recording's pace.
    #[arg(long, value_name = "ADDR", num_args = 0..=1, default_missing_value = "")]
    pub live: Option<String>,
}

/// A view waiting for its detections and recorded objects (same stamp).
struct PendingView {
    frame: Stamped<RgbdFrame>,
    replayed: Option<(Vec<Detection>, Vec<Object3D>)>,
}

pub fn run(config: Option<&std::path::Path>, args: ReplayArgs) -> Result<(), Failure> {
    let settings = Settings::load(config).map_err(bad_input)?;
    let mut calibration = match &args.calibration {
        Some(p) => Some(RgbdCalibration::load(p).map_err(bad_input)?),
        None => None,
    };
    let reader = RecordReader::open(&args.file).map_err(bad_input)?;
    let mut segmenter = DepthBoxSegmenter::new(settings.depth_segmenter_settings());
    let geometry = settings.geometry_settings();
    let mut tracker = Tracker::new(settings.tracker);
    // where to stream, started at the first message: the recording's clock
    // offset is known then (its metadata record comes first)
    let mut live_to = match args.live.as_deref() {
        None => None,
        Some(a) => {
            let address = if a.is_empty() {
                settings.live.socket_addr().map_err(bad_input)?
            } else {
                a.parse().map_err(|e| {
                    bad_input(anyhow::anyhow!(
                        "--live {a:?}: not host:port with an IP address ({e})"
                    ))
                })?
            };
            let mounting = opennav::live::Mounting {
                laser_left: settings.lasers.left.base_from_laser(),
                laser_right: settings.lasers.right.base_from_laser(),
                camera: settings
                    .camera
                    .base_from_camera
                    .to_isometry("camera.base_from_camera")
                    .map_err(bad_input)?,
            };
            Some((address, mounting))
        }
    };
    let mut live: Option<opennav::live::Live> = None;
    let mut live_sink: Option<opennav::live::LiveSink> = None;
    let mut pose: Option<Pose2> = None;
    let mut view: Option<PendingView> = None;
    let (mut views, mut same) = (0u64, 0u64);
    // the pace of a live replay: the first stamp against the wall clock
    let mut pace: Option<(Stamp, std::time::Instant)> = None;
    let mut reader = reader;
    while let Some(item) = reader.next() {
        let item = item.map_err(failed)?;
        if let Some((address, mounting)) = live_to.take() {
            let (started_tx, started_rx) = std::sync::mpsc::channel();
            // the recorded wall-clock times; a first-format recording has
            // none: its stamps shown from now
            let offset = match reader.wall_minus_monotonic() {
                Some(o) => o,
                None => opennav::live::wall_offset(Stamp::ZERO),
            };
            let (l, sink) =
                opennav::live::Live::start(address, mounting, offset, Some(&started_tx), None)
                    .map_err(|e| failed(anyhow::anyhow!(e)))?;
            if let Ok(a) = started_rx.try_recv() {
                eprintln!("opennav: live view on ws://{a} (Foxglove: Open connection → Foxglove WebSocket)");
            }
            live = Some(l);
            live_sink = Some(sink);
        }
        match item {
            // the one given on the command line wins
            Recorded::Calibration(c) if calibration.is_none() => {
                calibration = Some(RgbdCalibration::from_file(&c).map_err(|e| {
                    bad_input(anyhow::anyhow!(
                        "{}: the recorded calibration: {e}",
                        args.file.display()
                    ))
                })?);
            }
            Recorded::Pose(p) => pose = Some(p.value),
            Recorded::Rgbd(f) => {
                if live_sink.is_some() {
                    let (t0, w0) = *pace.get_or_insert((f.stamp, std::time::Instant::now()));
                    let due = w0 + f.stamp.0.saturating_sub(t0.0);
                    std::thread::sleep(due.saturating_duration_since(std::time::Instant::now()));
                }
                view = Some(PendingView {
                    frame: f,
                    replayed: None,
                });
            }
            Recorded::Detections(stamp, dets) => {
                let Some(v) = view.as_mut().filter(|v| v.frame.stamp == stamp) else {
                    continue;
                };
                let Some(cal) = &calibration else {
                    return Err(bad_input(anyhow::anyhow!(
                        "{}: no calibration recorded before the first view (a first-format \
                         recording): give --calibration FILE",
                        args.file.display()
                    )));
                };
                let depth = depth_in_color(cal, &v.frame.value.color, &v.frame.value.depth)
                    .map_err(failed)?;
                let r = lift_detections(
                    &mut segmenter,
                    &v.frame.value.color,
                    &depth,
                    dets.clone(),
                    &cal.color,
                    &cal.base_from_camera,
                    Frame::BaseLink,
                    &geometry,
                    opennav::perception::pipeline::floor_in_image(cal),
                )
                .map_err(failed)?;
                v.replayed = Some((dets, r.objects));
            }
            Recorded::Objects(stamp, recorded) => {
                let Some(v) = view.take().filter(|v| v.frame.stamp == stamp) else {
                    continue;
                };
                let Some((dets, objects)) = v.replayed else {
                    continue;
                };
                views += 1;
                let replayed: Vec<_> = objects.iter().map(object_record).collect();
                let is_same = replayed == recorded;
                same += u64::from(is_same);
                if let Some(p) = pose {
                    place(&mut tracker, stamp, p, &objects);
                }
                println!(
                    "{}",
                    json!({
                        "stamp_s": stamp.0.as_secs_f64(),
                        "detections": dets.len(),
                        "objects": replayed,
                        "same_as_recorded": is_same,
                    })
                );
                opennav::live::show(&live_sink, || opennav::live::LiveItem::View {
                    frame: v.frame.clone(),
                    detections: dets.clone(),
                    objects: objects.clone(),
                });
                opennav::live::show(&live_sink, || {
                    opennav::live::LiveItem::Step(Box::new(step_view(stamp, pose, &tracker)))
                });
            }
            _ => {}
        }
    }
    drop(live_sink);
    if let Some(l) = live {
        let r = l.finish();
        if r.dropped > 0 {
            eprintln!(
                "opennav: live view: {} of {} items dropped",
                r.dropped,
                r.dropped + r.shown
            );
        }
    }
    let tracks: Vec<_> = tracker
        .tracks()
        .iter()
        .filter(|t| t.confirmed)
        .map(|t| json!({"label": t.label, "center_m": t.center_m, "hits": t.hits}))
        .collect();
    println!(
        "{}",
        json!({"summary": {"views": views, "same_as_recorded": same, "tracks": tracks}})
    );
    if views == 0 {
        return Err(bad_input(anyhow::anyhow!(
            "{}: no camera views with detections in the recording",
            args.file.display()
        )));
    }
    Ok(())
}

/// Objects seen from `pose` into the tracker, in `odom`.
fn place(tracker: &mut Tracker, stamp: Stamp, pose: Pose2, objects: &[Object3D]) {
    let placed = opennav::perception::boxes::objects_in_odom(pose, objects.to_vec());
    tracker.update(stamp, &placed, |_| true);
}

fn step_view(stamp: Stamp, pose: Option<Pose2>, tracker: &Tracker) -> opennav::live::StepView {
    opennav::live::StepView {
        stamp,
        // a recording has the pose only
        odometry: pose.map(|pose| opennav::msg::Odometry {
            pose,
            ..Default::default()
        }),
        state: opennav::msg::SupervisorState::Idle,
        cmd: Default::default(),
        goal: None,
        phase: Some("replay".into()),
        goal_track: None,
        approach: None,
        tracks: opennav::live::TrackView::confirmed(tracker),
        plan_odom: Vec::new(),
        camera: None,
        said: Vec::new(),
        inputs: Vec::new(),
        actuator: None,
    }
}
