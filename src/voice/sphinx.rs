//! The few PocketSphinx calls opennav needs, behind a safe [`Recognizer`]:
//! a decoder configured with an acoustic model and a dictionary, searching
//! a JSGF grammar; one utterance of 16 kHz mono 16-bit samples in, the
//! best hypothesis, its score and its posterior probability out.

use std::ffi::{c_char, c_int, CStr, CString};
use std::path::{Path, PathBuf};

#[repr(C)]
struct CmdLn {
    _private: [u8; 0],
}
#[repr(C)]
struct ArgT {
    _private: [u8; 0],
}
#[repr(C)]
struct Decoder {
    _private: [u8; 0],
}
#[repr(C)]
struct LogMath {
    _private: [u8; 0],
}
#[repr(C)]
struct Seg {
    _private: [u8; 0],
}
#[repr(C)]
struct NBest {
    _private: [u8; 0],
}

extern "C" {
    fn ps_args() -> *const ArgT;
    fn cmd_ln_init(inout: *mut CmdLn, defn: *const ArgT, strict: i32, ...) -> *mut CmdLn;
    fn cmd_ln_free_r(cmdln: *mut CmdLn) -> c_int;
    fn ps_init(config: *mut CmdLn) -> *mut Decoder;
    fn ps_free(ps: *mut Decoder) -> c_int;
    fn ps_set_jsgf_string(ps: *mut Decoder, name: *const c_char, jsgf: *const c_char) -> c_int;
    fn ps_set_search(ps: *mut Decoder, name: *const c_char) -> c_int;
    fn ps_set_lm_file(ps: *mut Decoder, name: *const c_char, path: *const c_char) -> c_int;
    fn ps_set_allphone_file(ps: *mut Decoder, name: *const c_char, path: *const c_char) -> c_int;
    fn ps_start_stream(ps: *mut Decoder) -> c_int;
    fn ps_start_utt(ps: *mut Decoder) -> c_int;
    fn ps_process_raw(
        ps: *mut Decoder,
        data: *const i16,
        n_samples: usize,
        no_search: c_int,
        full_utt: c_int,
    ) -> c_int;
    fn ps_end_utt(ps: *mut Decoder) -> c_int;
    fn ps_get_hyp(ps: *mut Decoder, out_best_score: *mut i32) -> *const c_char;
    fn ps_get_prob(ps: *mut Decoder) -> i32;
    fn ps_get_logmath(ps: *mut Decoder) -> *mut LogMath;
    fn logmath_exp(lmath: *mut LogMath, logb_p: c_int) -> f64;
    fn ps_seg_iter(ps: *mut Decoder) -> *mut Seg;
    fn ps_seg_next(seg: *mut Seg) -> *mut Seg;
    fn ps_seg_prob(seg: *mut Seg, ascr: *mut i32, lscr: *mut i32, lback: *mut i32) -> i32;
    fn ps_nbest(ps: *mut Decoder) -> *mut NBest;
    fn ps_nbest_next(nbest: *mut NBest) -> *mut NBest;
    fn ps_nbest_hyp(nbest: *mut NBest, out_score: *mut i32) -> *const c_char;
    fn ps_nbest_free(nbest: *mut NBest);
    fn ps_add_word(
        ps: *mut Decoder,
        word: *const c_char,
        phones: *const c_char,
        update: c_int,
    ) -> c_int;
    fn ps_get_n_frames(ps: *mut Decoder) -> c_int;
    fn ps_seg_word(seg: *mut Seg) -> *const c_char;
    fn ps_seg_frames(seg: *mut Seg, out_sf: *mut c_int, out_ef: *mut c_int);
}

/// One pass's best path.
struct Pass {
    text: String,
    score: i32,
    probability: f64,
    inner_silence_frames: i32,
    word_frames: i32,
}

/// A segment's word is silence or a filler (`<sil>`, `[NOISE]`, `++UM++`).
fn filler(word: &str) -> bool {
    word.starts_with('<') || word.starts_with('[') || word.starts_with('+') || word == "(NULL)"
}

/// A path's segments (word, frames) → the frames its words take (speech,
/// not silence or fillers).
fn word_frames(segments: &[(String, i32)]) -> i32 {
    segments
        .iter()
        .filter(|(w, _)| !filler(w))
        .map(|(_, f)| *f)
        .sum()
}

/// A path's segments (word, frames) → the frames of silence and fillers
/// between its first and last word.
fn inner_silence(segments: &[(String, i32)]) -> i32 {
    let words: Vec<usize> = segments
        .iter()
        .enumerate()
        .filter(|(_, (w, _))| !filler(w))
        .map(|(i, _)| i)
        .collect();
    match (words.first(), words.last()) {
        (Some(&a), Some(&b)) => segments[a..=b]
            .iter()
            .filter(|(w, _)| filler(w))
            .map(|(_, f)| *f)
            .sum(),
        _ => 0,
    }
}

/// Where the models are (Debian's `pocketsphinx-en-us`).
#[derive(Debug, Clone, PartialEq)]
pub struct ModelPaths {
    /// The acoustic model directory (`-hmm`).
    pub hmm: PathBuf,
    /// The pronunciation dictionary (`-dict`).
    pub dict: PathBuf,
    /// A general English language model: the same audio decoded without
    /// the grammar says whether the grammar's words were really spoken.
    pub english_lm: PathBuf,
    /// A phonetic language model: the same audio decoded as free phones
    /// says how much better than the grammar anything at all explains it.
    pub phone_lm: PathBuf,
}

impl ModelPaths {
    /// Debian 12's US English model.
    pub fn debian_en_us() -> ModelPaths {
        let base = Path::new("/usr/share/pocketsphinx/model/en-us");
        ModelPaths {
            hmm: base.join("en-us"),
            dict: base.join("cmudict-en-us.dict"),
            english_lm: base.join("en-us.lm.bin"),
            phone_lm: base.join("en-us-phone.lm.bin"),
        }
    }
}

#[derive(Debug, thiserror::Error)]
pub enum SphinxError {
    #[error("speech model {path}: {reason}")]
    Model { path: String, reason: String },
    #[error("speech recogniser: {0}")]
    Decoder(String),
    #[error("grammar: {0}")]
    Grammar(String),
}

/// One decoded utterance.
#[derive(Debug, Clone, PartialEq)]
pub struct Hypothesis {
    /// The words heard (lower case, as the grammar spells them).
    pub text: String,
    /// The path's acoustic score (log domain, larger is better; without
    /// language or grammar weights).
    pub score: i32,
    /// The posterior probability of the hypothesis, 0..1.
    pub probability: f64,
    /// Frames of silence or filler the path put between its first and
    /// last word (speech it skipped: outside the grammar).
    pub inner_silence_frames: i32,
    /// What a general English decode of the same audio heard (free
    /// words, no grammar): agreement with `text` is the confidence.
    pub english: Option<String>,
    /// The acoustic score of the best free phone sequence (no words, no
    /// grammar): how well anything at all explains the audio.
    pub phone_score: Option<i32>,
    /// The grammar's next-best readings of the same audio, best first (a
    /// "stop" among them is not ignored).
    pub alternatives: Vec<String>,
    /// The grammar's ten best paths as they come (one reading may be
    /// several paths): how many agree with the best is a confidence.
    pub top_paths: Vec<String>,
    /// The utterance's length in 10 ms frames.
    pub frames: i32,
    /// The frames the path's words take (without silence and fillers):
    /// the speech, however much silence the cut left around it.
    pub word_frames: i32,
}

/// The best reading of an utterance under one named search.
#[derive(Debug, Clone, PartialEq)]
pub struct Reading {
    pub text: String,
    /// The best path's acoustic score (log domain, larger is better).
    pub score: i32,
    pub frames: i32,
}

/// A PocketSphinx decoder searching one JSGF grammar.
pub struct Recognizer {
    config: *mut CmdLn,
    ps: *mut Decoder,
}

// the decoder is used from one thread at a time (it is moved, never shared)
unsafe impl Send for Recognizer {}

fn cstring(what: &str, s: &str) -> Result<CString, SphinxError> {
    CString::new(s).map_err(|_| SphinxError::Decoder(format!("{what} contains a NUL byte")))
}

impl Recognizer {
    /// A decoder on `models` searching `jsgf` (the grammar's text).
    pub fn new(models: &ModelPaths, jsgf: &str) -> Result<Recognizer, SphinxError> {
        Self::with_pronunciations(models, jsgf, &[])
    }

    /// A decoder on `models` that also knows `extra` readings (`word(N)`,
    /// its phones) before it compiles `jsgf`.
    pub fn with_pronunciations(
        models: &ModelPaths,
        jsgf: &str,
        extra: &[(String, String)],
    ) -> Result<Recognizer, SphinxError> {
        for p in [
            &models.hmm,
            &models.dict,
            &models.english_lm,
            &models.phone_lm,
        ] {
            if !p.exists() {
                return Err(SphinxError::Model {
                    path: p.display().to_string(),
                    reason: "not found (Debian: apt-get install pocketsphinx-en-us)".into(),
                });
            }
        }
        let path = |p: &Path| cstring("a model path", &p.display().to_string());
        let (hmm, dict) = (path(&models.hmm)?, path(&models.dict)?);
        let k = |s: &str| cstring("an option", s);
        let (k_hmm, k_dict, k_log, v_log, k_bs, v_bs, k_ci) = (
            k("-hmm")?,
            k("-dict")?,
            k("-logfn")?,
            k("/dev/null")?,
            k("-bestpath")?,
            k("yes")?,
            // the free phone pass with context-independent phones: as
            // fast as the grammar's (with triphones it takes seconds)
            k("-allphone_ci")?,
        );
        // SAFETY: the variadic list is (name, value) C strings that live
        // until the call returns, terminated by NULL, as cmd_ln_init reads it
        let config = unsafe {
            cmd_ln_init(
                std::ptr::null_mut(),
                ps_args(),
                1,
                k_hmm.as_ptr(),
                hmm.as_ptr(),
                k_dict.as_ptr(),
                dict.as_ptr(),
                k_log.as_ptr(),
                v_log.as_ptr(),
                k_bs.as_ptr(),
                v_bs.as_ptr(),
                k_ci.as_ptr(),
                v_bs.as_ptr(),
                std::ptr::null::<c_char>(),
            )
        };
        if config.is_null() {
            return Err(SphinxError::Decoder("the configuration was refused".into()));
        }
        // SAFETY: a valid configuration
        let ps = unsafe { ps_init(config) };
        if ps.is_null() {
            // SAFETY: ours, not used again
            unsafe { cmd_ln_free_r(config) };
            return Err(SphinxError::Decoder(format!(
                "cannot load the models in {}",
                models.hmm.display()
            )));
        }
        let mut r = Recognizer { config, ps };
        for (word, phones) in extra {
            let (w, p) = (cstring("a word", word)?, cstring("phones", phones)?);
            // SAFETY: valid decoder and NUL-terminated strings
            if unsafe { ps_add_word(r.ps, w.as_ptr(), p.as_ptr(), 0) } < 0 {
                return Err(SphinxError::Model {
                    path: models.dict.display().to_string(),
                    reason: format!("the reading {word} = {phones} was refused (a phone the acoustic model lacks?)"),
                });
            }
        }
        let (name, lm) = (
            cstring("a search name", "english")?,
            path(&models.english_lm)?,
        );
        // SAFETY: valid decoder and NUL-terminated strings
        if unsafe { ps_set_lm_file(r.ps, name.as_ptr(), lm.as_ptr()) } != 0 {
            return Err(SphinxError::Model {
                path: models.english_lm.display().to_string(),
                reason: "PocketSphinx could not load it".into(),
            });
        }
        let (name, phones) = (cstring("a search name", "phones")?, path(&models.phone_lm)?);
        // SAFETY: valid decoder and NUL-terminated strings
        if unsafe { ps_set_allphone_file(r.ps, name.as_ptr(), phones.as_ptr()) } != 0 {
            return Err(SphinxError::Model {
                path: models.phone_lm.display().to_string(),
                reason: "PocketSphinx could not load it as a phonetic model".into(),
            });
        }
        r.set_grammar(jsgf)?;
        Ok(r)
    }

    /// Replaces the grammar (the active vocabulary changed).
    pub fn set_grammar(&mut self, jsgf: &str) -> Result<(), SphinxError> {
        let name = cstring("a search name", "opennav")?;
        let text = cstring("the grammar", jsgf)?;
        // SAFETY: valid decoder and NUL-terminated strings
        let rc = unsafe { ps_set_jsgf_string(self.ps, name.as_ptr(), text.as_ptr()) };
        if rc != 0 {
            return Err(SphinxError::Grammar(
                "PocketSphinx refused it (a syntax error, or a word not in the dictionary)".into(),
            ));
        }
        self.select("opennav")
    }

    /// Adds another grammar under `name` (searched only by [`Self::read`]).
    pub fn add_grammar(&mut self, name: &str, jsgf: &str) -> Result<(), SphinxError> {
        if name == "opennav" || name == "english" || name == "phones" {
            return Err(SphinxError::Grammar(format!(
                "{name:?} is a reserved search name"
            )));
        }
        let n = cstring("a search name", name)?;
        let text = cstring("the grammar", jsgf)?;
        // SAFETY: valid decoder and NUL-terminated strings
        let rc = unsafe { ps_set_jsgf_string(self.ps, n.as_ptr(), text.as_ptr()) };
        if rc != 0 {
            return Err(SphinxError::Grammar(format!(
                "PocketSphinx refused the grammar {name:?}"
            )));
        }
        self.select("opennav")
    }

    /// The best reading of `samples` under the grammar added as `name`.
    pub fn read(&mut self, name: &str, samples: &[i16]) -> Result<Option<Reading>, SphinxError> {
        self.select(name)?;
        let out = self.pass(samples);
        self.select("opennav")?;
        // SAFETY: valid decoder
        let frames = unsafe { ps_get_n_frames(self.ps) };
        Ok(out?.map(|p| Reading {
            text: p.text,
            score: p.score,
            frames,
        }))
    }

    fn select(&mut self, search: &str) -> Result<(), SphinxError> {
        let name = cstring("a search name", search)?;
        // SAFETY: valid decoder, NUL-terminated name
        if unsafe { ps_set_search(self.ps, name.as_ptr()) } != 0 {
            return Err(SphinxError::Decoder(format!(
                "cannot select the {search} search"
            )));
        }
        Ok(())
    }

    /// One pass over the utterance with the selected search: the text and
    /// score of its best path, and its posterior.
    fn pass(&mut self, samples: &[i16]) -> Result<Option<Pass>, SphinxError> {
        // SAFETY: valid decoder; the samples outlive the call
        unsafe {
            // a new stream: the front end's noise estimate starts from this
            // audio, not from whatever was decoded before it, so each pass
            // over an utterance (grammar, English, rival) and each utterance
            // is heard the same way whatever came before
            if ps_start_stream(self.ps) < 0 {
                return Err(SphinxError::Decoder("cannot start a stream".into()));
            }
            if ps_start_utt(self.ps) < 0 {
                return Err(SphinxError::Decoder("cannot start an utterance".into()));
            }
            if ps_process_raw(self.ps, samples.as_ptr(), samples.len(), 0, 1) < 0 {
                ps_end_utt(self.ps);
                return Err(SphinxError::Decoder("cannot process the audio".into()));
            }
            if ps_end_utt(self.ps) < 0 {
                return Err(SphinxError::Decoder("cannot end the utterance".into()));
            }
            let mut path_score = 0i32;
            let hyp = ps_get_hyp(self.ps, &mut path_score);
            if hyp.is_null() {
                return Ok(None);
            }
            let text = CStr::from_ptr(hyp).to_string_lossy().trim().to_string();
            // the acoustic part of the best path: its segments' scores
            let mut score = 0i64;
            let mut segments: Vec<(String, i32)> = Vec::new();
            let mut seg = ps_seg_iter(self.ps);
            while !seg.is_null() {
                let (mut ascr, mut lscr, mut lback) = (0i32, 0i32, 0i32);
                ps_seg_prob(seg, &mut ascr, &mut lscr, &mut lback);
                score += ascr as i64;
                let (mut sf, mut ef) = (0 as c_int, 0 as c_int);
                ps_seg_frames(seg, &mut sf, &mut ef);
                let w = ps_seg_word(seg);
                let word = if w.is_null() {
                    String::new()
                } else {
                    CStr::from_ptr(w).to_string_lossy().into_owned()
                };
                segments.push((word, (ef - sf + 1).max(0)));
                // ps_seg_next frees the iterator at the end
                seg = ps_seg_next(seg);
            }
            let score = score.clamp(i32::MIN as i64, i32::MAX as i64) as i32;
            let prob = ps_get_prob(self.ps);
            let lmath = ps_get_logmath(self.ps);
            let probability = if lmath.is_null() {
                0.0
            } else {
                logmath_exp(lmath, prob).clamp(0.0, 1.0)
            };
            Ok(Some(Pass {
                text,
                score,
                probability,
                inner_silence_frames: inner_silence(&segments),
                word_frames: word_frames(&segments),
            }))
        }
    }

    /// The last utterance's best paths under the current search, best
    /// first: the first `top` paths as they come (a reading found by
    /// several paths counts each time), and up to `distinct` different
    /// readings (walking at most `MAX_PATHS` paths).
    fn nbest(&mut self, top: usize, distinct: usize) -> (Vec<String>, Vec<String>) {
        const MAX_PATHS: usize = 200;
        let (mut paths, mut readings): (Vec<String>, Vec<String>) = (Vec::new(), Vec::new());
        // SAFETY: valid decoder after an utterance; the iterator is freed
        // by ps_nbest_next at its end, or here when we stop early
        unsafe {
            let mut it = ps_nbest(self.ps);
            let mut walked = 0;
            while !it.is_null()
                && (paths.len() < top || readings.len() < distinct)
                && walked < MAX_PATHS
            {
                walked += 1;
                let mut score = 0i32;
                let h = ps_nbest_hyp(it, &mut score);
                if !h.is_null() {
                    let t = CStr::from_ptr(h).to_string_lossy().trim().to_string();
                    if !t.is_empty() {
                        if paths.len() < top {
                            paths.push(t.clone());
                        }
                        if readings.len() < distinct && !readings.contains(&t) {
                            readings.push(t);
                        }
                    }
                }
                it = ps_nbest_next(it);
            }
            if !it.is_null() {
                ps_nbest_free(it);
            }
        }
        (paths, readings)
    }

    /// Decodes one whole utterance (16 kHz mono samples) with the grammar,
    /// and again as free phones for the comparison; None when nothing in
    /// the grammar was heard.
    pub fn decode(&mut self, samples: &[i16]) -> Result<Option<Hypothesis>, SphinxError> {
        self.select("opennav")?;
        let Some(Pass {
            text,
            score,
            probability,
            inner_silence_frames,
            word_frames,
        }) = self.pass(samples)?
        else {
            return Ok(None);
        };
        if text.is_empty() {
            return Ok(None);
        }
        let (top_paths, readings) = self.nbest(10, 10);
        let alternatives: Vec<String> = readings.into_iter().filter(|t| *t != text).collect();
        // SAFETY: valid decoder after an utterance
        let frames = unsafe { ps_get_n_frames(self.ps) };
        self.select("english")?;
        let english = self.pass(samples);
        self.select("phones")?;
        let phones = self.pass(samples);
        self.select("opennav")?;
        Ok(Some(Hypothesis {
            text,
            score,
            probability,
            inner_silence_frames,
            english: english?.map(|p| p.text),
            phone_score: phones?.map(|p| p.score),
            alternatives,
            top_paths,
            frames,
            word_frames,
        }))
    }
}

impl Drop for Recognizer {
    fn drop(&mut self) {
        // SAFETY: ours, freed once
        unsafe {
            ps_free(self.ps);
            cmd_ln_free_r(self.config);
        }
    }
}

/// 16-bit little-endian mono samples from raw bytes (an odd trailing byte
/// is an error naming the input).
pub fn samples_from_s16le(bytes: &[u8], what: &str) -> Result<Vec<i16>, SphinxError> {
    if !bytes.len().is_multiple_of(2) {
        return Err(SphinxError::Decoder(format!(
            "{what}: {} bytes is not a whole number of 16-bit samples",
            bytes.len()
        )));
    }
    Ok(bytes
        .chunks_exact(2)
        .map(|c| i16::from_le_bytes([c[0], c[1]]))
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn inner_silence_counts_only_between_words() {
        let segs = |v: &[(&str, i32)]| -> Vec<(String, i32)> {
            v.iter().map(|(w, f)| (w.to_string(), *f)).collect()
        };
        assert_eq!(
            inner_silence(&segs(&[
                ("<sil>", 30),
                ("go", 10),
                ("<sil>", 70),
                ("sofa", 20),
                ("<sil>", 40)
            ])),
            70
        );
        assert_eq!(
            inner_silence(&segs(&[
                ("<sil>", 30),
                ("door", 10),
                ("(NULL)", 1),
                ("<sil>", 40)
            ])),
            0
        );
        assert_eq!(inner_silence(&segs(&[("<sil>", 30)])), 0);
    }

    #[test]
    fn word_frames_leave_out_silence_and_fillers() {
        let segs = |v: &[(&str, i32)]| -> Vec<(String, i32)> {
            v.iter().map(|(w, f)| (w.to_string(), *f)).collect()
        };
        let path = segs(&[
            ("<s>", 3),
            ("<sil>", 30),
            ("go", 10),
            ("[NOISE]", 5),
            ("to", 8),
            ("door(2)", 20),
            ("(NULL)", 1),
            ("++UM++", 4),
            ("</s>", 40),
        ]);
        assert_eq!(word_frames(&path), 38);
        assert_eq!(word_frames(&segs(&[("<sil>", 30)])), 0);
    }
}
