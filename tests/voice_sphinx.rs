//! PocketSphinx through opennav's binding (the `voice` feature): the real
//! recording of the shared data decoded with its grammar, and speech made
//! with espeak-ng decoded with a grammar of the chair's words.
#![cfg(feature = "voice")]

mod common;

use opennav::voice::sphinx::{samples_from_s16le, ModelPaths, Recognizer};

/// A recogniser with the real recording's grammar, and its samples.
fn real_recording() -> (Recognizer, Vec<i16>) {
    let raw = common::asset(common::shared().join("data/speech/goforward.raw"));
    let gram = common::asset(common::shared().join("data/speech/goforward.gram"));
    let jsgf = std::fs::read_to_string(&gram).expect("grammar");
    let r = Recognizer::new(&ModelPaths::debian_en_us(), &jsgf).expect("recogniser");
    let samples =
        samples_from_s16le(&std::fs::read(&raw).expect("audio"), "goforward.raw").expect("samples");
    (r, samples)
}

#[test]
fn the_real_recording_decodes_to_its_words() {
    let (mut r, samples) = real_recording();
    let h = r
        .decode(&samples)
        .expect("decodes")
        .expect("heard something");
    assert_eq!(h.text, "go forward ten meters");
    assert!((0.0..=1.0).contains(&h.probability), "{h:?}");
    // silence is not a command
    assert_eq!(r.decode(&vec![0i16; 16_000]).expect("decodes"), None);
}

#[test]
fn an_utterance_is_heard_the_same_whatever_was_heard_before() {
    // the front end's noise estimate used to carry over from one
    // utterance to the next, so the same audio scored differently after
    // loud noise (and a target's rival pass differently from its own)
    let (mut r, samples) = real_recording();
    let first = r.decode(&samples).expect("decodes").expect("heard");
    // two seconds of loud noise in between
    let mut state = 12345u32;
    let noise: Vec<i16> = (0..32_000)
        .map(|_| {
            state = state.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            ((state >> 16) as i16) / 2
        })
        .collect();
    r.decode(&noise).expect("decodes");
    let again = r.decode(&samples).expect("decodes").expect("heard");
    assert_eq!(again.text, first.text);
    assert_eq!(again.score, first.score, "{first:?}\n{again:?}");
    assert_eq!(again.frames, first.frames);
}

#[test]
fn a_grammar_with_an_unknown_word_is_an_error() {
    let e = Recognizer::new(
        &ModelPaths::debian_en_us(),
        "#JSGF V1.0;\ngrammar g;\npublic <w> = qzxwvjk;\n",
    )
    .err()
    .expect("refused");
    assert!(e.to_string().contains("grammar"), "{e}");
}

/// The real-time trips and the many-file decodes take the cores one at a
/// time: on this 2-core machine two of them at once (the test runner's
/// threads) left a trip's chair moving at half pace behind its deadline —
/// the runner's load, not the chair's (the same tests pass one by one).
static CORES: std::sync::Mutex<()> = std::sync::Mutex::new(());

fn cores() -> std::sync::MutexGuard<'static, ()> {
    // a test that failed while holding it poisons it; the cores are free
    CORES.lock().unwrap_or_else(|e| e.into_inner())
}

fn opennav_check_voice(files: &[&std::path::Path], vocabulary: &str) -> Vec<serde_json::Value> {
    let _cores = cores();
    let words = ["check", "voice", "--vocabulary", vocabulary, "--wav"];
    let mut args: Vec<&std::ffi::OsStr> = words.iter().map(std::ffi::OsStr::new).collect();
    args.extend(files.iter().map(|f| f.as_os_str()));
    common::opennav_json_lines(&args)
}

/// `text` spoken by espeak-ng, as 16 kHz mono WAV (sox resamples).
fn spoken(dir: &std::path::Path, name: &str, text: &str) -> std::path::PathBuf {
    spoken_in(dir, name, text, "en")
}

/// `text` spoken by espeak-ng in `voice`, as 16 kHz mono WAV.
fn spoken_in(dir: &std::path::Path, name: &str, text: &str, voice: &str) -> std::path::PathBuf {
    let raw = dir.join(format!("{name}.22k.wav"));
    let wav = dir.join(format!("{name}.wav"));
    let ok = std::process::Command::new("espeak-ng")
        .args(["-v", voice, "-s", "150", "-w"])
        .arg(&raw)
        .arg(text)
        .status()
        .expect("espeak-ng runs (Debian espeak-ng; tests/run.sh installs it)")
        .success();
    assert!(ok, "espeak-ng failed");
    let ok = std::process::Command::new("sox")
        .arg(&raw)
        .args(["-r", "16000", "-c", "1", "-b", "16", "-e", "signed-integer"])
        .arg(&wav)
        .status()
        .expect("sox runs (Debian sox; tests/run.sh installs it)")
        .success();
    assert!(ok, "sox failed");
    wav
}

#[test]
fn check_voice_reports_what_was_heard_and_meant_and_never_sends_nonsense_anywhere() {
    let dir = tempfile::tempdir().expect("tmp");
    let real = common::asset(common::shared().join("data/speech/goforward.raw"));
    let stop = spoken(dir.path(), "stop", "stop");
    let fox = spoken(
        dir.path(),
        "fox",
        "the quick brown fox jumps over the lazy dog",
    );
    let lines = opennav_check_voice(&[&real, &stop, &fox], "forward,toilet,door,chair");
    assert_eq!(lines.len(), 3);
    for l in &lines {
        for k in ["file", "heard", "confidence", "intent", "label"] {
            assert!(l.get(k).is_some(), "{k} missing in {l}");
        }
    }
    // a real person: the grammar and free English agree on the target
    assert_eq!(lines[0]["intent"], "go", "{}", lines[0]);
    assert_eq!(lines[0]["label"], "forward", "{}", lines[0]);
    assert_eq!(lines[0]["confidence"], 1.0, "{}", lines[0]);
    // "stop" is a stop, whatever the confidence
    assert_eq!(lines[1]["intent"], "stop", "{}", lines[1]);
    // nonsense is never a target the chair would go to
    assert_ne!(lines[2]["intent"], "go", "{}", lines[2]);
    assert!(lines[2]["label"].is_null(), "{}", lines[2]);
    // with one word, the best reading without it is a command ("halt"):
    // a command with its lead is still a go, not a misheard stop
    let alone = opennav_check_voice(&[&real], "forward");
    assert_eq!(alone[0]["intent"], "go", "{}", alone[0]);
    assert_eq!(alone[0]["label"], "forward", "{}", alone[0]);
}

#[test]
fn check_voice_names_a_file_it_cannot_use() {
    let dir = tempfile::tempdir().expect("tmp");
    let bad = dir.path().join("cd.wav");
    let ok = std::process::Command::new("sox")
        .args(["-n", "-r", "44100", "-c", "2"])
        .arg(&bad)
        .args(["synth", "0.2", "sine", "440"])
        .status()
        .expect("sox runs")
        .success();
    assert!(ok);
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_opennav"))
        .args(["check", "voice", "--wav"])
        .arg(&bad)
        .output()
        .expect("runs");
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("cd.wav") && err.contains("44100 Hz"), "{err}");
}

/// Speech made by espeak-ng, padded and joined: `parts` are (text, silence
/// after, seconds), as one 16 kHz mono WAV.
fn spoken_sequence(
    dir: &std::path::Path,
    name: &str,
    voice: &str,
    parts: &[(&str, f64)],
) -> std::path::PathBuf {
    let mut pieces = Vec::new();
    for (i, (text, after)) in parts.iter().enumerate() {
        let w = spoken_in(dir, &format!("{name}{i}"), text, voice);
        let padded = dir.join(format!("{name}{i}.pad.wav"));
        let ok = std::process::Command::new("sox")
            .arg(&w)
            .arg(&padded)
            .args(["pad", "0.3", &after.to_string()])
            .status()
            .expect("sox")
            .success();
        assert!(ok);
        pieces.push(padded);
    }
    let out = dir.join(format!("{name}.wav"));
    let ok = std::process::Command::new("sox")
        .args(&pieces)
        .arg(&out)
        .status()
        .expect("sox")
        .success();
    assert!(ok);
    out
}

/// The simulated daemon at the wall clock's pace, listening to `wav`.
fn run_listening(
    wav: &std::path::Path,
    confirm: &str,
    max: &str,
    exit_on_arrival: bool,
) -> serde_json::Value {
    let _cores = cores();
    let mut c = std::process::Command::new(env!("CARGO_BIN_EXE_opennav"));
    c.args(["run", "--sim", "--clock", "realtime", "--no-stdin"]);
    if exit_on_arrival {
        c.arg("--exit-on-arrival");
    }
    let out = c
        .args(["--max-duration", max, "--voice-wav"])
        .arg(wav)
        .env("OPENNAV_VOICE__CONFIRM", confirm)
        // a turn on the spot with the rear unseen asks "Is it clear
        // behind?" and waits for a "yes" that a recording made beforehand
        // cannot time (whether the start's turn asks depends on the scans
        // the wall clock has given by then); that question has its own
        // tests (daemon::control tests, daemon_sim, switch_sim); these are
        // about the voice
        .env("OPENNAV_SAFETY__TURN_NEEDS_SEEN_REAR", "false")
        .output()
        .expect("runs");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    common::report(&out.stdout)
}

#[test]
fn a_spoken_command_drives_the_chair_and_a_spoken_stop_brings_it_to_rest() {
    let dir = tempfile::tempdir().expect("tmp");
    // a sure command goes at once (confirm = unsure); US English, the acoustic model's own accent (accuracy over voices,
    // speeds and noise is benches/voice_commands.rs's)
    let wav = spoken_sequence(
        dir.path(),
        "chair",
        "en-us",
        &[("take me to the chair", 1.0)],
    );
    let r = run_listening(&wav, "unsure", "30s", true);
    assert_eq!(r["outcome"], "arrived", "{r}");
    assert_eq!(r["sim"]["world"]["collision_steps"], 0, "{r}");
    // "stop" three seconds into the trip (the trip under way: its start
    // takes a second or two of the real-time run on a busy runner)
    let wav = spoken_sequence(
        dir.path(),
        "stop",
        "en-us",
        &[("take me to the chair", 3.0), ("stop", 2.0)],
    );
    let r = run_listening(&wav, "unsure", "12s", false);
    assert_eq!(r["outcome"], "timeout", "{r}");
    assert!(r["said"].to_string().contains("Stopped."), "{r}");
    assert_eq!(r["supervisor"]["Stopped"], "UserStop", "{r}");
    assert!(
        r["sim"]["world"]["v_mps"].as_f64().expect("v").abs() < 0.02,
        "{r}"
    );
    assert!(
        r["sim"]["world"]["distance_travelled_m"]
            .as_f64()
            .expect("d")
            > 0.05,
        "{r}"
    );
}

#[test]
fn an_unsure_utterance_is_asked_back_and_the_chair_waits() {
    let dir = tempfile::tempdir().expect("tmp");
    // espeak-ng's Scottish voice: the right word, but no margin over its
    // rivals
    let wav = spoken_sequence(
        dir.path(),
        "door",
        "en-gb-scotland",
        &[("take me to the chair", 1.0)],
    );
    let r = run_listening(&wav, "unsure", "8s", true);
    assert_eq!(r["outcome"], "timeout", "{r}");
    let said = r["said"].to_string();
    assert!(said.contains("Did you say the chair?"), "{said}");
    // nothing is looked for until "yes"
    assert_eq!(r["goal"]["state"], "none", "{r}");
    assert!(
        r["sim"]["world"]["distance_travelled_m"]
            .as_f64()
            .expect("d")
            < 0.01,
        "{r}"
    );
}
