//! The JSGF grammar the recogniser searches, made at run time from the
//! active vocabulary (the detector's labels and synonyms, or the word list)
//! and the commands: "stop" (and "halt"), "cancel", "yes", "no",
//! "go to / take me to / find / drive to [the] X" and the bare word X.
//! Words the pronunciation dictionary lacks cannot be recognised: they are
//! left out and reported.
//!
//! The US English dictionary spells every post-vocalic R; a British or
//! other non-rhotic speaker says "door" as D AO and "chair" as CH EH (AH).
//! Those readings are added for the grammar's words, so such a speaker's
//! "door" is not heard as "halt".

use std::collections::{HashMap, HashSet};
use std::path::Path;

/// A CMU-style pronunciation dictionary: each word (lower case) with its
/// pronunciations (ARPAbet phones), alternates `word(2)` under the word.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Dictionary {
    pub pronunciations: HashMap<String, Vec<Vec<String>>>,
}

impl Dictionary {
    pub fn contains(&self, word: &str) -> bool {
        self.pronunciations.contains_key(word)
    }

    /// Parses the dictionary's text (`word PH PH …` a line; a line without
    /// phones is an error naming it).
    pub fn parse(text: &str, what: &str) -> Result<Dictionary, String> {
        let mut d = Dictionary::default();
        for (i, line) in text.lines().enumerate() {
            let mut cols = line.split_whitespace();
            let Some(word) = cols.next() else { continue };
            let phones: Vec<String> = cols.map(str::to_string).collect();
            if phones.is_empty() {
                return Err(format!("{what} line {}: {word:?} has no phones", i + 1));
            }
            let base = word.split('(').next().unwrap_or(word).to_lowercase();
            d.pronunciations.entry(base).or_default().push(phones);
        }
        Ok(d)
    }
}

/// Reads a CMU-style dictionary file.
pub fn read_dictionary(path: &Path) -> Result<Dictionary, String> {
    let text = std::fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
    Dictionary::parse(&text, &path.display().to_string())
}

const VOWELS: [&str; 15] = [
    "AA", "AE", "AH", "AO", "AW", "AY", "EH", "ER", "EY", "IH", "IY", "OW", "OY", "UH", "UW",
];

/// The non-rhotic readings of one pronunciation: an R after a vowel and
/// not before one is dropped, ER not before a vowel is AH, and a final
/// EH/IH/UH + R is also said as a centring diphthong (+ AH). Empty when
/// the word has no such R.
pub fn non_rhotic(pron: &[String]) -> Vec<Vec<String>> {
    let vowel = |p: Option<&String>| p.is_some_and(|p| VOWELS.contains(&p.as_str()));
    let mut dropped = Vec::with_capacity(pron.len());
    for (i, ph) in pron.iter().enumerate() {
        let next = pron.get(i + 1);
        let prev = i.checked_sub(1).and_then(|j| pron.get(j));
        if ph == "R" && vowel(prev) && !vowel(next) {
            continue;
        }
        if ph == "ER" && !vowel(next) {
            dropped.push("AH".to_string());
            continue;
        }
        dropped.push(ph.clone());
    }
    let mut out = Vec::new();
    if dropped != pron {
        out.push(dropped);
    }
    if let [.., v, r] = pron {
        if r == "R" && ["EH", "IH", "UH"].contains(&v.as_str()) {
            let mut centring = pron[..pron.len() - 1].to_vec();
            centring.push("AH".into());
            if !out.contains(&centring) {
                out.push(centring);
            }
        }
    }
    out
}

/// The grammar and what went into it.
#[derive(Debug, Clone, PartialEq)]
pub struct Grammar {
    pub jsgf: String,
    /// The vocabulary entries in the grammar (lower case).
    pub targets: Vec<String>,
    /// Entries left out: a word not in the dictionary, or not a word.
    pub skipped: Vec<String>,
    /// Readings the dictionary lacks, added to the recogniser: (the word as
    /// an alternate, `door(3)`; its phones, `D AO`).
    pub extra_pronunciations: Vec<(String, String)>,
}

impl Grammar {
    /// The same grammar without the target `index`: the best reading of an
    /// utterance when that word is ruled out (the rival a heard target is
    /// measured against).
    pub fn jsgf_without(&self, index: usize) -> Option<String> {
        self.others(index).map(|o| jsgf(&o, Leads::Yes))
    }

    /// The same rival without the leads ("chair", "sofa please", the
    /// commands): every path through it ends where the grammar may end.
    /// PocketSphinx's grammar search reports nothing when none of the word
    /// ends in the utterance's last frame reaches the grammar's end, and
    /// the full rival of a bare target can end on a lead ("find a" for
    /// "sofa"); this one always reads something.
    pub fn bare_jsgf_without(&self, index: usize) -> Option<String> {
        self.others(index).map(|o| jsgf(&o, Leads::No))
    }

    /// The targets but `index` (None: no such target).
    fn others(&self, index: usize) -> Option<Vec<&str>> {
        (index < self.targets.len()).then(|| {
            self.targets
                .iter()
                .enumerate()
                .filter(|(i, _)| *i != index)
                .map(|(_, t)| t.as_str())
                .collect()
        })
    }
}

/// Whether a target may be said after a lead ("go to the", "find").
#[derive(Clone, Copy, PartialEq)]
enum Leads {
    Yes,
    No,
}

/// The stops alone: the best stop reading of an utterance, which must
/// read a bare target heard worse than the target does for it to stand
/// (a "stop" in noise can lose its S).
pub const STOPS_JSGF: &str = "#JSGF V1.0;\n\
                              grammar opennav;\n\
                              public <stop> = stop [please] | halt;\n";

/// The grammar for `targets` (without any: the commands alone), with or
/// without the leads before a target.
fn jsgf(targets: &[&str], leads: Leads) -> String {
    if targets.is_empty() {
        return "#JSGF V1.0;\n\
                grammar opennav;\n\
                public <command> = <stop> | <cancel> | <yes> | <no>;\n\
                <stop> = stop [please] | halt;\n\
                <cancel> = cancel;\n\
                <yes> = yes [please];\n\
                <no> = no;\n"
            .to_string();
    }
    let alternatives = targets.join(" | ");
    let go = match leads {
        Leads::Yes => {
            "<go> = [<lead> [the | a]] <target> [please];\n\
             <lead> = go to | take me to | drive to | find;\n"
        }
        Leads::No => "<go> = <target> [please];\n",
    };
    format!(
        "#JSGF V1.0;\n\
         grammar opennav;\n\
         public <command> = <stop> | <cancel> | <yes> | <no> | <go>;\n\
         <stop> = stop [please] | halt;\n\
         <cancel> = cancel;\n\
         <yes> = yes [please];\n\
         <no> = no;\n\
         {go}\
         <target> = {alternatives};\n"
    )
}

/// Command words: every one must be in the dictionary.
pub const COMMAND_WORDS: [&str; 14] = [
    "stop", "halt", "cancel", "yes", "no", "go", "to", "take", "me", "find", "drive", "the", "a",
    "please",
];

fn clean(entry: &str) -> Option<String> {
    let words: Vec<String> = entry.split_whitespace().map(|w| w.to_lowercase()).collect();
    let ok = !words.is_empty()
        && words
            .iter()
            .all(|w| w.chars().all(|c| c.is_ascii_lowercase() || c == '\''));
    ok.then(|| words.join(" "))
}

/// Builds the grammar for `vocabulary`, keeping entries whose every word
/// `dict` knows.
pub fn build(vocabulary: &[String], dict: &Dictionary) -> Result<Grammar, String> {
    if let Some(missing) = COMMAND_WORDS.iter().find(|w| !dict.contains(w)) {
        return Err(format!("the dictionary lacks the command word {missing:?}"));
    }
    let mut targets: Vec<String> = Vec::new();
    let mut skipped = Vec::new();
    for entry in vocabulary {
        match clean(entry) {
            Some(c) if c.split(' ').all(|w| dict.contains(w)) => {
                if !targets.contains(&c) {
                    targets.push(c);
                }
            }
            _ => skipped.push(entry.clone()),
        }
    }
    if targets.is_empty() {
        return Err("no word of the vocabulary can be recognised".into());
    }
    // the non-rhotic readings of every word in the grammar
    let mut words: Vec<&str> = COMMAND_WORDS.to_vec();
    words.extend(targets.iter().flat_map(|t| t.split(' ')));
    let mut seen_words = HashSet::new();
    let mut extra_pronunciations = Vec::new();
    for w in words {
        if !seen_words.insert(w) {
            continue;
        }
        let Some(prons) = dict.pronunciations.get(w) else {
            continue;
        };
        let mut all = prons.clone();
        for p in prons {
            for v in non_rhotic(p) {
                if !all.contains(&v) {
                    extra_pronunciations.push((format!("{w}({})", all.len() + 1), v.join(" ")));
                    all.push(v);
                }
            }
        }
    }
    let refs: Vec<&str> = targets.iter().map(String::as_str).collect();
    let jsgf = jsgf(&refs, Leads::Yes);
    Ok(Grammar {
        jsgf,
        targets,
        skipped,
        extra_pronunciations,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn dict(words: &[&str]) -> Dictionary {
        let mut d = Dictionary::default();
        for w in words.iter().chain(COMMAND_WORDS.iter()) {
            d.pronunciations
                .insert(w.to_string(), vec![vec!["AH".to_string()]]);
        }
        d
    }

    fn phones(s: &str) -> Vec<String> {
        s.split(' ').map(str::to_string).collect()
    }

    #[test]
    fn non_rhotic_readings_drop_the_r_after_a_vowel() {
        assert_eq!(non_rhotic(&phones("D AO R")), [phones("D AO")]);
        assert_eq!(
            non_rhotic(&phones("CH EH R")),
            [phones("CH EH"), phones("CH EH AH")]
        );
        // an R before a vowel stays; ER at the end is AH
        assert!(non_rhotic(&phones("T EY B AH L")).is_empty());
        assert_eq!(
            non_rhotic(&phones("R IH F R IH JH ER EY T ER")),
            [phones("R IH F R IH JH ER EY T AH")]
        );
        assert_eq!(
            non_rhotic(&phones("W AO R D R OW B")),
            [phones("W AO D R OW B")]
        );
    }

    #[test]
    fn the_dictionary_parses_alternates_under_their_word_and_names_a_bad_line() {
        let d = Dictionary::parse("door D AO R\nthe DH AH\nthe(2) DH IY\n", "d").expect("parses");
        assert_eq!(d.pronunciations["the"].len(), 2);
        let e = Dictionary::parse("door D AO R\nchair\n", "test.dict").unwrap_err();
        assert!(e.contains("test.dict line 2"), "{e}");
    }

    #[test]
    fn the_grammar_gets_the_non_rhotic_readings_and_a_rival_without_each_target() {
        let mut d = dict(&["table"]);
        d.pronunciations
            .insert("door".into(), vec![phones("D AO R")]);
        d.pronunciations
            .insert("chair".into(), vec![phones("CH EH R")]);
        let v: Vec<String> = ["door", "chair", "table"]
            .iter()
            .map(|s| s.to_string())
            .collect();
        let g = build(&v, &d).expect("grammar");
        assert!(g
            .extra_pronunciations
            .contains(&("door(2)".to_string(), "D AO".to_string())));
        assert!(g
            .extra_pronunciations
            .contains(&("chair(3)".to_string(), "CH EH AH".to_string())));
        let rival = g.jsgf_without(0).expect("rival");
        assert!(rival.contains("<target> = chair | table;"), "{rival}");
        assert!(g.jsgf_without(3).is_none());
        // the bare rival: no leads, the other targets and the commands
        let bare = g.bare_jsgf_without(0).expect("bare rival");
        assert!(bare.contains("<target> = chair | table;"), "{bare}");
        assert!(bare.contains("<go> = <target> [please];"), "{bare}");
        assert!(
            !bare.contains("<lead>") && bare.contains("<stop>"),
            "{bare}"
        );
        // a single target's rival is the commands alone
        let one = build(&["door".to_string()], &d).expect("grammar");
        let rival = one.jsgf_without(0).expect("rival");
        assert!(
            !rival.contains("<target>") && rival.contains("<stop>"),
            "{rival}"
        );
    }

    #[test]
    fn known_words_go_in_and_unknown_ones_are_reported() {
        let d = dict(&["chair", "dining", "table", "door"]);
        let v: Vec<String> = ["Chair", "dining table", "door", "qzx", "tv-screen", "chair"]
            .iter()
            .map(|s| s.to_string())
            .collect();
        let g = build(&v, &d).expect("grammar");
        assert_eq!(g.targets, ["chair", "dining table", "door"]);
        assert_eq!(g.skipped, ["qzx", "tv-screen"]);
        assert!(
            g.jsgf.contains("<target> = chair | dining table | door;"),
            "{}",
            g.jsgf
        );
        assert!(build(&["qzx".to_string()], &d).is_err());
        assert!(build(&v, &Dictionary::default())
            .unwrap_err()
            .contains("command word"));
    }
}
