//! The goal keeper's events and the sentence the person hears for each
//! (split out of `estimation::goal` to keep it readable).

use serde::Serialize;

/// What the user hears (and the log records).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub enum GoalEvent {
    Acquired {
        label: String,
        track: u64,
    },
    /// No free side around the object to stop at.
    NoApproach {
        label: String,
        track: u64,
    },
    OutOfView {
        label: String,
    },
    BackInView {
        label: String,
    },
    /// Held too long out of view: looked for again from where the chair
    /// is (at most [`super::SEARCH_AGAIN_AT_MOST`] times a word).
    SearchingAgain {
        label: String,
        held_s: f64,
    },
    /// Held too long out of view: dropped, the chair stops.
    Lost {
        label: String,
        held_s: f64,
    },
    Reached {
        label: String,
    },
    /// Held by something on the way within reach of the place beside the
    /// object: as near as the chair can safely go, so the trip ends there.
    ReachedNear {
        label: String,
        /// How far the place beside the object still is, m.
        off_m: f64,
    },
    /// Held on the way to the place beside the object: another side of
    /// it instead ([`super::GoalKeeper::refuse_approach`]).
    OtherSide {
        label: String,
    },
    /// Another object of the word is nearer than the one the chair was
    /// going to ([`super::NEARER_BY_M`]): it goes there instead.
    Nearer {
        label: String,
    },
    /// A full search turn without seeing the word: the goal is dropped.
    NotFound {
        label: String,
    },
    /// Held on the way for [`super::GoalSettings::give_up_held_after`] without a
    /// break: the goal is dropped, the chair stops.
    GaveUp {
        label: String,
        held_s: f64,
    },
    /// Held on the way for [`super::GoalSettings::give_up_held_after`]
    /// without a break: that object is given up and another of the word
    /// searched for ([`super::GoalKeeper::give_up`]).
    LookingForAnother {
        label: String,
        held_s: f64,
    },
    /// An object of the word was given up and no other was found: the
    /// chair stops.
    NoOtherFound {
        label: String,
    },
    /// An object of the word was given up and, `after_s` after the word
    /// was given (over [`super::GoalSettings::search_at_most`]), the chair
    /// has not got to another: it stops.
    AnotherOutOfTime {
        label: String,
        after_s: f64,
    },
    /// Searching, the chair stayed held in one place for `held_s`
    /// ([`super::GoalKeeper::give_up_search`]): the search is dropped, the
    /// chair stops.
    SearchHeld {
        label: String,
        held_s: f64,
    },
    /// A turn to look around is done: what is known around, nearest first.
    LookedAround {
        seen: Vec<String>,
    },
    /// Not seen from here: going on to look elsewhere.
    LookingFurther {
        label: String,
    },
}

impl GoalEvent {
    /// A sentence for the voice output / display.
    pub fn say(&self) -> String {
        match self {
            GoalEvent::Acquired { label, .. } => format!("Going to the {label}."),
            GoalEvent::NoApproach { label, .. } => {
                format!("I see the {label} but cannot find a free place beside it.")
            }
            GoalEvent::OutOfView { label } => format!("I lost sight of the {label}; waiting."),
            GoalEvent::BackInView { label } => format!("I see the {label} again."),
            GoalEvent::SearchingAgain { label, held_s } => format!(
                "I lost sight of the {label} for {held_s:.0} seconds. Looking for it again."
            ),
            GoalEvent::Lost { label, held_s } => {
                format!("I could not find the {label} again after {held_s:.0} seconds. Stopped.")
            }
            GoalEvent::Reached { label } => format!("Arrived at the {label}."),
            GoalEvent::ReachedNear { label, .. } => {
                format!("Arrived: this is as near the {label} as I can safely go.")
            }
            GoalEvent::OtherSide { label } => {
                format!("I cannot get to this side of the {label}. Trying another side.")
            }
            GoalEvent::Nearer { label } => format!("There is a nearer {label}. Going to it."),
            GoalEvent::NotFound { label } => format!("I cannot find a {label} here. Stopped."),
            GoalEvent::GaveUp { label, held_s } => format!(
                "I cannot get to the {label}: my way has been blocked for {held_s:.0} seconds. \
                 Stopped."
            ),
            GoalEvent::LookingForAnother { label, held_s } => format!(
                "I cannot get to this {label}: my way has been blocked for {held_s:.0} seconds. \
                 Looking for another {label}."
            ),
            GoalEvent::NoOtherFound { label } => format!(
                "I cannot get to the {label} I found, and I cannot find another {label}. Stopped."
            ),
            GoalEvent::AnotherOutOfTime { label, after_s } => format!(
                "I cannot get to another {label}: I have tried for {after_s:.0} seconds. Stopped."
            ),
            GoalEvent::SearchHeld { label, held_s } => format!(
                "I cannot look further for a {label}: I have been held in this place for \
                 {held_s:.0} seconds. Stopped."
            ),
            GoalEvent::LookingFurther { label } => {
                format!("I cannot see a {label} from here. Looking further.")
            }
            GoalEvent::LookedAround { seen } if seen.is_empty() => {
                "I looked around and saw nothing I know.".into()
            }
            GoalEvent::LookedAround { seen } => {
                let things: Vec<String> = seen.iter().map(|l| format!("the {l}")).collect();
                format!("I looked around. I see {}.", things.join(", "))
            }
        }
    }
}
