//! Images: RGB8 colour and depth in metres (f32, 0 = no return), loaded
//! from and saved to files.

use std::path::Path;

use thiserror::Error;

#[derive(Debug, Error)]
pub enum ImageError {
    #[error("{path}: cannot read image: {reason}")]
    Read { path: String, reason: String },
    #[error("{path}: depth image must be 16-bit single channel (got {got})")]
    DepthFormat { path: String, got: String },
    #[error("{what}: buffer of {len} values does not match {width}x{height}")]
    Size {
        what: &'static str,
        len: usize,
        width: usize,
        height: usize,
    },
    #[error("{what}: image is empty ({width}x{height})")]
    Empty {
        what: &'static str,
        width: usize,
        height: usize,
    },
}

/// An RGB8 image, row-major, 3 bytes a pixel.
#[derive(Debug, Clone, PartialEq)]
pub struct RgbImage {
    width: usize,
    height: usize,
    data: Vec<u8>,
}

impl RgbImage {
    pub fn new(width: usize, height: usize, data: Vec<u8>) -> Result<Self, ImageError> {
        if width == 0 || height == 0 {
            return Err(ImageError::Empty {
                what: "rgb image",
                width,
                height,
            });
        }
        if data.len() != width * height * 3 {
            return Err(ImageError::Size {
                what: "rgb image",
                len: data.len(),
                width,
                height,
            });
        }
        Ok(RgbImage {
            width,
            height,
            data,
        })
    }

    /// A uniform image.
    pub fn filled(width: usize, height: usize, rgb: [u8; 3]) -> Result<Self, ImageError> {
        let data = rgb
            .iter()
            .copied()
            .cycle()
            .take(width * height * 3)
            .collect();
        Self::new(width, height, data)
    }

    pub fn load(path: &Path) -> Result<Self, ImageError> {
        let img = image::ImageReader::open(path)
            .and_then(|r| r.with_guessed_format())
            .map_err(|e| ImageError::Read {
                path: path.display().to_string(),
                reason: e.to_string(),
            })?
            .decode()
            .map_err(|e| ImageError::Read {
                path: path.display().to_string(),
                reason: e.to_string(),
            })?
            .to_rgb8();
        let (w, h) = (img.width() as usize, img.height() as usize);
        Self::new(w, h, img.into_raw())
    }

    pub fn width(&self) -> usize {
        self.width
    }
    pub fn height(&self) -> usize {
        self.height
    }
    pub fn data(&self) -> &[u8] {
        &self.data
    }
    pub fn data_mut(&mut self) -> &mut [u8] {
        &mut self.data
    }

    pub fn pixel(&self, u: usize, v: usize) -> [u8; 3] {
        let i = (v * self.width + u) * 3;
        [self.data[i], self.data[i + 1], self.data[i + 2]]
    }

    pub fn save_png(&self, path: &Path) -> Result<(), ImageError> {
        image::save_buffer(
            path,
            &self.data,
            self.width as u32,
            self.height as u32,
            image::ExtendedColorType::Rgb8,
        )
        .map_err(|e| ImageError::Read {
            path: path.display().to_string(),
            reason: e.to_string(),
        })
    }
}

/// Depth in metres, row-major; 0.0 (or any non-finite / non-positive value)
/// means no return.
#[derive(Debug, Clone, PartialEq)]
pub struct DepthImage {
    width: usize,
    height: usize,
    depth_m: Vec<f32>,
}

impl DepthImage {
    pub fn new(width: usize, height: usize, depth_m: Vec<f32>) -> Result<Self, ImageError> {
        if width == 0 || height == 0 {
            return Err(ImageError::Empty {
                what: "depth image",
                width,
                height,
            });
        }
        if depth_m.len() != width * height {
            return Err(ImageError::Size {
                what: "depth image",
                len: depth_m.len(),
                width,
                height,
            });
        }
        Ok(DepthImage {
            width,
            height,
            depth_m,
        })
    }

    /// Loads a 16-bit PNG and applies the sensor's depth scale once
    /// (`depth_scale_m` metres per count; 0 stays "no return").
    pub fn load_png(path: &Path, depth_scale_m: f32) -> Result<Self, ImageError> {
        let img = image::ImageReader::open(path)
            .and_then(|r| r.with_guessed_format())
            .map_err(|e| ImageError::Read {
                path: path.display().to_string(),
                reason: e.to_string(),
            })?
            .decode()
            .map_err(|e| ImageError::Read {
                path: path.display().to_string(),
                reason: e.to_string(),
            })?;
        let luma = match img {
            image::DynamicImage::ImageLuma16(l) => l,
            other => {
                return Err(ImageError::DepthFormat {
                    path: path.display().to_string(),
                    got: format!("{:?}", other.color()),
                })
            }
        };
        let (w, h) = (luma.width() as usize, luma.height() as usize);
        let depth_m = luma
            .into_raw()
            .into_iter()
            .map(|c| c as f32 * depth_scale_m)
            .collect();
        Self::new(w, h, depth_m)
    }

    pub fn width(&self) -> usize {
        self.width
    }
    pub fn height(&self) -> usize {
        self.height
    }
    pub fn data(&self) -> &[f32] {
        &self.depth_m
    }

    /// Depth at (u, v) in metres when valid.
    #[inline]
    pub fn at(&self, u: usize, v: usize) -> Option<f32> {
        let d = self.depth_m[v * self.width + u];
        is_valid_depth(d).then_some(d)
    }
}

#[inline]
pub fn is_valid_depth(d: f32) -> bool {
    d.is_finite() && d > 0.0
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bad_sizes_are_errors() {
        assert!(RgbImage::new(2, 2, vec![0; 11]).is_err());
        assert!(DepthImage::new(0, 2, vec![]).is_err());
    }
}
