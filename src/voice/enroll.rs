//! The person's own voice, learnt: a speaker-adapted copy of the acoustic
//! model from a few minutes of their speech, as CMU Sphinx's adaptation
//! recipe makes it — features with `sphinx_fe`, state statistics with
//! SphinxTrain's `bw`, then maximum a posteriori re-estimation of the
//! Gaussians, mixture weights and transitions with `map_adapt`. The
//! adapted model is a directory the recogniser loads in place of Debian's
//! (`[voice] hmm`); an occupational therapist makes it once, the chair
//! keeps it, and the original stays untouched beside it.
//!
//! Debian's `pocketsphinx-en-us` ships its mixture weights only in the
//! decoder's quantised form (`sendump`); `bw` and `map_adapt` read
//! SphinxTrain's `mixture_weights`. [`mixture_weights_from_sendump`] undoes
//! the quantisation (each weight is `1.0001^-(q << 10)`, renormalised).
//!
//! The pure parts (the conversion, the transcript check) take bytes and
//! text; [`enroll`] runs the tools in a working directory.

use std::path::{Path, PathBuf};
use std::process::Command;

use super::grammar::Dictionary;

/// Sentences to read aloud for the adaptation (plain words of home life,
/// every one in the US English dictionary; none of them a command, so the
/// commands are not learnt from themselves). About two minutes of speech.
pub const SENTENCES: [&str; 30] = [
    "please open the window in the kitchen",
    "the morning light is warm on the garden wall",
    "my brother will visit us on sunday afternoon",
    "we keep the books on the shelf near the lamp",
    "the dog sleeps in the hall by the front step",
    "turn the radio down a little before the news",
    "she bought fresh bread and cheese at the market",
    "the water in the glass is cold and clear",
    "could you bring my jacket from the car",
    "a yellow bird sang outside the bedroom window",
    "the nurse comes every tuesday at nine o'clock",
    "there is a long queue at the post office today",
    "he painted the fence a pale shade of green",
    "i would rather watch a film than play cards",
    "the kettle is boiling so let us make coffee",
    "our neighbour grows tomatoes and potatoes every summer",
    "the thunder woke the children in the middle of the night",
    "put the plates away and wipe the counter",
    "the bus was late because of the heavy snow",
    "my phone battery is almost empty again",
    "the carpet in the living room needs cleaning",
    "we walked along the river until the sun went down",
    "the doctor said i should drink more water",
    "a quiet evening with a good book is all i need",
    "the shop on the corner sells newspapers and sweets",
    "her voice was soft but very clear",
    "move the box of toys out of the way",
    "the clock on the wall is five minutes fast",
    "we should fix the broken handle on the cupboard",
    "thank you for helping me with the shopping",
];

/// Fewer utterances than this give too few frames for a transform.
pub const MIN_RECORDINGS: usize = 5;

/// Each recording is also learnt with room noise added at these
/// signal-to-noise ratios (dB): a person enrols once, in a quiet room, and
/// speaks to the chair beside a kettle, a television, its own motors.
/// The noise is pink (most of its energy low, as in rooms), not the white
/// noise `benches/voice_commands.rs` tests with; the ratios were chosen on
/// that bench's tuning set (one copy at 6 or 12 dB, or two at 10 and 20).
pub const NOISY_COPIES_SNR_DB: [f64; 2] = [10.0, 20.0];

/// `samples` with pink noise added `snr_db` below their RMS level
/// (deterministic for a `seed`; Paul Kellet's filter of Gaussian noise).
pub fn with_room_noise(samples: &[i16], snr_db: f64, seed: u64) -> Vec<i16> {
    let mut normal = super::standard_normal(seed ^ 0xD1B5_4A32_D192_ED03);
    let mut b = [0.0f64; 7];
    let pink: Vec<f64> = samples
        .iter()
        .map(|_| {
            let w = normal();
            b[0] = 0.99886 * b[0] + w * 0.055_517_9;
            b[1] = 0.99332 * b[1] + w * 0.075_075_9;
            b[2] = 0.96900 * b[2] + w * 0.153_852;
            b[3] = 0.86650 * b[3] + w * 0.310_485_6;
            b[4] = 0.55000 * b[4] + w * 0.532_952_2;
            b[5] = -0.7616 * b[5] - w * 0.016_898;
            let p = b[..6].iter().sum::<f64>() + b[6] + w * 0.5362;
            b[6] = w * 0.115_926;
            p
        })
        .collect();
    let rms = |v: &mut dyn Iterator<Item = f64>| {
        let (sum, n) = v.fold((0.0, 0usize), |(s, n), x| (s + x * x, n + 1));
        (sum / n.max(1) as f64).sqrt()
    };
    let speech_rms = rms(&mut samples.iter().map(|&v| v as f64));
    let pink_rms = rms(&mut pink.iter().copied());
    if pink_rms == 0.0 {
        return samples.to_vec();
    }
    let gain = speech_rms / 10f64.powf(snr_db / 20.0) / pink_rms;
    samples
        .iter()
        .zip(&pink)
        .map(|(&v, &p)| super::to_i16_sample(v as f64 + gain * p))
        .collect()
}

/// One recorded sentence: 16 kHz mono samples and what was said.
#[derive(Debug, Clone, PartialEq)]
pub struct Recording {
    /// Where it came from (named in errors and in the report).
    pub name: String,
    pub samples: Vec<i16>,
    pub text: String,
}

/// SphinxTrain's `mixture_weights` (an s3 file: header, byte-order
/// magic, dimensions senones × streams × densities, float32 weights) from
/// PocketSphinx's `sendump` (a header of length-prefixed strings, then for
/// each stream and density one byte per senone: `q`, the weight being
/// `1.0001^-(q << 10)`). Only the unclustered 8-bit form (`cluster_count
/// 0`) exists in Debian's models; others are refused by name.
pub fn mixture_weights_from_sendump(sendump: &[u8]) -> Result<Vec<u8>, String> {
    let mut at = 0usize;
    let int = |at: &mut usize, what: &str| -> Result<i32, String> {
        let b = sendump
            .get(*at..*at + 4)
            .ok_or_else(|| format!("sendump: ends inside {what} at byte {at}"))?;
        *at += 4;
        Ok(i32::from_le_bytes([b[0], b[1], b[2], b[3]]))
    };
    let (mut streams, mut clusters) = (None, 0i32);
    loop {
        let n = int(&mut at, "a header length")?;
        if n == 0 {
            break;
        }
        if !(1..=4096).contains(&n) {
            return Err(format!(
                "sendump: header string of length {n} at byte {} (a big-endian or damaged file?)",
                at - 4
            ));
        }
        let s = sendump
            .get(at..at + n as usize)
            .ok_or_else(|| format!("sendump: ends inside the header at byte {at}"))?;
        at += n as usize;
        let text = String::from_utf8_lossy(s.strip_suffix(&[0]).unwrap_or(s)).to_string();
        let mut kv = text.split_whitespace();
        match (kv.next(), kv.next().and_then(|v| v.parse::<i32>().ok())) {
            (Some("feature_count"), Some(v)) => streams = Some(v),
            (Some("cluster_count"), Some(v)) => clusters = v,
            _ => {}
        }
    }
    if clusters != 0 {
        return Err(format!(
            "sendump: cluster_count {clusters}: only unclustered weights can be converted"
        ));
    }
    let streams = streams.ok_or("sendump: no feature_count in the header")?;
    let densities = int(&mut at, "the number of densities")?;
    let senones = int(&mut at, "the number of senones")?;
    let ok = |v: i32, max: i32| (1..=max).contains(&v);
    if !ok(streams, 8) || !ok(densities, 1 << 12) || !ok(senones, 1 << 20) {
        return Err(format!(
            "sendump: {streams} streams × {densities} densities × {senones} senones is not a model"
        ));
    }
    let (f, d, s) = (streams as usize, densities as usize, senones as usize);
    let body = sendump
        .get(at..)
        .filter(|b| b.len() == f * d * s)
        .ok_or_else(|| {
            format!(
                "sendump: {} bytes of weights, {f} × {d} × {s} = {} expected",
                sendump.len() - at.min(sendump.len()),
                f * d * s
            )
        })?;
    let step = 1024.0 * 1.0001f64.ln();
    let mut out = Vec::with_capacity(64 + 4 * f * d * s);
    let mut header = b"s3\nversion 1.0\n".to_vec();
    // the data on a 4-byte boundary, as SphinxTrain writes it
    let pad = (4 - (header.len() + b"endhdr\n".len()) % 4) % 4;
    header.extend(std::iter::repeat_n(b' ', pad));
    header.extend_from_slice(b"endhdr\n");
    out.extend_from_slice(&header);
    out.extend_from_slice(&0x1122_3344i32.to_le_bytes());
    for v in [s, f, d, s * f * d] {
        out.extend_from_slice(&(v as u32).to_le_bytes());
    }
    let mut weights = vec![0f64; d];
    for sen in 0..s {
        for stream in 0..f {
            for (dens, w) in weights.iter_mut().enumerate() {
                let q = body[(stream * d + dens) * s + sen];
                *w = (-(q as f64) * step).exp();
            }
            let total: f64 = weights.iter().sum();
            for w in &weights {
                out.extend_from_slice(&((w / total) as f32).to_le_bytes());
            }
        }
    }
    Ok(out)
}

/// The words of `text` the dictionary lacks (they cannot be aligned).
pub fn unknown_words(text: &str, dict: &Dictionary) -> Vec<String> {
    text.split_whitespace()
        .map(str::to_lowercase)
        .filter(|w| !dict.contains(w))
        .collect()
}

/// The `feat.params` options `bw` needs as well (`-feat`, `-svspec`,
/// `-cmn`, `-agc`) and the model type (`-model`: ptm, semi, cont).
fn feature_params(text: &str) -> Vec<(String, String)> {
    text.lines()
        .filter_map(|l| {
            let mut kv = l.split_whitespace();
            Some((kv.next()?.to_string(), kv.next()?.to_string()))
        })
        .collect()
}

/// Where the tools are (Debian 12: `sphinxtrain`, `sphinxbase-utils`,
/// `pocketsphinx`).
#[derive(Debug, Clone)]
pub struct Tools {
    pub sphinx_fe: PathBuf,
    pub bw: PathBuf,
    pub map_adapt: PathBuf,
    pub mdef_convert: PathBuf,
}

impl Tools {
    /// Debian's paths; a missing tool is named with its package.
    pub fn debian() -> Result<Tools, String> {
        let t = Tools {
            sphinx_fe: PathBuf::from("/usr/bin/sphinx_fe"),
            bw: PathBuf::from("/usr/lib/sphinxtrain/bw"),
            map_adapt: PathBuf::from("/usr/lib/sphinxtrain/map_adapt"),
            mdef_convert: PathBuf::from("/usr/bin/pocketsphinx_mdef_convert"),
        };
        for (p, package) in [
            (&t.sphinx_fe, "sphinxbase-utils"),
            (&t.bw, "sphinxtrain"),
            (&t.map_adapt, "sphinxtrain"),
            (&t.mdef_convert, "pocketsphinx"),
        ] {
            if !p.exists() {
                return Err(format!(
                    "{} not found (Debian: apt-get install {package})",
                    p.display()
                ));
            }
        }
        Ok(t)
    }
}

/// The model to adapt: its directory, and the dictionary the recordings'
/// words are read with.
#[derive(Debug, Clone, Copy)]
pub struct Model<'a> {
    pub hmm: &'a Path,
    pub dict_path: &'a Path,
    pub dict: &'a Dictionary,
}

/// What an enrollment made.
#[derive(Debug, Clone, PartialEq)]
pub struct Enrolled {
    /// Recordings used, and those `bw` could not align to their text
    /// (said differently, cut short, too noisy), by name; a copy with
    /// room noise is named "NAME (with noise at N dB)".
    pub used: usize,
    /// Noisy copies used (of `recordings` × [`NOISY_COPIES_SNR_DB`]).
    pub noisy_used: usize,
    pub not_aligned: Vec<String>,
    /// Seconds of speech.
    pub seconds: f64,
}

fn run(cmd: &mut Command, what: &str, log: &Path) -> Result<(), String> {
    let out = cmd
        .output()
        .map_err(|e| format!("{what}: cannot start {:?}: {e}", cmd.get_program()))?;
    let mut text = out.stdout;
    text.extend_from_slice(&out.stderr);
    if let Err(e) = std::fs::write(log, &text) {
        tracing::warn!(log = %log.display(), error = %e, "voice enroll: the tool's log cannot be written");
    }
    if !out.status.success() {
        let tail: String = String::from_utf8_lossy(&text)
            .lines()
            .rev()
            .take(3)
            .collect::<Vec<_>>()
            .join(" / ");
        return Err(format!(
            "{what} failed ({}; log {}): {tail}",
            out.status,
            log.display()
        ));
    }
    Ok(())
}

/// Makes the model in `hmm` adapted to the speaker of `recordings` as the
/// directory `out` (replaced whole if it exists), working in `work` (left
/// there: the tools' logs).
/// `samples` get the recogniser's noise floor first, so that the
/// adaptation hears what the recogniser will hear.
pub fn enroll(
    tools: &Tools,
    model: &Model,
    recordings: &[Recording],
    work: &Path,
    out: &Path,
    noise_floor: impl Fn(&[i16]) -> Vec<i16>,
) -> Result<Enrolled, String> {
    let Model {
        hmm,
        dict_path,
        dict,
    } = *model;
    if recordings.len() < MIN_RECORDINGS {
        return Err(format!(
            "{} recordings: at least {MIN_RECORDINGS} are needed (about {} sentences make a good transform)",
            recordings.len(),
            SENTENCES.len()
        ));
    }
    for r in recordings {
        let unknown = unknown_words(&r.text, dict);
        if !unknown.is_empty() {
            return Err(format!(
                "{}: not in the pronunciation dictionary {}: {}",
                r.name,
                dict_path.display(),
                unknown.join(", ")
            ));
        }
        if r.text.split_whitespace().next().is_none() {
            return Err(format!("{}: its text is empty", r.name));
        }
        if r.samples.len() < 16_000 / 2 {
            return Err(format!(
                "{}: {:.2} s of audio, too short for a sentence",
                r.name,
                r.samples.len() as f64 / 16_000.0
            ));
        }
    }
    let io = |e: std::io::Error, p: &Path| format!("{}: {e}", p.display());
    std::fs::create_dir_all(work).map_err(|e| io(e, work))?;
    // the model as bw reads it: text mdef, mixture_weights
    let bw_model = work.join("model");
    std::fs::create_dir_all(&bw_model).map_err(|e| io(e, &bw_model))?;
    let feat_path = hmm.join("feat.params");
    let feat_text = std::fs::read_to_string(&feat_path).map_err(|e| io(e, &feat_path))?;
    let params = feature_params(&feat_text);
    let param = |k: &str, default: &str| {
        params
            .iter()
            .find(|(key, _)| key == k)
            .map(|(_, v)| v.clone())
            .unwrap_or_else(|| default.to_string())
    };
    let ts2cb = match param("-model", "ptm").as_str() {
        "ptm" => ".ptm.",
        "semi" => ".semi.",
        "cont" => ".cont.",
        other => return Err(format!("{}: model type {other:?}", feat_path.display())),
    };
    let mdef = bw_model.join("mdef.txt");
    run(
        Command::new(&tools.mdef_convert)
            .arg("-text")
            .arg(hmm.join("mdef"))
            .arg(&mdef),
        "converting the model definition",
        &work.join("mdef_convert.log"),
    )?;
    let weights = hmm.join("mixture_weights");
    let weights = if weights.exists() {
        weights
    } else {
        let sendump = hmm.join("sendump");
        let bytes = std::fs::read(&sendump).map_err(|e| io(e, &sendump))?;
        let converted = mixture_weights_from_sendump(&bytes)?;
        let path = bw_model.join("mixture_weights");
        std::fs::write(&path, converted).map_err(|e| io(e, &path))?;
        path
    };
    for f in ["means", "variances", "transition_matrices", "noisedict"] {
        let (from, to) = (hmm.join(f), bw_model.join(f));
        std::fs::copy(&from, &to).map_err(|e| io(e, &from))?;
    }
    std::fs::copy(&feat_path, bw_model.join("feat.params")).map_err(|e| io(e, &feat_path))?;
    // the speech, as 16 kHz WAVs, and the transcription
    // u0000…: the recordings as read; then each again with room noise
    let mut utterances: Vec<(String, Vec<i16>, &str)> = recordings
        .iter()
        .map(|r| (r.name.clone(), noise_floor(&r.samples), r.text.as_str()))
        .collect();
    for (k, snr_db) in NOISY_COPIES_SNR_DB.iter().enumerate() {
        for (i, r) in recordings.iter().enumerate() {
            let seed = (k * recordings.len() + i) as u64;
            utterances.push((
                format!("{} (with noise at {snr_db} dB)", r.name),
                with_room_noise(&noise_floor(&r.samples), *snr_db, seed),
                r.text.as_str(),
            ));
        }
    }
    let (mut ids, mut trans) = (String::new(), String::new());
    for (i, (_, samples, text)) in utterances.iter().enumerate() {
        let id = format!("u{i:04}");
        let wav = work.join(format!("{id}.wav"));
        std::fs::write(&wav, super::wav::mono_16k_wav(samples)).map_err(|e| io(e, &wav))?;
        ids.push_str(&format!("{id}\n"));
        let words: Vec<String> = text.split_whitespace().map(str::to_lowercase).collect();
        trans.push_str(&format!("<s> {} </s> ({id})\n", words.join(" ")));
    }
    let seconds = recordings
        .iter()
        .map(|r| r.samples.len() as f64 / 16_000.0)
        .sum();
    let (ids_path, trans_path) = (work.join("ids"), work.join("transcription"));
    std::fs::write(&ids_path, ids).map_err(|e| io(e, &ids_path))?;
    std::fs::write(&trans_path, trans).map_err(|e| io(e, &trans_path))?;
    run(
        Command::new(&tools.sphinx_fe)
            .arg("-argfile")
            .arg(bw_model.join("feat.params"))
            .args(["-samprate", "16000", "-c"])
            .arg(&ids_path)
            .arg("-di")
            .arg(work)
            .arg("-do")
            .arg(work)
            .args(["-ei", "wav", "-eo", "mfc", "-mswav", "yes"]),
        "sphinx_fe (features)",
        &work.join("sphinx_fe.log"),
    )?;
    let bw_log = work.join("bw.log");
    run(
        Command::new(&tools.bw)
            .arg("-hmmdir")
            .arg(&bw_model)
            .arg("-moddeffn")
            .arg(&mdef)
            .args(["-ts2cbfn", ts2cb])
            .args(["-feat", &param("-feat", "1s_c_d_dd")])
            .args(["-svspec", &param("-svspec", "0-12/13-25/26-38")])
            .args(["-cmn", &param("-cmn", "batch")])
            .args(["-agc", &param("-agc", "none")])
            .arg("-dictfn")
            .arg(dict_path)
            .arg("-fdictfn")
            .arg(bw_model.join("noisedict"))
            .arg("-ctlfn")
            .arg(&ids_path)
            .arg("-lsnfn")
            .arg(&trans_path)
            .arg("-cepdir")
            .arg(work)
            .arg("-accumdir")
            .arg(work),
        "bw (statistics)",
        &bw_log,
    )?;
    // "u0003 ignored": an utterance bw could not align to its text
    // (without its log, which recordings bw skipped would be unknown)
    let log = std::fs::read_to_string(&bw_log).map_err(|e| io(e, &bw_log))?;
    let skipped: Vec<usize> = log
        .lines()
        .filter_map(|l| l.trim().strip_suffix(" ignored"))
        .filter_map(|l| l.rsplit(' ').next())
        .filter_map(|id| id.strip_prefix('u')?.parse::<usize>().ok())
        .filter(|&i| i < utterances.len())
        .collect();
    let not_aligned: Vec<String> = skipped.iter().map(|&i| utterances[i].0.clone()).collect();
    let clean_skipped = skipped.iter().filter(|&&i| i < recordings.len()).count();
    let used = recordings.len() - clean_skipped;
    let noisy_used =
        (utterances.len() - recordings.len()).saturating_sub(skipped.len() - clean_skipped);
    if used < MIN_RECORDINGS {
        return Err(format!(
            "only {used} of {} recordings match their text (not aligned: {}): \
             were the sentences read as written?",
            recordings.len(),
            not_aligned.join(", ")
        ));
    }
    // the adapted model: map_adapt's four files beside the original's
    // definition, features and fillers (as the recogniser reads a model)
    let adapted = work.join("adapted");
    std::fs::create_dir_all(&adapted).map_err(|e| io(e, &adapted))?;
    run(
        Command::new(&tools.map_adapt)
            .arg("-moddeffn")
            .arg(&mdef)
            .args(["-ts2cbfn", ts2cb])
            .arg("-meanfn")
            .arg(bw_model.join("means"))
            .arg("-varfn")
            .arg(bw_model.join("variances"))
            .arg("-mixwfn")
            .arg(&weights)
            .arg("-tmatfn")
            .arg(bw_model.join("transition_matrices"))
            .arg("-accumdir")
            .arg(work)
            .arg("-mapmeanfn")
            .arg(adapted.join("means"))
            .arg("-mapvarfn")
            .arg(adapted.join("variances"))
            .arg("-mapmixwfn")
            .arg(adapted.join("mixture_weights"))
            .arg("-maptmatfn")
            .arg(adapted.join("transition_matrices")),
        "map_adapt (the adapted model)",
        &work.join("map_adapt.log"),
    )?;
    for f in ["mdef", "feat.params", "noisedict"] {
        let (from, to) = (hmm.join(f), adapted.join(f));
        std::fs::copy(&from, &to).map_err(|e| io(e, &from))?;
    }
    // into place: a sibling first, then one rename (a daemon reading the
    // old model never sees half of the new one)
    let parent = out
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    std::fs::create_dir_all(parent).map_err(|e| io(e, parent))?;
    // ".NAME.new", ".NAME.old" beside `out`
    let sibling = |suffix: &str| {
        let name = out.file_name().map(|n| n.to_string_lossy());
        parent.join(format!(".{}.{suffix}", name.unwrap_or_default()))
    };
    let staging = sibling("new");
    // leftovers of an interrupted enrollment (usually none); one that
    // cannot go makes the copy or rename below fail with its name
    let _ = std::fs::remove_dir_all(&staging);
    std::fs::create_dir_all(&staging).map_err(|e| io(e, &staging))?;
    for e in std::fs::read_dir(&adapted).map_err(|e| io(e, &adapted))? {
        let from = e.map_err(|e| io(e, &adapted))?.path();
        let to = staging.join(from.file_name().unwrap_or_default());
        std::fs::copy(&from, &to).map_err(|e| io(e, &from))?;
    }
    if out.exists() {
        let old = sibling("old");
        let _ = std::fs::remove_dir_all(&old);
        std::fs::rename(out, &old).map_err(|e| io(e, out))?;
        std::fs::rename(&staging, out).map_err(|e| io(e, out))?;
        if let Err(e) = std::fs::remove_dir_all(&old) {
            tracing::warn!(old = %old.display(), error = %e, "voice enroll: the replaced model is left beside the new one");
        }
    } else {
        std::fs::rename(&staging, out).map_err(|e| io(e, out))?;
    }
    Ok(Enrolled {
        used,
        noisy_used,
        not_aligned,
        seconds,
    })
}

#[cfg(test)]
#[path = "enroll_tests.rs"]
mod tests;
