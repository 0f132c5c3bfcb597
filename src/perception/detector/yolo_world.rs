//! Open-vocabulary YOLO-World (un-fused export): `images` `[1,3,640,640]`
//! and `txt_feats` `[1,K,512]` (L2-normalised text embeddings) → `[1,4+K,N]`.
//! The prompts become text embeddings at run time through [`TextEmbedder`].

use ort::value::Tensor;

use super::text::TextEmbedder;
use super::yolo::image_input;
use super::{
    decode_yolo_head, Detection, Detector, DetectorError, DetectorSettings, InputLayout,
    PreparedImage, PromptReport,
};
use crate::perception::runtime::Model;

pub struct YoloWorld {
    model: Model,
    settings: DetectorSettings,
    text: TextEmbedder,
    image_name: String,
    input_size: usize,
    input_layout: InputLayout,
    /// Fixed K of the export, or None when dynamic.
    fixed_k: Option<usize>,
    dim: usize,
    /// (class slot, prompt, prompt) for the active prompts.
    active: Vec<(usize, String, String)>,
    txt_feats: Vec<f32>,
    k: usize,
}

impl YoloWorld {
    pub fn from_model(
        model: Model,
        settings: DetectorSettings,
        text: TextEmbedder,
    ) -> Result<Self, DetectorError> {
        let (image_name, input_size, input_layout) = image_input(&model, Some("images"))?;
        let t = model
            .signature
            .input("txt_feats")
            .ok_or_else(|| model.signature_error("no `txt_feats` input"))?;
        let (fixed_k, dim) = match t.shape.as_slice() {
            [b, k, d] if (*b == 1 || *b == -1) && *d > 0 => {
                ((*k > 0).then_some(*k as usize), *d as usize)
            }
            _ => {
                return Err(model
                    .signature_error("`txt_feats` must be [1, K, D]")
                    .into())
            }
        };
        if dim != text.dim() {
            return Err(model
                .signature_error(format!(
                    "`txt_feats` wants {dim}-dim embeddings but {} gives {}",
                    text.describe(),
                    text.dim()
                ))
                .into());
        }
        Ok(YoloWorld {
            model,
            settings,
            text,
            image_name,
            input_size,
            input_layout,
            fixed_k,
            dim,
            active: Vec::new(),
            txt_feats: Vec::new(),
            k: 0,
        })
    }
}

impl Detector for YoloWorld {
    fn backend(&self) -> &'static str {
        "yolo-world"
    }

    fn set_prompts(&mut self, prompts: &[String]) -> Result<PromptReport, DetectorError> {
        if prompts.is_empty() {
            return Err(DetectorError::Prompt("no prompt given".into()));
        }
        if let Some(k) = self.fixed_k {
            if prompts.len() > k {
                return Err(DetectorError::Prompt(format!(
                    "{} prompts, but {} takes at most {k}",
                    prompts.len(),
                    self.model.name()
                )));
            }
        }
        let embeddings = self.text.embed(prompts)?;
        let mut report = PromptReport::default();
        let mut active = Vec::new();
        let mut feats = Vec::new();
        for (p, e) in prompts.iter().zip(embeddings) {
            match e {
                Some(v) => {
                    active.push((active.len(), p.clone(), p.clone()));
                    feats.extend_from_slice(&v);
                    report.matched.push((p.clone(), p.clone()));
                }
                None => report.unmatched.push(p.clone()),
            }
        }
        // a fixed-K export gets zero rows for the unused slots; their
        // channels are never read
        let k = self.fixed_k.unwrap_or(active.len().max(1));
        feats.resize(k * self.dim, 0.0);
        self.active = active;
        self.txt_feats = feats;
        self.k = k;
        Ok(report)
    }

    // `detect`: the trait's, through the letterbox below

    fn letterbox_side(&self) -> Option<usize> {
        Some(self.input_size)
    }

    fn input_layout(&self) -> InputLayout {
        self.input_layout
    }

    fn detect_prepared(&mut self, input: PreparedImage) -> Result<Vec<Detection>, DetectorError> {
        input.check_side(self.input_size, self.input_layout)?;
        if self.active.is_empty() {
            return Ok(Vec::new());
        }
        let name = self.model.name();
        let err = |e: ort::Error| crate::perception::runtime::RuntimeError::Inference {
            model: name.clone(),
            reason: e.to_string(),
        };
        let letterbox = input.letterbox;
        let img = input.into_tensor().map_err(err)?;
        let txt = Tensor::from_array((vec![1usize, self.k, self.dim], self.txt_feats.clone()))
            .map_err(err)?;
        let out_name = self.model.signature.outputs[0].name.clone();
        let outputs = self
            .model
            .session
            .run(ort::inputs![self.image_name.as_str() => img, "txt_feats" => txt])
            .map_err(err)?;
        let (shape, data) = outputs[0].try_extract_tensor::<f32>().map_err(err)?;
        let dims: Vec<i64> = shape.to_vec();
        let (channels, anchors) = match dims.as_slice() {
            [1, c, n] if *c as usize == 4 + self.k => (*c as usize, *n as usize),
            _ => {
                return Err(DetectorError::Output {
                    model: name.clone(),
                    output: out_name,
                    shape: dims,
                    expected: format!("[1, {}, N]", 4 + self.k),
                })
            }
        };
        Ok(decode_yolo_head(
            data,
            channels,
            anchors,
            &self.active,
            &letterbox,
            &self.settings,
        ))
    }
}
