//! Voice, measured: a test set of spoken commands made here — espeak-ng
//! voices, speeds and pitches, with sox noise at 20 and 10 dB SNR — plus
//! the real recording of the shared data, through the same `hear` the
//! daemon uses. Scored for right targets (acted on, the right word), wrong
//! targets (acted on, another word), asked back, stop recall, and
//! sentences outside the grammar sent anywhere: first with the model as
//! installed, then with each voice enrolled (`opennav voice enroll` on
//! the 30 sentences, read once by that voice). Needs the `voice` feature,
//! espeak-ng, sox, and for the enrollment sphinxtrain, sphinxbase-utils and
//! pocketsphinx.
//!
//!   cargo bench --features voice --bench voice_commands
//!
//! `OPENNAV_BENCH_ENROLL=no|yes|both` (both), `OPENNAV_BENCH_VOICES=en,…`
//! (all three), `OPENNAV_BENCH_PHONE_LIMIT=X` (`[voice]
//! max_phone_excess_per_frame`; 1000 turns the check off),
//! `OPENNAV_BENCH_SET=tuning` (the set thresholds are chosen
//! on, not the measured one), `OPENNAV_BENCH_ONLY=stops` (only the stops),
//! `OPENNAV_BENCH_NOISE_DRAW=K` (another draw of the noise than the
//! measured set's), `OPENNAV_BENCH_DIR=D` (work in D, keeping each
//! enrolled model there for the next run). Each utterance's evidence is a line on stderr starting
//! with EVIDENCE.

use std::path::{Path, PathBuf};
use std::process::Command;

use opennav::config::Settings;
use opennav::msg::UserInput;
use opennav::voice::enroll;
use opennav::voice::grammar::read_dictionary;
use opennav::voice::intent::Decision;
use opennav::voice::listen::{hear, recogniser, with_noise_floor};
use opennav::voice::wav::read_audio;

/// What is spoken: targets in phrases, stops, sentences outside the
/// grammar, at speeds and pitches.
struct Set {
    targets: [&'static str; 6],
    phrases: [&'static str; 4],
    stops: [&'static str; 3],
    outside: [&'static str; 4],
    speeds: [u32; 2],
    pitches: [u32; 2],
}

/// The measured set.
const TEST: Set = Set {
    targets: ["chair", "door", "toilet", "table", "bed", "sofa"],
    phrases: ["{}", "go to the {}", "take me to the {}", "find the {}"],
    stops: ["stop", "stop please", "halt"],
    outside: [
        "the quick brown fox jumps over the lazy dog",
        "what time is it",
        "I would like a cup of tea",
        "good morning",
    ],
    speeds: [130, 175],
    pitches: [35, 65],
};

/// The set thresholds are chosen on (`OPENNAV_BENCH_SET=tuning`): other
/// words, phrasings, speeds, pitches and sentences than [`TEST`]'s.
const TUNING: Set = Set {
    targets: ["desk", "sink", "window", "lamp", "fridge", "plant"],
    phrases: [
        "drive to the {}",
        "{} please",
        "go to a {}",
        "take me to a {}",
    ],
    stops: ["stop now", "halt please", "stop stop"],
    outside: [
        "where did i leave my glasses",
        "it is very cold in here today",
        "hello how are you",
        "can you call my daughter",
    ],
    speeds: [110, 200],
    pitches: [20, 80],
};

const VOICES: [&str; 3] = ["en", "en-us", "en-gb-scotland"];
/// None: clean; Some(dB): white noise at that signal-to-noise ratio.
const NOISE: [Option<u32>; 3] = [None, Some(20), Some(10)];

fn run(cmd: &mut Command) {
    let ok = cmd.status().map(|s| s.success()).unwrap_or(false);
    assert!(ok, "{cmd:?} failed (espeak-ng and sox are needed)");
}

/// `text` as 16 kHz mono, with noise at `snr_db` below the speech level.
fn make(
    dir: &Path,
    n: usize,
    text: &str,
    voice: &str,
    speed: u32,
    pitch: u32,
    snr_db: Option<u32>,
) -> PathBuf {
    let raw = dir.join(format!("{n}.22k.wav"));
    let clean = dir.join(format!("{n}.clean.wav"));
    run(Command::new("espeak-ng")
        .args([
            "-v",
            voice,
            "-s",
            &speed.to_string(),
            "-p",
            &pitch.to_string(),
            "-w",
        ])
        .arg(&raw)
        .arg(text));
    run(Command::new("sox")
        .arg(&raw)
        .args(["-r", "16000", "-c", "1", "-b", "16", "-e", "signed-integer"])
        .arg(&clean)
        .args(["pad", "0.3", "0.5"]));
    let Some(snr) = snr_db else { return clean };
    // white noise scaled so that the speech's RMS is `snr` dB above it
    let rms = |p: &Path| -> f64 {
        let s = read_audio(p).expect("audio");
        (s.iter().map(|&v| (v as f64).powi(2)).sum::<f64>() / s.len().max(1) as f64).sqrt()
    };
    let speech = rms(&clean);
    let noise_amp = speech / 10f64.powf(snr as f64 / 20.0) / 32768.0 * 3f64.sqrt();
    let noisy = dir.join(format!("{n}.noisy.wav"));
    if let Some(draw) = noise_draw() {
        // another draw of the same white noise (uniform, as sox's), mixed
        // as `sox -m` mixes (each input halved)
        let samples = read_audio(&clean).expect("audio");
        let amp = noise_amp * 32768.0;
        let mut rng = opennav::sim::scene::SplitMix64::new(
            draw.wrapping_mul(0x9E37_79B9_7F4A_7C15)
                .wrapping_add(n as u64),
        );
        let mixed: Vec<i16> = samples
            .iter()
            .map(|&v| {
                ((v as f64 + amp * rng.range(-1.0, 1.0)) / 2.0)
                    .round()
                    .clamp(-32768.0, 32767.0) as i16
            })
            .collect();
        std::fs::write(&noisy, opennav::voice::wav::mono_16k_wav(&mixed)).expect("writes");
        return noisy;
    }
    let noise = dir.join(format!("{n}.noise.wav"));
    let secs = read_audio(&clean).expect("audio").len() as f64 / 16000.0;
    // -R: the same noise every run (a repeatable measure)
    run(Command::new("sox")
        .args(["-R", "-n", "-r", "16000", "-c", "1", "-b", "16"])
        .arg(&noise)
        .args([
            "synth",
            &format!("{secs:.3}"),
            "whitenoise",
            "vol",
            &format!("{noise_amp:.6}"),
        ]));
    run(Command::new("sox")
        .arg("-m")
        .arg(&clean)
        .arg(&noise)
        .arg(&noisy));
    noisy
}

/// `OPENNAV_BENCH_NOISE_DRAW=K` (K ≥ 1): the noise is another repeatable
/// draw, not sox's fixed one (thresholds chosen on draws the measured set
/// does not use).
fn noise_draw() -> Option<u64> {
    let v = std::env::var("OPENNAV_BENCH_NOISE_DRAW").ok()?;
    let k: u64 = v
        .parse()
        .unwrap_or_else(|e| panic!("OPENNAV_BENCH_NOISE_DRAW={v:?}: {e}"));
    (k > 0).then_some(k)
}

/// `OPENNAV_BENCH_ONLY=stops`: only the stops are spoken.
fn only_stops() -> bool {
    match std::env::var("OPENNAV_BENCH_ONLY").as_deref() {
        Ok("stops") => true,
        Err(_) => false,
        Ok(other) => panic!("OPENNAV_BENCH_ONLY={other:?}: stops or unset"),
    }
}

/// One utterance's evidence on stderr (tab-separated, after "EVIDENCE"),
/// to choose thresholds on the tuning set.
fn evidence(
    kind: &str,
    said: &str,
    h: &opennav::voice::listen::Heard,
    (voice, speed, pitch, noise, enrolled): (&str, u32, u32, Option<u32>, bool),
) {
    let num = |v: Option<f64>| v.map_or("-".to_string(), |v| format!("{v:.3}"));
    eprintln!(
        "EVIDENCE\t{kind}\t{said}\t{voice}\t{speed}\t{pitch}\t{noise:?}\t{enrolled}\t{:?}\t{:?}\t{:.3}\t{}\t{}\t{:.3}\t{:?}\t{}\t{}",
        h.heard.as_deref().unwrap_or(""),
        h.decision,
        h.confidence,
        num(h.margin_per_frame),
        num(h.phone_excess_per_frame),
        h.english_agreement,
        h.stop_rule,
        num(h.stop_margin_per_frame),
        h.no_rival
    );
}

#[derive(Default)]
struct Score {
    go: usize,
    right: usize,
    wrong: usize,
    asked_right: usize,
    asked_wrong: usize,
    stops: usize,
    stops_heard: usize,
    /// Stops that bring a chair driving itself to rest: heard as a stop,
    /// or as any word (which stops it while it drives, `UserInput::Heard`).
    stops_at_rest_moving: usize,
    outside: usize,
    outside_sent: usize,
    outside_asked: usize,
}

/// The voice's enrollment as a person's would be: the sentences of
/// `opennav voice sentences` read once (the voice's middle speed and pitch,
/// no noise), the model adapted to them (`opennav voice enroll`).
fn enrolled_model(dir: &Path, voice: &str, hmm: &Path, dict_path: &Path) -> PathBuf {
    let out = dir.join(format!("model-{voice}"));
    if std::env::var_os("OPENNAV_BENCH_DIR").is_some() && out.join("mdef").exists() {
        println!("  {voice}: the enrolled model of an earlier run in OPENNAV_BENCH_DIR");
        return out;
    }
    let dict = read_dictionary(dict_path).expect("dictionary");
    let recs: Vec<enroll::Recording> = enroll::SENTENCES
        .iter()
        .enumerate()
        .map(|(i, text)| {
            let f = make(dir, 100_000 + i, text, voice, 150, 50, None);
            enroll::Recording {
                name: format!("{voice} sentence {i}"),
                samples: read_audio(&f).expect("audio"),
                text: text.to_string(),
            }
        })
        .collect();
    let made = enroll::enroll(
        &enroll::Tools::debian().expect("sphinxtrain, sphinxbase-utils, pocketsphinx"),
        &enroll::Model {
            hmm,
            dict_path,
            dict: &dict,
        },
        &recs,
        &dir.join(format!("enroll-{voice}")),
        &out,
        with_noise_floor,
    )
    .expect("enrolls");
    println!(
        "  {voice}: enrolled on {:.0} s of speech, {} of {} sentences aligned, {} noisy copies",
        made.seconds,
        made.used,
        recs.len(),
        made.noisy_used
    );
    out
}

fn main() {
    let settings = Settings::load(None).expect("defaults");
    let tmp = tempfile::tempdir().expect("tmp");
    // OPENNAV_BENCH_DIR: work there and keep each voice's enrolled model
    // for the next run
    let dir = std::env::var_os("OPENNAV_BENCH_DIR").map(PathBuf::from);
    let dir = dir.as_deref().unwrap_or(tmp.path());
    let modes = std::env::var("OPENNAV_BENCH_ENROLL").unwrap_or_else(|_| "both".into());
    for enrolled in [false, true] {
        let wanted = match modes.as_str() {
            "both" => true,
            "no" => !enrolled,
            "yes" => enrolled,
            other => panic!("OPENNAV_BENCH_ENROLL={other:?}: both, no or yes"),
        };
        if wanted {
            let set = match std::env::var("OPENNAV_BENCH_SET").as_deref() {
                Ok("tuning") => &TUNING,
                Ok("test") | Err(_) => &TEST,
                Ok(other) => panic!("OPENNAV_BENCH_SET={other:?}: test or tuning"),
            };
            measure(&settings, dir, enrolled, set);
        }
    }
    real_recording(&settings);
}

fn measure(settings: &Settings, dir: &Path, enrolled: bool, set: &Set) {
    let v = &settings.voice;
    let vocabulary: Vec<String> = v.vocabulary.clone();
    println!(
        "{}",
        if enrolled {
            "each voice enrolled (opennav voice enroll on the 30 sentences):"
        } else {
            "the model as installed:"
        }
    );
    let mut score = Score::default();
    // (voice, noise) → (commands, right, wrong)
    let mut by: std::collections::BTreeMap<(String, String), (usize, usize, usize)> =
        Default::default();
    let mut n = 0usize;
    let t0 = std::time::Instant::now();
    let only = std::env::var("OPENNAV_BENCH_VOICES").ok();
    let stops_only = only_stops();
    for voice in VOICES {
        if only
            .as_ref()
            .is_some_and(|o| !o.split(',').any(|x| x == voice))
        {
            continue;
        }
        let mut vs = v.clone();
        if enrolled {
            let hmm = enrolled_model(dir, voice, Path::new(&v.hmm), Path::new(&v.dict));
            vs.hmm = hmm.display().to_string();
            vs.max_phone_excess_per_frame = opennav::voice::intent::MAX_PHONE_EXCESS_ENROLLED;
        }
        // a limit of 1000 turns the phone check off: the EVIDENCE lines
        // then say what any limit would have done (choosing it)
        if let Ok(limit) = std::env::var("OPENNAV_BENCH_PHONE_LIMIT") {
            vs.max_phone_excess_per_frame = limit
                .parse()
                .unwrap_or_else(|e| panic!("OPENNAV_BENCH_PHONE_LIMIT={limit:?}: {e}"));
        }
        let v = &vs;
        let (mut r, g) = recogniser(v, &vocabulary).expect("recogniser");
        for speed in set.speeds {
            for pitch in set.pitches {
                for noise in NOISE {
                    let targets: &[&str] = if stops_only { &[] } else { &set.targets };
                    let outside: &[&str] = if stops_only { &[] } else { &set.outside };
                    for &target in targets {
                        for phrase in set.phrases {
                            n += 1;
                            let text = phrase.replace("{}", target);
                            let f = make(dir, n, &text, voice, speed, pitch, noise);
                            let h = hear(&mut r, &g, v, &read_audio(&f).expect("audio"))
                                .expect("decodes");
                            evidence("go", target, &h, (voice, speed, pitch, noise, enrolled));
                            score.go += 1;
                            let cell = by
                                .entry((voice.to_string(), format!("{noise:?}")))
                                .or_default();
                            cell.0 += 1;
                            match h.decision {
                                Decision::Act(UserInput::Goto(l)) if l == target => {
                                    cell.1 += 1;
                                    score.right += 1
                                }
                                Decision::Act(UserInput::Goto(_)) => {
                                    cell.2 += 1;
                                    eprintln!("wrong target: {text:?} ({voice} {speed} {pitch} {noise:?}) heard {:?}", h.heard);
                                    score.wrong += 1
                                }
                                Decision::Ask(l) if l == target => score.asked_right += 1,
                                Decision::Ask(_) => score.asked_wrong += 1,
                                _ => {}
                            }
                        }
                    }
                    for &text in &set.stops {
                        n += 1;
                        let f = make(dir, n, text, voice, speed, pitch, noise);
                        let h =
                            hear(&mut r, &g, v, &read_audio(&f).expect("audio")).expect("decodes");
                        evidence("stop", text, &h, (voice, speed, pitch, noise, enrolled));
                        score.stops += 1;
                        match &h.decision {
                            Decision::Act(UserInput::Stop) => {
                                score.stops_heard += 1;
                                score.stops_at_rest_moving += 1;
                            }
                            Decision::Act(UserInput::Goto(_)) | Decision::Ask(_) => {
                                eprintln!("stop not heard as a stop: {text:?} ({voice} {speed} {pitch} {noise:?}) heard {:?}, {:?}", h.heard, h.decision);
                                score.stops_at_rest_moving += 1;
                            }
                            d => eprintln!("stop missed: {text:?} ({voice} {speed} {pitch} {noise:?}) heard {:?}, {d:?}", h.heard),
                        }
                    }
                    for &text in outside {
                        n += 1;
                        let f = make(dir, n, text, voice, speed, pitch, noise);
                        let h =
                            hear(&mut r, &g, v, &read_audio(&f).expect("audio")).expect("decodes");
                        evidence("outside", text, &h, (voice, speed, pitch, noise, enrolled));
                        score.outside += 1;
                        match h.decision {
                            Decision::Act(UserInput::Goto(_)) => score.outside_sent += 1,
                            Decision::Ask(_) => score.outside_asked += 1,
                            _ => {}
                        }
                    }
                }
            }
        }
    }
    let pct = |a: usize, b: usize| 100.0 * a as f64 / b.max(1) as f64;
    println!(
        "voice commands (confirm = {:?}, min_confidence {}), {} utterances in {:.0} s:",
        v.confirm,
        v.min_confidence,
        n,
        t0.elapsed().as_secs_f64()
    );
    println!(
        "  go ({}): right target {:.1} %, wrong target {:.1} %, asked back {:.1} % (the right word {:.1} %, another {:.1} %)",
        score.go,
        pct(score.right, score.go),
        pct(score.wrong, score.go),
        pct(score.asked_right + score.asked_wrong, score.go),
        pct(score.asked_right, score.go),
        pct(score.asked_wrong, score.go)
    );
    println!(
        "  stop ({}): heard as a stop {:.1} %; brings a chair driving itself to rest {:.1} % (any word does)",
        score.stops,
        pct(score.stops_heard, score.stops),
        pct(score.stops_at_rest_moving, score.stops)
    );
    println!(
        "  outside the grammar ({}): sent somewhere {:.1} %, asked back {:.1} %",
        score.outside,
        pct(score.outside_sent, score.outside),
        pct(score.outside_asked, score.outside)
    );
    for ((voice, noise), (n, right, wrong)) in &by {
        println!(
            "    {voice:>15} {noise:>9}: right {:5.1} %, wrong {:4.1} % of {n}",
            pct(*right, *n),
            pct(*wrong, *n)
        );
    }
}

/// The real recording: "go forward ten meters" with "forward" a target.
fn real_recording(settings: &Settings) {
    let v = &settings.voice;
    let real = std::env::var_os("OPENNAV_SHARED")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from("../shared"))
        .join("data/speech/goforward.raw");
    let real_line = match recogniser(v, &["forward".to_string()]) {
        Ok((mut rr, gg)) if real.exists() => {
            let h = hear(&mut rr, &gg, v, &read_audio(&real).expect("audio")).expect("decodes");
            format!(
                "real recording goforward.raw: heard {:?}, decision {:?}",
                h.heard, h.decision
            )
        }
        _ => format!("real recording {} not found", real.display()),
    };
    println!("  {real_line}");
}
