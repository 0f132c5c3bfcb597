//! What the chair says, spoken: every sentence of the goal keeper, the
//! supervisor and the faults goes through espeak-ng (Debian `espeak-ng`)
//! with the configured voice, rate and volume, on its own thread: the
//! control path only hands a sentence over and never waits. When the
//! speaker falls behind, the oldest sentences are skipped (counted and
//! logged) so what it says is current; a stop is never delayed by speech.
//! For tests and technicians each sentence can be written to a WAV file
//! instead of the sound card.

use std::io::Write;
use std::path::PathBuf;
use std::process::{Command, Stdio};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::mpsc::{sync_channel, Receiver, SyncSender, TrySendError};
use std::sync::Arc;

/// Config `[speech]`.
#[derive(Debug, Clone, PartialEq, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SpeechSettings {
    /// Speak on the chair (`opennav run`; with --sim only with --speak).
    pub enabled: bool,
    /// The synthesiser: espeak-ng (or a compatible command).
    pub command: String,
    /// espeak-ng voice, e.g. "en", "en-gb", "de".
    pub voice: String,
    /// Words per minute (80–450).
    pub rate_wpm: u32,
    /// Amplitude (0–200; 100 is espeak-ng's default).
    pub volume: u32,
    /// Non-empty: each sentence is written as NNNN.wav (and NNNN.txt)
    /// here instead of being played (tests, checking a voice setting).
    pub wav_dir: String,
}

#[derive(Debug, thiserror::Error)]
pub enum SpeechError {
    #[error("speech: {command} cannot be run ({reason}); install Debian's espeak-ng or set speech.enabled = false")]
    Missing { command: String, reason: String },
    #[error("speech: wav_dir {dir}: {reason}")]
    WavDir { dir: String, reason: String },
}

/// Sentences waiting at most; older ones are skipped when it is full.
const QUEUE: usize = 4;

/// The speaking thread's handle.
pub struct Speaker {
    tx: SyncSender<String>,
    /// Sentences skipped because the speaker was behind.
    pub skipped: Arc<AtomicU64>,
    /// Sentences the synthesiser failed on.
    pub failed: Arc<AtomicU64>,
    thread: Option<std::thread::JoinHandle<()>>,
}

impl Speaker {
    /// Checks the synthesiser runs, then starts the thread.
    pub fn start(s: &SpeechSettings) -> Result<Speaker, SpeechError> {
        let missing = |reason: String| SpeechError::Missing {
            command: s.command.clone(),
            reason,
        };
        let out = Command::new(&s.command)
            .arg("--version")
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .status()
            .map_err(|e| missing(e.to_string()))?;
        if !out.success() {
            return Err(missing(format!("--version exited with {out}")));
        }
        if !s.wav_dir.is_empty() {
            std::fs::create_dir_all(&s.wav_dir).map_err(|e| SpeechError::WavDir {
                dir: s.wav_dir.clone(),
                reason: e.to_string(),
            })?;
        }
        let (tx, rx) = sync_channel::<String>(QUEUE);
        let skipped = Arc::new(AtomicU64::new(0));
        let failed = Arc::new(AtomicU64::new(0));
        let settings = s.clone();
        let f = failed.clone();
        let thread = std::thread::Builder::new()
            .name("speech".into())
            .spawn(move || speak_all(&settings, rx, &f))
            .map_err(|e| missing(format!("thread: {e}")))?;
        Ok(Speaker {
            tx,
            skipped,
            failed,
            thread: Some(thread),
        })
    }

    /// Hands a sentence over; never waits.
    pub fn say(&self, sentence: &str) {
        match self.tx.try_send(sentence.to_string()) {
            Ok(()) => {}
            Err(TrySendError::Full(_)) => {
                self.skipped.fetch_add(1, Ordering::Relaxed);
                tracing::warn!(
                    sentence,
                    "speech behind: a sentence not spoken (it is in the log and the status)"
                );
            }
            Err(TrySendError::Disconnected(_)) => {
                tracing::error!(sentence, "the speech thread is gone: not spoken");
            }
        }
    }

    /// Says what is queued, then ends the thread.
    pub fn finish(self) {
        let Speaker { tx, thread, .. } = self;
        drop(tx);
        if let Some(t) = thread {
            if t.join().is_err() {
                tracing::error!("the speech thread panicked");
            }
        }
    }
}

fn speak_all(s: &SpeechSettings, rx: Receiver<String>, failed: &AtomicU64) {
    let mut n = 0u64;
    let mut failing = 0u32;
    while let Ok(sentence) = rx.recv() {
        n += 1;
        let wav: Option<PathBuf> =
            (!s.wav_dir.is_empty()).then(|| PathBuf::from(&s.wav_dir).join(format!("{n:04}.wav")));
        match speak(s, &sentence, wav.as_ref()) {
            Ok(()) => {
                failing = 0;
                if let Some(w) = &wav {
                    let txt = w.with_extension("txt");
                    if let Err(e) = std::fs::write(&txt, &sentence) {
                        tracing::warn!(error = %e, path = %txt.display(), "speech: text not written");
                    }
                }
            }
            Err(e) => {
                failed.fetch_add(1, Ordering::Relaxed);
                failing += 1;
                if failing <= 3 {
                    tracing::error!(error = %e, sentence, "speech: not spoken");
                }
            }
        }
    }
}

/// One sentence through the synthesiser (the text on its stdin, so that
/// nothing in it is taken for an option).
fn speak(s: &SpeechSettings, sentence: &str, wav: Option<&PathBuf>) -> Result<(), String> {
    let mut cmd = Command::new(&s.command);
    cmd.args(["--stdin", "-v", &s.voice])
        .args(["-s", &s.rate_wpm.to_string()])
        .args(["-a", &s.volume.to_string()])
        .stdin(Stdio::piped())
        .stdout(Stdio::null())
        .stderr(Stdio::piped());
    if let Some(w) = wav {
        cmd.arg("-w").arg(w);
    }
    let mut child = cmd.spawn().map_err(|e| e.to_string())?;
    if let Some(mut stdin) = child.stdin.take() {
        stdin
            .write_all(sentence.as_bytes())
            .map_err(|e| e.to_string())?;
    }
    let out = child.wait_with_output().map_err(|e| e.to_string())?;
    if out.status.success() {
        Ok(())
    } else {
        Err(format!(
            "{} exited with {}: {}",
            s.command,
            out.status,
            String::from_utf8_lossy(&out.stderr).trim()
        ))
    }
}
