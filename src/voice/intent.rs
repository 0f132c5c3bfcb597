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

/// The confidence in what the grammar heard: the share of its meaningful
/// words — the target's, or the command word — that a free English decode
/// of the same audio heard too (0..1). The grammar always finds its best
/// path, even in "the quick brown fox"; free English does not then say
/// "toilet".
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
}
