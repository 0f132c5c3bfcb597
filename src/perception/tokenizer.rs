//! CLIP's byte-level BPE tokenizer, for the text encoder that turns prompts
//! into YOLO-World text embeddings.
//!
//! Same algorithm and vocabulary as CLIP's `simple_tokenizer`: text is
//! whitespace-collapsed and lower-cased, split by CLIP's pattern, each piece
//! mapped byte→unicode and merged by BPE rank. One difference: CLIP runs
//! `ftfy.fix_text` and HTML unescaping first; prompts here are typed or
//! spoken words, so only the common HTML entities are unescaped.

use std::collections::HashMap;
use std::io::Read;
use std::path::Path;

use regex::Regex;
use thiserror::Error;

/// The standard vocabulary (OpenAI CLIP, MIT), embedded.
const EMBEDDED_VOCAB_GZ: &[u8] = include_bytes!("../../assets/clip/bpe_simple_vocab_16e6.txt.gz");

pub const CONTEXT_LENGTH: usize = 77;
pub const START_OF_TEXT: i64 = 49406;
pub const END_OF_TEXT: i64 = 49407;

#[derive(Debug, Error)]
pub enum TokenizerError {
    #[error("{path}: cannot read BPE vocabulary: {reason}")]
    Read { path: String, reason: String },
    #[error("BPE vocabulary {source_name}: {reason}")]
    Format { source_name: String, reason: String },
}

pub struct ClipTokenizer {
    encoder: HashMap<String, i64>,
    ranks: HashMap<(String, String), usize>,
    byte_encoder: [char; 256],
    pattern: Regex,
}

impl std::fmt::Debug for ClipTokenizer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ClipTokenizer")
            .field("vocab_size", &self.encoder.len())
            .finish()
    }
}

/// CLIP's reversible byte → printable-unicode table.
fn bytes_to_unicode() -> [char; 256] {
    let mut table = ['\0'; 256];
    let mut printable = vec![false; 256];
    for r in [(b'!', b'~'), (0xA1u8, 0xACu8), (0xAEu8, 0xFFu8)] {
        for b in r.0..=r.1 {
            printable[b as usize] = true;
        }
    }
    let mut n = 0u32;
    for b in 0..256usize {
        table[b] = if printable[b] {
            char::from_u32(b as u32).unwrap_or('\u{FFFD}')
        } else {
            let c = char::from_u32(256 + n).unwrap_or('\u{FFFD}');
            n += 1;
            c
        };
    }
    table
}

impl ClipTokenizer {
    /// The tokenizer with the embedded standard vocabulary.
    pub fn standard() -> Result<Self, TokenizerError> {
        let mut text = String::new();
        flate2::read::GzDecoder::new(EMBEDDED_VOCAB_GZ)
            .read_to_string(&mut text)
            .map_err(|e| TokenizerError::Format {
                source_name: "embedded".into(),
                reason: e.to_string(),
            })?;
        Self::from_merges_text(&text, "embedded")
    }

    /// Loads `bpe_simple_vocab_16e6.txt` (plain or `.gz`).
    pub fn from_file(path: &Path) -> Result<Self, TokenizerError> {
        let bytes = std::fs::read(path).map_err(|e| TokenizerError::Read {
            path: path.display().to_string(),
            reason: e.to_string(),
        })?;
        let text = if bytes.starts_with(&[0x1f, 0x8b]) {
            let mut s = String::new();
            flate2::read::GzDecoder::new(&bytes[..])
                .read_to_string(&mut s)
                .map_err(|e| TokenizerError::Read {
                    path: path.display().to_string(),
                    reason: e.to_string(),
                })?;
            s
        } else {
            String::from_utf8(bytes).map_err(|e| TokenizerError::Read {
                path: path.display().to_string(),
                reason: e.to_string(),
            })?
        };
        Self::from_merges_text(&text, &path.display().to_string())
    }

    fn from_merges_text(text: &str, source_name: &str) -> Result<Self, TokenizerError> {
        let fmt_err = |reason: String| TokenizerError::Format {
            source_name: source_name.to_string(),
            reason,
        };
        // lines 1 .. 48894 inclusive are the merges (line 0 is a version header)
        const N_MERGES: usize = 49152 - 256 - 2;
        let lines: Vec<&str> = text.split('\n').collect();
        if lines.len() < N_MERGES + 1 {
            return Err(fmt_err(format!(
                "{} lines, expected at least {}",
                lines.len(),
                N_MERGES + 1
            )));
        }
        let mut merges = Vec::with_capacity(N_MERGES);
        for (i, line) in lines[1..=N_MERGES].iter().enumerate() {
            let mut parts = line.split(' ');
            match (parts.next(), parts.next(), parts.next()) {
                (Some(a), Some(b), None) if !a.is_empty() && !b.is_empty() => {
                    merges.push((a.to_string(), b.to_string()))
                }
                _ => {
                    return Err(fmt_err(format!(
                        "line {}: not a merge pair: {line:?}",
                        i + 2
                    )))
                }
            }
        }
        let byte_encoder = bytes_to_unicode();
        // CLIP's order: the printable bytes first (in byte order), then the
        // remapped ones, i.e. by the code point they map to
        let mut base: Vec<char> = byte_encoder.to_vec();
        base.sort_by_key(|c| {
            let cp = *c as u32;
            if cp < 256 {
                (0, cp)
            } else {
                (1, cp)
            }
        });
        let mut vocab: Vec<String> = base.iter().map(|c| c.to_string()).collect();
        let with_end: Vec<String> = vocab.iter().map(|v| format!("{v}</w>")).collect();
        vocab.extend(with_end);
        vocab.extend(merges.iter().map(|(a, b)| format!("{a}{b}")));
        vocab.push("<|startoftext|>".into());
        vocab.push("<|endoftext|>".into());
        let encoder = vocab
            .into_iter()
            .enumerate()
            .map(|(i, v)| (v, i as i64))
            .collect();
        let ranks = merges
            .into_iter()
            .enumerate()
            .map(|(i, m)| (m, i))
            .collect();
        let pattern = Regex::new(
            r"(?i)<\|startoftext\|>|<\|endoftext\|>|'s|'t|'re|'ve|'m|'ll|'d|[\p{L}]+|[\p{N}]|[^\s\p{L}\p{N}]+",
        )
        .map_err(|e| fmt_err(e.to_string()))?;
        Ok(ClipTokenizer {
            encoder,
            ranks,
            byte_encoder,
            pattern,
        })
    }

    fn bpe(&self, token: &str) -> Vec<String> {
        let chars: Vec<char> = token.chars().collect();
        let Some((last, init)) = chars.split_last() else {
            return Vec::new();
        };
        let mut word: Vec<String> = init.iter().map(|c| c.to_string()).collect();
        word.push(format!("{last}</w>"));
        loop {
            if word.len() < 2 {
                break;
            }
            let best = word
                .windows(2)
                .filter_map(|p| {
                    self.ranks
                        .get(&(p[0].clone(), p[1].clone()))
                        .map(|&r| (r, p[0].clone(), p[1].clone()))
                })
                .min_by_key(|(r, _, _)| *r);
            let Some((_, first, second)) = best else {
                break;
            };
            let mut merged = Vec::with_capacity(word.len());
            let mut i = 0;
            while i < word.len() {
                if i + 1 < word.len() && word[i] == first && word[i + 1] == second {
                    merged.push(format!("{first}{second}"));
                    i += 2;
                } else {
                    merged.push(word[i].clone());
                    i += 1;
                }
            }
            word = merged;
        }
        word
    }

    /// Token ids of `text` without start/end markers.
    pub fn encode(&self, text: &str) -> Vec<i64> {
        let cleaned = clean(text);
        let mut ids = Vec::new();
        for m in self.pattern.find_iter(&cleaned) {
            let piece: String = m
                .as_str()
                .bytes()
                .map(|b| self.byte_encoder[b as usize])
                .collect();
            for sub in self.bpe(&piece) {
                // every BPE output symbol is in the vocabulary by construction
                if let Some(&id) = self.encoder.get(&sub) {
                    ids.push(id);
                }
            }
        }
        ids
    }

    /// `[SOT, ids…, EOT]`, truncated so EOT always ends it within
    /// `CONTEXT_LENGTH`.
    pub fn encode_with_markers(&self, text: &str) -> Vec<i64> {
        let mut ids = vec![START_OF_TEXT];
        let body = self.encode(text);
        ids.extend(body.into_iter().take(CONTEXT_LENGTH - 2));
        ids.push(END_OF_TEXT);
        ids
    }

    /// Fixed-length row for the text encoder: markers, zero padding to 77.
    pub fn tokenize_padded(&self, text: &str) -> [i64; CONTEXT_LENGTH] {
        let mut row = [0i64; CONTEXT_LENGTH];
        for (slot, id) in row.iter_mut().zip(self.encode_with_markers(text)) {
            *slot = id;
        }
        row
    }
}

fn clean(text: &str) -> String {
    let unescaped = text
        .replace("&quot;", "\"")
        .replace("&#39;", "'")
        .replace("&apos;", "'")
        .replace("&lt;", "<")
        .replace("&gt;", ">")
        .replace("&amp;", "&");
    unescaped
        .split_whitespace()
        .collect::<Vec<_>>()
        .join(" ")
        .to_lowercase()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn golden_ids() {
        let t = ClipTokenizer::standard().unwrap();
        assert_eq!(
            t.encode_with_markers("a photo of a chair"),
            vec![49406, 320, 1125, 539, 320, 4269, 49407]
        );
        assert_eq!(
            t.encode_with_markers("door handle"),
            vec![49406, 2489, 7245, 49407]
        );
        assert_eq!(t.encode_with_markers("person"), vec![49406, 2533, 49407]);
        assert_eq!(
            t.encode_with_markers("wheelchair ramp"),
            vec![49406, 17713, 14271, 49407]
        );
        // case and spacing do not matter
        assert_eq!(t.encode("  Door   HANDLE "), vec![2489, 7245]);
    }

    #[test]
    fn padding_and_truncation() {
        let t = ClipTokenizer::standard().unwrap();
        let row = t.tokenize_padded("person");
        assert_eq!(&row[..4], &[49406, 2533, 49407, 0]);
        assert!(row[3..].iter().all(|&x| x == 0));
        let long = "chair ".repeat(100);
        let row = t.tokenize_padded(&long);
        assert_eq!(row[0], START_OF_TEXT);
        assert_eq!(row[76], END_OF_TEXT);
        assert!(row[1..76].iter().all(|&x| x == 4269));
    }

    #[test]
    fn bad_vocabulary_file_is_an_error() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("vocab.txt");
        std::fs::write(&p, "#version: 0.2\ni n\n").unwrap();
        let e = ClipTokenizer::from_file(&p).unwrap_err().to_string();
        assert!(e.contains("vocab.txt"), "{e}");
        assert!(ClipTokenizer::from_file(&dir.path().join("missing.txt")).is_err());
    }
}
