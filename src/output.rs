//! What `opennav detect` writes: the JSON report (stable schema, see
//! docs/perception.md), an overlay PNG and a PLY cloud per object.

use std::io::Write;
use std::path::Path;

use font8x8::UnicodeFonts;
use serde::Serialize;

use crate::msg::RgbImage;
use crate::perception::boxes::Object3D;
use crate::perception::detector::{Detection, PromptReport};
use crate::perception::masks::Mask;
use crate::perception::pipeline::{Dropped, Timing, ViewResult};

#[derive(Debug, Serialize)]
pub struct ObjectReport {
    pub label: String,
    pub score: f32,
    pub frame: &'static str,
    /// Axis-aligned box (as the paper): centre, size, corners, metres.
    pub center_m: [f64; 3],
    pub size_m: [f64; 3],
    pub min_m: [f64; 3],
    pub max_m: [f64; 3],
    /// Yaw of the box oriented about gravity (z), radians.
    pub yaw_rad: f64,
    /// The oriented box: centre, (length along yaw, width, height).
    pub oriented_center_m: [f64; 3],
    pub oriented_size_m: [f64; 3],
    /// Number of 3D points.
    pub points: usize,
    pub box_xyxy: Option<[f32; 4]>,
}

impl From<&Object3D> for ObjectReport {
    fn from(o: &Object3D) -> Self {
        ObjectReport {
            label: o.label.clone(),
            score: o.score,
            frame: o.frame.name(),
            center_m: o.aabb.center_m(),
            size_m: o.aabb.size_m(),
            min_m: o.aabb.min_m,
            max_m: o.aabb.max_m,
            yaw_rad: o.obb.yaw_rad,
            oriented_center_m: o.obb.center_m,
            oriented_size_m: o.obb.size_m,
            points: o.points.len(),
            box_xyxy: o.box_xyxy,
        }
    }
}

#[derive(Debug, Serialize)]
pub struct DetectReport {
    pub prompts: PromptReport,
    pub detections: Vec<Detection>,
    pub objects: Vec<ObjectReport>,
    pub dropped: Vec<Dropped>,
    pub timing_ms: Timing,
}

impl From<&ViewResult> for DetectReport {
    fn from(v: &ViewResult) -> Self {
        DetectReport {
            prompts: v.prompts.clone(),
            detections: v.detections.clone(),
            objects: v.objects.iter().map(ObjectReport::from).collect(),
            dropped: v.dropped.clone(),
            timing_ms: v.timing_ms,
        }
    }
}

const PALETTE: [[u8; 3]; 8] = [
    [230, 25, 75],
    [60, 180, 75],
    [255, 225, 25],
    [0, 130, 200],
    [245, 130, 48],
    [145, 30, 180],
    [70, 240, 240],
    [240, 50, 230],
];

/// The colour image with masks tinted, boxes outlined and labelled.
pub fn overlay(image: &RgbImage, detections: &[Detection], masks: &[Mask]) -> RgbImage {
    let mut out = image.clone();
    let (w, h) = (out.width(), out.height());
    for (i, m) in masks.iter().enumerate() {
        let c = PALETTE[i % PALETTE.len()];
        for (u, v) in m.pixels() {
            if u < w && v < h {
                let px = &mut out.data_mut()[(v * w + u) * 3..(v * w + u) * 3 + 3];
                for k in 0..3 {
                    px[k] = ((px[k] as u16 + c[k] as u16) / 2) as u8;
                }
            }
        }
    }
    for (i, d) in detections.iter().enumerate() {
        let c = PALETTE[i % PALETTE.len()];
        let [x1, y1, x2, y2] = d.box_xyxy;
        let (x1, y1) = (x1.max(0.0) as usize, y1.max(0.0) as usize);
        let (x2, y2) = (
            (x2.max(0.0) as usize).min(w.saturating_sub(1)),
            (y2.max(0.0) as usize).min(h.saturating_sub(1)),
        );
        for t in 0..2 {
            for u in x1..=x2 {
                put(&mut out, u, y1 + t, c);
                put(&mut out, u, y2.saturating_sub(t), c);
            }
            for v in y1..=y2 {
                put(&mut out, x1 + t, v, c);
                put(&mut out, x2.saturating_sub(t), v, c);
            }
        }
        let text = format!("{} {:.2}", d.label, d.score);
        let ty = y1.saturating_sub(10);
        for (u, v) in
            (x1..x1 + 8 * text.chars().count() + 2).flat_map(|u| (ty..ty + 10).map(move |v| (u, v)))
        {
            put(&mut out, u, v, c);
        }
        draw_text(&mut out, x1 + 1, ty + 1, &text, [0, 0, 0]);
    }
    out
}

pub(crate) fn put(img: &mut RgbImage, u: usize, v: usize, c: [u8; 3]) {
    let (w, h) = (img.width(), img.height());
    if u < w && v < h {
        img.data_mut()[(v * w + u) * 3..(v * w + u) * 3 + 3].copy_from_slice(&c);
    }
}

pub(crate) fn draw_text(img: &mut RgbImage, x: usize, y: usize, text: &str, c: [u8; 3]) {
    for (i, ch) in text.chars().enumerate() {
        let Some(glyph) = font8x8::BASIC_FONTS.get(ch) else {
            continue;
        };
        for (row, bits) in glyph.iter().enumerate() {
            for col in 0..8 {
                if bits & (1 << col) != 0 {
                    put(img, x + i * 8 + col, y + row, c);
                }
            }
        }
    }
}

/// Writes an ASCII PLY of the object's points (metres, in its frame).
pub fn write_ply(path: &Path, object: &Object3D) -> std::io::Result<()> {
    let mut f = std::io::BufWriter::new(std::fs::File::create(path)?);
    writeln!(f, "ply\nformat ascii 1.0")?;
    writeln!(
        f,
        "comment opennav object \"{}\" score {:.3} frame {}",
        object.label,
        object.score,
        object.frame.name()
    )?;
    writeln!(f, "element vertex {}", object.points.len())?;
    writeln!(
        f,
        "property float x\nproperty float y\nproperty float z\nend_header"
    )?;
    for p in &object.points {
        writeln!(f, "{} {} {}", p.x, p.y, p.z)?;
    }
    f.flush()
}

/// A file-name-safe form of a label.
pub fn slug(label: &str) -> String {
    label
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() {
                c.to_ascii_lowercase()
            } else {
                '_'
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::msg::Frame;
    use nalgebra::Point3;

    #[test]
    fn ply_round_trip_counts_vertices() {
        let o = Object3D::from_points(
            "door handle".into(),
            0.5,
            Frame::BaseLink,
            vec![Point3::new(1.0, 2.0, 3.0), Point3::new(1.5, 2.0, 3.0)],
            None,
        )
        .unwrap();
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join(format!("{}.ply", slug(&o.label)));
        write_ply(&p, &o).unwrap();
        let text = std::fs::read_to_string(&p).unwrap();
        assert!(text.contains("element vertex 2"));
        assert!(text.lines().last().unwrap().starts_with("1.5 2 3"));
        assert!(p.ends_with("door_handle.ply"));
    }

    #[test]
    fn overlay_draws_the_box_in_its_colour() {
        let img = RgbImage::filled(50, 50, [0, 0, 0]).unwrap();
        let d = Detection {
            label: "x".into(),
            class: "x".into(),
            score: 0.5,
            box_xyxy: [10.0, 20.0, 30.0, 40.0],
        };
        let o = overlay(&img, &[d], &[]);
        assert_eq!(o.pixel(20, 40), PALETTE[0]);
        assert_eq!(o.pixel(10, 30), PALETTE[0]);
        assert_eq!(o.pixel(20, 30), [0, 0, 0]);
    }
}
