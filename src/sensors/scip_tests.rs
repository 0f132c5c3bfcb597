//! The SCIP 2.0 codec's tests.

use super::*;

#[test]
fn checksums_and_values_from_the_specification() {
    assert_eq!(checksum(b"00"), b'P');
    assert_eq!(checksum(b"99"), b'b');
    assert_eq!(checksum(b"0E"), b'e');
    assert_eq!(decode_value(b"CB").unwrap(), 1234);
    assert_eq!(decode_value(b"1Dh").unwrap(), 5432);
    assert_eq!(decode_value(b"m2@0").unwrap(), 16_000_000);
    assert_eq!(encode_value(5432, 3), b"1Dh".to_vec());
    assert_eq!(encode_value(16_000_000, 4), b"m2@0".to_vec());
    assert!(matches!(
        decode_value(b"C\x7f"),
        Err(ScipError::BadChar(_, 0x7f))
    ));
}

#[test]
fn a_scip11_reply_is_recognised_by_its_one_character_status() {
    assert_eq!(scip11_status(b"QT\nE\n\n", b"QT"), Some(b'E'));
    assert_eq!(scip11_status(b"SCIP2.0\n0\n\n", b"SCIP2.0"), Some(b'0'));
    // SCIP 2.0 replies, other echoes and fragments are not
    assert_eq!(scip11_status(b"QT\n00P\n\n", b"QT"), None);
    assert_eq!(scip11_status(b"PP\nE\n\n", b"QT"), None);
    assert_eq!(scip11_status(b"QT\nE\n", b"QT"), None);
    assert_eq!(scip11_status(b"QT\nE\nX\n\n", b"QT"), None);
}

#[test]
fn commands_encode_as_the_specification() {
    let md = Command::Md(ScanRequest {
        start: 44,
        end: 725,
        cluster: 1,
        interval: 0,
        scans: 0,
    });
    assert_eq!(md.encode(None), b"MD0044072501000\n".to_vec());
    assert_eq!(
        Command::Gd {
            start: 44,
            end: 725,
            cluster: 0
        }
        .encode(Some("abc")),
        b"GD0044072500;abc\n".to_vec()
    );
    assert_eq!(Command::Scip20.encode(None), b"SCIP2.0\n".to_vec());
    assert_eq!(Command::Tm(2).encode(None), b"TM2\n".to_vec());
    // tags are cut to 16 printable characters
    assert_eq!(
        Command::Qt.encode(Some("0123456789abcdefXYZ")),
        b"QT;0123456789abcdef\n".to_vec()
    );
}

#[test]
fn scan_reply_round_trip_across_line_boundaries() {
    // 682 steps × 3 chars = 2046 chars: values straddle the 64-char lines
    let values: Vec<u32> = (0..682).map(|i| (i * 37 % 5600) as u32).collect();
    let data: Vec<u8> = values.iter().flat_map(|&v| encode_value(v, 3)).collect();
    let block = build_reply(b"MD0044072501000", b"99", Some(0xFF_FFFE), &data);
    let r = parse_reply(&block).unwrap();
    assert_eq!(r.status.code(), "99");
    assert_eq!(r.timestamp, Some(0xFF_FFFE));
    assert_eq!(decode_ranges(&r.data, 3).unwrap(), values);
    assert_eq!(r.lines.len(), 2046usize.div_ceil(64));
}

#[test]
fn a_bad_checksum_rejects_the_reply() {
    let data: Vec<u8> = (0..100u32).flat_map(|v| encode_value(v * 10, 3)).collect();
    let mut block = build_reply(b"MD0044072501000", b"99", Some(5), &data);
    // corrupt one data byte in the second data line
    let pos = block
        .iter()
        .enumerate()
        .filter(|(_, &b)| b == b'\n')
        .nth(3)
        .unwrap()
        .0
        + 3;
    block[pos] = if block[pos] == b'0' { b'1' } else { b'0' };
    match parse_reply(&block) {
        Err(ScipError::Checksum { line, .. }) => assert_eq!(line, 4),
        other => panic!("{other:?}"),
    }
}

#[test]
fn first_md_reply_has_no_timestamp() {
    let r = parse_reply(b"MD0044072501000\n00P\n\n").unwrap();
    assert!(r.status.is_ok());
    assert_eq!(r.timestamp, None);
    assert!(r.data.is_empty());
}

/// A PP reply with these values (checksums right).
fn pp_block(values: &[(&str, &str)]) -> Vec<u8> {
    build_key_value_reply(b"PP", values)
}

#[test]
fn pp_values_out_of_range_are_errors_not_overflows() {
    let base = [
        ("DMIN", "20"),
        ("DMAX", "5600"),
        ("ARES", "1024"),
        ("AMIN", "44"),
        ("AMAX", "725"),
        ("AFRT", "384"),
        ("SCAN", "600"),
    ];
    let with = |k: &str, v: &'static str| {
        let vals: Vec<(&str, &str)> = base
            .iter()
            .map(|&(bk, bv)| if bk == k { (bk, v) } else { (bk, bv) })
            .collect();
        parse_pp(&parse_reply(&pp_block(&vals)).expect("reply"))
    };
    assert!(with("AMIN", "44").is_ok());
    // ARES · 2 beyond u32: no overflow, AMAX within a turn is fine
    assert!(with("ARES", "4294967295").is_ok());
    // AMAX beyond what a 4-digit scan request addresses
    let e = with("ARES", "4294967295").and_then(|_| with("AMAX", "70000"));
    assert!(
        matches!(e, Err(ScipError::Parameter { ref key, .. }) if key == "AMAX"),
        "{e:?}"
    );
}

#[test]
fn pp_reply_parses_with_either_checksum_form() {
    let mut block = b"PP\n00P\n".to_vec();
    for (i, (k, v)) in [
        (
            "MODL",
            "URG-04LX-UG01(Simple-URG)(Hokuyo Automatic Co.,Ltd.)",
        ),
        ("DMIN", "20"),
        ("DMAX", "5600"),
        ("ARES", "1024"),
        ("AMIN", "44"),
        ("AMAX", "725"),
        ("AFRT", "384"),
        ("SCAN", "600"),
    ]
    .iter()
    .enumerate()
    {
        let kv = format!("{k}:{v}");
        // alternate: sum without and with the ';'
        let sum = if i % 2 == 0 {
            checksum(kv.as_bytes())
        } else {
            checksum(format!("{kv};").as_bytes())
        };
        block.extend_from_slice(kv.as_bytes());
        block.push(b';');
        block.push(sum);
        block.push(b'\n');
    }
    block.push(b'\n');
    let r = parse_reply(&block).unwrap();
    let p = parse_pp(&r).unwrap();
    assert_eq!(p, SensorParams::URG_04LX);
    assert!((p.step_angle_rad(44).to_degrees() + 119.53125).abs() < 1e-9);
    assert!((p.step_angle_rad(725).to_degrees() - 119.8828125).abs() < 1e-9);
    assert!((p.scan_period_s() - 0.1).abs() < 1e-12);
}

#[test]
fn range_error_codes_are_no_returns_with_reasons() {
    assert_eq!(classify(0), Reading::NoReturn(NoReturn::NoObject));
    assert_eq!(classify(2), Reading::NoReturn(NoReturn::LowIntensity));
    assert_eq!(classify(7), Reading::NoReturn(NoReturn::Other(7)));
    assert_eq!(classify(18), Reading::NoReturn(NoReturn::StrongReflector));
    assert_eq!(classify(19), Reading::NoReturn(NoReturn::NonMeasurable));
    assert_eq!(classify(20), Reading::RangeMm(20));
    assert_eq!(classify(5600), Reading::RangeMm(5600));
}

#[test]
fn status_meanings() {
    assert_eq!(
        Status(*b"0E").meaning(b"XX"),
        "undefined command (sensor in SCIP 1.1 or bad command)"
    );
    assert_eq!(Status(*b"02").meaning(b"BM"), "laser already on");
    assert_eq!(
        Status(*b"03").meaning(b"MD0044072501000"),
        "bad scan parameter (status 03)"
    );
    assert_eq!(Status(*b"55").meaning(b"MD"), "hardware fault");
}

#[test]
fn framer_splits_a_stream_in_any_chunking() {
    let a = build_reply(b"MD0044072501000", b"99", Some(1), &encode_value(1000, 3));
    let b = build_reply(b"MD0044072501000", b"99", Some(2), &encode_value(2000, 3));
    let stream: Vec<u8> = [a.clone(), b.clone()].concat();
    for chunk in [1usize, 3, 7, 64, 1000] {
        let mut f = ReplyFramer::default();
        let mut got = Vec::new();
        for c in stream.chunks(chunk) {
            got.extend(f.push(c).unwrap());
        }
        assert_eq!(got, vec![a.clone(), b.clone()]);
        assert_eq!(f.pending(), 0);
    }
    let mut f = ReplyFramer::new(100);
    assert_eq!(f.push(&[b'A'; 101]), Err(ScipError::Overflow(100)));
    assert_eq!(f.pending(), 0);
}

#[test]
fn malformed_replies_are_errors_not_panics() {
    for bad in [
        &b""[..],
        b"\n\n",
        b"MD\n\n",
        b"MD\n0\n\n",
        b"MD\n99b\n\n",
        b"PP\n00P\nxyz\n\n",
        b"no end",
    ] {
        assert!(
            parse_reply(bad).is_err(),
            "{:?}",
            String::from_utf8_lossy(bad)
        );
    }
}

/// A key-value reply is the sensor's bytes (echo, `00P`, one checksummed
/// line per pair, blank line) and reads back pair for pair.
#[test]
fn key_value_replies_read_back() {
    let block = build_key_value_reply(b"VV", &[("VEND", "Hokuyo"), ("FIRM", "3.4.03")]);
    let vend_sum = checksum(b"VEND:Hokuyo");
    let mut want = b"VV\n00P\nVEND:Hokuyo;".to_vec();
    want.push(vend_sum);
    want.extend_from_slice(b"\nFIRM:3.4.03;");
    want.push(checksum(b"FIRM:3.4.03"));
    want.extend_from_slice(b"\n\n");
    assert_eq!(block, want);
    let values = key_values(&parse_reply(&block).expect("reply")).expect("pairs");
    assert_eq!(values.get("VEND").map(String::as_str), Some("Hokuyo"));
    assert_eq!(values.get("FIRM").map(String::as_str), Some("3.4.03"));
    assert_eq!(values.len(), 2);
}
