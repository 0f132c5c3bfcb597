//! The live view during a simulated trip, seen by a WebSocket client
//! written here from the Foxglove WebSocket protocol (v1): it connects
//! with the `foxglove.sdk.v1` subprotocol, reads the advertised
//! channels, subscribes to each, and decodes what comes — every topic
//! arrives, in its Foxglove schema, with wall-clock times.

mod common;

use std::collections::BTreeMap;
use std::net::SocketAddr;
use std::time::Duration;

use foxglove::messages as fg;
use foxglove::Decode;
use futures_util::{SinkExt, StreamExt};
use opennav::config::Settings;
use opennav::daemon::{Outcome, RunOptions};
use opennav::msg::UserInput;
use opennav::sim::world::SimWorld;
use serde_json::{json, Value};
use tokio_tungstenite::tungstenite::client::IntoClientRequest;
use tokio_tungstenite::tungstenite::Message;

/// What the client got: per topic, its advertised schema name and the
/// messages' log times and payloads.
#[derive(Default, Debug)]
struct Received {
    schema: BTreeMap<String, String>,
    messages: BTreeMap<String, Vec<(u64, Vec<u8>)>>,
}

/// Connects to `address`, subscribes to every advertised channel and
/// collects until the server closes the connection.
async fn viewer(address: SocketAddr) -> Received {
    let mut req = format!("ws://{address}")
        .into_client_request()
        .expect("request");
    req.headers_mut().insert(
        "Sec-WebSocket-Protocol",
        "foxglove.sdk.v1".parse().expect("header"),
    );
    let (mut ws, resp) = tokio_tungstenite::connect_async(req)
        .await
        .expect("the live view accepts a connection");
    assert_eq!(
        resp.headers()
            .get("sec-websocket-protocol")
            .and_then(|v| v.to_str().ok()),
        Some("foxglove.sdk.v1")
    );
    let mut got = Received::default();
    let mut topic_of_sub: BTreeMap<u32, String> = BTreeMap::new();
    while let Some(msg) = ws.next().await {
        let Ok(msg) = msg else { break };
        match msg {
            Message::Text(t) => {
                let v: Value = serde_json::from_str(&t).expect("JSON from the server");
                if v["op"] == "advertise" {
                    let mut subs = Vec::new();
                    for c in v["channels"].as_array().expect("channels") {
                        let id = c["id"].as_u64().expect("channel id");
                        let topic = c["topic"].as_str().expect("topic").to_string();
                        got.schema.insert(
                            topic.clone(),
                            c["schemaName"].as_str().unwrap_or("").to_string(),
                        );
                        let sub = topic_of_sub.len() as u32 + 1;
                        topic_of_sub.insert(sub, topic);
                        subs.push(json!({"id": sub, "channelId": id}));
                    }
                    ws.send(Message::text(
                        json!({"op": "subscribe", "subscriptions": subs}).to_string(),
                    ))
                    .await
                    .expect("subscribe");
                }
            }
            // opcode 1: message data — u32 subscription, u64 log time
            Message::Binary(b) if b.first() == Some(&1) && b.len() >= 13 => {
                let sub = u32::from_le_bytes(b[1..5].try_into().expect("4 bytes"));
                let t = u64::from_le_bytes(b[5..13].try_into().expect("8 bytes"));
                if let Some(topic) = topic_of_sub.get(&sub) {
                    got.messages
                        .entry(topic.clone())
                        .or_default()
                        .push((t, b[13..].to_vec()));
                }
            }
            Message::Close(_) => break,
            _ => {}
        }
    }
    got
}

#[tokio::test(start_paused = true)]
async fn a_viewer_receives_every_topic_of_a_trip_in_foxglove_schemas() {
    let settings = Settings::load(None).expect("defaults");
    let world = SimWorld::living_room(settings.drive_params());
    let (started_tx, started_rx) = std::sync::mpsc::channel::<SocketAddr>();
    // the viewer on its own thread and (real-time) runtime
    let viewer = std::thread::spawn(move || {
        let address = started_rx
            .recv_timeout(Duration::from_secs(60))
            .expect("the live view starts");
        tokio::runtime::Runtime::new()
            .expect("runtime")
            .block_on(viewer(address))
    });
    let opts = RunOptions {
        exit_on_arrival: true,
        max_duration: Some(Duration::from_secs(120)),
        live: Some("127.0.0.1:0".parse().expect("address")),
        live_started: Some(started_tx),
        // a trip on the virtual clock is over in seconds: start once the
        // viewer is there
        live_wait: Some(Duration::from_secs(60)),
        ..Default::default()
    };
    let words = vec![(Duration::ZERO, UserInput::Goto("chair".into()))];
    let (r, _) = common::sim_run(&settings, world, words, opts, |_, _| {}).await;
    assert_eq!(r.outcome, Outcome::Arrived, "{r:?}");
    let live = r.live.clone().expect("a live report");
    assert!(live.shown > 100, "{live:?}");
    assert_eq!(live.dropped, 0, "{live:?}");
    let got = viewer.join().expect("the viewer");

    let expect_schema = [
        ("/laser/left", "foxglove.LaserScan"),
        ("/laser/right", "foxglove.LaserScan"),
        ("/camera/color", "foxglove.RawImage"),
        ("/camera/depth", "foxglove.RawImage"),
        ("/camera/detections", "foxglove.ImageAnnotations"),
        ("/camera/obstacles", "foxglove.PointCloud"),
        ("/objects", "foxglove.SceneUpdate"),
        ("/tracks", "foxglove.SceneUpdate"),
        ("/plan", "foxglove.PosesInFrame"),
        ("/tf", "foxglove.FrameTransforms"),
        ("/said", "foxglove.Log"),
        ("/input", "foxglove.Log"),
        ("/supervisor", "opennav.Supervisor"),
    ];
    assert_eq!(expect_schema.len(), opennav::live::TOPICS.len());
    for (topic, schema) in expect_schema {
        assert_eq!(
            got.schema.get(topic).map(String::as_str),
            Some(schema),
            "{topic}: {:?}",
            got.schema
        );
        let n = got.messages.get(topic).map_or(0, Vec::len);
        assert!(n > 0, "nothing on {topic}: {:?}", got.messages.keys());
    }
    // wall-clock times (after 2024), not the run's monotonic stamps
    let first = got.messages["/tf"][0].0;
    assert!(first > 1_704_067_200_000_000_000, "log time {first}");

    // the payloads decode as their schemas say
    let m = &got.messages;
    let scan = fg::LaserScan::decode(&m["/laser/left"][0].1[..]).expect("LaserScan");
    assert_eq!(scan.frame_id, "laser_left");
    assert!(scan.ranges.len() > 600, "{} steps", scan.ranges.len());
    assert!(scan.ranges.iter().any(|r| r.is_finite() && *r > 0.1));
    let color = fg::RawImage::decode(&m["/camera/color"][0].1[..]).expect("RawImage");
    assert_eq!(color.encoding, "rgb8");
    assert_eq!(color.data.len(), (color.width * color.height * 3) as usize);
    let depth = fg::RawImage::decode(&m["/camera/depth"][0].1[..]).expect("RawImage");
    assert_eq!(depth.encoding, "32FC1");
    assert_eq!(depth.data.len(), (depth.width * depth.height * 4) as usize);
    // some depth pixel is a plausible distance in metres
    assert!(depth
        .data
        .chunks_exact(4)
        .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
        .any(|d| (0.3..10.0).contains(&d)));
    let boxes = m["/camera/detections"]
        .iter()
        .map(|(_, b)| fg::ImageAnnotations::decode(&b[..]).expect("ImageAnnotations"))
        .find(|a| !a.points.is_empty())
        .expect("a view with a detection");
    assert_eq!(boxes.points[0].points.len(), 4);
    assert_eq!(boxes.points.len(), boxes.texts.len());
    // the chair's track is drawn, the goal's with the approach arrow
    let tracks: Vec<fg::SceneUpdate> = m["/tracks"]
        .iter()
        .map(|(_, b)| fg::SceneUpdate::decode(&b[..]).expect("SceneUpdate"))
        .collect();
    assert!(tracks.iter().any(|u| u
        .entities
        .iter()
        .any(|e| e.id == "approach" && e.frame_id == "odom")));
    assert!(tracks.iter().any(|u| u
        .entities
        .iter()
        .any(|e| e.texts.iter().any(|t| t.text == "chair"))));
    let plans: Vec<fg::PosesInFrame> = m["/plan"]
        .iter()
        .map(|(_, b)| fg::PosesInFrame::decode(&b[..]).expect("PosesInFrame"))
        .collect();
    assert!(plans.iter().any(|p| p.poses.len() >= 10), "no MPC path");
    // odom→base_link moves, and the sensors' mounting is there
    let tfs: Vec<fg::FrameTransform> = m["/tf"]
        .iter()
        .flat_map(|(_, b)| {
            fg::FrameTransforms::decode(&b[..])
                .expect("FrameTransforms")
                .transforms
        })
        .collect();
    for child in ["base_link", "laser_left", "laser_right", "camera_optical"] {
        assert!(
            tfs.iter().any(|t| t.child_frame_id == child),
            "no transform to {child}"
        );
    }
    let xs: Vec<f64> = tfs
        .iter()
        .filter(|t| t.child_frame_id == "base_link")
        .filter_map(|t| t.translation.as_ref().map(|v| v.x))
        .collect();
    let travelled =
        xs.iter().cloned().fold(f64::MIN, f64::max) - xs.iter().cloned().fold(f64::MAX, f64::min);
    assert!(travelled > 0.5, "base_link moved {travelled} m in x");
    // the sentences and the supervisor's state
    let said: Vec<String> = m["/said"]
        .iter()
        .map(|(_, b)| fg::Log::decode(&b[..]).expect("Log").message)
        .collect();
    assert!(
        said.iter().any(|s| s == "Arrived at the chair."),
        "{said:?}"
    );
    // the person's word, as the daemon took it
    let inputs: Vec<String> = m["/input"]
        .iter()
        .map(|(_, b)| fg::Log::decode(&b[..]).expect("Log").message)
        .collect();
    assert_eq!(inputs, vec![r#"Goto("chair")"#.to_string()], "{inputs:?}");
    let states: Vec<Value> = m["/supervisor"]
        .iter()
        .map(|(_, b)| serde_json::from_slice(b).expect("JSON"))
        .collect();
    assert!(states
        .iter()
        .any(|s| s["state"] == "navigating" && s["goal"] == "chair"));
    assert!(states
        .iter()
        .any(|s| s["v_mps"].as_f64().is_some_and(|v| v > 0.1)));
    // and what the motor interface sent: forward on the joystick
    assert!(
        states
            .iter()
            .any(|s| s["actuator"].is_string()
                && s["joystick_forward"].as_i64().is_some_and(|f| f > 0)),
        "{:?}",
        states.last()
    );
}

#[test]
fn an_address_in_use_is_an_error_naming_it() {
    let taken = std::net::TcpListener::bind("127.0.0.1:0").expect("a port");
    let address = taken.local_addr().expect("address");
    let mounting = opennav::live::Mounting {
        laser_left: nalgebra::Isometry3::identity(),
        laser_right: nalgebra::Isometry3::identity(),
        camera: nalgebra::Isometry3::identity(),
    };
    let e = match opennav::live::Live::start(address, mounting, Duration::ZERO, None, None) {
        Ok(_) => panic!("started on a port in use"),
        Err(e) => e,
    };
    assert!(e.contains(&address.to_string()), "{e}");
}

/// Every topic the repository's Foxglove layout shows is one the live
/// view streams (a renamed topic would leave a panel empty).
#[test]
fn the_foxglove_layout_shows_only_topics_that_exist() {
    let layout = common::read_json(&common::repo().join("foxglove/opennav-layout.json"));
    fn topics_in(v: &Value, out: &mut Vec<String>) {
        match v {
            Value::String(s) if s.starts_with('/') => {
                out.push(s.split('.').next().unwrap_or(s).to_string())
            }
            Value::Array(a) => a.iter().for_each(|x| topics_in(x, out)),
            Value::Object(o) => {
                for (k, x) in o {
                    if k.starts_with('/') {
                        out.push(k.clone());
                    }
                    topics_in(x, out);
                }
            }
            _ => {}
        }
    }
    let mut shown = Vec::new();
    topics_in(&layout["configById"], &mut shown);
    assert!(shown.len() >= 8, "{shown:?}");
    for t in &shown {
        assert!(
            opennav::live::TOPICS.contains(&t.as_str()),
            "the layout shows {t}, which the live view does not stream"
        );
    }
    // the camera with its detections, the 3D scene and the supervisor
    for panel in ["Image!camera", "3D!scene", "RawMessages!supervisor"] {
        assert!(layout["configById"].get(panel).is_some(), "no {panel}");
    }
}
