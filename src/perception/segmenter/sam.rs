//! SAM-family segmentation through ONNX (MobileSAM's published export
//! layout): the image encoder runs once per frame, the prompt decoder once
//! per box (the box as two corner points with labels 2 and 3); mask logits
//! above 0 are the mask.
//!
//! Encoder: `[1,3,1024,1024]` float (RGB resized so the longest side is
//! 1024, normalised with ImageNet mean/std in 0..255 units, zero-padded
//! right/bottom) → `image_embeddings` `[1,256,64,64]`.
//! Decoder: `image_embeddings`, `point_coords` `[1,N,2]`, `point_labels`
//! `[1,N]`, `mask_input` `[1,1,256,256]`, `has_mask_input` `[1]`,
//! `orig_im_size` `[2]` → `masks` `[1,M,H,W]`, `iou_predictions` `[1,M]`.

use ort::value::Tensor;

use super::{Segmenter, SegmenterError};
use crate::msg::{DepthImage, RgbImage};
use crate::perception::image::resize_bilinear;
use crate::perception::masks::Mask;
use crate::perception::runtime::{Model, RuntimeError};

const MEAN: [f32; 3] = [123.675, 116.28, 103.53];
const STD: [f32; 3] = [58.395, 57.12, 57.375];
const DECODER_INPUTS: [&str; 6] = [
    "image_embeddings",
    "point_coords",
    "point_labels",
    "mask_input",
    "has_mask_input",
    "orig_im_size",
];

pub struct SamSegmenter {
    encoder: Model,
    decoder: Model,
    encoder_input: String,
    size: usize,
    embedding_shape: Vec<usize>,
}

impl SamSegmenter {
    pub fn new(encoder: Model, decoder: Model) -> Result<Self, RuntimeError> {
        let input = encoder
            .signature
            .inputs
            .first()
            .ok_or_else(|| encoder.signature_error("no input"))?;
        let size = match input.shape.as_slice() {
            [1, 3, h, w] if h == w && *h > 0 => *h as usize,
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
        for name in DECODER_INPUTS {
            if decoder.signature.input(name).is_none() {
                return Err(decoder.signature_error(format!("decoder input `{name}` missing")));
            }
        }
        if decoder.signature.output("masks").is_none() {
            return Err(decoder.signature_error("decoder output `masks` missing"));
        }
        Ok(SamSegmenter {
            encoder,
            decoder,
            encoder_input,
            size,
            embedding_shape,
        })
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

fn rt(model: &str) -> impl Fn(ort::Error) -> RuntimeError + '_ {
    move |e| RuntimeError::Inference {
        model: model.to_string(),
        reason: e.to_string(),
    }
}

impl Segmenter for SamSegmenter {
    fn backend(&self) -> &'static str {
        "sam"
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
        let (input, _) = self.preprocess(image);
        let s = self.size;
        let enc_name = self.encoder.name();
        let embedding: Vec<f32> = {
            let t = Tensor::from_array((vec![1usize, 3, s, s], input)).map_err(rt(&enc_name))?;
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
        let dec_name = self.decoder.name();
        let mut masks = Vec::with_capacity(boxes.len());
        for b in boxes {
            let coords = vec![b[0] * sx, b[1] * sy, b[2] * sx, b[3] * sy];
            let e = rt(&dec_name);
            let inputs = ort::inputs![
                "image_embeddings" => Tensor::from_array((self.embedding_shape.clone(), embedding.clone())).map_err(&e)?,
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
            let mut pick = 0usize;
            if m_count > 1 {
                if let Some(iou) = out.get("iou_predictions") {
                    let (_, ious) = iou.try_extract_tensor::<f32>().map_err(&e)?;
                    pick = ious
                        .iter()
                        .take(m_count)
                        .enumerate()
                        .max_by(|a, b| a.1.total_cmp(b.1))
                        .map(|(i, _)| i)
                        .unwrap_or(0);
                }
            }
            let plane = &mdata[pick * w * h..(pick + 1) * w * h];
            let bits: Vec<bool> = plane.iter().map(|&l| l > 0.0).collect();
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
