//! The live view's messages in Foxglove schemas: a view and a control
//! step as `foxglove` messages, pure (the recorder writes the same).

use foxglove::messages as fg;
use nalgebra::{Isometry3, UnitQuaternion};
use serde::Serialize;

use super::*;
use crate::msg::Object3D;
use crate::msg::{LaserScan, MapObstacles, RgbdFrame, SupervisorState};
use crate::perception::detector::Detection;

/// The JSON schema of `/supervisor`.
pub const SUPERVISOR_SCHEMA: &str = r#"{
  "type": "object",
  "properties": {
    "state": {"type": "string"},
    "reason": {"type": ["string", "null"]},
    "v_mps": {"type": "number"},
    "omega_radps": {"type": "number"},
    "goal": {"type": ["string", "null"]},
    "phase": {"type": ["string", "null"]},
    "actuator": {"type": ["string", "null"]},
    "joystick_turn": {"type": ["integer", "null"]},
    "joystick_forward": {"type": ["integer", "null"]}
  }
}"#;

#[derive(Serialize)]
struct SupervisorMsg<'a> {
    state: &'a str,
    reason: Option<String>,
    v_mps: f64,
    omega_radps: f64,
    goal: Option<&'a str>,
    phase: Option<&'a str>,
    /// The motor interface's state and its last output (turn, forward).
    actuator: Option<&'a str>,
    joystick_turn: Option<i8>,
    joystick_forward: Option<i8>,
}

/// One message of a control step, by its schema.
pub enum StepMessage {
    Tf(fg::FrameTransforms),
    Scene(fg::SceneUpdate),
    Path(fg::PosesInFrame),
    Cloud(fg::PointCloud),
    Log(fg::Log),
    /// `opennav.Supervisor`, JSON.
    Supervisor(Vec<u8>),
}

/// What a control step shows, topic by topic (the live view and the
/// recording write the same): `odom`→`base_link`, the tracks and approach,
/// the MPC's path, the camera's obstacles, each sentence, the supervisor.
pub fn step_messages(s: &StepView, ts: fg::Timestamp) -> Vec<(&'static str, StepMessage)> {
    let mut out = Vec::new();
    if let Some(p) = s.odometry.map(|o| o.pose) {
        out.push((
            TOPIC_TF,
            StepMessage::Tf(fg::FrameTransforms {
                transforms: vec![transform(FRAME_ODOM, FRAME_BASE, &p.to_isometry3(), ts)],
            }),
        ));
    }
    out.push((TOPIC_TRACKS, StepMessage::Scene(tracks_scene(s, ts))));
    out.push((
        TOPIC_PLAN,
        StepMessage::Path(fg::PosesInFrame {
            timestamp: Some(ts),
            frame_id: FRAME_ODOM.into(),
            poses: s
                .plan_odom
                .iter()
                .map(|p| pose([p[0], p[1], 0.0], UnitQuaternion::identity()))
                .collect(),
        }),
    ));
    if let Some(c) = &s.camera {
        out.push((
            TOPIC_CAMERA_OBSTACLES,
            StepMessage::Cloud(camera_cloud(c, ts)),
        ));
    }
    let log = |message: &String, name: &str| {
        StepMessage::Log(fg::Log {
            timestamp: Some(ts),
            level: fg::log::Level::Info as i32,
            message: message.clone(),
            name: name.into(),
            file: String::new(),
            line: 0,
        })
    };
    for line in &s.said {
        out.push((TOPIC_SAID, log(line, "opennav")));
    }
    for input in &s.inputs {
        out.push((TOPIC_INPUT, log(input, "person")));
    }
    let (state, reason) = state_words(&s.state);
    let msg = SupervisorMsg {
        state,
        reason,
        v_mps: s.cmd.v_mps,
        omega_radps: s.cmd.omega_radps,
        goal: s.goal.as_deref(),
        phase: s.phase.as_deref(),
        actuator: s.actuator.as_ref().map(|a| a.state.as_str()),
        joystick_turn: s.actuator.as_ref().map(|a| a.last_output.0),
        joystick_forward: s.actuator.as_ref().map(|a| a.last_output.1),
    };
    match serde_json::to_vec(&msg) {
        Ok(bytes) => out.push((TOPIC_SUPERVISOR, StepMessage::Supervisor(bytes))),
        Err(e) => tracing::warn!(error = %e, "the supervisor's state as JSON"),
    }
    out
}

/// The supervisor's state as a word, and the reason of a stop or fault.
pub fn state_words(s: &SupervisorState) -> (&'static str, Option<String>) {
    match s {
        SupervisorState::Idle => ("idle", None),
        SupervisorState::Navigating => ("navigating", None),
        SupervisorState::Holding => ("holding", None),
        SupervisorState::Stopped(r) => ("stopped", Some(format!("{r:?}"))),
        SupervisorState::Fault(r) => ("fault", Some(format!("{r:?}"))),
    }
}

pub(super) fn timestamp(ns: u64) -> fg::Timestamp {
    fg::Timestamp::new((ns / 1_000_000_000) as u32, (ns % 1_000_000_000) as u32)
}

fn pose(p: [f64; 3], q: UnitQuaternion<f64>) -> fg::Pose {
    fg::Pose {
        position: Some(fg::Vector3 {
            x: p[0],
            y: p[1],
            z: p[2],
        }),
        orientation: Some(fg::Quaternion {
            x: q.i,
            y: q.j,
            z: q.k,
            w: q.w,
        }),
    }
}

fn transform(
    parent: &str,
    child: &str,
    iso: &Isometry3<f64>,
    ts: fg::Timestamp,
) -> fg::FrameTransform {
    let t = iso.translation.vector;
    let q = iso.rotation;
    fg::FrameTransform {
        timestamp: Some(ts),
        parent_frame_id: parent.into(),
        child_frame_id: child.into(),
        translation: Some(fg::Vector3 {
            x: t.x,
            y: t.y,
            z: t.z,
        }),
        rotation: Some(fg::Quaternion {
            x: q.i,
            y: q.j,
            z: q.k,
            w: q.w,
        }),
    }
}

/// `base_link` → the lasers and the camera.
pub fn mounting_transforms(m: &Mounting, ts: fg::Timestamp) -> fg::FrameTransforms {
    fg::FrameTransforms {
        transforms: vec![
            transform(FRAME_BASE, FRAME_LASER_LEFT, &m.laser_left, ts),
            transform(FRAME_BASE, FRAME_LASER_RIGHT, &m.laser_right, ts),
            transform(FRAME_BASE, FRAME_CAMERA, &m.camera, ts),
        ],
    }
}

/// A scan in its laser's frame; a step with no return is NaN (Foxglove
/// draws nothing there).
pub fn laser_scan(s: &LaserScan, frame: &str, ts: fg::Timestamp) -> fg::LaserScan {
    let n = s.ranges_m.len();
    fg::LaserScan {
        timestamp: Some(ts),
        frame_id: frame.into(),
        pose: Some(pose([0.0; 3], UnitQuaternion::identity())),
        start_angle: s.angle_min_rad,
        end_angle: s.angle_min_rad + s.angle_increment_rad * n.saturating_sub(1) as f64,
        ranges: s
            .ranges_m
            .iter()
            .map(|r| r.map_or(f64::NAN, f64::from))
            .collect(),
        intensities: Vec::new(),
    }
}

/// Colour (`rgb8`) and depth (`32FC1`, metres: exact) in the camera's
/// optical frame.
pub fn images(f: &RgbdFrame, ts: fg::Timestamp) -> (fg::RawImage, fg::RawImage) {
    let (cw, ch) = (f.color.width() as u32, f.color.height() as u32);
    let (dw, dh) = (f.depth.width() as u32, f.depth.height() as u32);
    let depth: Vec<u8> = f
        .depth
        .data()
        .iter()
        .flat_map(|d| d.to_le_bytes())
        .collect();
    (
        fg::RawImage {
            timestamp: Some(ts),
            frame_id: FRAME_CAMERA.into(),
            width: cw,
            height: ch,
            encoding: "rgb8".into(),
            step: cw * 3,
            data: f.color.data().to_vec().into(),
        },
        fg::RawImage {
            timestamp: Some(ts),
            frame_id: FRAME_CAMERA.into(),
            width: dw,
            height: dh,
            encoding: "32FC1".into(),
            step: dw * 4,
            data: depth.into(),
        },
    )
}

fn color(r: f64, g: f64, b: f64, a: f64) -> fg::Color {
    fg::Color { r, g, b, a }
}

/// The detector's boxes (closed outlines) and their labels with scores.
pub fn image_annotations(dets: &[Detection], ts: fg::Timestamp) -> fg::ImageAnnotations {
    let outline = color(0.1, 0.9, 0.2, 1.0);
    fg::ImageAnnotations {
        points: dets
            .iter()
            .map(|d| {
                let [x1, y1, x2, y2] = d.box_xyxy.map(f64::from);
                fg::PointsAnnotation {
                    timestamp: Some(ts),
                    r#type: fg::points_annotation::Type::LineLoop as i32,
                    points: [(x1, y1), (x2, y1), (x2, y2), (x1, y2)]
                        .iter()
                        .map(|&(x, y)| fg::Point2 { x, y })
                        .collect(),
                    outline_color: Some(outline),
                    thickness: 2.0,
                    ..Default::default()
                }
            })
            .collect(),
        texts: dets
            .iter()
            .map(|d| fg::TextAnnotation {
                timestamp: Some(ts),
                position: Some(fg::Point2 {
                    x: f64::from(d.box_xyxy[0]),
                    y: f64::from(d.box_xyxy[1]),
                }),
                text: format!("{} {:.2}", d.label, d.score),
                font_size: 14.0,
                text_color: Some(color(1.0, 1.0, 1.0, 1.0)),
                background_color: Some(color(0.0, 0.0, 0.0, 0.6)),
                ..Default::default()
            })
            .collect(),
        ..Default::default()
    }
}

fn cube(
    id: String,
    frame: &str,
    ts: fg::Timestamp,
    lo: [f64; 3],
    hi: [f64; 3],
    label: &str,
    c: fg::Color,
) -> fg::SceneEntity {
    let center = [0, 1, 2].map(|i| (lo[i] + hi[i]) / 2.0);
    let size = [0, 1, 2].map(|i| (hi[i] - lo[i]).max(0.01));
    fg::SceneEntity {
        timestamp: Some(ts),
        frame_id: frame.into(),
        id,
        cubes: vec![fg::CubePrimitive {
            pose: Some(pose(center, UnitQuaternion::identity())),
            size: Some(fg::Vector3 {
                x: size[0],
                y: size[1],
                z: size[2],
            }),
            color: Some(c),
        }],
        texts: vec![fg::TextPrimitive {
            pose: Some(pose(
                [center[0], center[1], hi[2] + 0.1],
                UnitQuaternion::identity(),
            )),
            billboard: true,
            font_size: 14.0,
            scale_invariant: true,
            color: Some(color(1.0, 1.0, 1.0, 1.0)),
            text: label.into(),
        }],
        ..Default::default()
    }
}

/// The view's 3D objects (upright boxes) in their frame, replacing the
/// last view's.
pub fn objects_scene(objects: &[Object3D], ts: fg::Timestamp) -> fg::SceneUpdate {
    fg::SceneUpdate {
        deletions: vec![fg::SceneEntityDeletion {
            timestamp: Some(ts),
            r#type: fg::scene_entity_deletion::Type::All as i32,
            id: String::new(),
        }],
        entities: objects
            .iter()
            .enumerate()
            .map(|(i, o)| {
                let frame = match o.frame {
                    crate::msg::Frame::BaseLink => FRAME_BASE,
                    crate::msg::Frame::Odom => FRAME_ODOM,
                    crate::msg::Frame::CameraOptical => FRAME_CAMERA,
                };
                cube(
                    format!("object-{i}"),
                    frame,
                    ts,
                    o.aabb.min_m,
                    o.aabb.max_m,
                    &format!("{} {:.2}", o.label, o.score),
                    color(0.2, 0.6, 1.0, 0.4),
                )
            })
            .collect(),
    }
}

/// The tracks (the goal's in green) and the approach pose (an arrow), in
/// odom, replacing the last step's.
pub fn tracks_scene(s: &StepView, ts: fg::Timestamp) -> fg::SceneUpdate {
    let mut entities: Vec<fg::SceneEntity> = s
        .tracks
        .iter()
        .map(|t| {
            let lo = [0, 1, 2].map(|i| t.center_m[i] - t.size_m[i] / 2.0);
            let hi = [0, 1, 2].map(|i| t.center_m[i] + t.size_m[i] / 2.0);
            let c = if Some(t.id) == s.goal_track {
                color(0.1, 0.9, 0.2, 0.5)
            } else {
                color(0.9, 0.7, 0.2, 0.35)
            };
            cube(
                format!("track-{}", t.id),
                FRAME_ODOM,
                ts,
                lo,
                hi,
                &t.label,
                c,
            )
        })
        .collect();
    if let Some(a) = s.approach {
        entities.push(fg::SceneEntity {
            timestamp: Some(ts),
            frame_id: FRAME_ODOM.into(),
            id: "approach".into(),
            arrows: vec![fg::ArrowPrimitive {
                pose: Some(pose(
                    [a.x_m, a.y_m, 0.05],
                    UnitQuaternion::from_euler_angles(0.0, 0.0, a.yaw_rad),
                )),
                shaft_length: 0.4,
                shaft_diameter: 0.05,
                head_length: 0.15,
                head_diameter: 0.12,
                color: Some(color(0.1, 0.9, 0.2, 1.0)),
            }],
            ..Default::default()
        });
    }
    fg::SceneUpdate {
        deletions: vec![fg::SceneEntityDeletion {
            timestamp: Some(ts),
            r#type: fg::scene_entity_deletion::Type::All as i32,
            id: String::new(),
        }],
        entities,
    }
}

/// The camera's remembered obstacles (`kind` 0), drop-offs (1) and
/// drop-offs that may lie out of its view (2), in odom: x, y, z (0), kind
/// as f32.
pub fn camera_cloud(c: &MapObstacles, ts: fg::Timestamp) -> fg::PointCloud {
    let n = c.obstacles_odom.len() + c.drop_offs_odom.len() + c.drop_offs_unseen_odom.len();
    let mut data = Vec::with_capacity(n * 16);
    for (points, kind) in [
        (&c.obstacles_odom, 0.0f32),
        (&c.drop_offs_odom, 1.0),
        (&c.drop_offs_unseen_odom, 2.0),
    ] {
        for p in points {
            for v in [p[0] as f32, p[1] as f32, 0.0, kind] {
                data.extend_from_slice(&v.to_le_bytes());
            }
        }
    }
    let field = |name: &str, offset: u32| fg::PackedElementField {
        name: name.into(),
        offset,
        r#type: fg::packed_element_field::NumericType::Float32 as i32,
    };
    fg::PointCloud {
        timestamp: Some(ts),
        frame_id: FRAME_ODOM.into(),
        pose: Some(pose([0.0; 3], UnitQuaternion::identity())),
        point_stride: 16,
        fields: vec![
            field("x", 0),
            field("y", 4),
            field("z", 8),
            field("kind", 12),
        ],
        data: data.into(),
    }
}
