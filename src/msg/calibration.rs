//! Camera models and the calibration file: pinhole intrinsics, the RGB-D
//! rig (`RgbdCalibration`) and the transforms as written in files.
//!
//! Calibration file (JSON, `opennav-calibration/1`):
//! ```json
//! {
//!   "format": "opennav-calibration/1",
//!   "color": {"width": 640, "height": 480, "fx": 521.2, "fy": 493.0, "cx": 322.5, "cy": 259.1},
//!   "depth": {"width": 640, "height": 480, "fx": 572.9, "fy": 542.7, "cx": 314.6, "cy": 240.2},
//!   "depth_scale_m": 0.001,
//!   "color_from_depth": {"rotation": [[1,0,0],[0,1,0],[0,0,1]], "translation_m": [0.0, 0.0, 0.0]},
//!   "base_from_camera": {"rotation": [[0,0,1],[-1,0,0],[0,-1,0]], "translation_m": [0.3, 0.0, 0.9]}
//! }
//! ```
//! - `color`: pinhole intrinsics of the colour camera, pixels.
//! - `depth`: intrinsics of the depth camera; omit it when the depth image is
//!   already registered to the colour image (RealSense "aligned" streams).
//! - `depth_scale_m`: metres per depth count of the 16-bit depth PNG.
//! - `color_from_depth`: pose of the depth optical frame in the colour optical
//!   frame (required with `depth`).
//! - `base_from_camera`: pose of the colour optical frame (z forward, x right,
//!   y down) in the chair's `base_link` (x forward, y left, z up).
//!
//! Rotations are 3×3 row-major matrices that must be orthonormal with
//! determinant +1 (to 1e-4); translations are metres. Lens distortion is not
//! modelled: streams are expected rectified, as RealSense delivers them.

use std::path::Path;

use nalgebra::{Isometry3, Matrix3, Point3, Rotation3, Translation3, UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};
use thiserror::Error;

#[derive(Debug, Error)]
pub enum CalibrationError {
    #[error("{path}: cannot read calibration: {reason}")]
    Read { path: String, reason: String },
    #[error("{path}: invalid calibration: {reason}")]
    Parse { path: String, reason: String },
    #[error("calibration key `{key}`: {reason}")]
    Invalid { key: String, reason: String },
}

/// Pinhole intrinsics in pixels.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Intrinsics {
    pub width: usize,
    pub height: usize,
    pub fx: f64,
    pub fy: f64,
    pub cx: f64,
    pub cy: f64,
}

impl Intrinsics {
    fn validate(&self, key: &str) -> Result<(), CalibrationError> {
        let bad = |field: &str, reason: String| CalibrationError::Invalid {
            key: format!("{key}.{field}"),
            reason,
        };
        if self.width == 0 || self.height == 0 || self.width > 16384 || self.height > 16384 {
            return Err(bad(
                "width",
                format!("image size {}x{} out of range", self.width, self.height),
            ));
        }
        for (name, f) in [("fx", self.fx), ("fy", self.fy)] {
            if !(f.is_finite() && f > 1.0 && f < 1.0e5) {
                return Err(bad(
                    name,
                    format!("focal length {f} px out of range (1, 1e5)"),
                ));
            }
        }
        for (name, c, lim) in [
            ("cx", self.cx, self.width as f64),
            ("cy", self.cy, self.height as f64),
        ] {
            if !(c.is_finite() && c >= 0.0 && c <= lim) {
                return Err(bad(
                    name,
                    format!("principal point {c} px outside the image (0..{lim})"),
                ));
            }
        }
        Ok(())
    }

    /// Back-projects pixel (u, v) at depth `z_m` into the camera's optical frame.
    #[inline]
    pub fn back_project(&self, u: f64, v: f64, z_m: f64) -> Point3<f64> {
        Point3::new(
            (u - self.cx) * z_m / self.fx,
            (v - self.cy) * z_m / self.fy,
            z_m,
        )
    }

    /// Projects a point of the optical frame to a pixel; None behind the camera.
    #[inline]
    pub fn project(&self, p: &Point3<f64>) -> Option<(f64, f64)> {
        (p.z > 0.0).then(|| (self.fx * p.x / p.z + self.cx, self.fy * p.y / p.z + self.cy))
    }
}

/// A rigid transform as written in the calibration and config files.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TransformSpec {
    pub rotation: [[f64; 3]; 3],
    pub translation_m: [f64; 3],
}

impl TransformSpec {
    pub fn identity() -> Self {
        TransformSpec {
            rotation: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
            translation_m: [0.0; 3],
        }
    }

    /// Validated isometry; `key` names the field in errors.
    pub fn to_isometry(&self, key: &str) -> Result<Isometry3<f64>, CalibrationError> {
        let r = &self.rotation;
        let m = Matrix3::new(
            r[0][0], r[0][1], r[0][2], r[1][0], r[1][1], r[1][2], r[2][0], r[2][1], r[2][2],
        );
        if m.iter().any(|v| !v.is_finite()) || self.translation_m.iter().any(|v| !v.is_finite()) {
            return Err(CalibrationError::Invalid {
                key: key.to_string(),
                reason: "non-finite value".into(),
            });
        }
        let ortho_err = (m.transpose() * m - Matrix3::identity()).abs().max();
        let det = m.determinant();
        if ortho_err > 1e-4 || (det - 1.0).abs() > 1e-4 {
            return Err(CalibrationError::Invalid {
                key: format!("{key}.rotation"),
                reason: format!(
                    "not a rotation (|RᵀR − I| = {ortho_err:.2e}, det = {det:.6}); expected orthonormal, det +1"
                ),
            });
        }
        let rot = Rotation3::from_matrix(&m);
        let t = self.translation_m;
        Ok(Isometry3::from_parts(
            Translation3::new(t[0], t[1], t[2]),
            UnitQuaternion::from_rotation_matrix(&rot),
        ))
    }

    pub fn from_isometry(iso: &Isometry3<f64>) -> Self {
        let m = iso.rotation.to_rotation_matrix();
        let m = m.matrix();
        let t = iso.translation.vector;
        TransformSpec {
            rotation: [
                [m[(0, 0)], m[(0, 1)], m[(0, 2)]],
                [m[(1, 0)], m[(1, 1)], m[(1, 2)]],
                [m[(2, 0)], m[(2, 1)], m[(2, 2)]],
            ],
            translation_m: [t.x, t.y, t.z],
        }
    }
}

/// The calibration file as written.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CalibrationFile {
    pub format: String,
    pub color: Intrinsics,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub depth: Option<Intrinsics>,
    pub depth_scale_m: f64,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub color_from_depth: Option<TransformSpec>,
    pub base_from_camera: TransformSpec,
    /// The floor's height in `base_link`, m, where base_link stands on a
    /// floor (the chair's: 0); absent for a sensor's own frame.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub floor_z_m: Option<f64>,
    /// Free text: where this calibration came from.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub source: Option<String>,
}

pub const CALIBRATION_FORMAT: &str = "opennav-calibration/1";

impl CalibrationFile {
    /// The file of a validated rig (what a recording keeps).
    pub fn of(c: &RgbdCalibration, source: Option<String>) -> CalibrationFile {
        CalibrationFile {
            format: CALIBRATION_FORMAT.into(),
            color: c.color,
            depth: c.depth.map(|(k, _)| k),
            depth_scale_m: c.depth_scale_m,
            color_from_depth: c.depth.map(|(_, t)| TransformSpec::from_isometry(&t)),
            base_from_camera: TransformSpec::from_isometry(&c.base_from_camera),
            floor_z_m: c.floor_z_m,
            source,
        }
    }
}

/// A validated RGB-D rig: colour intrinsics, optional separate depth camera,
/// and the camera's pose on the chair.
#[derive(Debug, Clone, PartialEq)]
pub struct RgbdCalibration {
    pub color: Intrinsics,
    /// Separate depth camera and `color_from_depth`; None when depth is
    /// already registered to colour.
    pub depth: Option<(Intrinsics, Isometry3<f64>)>,
    pub depth_scale_m: f64,
    pub base_from_camera: Isometry3<f64>,
    /// The floor's height in `base_link`, m, when base_link stands on a
    /// floor (the chair's: 0, z up); None when not known (a dataset's
    /// sensor frame). Objects' masks keep off the floor where it is known.
    pub floor_z_m: Option<f64>,
}

impl RgbdCalibration {
    /// Colour and depth share one registered image; the floor not known.
    pub fn registered(color: Intrinsics, base_from_camera: Isometry3<f64>) -> Self {
        RgbdCalibration {
            color,
            depth: None,
            depth_scale_m: 0.001,
            base_from_camera,
            floor_z_m: None,
        }
    }

    /// The same rig over a floor at `floor_z_m` in base_link.
    pub fn with_floor_z(self, floor_z_m: f64) -> Self {
        RgbdCalibration {
            floor_z_m: Some(floor_z_m),
            ..self
        }
    }

    pub fn load(path: &Path) -> Result<Self, CalibrationError> {
        let text = std::fs::read_to_string(path).map_err(|e| CalibrationError::Read {
            path: path.display().to_string(),
            reason: e.to_string(),
        })?;
        let file: CalibrationFile =
            serde_json::from_str(&text).map_err(|e| CalibrationError::Parse {
                path: path.display().to_string(),
                reason: e.to_string(),
            })?;
        Self::from_file(&file).map_err(|e| CalibrationError::Parse {
            path: path.display().to_string(),
            reason: e.to_string(),
        })
    }

    pub fn from_file(file: &CalibrationFile) -> Result<Self, CalibrationError> {
        if file.format != CALIBRATION_FORMAT {
            return Err(CalibrationError::Invalid {
                key: "format".into(),
                reason: format!("`{}`, expected `{CALIBRATION_FORMAT}`", file.format),
            });
        }
        file.color.validate("color")?;
        if !(file.depth_scale_m.is_finite() && file.depth_scale_m > 0.0 && file.depth_scale_m < 1.0)
        {
            return Err(CalibrationError::Invalid {
                key: "depth_scale_m".into(),
                reason: format!("{} m per count out of range (0, 1)", file.depth_scale_m),
            });
        }
        let depth = match (&file.depth, &file.color_from_depth) {
            (Some(d), Some(t)) => {
                d.validate("depth")?;
                Some((*d, t.to_isometry("color_from_depth")?))
            }
            (Some(_), None) => {
                return Err(CalibrationError::Invalid {
                    key: "color_from_depth".into(),
                    reason: "required when `depth` is given".into(),
                })
            }
            (None, Some(_)) => {
                return Err(CalibrationError::Invalid {
                    key: "depth".into(),
                    reason: "`color_from_depth` given without depth intrinsics".into(),
                })
            }
            (None, None) => None,
        };
        if let Some(z) = file
            .floor_z_m
            .filter(|z| !(z.is_finite() && z.abs() < 10.0))
        {
            return Err(CalibrationError::Invalid {
                key: "floor_z_m".into(),
                reason: format!("{z} m is not a floor height (finite, within 10 m)"),
            });
        }
        Ok(RgbdCalibration {
            color: file.color,
            depth,
            depth_scale_m: file.depth_scale_m,
            base_from_camera: file.base_from_camera.to_isometry("base_from_camera")?,
            floor_z_m: file.floor_z_m,
        })
    }

    /// Size the depth image must have.
    pub fn depth_size(&self) -> (usize, usize) {
        match &self.depth {
            Some((d, _)) => (d.width, d.height),
            None => (self.color.width, self.color.height),
        }
    }
}

/// Convenience: vector from an array.
pub fn vec3(a: [f64; 3]) -> Vector3<f64> {
    Vector3::new(a[0], a[1], a[2])
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// A 160×120 pinhole camera for tests, f 120, centred.
    pub(crate) fn intr_160x120() -> Intrinsics {
        Intrinsics {
            width: 160,
            height: 120,
            fx: 120.0,
            fy: 120.0,
            cx: 80.0,
            cy: 60.0,
        }
    }

    /// A small pinhole camera for tests (64×48, f 50).
    pub(crate) fn intr() -> Intrinsics {
        Intrinsics {
            width: 64,
            height: 48,
            fx: 50.0,
            fy: 50.0,
            cx: 32.0,
            cy: 24.0,
        }
    }

    #[test]
    fn project_inverts_back_project() {
        let k = intr();
        let p = k.back_project(10.0, 40.0, 2.0);
        let (u, v) = k.project(&p).unwrap();
        assert!((u - 10.0).abs() < 1e-12 && (v - 40.0).abs() < 1e-12);
        assert_eq!(
            p,
            Point3::new((10.0 - 32.0) * 2.0 / 50.0, (40.0 - 24.0) * 2.0 / 50.0, 2.0)
        );
    }

    #[test]
    fn non_rotation_is_rejected_with_its_key() {
        let mut t = TransformSpec::identity();
        t.rotation[0][0] = 2.0;
        let e = t.to_isometry("base_from_camera").unwrap_err().to_string();
        assert!(e.contains("base_from_camera.rotation"), "{e}");
    }

    #[test]
    fn the_floor_height_goes_through_the_file_and_a_bad_one_is_named() {
        let rig = RgbdCalibration::registered(intr(), Isometry3::identity());
        let back = RgbdCalibration::from_file(&CalibrationFile::of(&rig, None)).unwrap();
        assert_eq!(back.floor_z_m, None);
        let rig = rig.with_floor_z(-0.02);
        let file = CalibrationFile::of(&rig, None);
        let text = serde_json::to_string(&file).unwrap();
        assert!(text.contains("\"floor_z_m\":-0.02"), "{text}");
        let back = RgbdCalibration::from_file(&serde_json::from_str(&text).unwrap()).unwrap();
        assert_eq!(back, rig);
        for bad in [f64::NAN, 12.0] {
            let mut f = file.clone();
            f.floor_z_m = Some(bad);
            let e = RgbdCalibration::from_file(&f).unwrap_err().to_string();
            assert!(e.contains("floor_z_m"), "{e}");
        }
    }
}
