//! Switch scanning, the pure core: a person who can press one switch (or
//! two) chooses where to go. Time comes in as an argument.
//!
//! One switch: a press wakes the menu; the chair says the candidates one
//! by one, each for `dwell` — the objects it sees, nearest first, then the
//! favourites from config — and a press selects the one being said. Two
//! switches: *step* says the next candidate, *select* takes it.
//!
//! Whatever the menu is doing: a press while the chair moves stops it (on
//! the press, not the release); a press while the chair asks a question is
//! "yes"; holding the switch for `long_press` is a stop and acknowledges a
//! latched fault (a carer's gesture).

use std::time::Duration;

use crate::msg::{Stamp, UserInput};

/// Config `[input.switch]` (timing and favourites).
#[derive(Debug, Clone, PartialEq)]
pub struct ScanSettings {
    pub dwell: Duration,
    pub long_press: Duration,
    pub favourites: Vec<String>,
    /// Two switches: step and select (else one, with dwell scanning).
    pub two_switch: bool,
}

/// Which switch.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Switch {
    Select,
    Step,
}

/// What the daemon is doing, as far as the menu cares.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ChairNow {
    pub moving: bool,
    pub asking: bool,
    /// Labels of the objects it sees, nearest first.
    pub seen: Vec<String>,
}

/// What the scanner wants done.
#[derive(Debug, Clone, PartialEq)]
pub enum ScanAction {
    Say(String),
    Input(UserInput),
}

/// The menu item that turns the chair once to see what is around.
pub const LOOK_AROUND: &str = "look around";

#[derive(Debug, Clone, PartialEq)]
enum Menu {
    Closed,
    Open {
        items: Vec<String>,
        index: usize,
        /// When the current item was said.
        since: Stamp,
        /// Items said since the menu opened (one full round closes it).
        said: usize,
    },
}

#[derive(Debug, Clone)]
pub struct Scanner {
    pub settings: ScanSettings,
    menu: Menu,
    /// The select switch is down since; whether this press was used
    /// already (a stop, a long press); the candidate said when it went down.
    down: Option<(Stamp, bool, Option<usize>)>,
}

impl Scanner {
    pub fn new(settings: ScanSettings) -> Self {
        Scanner {
            settings,
            menu: Menu::Closed,
            down: None,
        }
    }

    pub fn menu_open(&self) -> bool {
        matches!(self.menu, Menu::Open { .. })
    }

    fn say_item(item: &str) -> ScanAction {
        ScanAction::Say(format!("{item}?"))
    }

    /// A switch went down at `now`.
    pub fn press(&mut self, now: Stamp, which: Switch, chair: &ChairNow) -> Vec<ScanAction> {
        if chair.moving {
            // any press while the chair moves: stop, at once
            self.menu = Menu::Closed;
            self.down = Some((now, true, None));
            return vec![ScanAction::Input(UserInput::Stop)];
        }
        match which {
            Switch::Select => {
                let current = match &self.menu {
                    Menu::Open { index, .. } => Some(*index),
                    Menu::Closed => None,
                };
                self.down = Some((now, false, current));
                Vec::new()
            }
            Switch::Step => self.step(now, chair),
        }
    }

    /// The second switch: the next candidate (opening the menu first).
    fn step(&mut self, now: Stamp, chair: &ChairNow) -> Vec<ScanAction> {
        match &mut self.menu {
            Menu::Closed => self.open(now, chair),
            Menu::Open {
                items,
                index,
                since,
                said,
            } => {
                *index = (*index + 1) % items.len();
                *since = now;
                *said += 1;
                vec![Self::say_item(&items[*index])]
            }
        }
    }

    fn open(&mut self, now: Stamp, chair: &ChairNow) -> Vec<ScanAction> {
        // what it sees, nearest first; then "look around"; then the
        // favourites when it sees nothing
        let mut items = chair.seen.clone();
        items.push(LOOK_AROUND.to_string());
        if chair.seen.is_empty() {
            items.extend(self.settings.favourites.iter().cloned());
        }
        let first = Self::say_item(&items[0]);
        self.menu = Menu::Open {
            items,
            index: 0,
            since: now,
            said: 1,
        };
        vec![first]
    }

    /// The select switch came up at `now`.
    pub fn release(&mut self, now: Stamp, which: Switch, chair: &ChairNow) -> Vec<ScanAction> {
        if which == Switch::Step {
            return Vec::new();
        }
        let Some((_, used, pressed_at)) = self.down.take() else {
            return Vec::new();
        };
        if used {
            return Vec::new();
        }
        if chair.asking {
            return vec![ScanAction::Input(UserInput::Yes)];
        }
        match std::mem::replace(&mut self.menu, Menu::Closed) {
            Menu::Closed => self.open(now, chair),
            Menu::Open { items, index, .. } => {
                // the candidate being said when the switch went down
                let item = items[pressed_at.unwrap_or(index).min(items.len() - 1)].clone();
                if item == LOOK_AROUND {
                    return vec![ScanAction::Input(UserInput::LookAround)];
                }
                vec![
                    ScanAction::Say(format!("Going to the {item}.")),
                    ScanAction::Input(UserInput::Goto(item)),
                ]
            }
        }
    }

    /// Time passes: the long press, and the dwell of one-switch scanning.
    pub fn tick(&mut self, now: Stamp) -> Vec<ScanAction> {
        let mut out = Vec::new();
        if let Some((since, used, _)) = &mut self.down {
            if !*used && since.age_at(now) >= self.settings.long_press {
                *used = true;
                self.menu = Menu::Closed;
                out.push(ScanAction::Input(UserInput::Stop));
                out.push(ScanAction::Input(UserInput::AckFault));
                return out;
            }
        }
        if self.settings.two_switch {
            return out;
        }
        if let Menu::Open {
            items,
            index,
            since,
            said,
        } = &mut self.menu
        {
            if since.age_at(now) >= self.settings.dwell {
                if *said >= items.len() {
                    self.menu = Menu::Closed;
                    out.push(ScanAction::Say("Nothing chosen.".into()));
                } else {
                    *index = (*index + 1) % items.len();
                    *since = now;
                    *said += 1;
                    out.push(Self::say_item(&items[*index]));
                }
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn at(ms: u64) -> Stamp {
        Stamp(Duration::from_millis(ms))
    }

    fn scanner(two: bool) -> Scanner {
        Scanner::new(ScanSettings {
            dwell: Duration::from_millis(2000),
            long_press: Duration::from_millis(2000),
            favourites: vec!["kitchen table".into(), "bed".into()],
            two_switch: two,
        })
    }

    fn still(seen: &[&str]) -> ChairNow {
        ChairNow {
            moving: false,
            asking: false,
            seen: seen.iter().map(|s| s.to_string()).collect(),
        }
    }

    /// Ticks every 100 ms from `from` to `to`, collecting actions.
    fn run(s: &mut Scanner, from: u64, to: u64) -> Vec<ScanAction> {
        let mut out = Vec::new();
        let mut t = from;
        while t <= to {
            out.extend(s.tick(at(t)));
            t += 100;
        }
        out
    }

    fn click(s: &mut Scanner, t: u64, chair: &ChairNow) -> Vec<ScanAction> {
        let mut out = s.press(at(t), Switch::Select, chair);
        out.extend(s.release(at(t + 150), Switch::Select, chair));
        out
    }

    #[test]
    fn one_switch_selects_the_second_candidate_after_two_dwell_times() {
        let mut s = scanner(false);
        let chair = still(&["chair", "desk", "door"]);
        assert_eq!(
            click(&mut s, 0, &chair),
            vec![ScanAction::Say("chair?".into())]
        );
        let said = run(&mut s, 200, 2200);
        assert_eq!(said, vec![ScanAction::Say("desk?".into())]);
        // pressed while "desk?" is current
        assert_eq!(
            click(&mut s, 3000, &chair),
            vec![
                ScanAction::Say("Going to the desk.".into()),
                ScanAction::Input(UserInput::Goto("desk".into()))
            ]
        );
        assert!(!s.menu_open());
    }

    #[test]
    fn nothing_seen_offers_look_around_then_the_favourites_and_one_round_closes_the_menu() {
        let mut s = scanner(false);
        let chair = still(&[]);
        assert_eq!(
            click(&mut s, 0, &chair),
            vec![ScanAction::Say("look around?".into())]
        );
        let said = run(&mut s, 200, 6200);
        assert_eq!(
            said,
            vec![
                ScanAction::Say("kitchen table?".into()),
                ScanAction::Say("bed?".into()),
                ScanAction::Say("Nothing chosen.".into())
            ]
        );
        assert!(!s.menu_open());
    }

    #[test]
    fn look_around_follows_what_is_seen_and_turns_the_chair_when_chosen() {
        let mut s = scanner(false);
        let chair = still(&["chair"]);
        assert_eq!(
            click(&mut s, 0, &chair),
            vec![ScanAction::Say("chair?".into())]
        );
        // no favourites while something is seen
        assert_eq!(
            run(&mut s, 200, 2200),
            vec![ScanAction::Say("look around?".into())]
        );
        assert_eq!(
            click(&mut s, 3000, &chair),
            vec![ScanAction::Input(UserInput::LookAround)]
        );
    }

    #[test]
    fn a_press_while_moving_stops_at_once_and_selects_nothing() {
        let mut s = scanner(false);
        let mut chair = still(&["chair"]);
        click(&mut s, 0, &chair);
        chair.moving = true;
        assert_eq!(
            s.press(at(500), Switch::Select, &chair),
            vec![ScanAction::Input(UserInput::Stop)]
        );
        assert!(s.release(at(600), Switch::Select, &chair).is_empty());
        assert!(!s.menu_open());
        // the step switch stops too
        assert_eq!(
            s.press(at(700), Switch::Step, &chair),
            vec![ScanAction::Input(UserInput::Stop)]
        );
    }

    #[test]
    fn a_press_answers_yes_and_a_long_press_stops_and_acknowledges() {
        let mut s = scanner(false);
        let mut chair = still(&["chair"]);
        chair.asking = true;
        assert_eq!(
            click(&mut s, 0, &chair),
            vec![ScanAction::Input(UserInput::Yes)]
        );
        chair.asking = false;
        assert!(s.press(at(1000), Switch::Select, &chair).is_empty());
        assert!(run(&mut s, 1100, 2900).is_empty());
        assert_eq!(
            s.tick(at(3000)),
            vec![
                ScanAction::Input(UserInput::Stop),
                ScanAction::Input(UserInput::AckFault)
            ]
        );
        // once per hold; the release opens no menu
        assert!(run(&mut s, 3100, 4000).is_empty());
        assert!(s.release(at(4100), Switch::Select, &chair).is_empty());
        assert!(!s.menu_open());
    }

    #[test]
    fn two_switches_step_and_select_without_dwell() {
        let mut s = scanner(true);
        let chair = still(&["chair", "desk"]);
        assert_eq!(
            s.press(at(0), Switch::Step, &chair),
            vec![ScanAction::Say("chair?".into())]
        );
        // no dwell: nothing moves on by itself
        assert!(run(&mut s, 100, 10_000).is_empty());
        assert_eq!(
            s.press(at(10_100), Switch::Step, &chair),
            vec![ScanAction::Say("desk?".into())]
        );
        assert_eq!(
            click(&mut s, 10_300, &chair)[1],
            ScanAction::Input(UserInput::Goto("desk".into()))
        );
    }
}
