//! Property tests: the parsers of outside data (model metadata, calibration
//! and embeddings files, prompt text) return errors or values, never panic.

use opennav::msg::calibration::CalibrationFile;
use opennav::msg::RgbdCalibration;
use opennav::perception::detector::parse_prompts;
use opennav::perception::detector::vocab::{parse_class_names, resolve_prompt};
use opennav::perception::tokenizer::{ClipTokenizer, CONTEXT_LENGTH, END_OF_TEXT, START_OF_TEXT};
use proptest::prelude::*;

proptest! {
    #![proptest_config(ProptestConfig::with_cases(300))]

    #[test]
    fn class_names_never_panic(s in ".{0,200}") {
        let _ = parse_class_names(&s);
    }

    #[test]
    fn class_names_round_trip(names in proptest::collection::vec("[a-z ]{1,12}", 1..20)) {
        let dict = names.iter().enumerate().map(|(i, n)| format!("{i}: '{n}'")).collect::<Vec<_>>().join(", ");
        let parsed = parse_class_names(&format!("{{{dict}}}")).expect("valid dict");
        prop_assert_eq!(parsed, names);
    }

    #[test]
    fn prompts_and_resolution_never_panic(s in ".{0,100}") {
        let names = vec!["person".to_string(), "dining table".to_string()];
        for p in parse_prompts(&s) {
            prop_assert!(!p.trim().is_empty());
            let _ = resolve_prompt(&p, &names);
        }
    }

    #[test]
    fn calibration_json_never_panics(s in ".{0,300}") {
        if let Ok(f) = serde_json::from_str::<CalibrationFile>(&s) {
            let _ = RgbdCalibration::from_file(&f);
        }
    }

    #[test]
    fn calibration_values_are_validated(fx in -1e6f64..1e6, cx in -1e4f64..1e4, scale in -1.0f64..2.0, r00 in -2.0f64..2.0) {
        let text = format!(
            r#"{{"format":"opennav-calibration/1","color":{{"width":640,"height":480,"fx":{fx},"fy":500,"cx":{cx},"cy":240}},
               "depth_scale_m":{scale},"base_from_camera":{{"rotation":[[{r00},0,0],[0,1,0],[0,0,1]],"translation_m":[0,0,0]}}}}"#
        );
        let f: CalibrationFile = serde_json::from_str(&text).expect("json");
        let ok = RgbdCalibration::from_file(&f).is_ok();
        let valid = fx > 1.0 && fx < 1e5 && (0.0..=640.0).contains(&cx) && scale > 0.0 && scale < 1.0 && (r00 - 1.0).abs() <= 1e-4;
        prop_assert_eq!(ok, valid);
    }
}

#[test]
fn tokenizer_never_panics_and_always_frames() {
    let t = ClipTokenizer::standard().expect("tokenizer");
    let mut runner = proptest::test_runner::TestRunner::new(ProptestConfig::with_cases(300));
    runner
        .run(&".{0,120}", |s| {
            let row = t.tokenize_padded(&s);
            prop_assert_eq!(row[0], START_OF_TEXT);
            let end = row.iter().position(|&x| x == END_OF_TEXT);
            prop_assert!(end.is_some());
            prop_assert!(row.len() == CONTEXT_LENGTH);
            // every id is in the vocabulary
            prop_assert!(row.iter().all(|&x| (0..49408).contains(&x)));
            Ok(())
        })
        .expect("property holds");
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(500))]

    #[test]
    fn rnet_decoder_never_panics(id in any::<u32>(), ext in any::<bool>(), len in 0u8..=15, data in any::<[u8; 8]>()) {
        let f = opennav::actuation::rnet::CanFrame { id, extended: ext, len, data };
        let _ = opennav::actuation::rnet::decode(&f);
        let _ = f.to_string();
    }

    #[test]
    fn rnet_mapping_is_bounded(v in proptest::num::f64::ANY, w in proptest::num::f64::ANY) {
        let m = opennav::actuation::rnet::JoystickMapping { forward_full_mps: 0.3, reverse_full_mps: 0.15, turn_full_radps: 0.8, deadband: 2 };
        let (x, y) = m.to_joystick(v, w);
        prop_assert!((-100..=100).contains(&x) && (-100..=100).contains(&y));
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(500))]

    #[test]
    fn rebus_decoder_never_panics_and_round_trips(noise in proptest::collection::vec(any::<u8>(), 0..200), seq in 0u8..32, vx in any::<i8>(), vy in any::<i8>()) {
        use opennav::actuation::rebus::{Decoder, Packet};
        let mut d = Decoder::default();
        let _ = d.push(&noise);
        // after any noise, a packet preceded by a fresh decoder state decodes
        let p = Packet::velocity(seq, vx, vy);
        let mut d = Decoder::default();
        let got: Vec<_> = d.push(&p.encode()).into_iter().filter_map(|r| r.ok()).collect();
        prop_assert_eq!(got, vec![p]);
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(300))]

    /// Error frames of any content decode without panicking, and what is
    /// decoded encodes back to the same fields.
    #[test]
    fn can_error_frames_decode_anything(id in any::<u32>(), data in proptest::collection::vec(any::<u8>(), 0..12)) {
        use opennav::actuation::can::BusError;
        let e = BusError::decode(id, &data);
        let _ = (e.is_fault(), e.describe());
        let (id2, d2) = e.encode();
        prop_assert_eq!(BusError::decode(id2, &d2), e);
    }

    /// The takeover fed any frames from the bus at any times never panics,
    /// never sends values it was not commanded, and sends only centred
    /// frames once the command is stale.
    #[test]
    fn takeover_survives_any_bus_traffic(frames in proptest::collection::vec((any::<u32>(), any::<bool>(), 0u8..=8, any::<[u8; 8]>(), 0u64..30), 0..200), follow in any::<bool>()) {
        use opennav::actuation::rnet::{CanFrame, Takeover, TakeoverMode};
        use opennav::msg::Stamp;
        use std::time::Duration;
        let mode = if follow { TakeoverMode::FollowJsm } else { TakeoverMode::JsmError };
        let mut tk = Takeover::new(mode);
        tk.set_command(-7, 12, Stamp::ZERO);
        let mut t = 0u64;
        for (id, ext, len, data, dt) in frames {
            t += dt;
            let now = Stamp(Duration::from_millis(t));
            let f = CanFrame { id, extended: ext, len, data };
            let (out, _) = tk.on_frame(&f, now);
            let ticked = tk.tick(now);
            for o in out.iter().chain(ticked.iter()) {
                if o.len == 2 {
                    let xy = (o.data[0] as i8, o.data[1] as i8);
                    prop_assert!(xy == (0, 0) || xy == (-7, 12), "{:?}", xy);
                    if t > 100 {
                        prop_assert_eq!(xy, (0, 0));
                    }
                }
            }
        }
    }

    /// The Rebus link fed any packets never panics and only ever sends
    /// start-up, centred or commanded velocity packets.
    #[test]
    fn rebus_link_survives_any_chipset_traffic(packets in proptest::collection::vec((0u8..32, 0u8..3, proptest::collection::vec(any::<u8>(), 0..6), 0u64..40), 0..200)) {
        use opennav::actuation::rebus::{Kind, Packet};
        use opennav::actuation::rebus_link::{RebusLink, RebusSettings};
        use opennav::actuation::rnet::JoystickMapping;
        use opennav::msg::Stamp;
        use std::time::Duration;
        let mut l = RebusLink::new(RebusSettings::new(JoystickMapping { forward_full_mps: 1.0, reverse_full_mps: 0.5, turn_full_radps: 1.5, deadband: 3 }));
        l.set_command(5, -9, Stamp::ZERO);
        let mut t = 0u64;
        for (seq, kind, data, dt) in packets {
            t += dt;
            let now = Stamp(Duration::from_millis(t));
            let kind = [Kind::Ack, Kind::Nack, Kind::Data][kind as usize];
            let (reply, _) = l.on_packet(&Packet { seq, startup: false, kind, data }, now);
            if let Some(r) = reply {
                prop_assert_eq!(r.kind, Kind::Ack);
                prop_assert_eq!(r.seq, seq);
            }
            if let (Some(p), _) = l.tick(now) {
                if !p.startup {
                    let xy = (p.data[3] as i8, p.data[4] as i8);
                    prop_assert!(xy == (0, 0) || (xy == (5, -9) && t <= 100), "{:?} at {}", xy, t);
                }
            }
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]

    /// A recording of any bytes (or a valid one with a byte changed) is read
    /// or refused with an error, never a panic.
    #[test]
    fn recordings_of_any_bytes_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..400), pos in any::<proptest::sample::Index>(), flip in 1u8..=255) {
        let dir = tempfile::tempdir().expect("tmp");
        let p = dir.path().join("x.mcap");
        std::fs::write(&p, &bytes).expect("write");
        let _ = opennav::record::read_all(&p);
        // a small valid recording, one byte changed
        let q = dir.path().join("y.mcap");
        let mut r = opennav::record::Recorder::create(&q).expect("create");
        r.ticks(&opennav::msg::Stamped::new(opennav::msg::Stamp::ZERO, opennav::msg::WheelTicks { seq: 1, mcu_time_us: 2, left: 3, right: 4, left_illegal: 0, right_illegal: 0, gap: 0 })).expect("ticks");
        r.finish().expect("finish");
        let mut good = std::fs::read(&q).expect("read");
        let i = pos.index(good.len());
        good[i] ^= flip;
        std::fs::write(&q, &good).expect("write");
        let _ = opennav::record::read_all(&q);
    }
}
