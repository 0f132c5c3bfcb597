use super::*;

fn sendump(streams: i32, densities: i32, senones: i32, q: &[u8]) -> Vec<u8> {
    let mut b = Vec::new();
    for s in [
        "BEGIN FILE FORMAT DESCRIPTION",
        "END FILE FORMAT DESCRIPTION",
        "cluster_count 0",
        "codebook_count 1",
        &format!("feature_count {streams}"),
    ] {
        b.extend_from_slice(&(s.len() as i32 + 1).to_le_bytes());
        b.extend_from_slice(s.as_bytes());
        b.push(0);
    }
    b.extend_from_slice(&0i32.to_le_bytes());
    b.extend_from_slice(&densities.to_le_bytes());
    b.extend_from_slice(&senones.to_le_bytes());
    b.extend_from_slice(q);
    b
}

fn floats(b: &[u8]) -> Vec<f32> {
    b.chunks_exact(4)
        .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect()
}

#[test]
fn sendump_weights_come_back_per_senone_and_stream_summing_to_one() {
    // 2 streams × 2 densities × 3 senones, laid out [stream][density][senone]
    let q = [
        0, 10, 255, /* s0 d1 */ 0, 0, 0, /* s1 d0 */ 5, 5, 0, /* s1 d1 */ 5, 0, 0,
    ];
    let out = mixture_weights_from_sendump(&sendump(2, 2, 3, &q)).expect("converts");
    let end = out
        .windows(7)
        .position(|w| w == b"endhdr\n")
        .expect("header end")
        + 7;
    assert_eq!(&out[..3], b"s3\n");
    assert_eq!(end % 4, 0, "data on a 4-byte boundary");
    let magic = i32::from_le_bytes([out[end], out[end + 1], out[end + 2], out[end + 3]]);
    assert_eq!(magic, 0x1122_3344);
    let dims: Vec<u32> = out[end + 4..end + 20]
        .chunks_exact(4)
        .map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect();
    assert_eq!(dims, vec![3, 2, 2, 12]);
    let w = floats(&out[end + 20..]);
    assert_eq!(w.len(), 12);
    // [senone][stream][density]
    for pair in w.chunks_exact(2) {
        assert!((pair[0] + pair[1] - 1.0).abs() < 1e-6, "{pair:?}");
    }
    // senone 0: stream 0 q 0 and 0, stream 1 q 5 and 5 → equal
    for w in &w[0..4] {
        assert!((w - 0.5).abs() < 1e-6, "{w}");
    }
    // senone 1, stream 0: q 10 against 0 → e^(-10·0.1024) : 1
    let ratio = w[4] / w[5];
    assert!((ratio - (-10.0 * 1024.0 * 1.0001f32.ln()).exp()).abs() < 1e-4);
    // senone 2, stream 0: q 255 is (nearly) nothing; stream 1 equal
    assert!(w[8] < 1e-10 && (w[9] - 1.0).abs() < 1e-6);
    assert!((w[10] - 0.5).abs() < 1e-6);
}

#[test]
fn a_damaged_or_clustered_sendump_is_refused_by_name() {
    let q = [0u8; 12];
    let mut short = sendump(2, 2, 3, &q);
    short.pop();
    let e = mixture_weights_from_sendump(&short).expect_err("short");
    assert!(e.contains("11 bytes of weights, 2 × 2 × 3 = 12"), "{e}");
    let e = mixture_weights_from_sendump(&[1, 0, 0]).expect_err("truncated");
    assert!(e.contains("ends inside a header length"), "{e}");
    let mut big = sendump(2, 2, 3, &q);
    big[..4].copy_from_slice(&0x1000_0000i32.to_le_bytes());
    let e = mixture_weights_from_sendump(&big).expect_err("big-endian");
    assert!(e.contains("big-endian or damaged"), "{e}");
    let clustered = sendump(2, 2, 3, &q);
    let text = String::from_utf8_lossy(&clustered).replace("cluster_count 0", "cluster_count 8");
    let e = mixture_weights_from_sendump(text.as_bytes()).expect_err("clustered");
    assert!(e.contains("cluster_count 8"), "{e}");
    let e = mixture_weights_from_sendump(&sendump(2, 0, 3, &[])).expect_err("no densities");
    assert!(e.contains("is not a model"), "{e}");
}

#[cfg(feature = "voice")]
#[test]
fn every_enrollment_sentence_is_in_the_dictionary_and_none_is_a_command() {
    let dict = Path::new("/usr/share/pocketsphinx/model/en-us/cmudict-en-us.dict");
    let Ok(d) = super::super::grammar::read_dictionary(dict) else {
        panic!(
            "{} is needed (Debian: apt-get install pocketsphinx-en-us)",
            dict.display()
        );
    };
    for s in SENTENCES {
        assert_eq!(unknown_words(s, &d), Vec::<String>::new(), "{s}");
        for command in ["stop", "halt", "cancel", "yes", "no", "go", "take", "find"] {
            assert!(
                !s.split_whitespace().any(|w| w == command),
                "{s}: {command}"
            );
        }
    }
}

#[test]
fn room_noise_is_added_at_its_ratio_low_pitched_and_the_same_every_time() {
    // a 440 Hz tone, 1 s, at about −12 dBFS
    let tone: Vec<i16> = (0..16_000)
        .map(|i| (8000.0 * (std::f64::consts::TAU * 440.0 * i as f64 / 16_000.0).sin()) as i16)
        .collect();
    let noisy = with_room_noise(&tone, 12.0, 7);
    assert_eq!(noisy.len(), tone.len());
    assert_eq!(noisy, with_room_noise(&tone, 12.0, 7), "deterministic");
    assert_ne!(noisy, with_room_noise(&tone, 12.0, 8), "the seed matters");
    let noise: Vec<f64> = noisy
        .iter()
        .zip(&tone)
        .map(|(&n, &t)| n as f64 - t as f64)
        .collect();
    let power = |v: &[f64]| v.iter().map(|x| x * x).sum::<f64>() / v.len() as f64;
    let tone_power = power(&tone.iter().map(|&v| v as f64).collect::<Vec<_>>());
    let snr_db = 10.0 * (tone_power / power(&noise)).log10();
    assert!((snr_db - 12.0).abs() < 0.1, "SNR {snr_db:.2} dB");
    // pink: neighbouring samples alike (white noise's lag-1
    // correlation is about 0; pink noise's, high)
    let lag1 = noise.windows(2).map(|w| w[0] * w[1]).sum::<f64>()
        / noise.iter().map(|x| x * x).sum::<f64>();
    assert!(lag1 > 0.5, "lag-1 correlation {lag1:.2}");
    // silence stays silence (no speech level to set the noise by)
    assert_eq!(with_room_noise(&[0; 100], 12.0, 1), vec![0; 100]);
    assert_eq!(with_room_noise(&[], 12.0, 1), Vec::<i16>::new());
}
