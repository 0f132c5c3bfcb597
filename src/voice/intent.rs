//! What a heard utterance means, and what to do about it. A wrong target
//! is worse than a question: a "go" the recogniser is unsure of is asked
//! back ("Did you say the door?") and needs "yes" (or a switch press); a
//! "stop" is acted on whatever the confidence.

use serde::Serialize;

use crate::msg::UserInput;

/// The meaning of an utterance.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Intent {
    Go,
    Stop,
    Cancel,
    Yes,
    No,
    /// Heard, but too unsure to act on.
    Unsure,
    /// Nothing in the grammar.
    None,
}

/// When to ask back before going (config `voice.confirm`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Deserialize, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Confirm {
    Always,
    Unsure,
    Never,
}

/// The words heard → intent and, for `go`, the vocabulary entry (the
/// longest `targets` entry the utterance ends with, so "dining table" wins
/// over "table").
pub fn meaning(heard: &str, targets: &[String]) -> (Intent, Option<String>) {
    let words: Vec<&str> = heard.split_whitespace().collect();
    match words.as_slice() {
        [] => return (Intent::None, None),
        ["stop", ..] | ["halt", ..] => return (Intent::Stop, None),
        ["cancel", ..] => return (Intent::Cancel, None),
        ["yes", ..] => return (Intent::Yes, None),
        ["no", ..] => return (Intent::No, None),
        _ => {}
    }
    let text = words
        .iter()
        .copied()
        .filter(|w| *w != "please")
        .collect::<Vec<_>>()
        .join(" ");
    let label = targets
        .iter()
        .filter(|t| text == **t || text.ends_with(&format!(" {t}")))
        .max_by_key(|t| t.len())
        .cloned();
    match label {
        Some(l) => (Intent::Go, Some(l)),
        None => (Intent::None, None),
    }
}

/// The share of the meaningful words — the target's, or the command word —
/// that a free English decode of the same audio heard too (0..1). The
/// grammar always finds its best path, even in "the quick brown fox"; free
/// English does not then say "toilet". It understands real speech far
/// better than synthetic speech.
pub fn agreement(intent: &Intent, label: Option<&str>, english: Option<&str>) -> f64 {
    let heard: Vec<&str> = english.unwrap_or("").split_whitespace().collect();
    let wanted: Vec<&str> = match (intent, label) {
        (Intent::Go, Some(l)) => l.split_whitespace().collect(),
        (Intent::Stop, _) => {
            return if heard.iter().any(|w| *w == "stop" || *w == "halt") {
                1.0
            } else {
                0.0
            }
        }
        (Intent::Cancel, _) => vec!["cancel"],
        (Intent::Yes, _) => vec!["yes"],
        (Intent::No, _) => vec!["no"],
        _ => return 0.0,
    };
    if wanted.is_empty() {
        return 0.0;
    }
    let found = wanted.iter().filter(|w| heard.contains(w)).count();
    found as f64 / wanted.len() as f64
}

/// The acoustic margin per 10 ms frame of a heard target over the best
/// reading with that word ruled out, at which the target counts as sure
/// (confidence 0.5; PocketSphinx's acoustic score units). Chosen on a
/// tuning set of espeak-ng commands (other phrasings, speeds and pitches
/// than `benches/voice_commands.rs` scores) as the smallest margin with at
/// most 1 % wrong targets acted on.
pub const SURE_MARGIN_PER_FRAME: f64 = 2.0;

/// The sure margin of a bare target ("door", "sofa please"): a word said
/// alone has no lead to confirm it, and "stop" said in noise loses its S
/// and comes out as a bare "door" with margins up to 2.7 per frame (396
/// espeak-ng stops at 20 and 10 dB SNR, four noise draws other than the
/// bench's). A bare target with less than this margin is asked back, so
/// such a stop leaves a chair at rest where it is.
pub const SURE_MARGIN_BARE_PER_FRAME: f64 = 2.8;

/// Silence or filler the grammar's path puts between its words beyond
/// this (frames) means it skipped speech it could not fit: a sentence
/// outside the grammar.
pub const MAX_INNER_SILENCE_FRAMES: i32 = 15;

/// How much better per frame of the words heard free phones may explain
/// the audio than the grammar's path, at most, for the path's acoustic
/// margin to count (`[voice] max_phone_excess_per_frame`): a sentence
/// outside the grammar is forced onto its nearest command, which then
/// fits it far worse than the phones do; a command said fits both about
/// as well. The phones decode with context-independent models, the
/// grammar with triphones, so the excess of a command said is positive,
/// and larger with the model as installed than with one adapted to the
/// voice. Per frame of the path's words, not of the whole cut: silence
/// scores alike in both, so the silence a cut leaves around the speech
/// (the daemon's voice activity detection, a file's padding) does not
/// dilute it, and a sentence whose speech the path filled with silence
/// ("the quick brown fox…" heard as "oven please") stands out. Chosen on
/// the tuning set of `benches/voice_commands.rs`
/// (`OPENNAV_BENCH_SET=tuning`: other words, phrasings, sentences, speeds
/// and pitches than the measured set; voices en and en-us). The model as
/// installed: sentences outside the grammar sent somewhere 16.7 % → 4.2 %,
/// right targets 66.8 % → 64.6 % (at 45: 2.1 % and 62.3 %; per frame of
/// the whole cut, at 26: 7.3 % and 64.8 %).
pub const MAX_PHONE_EXCESS_INSTALLED: f64 = 50.0;

/// The same for a model adapted to the voice (`opennav voice enroll`, its
/// noisy copies included): outside sent 38.5 % → 0.0 %, right targets
/// 88.2 % → 88.2 % (0.0 % from 50 down; at 40: 87.7 %).
pub const MAX_PHONE_EXCESS_ENROLLED: f64 = 45.0;

/// What the recogniser measured of one utterance.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Evidence<'a> {
    /// A free English decode of the same audio.
    pub english: Option<&'a str>,
    /// The heard target's acoustic margin per frame over the best reading
    /// without it (None: not a target, or no rival reading).
    pub margin_per_frame: Option<f64>,
    /// The target was heard alone, without a lead ("door", "door please").
    pub bare: bool,
    /// The share of the grammar's N best readings that mean the same.
    pub nbest_agreement: f64,
    /// Frames of silence or filler between the path's first and last word.
    pub inner_silence_frames: i32,
    /// How much better per frame free phones explain the audio than the
    /// grammar's path (None: no phone pass).
    pub phone_excess_per_frame: Option<f64>,
}

/// The confidence in what the grammar heard (0..1): the larger of the free
/// English agreement and the acoustic evidence — the target's margin over
/// its best rival (`SURE_MARGIN_PER_FRAME` is 0.5, for a bare target
/// `SURE_MARGIN_BARE_PER_FRAME`), scaled by how many of the N best
/// readings agree, and nothing when the path skipped speech or free phones
/// explain the audio far better than it (speech outside the grammar).
pub fn confidence(
    intent: &Intent,
    label: Option<&str>,
    e: &Evidence,
    max_phone_excess_per_frame: f64,
) -> f64 {
    let english = agreement(intent, label, e.english);
    let sure = if e.bare {
        SURE_MARGIN_BARE_PER_FRAME
    } else {
        SURE_MARGIN_PER_FRAME
    };
    let acoustic = match (intent, e.margin_per_frame) {
        (Intent::Go, Some(m))
            if e.inner_silence_frames <= MAX_INNER_SILENCE_FRAMES
                && e.phone_excess_per_frame
                    .is_none_or(|x| x <= max_phone_excess_per_frame) =>
        {
            e.nbest_agreement.clamp(0.0, 1.0) * (m / (2.0 * sure)).clamp(0.0, 1.0)
        }
        _ => 0.0,
    };
    english.max(acoustic)
}

/// What the daemon does with a decoded utterance.
#[derive(Debug, Clone, PartialEq)]
pub enum Decision {
    /// Hand this to the input hub now.
    Act(UserInput),
    /// Ask "Did you say the X?" and wait for yes/no.
    Ask(String),
    /// Not acted on (nothing meant, or unsure of a yes/no).
    Ignore,
}

/// The intent with its confidence, under the confirm policy: stops always
/// act; a go acts when sure (or never confirmed), else is asked back; a
/// yes/no needs to be sure.
pub fn decide(
    intent: &Intent,
    label: Option<&str>,
    confidence: f64,
    confirm: Confirm,
    min_confidence: f64,
) -> Decision {
    let sure = confidence >= min_confidence;
    match (intent, label) {
        (Intent::Stop, _) => Decision::Act(UserInput::Stop),
        (Intent::Go, Some(l)) => match confirm {
            Confirm::Never => Decision::Act(UserInput::Goto(l.to_string())),
            Confirm::Unsure if sure => Decision::Act(UserInput::Goto(l.to_string())),
            _ => Decision::Ask(l.to_string()),
        },
        (Intent::Yes, _) if sure => Decision::Act(UserInput::Yes),
        (Intent::No, _) if sure => Decision::Act(UserInput::No),
        // "cancel" drops the goal as a stop does, and latches like one
        (Intent::Cancel, _) => Decision::Act(UserInput::Stop),
        _ => Decision::Ignore,
    }
}

/// The intent reported for an utterance at this confidence (`unsure` for
/// a go that would be asked back, or an unsure yes/no).
pub fn reported(intent: &Intent, confidence: f64, min_confidence: f64) -> Intent {
    match intent {
        Intent::Go | Intent::Yes | Intent::No if confidence < min_confidence => Intent::Unsure,
        other => other.clone(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn targets() -> Vec<String> {
        ["table", "dining table", "door", "chair"]
            .iter()
            .map(|s| s.to_string())
            .collect()
    }

    #[test]
    fn utterances_mean_their_command_or_target() {
        let t = targets();
        assert_eq!(
            meaning("take me to the chair", &t),
            (Intent::Go, Some("chair".into()))
        );
        assert_eq!(
            meaning("go to the dining table please", &t),
            (Intent::Go, Some("dining table".into()))
        );
        assert_eq!(meaning("door", &t), (Intent::Go, Some("door".into())));
        assert_eq!(meaning("stop please", &t), (Intent::Stop, None));
        assert_eq!(meaning("halt", &t), (Intent::Stop, None));
        assert_eq!(meaning("yes", &t), (Intent::Yes, None));
        assert_eq!(meaning("", &t), (Intent::None, None));
        assert_eq!(meaning("go to the piano", &t), (Intent::None, None));
    }

    #[test]
    fn a_stop_always_acts_and_an_unsure_go_is_asked_back() {
        assert_eq!(
            decide(&Intent::Stop, None, 0.01, Confirm::Always, 0.5),
            Decision::Act(UserInput::Stop)
        );
        assert_eq!(
            decide(&Intent::Go, Some("door"), 0.3, Confirm::Unsure, 0.5),
            Decision::Ask("door".into())
        );
        assert_eq!(
            decide(&Intent::Go, Some("door"), 0.9, Confirm::Unsure, 0.5),
            Decision::Act(UserInput::Goto("door".into()))
        );
        assert_eq!(
            decide(&Intent::Go, Some("door"), 0.99, Confirm::Always, 0.5),
            Decision::Ask("door".into())
        );
        assert_eq!(
            decide(&Intent::Go, Some("door"), 0.1, Confirm::Never, 0.5),
            Decision::Act(UserInput::Goto("door".into()))
        );
        assert_eq!(
            decide(&Intent::Yes, None, 0.2, Confirm::Unsure, 0.5),
            Decision::Ignore
        );
        assert_eq!(reported(&Intent::Go, 0.2, 0.5), Intent::Unsure);
        assert_eq!(reported(&Intent::Stop, 0.2, 0.5), Intent::Stop);
    }

    #[test]
    fn agreement_is_the_share_of_meaningful_words_free_english_heard_too() {
        assert_eq!(
            agreement(&Intent::Go, Some("chair"), Some("take me to the chair")),
            1.0
        );
        assert_eq!(
            agreement(&Intent::Go, Some("dining table"), Some("the table")),
            0.5
        );
        assert_eq!(
            agreement(&Intent::Go, Some("toilet"), Some("the quick brown fox")),
            0.0
        );
        assert_eq!(agreement(&Intent::Yes, None, Some("yes")), 1.0);
        assert_eq!(agreement(&Intent::Go, Some("door"), None), 0.0);
    }

    #[test]
    fn a_target_is_sure_when_it_beats_its_rival_and_the_n_best_agree() {
        let e = |m: f64, agree: f64, sil: i32| Evidence {
            english: Some("the quick brown fox"),
            margin_per_frame: Some(m),
            nbest_agreement: agree,
            inner_silence_frames: sil,
            bare: false,
            phone_excess_per_frame: Some(0.0),
        };
        const LIMIT: f64 = MAX_PHONE_EXCESS_INSTALLED;
        let go = |ev: &Evidence| confidence(&Intent::Go, Some("door"), ev, LIMIT);
        assert_eq!(go(&e(SURE_MARGIN_PER_FRAME, 1.0, 0)), 0.5);
        assert_eq!(go(&e(10.0, 1.0, 0)), 1.0);
        assert!(go(&e(SURE_MARGIN_PER_FRAME, 0.8, 0)) < 0.5);
        assert_eq!(go(&e(-3.0, 1.0, 0)), 0.0);
        // speech skipped between the words: outside the grammar
        assert_eq!(go(&e(10.0, 1.0, MAX_INNER_SILENCE_FRAMES + 1)), 0.0);
        // free phones fit far better than the command: outside the grammar
        let outside = Evidence {
            phone_excess_per_frame: Some(LIMIT + 0.1),
            ..e(10.0, 1.0, 0)
        };
        assert_eq!(go(&outside), 0.0);
        let inside = Evidence {
            phone_excess_per_frame: Some(LIMIT - 0.1),
            ..e(10.0, 1.0, 0)
        };
        assert_eq!(go(&inside), 1.0);
        // free English that heard the word is enough on its own
        let heard = Evidence {
            english: Some("go to the door"),
            ..Default::default()
        };
        assert_eq!(go(&heard), 1.0);
        // a bare word needs the larger margin: "stop" that lost its S is
        // heard as a bare "door" with the margin a command has
        let bare = |m: f64| Evidence {
            bare: true,
            ..e(m, 1.0, 0)
        };
        assert!(go(&bare(2.7)) < 0.5, "{}", go(&bare(2.7)));
        assert!(go(&e(2.7, 1.0, 0)) > 0.5);
        assert_eq!(go(&bare(SURE_MARGIN_BARE_PER_FRAME)), 0.5);
        // the margin says nothing about a yes
        assert_eq!(confidence(&Intent::Yes, None, &e(10.0, 1.0, 0), LIMIT), 0.0);
    }
}
