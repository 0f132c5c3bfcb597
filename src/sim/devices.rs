//! The simulator's [`Devices`]: the same traits as the chair's drivers,
//! played by the simulated world. A world task steps the chair's motion
//! at 100 Hz from what its power module does (the simulated R-Net chair,
//! JSM and power module, on an in-memory CAN bus driven by the real R-Net
//! writer); the encoder board's counts, the camera IMU's yaw rate and the
//! two lasers' scans (10 Hz, ray casting) come from it as sources; the
//! camera renders the room from the chair's true pose, and the simulator's
//! ground-truth detector boxes the objects it sees, whose frames go through
//! the same perception pipeline as the chair's.

use std::sync::{Arc, Mutex};
use std::time::Duration;

use nalgebra::Isometry3;
use serde::Serialize;
use tokio::sync::watch;
use tokio_util::sync::CancellationToken;

use super::replica::SimGtDetector;
use super::rnet::{advance, run_sim_chair, SimChair, SimChairSettings};
use super::still::Still;
use super::world::{SimReport, SimWorld};
use crate::actuation::can::MemoryBus;
use crate::actuation::writer::RnetActuator;
use crate::actuation::{Actuator, ActuatorError};
use crate::config::Settings;
use crate::config::SimDetectorChoice;
use crate::daemon::devices::{CameraDevice, DeviceError, Devices, WatchSource};
use crate::daemon::Source;
use crate::msg::RgbImage;
use crate::msg::{Clock, LaserScan, RgbdFrame, Stamp, Stamped, WheelTicks};
use crate::msg::{Intrinsics, RgbdCalibration};
use crate::perception::detector::{Detection, Detector, DetectorError, PromptReport};
use crate::perception::segmenter::DepthBoxSegmenter;
use crate::sensors::camera::{CameraError, CameraSource};

/// The world's step, s.
const WORLD_STEP: Duration = Duration::from_millis(10);
/// The lasers scan every this many world steps (10 Hz).
const LASER_EVERY: u64 = 10;

/// What the simulator's camera rendered last, for its detector.
type LastView = Arc<Mutex<Option<Vec<i32>>>>;

/// The world's steps as they happen, for a camera that waits for the
/// next one as a real camera's read waits for its next exposure.
#[derive(Clone, Default)]
struct WorldSteps(Arc<(Mutex<u64>, std::sync::Condvar)>);

impl WorldSteps {
    /// A step was taken.
    fn stepped(&self) {
        let (count, cv) = &*self.0;
        if let Ok(mut n) = count.lock() {
            *n += 1;
        }
        cv.notify_all();
    }

    /// Blocks until the world takes its next step, or `at_most` passes
    /// (a world that has stopped stepping, whose task's end the daemon
    /// reports: its last state is what there is to see).
    fn wait_next(&self, at_most: Duration) {
        let (count, cv) = &*self.0;
        let waited = count.lock().ok().and_then(|n| {
            let seen = *n;
            cv.wait_timeout_while(n, at_most, |n| *n == seen)
                .ok()
                .map(|(_, t)| t.timed_out())
        });
        match waited {
            Some(false) => {}
            // the world task's end is reported as a device's; the camera
            // renders its last state meanwhile
            Some(true) => tracing::debug!("simulator: no world step for the camera to wait for"),
            None => tracing::warn!(
                "simulator: the world's step count is poisoned; the camera renders without waiting"
            ),
        }
    }
}

/// The simulated world while the daemon runs on it.
#[derive(Clone)]
pub struct SimHandle {
    pub world: Arc<Mutex<SimWorld>>,
    /// The chair's CAN bus (tests attach other nodes to it).
    pub bus: MemoryBus,
    /// The chair's JSM and power module.
    pub chair: Arc<Mutex<SimChair>>,
}

/// What the simulator measured of a trip.
#[derive(Debug, Clone, Serialize)]
pub struct SimSummary {
    pub world: SimReport,
    /// From the chair's footprint centre (base_link) to the nearest object
    /// of the goal's word, box to point, m.
    pub distance_to_goal_object_m: Option<f64>,
}

impl SimHandle {
    /// The trip's measurements; `label`: the goal's word.
    pub fn summary(&self, label: Option<&str>) -> Option<SimSummary> {
        let w = self.world.lock().ok()?;
        let distance = label.and_then(|l| {
            w.room
                .objects
                .iter()
                .filter(|o| o.label.eq_ignore_ascii_case(l))
                .map(|o| {
                    let dx = (o.min_m[0] - w.truth.x_m)
                        .max(w.truth.x_m - o.max_m[0])
                        .max(0.0);
                    let dy = (o.min_m[1] - w.truth.y_m)
                        .max(w.truth.y_m - o.max_m[1])
                        .max(0.0);
                    dx.hypot(dy)
                })
                .min_by(f64::total_cmp)
        });
        Some(SimSummary {
            world: w.report,
            distance_to_goal_object_m: distance,
        })
    }
}

/// Where the simulated chair's R-Net writer runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SimWriter {
    /// A task on the daemon's runtime, ticking on tokio's clock: what the
    /// virtual (paused) clock needs.
    Task,
    /// Its own thread at real-time priority with the precise timer, as on
    /// the chair (`daemon::chair`): for the wall clock's pace.
    OwnThread,
}

/// The simulator's devices on `world`, timed by `clock` (tokio's: real
/// or paused), the writer a task.
pub fn devices(
    settings: &Settings,
    world: SimWorld,
    clock: Arc<dyn Clock>,
) -> Result<(Devices, SimHandle), DeviceError> {
    devices_with(settings, world, clock, SimWriter::Task)
}

/// [`devices`] with the writer where `writer` says.
pub fn devices_with(
    settings: &Settings,
    world: SimWorld,
    clock: Arc<dyn Clock>,
    writer: SimWriter,
) -> Result<(Devices, SimHandle), DeviceError> {
    let world = Arc::new(Mutex::new(world));
    let stop = CancellationToken::new();
    let base_from_camera = settings
        .camera
        .base_from_camera
        .to_isometry("camera.base_from_camera")
        .map_err(|e| DeviceError::new("camera", e.to_string()))?;
    let lasers_at = [
        settings.lasers.left.base_from_laser(),
        settings.lasers.right.base_from_laser(),
    ];

    // the chair's R-Net bus: its JSM and power module
    let bus = MemoryBus::new();
    let start = clock.now();
    let chair = Arc::new(Mutex::new(SimChair::new(
        SimChairSettings::default(),
        start,
    )));
    let chair_task = {
        let (endpoint, chair, clock, stop) =
            (bus.endpoint(), chair.clone(), clock.clone(), stop.clone());
        async move {
            run_sim_chair(endpoint, chair, clock, stop.clone()).await;
            if stop.is_cancelled() {
                Ok(())
            } else {
                Err(DeviceError::new("sim-chair", "the simulated chair stopped"))
            }
        }
    };

    // the world: 100 Hz, driven by what the power module does
    let (ticks_tx, ticks_rx) = watch::channel::<Option<Stamped<WheelTicks>>>(None);
    let (gyro_tx, gyro_rx) = watch::channel::<Option<Stamped<f64>>>(None);
    let (left_tx, left_rx) = watch::channel::<Option<Stamped<LaserScan>>>(None);
    let (right_tx, right_rx) = watch::channel::<Option<Stamped<LaserScan>>>(None);
    let mapping = settings.joystick_mapping();
    let steps = WorldSteps::default();
    let world_task = {
        let (world, chair, clock, stop, steps) = (
            world.clone(),
            chair.clone(),
            clock.clone(),
            stop.clone(),
            steps.clone(),
        );
        async move {
            // half a step after the joystick module's frames: the motors
            // act on the latest frame, which under FollowJSM is ours right
            // after the JSM's, not on the JSM's in the instant it is sent.
            // The steps keep to the JSM's grid (from `start`), whenever
            // this task first runs: on the wall clock of a busy machine a
            // grid of its own could land each step between the JSM's
            // centred frame and ours, and the chair would crawl at a
            // fraction of its command for the whole trip
            let (origin_instant, origin_stamp) = (tokio::time::Instant::now(), clock.now());
            let first = Stamp(start.0 + WORLD_STEP / 2);
            let first = if first >= origin_stamp {
                first
            } else {
                advance(first, WORLD_STEP, origin_stamp)
            };
            let mut tick = tokio::time::interval_at(
                origin_instant + first.0.saturating_sub(origin_stamp.0),
                WORLD_STEP,
            );
            let mut k: u64 = 0;
            // the last ranges of both lasers
            let mut still_ranges: Still<[Vec<u32>; 2]> = Still::default();
            loop {
                tokio::select! {
                    biased;
                    _ = stop.cancelled() => return Ok(()),
                    _ = tick.tick() => {}
                }
                let now = clock.now();
                let motor = chair
                    .lock()
                    .map_err(|_| DeviceError::new("sim-world", "the chair model is poisoned"))?
                    .motor_output(now);
                let mut w = world
                    .lock()
                    .map_err(|_| DeviceError::new("sim-world", "the world is poisoned"))?;
                w.step(WORLD_STEP.as_secs_f64(), motor, &mapping);
                w.now = now;
                gyro_tx.send_replace(Some(Stamped::new(now, w.omega_radps)));
                ticks_tx.send_replace(Some(Stamped::new(now, w.wheel_ticks())));
                if k.is_multiple_of(LASER_EVERY) {
                    let ms = (now.0.as_millis() & 0xFF_FFFF) as u32;
                    // a chair at rest in a still room: the last ranges again
                    let ranges =
                        still_ranges.get_or(&w, |w| lasers_at.map(|at| w.laser_values(&at)));
                    let p = crate::sensors::scip::SensorParams::URG_04LX;
                    for (tx, values) in [&left_tx, &right_tx].into_iter().zip(&ranges) {
                        tx.send_replace(Some(Stamped::new(
                            now,
                            crate::msg::LaserScan::from_values(&p, p.amin, values, ms),
                        )));
                    }
                }
                drop(w);
                steps.stepped();
                k += 1;
            }
        }
    };

    // the motor interface: the real R-Net writer on the simulated bus,
    // ticking on tokio's clock (real or paused)
    // the configured takeover mode, as on the chair
    let mut rnet = settings.rnet_settings();
    rnet.precise_timer = writer == SimWriter::OwnThread;
    let endpoint = bus.endpoint();
    let actuator: crate::daemon::devices::ActuatorStart = Box::new(move |io| {
        if writer == SimWriter::OwnThread {
            let h = crate::actuation::spawn_actuator_thread(
                "rnet-writer",
                50,
                move || {
                    Ok(RnetActuator {
                        bus: endpoint,
                        settings: rnet,
                    })
                },
                io,
            )
            .map_err(|e| DeviceError::new("rnet-writer", e.to_string()))?;
            return Ok(Box::pin(crate::actuation::thread_result(h)));
        }
        let h = tokio::spawn(
            RnetActuator {
                bus: endpoint,
                settings: rnet,
            }
            .run(io),
        );
        Ok(Box::pin(async move {
            h.await.unwrap_or_else(|e| {
                Err(ActuatorError::Task(if e.is_panic() {
                    format!("panicked: {}", crate::daemon::panic_message(e.into_panic()))
                } else {
                    e.to_string()
                }))
            })
        }))
    });

    // the camera and its ground-truth detector
    let cam = super::replica::camera(2);
    let k = cam.intrinsics();
    let last: LastView = Arc::new(Mutex::new(None));
    let room = world
        .lock()
        .map_err(|_| DeviceError::new("sim-world", "the world is poisoned"))?
        .room
        .clone();
    let detector = SimDetector {
        gt: SimGtDetector::new(room, cam),
        last: last.clone(),
        width: k.width,
        height: k.height,
        prompts: Vec::new(),
        noise: settings.sim,
        rng: super::scene::SplitMix64::new(settings.sim.seed),
    };
    let camera_world = world.clone();
    // at the wall clock's pace a frame is of the world's next step, as a
    // real camera's is of its next exposure: rendered from the last step,
    // it would be 0–10 ms old when read (virtual time stands still while
    // perception runs, so there it is the last step's)
    let fresh = (writer == SimWriter::OwnThread).then_some(steps);
    let camera = CameraDevice {
        open: Box::new(move || {
            Ok(Box::new(SimCamera {
                world: camera_world.clone(),
                calibration: RgbdCalibration::registered(k, base_from_camera).with_floor_z(0.0),
                k,
                base_from_camera,
                last: last.clone(),
                fresh: fresh.clone(),
                still: Still::default(),
            }) as Box<dyn CameraSource>)
        }),
        detector: Box::new(detector),
        segmenter: Box::new(DepthBoxSegmenter::new(settings.depth_segmenter_settings())),
        restamp: false,
        period: Duration::from_millis(500),
        latency: Duration::from_millis(100),
    };
    let camera = match settings.sim.detector {
        SimDetectorChoice::Truth => camera,
        SimDetectorChoice::Model => {
            let choice = crate::setup::PerceptionChoice::default();
            CameraDevice {
                detector: crate::setup::open_configured_detector(settings, &choice)
                    .map_err(|e| DeviceError::new("detector", e.to_string()))?,
                segmenter: crate::setup::open_configured_segmenter(settings, &choice)
                    .map_err(|e| DeviceError::new("segmenter", e.to_string()))?,
                period: Duration::from_millis(33),
                latency: Duration::ZERO,
                ..camera
            }
        }
    };

    let devices = Devices {
        lasers: [
            (
                Box::new(WatchSource::new("laser-left", left_rx)) as Box<dyn Source<LaserScan>>,
                lasers_at[0],
            ),
            (
                Box::new(WatchSource::new("laser-right", right_rx)),
                lasers_at[1],
            ),
        ],
        wheels: Box::new(WatchSource::new("encoders", ticks_rx)),
        gyro: Some(Box::new(WatchSource::new("gyro", gyro_rx))),
        camera: Some(camera),
        actuator,
        background: vec![
            ("sim-world".into(), Box::pin(world_task)),
            ("sim-chair".into(), Box::pin(chair_task)),
        ],
        stop,
        close: Vec::new(),
    };
    Ok((devices, SimHandle { world, bus, chair }))
}

/// The simulator's RGB-D camera: the room rendered from the chair's true
/// pose, depth registered to colour.
struct SimCamera {
    world: Arc<Mutex<SimWorld>>,
    calibration: RgbdCalibration,
    k: Intrinsics,
    base_from_camera: Isometry3<f64>,
    last: LastView,
    /// Wait for the world's next step before rendering.
    fresh: Option<WorldSteps>,
    /// The last rendering.
    still: Still<super::room::Rendered>,
}

impl CameraSource for SimCamera {
    fn calibration(&self) -> &RgbdCalibration {
        &self.calibration
    }

    fn next_frame(&mut self) -> Result<Option<Stamped<RgbdFrame>>, CameraError> {
        if let Some(steps) = &self.fresh {
            steps.wait_next(3 * WORLD_STEP);
        }
        let (r, stamp): (_, Stamp) = {
            let w = self
                .world
                .lock()
                .map_err(|_| CameraError::Device("the simulated world is poisoned".into()))?;
            // a chair at rest in a still room sees what it saw: the last
            // rendering again (about a fifth of a benchmark's frames)
            let (k, base_from_camera) = (&self.k, &self.base_from_camera);
            let rendered = self
                .still
                .try_get_or(&w, |w| w.render(k, base_from_camera))?;
            (rendered, w.now)
        };
        if let Ok(mut l) = self.last.lock() {
            *l = Some(r.instance);
        }
        Ok(Some(Stamped::new(
            stamp,
            RgbdFrame {
                color: r.color,
                depth: r.depth,
                color_stamp: stamp,
                depth_stamp: stamp,
            },
        )))
    }
}

/// The simulator's detector: boxes of the prompted objects' visible pixels
/// in the camera's last rendering (ground truth, from the room, not from
/// the image).
struct SimDetector {
    gt: SimGtDetector,
    last: LastView,
    width: usize,
    height: usize,
    prompts: Vec<String>,
    noise: crate::config::SimSection,
    rng: super::scene::SplitMix64,
}

impl SimDetector {
    /// A real detector's faults on the ground truth's boxes: misses, box
    /// noise, a false box now and then.
    fn degrade(&mut self, dets: &mut Vec<Detection>) {
        let n = self.noise;
        let rng = &mut self.rng;
        if n.detector_miss_rate > 0.0 {
            dets.retain(|_| !rng.chance(n.detector_miss_rate));
        }
        let (w, h) = (self.width as f32, self.height as f32);
        if n.detector_box_noise_px > 0.0 {
            for d in dets.iter_mut() {
                for (i, e) in d.box_xyxy.iter_mut().enumerate() {
                    let jitter =
                        rng.range(-n.detector_box_noise_px, n.detector_box_noise_px) as f32;
                    let max = if i % 2 == 0 { w } else { h };
                    *e = (*e + jitter).clamp(0.0, max);
                }
                let b = &mut d.box_xyxy;
                if b[2] < b[0] + 1.0 {
                    b[2] = (b[0] + 1.0).min(w);
                }
                if b[3] < b[1] + 1.0 {
                    b[3] = (b[1] + 1.0).min(h);
                }
            }
        }
        if !self.prompts.is_empty() && rng.chance(n.detector_false_positive_rate) {
            let label = self.prompts[rng.below(self.prompts.len())].clone();
            let (bw, bh) = (rng.range(20.0, 100.0), rng.range(20.0, 100.0));
            let x = rng.range(0.0, (w as f64 - bw).max(1.0));
            let y = rng.range(0.0, (h as f64 - bh).max(1.0));
            dets.push(Detection {
                class: label.clone(),
                label,
                score: 0.5,
                box_xyxy: [x as f32, y as f32, (x + bw) as f32, (y + bh) as f32],
            });
        }
    }
}

impl Detector for SimDetector {
    fn backend(&self) -> &'static str {
        "simulator ground truth"
    }

    fn set_prompts(&mut self, prompts: &[String]) -> Result<PromptReport, DetectorError> {
        let mut report = PromptReport::default();
        for p in prompts {
            match self
                .gt
                .room
                .objects
                .iter()
                .find(|o| o.label.eq_ignore_ascii_case(p))
            {
                Some(o) => report.matched.push((p.clone(), o.label.clone())),
                None => report.unmatched.push(p.clone()),
            }
        }
        self.prompts = prompts.to_vec();
        Ok(report)
    }

    fn detect(&mut self, image: &RgbImage) -> Result<Vec<Detection>, DetectorError> {
        let instance = self
            .last
            .lock()
            .map_err(|_| DetectorError::Prompt("simulator: the last view is poisoned".into()))?
            .take()
            .ok_or_else(|| {
                DetectorError::Prompt("simulator: no view rendered for this image".into())
            })?;
        if instance.len() != image.width() * image.height() || image.width() != self.width {
            return Err(DetectorError::Prompt(
                "simulator: the image is not the camera's last view".into(),
            ));
        }
        let mut dets = self.gt.detect_instances(&instance, self.width);
        dets.retain(|d| {
            self.prompts
                .iter()
                .any(|p| p.eq_ignore_ascii_case(&d.class))
        });
        for d in &mut dets {
            if let Some(p) = self
                .prompts
                .iter()
                .find(|p| p.eq_ignore_ascii_case(&d.class))
            {
                d.label = p.clone();
            }
        }
        self.degrade(&mut dets);
        Ok(dets)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The camera's wait for a fresh frame ends at the world's next step,
    /// not before it (a step taken before the wait does not count), and
    /// a world that stopped stepping does not hold it past its bound.
    #[test]
    fn a_fresh_frame_waits_for_the_worlds_next_step() {
        let steps = WorldSteps::default();
        steps.stepped();
        let done = Arc::new(std::sync::atomic::AtomicBool::new(false));
        let waiter = {
            let (steps, done) = (steps.clone(), done.clone());
            std::thread::spawn(move || {
                steps.wait_next(Duration::from_secs(60));
                done.store(true, std::sync::atomic::Ordering::SeqCst);
            })
        };
        std::thread::sleep(Duration::from_millis(50));
        assert!(
            !done.load(std::sync::atomic::Ordering::SeqCst),
            "returned before the next step"
        );
        steps.stepped();
        waiter.join().expect("the waiter");
        assert!(done.load(std::sync::atomic::Ordering::SeqCst));
        // no step: back after the bound, with the last state to render
        steps.wait_next(Duration::from_millis(1));
    }

    fn detector(noise: crate::config::SimSection) -> SimDetector {
        SimDetector {
            gt: SimGtDetector::new(
                super::super::room::Room::living_room(),
                super::super::replica::camera(2),
            ),
            last: Arc::new(Mutex::new(None)),
            width: 320,
            height: 180,
            prompts: vec!["chair".into()],
            noise,
            rng: super::super::scene::SplitMix64::new(noise.seed),
        }
    }

    fn boxes(n: usize) -> Vec<Detection> {
        (0..n)
            .map(|i| Detection {
                label: "chair".into(),
                class: "chair".into(),
                score: 0.9,
                box_xyxy: [10.0 + i as f32, 20.0, 60.0 + i as f32, 90.0],
            })
            .collect()
    }

    #[test]
    fn the_detector_misses_jitters_and_invents_as_configured() {
        let none = crate::config::SimSection {
            detector_miss_rate: 0.0,
            detector_false_positive_rate: 0.0,
            detector_box_noise_px: 0.0,
            seed: 3,
            detector: crate::config::SimDetectorChoice::Truth,
        };
        // no noise: the ground truth as it is
        let mut d = detector(none);
        let mut b = boxes(5);
        d.degrade(&mut b);
        assert_eq!(b, boxes(5));
        // misses at about the rate
        let mut d = detector(crate::config::SimSection {
            detector_miss_rate: 0.3,
            ..none
        });
        let mut kept = 0;
        for _ in 0..200 {
            let mut b = boxes(10);
            d.degrade(&mut b);
            kept += b.len();
        }
        let rate = 1.0 - kept as f64 / 2000.0;
        assert!((rate - 0.3).abs() < 0.05, "{rate}");
        // box noise within its bound, boxes inside the image
        let mut d = detector(crate::config::SimSection {
            detector_box_noise_px: 4.0,
            ..none
        });
        let mut b = boxes(5);
        d.degrade(&mut b);
        for (x, y) in b.iter().zip(boxes(5)) {
            assert_ne!(x.box_xyxy, y.box_xyxy);
            for (e, f) in x.box_xyxy.iter().zip(y.box_xyxy) {
                assert!((e - f).abs() <= 4.0, "{e} vs {f}");
            }
        }
        // a false box of the prompted word in every frame at rate 1
        let mut d = detector(crate::config::SimSection {
            detector_false_positive_rate: 1.0,
            ..none
        });
        let mut b = Vec::new();
        d.degrade(&mut b);
        assert_eq!(b.len(), 1);
        assert_eq!(b[0].label, "chair");
        assert!(b[0].box_xyxy[2] <= 320.0 && b[0].box_xyxy[3] <= 180.0);
    }
}
