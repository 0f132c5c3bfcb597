//! Listening: audio from the microphone (ALSA through `arecord`, 16 kHz
//! mono) or from a file (tests, technicians: played at its own pace, as a
//! microphone would deliver it), split into utterances, recognised, and
//! handed to the input hub: a sure command acts, an unsure word is asked
//! back, a stop always acts. On its own thread: the control path never
//! waits for recognition.

use std::io::Read;
use std::path::PathBuf;
use std::time::Duration;

use tokio::sync::mpsc;

use super::grammar::{self, Grammar};
use super::intent::{self, Decision};
use super::sphinx::{Hypothesis, ModelPaths, Recognizer};
use super::vad::{Vad, VadSettings};
use super::VoiceSettings;
use crate::input::InputHub;
use crate::msg::UserInput;

/// 16-bit little-endian samples from a byte stream read in pieces: a read
/// that ends inside a sample keeps its odd byte for the next (dropping it
/// would shift every sample after it by a byte).
#[derive(Debug, Default)]
pub struct S16Stream {
    odd: Option<u8>,
}

impl S16Stream {
    pub fn push(&mut self, bytes: &[u8]) -> Vec<i16> {
        let mut out = Vec::with_capacity(bytes.len() / 2 + 1);
        let mut rest = bytes;
        if let (Some(lo), Some((&hi, tail))) = (self.odd, rest.split_first()) {
            out.push(i16::from_le_bytes([lo, hi]));
            self.odd = None;
            rest = tail;
        }
        let mut chunks = rest.chunks_exact(2);
        out.extend(chunks.by_ref().map(|c| i16::from_le_bytes([c[0], c[1]])));
        if let [b] = chunks.remainder() {
            self.odd = Some(*b);
        }
        out
    }
}

/// Where the audio comes from.
#[derive(Debug, Clone, PartialEq)]
pub enum AudioInput {
    /// An ALSA capture device (`arecord -D`).
    Device(String),
    /// A 16 kHz mono WAV or .raw file, played once at its own pace.
    File(PathBuf),
}

/// The grammar and recogniser for `vocabulary` (errors name what is
/// missing).
pub fn recogniser(
    s: &VoiceSettings,
    vocabulary: &[String],
) -> Result<(Recognizer, Grammar), String> {
    let dict_path = PathBuf::from(&s.dict);
    let dict = grammar::read_dictionary(&dict_path)?;
    let g = grammar::build(vocabulary, &dict)?;
    if !g.skipped.is_empty() {
        tracing::warn!(skipped = ?g.skipped, "voice: words not in the pronunciation dictionary cannot be recognised");
    }
    let mut r = Recognizer::with_pronunciations(
        &ModelPaths {
            hmm: PathBuf::from(&s.hmm),
            dict: dict_path,
            english_lm: PathBuf::from(&s.english_lm),
            phone_lm: PathBuf::from(&s.phone_lm),
        },
        &g.jsgf,
        &g.extra_pronunciations,
    )
    .map_err(|e| e.to_string())?;
    // each target's rival: the grammar without it
    for i in 0..g.targets.len() {
        if let Some(jsgf) = g.jsgf_without(i) {
            r.add_grammar(&rival_search(i), &jsgf)
                .map_err(|e| e.to_string())?;
        }
        if let Some(jsgf) = g.bare_jsgf_without(i) {
            r.add_grammar(&bare_rival_search(i), &jsgf)
                .map_err(|e| e.to_string())?;
        }
    }
    r.add_grammar(STOPS_SEARCH, grammar::STOPS_JSGF)
        .map_err(|e| e.to_string())?;
    Ok((r, g))
}

/// The search that reads an utterance as a stop.
const STOPS_SEARCH: &str = "stops";

fn rival_search(index: usize) -> String {
    format!("rival{index}")
}

fn bare_rival_search(index: usize) -> String {
    format!("barerival{index}")
}

/// How much better per 10 ms frame the heard path explains the audio
/// acoustically than another reading's score.
fn margin_over(h: &Hypothesis, other_score: i32) -> f64 {
    (h.score as f64 - other_score as f64) / h.frames.max(1) as f64
}

/// The standard deviation of the noise floor added before decoding, in
/// 16-bit sample units (about −60 dBFS). A microphone always hears a room;
/// digital silence (a file, a muted input) is outside what the acoustic
/// model and PocketSphinx's noise estimate were made for, and recognition
/// of such audio is measurably worse (`benches/voice_commands.rs`).
pub const NOISE_FLOOR: f64 = 30.0;

/// `samples` with the noise floor added: deterministic (the same audio is
/// always heard the same way), Gaussian from a fixed-seed generator.
pub fn with_noise_floor(samples: &[i16]) -> Vec<i16> {
    let mut normal = super::standard_normal(0x9E37_79B9_7F4A_7C15);
    samples
        .iter()
        .map(|&v| super::to_i16_sample(v as f64 + NOISE_FLOOR * normal()))
        .collect()
}

/// One utterance, understood.
#[derive(Debug, Clone, PartialEq)]
pub struct Heard {
    /// The grammar's words, None when nothing in it was heard.
    pub heard: Option<String>,
    pub confidence: f64,
    pub intent: intent::Intent,
    pub label: Option<String>,
    pub decision: Decision,
    /// The evidence (for the log and the technician): a heard target's
    /// acoustic margin per frame over its best rival, and how much better
    /// per frame free phones explain the audio than the grammar's path.
    pub margin_per_frame: Option<f64>,
    pub phone_excess_per_frame: Option<f64>,
    /// The share of the meant words a free English decode heard too.
    pub english_agreement: f64,
    /// Why a heard target was taken for a stop, if it was.
    pub stop_rule: Option<StopRule>,
    /// A bare target heard: its acoustic margin per frame over the best
    /// stop reading of the same audio.
    pub stop_margin_per_frame: Option<f64>,
    /// A target heard and the grammar without it reached no end (its rival
    /// was then read without the leads).
    pub no_rival: bool,
}

/// Why an utterance the grammar heard as something else is a stop.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum StopRule {
    /// A stop was among the grammar's close readings.
    Nearby,
    /// A bare target whose best rival reading is a stop; the target's
    /// acoustic margin per frame over that stop.
    BareRival { margin_per_frame: f64 },
    /// A bare target that the stops alone read better than it (its
    /// margin per frame over them, negative).
    StopReadsBetter { margin_per_frame: f64 },
}

impl Heard {
    /// As `opennav check voice` reports it (`unsure` for what would be
    /// asked back; a label only with `go`).
    pub fn json(&self, file: &std::path::Path, min_confidence: f64) -> serde_json::Value {
        let reported = intent::reported(&self.intent, self.confidence, min_confidence);
        let label = if reported == intent::Intent::Go {
            self.label.clone()
        } else {
            None
        };
        serde_json::json!({
            "file": file,
            "heard": self.heard,
            "confidence": (self.confidence * 1000.0).round() / 1000.0,
            "intent": reported,
            "label": label,
        })
    }
}

/// Decodes one utterance and decides what it means (the daemon and
/// `opennav check voice` alike).
pub fn hear(
    r: &mut Recognizer,
    g: &Grammar,
    s: &VoiceSettings,
    samples: &[i16],
) -> Result<Heard, String> {
    let samples = with_noise_floor(samples);
    let h = r.decode(&samples).map_err(|e| e.to_string())?;
    let heard = h.as_ref().map(|h| h.text.clone());
    let (mut meant, mut label) = intent::meaning(heard.as_deref().unwrap_or(""), &g.targets);
    let bare = |l: &str| {
        heard
            .as_deref()
            .is_some_and(|t| t == l || t.strip_suffix(" please") == Some(l))
    };
    // a bare target against the best stop reading of the same audio
    let stop_margin_per_frame = match (&label, &h) {
        (Some(l), Some(h)) if bare(l) => r
            .read(STOPS_SEARCH, &samples)
            .map_err(|e| e.to_string())?
            .map(|s| margin_over(h, s.score)),
        _ => None,
    };
    // a missed stop is dangerous, a false one is not: a stop among the
    // grammar's close readings is a stop
    let stop_nearby = h.as_ref().is_some_and(|h| {
        h.alternatives
            .iter()
            .any(|a| intent::meaning(a, &g.targets).0 == intent::Intent::Stop)
    });
    let mut stop_rule = None;
    if stop_nearby && meant != intent::Intent::Stop {
        tracing::info!(heard = ?heard, "voice: a stop among the close readings: stopping");
        meant = intent::Intent::Stop;
        label = None;
        stop_rule = Some(StopRule::Nearby);
    }
    // a bare target that a stop explains better, acoustically, is a stop
    // (the grammar's weights can still prefer the target)
    if let Some(m) = stop_margin_per_frame.filter(|m| *m < 0.0) {
        if meant != intent::Intent::Stop {
            tracing::info!(heard = ?heard, margin_per_frame = m, "voice: a stop reads the bare target better: stopping");
            meant = intent::Intent::Stop;
            label = None;
            stop_rule = Some(StopRule::StopReadsBetter {
                margin_per_frame: m,
            });
        }
    }
    // a heard target against its rival: the best reading without it
    // (the grammar without leads when the full one reaches no end)
    let mut no_rival = false;
    let rival = match (&meant, &label, &h) {
        (intent::Intent::Go, Some(l), Some(_)) => match g.targets.iter().position(|t| t == l) {
            Some(i) => match r
                .read(&rival_search(i), &samples)
                .map_err(|e| e.to_string())?
            {
                Some(rv) => Some(rv),
                None => {
                    tracing::debug!(heard = ?heard, "voice: the grammar without the target reaches no end; its rival read without the leads");
                    no_rival = true;
                    r.read(&bare_rival_search(i), &samples)
                        .map_err(|e| e.to_string())?
                }
            },
            None => None,
        },
        _ => None,
    };
    // "stop" in noise can lose its S and come out as a bare target
    // ("sofa", "door please"), even with a clear margin: a bare target
    // whose best rival is a stop is a stop (no spoken target in the test
    // set has a stop for its rival; a command with its lead, "go to the
    // X", is not a misheard stop)
    if let (Some(rv), Some(l), Some(h)) = (&rival, &label, &h) {
        if bare(l) && intent::meaning(&rv.text, &g.targets).0 == intent::Intent::Stop {
            let margin_per_frame = margin_over(h, rv.score);
            tracing::info!(heard = ?heard, rival = %rv.text, margin_per_frame, "voice: a stop is the best reading without the target: stopping");
            meant = intent::Intent::Stop;
            label = None;
            stop_rule = Some(StopRule::BareRival { margin_per_frame });
        }
    }
    let margin_per_frame = match (&meant, &rival, &h) {
        (intent::Intent::Go, Some(rival), Some(h)) => Some(margin_over(h, rival.score)),
        _ => None,
    };
    let nbest_agreement = h.as_ref().map_or(0.0, |h| {
        if h.top_paths.is_empty() {
            return 0.0;
        }
        let same = h
            .top_paths
            .iter()
            .filter(|a| intent::meaning(a, &g.targets) == (meant.clone(), label.clone()))
            .count();
        same as f64 / h.top_paths.len() as f64
    });
    // per frame of the words heard, not of the whole cut: silence scores
    // alike in both passes, so how much of it the voice activity
    // detection (or a file) leaves around the speech does not dilute it
    let phone_excess_per_frame = h.as_ref().and_then(|h| {
        h.phone_score
            .map(|p| (p as f64 - h.score as f64) / h.word_frames.max(1) as f64)
    });
    let english_agreement = intent::agreement(
        &meant,
        label.as_deref(),
        h.as_ref().and_then(|h| h.english.as_deref()),
    );
    tracing::debug!(heard = ?heard, margin_per_frame, phone_excess_per_frame, english_agreement, nbest_agreement, inner_silence = h.as_ref().map_or(0, |h| h.inner_silence_frames), "voice: evidence");
    let confidence = intent::confidence(
        &meant,
        label.as_deref(),
        &intent::Evidence {
            english: h.as_ref().and_then(|h| h.english.as_deref()),
            margin_per_frame,
            bare: label.as_deref().is_some_and(bare),
            nbest_agreement,
            inner_silence_frames: h.as_ref().map_or(0, |h| h.inner_silence_frames),
            phone_excess_per_frame,
        },
        s.max_phone_excess_per_frame,
    );
    let decision = intent::decide(
        &meant,
        label.as_deref(),
        confidence,
        s.confirm,
        s.min_confidence,
    );
    Ok(Heard {
        heard,
        confidence,
        intent: meant,
        label,
        decision,
        margin_per_frame,
        phone_excess_per_frame,
        english_agreement,
        stop_rule,
        stop_margin_per_frame,
        no_rival,
    })
}

fn act(hub: &InputHub, d: Decision) {
    let input = match d {
        // a sure target word: the daemon decides, knowing whether the
        // chair is driving itself (then any word stops it)
        Decision::Act(UserInput::Goto(l)) => UserInput::Heard(l),
        Decision::Act(i) => i,
        Decision::Ask(l) => UserInput::Unsure(l),
        Decision::Ignore => return,
    };
    if let Err(e) = hub.send(input.clone()) {
        tracing::warn!(input = ?input, error = %e, "voice: input not taken");
    }
}

/// Starts listening on its own thread (the recogniser is built first: a
/// missing model is an error here, not later).
pub fn spawn(
    s: &VoiceSettings,
    input: AudioInput,
    vocabulary: &[String],
    hub: InputHub,
    say: mpsc::UnboundedSender<String>,
) -> Result<std::thread::JoinHandle<()>, String> {
    let (mut r, g) = recogniser(s, vocabulary)?;
    let s = s.clone();
    std::thread::Builder::new()
        .name("voice".into())
        .spawn(move || {
            let mut vad = Vad::new(VadSettings::default());
            let mut handle = |u: Vec<i16>| match hear(&mut r, &g, &s, &u) {
                Ok(h) => {
                    tracing::info!(heard = ?h.heard, confidence = h.confidence, decision = ?h.decision, "voice");
                    act(&hub, h.decision);
                }
                Err(e) => tracing::error!(error = %e, "voice: an utterance could not be decoded"),
            };
            match input {
                AudioInput::File(path) => {
                    let samples = match super::wav::read_audio(&path) {
                        Ok(s) => s,
                        Err(e) => {
                            tracing::error!(error = %e, "voice: audio file");
                            return;
                        }
                    };
                    // 100 ms at a time, as a microphone delivers it
                    for chunk in samples.chunks(1600) {
                        for u in vad.push(chunk) {
                            handle(u);
                        }
                        std::thread::sleep(Duration::from_millis(100));
                    }
                    if let Some(u) = vad.flush() {
                        handle(u);
                    }
                    tracing::info!(file = %path.display(), "voice: the audio file ended");
                }
                AudioInput::Device(dev) => loop {
                    let child = std::process::Command::new("arecord")
                        .args(["-q", "-D", &dev, "-f", "S16_LE", "-r", "16000", "-c", "1", "-t", "raw"])
                        .stdout(std::process::Stdio::piped())
                        .stderr(std::process::Stdio::null())
                        .spawn();
                    let mut child = match child {
                        Ok(c) => c,
                        Err(e) => {
                            tracing::error!(device = %dev, error = %e, "voice: cannot run arecord (alsa-utils)");
                            say.send("I cannot hear: the microphone does not work.".into()).ok();
                            return;
                        }
                    };
                    let Some(mut out) = child.stdout.take() else { return };
                    let mut buf = vec![0u8; 3200];
                    let mut pcm = S16Stream::default();
                    loop {
                        match out.read(&mut buf) {
                            Ok(0) | Err(_) => break,
                            Ok(n) => {
                                for u in vad.push(&pcm.push(&buf[..n])) {
                                    handle(u);
                                }
                            }
                        }
                    }
                    // its output ended: make sure it is gone before the next
                    if let Err(e) = child.kill().and_then(|_| child.wait().map(drop)) {
                        tracing::debug!(error = %e, "voice: arecord already gone");
                    }
                    tracing::error!(device = %dev, "voice: the microphone stopped; retrying");
                    say.send("The microphone stopped. Trying again.".into()).ok();
                    std::thread::sleep(Duration::from_secs(2));
                },
            }
        })
        .map_err(|e| format!("voice thread: {e}"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn samples_split_across_reads_are_joined() {
        let samples: Vec<i16> = vec![1, -2, 300, -32768, 32767, 7];
        let bytes: Vec<u8> = samples.iter().flat_map(|s| s.to_le_bytes()).collect();
        for cut in [1usize, 3, 5] {
            let mut s = S16Stream::default();
            let mut got = Vec::new();
            for piece in bytes.chunks(cut) {
                got.extend(s.push(piece));
            }
            assert_eq!(got, samples, "pieces of {cut} bytes");
        }
    }

    #[test]
    fn the_noise_floor_is_small_and_the_same_every_time() {
        let silence = vec![0i16; 16_000];
        let a = with_noise_floor(&silence);
        assert_eq!(a, with_noise_floor(&silence));
        let rms = (a.iter().map(|&v| (v as f64).powi(2)).sum::<f64>() / a.len() as f64).sqrt();
        assert!(
            (NOISE_FLOOR * 0.9..NOISE_FLOOR * 1.1).contains(&rms),
            "{rms}"
        );
        // loud samples stay within range
        assert_eq!(with_noise_floor(&[i16::MAX; 4]).len(), 4);
    }
}
