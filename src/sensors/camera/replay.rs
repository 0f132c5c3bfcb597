//! A recorded RGB-D stream in the TUM RGB-D layout:
//!
//! ```text
//! DIR/rgb.txt          "timestamp filename" per line (# comments), seconds
//! DIR/depth.txt        same, 16-bit depth PNGs
//! DIR/rgb/…png, DIR/depth/…png
//! DIR/calibration.json opennav-calibration/1 (its depth_scale_m: 0.0002 for TUM's 5000 per metre)
//! ```
//! Colour and depth are paired by timestamp ([`super::associate`]); frames
//! without a partner are counted and skipped, never guessed.

use std::path::{Path, PathBuf};

use super::{associate, CameraError, CameraSource};
use crate::msg::RgbdCalibration;
use crate::msg::RgbdFrame;
use crate::msg::{DepthImage, RgbImage};
use crate::msg::{Stamp, Stamped};

/// Largest colour/depth time difference accepted as a pair, seconds.
pub const MAX_PAIR_DT_S: f64 = 0.02;

/// Timestamps beyond this (seconds; Unix time in the year 33 658) are
/// refused: a broken list, not a recording.
pub const MAX_TIMESTAMP_S: f64 = 1e12;

fn rerr(path: &Path, reason: impl std::fmt::Display) -> CameraError {
    CameraError::Recording {
        path: path.display().to_string(),
        reason: reason.to_string(),
    }
}

/// Parses a TUM list file: (timestamp s, relative path).
pub fn parse_list(text: &str, path: &Path) -> Result<Vec<(f64, String)>, CameraError> {
    let mut out = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let l = line.trim();
        if l.is_empty() || l.starts_with('#') {
            continue;
        }
        let mut it = l.split_whitespace();
        let (Some(t), Some(f)) = (it.next(), it.next()) else {
            return Err(rerr(
                path,
                format!("line {}: expected `timestamp filename`", i + 1),
            ));
        };
        let t: f64 = t
            .parse()
            .ok()
            .filter(|t: &f64| t.is_finite())
            .ok_or_else(|| {
                rerr(
                    path,
                    format!("line {}: timestamp `{t}` is not a number", i + 1),
                )
            })?;
        if !(0.0..=MAX_TIMESTAMP_S).contains(&t) {
            return Err(rerr(
                path,
                format!(
                    "line {}: timestamp `{t}` is out of range (0 to {MAX_TIMESTAMP_S:e} s)",
                    i + 1
                ),
            ));
        }
        if f.contains("..") {
            return Err(rerr(
                path,
                format!("line {}: `{f}` leaves the recording", i + 1),
            ));
        }
        out.push((t, f.to_string()));
    }
    Ok(out)
}

pub struct ReplaySource {
    dir: PathBuf,
    calibration: RgbdCalibration,
    /// (colour t, colour file, depth t, depth file), by colour time
    pairs: Vec<(f64, String, f64, String)>,
    next: usize,
    t0: f64,
    /// Colour frames that found no depth partner.
    pub unpaired_color: usize,
    pub unpaired_depth: usize,
    /// Start over at the end.
    pub looping: bool,
}

impl ReplaySource {
    pub fn open(dir: &Path) -> Result<Self, CameraError> {
        let read = |name: &str| -> Result<Vec<(f64, String)>, CameraError> {
            let p = dir.join(name);
            let text = std::fs::read_to_string(&p).map_err(|e| rerr(&p, e))?;
            parse_list(&text, &p)
        };
        let colors = read("rgb.txt")?;
        let depths = read("depth.txt")?;
        let calibration = RgbdCalibration::load(&dir.join("calibration.json"))?;
        let ct: Vec<f64> = colors.iter().map(|c| c.0).collect();
        let dt: Vec<f64> = depths.iter().map(|d| d.0).collect();
        let idx = associate(&ct, &dt, MAX_PAIR_DT_S);
        if idx.is_empty() {
            return Err(rerr(
                dir,
                format!(
                    "no colour frame has a depth frame within {} ms",
                    MAX_PAIR_DT_S * 1e3
                ),
            ));
        }
        let mut pairs: Vec<(f64, String, f64, String)> = idx
            .iter()
            .map(|&(i, j)| {
                (
                    colors[i].0,
                    colors[i].1.clone(),
                    depths[j].0,
                    depths[j].1.clone(),
                )
            })
            .collect();
        pairs.sort_by(|a, b| a.0.total_cmp(&b.0));
        let t0 = pairs.first().map(|p| p.0).unwrap_or(0.0);
        Ok(ReplaySource {
            dir: dir.to_path_buf(),
            calibration,
            unpaired_color: colors.len() - pairs.len(),
            unpaired_depth: depths.len() - pairs.len(),
            pairs,
            next: 0,
            t0,
            looping: false,
        })
    }

    pub fn len(&self) -> usize {
        self.pairs.len()
    }

    pub fn is_empty(&self) -> bool {
        self.pairs.is_empty()
    }
}

impl CameraSource for ReplaySource {
    fn calibration(&self) -> &RgbdCalibration {
        &self.calibration
    }

    fn next_frame(&mut self) -> Result<Option<Stamped<RgbdFrame>>, CameraError> {
        if self.next >= self.pairs.len() {
            if !self.looping {
                return Ok(None);
            }
            self.next = 0;
        }
        let (ct, cf, dt, df) = self.pairs[self.next].clone();
        self.next += 1;
        let color = RgbImage::load(&self.dir.join(&cf))?;
        let depth =
            DepthImage::load_png(&self.dir.join(&df), self.calibration.depth_scale_m as f32)?;
        let cs = Stamp::from_secs_f64(ct - self.t0);
        Ok(Some(Stamped::new(
            cs,
            RgbdFrame {
                color,
                depth,
                color_stamp: cs,
                depth_stamp: Stamp::from_secs_f64((dt - self.t0).max(0.0)),
            },
        )))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_timestamp_out_of_range_is_an_error_naming_its_line() {
        let p = Path::new("rgb.txt");
        assert!(parse_list("1.5 rgb/1.png\n", p).is_ok());
        for t in ["1e300", "-3", "inf", "nan"] {
            let e = parse_list(&format!("# a list\n1.0 rgb/0.png\n{t} rgb/1.png\n"), p)
                .expect_err(t)
                .to_string();
            assert!(e.contains("rgb.txt") && e.contains("line 3"), "{t}: {e}");
        }
    }
}
