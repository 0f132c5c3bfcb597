//! MCAP recordings: the simulated chair's streams (both lasers, the
//! encoder board, RGB-D views) and what perception made of them are
//! written, read back exactly, and the recorded views replayed through the
//! real geometry pipeline give the recorded objects again.

use std::collections::BTreeMap;
use std::sync::Arc;

use opennav::config::Settings;
use opennav::eval::replica::{ReplicaView, ViewDetector};
use opennav::msg::RgbdFrame;
use opennav::msg::{Frame, Stamp, Stamped};
use opennav::perception::pipeline::lift_detections;
use opennav::perception::segmenter::DepthBoxSegmenter;
use opennav::record::{object_record, read_all, Recorded, Recorder, TOPIC_RGBD};
use opennav::sim::replica::{camera, SimGtDetector};
use opennav::sim::world::SimWorld;

#[test]
fn a_recording_reads_back_exactly_and_replays_to_the_same_objects() {
    let settings = Settings::load(None).expect("defaults");
    let base_from_camera = settings
        .camera
        .base_from_camera
        .to_isometry("camera.base_from_camera")
        .expect("valid");
    let mapping = settings.joystick_mapping();
    let lasers = [
        settings.lasers.left.base_from_laser(),
        settings.lasers.right.base_from_laser(),
    ];
    let cam = camera(2);
    let k = cam.intrinsics();
    let mut world = SimWorld::living_room(settings.drive_params());
    let mut detector = SimGtDetector::new(world.room.clone(), cam);
    let mut segmenter = DepthBoxSegmenter::new(settings.depth_segmenter_settings());
    let geometry = settings.geometry_settings();

    let dir = tempfile::tempdir().expect("tmp");
    let path = dir.path().join("run.mcap");
    let mut rec = Recorder::create(&path).expect("create");
    let mut written_scans = Vec::new();
    let mut written_ticks = Vec::new();
    let mut written_frames = Vec::new();
    let mut written_objects = Vec::new();
    let mut written_dets = Vec::new();
    // the simulated world's floor: z = 0 in base_link
    let floor = Some(opennav::perception::segmenter::FloorInImage::new(
        &k,
        &base_from_camera,
        0.0,
    ));
    for step in 0..150u64 {
        let stamp = Stamp(std::time::Duration::from_millis(10 * step));
        // turning on the spot
        world.step(0.01, Some((-30, 0)), &mapping);
        let t = Stamped::new(stamp, world.wheel_ticks());
        rec.ticks(&t).expect("ticks");
        written_ticks.push(t);
        if step % 10 == 0 {
            for (i, l) in lasers.iter().enumerate() {
                let s = Stamped::new(stamp, world.laser_scan(l, step as u32));
                rec.scan(i == 0, &s).expect("scan");
                written_scans.push((i == 0, s));
            }
        }
        if step % 50 == 0 {
            let r = world.render(&k, &base_from_camera).expect("render");
            let view = ReplicaView {
                index: 0,
                color: r.color.clone(),
                depth: r.depth.clone(),
                world_from_camera: world.world_from_camera(&base_from_camera),
            };
            let dets = detector.detect_view(&view).expect("detections");
            let lifted = lift_detections(
                &mut segmenter,
                &r.color,
                &r.depth,
                dets.clone(),
                &k,
                &base_from_camera,
                Frame::BaseLink,
                &geometry,
                floor,
            )
            .expect("lifted");
            assert!(!lifted.objects.is_empty());
            let f = Stamped::new(
                stamp,
                RgbdFrame {
                    color: r.color,
                    depth: r.depth,
                    color_stamp: stamp,
                    depth_stamp: stamp,
                },
            );
            rec.rgbd(&f).expect("frame");
            rec.detections(stamp, &dets).expect("detections");
            rec.objects(stamp, &lifted.objects).expect("objects");
            written_frames.push(f);
            written_dets.push(dets);
            written_objects.push(lifted.objects.iter().map(object_record).collect::<Vec<_>>());
        }
    }
    rec.finish().expect("finish");

    let all = read_all(&path).expect("reads");
    let mut scans = Vec::new();
    let mut ticks = Vec::new();
    let mut frames = Vec::new();
    let mut dets = Vec::new();
    let mut objects = Vec::new();
    for r in all {
        match r {
            Recorded::Scan { left, scan } => scans.push((left, scan)),
            Recorded::Ticks(t) => ticks.push(t),
            Recorded::Rgbd(f) => frames.push(f),
            Recorded::Detections(_, d) => dets.push(d),
            Recorded::Objects(_, o) => objects.push(o),
            // what only shows in Foxglove: the boxes on the image, the 3D boxes
            Recorded::Other { topic, .. } => {
                assert!(
                    topic == "/camera/detections" || topic == "/objects",
                    "unexpected {topic}"
                )
            }
            other => panic!("unexpected {other:?}"),
        }
    }
    assert_eq!(ticks, written_ticks);
    assert_eq!(scans.len(), written_scans.len());
    for ((l0, s0), (l1, s1)) in scans.iter().zip(&written_scans) {
        assert_eq!(l0, l1);
        assert_eq!(s0, s1);
    }
    assert_eq!(frames.len(), 3);
    for (f0, f1) in frames.iter().zip(&written_frames) {
        assert_eq!(f0.stamp, f1.stamp);
        assert_eq!(f0.value.color.data(), f1.value.color.data());
        assert_eq!(f0.value.depth.data(), f1.value.depth.data());
    }
    assert_eq!(dets, written_dets);
    assert_eq!(objects, written_objects);

    // replay: the recorded views and detections through the geometry again
    for ((f, d), o) in frames.iter().zip(&dets).zip(&objects) {
        let again = lift_detections(
            &mut segmenter,
            &f.value.color,
            &f.value.depth,
            d.clone(),
            &k,
            &base_from_camera,
            Frame::BaseLink,
            &geometry,
            floor,
        )
        .expect("replayed");
        let again: Vec<_> = again.objects.iter().map(object_record).collect();
        assert_eq!(&again, o);
    }
    let _ = Arc::new(());

    // `opennav replay`: this recording has no calibration — it asks for one
    let replay = |extra: &[&std::ffi::OsStr]| {
        std::process::Command::new(env!("CARGO_BIN_EXE_opennav"))
            .arg("replay")
            .arg(&path)
            .args(extra)
            .output()
            .expect("runs")
    };
    let out = replay(&[]);
    assert_eq!(out.status.code(), Some(2), "{out:?}");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("--calibration") && err.contains("run.mcap"),
        "{err}"
    );
    // given the camera's, every view replays to the recorded objects
    let cal = dir.path().join("calibration.json");
    let file = opennav::msg::calibration::CalibrationFile::of(
        &opennav::msg::calibration::RgbdCalibration::registered(k, base_from_camera)
            .with_floor_z(0.0),
        None,
    );
    std::fs::write(&cal, serde_json::to_string(&file).expect("json")).expect("write");
    let out = replay(&["--calibration".as_ref(), cal.as_os_str()]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let lines: Vec<serde_json::Value> = String::from_utf8_lossy(&out.stdout)
        .lines()
        .map(|l| serde_json::from_str(l).expect("JSON line"))
        .collect();
    let (summary, views) = lines.split_last().expect("lines");
    assert_eq!(views.len(), 3, "{lines:?}");
    assert!(
        views.iter().all(|v| v["same_as_recorded"] == true),
        "{views:?}"
    );
    assert_eq!(summary["summary"]["views"], 3);
    assert_eq!(summary["summary"]["same_as_recorded"], 3);
}

#[test]
fn bad_recordings_are_errors_naming_the_file_and_message() {
    let dir = tempfile::tempdir().expect("tmp");
    // not MCAP at all
    let junk = dir.path().join("junk.mcap");
    std::fs::write(&junk, b"hello").expect("write");
    let e = read_all(&junk).expect_err("junk");
    assert!(e.to_string().contains("junk.mcap"), "{e}");
    // a frame whose size disagrees with its header
    let bad = dir.path().join("bad.mcap");
    {
        let f = std::io::BufWriter::new(std::fs::File::create(&bad).expect("create"));
        let mut w = mcap::Writer::new(f).expect("writer");
        let ch = w
            .add_channel(0, TOPIC_RGBD, "opennav.rgbd/1", &BTreeMap::new())
            .expect("channel");
        let mut data = b"RGBD".to_vec();
        data.extend_from_slice(&4u32.to_le_bytes());
        data.extend_from_slice(&4u32.to_le_bytes());
        data.extend_from_slice(&[0u8; 10]);
        w.write_to_known_channel(
            &mcap::records::MessageHeader {
                channel_id: ch,
                sequence: 1,
                log_time: 5,
                publish_time: 5,
            },
            &data,
        )
        .expect("message");
        w.finish().expect("finish");
    }
    let e = read_all(&bad).expect_err("bad frame");
    let msg = e.to_string();
    assert!(
        msg.contains("bad.mcap") && msg.contains("/camera/rgbd") && msg.contains("message 0"),
        "{msg}"
    );
    assert!(msg.contains("expected 124"), "{msg}");
    // the Foxglove format: a depth image with no colour image before it
    let lone = dir.path().join("lone.mcap");
    {
        use foxglove::Encode;
        let f = std::io::BufWriter::new(std::fs::File::create(&lone).expect("create"));
        let mut w = mcap::Writer::new(f).expect("writer");
        let schema = <foxglove::messages::RawImage as Encode>::get_schema().expect("schema");
        let sid = w
            .add_schema(&schema.name, &schema.encoding, &schema.data)
            .expect("schema");
        let ch = w
            .add_channel(sid, "/camera/depth", "protobuf", &BTreeMap::new())
            .expect("channel");
        for (seq, (w_px, len)) in [(2u32, 16usize)].into_iter().enumerate() {
            let im = foxglove::messages::RawImage {
                width: w_px,
                height: 2,
                encoding: "32FC1".into(),
                step: w_px * 4,
                data: vec![0u8; len].into(),
                ..Default::default()
            };
            let mut buf = Vec::new();
            im.encode(&mut buf).expect("encode");
            w.write_to_known_channel(
                &mcap::records::MessageHeader {
                    channel_id: ch,
                    sequence: seq as u32,
                    log_time: 5,
                    publish_time: 5,
                },
                &buf,
            )
            .expect("message");
        }
        w.finish().expect("finish");
    }
    let e = read_all(&lone).expect_err("depth alone").to_string();
    assert!(
        e.contains("lone.mcap") && e.contains("/camera/depth") && e.contains("without its colour"),
        "{e}"
    );
}

#[test]
fn the_reader_streams_and_a_truncated_recording_keeps_what_came_before() {
    use opennav::record::RecordReader;
    let settings = Settings::load(None).expect("defaults");
    let left = settings.lasers.left.base_from_laser();
    let world = SimWorld::living_room(settings.drive_params());
    let dir = tempfile::tempdir().expect("tmp");
    let path = dir.path().join("long.mcap");
    let mut rec = Recorder::create(&path).expect("create");
    let n = 2000u64;
    for k in 0..n {
        let stamp = Stamp(std::time::Duration::from_millis(100 * k));
        rec.scan(
            true,
            &Stamped::new(stamp, world.laser_scan(&left, k as u32)),
        )
        .expect("scan");
    }
    rec.finish().expect("finish");
    // streamed: every message, in order
    let mut count = 0u64;
    for r in RecordReader::open(&path).expect("open") {
        match r.expect("message") {
            Recorded::Scan { scan, .. } => {
                assert_eq!(
                    scan.stamp,
                    Stamp(std::time::Duration::from_millis(100 * count))
                );
                count += 1;
            }
            other => panic!("unexpected {other:?}"),
        }
    }
    assert_eq!(count, n);
    // the last third cut off (a recording the power cut short): the
    // messages before the cut come out, then one error naming the file
    let bytes = std::fs::read(&path).expect("read");
    let cut = dir.path().join("cut.mcap");
    std::fs::write(&cut, &bytes[..bytes.len() * 2 / 3]).expect("write");
    let mut good = 0u64;
    let mut errors = Vec::new();
    for r in RecordReader::open(&cut).expect("open") {
        match r {
            Ok(_) => good += 1,
            Err(e) => errors.push(e.to_string()),
        }
    }
    assert!(good > n / 3 && good < n, "{good} messages before the cut");
    assert_eq!(errors.len(), 1, "{errors:?}");
    assert!(errors[0].contains("cut.mcap"), "{errors:?}");
    // read_all reports the same error and nothing else
    assert!(read_all(&cut).is_err());
}
