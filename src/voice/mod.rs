//! The person's voice: speech recognition on the chair's laptop, offline.
//! The grammar made from the active vocabulary, the meaning of what was
//! heard and the decision (act, ask back, ignore) are pure; the recogniser
//! is PocketSphinx (Debian's 0.8 libraries) behind the `voice` feature.

pub mod enroll;
pub mod grammar;
pub mod intent;
#[cfg(feature = "voice")]
pub mod listen;
#[cfg(feature = "voice")]
pub mod sphinx;
pub mod vad;
pub mod wav;

/// A sample value rounded and held to 16 bits (loud noise clips, as a
/// microphone's converter does).
pub(crate) fn to_i16_sample(v: f64) -> i16 {
    v.round().clamp(i16::MIN as f64, i16::MAX as f64) as i16
}

/// Standard normal draws from a fixed-seed generator (xorshift64*, then
/// Box–Muller): the noise added to audio is the same every run.
pub(crate) fn standard_normal(seed: u64) -> impl FnMut() -> f64 {
    let mut state = if seed == 0 { 1 } else { seed };
    let mut uniform = move || {
        state ^= state >> 12;
        state ^= state << 25;
        state ^= state >> 27;
        let x = state.wrapping_mul(0x2545_F491_4F6C_DD1D);
        ((x >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    };
    move || {
        let (u1, u2) = (uniform(), uniform());
        (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
    }
}

/// Config `[voice]`.
#[derive(Debug, Clone, PartialEq, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct VoiceSettings {
    /// Listen to the microphone (`opennav run`; `--voice-wav FILE` listens
    /// to a file instead, whatever this says).
    pub enabled: bool,
    /// The ALSA capture device (`arecord -L` lists them).
    pub capture_device: String,
    /// What may be asked for when the detector gives no vocabulary of its
    /// own (an open-vocabulary detector's word list).
    pub vocabulary: Vec<String>,
    /// When to ask back before going: always, unsure, never.
    pub confirm: intent::Confirm,
    /// Below this confidence (0..1, `intent::confidence`) an utterance is unsure.
    pub min_confidence: f64,
    /// The acoustic model directory and the pronunciation dictionary.
    pub hmm: String,
    pub dict: String,
    /// A general English language model, to check what the grammar heard.
    pub english_lm: String,
    /// A phonetic language model, to check how much better than the
    /// grammar free phones explain what was heard.
    pub phone_lm: String,
    /// How much better per frame free phones may explain an utterance than
    /// the grammar's path for its margin to count (`intent::
    /// MAX_PHONE_EXCESS_INSTALLED` for Debian's model,
    /// `MAX_PHONE_EXCESS_ENROLLED` for one adapted to the person).
    pub max_phone_excess_per_frame: f64,
}
