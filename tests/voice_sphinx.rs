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
fn a_bare_target_whose_rival_grammar_reaches_no_end_is_measured_against_it_without_the_leads() {
    // "sofa" alone: the grammar without "sofa" can end the utterance on a
    // lead ("find a…"), where the grammar cannot end, and PocketSphinx
    // then reports nothing; such a target had no margin and was always
    // asked back. Its rival without the leads reads something. Whether
    // the full rival reaches its end for one utterance varies with the
    // decoder's state, so several are heard: every bare target heard has
    // its margins, and some of them were measured the bare way.
    let _cores = cores();
    let dir = tempfile::tempdir().expect("tmp");
    let settings = opennav::config::Settings::load(None).expect("defaults");
    let v = &settings.voice;
    let (mut r, g) = opennav::voice::listen::recogniser(v, &v.vocabulary).expect("recogniser");
    let mut bare_way = Vec::new();
    for voice in ["en", "en-us", "en-gb-scotland"] {
        for word in ["sofa", "table"] {
            let wav = spoken_sequence(
                dir.path(),
                &format!("{word}-{voice}"),
                voice,
                &[(word, 0.5)],
            );
            let samples = opennav::voice::wav::read_audio(&wav).expect("audio");
            let h = opennav::voice::listen::hear(&mut r, &g, v, &samples).expect("decodes");
            eprintln!("{word} ({voice}): {h:?}");
            if h.heard.as_deref() != Some(word) {
                continue;
            }
            // a bare target heard always has its margin over the stops
            assert!(h.stop_margin_per_frame.is_some(), "{h:?}");
            if h.intent == opennav::voice::intent::Intent::Go {
                // and over its rival, however that was read
                assert!(h.margin_per_frame.is_some(), "{h:?}");
            }
            if h.no_rival {
                bare_way.push(h);
            }
        }
    }
    assert!(
        !bare_way.is_empty(),
        "no bare target's full rival reached no end: nothing measured the bare way"
    );
    // the bare way makes a bare word sure: the chair goes
    assert!(
        bare_way.iter().any(|h| matches!(
            &h.decision,
            opennav::voice::intent::Decision::Act(opennav::msg::UserInput::Goto(l)) if h.heard.as_deref() == Some(l.as_str())
        )),
        "{bare_way:?}"
    );
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
    run_listening_with(wav, confirm, max, exit_on_arrival, None)
}

/// The same, with the acoustic model adapted to the voice in `adapted`
/// (`opennav voice enroll`'s directory) when given.
fn run_listening_with(
    wav: &std::path::Path,
    confirm: &str,
    max: &str,
    exit_on_arrival: bool,
    adapted: Option<&std::path::Path>,
) -> serde_json::Value {
    let _cores = cores();
    let mut c = std::process::Command::new(env!("CARGO_BIN_EXE_opennav"));
    if let Some(model) = adapted {
        c.env("OPENNAV_VOICE__HMM", model).env(
            "OPENNAV_VOICE__MAX_PHONE_EXCESS_PER_FRAME",
            opennav::voice::intent::MAX_PHONE_EXCESS_ENROLLED.to_string(),
        );
    }
    c.args(["run", "--sim", "--clock", "realtime", "--no-stdin"]);
    if exit_on_arrival {
        c.arg("--exit-on-arrival");
    }
    let out = c
        .args(["--max-duration", max, "--voice-wav"])
        .arg(wav)
        .env("OPENNAV_VOICE__CONFIRM", confirm)
        // a turn on the spot with the rear (or the floor beside the
        // chair) unseen asks "Is it clear behind?" ("… around me?") and
        // waits for a "yes" that a recording made beforehand cannot time
        // (whether the start's turn asks depends on the scans and frames
        // the wall clock has given by then); that question has its own
        // tests (daemon::control tests, daemon_sim, switch_sim); these are
        // about the voice
        .env("OPENNAV_SAFETY__TURN_NEEDS_SEEN_REAR", "false")
        .env("OPENNAV_SAFETY__TURN_NEEDS_SEEN_FLOOR", "false")
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
    // a sure command goes at once (confirm = unsure), with Debian's model
    // as installed (free phones fit the daemon's cut of it by about 27 per
    // frame of its words better than the command, under the 50 allowed;
    // accuracy over voices, speeds and noise is benches/voice_commands.rs's)
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
    // takes a second or two of the real-time run on a busy runner), with
    // the voice enrolled, as it is set up on the chair
    let model = enrolled_model(dir.path(), "en-us");
    let wav = spoken_sequence(
        dir.path(),
        "stop",
        "en-us",
        &[("take me to the chair", 3.0), ("stop", 2.0)],
    );
    let r = run_listening_with(&wav, "unsure", "12s", false, Some(&model));
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

/// The enrollment sentences read by espeak-ng's `voice` into `dir` as
/// NN.wav with NN.txt (as an occupational therapist records them).
fn enrollment_recordings(dir: &std::path::Path, voice: &str) {
    let made = tempfile::tempdir().expect("tmp");
    for (i, text) in opennav::voice::enroll::SENTENCES.iter().enumerate() {
        let wav = spoken_in(made.path(), &format!("{i:02}"), text, voice);
        std::fs::copy(&wav, dir.join(format!("{i:02}.wav"))).expect("copy");
        std::fs::write(dir.join(format!("{i:02}.txt")), text).expect("text");
    }
}

/// `voice`'s enrollment sentences through `opennav voice enroll`: the
/// adapted model's directory (under `dir`).
fn enrolled_model(dir: &std::path::Path, voice: &str) -> std::path::PathBuf {
    let recordings = dir.join(format!("recordings-{voice}"));
    std::fs::create_dir(&recordings).expect("dir");
    enrollment_recordings(&recordings, voice);
    let model = dir.join(format!("model-{voice}"));
    let out = opennav_enroll(&recordings, &model);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    model
}

/// `opennav voice enroll --dir recordings --out model`, the cores its own.
fn opennav_enroll(recordings: &std::path::Path, model: &std::path::Path) -> std::process::Output {
    let _cores = cores();
    opennav(&[
        std::ffi::OsStr::new("voice"),
        std::ffi::OsStr::new("enroll"),
        std::ffi::OsStr::new("--dir"),
        recordings.as_os_str(),
        std::ffi::OsStr::new("--out"),
        model.as_os_str(),
    ])
}

fn opennav(args: &[&std::ffi::OsStr]) -> std::process::Output {
    std::process::Command::new(env!("CARGO_BIN_EXE_opennav"))
        .args(args)
        .output()
        .expect("runs")
}

#[test]
fn a_persons_enrollment_adapts_the_model_and_a_doubtful_command_is_then_heard() {
    use std::ffi::OsStr;
    let dir = tempfile::tempdir().expect("tmp");
    let recordings = dir.path().join("recordings");
    std::fs::create_dir(&recordings).expect("dir");
    enrollment_recordings(&recordings, "en-gb-scotland");
    let model = dir.path().join("model");
    let out = opennav_enroll(&recordings, &model);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let line: serde_json::Value = serde_json::from_slice(&out.stdout).expect("one JSON line");
    assert_eq!(line["recordings"], 30, "{line}");
    assert!(
        line["config"].as_str().is_some_and(|c| c.contains(&format!(
            "max_phone_excess_per_frame = {}",
            opennav::voice::intent::MAX_PHONE_EXCESS_ENROLLED
        ))),
        "{line}"
    );
    let used = line["used"].as_u64().expect("used");
    assert!(used >= 25, "{line}");
    // each recording is learnt again with room noise at 10 and 20 dB
    let noisy_used = line["noisy_used"].as_u64().expect("noisy_used");
    assert!(noisy_used >= 45, "{line}");
    assert_eq!(
        line["not_aligned"].as_array().expect("list").len() as u64,
        30 + 60 - used - noisy_used,
        "{line}"
    );
    for f in [
        "means",
        "variances",
        "mixture_weights",
        "transition_matrices",
        "mdef",
        "feat.params",
        "noisedict",
    ] {
        assert!(model.join(f).is_file(), "{f} missing in the adapted model");
    }
    // enrolled again: the model replaced whole, nothing left beside it
    let again = opennav_enroll(&recordings, &model);
    assert!(
        again.status.success(),
        "{}",
        String::from_utf8_lossy(&again.stderr)
    );
    let beside: Vec<String> = std::fs::read_dir(dir.path())
        .expect("dir")
        .filter_map(|e| e.ok())
        .map(|e| e.file_name().to_string_lossy().to_string())
        .filter(|n| n.starts_with('.'))
        .collect();
    assert!(beside.is_empty(), "{beside:?}");
    assert!(model.join("means").is_file());
    // a command the installed model is unsure of (the same voice; no
    // command is among the sentences): asked back before, acted on after
    let wav = spoken_sequence(
        dir.path(),
        "command",
        "en-gb-scotland",
        &[("take me to the chair", 1.0)],
    );
    let before = &opennav_check_voice(&[&wav], "chair,door,toilet,table,bed,sofa")[0];
    assert_eq!(before["intent"], "unsure", "{before}");
    let config = dir.path().join("adapted.toml");
    std::fs::write(
        &config,
        format!(
            "[voice]\nhmm = {:?}\nmax_phone_excess_per_frame = {}\n",
            model.display().to_string(),
            opennav::voice::intent::MAX_PHONE_EXCESS_ENROLLED
        ),
    )
    .expect("config");
    let after = {
        let _cores = cores();
        common::opennav_json_lines(&[
            OsStr::new("--config"),
            config.as_os_str(),
            OsStr::new("check"),
            OsStr::new("voice"),
            OsStr::new("--vocabulary"),
            OsStr::new("chair,door,toilet,table,bed,sofa"),
            OsStr::new("--wav"),
            wav.as_os_str(),
        ])
    };
    assert_eq!(after[0]["intent"], "go", "{}", after[0]);
    assert_eq!(after[0]["label"], "chair", "{}", after[0]);
    assert!(
        after[0]["confidence"].as_f64().expect("c") > before["confidence"].as_f64().expect("c"),
        "{before} → {}",
        after[0]
    );
}

#[test]
fn an_enrollment_with_bad_recordings_names_what_is_wrong() {
    use std::ffi::OsStr;
    let dir = tempfile::tempdir().expect("tmp");
    let enroll = |recordings: &std::path::Path| {
        let out = opennav(&[
            OsStr::new("voice"),
            OsStr::new("enroll"),
            OsStr::new("--dir"),
            recordings.as_os_str(),
            OsStr::new("--out"),
            dir.path().join("model").as_os_str(),
        ]);
        assert!(!out.status.success());
        assert!(
            !dir.path().join("model").exists(),
            "no model from bad input"
        );
        String::from_utf8_lossy(&out.stderr).to_string()
    };
    let e = enroll(&dir.path().join("nowhere"));
    assert!(e.contains("nowhere"), "{e}");
    let recs = dir.path().join("recs");
    std::fs::create_dir(&recs).expect("dir");
    let e = enroll(&recs);
    assert!(e.contains("no .wav recordings"), "{e}");
    // a recording without its text
    let made = tempfile::tempdir().expect("tmp");
    let wav = spoken_in(made.path(), "a", "the water in the glass is cold", "en");
    std::fs::copy(&wav, recs.join("01.wav")).expect("copy");
    let e = enroll(&recs);
    assert!(
        e.contains("01.wav: its text") && e.contains("01.txt"),
        "{e}"
    );
    // a word the dictionary lacks
    std::fs::write(recs.join("01.txt"), "the water in the glazz is cold").expect("text");
    for i in 2..=6 {
        std::fs::copy(&wav, recs.join(format!("{i:02}.wav"))).expect("copy");
        std::fs::write(
            recs.join(format!("{i:02}.txt")),
            "the water in the glass is cold",
        )
        .expect("text");
    }
    let e = enroll(&recs);
    assert!(e.contains("01.wav") && e.contains("glazz"), "{e}");
    // too few
    std::fs::write(recs.join("01.txt"), "the water in the glass is cold").expect("text");
    for i in 2..=6 {
        std::fs::remove_file(recs.join(format!("{i:02}.wav"))).expect("rm");
    }
    let e = enroll(&recs);
    assert!(e.contains("1 recordings: at least 5"), "{e}");
}
