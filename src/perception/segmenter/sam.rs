//! SAM-family segmentation through ONNX (MobileSAM's published export
//! layout): the image encoder runs once per frame, the prompt decoder once
//! per box (the box as two corner points with labels 2 and 3); mask logits
//! above 0 are the mask.
//!
//! Encoder: `[1,3,1024,1024]` float (RGB resized so the longest side is
//! 1024, normalised with ImageNet mean/std in 0..255 units, zero-padded
//! right/bottom) → `image_embeddings` `[1,256,64,64]`.
//! Decoder, SAM's export (SAM, MobileSAM, RepViT-SAM): `image_embeddings`,
//! `point_coords` `[1,N,2]`, `point_labels` `[1,N]`, `mask_input`
//! `[1,1,256,256]`, `has_mask_input` `[1]`, `orig_im_size` `[2]` → `masks`
//! `[1,M,H,W]`, `iou_predictions` `[1,M]`.
//! EfficientSAM's split export: encoder `batched_images` `[1,3,H,W]` (the
//! image at its own size, 0..1: it resizes and normalises inside) →
//! `image_embeddings`; decoder `image_embeddings`, `batched_point_coords`
//! `[1,1,N,2]`, `batched_point_labels` `[1,1,N]` (image pixels),
//! `orig_im_size` int64 `[2]` → `output_masks` `[1,1,M,H,W]`,
//! `iou_predictions` `[1,1,M]`.
//! Decoder, EdgeSAM's export: `image_embeddings`, `point_coords`,
//! `point_labels` → `scores` `[1,M]`, `masks` `[1,M,256,256]`: low-resolution
//! logits over the padded encoder frame, brought to the image as SAM's
//! `postprocess_masks` does (bilinear up to the encoder frame, the padding
//! cropped, bilinear to the image; half-pixel centres).

use ort::value::Tensor;

use super::{Segmenter, SegmenterError};
use crate::msg::{DepthImage, RgbImage};
use crate::perception::image::resize_bilinear;
use crate::perception::masks::Mask;
use crate::perception::runtime::{Model, RuntimeError};

const MEAN: [f32; 3] = [123.675, 116.28, 103.53];
const STD: [f32; 3] = [58.395, 57.12, 57.375];
const EFFICIENT_DECODER_INPUTS: [&str; 4] = [
    "image_embeddings",
    "batched_point_coords",
    "batched_point_labels",
    "orig_im_size",
];
const DECODER_INPUTS: [&str; 6] = [
    "image_embeddings",
    "point_coords",
    "point_labels",
    "mask_input",
    "has_mask_input",
    "orig_im_size",
];

/// Which decoder export.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum DecoderKind {
    /// SAM's: masks at the image's size.
    Sam,
    /// EdgeSAM's: low-resolution masks and their scores.
    EdgeSam,
    /// EfficientSAM's: the image as it is in, batched prompts, masks at
    /// the image's size.
    EfficientSam,
}

pub struct SamSegmenter {
    encoder: Model,
    decoder: Model,
    encoder_input: String,
    size: usize,
    embedding_shape: Vec<usize>,
    kind: DecoderKind,
}

/// Source index pair and weight of destination `dst` when `src_len`
/// samples are resized to `dst_len` (bilinear, half-pixel centres, edges
/// clamped: OpenCV's INTER_LINEAR and PyTorch's `align_corners=False`).
fn linear_taps(dst: usize, src_len: usize, dst_len: usize) -> (usize, usize, f32) {
    let x = ((dst as f32 + 0.5) * src_len as f32 / dst_len as f32 - 0.5).max(0.0);
    let i0 = (x.floor() as usize).min(src_len - 1);
    let i1 = (i0 + 1).min(src_len - 1);
    (i0, i1, x - i0 as f32)
}

/// Low-resolution mask logits (`low_h`×`low_w`, covering the padded
/// `size`×`size` encoder frame) at the image's `width`×`height`: bilinear
/// up to the frame, the `resized_w`×`resized_h` image part kept, bilinear
/// to the image — SAM's `postprocess_masks`, evaluated per output pixel.
#[allow(clippy::too_many_arguments)]
pub fn upscale_low_res(
    low: &[f32],
    low_w: usize,
    low_h: usize,
    size: usize,
    resized_w: usize,
    resized_h: usize,
    width: usize,
    height: usize,
) -> Vec<f32> {
    // the frame's value at (fx, fy), itself bilinear from the low-res grid
    let frame = |fx: usize, fy: usize| -> f32 {
        let (y0, y1, wy) = linear_taps(fy, low_h, size);
        let (x0, x1, wx) = linear_taps(fx, low_w, size);
        let at = |x: usize, y: usize| low[y * low_w + x];
        let top = at(x0, y0) * (1.0 - wx) + at(x1, y0) * wx;
        let bottom = at(x0, y1) * (1.0 - wx) + at(x1, y1) * wx;
        top * (1.0 - wy) + bottom * wy
    };
    let cols: Vec<(usize, usize, f32)> = (0..width)
        .map(|u| linear_taps(u, resized_w, width))
        .collect();
    let mut out = Vec::with_capacity(width * height);
    for v in 0..height {
        let (y0, y1, wy) = linear_taps(v, resized_h, height);
        for &(x0, x1, wx) in &cols {
            let top = frame(x0, y0) * (1.0 - wx) + frame(x1, y0) * wx;
            let bottom = frame(x0, y1) * (1.0 - wx) + frame(x1, y1) * wx;
            out.push(top * (1.0 - wy) + bottom * wy);
        }
    }
    out
}

impl SamSegmenter {
    pub fn new(encoder: Model, decoder: Model) -> Result<Self, RuntimeError> {
        let input = encoder
            .signature
            .inputs
            .first()
            .ok_or_else(|| encoder.signature_error("no input"))?;
        let efficient = input.name == "batched_images"
            || decoder.signature.input("batched_point_coords").is_some();
        let size = match (efficient, input.shape.as_slice()) {
            // EfficientSAM takes the image at its own size
            (true, [_, 3, _, _]) => 0,
            (false, [1, 3, h, w]) if h == w && *h > 0 => *h as usize,
            (true, _) => {
                return Err(
                    encoder.signature_error("EfficientSAM's encoder input must be [1,3,H,W]")
                )
            }
            _ => return Err(encoder.signature_error("encoder input must be [1,3,S,S] (S = 1024)")),
        };
        let encoder_input = input.name.clone();
        let out = encoder
            .signature
            .outputs
            .first()
            .ok_or_else(|| encoder.signature_error("no output"))?;
        let embedding_shape: Vec<usize> = match out.shape.as_slice() {
            [1, c, h, w] if *c > 0 && *h > 0 && *w > 0 => {
                vec![1, *c as usize, *h as usize, *w as usize]
            }
            _ => return Err(encoder.signature_error("encoder output must be [1,C,H,W]")),
        };
        // EdgeSAM's export: no mask prompt, low-resolution masks with scores
        let kind = if efficient {
            DecoderKind::EfficientSam
        } else if decoder.signature.input("mask_input").is_none()
            && decoder.signature.output("scores").is_some()
        {
            DecoderKind::EdgeSam
        } else {
            DecoderKind::Sam
        };
        let needed: &[&str] = match kind {
            DecoderKind::Sam => &DECODER_INPUTS,
            DecoderKind::EdgeSam => &DECODER_INPUTS[..3],
            DecoderKind::EfficientSam => &EFFICIENT_DECODER_INPUTS,
        };
        for name in needed {
            if decoder.signature.input(name).is_none() {
                return Err(decoder.signature_error(format!("decoder input `{name}` missing")));
            }
        }
        let (masks_out, rating) = match kind {
            DecoderKind::EfficientSam => ("output_masks", Some("iou_predictions")),
            DecoderKind::EdgeSam => ("masks", Some("scores")),
            DecoderKind::Sam => ("masks", None),
        };
        for out in std::iter::once(masks_out).chain(rating) {
            if decoder.signature.output(out).is_none() {
                return Err(decoder.signature_error(format!("decoder output `{out}` missing")));
            }
        }
        Ok(SamSegmenter {
            encoder,
            decoder,
            encoder_input,
            size,
            embedding_shape,
            kind,
        })
    }

    /// SAM's decoder: the chosen mask's logits at the image's size.
    fn decode_sam(
        &mut self,
        embedding: &[f32],
        coords: Vec<f32>,
        w: usize,
        h: usize,
    ) -> Result<Vec<f32>, SegmenterError> {
        let dec_name = self.decoder.name();
        let e = rt(&dec_name);
        let inputs = ort::inputs![
            "image_embeddings" => Tensor::from_array((self.embedding_shape.clone(), embedding.to_vec())).map_err(&e)?,
            "point_coords" => Tensor::from_array((vec![1usize, 2, 2], coords)).map_err(&e)?,
            "point_labels" => Tensor::from_array((vec![1usize, 2], vec![2.0f32, 3.0])).map_err(&e)?,
            "mask_input" => Tensor::from_array((vec![1usize, 1, 256, 256], vec![0.0f32; 256 * 256])).map_err(&e)?,
            "has_mask_input" => Tensor::from_array((vec![1usize], vec![0.0f32])).map_err(&e)?,
            "orig_im_size" => Tensor::from_array((vec![2usize], vec![h as f32, w as f32])).map_err(&e)?,
        ];
        let out = self.decoder.session.run(inputs).map_err(&e)?;
        let (mshape, mdata) = out["masks"].try_extract_tensor::<f32>().map_err(&e)?;
        let dims = mshape.to_vec();
        let m_count = match dims.as_slice() {
            [1, m, hh, ww] if *hh as usize == h && *ww as usize == w && *m >= 1 => *m as usize,
            _ => {
                return Err(SegmenterError::Output {
                    model: dec_name.clone(),
                    output: "masks".into(),
                    shape: dims,
                    expected: format!("[1, M, {h}, {w}]"),
                })
            }
        };
        // several masks: the one with the highest predicted IoU
        let pick = best_output(&out, "iou_predictions", m_count, &e)?;
        Ok(mdata[pick * w * h..(pick + 1) * w * h].to_vec())
    }

    /// EfficientSAM's decoder: the box's corners in image pixels; the mask
    /// with the highest predicted IoU, at the image's size.
    fn decode_efficient_sam(
        &mut self,
        embedding: &[f32],
        b: [f32; 4],
        w: usize,
        h: usize,
    ) -> Result<Vec<f32>, SegmenterError> {
        let dec_name = self.decoder.name();
        let e = rt(&dec_name);
        let inputs = ort::inputs![
            "image_embeddings" => Tensor::from_array((self.embedding_shape.clone(), embedding.to_vec())).map_err(&e)?,
            "batched_point_coords" => Tensor::from_array((vec![1usize, 1, 2, 2], b.to_vec())).map_err(&e)?,
            "batched_point_labels" => Tensor::from_array((vec![1usize, 1, 2], vec![2.0f32, 3.0])).map_err(&e)?,
            "orig_im_size" => Tensor::from_array((vec![2usize], vec![h as i64, w as i64])).map_err(&e)?,
        ];
        let out = self.decoder.session.run(inputs).map_err(&e)?;
        let (mshape, mdata) = out["output_masks"]
            .try_extract_tensor::<f32>()
            .map_err(&e)?;
        let dims = mshape.to_vec();
        let m_count = match dims.as_slice() {
            [1, 1, m, hh, ww] if *hh as usize == h && *ww as usize == w && *m >= 1 => *m as usize,
            _ => {
                return Err(SegmenterError::Output {
                    model: dec_name.clone(),
                    output: "output_masks".into(),
                    shape: dims,
                    expected: format!("[1, 1, M, {h}, {w}]"),
                })
            }
        };
        let pick = best_output(&out, "iou_predictions", m_count, &e)?;
        Ok(mdata[pick * w * h..(pick + 1) * w * h].to_vec())
    }

    /// EdgeSAM's decoder: the best-scored low-resolution mask (width,
    /// height, logits).
    fn decode_edge_sam(
        &mut self,
        embedding: &[f32],
        coords: Vec<f32>,
    ) -> Result<(usize, usize, Vec<f32>), SegmenterError> {
        let dec_name = self.decoder.name();
        let e = rt(&dec_name);
        let inputs = ort::inputs![
            "image_embeddings" => Tensor::from_array((self.embedding_shape.clone(), embedding.to_vec())).map_err(&e)?,
            "point_coords" => Tensor::from_array((vec![1usize, 2, 2], coords)).map_err(&e)?,
            "point_labels" => Tensor::from_array((vec![1usize, 2], vec![2.0f32, 3.0])).map_err(&e)?,
        ];
        let out = self.decoder.session.run(inputs).map_err(&e)?;
        let (mshape, mdata) = out["masks"].try_extract_tensor::<f32>().map_err(&e)?;
        let dims = mshape.to_vec();
        let (m_count, lh, lw) = match dims.as_slice() {
            [1, m, lh, lw] if *m >= 1 && *lh > 0 && *lw > 0 => {
                (*m as usize, *lh as usize, *lw as usize)
            }
            _ => {
                return Err(SegmenterError::Output {
                    model: dec_name.clone(),
                    output: "masks".into(),
                    shape: dims,
                    expected: "[1, M, 256, 256]".into(),
                })
            }
        };
        let (sshape, scores) = out["scores"].try_extract_tensor::<f32>().map_err(&e)?;
        if scores.len() < m_count {
            return Err(SegmenterError::Output {
                model: dec_name.clone(),
                output: "scores".into(),
                shape: sshape.to_vec(),
                expected: format!("[1, {m_count}]"),
            });
        }
        let pick = best(scores, m_count);
        Ok((lw, lh, mdata[pick * lw * lh..(pick + 1) * lw * lh].to_vec()))
    }

    /// The encoder's input tensor and the resize scale.
    pub fn preprocess(&self, image: &RgbImage) -> (Vec<f32>, f32) {
        let (w, h) = (image.width(), image.height());
        let s = self.size;
        let scale = s as f32 / w.max(h) as f32;
        let nw = ((w as f32 * scale + 0.5) as usize).clamp(1, s);
        let nh = ((h as f32 * scale + 0.5) as usize).clamp(1, s);
        let resized = resize_bilinear(image, nw, nh);
        let plane = s * s;
        let mut out = vec![0.0f32; 3 * plane];
        for y in 0..nh {
            for x in 0..nw {
                for c in 0..3 {
                    out[c * plane + y * s + x] =
                        (resized[(y * nw + x) * 3 + c] as f32 - MEAN[c]) / STD[c];
                }
            }
        }
        (out, scale)
    }
}

/// EfficientSAM's encoder input: the image as it is, CHW, 0..1.
fn efficient_input(image: &RgbImage) -> Vec<f32> {
    let plane = image.width() * image.height();
    let mut chw = vec![0.0f32; 3 * plane];
    for (i, px) in image.data().chunks_exact(3).enumerate() {
        for c in 0..3 {
            chw[c * plane + i] = f32::from(px[c]) / 255.0;
        }
    }
    chw
}

/// Of `n` masks, the one output `name` rates highest; the first when
/// there is only one or the model gives no such output (a decoder's
/// signature is checked when it is opened).
fn best_output(
    out: &ort::session::SessionOutputs<'_>,
    name: &str,
    n: usize,
    e: &impl Fn(ort::Error) -> RuntimeError,
) -> Result<usize, SegmenterError> {
    if n <= 1 {
        return Ok(0);
    }
    match out.get(name) {
        Some(v) => {
            let (_, values) = v.try_extract_tensor::<f32>().map_err(e)?;
            Ok(best(values, n))
        }
        None => Ok(0),
    }
}

/// The index of the highest of the first `n` values.
fn best(values: &[f32], n: usize) -> usize {
    values
        .iter()
        .take(n)
        .enumerate()
        .max_by(|a, b| a.1.total_cmp(b.1))
        .map_or(0, |(i, _)| i)
}

fn rt(model: &str) -> impl Fn(ort::Error) -> RuntimeError + '_ {
    move |e| RuntimeError::Inference {
        model: model.to_string(),
        reason: e.to_string(),
    }
}

impl Segmenter for SamSegmenter {
    fn backend(&self) -> &'static str {
        match self.kind {
            DecoderKind::Sam => "sam",
            DecoderKind::EdgeSam => "edge-sam",
            DecoderKind::EfficientSam => "efficient-sam",
        }
    }

    fn segment(
        &mut self,
        image: &RgbImage,
        _depth: Option<&DepthImage>,
        boxes: &[[f32; 4]],
    ) -> Result<Vec<Mask>, SegmenterError> {
        if boxes.is_empty() {
            return Ok(Vec::new());
        }
        let (w, h) = (image.width(), image.height());
        let (input, shape) = match self.kind {
            DecoderKind::EfficientSam => (efficient_input(image), vec![1usize, 3, h, w]),
            _ => (
                self.preprocess(image).0,
                vec![1usize, 3, self.size, self.size],
            ),
        };
        let s = self.size.max(1);
        let enc_name = self.encoder.name();
        let embedding: Vec<f32> = {
            let t = Tensor::from_array((shape, input)).map_err(rt(&enc_name))?;
            let out = self
                .encoder
                .session
                .run(ort::inputs![self.encoder_input.as_str() => t])
                .map_err(rt(&enc_name))?;
            let (shape, data) = out[0].try_extract_tensor::<f32>().map_err(rt(&enc_name))?;
            let got: Vec<usize> = shape.iter().map(|&d| d.max(0) as usize).collect();
            if got != self.embedding_shape {
                return Err(SegmenterError::Output {
                    model: enc_name.clone(),
                    output: self.encoder.signature.outputs[0].name.clone(),
                    shape: shape.to_vec(),
                    expected: format!("{:?}", self.embedding_shape),
                });
            }
            data.to_vec()
        };
        // SAM's ResizeLongestSide maps coordinates by the new/old size ratio
        let scale = s as f32 / w.max(h) as f32;
        let nw = ((w as f32 * scale + 0.5) as usize).clamp(1, s) as f32;
        let nh = ((h as f32 * scale + 0.5) as usize).clamp(1, s) as f32;
        let (sx, sy) = (nw / w as f32, nh / h as f32);
        let mut masks = Vec::with_capacity(boxes.len());
        for b in boxes {
            let coords = vec![b[0] * sx, b[1] * sy, b[2] * sx, b[3] * sy];
            let logits = match self.kind {
                DecoderKind::Sam => self.decode_sam(&embedding, coords, w, h)?,
                DecoderKind::EfficientSam => self.decode_efficient_sam(&embedding, *b, w, h)?,
                DecoderKind::EdgeSam => {
                    let (lw, lh, low) = self.decode_edge_sam(&embedding, coords)?;
                    upscale_low_res(&low, lw, lh, s, nw as usize, nh as usize, w, h)
                }
            };
            let bits: Vec<bool> = logits.iter().map(|&l| l > 0.0).collect();
            // keep only the box's region, as the other backends do
            let full = Mask::from_full(w, h, bits)
                .ok_or_else(|| SegmenterError::Input("mask size".into()))?;
            let mut m = Mask::for_box(w, h, *b);
            let (x0, y0, bw, bh) = m.region();
            for v in y0..y0 + bh {
                for u in x0..x0 + bw {
                    if full.get(u, v) {
                        m.set(u, v, true);
                    }
                }
            }
            masks.push(m);
        }
        Ok(masks)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn low_resolution_masks_resize_with_half_pixel_centres() {
        // [0, 1] over a 4-wide frame: 0, 0.25, 0.75, 1 (edges clamped)
        let out = upscale_low_res(&[0.0, 1.0], 2, 1, 4, 4, 4, 4, 4);
        for row in out.chunks(4) {
            assert_eq!(row, &[0.0, 0.25, 0.75, 1.0]);
        }
        // only the image part of the frame (its left half) reaches the image
        let out = upscale_low_res(&[0.0, 1.0], 2, 1, 4, 2, 4, 2, 4);
        assert_eq!(&out[..2], &[0.0, 0.25]);
    }
}
