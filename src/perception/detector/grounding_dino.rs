//! Grounding DINO (the paper's second 2D stack) on ONNX Runtime, in the
//! I/O of its common ONNX export: the image (`img`, or `samples`/`inputs`)
//! `[1,3,H,W]` (resized, ImageNet-normalised), and the caption tokenised by
//! BERT's WordPiece (`input_ids`, `attention_mask`, `token_type_ids`,
//! `position_ids` `[1,T]`, and the sub-sentence self-attention mask
//! `text_token_mask` or `text_self_attention_masks` `[1,T,T]`) →
//! `logits` `[1,Q,L]` (Q queries, typically 900, over L = 256 text
//! positions) and `boxes` `[1,Q,4]` (normalised cx, cy, w, h).
//! The Hugging Face export (`GroundingDinoForObjectDetection` through
//! `optimum`) is read too: `pixel_values`, `input_ids`, `token_type_ids`,
//! `attention_mask`, `pixel_mask` `[1,H,W]` → `logits` `[1,Q,T]`,
//! `pred_boxes` `[1,Q,4]` (the masks and positions made inside).
//!
//! The caption is the prompts joined as the reference does ("chair .
//! table ."); each prompt's tokens are found from the tokenizer's offsets.
//! A query is kept when its best token probability exceeds the box
//! threshold; its label is the prompt whose tokens pass the text threshold
//! with the highest probability (the reference decodes those tokens into a
//! phrase; here the phrase is mapped back to the prompt it came from). The
//! masks follow the reference's `generate_masks_with_special_tokens_and_
//! transfer_map`: each phrase attends only to itself and its positions
//! restart at 0 after each `.`.

use std::path::Path;

use ort::value::Tensor;

use super::{nms_classwise, Detection, Detector, DetectorError, DetectorSettings, PromptReport};
use crate::msg::RgbImage;
use crate::perception::image::resize_bilinear;
use crate::perception::runtime::Model;

/// The reference's special tokens: `[CLS]`, `[SEP]`, `.`, `?` in BERT base
/// uncased's vocabulary.
pub const SPECIAL_TOKENS: [i64; 4] = [101, 102, 1012, 1029];
/// Text positions of the model (`max_text_len`).
pub const MAX_TEXT_LEN: usize = 256;
/// The reference's thresholds (its demo's defaults).
pub const BOX_THRESHOLD: f32 = 0.35;
pub const TEXT_THRESHOLD: f32 = 0.25;
/// ImageNet normalisation, RGB.
const MEAN: [f32; 3] = [0.485, 0.456, 0.406];
const STD: [f32; 3] = [0.229, 0.224, 0.225];
/// The image size when the export leaves it dynamic (the reference
/// resizes the shorter side to 800).
const DEFAULT_SIZE: usize = 800;

/// The caption of the prompts and where each prompt sits in it (byte
/// ranges), lower-cased as the reference does.
#[derive(Debug, Clone, PartialEq)]
pub struct Caption {
    pub text: String,
    pub spans: Vec<(usize, usize)>,
}

/// "chair . table ." from ["chair", "Table"].
pub fn caption(prompts: &[String]) -> Caption {
    let mut text = String::new();
    let mut spans = Vec::new();
    for p in prompts {
        let p = p.trim().to_lowercase();
        let start = text.len();
        text.push_str(&p);
        spans.push((start, text.len()));
        text.push_str(" . ");
    }
    Caption {
        text: text.trim_end().to_string(),
        spans,
    }
}

/// The text inputs of one caption.
#[derive(Debug, Clone, PartialEq)]
pub struct TextInputs {
    pub input_ids: Vec<i64>,
    pub token_type_ids: Vec<i64>,
    pub attention_mask: Vec<bool>,
    pub position_ids: Vec<i64>,
    /// T×T, row-major: token i may attend to token j.
    pub self_attention: Vec<bool>,
    /// Per prompt, its token indices.
    pub prompt_tokens: Vec<Vec<usize>>,
}

/// The sub-sentence self-attention mask and position ids: special tokens
/// (`special`) cut the caption into phrases; a phrase's tokens (up to and
/// including the `.` that ends it) attend to each other only, positions
/// counting from 0 in each; the first and last token attend to themselves
/// with position 0.
pub fn sub_sentence_masks(input_ids: &[i64], special: &[i64]) -> (Vec<bool>, Vec<i64>) {
    let t = input_ids.len();
    let mut mask = vec![false; t * t];
    for i in 0..t {
        mask[i * t + i] = true;
    }
    let mut position = vec![0i64; t];
    let mut previous = 0usize;
    for (col, id) in input_ids.iter().enumerate() {
        if !special.contains(id) {
            continue;
        }
        if col == 0 || col == t - 1 {
            mask[col * t + col] = true;
            position[col] = 0;
        } else {
            for r in previous + 1..=col {
                for c in previous + 1..=col {
                    mask[r * t + c] = true;
                }
                position[r] = (r - previous - 1) as i64;
            }
        }
        previous = col;
    }
    (mask, position)
}

/// Tokens whose byte range lies in `span` (the tokenizer's offsets; the
/// special tokens have empty ranges and never count).
pub fn tokens_in(offsets: &[(usize, usize)], span: (usize, usize)) -> Vec<usize> {
    offsets
        .iter()
        .enumerate()
        .filter(|(_, (s, e))| e > s && *s >= span.0 && *e <= span.1)
        .map(|(i, _)| i)
        .collect()
}

/// Tokenises the caption (truncated to [`MAX_TEXT_LEN`]) and makes the
/// model's text inputs.
pub fn text_inputs(
    tokenizer: &tokenizers::Tokenizer,
    caption: &Caption,
) -> Result<TextInputs, String> {
    let enc = tokenizer
        .encode(caption.text.as_str(), true)
        .map_err(|e| format!("tokenising {:?}: {e}", caption.text))?;
    let t = enc.get_ids().len().min(MAX_TEXT_LEN);
    let input_ids: Vec<i64> = enc.get_ids()[..t].iter().map(|&i| i64::from(i)).collect();
    let (self_attention, position_ids) = sub_sentence_masks(&input_ids, &SPECIAL_TOKENS);
    let offsets = &enc.get_offsets()[..t];
    Ok(TextInputs {
        token_type_ids: enc.get_type_ids()[..t]
            .iter()
            .map(|&i| i64::from(i))
            .collect(),
        attention_mask: enc.get_attention_mask()[..t]
            .iter()
            .map(|&m| m != 0)
            .collect(),
        position_ids,
        self_attention,
        prompt_tokens: caption
            .spans
            .iter()
            .map(|&s| tokens_in(offsets, s))
            .collect(),
        input_ids,
    })
}

fn sigmoid(x: f32) -> f32 {
    1.0 / (1.0 + (-x).exp())
}

/// What decoding needs besides the outputs.
pub struct DecodeSpec<'a> {
    /// Per prompt: its label and its token indices.
    pub prompts: &'a [(String, Vec<usize>)],
    /// Tokens of the caption (positions past it are padding).
    pub tokens: usize,
    pub box_threshold: f32,
    pub text_threshold: f32,
    pub image_width: usize,
    pub image_height: usize,
}

/// Decodes `logits` `[Q, L]` and `boxes` `[Q, 4]` into detections (before
/// NMS), each with the prompt's index.
pub fn decode(
    logits: &[f32],
    boxes: &[f32],
    queries: usize,
    positions: usize,
    spec: &DecodeSpec,
) -> Vec<(usize, Detection)> {
    let mut out = Vec::new();
    let valid = spec.tokens.min(positions);
    let (w, h) = (spec.image_width as f32, spec.image_height as f32);
    for q in 0..queries {
        let Some(row) = logits.get(q * positions..q * positions + valid) else {
            break;
        };
        let probs: Vec<f32> = row.iter().map(|&l| sigmoid(l)).collect();
        let score = probs.iter().cloned().fold(0.0f32, f32::max);
        if score <= spec.box_threshold {
            continue;
        }
        // the prompt whose tokens pass the text threshold most strongly
        let best = spec
            .prompts
            .iter()
            .enumerate()
            .filter_map(|(k, (_, toks))| {
                toks.iter()
                    .filter_map(|&i| probs.get(i).copied())
                    .filter(|&p| p > spec.text_threshold)
                    .fold(None, |m: Option<f32>, p| Some(m.map_or(p, |m| m.max(p))))
                    .map(|p| (k, p))
            })
            .max_by(|a, b| a.1.total_cmp(&b.1));
        let Some((k, _)) = best else { continue };
        let Some(b) = boxes.get(q * 4..q * 4 + 4) else {
            break;
        };
        let (cx, cy, bw, bh) = (b[0] * w, b[1] * h, b[2] * w, b[3] * h);
        let xyxy = [
            (cx - bw / 2.0).clamp(0.0, w),
            (cy - bh / 2.0).clamp(0.0, h),
            (cx + bw / 2.0).clamp(0.0, w),
            (cy + bh / 2.0).clamp(0.0, h),
        ];
        if !(xyxy[2] > xyxy[0] && xyxy[3] > xyxy[1]) {
            continue;
        }
        let label = spec.prompts[k].0.clone();
        out.push((
            k,
            Detection {
                class: label.clone(),
                label,
                score,
                box_xyxy: xyxy,
            },
        ));
    }
    out
}

/// The image resized to `width`×`height` (bilinear), ImageNet-normalised,
/// CHW.
pub fn image_input(image: &RgbImage, width: usize, height: usize) -> Vec<f32> {
    let rgb = resize_bilinear(image, width, height);
    let plane = width * height;
    let mut chw = vec![0.0f32; 3 * plane];
    for (i, px) in rgb.chunks_exact(3).enumerate() {
        for c in 0..3 {
            chw[c * plane + i] = (f32::from(px[c]) / 255.0 - MEAN[c]) / STD[c];
        }
    }
    chw
}

/// Which export: the reference's I/O (masks and positions fed in, the
/// mask input's name) or Hugging Face's (made inside, a pixel mask in).
#[derive(Debug, Clone, PartialEq, Eq)]
enum Export {
    Reference { mask_name: String },
    HuggingFace,
}

pub struct GroundingDino {
    model: Model,
    settings: DetectorSettings,
    tokenizer: tokenizers::Tokenizer,
    image_name: String,
    export: Export,
    /// `attention_mask` as booleans (else int64).
    bool_attention: bool,
    boxes_name: String,
    width: usize,
    height: usize,
    prompts: Vec<String>,
    text: Option<TextInputs>,
}

/// Whether a model has Grounding DINO's inputs: the text and its
/// sub-sentence mask (the reference's export), or Hugging Face's text with
/// token types and a pixel mask.
pub fn is_grounding_dino(model: &Model) -> bool {
    let has = |n: &str| model.signature.input(n).is_some();
    has("input_ids")
        && (has("text_token_mask")
            || has("text_self_attention_masks")
            || (has("token_type_ids") && has("pixel_values") && has("pixel_mask")))
}

impl GroundingDino {
    /// The model and the tokenizer shipped beside it (`tokenizer.json`).
    pub fn from_model(
        model: Model,
        settings: DetectorSettings,
        tokenizer_path: &Path,
    ) -> Result<Self, DetectorError> {
        let tokenizer = tokenizers::Tokenizer::from_file(tokenizer_path).map_err(|e| {
            DetectorError::Prompt(format!(
                "{} is a Grounding DINO model: its tokenizer {}: {e}",
                model.name(),
                tokenizer_path.display()
            ))
        })?;
        let image = model
            .signature
            .inputs
            .iter()
            .find(|i| i.shape.len() == 4)
            .ok_or_else(|| model.signature_error("no 4-D image input"))?;
        let (width, height) = match image.shape.as_slice() {
            [_, 3, h, w] => (
                if *w > 0 { *w as usize } else { DEFAULT_SIZE },
                if *h > 0 { *h as usize } else { DEFAULT_SIZE },
            ),
            _ => {
                return Err(model
                    .signature_error("the image input must be [1, 3, H, W]")
                    .into())
            }
        };
        let image_name = image.name.clone();
        let has = |n: &str| model.signature.input(n).is_some();
        let export = if has("text_token_mask") {
            Export::Reference {
                mask_name: "text_token_mask".into(),
            }
        } else if has("text_self_attention_masks") {
            Export::Reference {
                mask_name: "text_self_attention_masks".into(),
            }
        } else {
            Export::HuggingFace
        };
        let (needed, boxes_name): (&[&str], &str) = match export {
            Export::Reference { .. } => (
                &["attention_mask", "token_type_ids", "position_ids"],
                "boxes",
            ),
            Export::HuggingFace => (
                &["attention_mask", "token_type_ids", "pixel_mask"],
                "pred_boxes",
            ),
        };
        for needed in needed {
            if !has(needed) {
                return Err(model.signature_error(format!("no `{needed}` input")).into());
            }
        }
        for out in ["logits", boxes_name] {
            if model.signature.output(out).is_none() {
                return Err(model.signature_error(format!("no `{out}` output")).into());
            }
        }
        let bool_attention = model
            .signature
            .input("attention_mask")
            .is_some_and(|a| a.dtype == "bool");
        Ok(GroundingDino {
            model,
            settings,
            tokenizer,
            image_name,
            export,
            bool_attention,
            boxes_name: boxes_name.to_string(),
            width,
            height,
            prompts: Vec::new(),
            text: None,
        })
    }
}

impl Detector for GroundingDino {
    fn backend(&self) -> &'static str {
        "grounding-dino"
    }

    fn set_prompts(&mut self, prompts: &[String]) -> Result<PromptReport, DetectorError> {
        if prompts.is_empty() {
            return Err(DetectorError::Prompt("no prompt given".into()));
        }
        let c = caption(prompts);
        let text = text_inputs(&self.tokenizer, &c).map_err(DetectorError::Prompt)?;
        let mut report = PromptReport::default();
        for (p, toks) in prompts.iter().zip(&text.prompt_tokens) {
            if toks.is_empty() {
                // cut off by the 256-token limit
                report.unmatched.push(p.clone());
            } else {
                report.matched.push((p.clone(), p.clone()));
            }
        }
        self.prompts = prompts.to_vec();
        self.text = Some(text);
        Ok(report)
    }

    fn detect(&mut self, image: &RgbImage) -> Result<Vec<Detection>, DetectorError> {
        let Some(text) = &self.text else {
            return Ok(Vec::new());
        };
        let name = self.model.name();
        let err = |e: ort::Error| crate::perception::runtime::RuntimeError::Inference {
            model: name.clone(),
            reason: e.to_string(),
        };
        let t = text.input_ids.len();
        let img = Tensor::from_array((
            vec![1usize, 3, self.height, self.width],
            image_input(image, self.width, self.height),
        ))
        .map_err(err)?;
        let ids = Tensor::from_array((vec![1usize, t], text.input_ids.clone())).map_err(err)?;
        let types =
            Tensor::from_array((vec![1usize, t], text.token_type_ids.clone())).map_err(err)?;
        let att: ort::value::DynValue = if self.bool_attention {
            Tensor::from_array((vec![1usize, t], text.attention_mask.clone()))
                .map_err(err)?
                .into_dyn()
        } else {
            let ints: Vec<i64> = text.attention_mask.iter().map(|&m| i64::from(m)).collect();
            Tensor::from_array((vec![1usize, t], ints))
                .map_err(err)?
                .into_dyn()
        };
        let mut inputs = ort::inputs![
            self.image_name.as_str() => img,
            "input_ids" => ids,
            "attention_mask" => att,
            "token_type_ids" => types,
        ];
        match &self.export {
            // the reference's export: the masks and positions fed in
            Export::Reference { mask_name } => inputs.extend(ort::inputs![
                "position_ids" => Tensor::from_array((vec![1usize, t], text.position_ids.clone())).map_err(err)?,
                mask_name.as_str() => Tensor::from_array((vec![1usize, t, t], text.self_attention.clone())).map_err(err)?,
            ]),
            // Hugging Face's: made inside; every pixel is image
            Export::HuggingFace => inputs.extend(ort::inputs![
                "pixel_mask" => Tensor::from_array((
                    vec![1usize, self.height, self.width],
                    vec![1i64; self.height * self.width],
                ))
                .map_err(err)?,
            ]),
        }
        let outputs = self.model.session.run(inputs).map_err(err)?;
        let (lshape, logits) = outputs["logits"].try_extract_tensor::<f32>().map_err(err)?;
        let (bshape, boxes) = outputs[self.boxes_name.as_str()]
            .try_extract_tensor::<f32>()
            .map_err(err)?;
        let (queries, positions) = match (lshape.to_vec().as_slice(), bshape.to_vec().as_slice()) {
            ([1, q, l], [1, q2, 4]) if q == q2 && *l as usize >= t => (*q as usize, *l as usize),
            (l, _) => {
                return Err(DetectorError::Output {
                    model: name.clone(),
                    output: "logits".into(),
                    shape: l.to_vec(),
                    expected: format!("[1, Q, L ≥ {t}] with boxes [1, Q, 4]"),
                })
            }
        };
        let prompts: Vec<(String, Vec<usize>)> = self
            .prompts
            .iter()
            .cloned()
            .zip(text.prompt_tokens.iter().cloned())
            .collect();
        let cands = decode(
            logits,
            boxes,
            queries,
            positions,
            &DecodeSpec {
                prompts: &prompts,
                tokens: t,
                box_threshold: BOX_THRESHOLD.max(self.settings.score_threshold),
                text_threshold: TEXT_THRESHOLD,
                image_width: image.width(),
                image_height: image.height(),
            },
        );
        Ok(nms_classwise(
            cands,
            self.settings.nms_iou,
            self.settings.max_detections,
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_caption_joins_prompts_with_full_stops_and_knows_where_each_is() {
        let c = caption(&["chair".into(), "Door Handle".into()]);
        assert_eq!(c.text, "chair . door handle .");
        assert_eq!(&c.text[c.spans[0].0..c.spans[0].1], "chair");
        assert_eq!(&c.text[c.spans[1].0..c.spans[1].1], "door handle");
    }

    #[test]
    fn phrases_attend_to_themselves_with_positions_from_zero() {
        // [CLS] chair . door handle . [SEP]
        let ids = [101, 7, 1012, 8, 9, 1012, 102];
        let (m, pos) = sub_sentence_masks(&ids, &SPECIAL_TOKENS);
        let t = ids.len();
        let at = |i: usize, j: usize| m[i * t + j];
        assert_eq!(pos, vec![0, 0, 1, 0, 1, 2, 0]);
        // "chair ." together, not with "door handle ."
        assert!(at(1, 2) && at(2, 1));
        assert!(!at(1, 3) && !at(3, 1));
        // "door handle ." together
        assert!(at(3, 4) && at(4, 5) && at(5, 3));
        // [CLS] and [SEP] only themselves
        assert!(at(0, 0) && !at(0, 1));
        assert!(at(6, 6) && !at(6, 5));
    }

    #[test]
    fn tokens_are_found_by_their_offsets() {
        // [CLS] chair . door handle . [SEP] (offsets into "chair . door handle .")
        let offsets = [(0, 0), (0, 5), (6, 7), (8, 12), (13, 19), (20, 21), (0, 0)];
        assert_eq!(tokens_in(&offsets, (0, 5)), vec![1]);
        assert_eq!(tokens_in(&offsets, (8, 19)), vec![3, 4]);
    }

    #[test]
    fn a_query_takes_the_prompt_whose_tokens_pass_the_text_threshold() {
        // 3 queries × 8 positions; 5 tokens
        let l = 8;
        let logit = |p: f32| (p / (1.0 - p)).ln();
        let mut logits = vec![-10.0f32; 3 * l];
        // query 0: "door handle" tokens 3, 4 at 0.6 / 0.5: door handle, 0.6
        logits[3] = logit(0.6);
        logits[4] = logit(0.5);
        // query 1: best token 0.3 (< box threshold 0.35): dropped
        logits[l + 1] = logit(0.3);
        // query 2: chair token at 0.9, and a padding position (6) at 0.99
        // that is not a token: chair, 0.9
        logits[2 * l + 1] = logit(0.9);
        logits[2 * l + 6] = logit(0.99);
        let boxes = [
            0.5, 0.5, 0.2, 0.4, //
            0.5, 0.5, 0.2, 0.4, //
            0.25, 0.25, 0.5, 0.5,
        ];
        let prompts = vec![
            ("chair".to_string(), vec![1]),
            ("door handle".to_string(), vec![3, 4]),
        ];
        let d = decode(
            &logits,
            &boxes,
            3,
            l,
            &DecodeSpec {
                prompts: &prompts,
                tokens: 5,
                box_threshold: BOX_THRESHOLD,
                text_threshold: TEXT_THRESHOLD,
                image_width: 200,
                image_height: 100,
            },
        );
        assert_eq!(d.len(), 2, "{d:?}");
        assert_eq!((d[0].0, d[0].1.label.as_str()), (1, "door handle"));
        assert!((d[0].1.score - 0.6).abs() < 1e-5);
        assert_eq!(d[0].1.box_xyxy, [80.0, 30.0, 120.0, 70.0]);
        assert_eq!((d[1].0, d[1].1.label.as_str()), (0, "chair"));
        assert!((d[1].1.score - 0.9).abs() < 1e-5);
        assert_eq!(d[1].1.box_xyxy, [0.0, 0.0, 100.0, 50.0]);
    }
}
