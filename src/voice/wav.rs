//! Audio files for the recogniser: WAV (PCM, 16-bit, mono, 16 kHz) or raw
//! 16-bit little-endian samples at 16 kHz (`.raw`). Anything else is an
//! error naming the file and what to do about it.

use std::path::Path;

/// The rate the acoustic model wants.
pub const RATE_HZ: u32 = 16_000;

fn err(path: &Path, what: impl std::fmt::Display) -> String {
    format!("{}: {what}", path.display())
}

fn u16_at(b: &[u8], i: usize) -> Option<u16> {
    Some(u16::from_le_bytes([*b.get(i)?, *b.get(i + 1)?]))
}

fn u32_at(b: &[u8], i: usize) -> Option<u32> {
    Some(u32::from_le_bytes([
        *b.get(i)?,
        *b.get(i + 1)?,
        *b.get(i + 2)?,
        *b.get(i + 3)?,
    ]))
}

fn s16le(bytes: &[u8]) -> Vec<i16> {
    bytes
        .chunks_exact(2)
        .map(|c| i16::from_le_bytes([c[0], c[1]]))
        .collect()
}

/// The samples of a WAV file's bytes (16 kHz mono 16-bit PCM).
pub fn parse_wav(path: &Path, b: &[u8]) -> Result<Vec<i16>, String> {
    if b.len() < 12 || &b[0..4] != b"RIFF" || &b[8..12] != b"WAVE" {
        return Err(err(path, "not a WAV file (no RIFF/WAVE header)"));
    }
    let mut i = 12usize;
    let mut format: Option<(u16, u16, u32, u16)> = None;
    while i + 8 <= b.len() {
        let id = &b[i..i + 4];
        let len = u32_at(b, i + 4).ok_or_else(|| err(path, "truncated chunk header"))? as usize;
        let body_start = i + 8;
        // espeak-ng writing to a pipe leaves the data length at 0x7fffffff
        let body_end = body_start.saturating_add(len).min(b.len());
        match id {
            b"fmt " => {
                let f = &b[body_start..body_end];
                format = Some((
                    u16_at(f, 0).ok_or_else(|| err(path, "short fmt chunk"))?,
                    u16_at(f, 2).ok_or_else(|| err(path, "short fmt chunk"))?,
                    u32_at(f, 4).ok_or_else(|| err(path, "short fmt chunk"))?,
                    u16_at(f, 14).ok_or_else(|| err(path, "short fmt chunk"))?,
                ));
            }
            b"data" => {
                let (fmt, channels, rate, bits) =
                    format.ok_or_else(|| err(path, "data before the fmt chunk"))?;
                if fmt != 1 || bits != 16 || channels != 1 || rate != RATE_HZ {
                    return Err(err(
                        path,
                        format!(
                            "{rate} Hz, {channels} channel(s), {bits}-bit, format {fmt}: \
                             16000 Hz mono 16-bit PCM needed \
                             (sox IN -r 16000 -c 1 -b 16 -e signed-integer OUT.wav)"
                        ),
                    ));
                }
                return Ok(s16le(&b[body_start..body_end]));
            }
            _ => {}
        }
        // chunks are padded to an even length
        i = body_start.saturating_add(len + (len & 1));
    }
    Err(err(path, "no data chunk"))
}

/// Reads `path`: `.raw` as 16 kHz s16le mono, anything else as WAV.
pub fn read_audio(path: &Path) -> Result<Vec<i16>, String> {
    let b = std::fs::read(path).map_err(|e| err(path, e))?;
    if path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("raw"))
    {
        if !b.len().is_multiple_of(2) {
            return Err(err(path, "odd number of bytes for 16-bit samples"));
        }
        return Ok(s16le(&b));
    }
    parse_wav(path, &b)
}

/// 16-bit mono 16 kHz PCM as a WAV file (what [`read_audio`] reads back).
pub fn mono_16k_wav(samples: &[i16]) -> Vec<u8> {
    let data = (samples.len() * 2) as u32;
    let mut b = Vec::with_capacity(44 + data as usize);
    b.extend_from_slice(b"RIFF");
    b.extend_from_slice(&(36 + data).to_le_bytes());
    b.extend_from_slice(b"WAVEfmt ");
    b.extend_from_slice(&16u32.to_le_bytes());
    b.extend_from_slice(&1u16.to_le_bytes()); // PCM
    b.extend_from_slice(&1u16.to_le_bytes()); // mono
    b.extend_from_slice(&16_000u32.to_le_bytes());
    b.extend_from_slice(&32_000u32.to_le_bytes());
    b.extend_from_slice(&2u16.to_le_bytes());
    b.extend_from_slice(&16u16.to_le_bytes());
    b.extend_from_slice(b"data");
    b.extend_from_slice(&data.to_le_bytes());
    for s in samples {
        b.extend_from_slice(&s.to_le_bytes());
    }
    b
}

#[cfg(test)]
mod tests {
    use super::*;

    fn wav(rate: u32, channels: u16, samples: &[i16]) -> Vec<u8> {
        let mut b = b"RIFF\0\0\0\0WAVEfmt ".to_vec();
        b.extend(16u32.to_le_bytes());
        b.extend(1u16.to_le_bytes());
        b.extend(channels.to_le_bytes());
        b.extend(rate.to_le_bytes());
        b.extend((rate * 2 * channels as u32).to_le_bytes());
        b.extend((2 * channels).to_le_bytes());
        b.extend(16u16.to_le_bytes());
        b.extend(b"data");
        b.extend(((samples.len() * 2) as u32).to_le_bytes());
        for s in samples {
            b.extend(s.to_le_bytes());
        }
        b
    }

    #[test]
    fn reads_16k_mono_and_names_what_else_is_wrong() {
        let p = Path::new("x.wav");
        assert_eq!(
            parse_wav(p, &wav(16_000, 1, &[1, -2, 3])).unwrap(),
            vec![1, -2, 3]
        );
        let e = parse_wav(p, &wav(22_050, 1, &[1])).unwrap_err();
        assert!(
            e.contains("x.wav") && e.contains("22050 Hz") && e.contains("sox"),
            "{e}"
        );
        assert!(parse_wav(p, &wav(16_000, 2, &[1, 2]))
            .unwrap_err()
            .contains("2 channel"));
        assert!(parse_wav(p, b"hello").unwrap_err().contains("not a WAV"));
        // any truncation: an error or fewer samples, never a panic
        let full = wav(16_000, 1, &[5; 100]);
        for n in 0..full.len() {
            let _ = parse_wav(p, &full[..n]);
        }
    }

    #[test]
    fn the_wav_header_says_16_khz_mono_16_bit() {
        let b = mono_16k_wav(&[1, -1, 300]);
        assert_eq!(b.len(), 44 + 6);
        let parsed = parse_wav(Path::new("x.wav"), &b).expect("parses");
        assert_eq!(parsed, vec![1, -1, 300]);
    }
}
