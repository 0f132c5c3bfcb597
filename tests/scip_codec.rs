//! The SCIP 2.0 codec on the real SENA indoor scans (resampled to the
//! URG-04LX's 682 steps over 240°, clipped to 5.6 m), and fuzzing of the
//! reply parser with arbitrary and mutated bytes.

mod common;

use opennav::msg::{NoReturn, Reading};
use opennav::sensors::scip::{
    build_reply, classify, decode_ranges, encode_value, parse_reply, ReplyFramer, SensorParams,
};
use opennav::sim::hokuyo::{load_sena_csv, resample_to_urg};
use proptest::prelude::*;

/// SENA scans: ranges in metres (NaN = invalid), 361 rays over 180°.
fn sena() -> Vec<Vec<f64>> {
    load_sena_csv(&common::asset(
        common::shared().join("data/laser/sena_2006_laser_scans.csv"),
    ))
    .expect("readable")
}

/// URG steps AMIN..=AMAX in millimetres (the emulator's resampling).
fn resample(scan: &[f64]) -> Vec<u32> {
    resample_to_urg(scan, &SensorParams::URG_04LX)
}

#[test]
fn real_scans_come_back_to_the_millimetre() {
    let scans = sena();
    assert_eq!(scans.len(), 225);
    let mut framer = ReplyFramer::default();
    let mut stream = Vec::new();
    let mut expected = Vec::new();
    for (i, s) in scans.iter().enumerate() {
        assert_eq!(s.len(), 361);
        let mm = resample(s);
        assert_eq!(mm.len(), 682);
        let data: Vec<u8> = mm.iter().flat_map(|&v| encode_value(v, 3)).collect();
        // the sensor's 24-bit clock wraps during the run
        let ts = (0xFF_FF00 + 100 * i as u32) & 0xFF_FFFF;
        stream.extend(build_reply(b"MD0044072501000", b"99", Some(ts), &data));
        expected.push((ts, mm));
    }
    // delivered in uneven chunks, as a USB CDC port does
    let mut got = Vec::new();
    let mut off = 0;
    let mut k = 0;
    while off < stream.len() {
        let len = [1usize, 17, 63, 64, 65, 511, 4096][k % 7].min(stream.len() - off);
        for block in framer.push(&stream[off..off + len]).expect("in step") {
            let r = parse_reply(&block).expect("valid reply");
            got.push((
                r.timestamp.expect("scan timestamp"),
                decode_ranges(&r.data, 3).expect("ranges"),
            ));
        }
        off += len;
        k += 1;
    }
    assert_eq!(got, expected);
    let valid = expected
        .iter()
        .flat_map(|(_, r)| r)
        .filter(|&&v| matches!(classify(v), Reading::RangeMm(_)))
        .count();
    let none = expected
        .iter()
        .flat_map(|(_, r)| r)
        .filter(|&&v| classify(v) == Reading::NoReturn(NoReturn::NoObject))
        .count();
    assert!(valid > 225 * 300, "{valid} valid ranges");
    assert!(none > 0);
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(500))]

    #[test]
    fn arbitrary_bytes_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..600)) {
        let mut f = ReplyFramer::new(512);
        if let Ok(blocks) = f.push(&bytes) {
            for b in blocks {
                if let Ok(r) = parse_reply(&b) {
                    let _ = decode_ranges(&r.data, 3);
                    let _ = opennav::sensors::scip::parse_pp(&r);
                }
            }
        }
        let _ = parse_reply(&bytes);
    }

    #[test]
    fn any_single_corruption_of_a_scan_is_caught(values in proptest::collection::vec(0u32..4096, 1..100), pos in any::<proptest::sample::Index>(), flip in 1u8..=255) {
        let data: Vec<u8> = values.iter().flat_map(|&v| encode_value(v, 3)).collect();
        let good = build_reply(b"MD0044072501000", b"99", Some(7), &data);
        let mut bad = good.clone();
        let i = pos.index(bad.len());
        bad[i] ^= flip;
        match parse_reply(&bad) {
            // a corruption that still parses must not change the values silently
            // (a changed echo is the driver's to reject: it compares echoes)
            Ok(r) if r.echo == b"MD0044072501000".to_vec() => {
                let decoded = decode_ranges(&r.data, 3);
                prop_assert!(decoded.is_err() || (decoded.as_deref() == Ok(&values[..]) && r.timestamp == Some(7)),
                    "corruption at {} gave other values without an error", i);
            }
            Ok(_) => {}
            Err(_) => {}
        }
    }
}

/// Every single-byte corruption of a few scans (every position, every flip)
/// is an error or leaves the values and timestamp intact. Includes the case
/// a data line ending in ';' once slipped through on the PP/VV/II
/// alternative checksum.
#[test]
fn every_single_byte_corruption_is_caught_exhaustively() {
    let mut semicolon_line = vec![0u32; 98];
    semicolon_line[24] = 2624;
    semicolon_line[42] = 704;
    let cases = [
        semicolon_line,
        (0..682).map(|i| (i * 37 % 4096) as u32).collect(),
        vec![4095; 21],
    ];
    for values in cases {
        let data: Vec<u8> = values.iter().flat_map(|&v| encode_value(v, 3)).collect();
        let good = build_reply(b"MD0044072501000", b"99", Some(7), &data);
        for i in 0..good.len() {
            for flip in 1..=255u8 {
                let mut bad = good.clone();
                bad[i] ^= flip;
                if let Ok(r) = parse_reply(&bad) {
                    if r.echo == b"MD0044072501000" {
                        let decoded = decode_ranges(&r.data, 3);
                        assert!(
                            decoded.is_err()
                                || (decoded.as_deref() == Ok(&values[..])
                                    && r.timestamp == Some(7)),
                            "flip {flip:#04x} at byte {i} changed the scan silently"
                        );
                    }
                }
            }
        }
    }
}
