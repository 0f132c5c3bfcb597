//! Voice, measured: a test set of spoken commands made here — espeak-ng
//! voices, speeds and pitches, with sox noise at 20 and 10 dB SNR — plus
//! the real recording of the shared data, through the same `hear` the
//! daemon uses. Scored for right targets (acted on, the right word), wrong
//! targets (acted on, another word), asked back, stop recall, and
//! sentences outside the grammar sent anywhere. Needs the `voice` feature,
//! espeak-ng and sox.
//!
//!   cargo bench --features voice --bench voice_commands

use std::path::{Path, PathBuf};
use std::process::Command;

use opennav::config::Settings;
use opennav::msg::UserInput;
use opennav::voice::intent::Decision;
use opennav::voice::listen::{hear, recogniser};
use opennav::voice::wav::read_audio;

const TARGETS: [&str; 6] = ["chair", "door", "toilet", "table", "bed", "sofa"];
const PHRASES: [&str; 4] = ["{}", "go to the {}", "take me to the {}", "find the {}"];
const STOPS: [&str; 3] = ["stop", "stop please", "halt"];
const OUTSIDE: [&str; 4] = [
    "the quick brown fox jumps over the lazy dog",
    "what time is it",
    "I would like a cup of tea",
    "good morning",
];
const VOICES: [&str; 3] = ["en", "en-us", "en-gb-scotland"];
const SPEEDS: [u32; 2] = [130, 175];
const PITCHES: [u32; 2] = [35, 65];
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

fn main() {
    let settings = Settings::load(None).expect("defaults");
    let v = &settings.voice;
    let vocabulary: Vec<String> = v.vocabulary.clone();
    let (mut r, g) = recogniser(v, &vocabulary).expect("recogniser");
    let dir = tempfile::tempdir().expect("tmp");
    let mut score = Score::default();
    let mut n = 0usize;
    let t0 = std::time::Instant::now();
    for voice in VOICES {
        for speed in SPEEDS {
            for pitch in PITCHES {
                for noise in NOISE {
                    for target in TARGETS {
                        for phrase in PHRASES {
                            n += 1;
                            let text = phrase.replace("{}", target);
                            let f = make(dir.path(), n, &text, voice, speed, pitch, noise);
                            let h = hear(&mut r, &g, v, &read_audio(&f).expect("audio"))
                                .expect("decodes");
                            score.go += 1;
                            match h.decision {
                                Decision::Act(UserInput::Goto(l)) if l == target => {
                                    score.right += 1
                                }
                                Decision::Act(UserInput::Goto(_)) => {
                                    eprintln!("wrong target: {text:?} ({voice} {speed} {pitch} {noise:?}) heard {:?}", h.heard);
                                    score.wrong += 1
                                }
                                Decision::Ask(l) if l == target => score.asked_right += 1,
                                Decision::Ask(_) => score.asked_wrong += 1,
                                _ => {}
                            }
                        }
                    }
                    for text in STOPS {
                        n += 1;
                        let f = make(dir.path(), n, text, voice, speed, pitch, noise);
                        let h =
                            hear(&mut r, &g, v, &read_audio(&f).expect("audio")).expect("decodes");
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
                    for text in OUTSIDE {
                        n += 1;
                        let f = make(dir.path(), n, text, voice, speed, pitch, noise);
                        let h =
                            hear(&mut r, &g, v, &read_audio(&f).expect("audio")).expect("decodes");
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
    // the real recording: "go forward ten meters" with "forward" a target
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
