//! Voice activity detection: splits a 16 kHz stream into utterances by
//! frame energy against a tracked noise floor. Pure: samples in,
//! finished utterances out.
//!
//! A 10 ms frame is speech when its level is `margin_db` above the noise
//! floor (and above an absolute minimum); an utterance starts after
//! `start_frames` speech frames (with `pre_roll` frames kept before it)
//! and ends after `end_silence` of non-speech, or at `max_len`.

use std::collections::VecDeque;

/// Samples per 10 ms frame at 16 kHz.
pub const FRAME: usize = 160;

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VadSettings {
    pub margin_db: f64,
    pub min_level_dbfs: f64,
    pub start_frames: usize,
    pub end_silence_frames: usize,
    pub pre_roll_frames: usize,
    pub max_frames: usize,
}

impl Default for VadSettings {
    fn default() -> Self {
        VadSettings {
            margin_db: 12.0,
            min_level_dbfs: -50.0,
            start_frames: 3,
            end_silence_frames: 50,
            pre_roll_frames: 20,
            max_frames: 600,
        }
    }
}

/// A frame's level, dBFS.
pub fn level_dbfs(frame: &[i16]) -> f64 {
    if frame.is_empty() {
        return -120.0;
    }
    let ms: f64 = frame.iter().map(|&s| (s as f64) * (s as f64)).sum::<f64>() / frame.len() as f64;
    10.0 * (ms / (32768.0 * 32768.0)).max(1e-12).log10()
}

#[derive(Debug, Clone)]
pub struct Vad {
    s: VadSettings,
    noise_db: f64,
    pending: Vec<i16>,
    recent: VecDeque<Vec<i16>>,
    run: usize,
    utterance: Option<(Vec<i16>, usize, usize)>,
}

impl Vad {
    pub fn new(s: VadSettings) -> Self {
        Vad {
            s,
            noise_db: -70.0,
            pending: Vec::new(),
            recent: VecDeque::new(),
            run: 0,
            utterance: None,
        }
    }

    /// Feeds samples; returns the utterances they completed.
    pub fn push(&mut self, samples: &[i16]) -> Vec<Vec<i16>> {
        self.pending.extend_from_slice(samples);
        let mut out = Vec::new();
        let mut start = 0;
        while self.pending.len() - start >= FRAME {
            let frame = self.pending[start..start + FRAME].to_vec();
            start += FRAME;
            if let Some(u) = self.frame(frame) {
                out.push(u);
            }
        }
        self.pending.drain(..start);
        out
    }

    /// The end of the stream: an utterance in progress is finished.
    pub fn flush(&mut self) -> Option<Vec<i16>> {
        self.utterance.take().map(|(u, _, _)| u)
    }

    fn frame(&mut self, frame: Vec<i16>) -> Option<Vec<i16>> {
        let level = level_dbfs(&frame);
        let speech = level > self.noise_db + self.s.margin_db && level > self.s.min_level_dbfs;
        if !speech {
            // the floor follows quiet frames (fast down, slow up)
            let k = if level < self.noise_db { 0.3 } else { 0.02 };
            self.noise_db += k * (level - self.noise_db);
        }
        if let Some((u, frames, silent)) = &mut self.utterance {
            u.extend_from_slice(&frame);
            *frames += 1;
            *silent = if speech { 0 } else { *silent + 1 };
            if *silent >= self.s.end_silence_frames || *frames >= self.s.max_frames {
                return self.utterance.take().map(|(u, _, _)| u);
            }
            return None;
        }
        self.run = if speech { self.run + 1 } else { 0 };
        self.recent.push_back(frame);
        while self.recent.len() > self.s.pre_roll_frames + self.s.start_frames {
            self.recent.pop_front();
        }
        if self.run >= self.s.start_frames {
            let u: Vec<i16> = self.recent.drain(..).flatten().collect();
            let frames = u.len() / FRAME;
            self.run = 0;
            self.utterance = Some((u, frames, 0));
        }
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tone(ms: usize, amp: f64) -> Vec<i16> {
        (0..ms * 16)
            .map(|i| (amp * (i as f64 * 0.2).sin()) as i16)
            .collect()
    }

    fn quiet(ms: usize) -> Vec<i16> {
        // faint noise, not digital silence
        (0..ms * 16)
            .map(|i| ((i * 7919) % 21) as i16 - 10)
            .collect()
    }

    #[test]
    fn two_words_with_a_pause_are_two_utterances() {
        let mut v = Vad::new(VadSettings::default());
        let mut audio = quiet(500);
        audio.extend(tone(400, 8000.0));
        audio.extend(quiet(800));
        audio.extend(tone(300, 8000.0));
        audio.extend(quiet(800));
        let mut got = Vec::new();
        for chunk in audio.chunks(1000) {
            got.extend(v.push(chunk));
        }
        assert_eq!(
            got.len(),
            2,
            "{:?}",
            got.iter().map(Vec::len).collect::<Vec<_>>()
        );
        // each holds its word, its pre-roll and its trailing silence
        let ms = |u: &Vec<i16>| u.len() / 16;
        assert!((400..=1150).contains(&ms(&got[0])), "{}", ms(&got[0]));
        assert!((300..=1050).contains(&ms(&got[1])), "{}", ms(&got[1]));
        assert!(v.flush().is_none());
    }

    #[test]
    fn a_click_is_not_an_utterance_and_a_long_one_is_cut() {
        let mut v = Vad::new(VadSettings::default());
        let mut audio = quiet(500);
        audio.extend(tone(20, 8000.0));
        audio.extend(quiet(800));
        assert!(v.push(&audio).is_empty());
        let mut long = tone(7000, 8000.0);
        long.extend(quiet(100));
        let got = v.push(&long);
        assert_eq!(got.len(), 1);
        assert!(got[0].len() <= 600 * FRAME);
    }
}
