//! Step 1: 2D detectors. A trait with ONNX backends (closed-vocabulary
//! YOLO v8/11, open-vocabulary YOLO-World with text embeddings, and
//! Grounding DINO with its BERT caption), the shared decoding of the
//! `[1, 4+C, N]` head and class-wise NMS.

pub mod grounding_dino;
pub mod text;
pub mod vocab;
pub mod yolo;
pub mod yolo_world;

use std::path::Path;

use serde::Serialize;
use thiserror::Error;

use super::image::Letterbox;
use super::runtime::{Model, RuntimeError, SessionSettings};
use crate::msg::RgbImage;

pub use grounding_dino::GroundingDino;
pub use text::{TextEmbedder, TextEmbeddingError};
pub use yolo::ClosedVocabularyYolo;
pub use yolo_world::YoloWorld;

#[derive(Debug, Error)]
pub enum DetectorError {
    #[error(transparent)]
    Runtime(#[from] RuntimeError),
    #[error(transparent)]
    Text(#[from] TextEmbeddingError),
    #[error("prompt: {0}")]
    Prompt(String),
    #[error("the {backend} detector takes the image itself, not an input made beforehand")]
    NotPrepared { backend: &'static str },
    #[error("an input made for a {made}×{made} model given to one of {wanted}×{wanted}")]
    PreparedSize { made: usize, wanted: usize },
    #[error("an input made as {made:?} given to a model that takes {wanted:?}")]
    PreparedLayout {
        made: InputLayout,
        wanted: InputLayout,
    },
    #[error("{model}: output `{output}` has shape {shape:?}, expected {expected}")]
    Output {
        model: String,
        output: String,
        shape: Vec<i64>,
        expected: String,
    },
}

/// A 2D detection in original image pixels.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Detection {
    /// The prompt it answers, as the user said it.
    pub label: String,
    /// The detector's own class name (differs from `label` for synonyms).
    pub class: String,
    pub score: f32,
    /// `[x1, y1, x2, y2]`, pixel edges, clipped to the image.
    pub box_xyxy: [f32; 4],
}

/// How the active prompts map onto what the detector can see.
#[derive(Debug, Clone, PartialEq, Default, Serialize)]
pub struct PromptReport {
    /// (prompt, class name) pairs the detector will report.
    pub matched: Vec<(String, String)>,
    /// Prompts the detector has no class for.
    pub unmatched: Vec<String>,
}

/// Post-processing settings shared by the backends.
#[derive(Debug, Clone, PartialEq)]
pub struct DetectorSettings {
    /// Minimum class score kept, 0..1.
    pub score_threshold: f32,
    /// IoU above which a lower-scored box of the same class is suppressed.
    pub nms_iou: f32,
    /// Most detections returned per image.
    pub max_detections: usize,
    pub session: SessionSettings,
}

impl Default for DetectorSettings {
    fn default() -> Self {
        DetectorSettings {
            score_threshold: 0.25,
            nms_iou: 0.45,
            max_detections: 300,
            session: SessionSettings::default(),
        }
    }
}

/// An open- or closed-vocabulary 2D detector.
pub trait Detector: Send {
    /// Backend name for logs and status.
    fn backend(&self) -> &'static str;
    /// Sets the active prompts; the vocabulary may change at any time.
    fn set_prompts(&mut self, prompts: &[String]) -> Result<PromptReport, DetectorError>;
    /// Detections for the active prompts, sorted by descending score.
    /// By default the image letterboxed into the model's input and
    /// [`detect_prepared`](Self::detect_prepared) (the YOLO models); a
    /// detector that takes the image itself has its own.
    fn detect(&mut self, image: &RgbImage) -> Result<Vec<Detection>, DetectorError> {
        match self.letterbox_side() {
            Some(side) => {
                self.detect_prepared(PreparedImage::letterboxed(image, side, self.input_layout()))
            }
            None => Err(DetectorError::NotPrepared {
                backend: self.backend(),
            }),
        }
    }
    /// The side of the square letterboxed input (grey 114 padding, as
    /// Ultralytics) when that is all the model takes of the image (YOLO,
    /// YOLO-World): views pipelined across frames
    /// ([`Pipeline::process_stream`](crate::perception::pipeline::Pipeline::process_stream))
    /// make the next frame's input on another thread while the model runs.
    /// None: the detector takes the image itself.
    fn letterbox_side(&self) -> Option<usize> {
        None
    }
    /// How the letterboxed input is laid out: float planes (the exports'
    /// own `[1,3,S,S]`), or the image's bytes as they are (`[1,S,S,3]`
    /// uint8, a model that converts them itself: on a GPU the conversion
    /// runs there, and a quarter of the bytes cross to it).
    fn input_layout(&self) -> InputLayout {
        InputLayout::ChwF32
    }
    /// Runs the model once on a blank input, whatever the prompts, so that
    /// the first view does not pay the runtime's start (on a GPU: the
    /// CUDA context and cuDNN's search for convolution algorithms, about
    /// 1.5 s). Changes nothing a later view sees. Detectors without a
    /// cost to hide do nothing.
    fn warm_up(&mut self) -> Result<(), DetectorError> {
        Ok(())
    }
    /// [`detect`](Self::detect) on an image made into the model's input
    /// beforehand ([`PreparedImage::letterboxed`] at
    /// [`letterbox_side`](Self::letterbox_side)): the same detections.
    fn detect_prepared(&mut self, input: PreparedImage) -> Result<Vec<Detection>, DetectorError> {
        let _ = input;
        Err(DetectorError::NotPrepared {
            backend: self.backend(),
        })
    }
}

/// The layout of a YOLO model's square image input.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum InputLayout {
    /// `[1,3,S,S]` float: the colour planes, 0..1.
    #[default]
    ChwF32,
    /// `[1,S,S,3]` uint8: the RGB bytes, row by row.
    HwcU8,
}

/// A letterboxed input's pixels, in the model's layout.
#[derive(Debug, Clone, PartialEq)]
pub enum InputPixels {
    /// The colour planes (CHW), byte / 255.
    ChwF32(Vec<f32>),
    /// The RGB bytes (HWC).
    HwcU8(Vec<u8>),
}

impl InputPixels {
    pub fn layout(&self) -> InputLayout {
        match self {
            InputPixels::ChwF32(_) => InputLayout::ChwF32,
            InputPixels::HwcU8(_) => InputLayout::HwcU8,
        }
    }
    fn len(&self) -> usize {
        match self {
            InputPixels::ChwF32(v) => v.len(),
            InputPixels::HwcU8(v) => v.len(),
        }
    }
}

/// An image made into a YOLO model's input ahead of the model: its
/// letterboxed pixels and where the image lies in them.
#[derive(Debug, Clone)]
pub struct PreparedImage {
    pub pixels: InputPixels,
    pub letterbox: Letterbox,
    /// The square input's side, pixels.
    pub side: usize,
}

impl PreparedImage {
    pub fn letterboxed(image: &RgbImage, side: usize, layout: InputLayout) -> PreparedImage {
        let (pixels, letterbox) = match layout {
            InputLayout::ChwF32 => {
                let (chw, l) = super::image::letterbox_chw(image, side, yolo::PAD_VALUE);
                (InputPixels::ChwF32(chw), l)
            }
            InputLayout::HwcU8 => {
                let (hwc, l) = super::image::letterbox_hwc_u8(image, side, yolo::PAD_VALUE);
                (InputPixels::HwcU8(hwc), l)
            }
        };
        PreparedImage {
            pixels,
            letterbox,
            side,
        }
    }

    /// The input for a model of this side and layout.
    pub(crate) fn check_side(
        &self,
        wanted: usize,
        layout: InputLayout,
    ) -> Result<(), DetectorError> {
        if self.pixels.layout() != layout {
            return Err(DetectorError::PreparedLayout {
                made: self.pixels.layout(),
                wanted: layout,
            });
        }
        if self.side == wanted && self.pixels.len() == 3 * wanted * wanted {
            Ok(())
        } else {
            Err(DetectorError::PreparedSize {
                made: self.side,
                wanted,
            })
        }
    }
}

impl PreparedImage {
    /// The model's input tensor: `[1,3,S,S]` float or `[1,S,S,3]` uint8.
    pub fn into_tensor(self) -> Result<ort::value::DynValue, ort::Error> {
        let s = self.side;
        Ok(match self.pixels {
            InputPixels::ChwF32(chw) => {
                ort::value::Tensor::from_array((vec![1usize, 3, s, s], chw))?.into_dyn()
            }
            InputPixels::HwcU8(hwc) => {
                ort::value::Tensor::from_array((vec![1usize, s, s, 3], hwc))?.into_dyn()
            }
        })
    }
}

/// Splits a prompt line ("chair, person; door handle") into prompts:
/// separated by commas or semicolons, trimmed, empty pieces dropped,
/// duplicates (case-insensitive) removed.
pub fn parse_prompts(line: &str) -> Vec<String> {
    let mut out: Vec<String> = Vec::new();
    for p in line.split([',', ';']) {
        let p = p.split_whitespace().collect::<Vec<_>>().join(" ");
        if !p.is_empty() && !out.iter().any(|q| q.eq_ignore_ascii_case(&p)) {
            out.push(p);
        }
    }
    out
}

/// The tokenizer Grounding DINO's caption needs: shipped beside the model.
pub const GROUNDING_DINO_TOKENIZER: &str = "tokenizer.json";

/// Opens a detector model, recognising its backend from its I/O signature:
/// an input named `txt_feats` → YOLO-World (needs `text`); `input_ids` with
/// a text self-attention mask → Grounding DINO (its `tokenizer.json`
/// beside it); otherwise one image input `[1,3,H,W]` with a `names`
/// metadata entry → closed-vocabulary YOLO.
pub fn open_detector(
    path: &Path,
    settings: &DetectorSettings,
    text: Option<TextEmbedder>,
) -> Result<Box<dyn Detector>, DetectorError> {
    let model = Model::load(path, &settings.session)?;
    if grounding_dino::is_grounding_dino(&model) {
        let tokenizer = path.with_file_name(GROUNDING_DINO_TOKENIZER);
        return Ok(Box::new(GroundingDino::from_model(
            model,
            settings.clone(),
            &tokenizer,
        )?));
    }
    if model.signature.input("txt_feats").is_some() {
        let text = text.ok_or_else(|| {
            DetectorError::Prompt(format!(
                "{} is a YOLO-World model: it needs a CLIP text encoder (clip_text_encoder.onnx) \
                 or a text-embeddings file in the models directory",
                path.display()
            ))
        })?;
        return Ok(Box::new(YoloWorld::from_model(
            model,
            settings.clone(),
            text,
        )?));
    }
    Ok(Box::new(ClosedVocabularyYolo::from_model(
        model,
        settings.clone(),
    )?))
}

/// Decodes a YOLO head `[1, 4+C, N]` (cx, cy, w, h in input pixels, then C
/// class scores) for the requested `classes` (index → label, class name),
/// maps boxes back through the letterbox and runs class-wise NMS.
pub(crate) fn decode_yolo_head(
    data: &[f32],
    channels: usize,
    anchors: usize,
    classes: &[(usize, String, String)],
    letterbox: &Letterbox,
    settings: &DetectorSettings,
) -> Vec<Detection> {
    let mut cands: Vec<(usize, Detection)> = Vec::new();
    if data.len() < channels * anchors {
        return Vec::new();
    }
    for n in 0..anchors {
        let mut best: Option<(usize, f32)> = None;
        for (k, (ci, _, _)) in classes.iter().enumerate() {
            let ch = 4 + ci;
            if ch >= channels {
                continue;
            }
            let s = data[ch * anchors + n];
            if s > settings.score_threshold && best.is_none_or(|(_, b)| s > b) {
                best = Some((k, s));
            }
        }
        let Some((k, score)) = best else { continue };
        let cx = data[n];
        let cy = data[anchors + n];
        let w = data[2 * anchors + n];
        let h = data[3 * anchors + n];
        let b = letterbox.to_original([cx - w / 2.0, cy - h / 2.0, cx + w / 2.0, cy + h / 2.0]);
        if !(b[2] > b[0] && b[3] > b[1]) {
            continue;
        }
        let (_, label, class) = &classes[k];
        cands.push((
            k,
            Detection {
                label: label.clone(),
                class: class.clone(),
                score,
                box_xyxy: b,
            },
        ));
    }
    nms_classwise(cands, settings.nms_iou, settings.max_detections)
}

/// IoU of two `[x1, y1, x2, y2]` boxes.
pub fn iou_xyxy(a: &[f32; 4], b: &[f32; 4]) -> f32 {
    let iw = (a[2].min(b[2]) - a[0].max(b[0])).max(0.0);
    let ih = (a[3].min(b[3]) - a[1].max(b[1])).max(0.0);
    let inter = iw * ih;
    let area = |r: &[f32; 4]| (r[2] - r[0]).max(0.0) * (r[3] - r[1]).max(0.0);
    let union = area(a) + area(b) - inter;
    if union <= 0.0 {
        0.0
    } else {
        inter / union
    }
}

/// Greedy NMS per class key; output sorted by descending score.
pub(crate) fn nms_classwise(
    mut cands: Vec<(usize, Detection)>,
    iou_threshold: f32,
    max_detections: usize,
) -> Vec<Detection> {
    cands.sort_by(|a, b| b.1.score.total_cmp(&a.1.score));
    let mut kept: Vec<(usize, Detection)> = Vec::new();
    for (k, d) in cands {
        if kept.len() >= max_detections {
            break;
        }
        let suppressed = kept
            .iter()
            .any(|(kk, kd)| *kk == k && iou_xyxy(&kd.box_xyxy, &d.box_xyxy) > iou_threshold);
        if !suppressed {
            kept.push((k, d));
        }
    }
    kept.into_iter().map(|(_, d)| d).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn det(score: f32, b: [f32; 4]) -> Detection {
        Detection {
            label: "x".into(),
            class: "x".into(),
            score,
            box_xyxy: b,
        }
    }

    #[test]
    fn prompts_are_split_trimmed_and_deduplicated() {
        assert_eq!(
            parse_prompts(" chair,person ;  door   handle,, Chair "),
            vec!["chair", "person", "door handle"]
        );
        assert!(parse_prompts(" , ; ").is_empty());
    }

    #[test]
    fn nms_is_classwise() {
        let c = vec![
            (0, det(0.9, [0.0, 0.0, 10.0, 10.0])),
            (0, det(0.8, [1.0, 1.0, 11.0, 11.0])), // IoU 0.68 with first: gone
            (1, det(0.7, [1.0, 1.0, 11.0, 11.0])), // other class: kept
            (0, det(0.6, [20.0, 20.0, 30.0, 30.0])),
        ];
        let k = nms_classwise(c, 0.45, 300);
        let scores: Vec<f32> = k.iter().map(|d| d.score).collect();
        assert_eq!(scores, vec![0.9, 0.7, 0.6]);
        assert!(
            (iou_xyxy(&[0.0, 0.0, 10.0, 10.0], &[1.0, 1.0, 11.0, 11.0]) - 81.0 / 119.0).abs()
                < 1e-6
        );
    }

    #[test]
    fn head_decoding_maps_boxes_through_the_letterbox() {
        // 2 anchors, 2 classes; letterbox scale 0.5, pad top 160
        let anchors = 2;
        let channels = 6;
        let mut data = vec![0.0f32; channels * anchors];
        // anchor 0: box centred (320, 320) 100x50, class 1 score 0.9
        data[0] = 320.0;
        data[anchors] = 320.0;
        data[2 * anchors] = 100.0;
        data[3 * anchors] = 50.0;
        data[5 * anchors] = 0.9;
        // anchor 1: below threshold
        data[4 * anchors + 1] = 0.1;
        let lb = Letterbox {
            scale: 0.5,
            pad_left: 0.0,
            pad_top: 160.0,
            orig_width: 1280,
            orig_height: 640,
        };
        let classes = vec![
            (0, "cat".to_string(), "cat".to_string()),
            (1, "sofa".to_string(), "couch".to_string()),
        ];
        let d = decode_yolo_head(
            &data,
            channels,
            anchors,
            &classes,
            &lb,
            &DetectorSettings::default(),
        );
        assert_eq!(d.len(), 1);
        assert_eq!(d[0].label, "sofa");
        assert_eq!(d[0].class, "couch");
        assert_eq!(d[0].box_xyxy, [540.0, 270.0, 740.0, 370.0]);
    }
}
