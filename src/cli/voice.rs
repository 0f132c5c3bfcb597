//! `opennav voice`: the person's own voice. `sentences` prints what to
//! read aloud; `enroll` makes the acoustic model adapted to the person
//! from the recordings (`[voice] hmm` then points at it).

use std::path::{Path, PathBuf};

use clap::Subcommand;

use opennav::config::Settings;
use opennav::voice::enroll;

use super::{bad_input, failed, Failure};

#[derive(Subcommand, Debug)]
pub enum VoiceCommand {
    /// The sentences to read aloud for `enroll`, one a line (record each
    /// as 01.wav, 02.wav, … with the sentence in 01.txt, 02.txt, …).
    Sentences,
    /// Learns the person's voice from their recordings: DIR holds NAME.wav
    /// (16 kHz mono) with NAME.txt (the words said) for each; writes the
    /// acoustic model of config `[voice] hmm` adapted to them as the
    /// directory OUT (then set `[voice] hmm = "OUT"`). Prints one JSON
    /// line; needs Debian's sphinxtrain, sphinxbase-utils and pocketsphinx.
    Enroll {
        /// The recordings and their texts.
        #[arg(long)]
        dir: PathBuf,
        /// The adapted model's directory (replaced whole if it exists).
        #[arg(long)]
        out: PathBuf,
    },
}

pub fn run(config: Option<&Path>, cmd: VoiceCommand) -> Result<(), Failure> {
    match cmd {
        VoiceCommand::Sentences => {
            use std::io::Write;
            let mut out = std::io::stdout().lock();
            for s in enroll::SENTENCES {
                // a reader that stopped early (`| head`) is not an error
                if writeln!(out, "{s}").is_err() {
                    break;
                }
            }
            Ok(())
        }
        VoiceCommand::Enroll { dir, out } => {
            let settings = Settings::load(config).map_err(bad_input)?;
            enroll_dir(&settings, &dir, &out)
        }
    }
}

/// The recordings of `dir`: every NAME.wav with its NAME.txt, by name.
#[cfg(feature = "voice")]
pub fn recordings(dir: &Path) -> Result<Vec<enroll::Recording>, String> {
    let entries = std::fs::read_dir(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    let mut wavs: Vec<PathBuf> = entries
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "wav"))
        .collect();
    wavs.sort();
    if wavs.is_empty() {
        return Err(format!("{}: no .wav recordings", dir.display()));
    }
    wavs.iter()
        .map(|wav| {
            let txt = wav.with_extension("txt");
            let text = std::fs::read_to_string(&txt)
                .map_err(|e| format!("{}: its text {}: {e}", wav.display(), txt.display()))?;
            let samples = opennav::voice::wav::read_audio(wav)?;
            Ok(enroll::Recording {
                name: wav.display().to_string(),
                samples,
                text: text.trim().to_string(),
            })
        })
        .collect()
}

#[cfg(not(feature = "voice"))]
fn enroll_dir(_: &Settings, _: &Path, _: &Path) -> Result<(), Failure> {
    Err(failed(anyhow::anyhow!(
        "this build has no speech recognition: build with --features voice \
         (Debian: libpocketsphinx-dev libsphinxbase-dev pocketsphinx-en-us)"
    )))
}

#[cfg(feature = "voice")]
fn enroll_dir(settings: &Settings, dir: &Path, out: &Path) -> Result<(), Failure> {
    let v = &settings.voice;
    let recs = recordings(dir).map_err(|e| bad_input(anyhow::anyhow!(e)))?;
    let dict_path = PathBuf::from(&v.dict);
    let dict = opennav::voice::grammar::read_dictionary(&dict_path)
        .map_err(|e| failed(anyhow::anyhow!(e)))?;
    let tools = enroll::Tools::debian().map_err(|e| failed(anyhow::anyhow!(e)))?;
    let work = tempfile::tempdir().map_err(failed)?;
    let made = enroll::enroll(
        &tools,
        &enroll::Model {
            hmm: Path::new(&v.hmm),
            dict_path: &dict_path,
            dict: &dict,
        },
        &recs,
        work.path(),
        out,
        opennav::voice::listen::with_noise_floor,
    )
    .map_err(|e| failed(anyhow::anyhow!(e)))?;
    check_loads(settings, out)?;
    let line = serde_json::json!({
        "out": out,
        "recordings": recs.len(),
        "used": made.used,
        "noisy_used": made.noisy_used,
        "not_aligned": made.not_aligned,
        "speech_s": (made.seconds * 10.0).round() / 10.0,
        "config": format!(
            "[voice] hmm = {:?}, max_phone_excess_per_frame = {}",
            out.display().to_string(),
            opennav::voice::intent::MAX_PHONE_EXCESS_ENROLLED
        ),
    });
    println!("{line}");
    Ok(())
}

/// The recogniser starts on the adapted model.
#[cfg(feature = "voice")]
fn check_loads(settings: &Settings, out: &Path) -> Result<(), Failure> {
    let mut v = settings.voice.clone();
    v.hmm = out.display().to_string();
    v.max_phone_excess_per_frame = opennav::voice::intent::MAX_PHONE_EXCESS_ENROLLED;
    opennav::voice::listen::recogniser(&v, &v.vocabulary)
        .map(|_| ())
        .map_err(|e| {
            failed(anyhow::anyhow!(
                "the recogniser refuses the adapted model: {e}"
            ))
        })
}
