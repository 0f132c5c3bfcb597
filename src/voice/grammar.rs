//! The JSGF grammar the recogniser searches, made at run time from the
//! active vocabulary (the detector's labels and synonyms, or the word list)
//! and the commands: "stop" (and "halt"), "cancel", "yes", "no",
//! "go to / take me to / find / drive to [the] X" and the bare word X.
//! Words the pronunciation dictionary lacks cannot be recognised: they are
//! left out and reported.

use std::collections::HashSet;
use std::path::Path;

/// The dictionary's words (the first column of a CMU-style dictionary;
/// alternates like `word(2)` are the same word).
pub fn dictionary_words(path: &Path) -> Result<HashSet<String>, String> {
    let text = std::fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
    Ok(text
        .lines()
        .filter_map(|l| l.split_whitespace().next())
        .map(|w| w.split('(').next().unwrap_or(w).to_lowercase())
        .collect())
}

/// The grammar and what went into it.
#[derive(Debug, Clone, PartialEq)]
pub struct Grammar {
    pub jsgf: String,
    /// The vocabulary entries in the grammar (lower case).
    pub targets: Vec<String>,
    /// Entries left out: a word not in the dictionary, or not a word.
    pub skipped: Vec<String>,
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
pub fn build(vocabulary: &[String], dict: &HashSet<String>) -> Result<Grammar, String> {
    if let Some(missing) = COMMAND_WORDS.iter().find(|w| !dict.contains(**w)) {
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
    let alternatives = targets.join(" | ");
    let jsgf = format!(
        "#JSGF V1.0;\n\
         grammar opennav;\n\
         public <command> = <stop> | <cancel> | <yes> | <no> | <go>;\n\
         <stop> = stop [please] | halt;\n\
         <cancel> = cancel;\n\
         <yes> = yes [please];\n\
         <no> = no;\n\
         <go> = [<lead> [the | a]] <target> [please];\n\
         <lead> = go to | take me to | drive to | find;\n\
         <target> = {alternatives};\n"
    );
    Ok(Grammar {
        jsgf,
        targets,
        skipped,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn dict(words: &[&str]) -> HashSet<String> {
        words
            .iter()
            .chain(COMMAND_WORDS.iter())
            .map(|w| w.to_string())
            .collect()
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
        assert!(build(&v, &HashSet::new())
            .unwrap_err()
            .contains("command word"));
    }
}
