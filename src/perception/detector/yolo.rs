//! Closed-vocabulary YOLO (Ultralytics v8/11 export): `images`
//! `[1,3,S,S]` → `output0` `[1, 4+C, N]`, class names in the `names`
//! metadata, no NMS inside. The segmentation exports (YOLO11-seg, and
//! YOLOE-seg with its text prompts set before export: `set_classes`) carry
//! M mask coefficients after the classes, `output0` `[1, 4+C+M, N]`, and
//! the prototypes `output1` `[1, M, H, W]`: their boxes are read the same
//! way (the masks come from the segmenter, as for every detector).

use super::vocab::{parse_class_names, resolve_prompt};
use super::{
    decode_yolo_head, Detection, Detector, DetectorError, DetectorSettings, InputLayout,
    InputPixels, PreparedImage, PromptReport,
};
use crate::perception::runtime::Model;

/// Letterbox padding value (grey 114), as Ultralytics.
pub const PAD_VALUE: u8 = 114;

pub struct ClosedVocabularyYolo {
    model: Model,
    settings: DetectorSettings,
    input_name: String,
    input_size: usize,
    input_layout: InputLayout,
    names: Vec<String>,
    /// Mask coefficients after the classes (a segmentation export), M.
    mask_channels: usize,
    /// A YOLOE export (its metadata says so).
    yoloe: bool,
    /// (class index, prompt, class name) for the active prompts.
    active: Vec<(usize, String, String)>,
}

/// Checks an image input, `[1, 3, S, S]` float or `[1, S, S, 3]` uint8
/// (S fixed), and returns (name, S, layout).
pub(crate) fn image_input(
    model: &Model,
    name: Option<&str>,
) -> Result<(String, usize, InputLayout), DetectorError> {
    let spec = match name {
        Some(n) => model.signature.input(n),
        None => model.signature.inputs.first(),
    }
    .ok_or_else(|| model.signature_error("no image input"))?;
    match spec.shape.as_slice() {
        [b, 3, h, w] if (*b == 1 || *b == -1) && *h > 0 && h == w && spec.dtype == "float32" => {
            Ok((spec.name.clone(), *h as usize, InputLayout::ChwF32))
        }
        [b, h, w, 3] if (*b == 1 || *b == -1) && *h > 0 && h == w && spec.dtype == "uint8" => {
            Ok((spec.name.clone(), *h as usize, InputLayout::HwcU8))
        }
        _ => Err(model
            .signature_error(format!(
                "image input `{}` ({} {:?}) must be float32 [1,3,S,S] or uint8 [1,S,S,3] \
                 with a fixed square size S",
                spec.name, spec.dtype, spec.shape
            ))
            .into()),
    }
}

impl ClosedVocabularyYolo {
    pub fn from_model(model: Model, settings: DetectorSettings) -> Result<Self, DetectorError> {
        if model.signature.inputs.len() != 1 {
            return Err(model
                .signature_error("a closed-vocabulary YOLO has exactly one input")
                .into());
        }
        let (input_name, input_size, input_layout) = image_input(&model, None)?;
        let names_text = model.metadata("names").ok_or_else(|| {
            model.signature_error("no `names` metadata: cannot tell what the classes are")
        })?;
        let names = parse_class_names(&names_text).map_err(|e| model.signature_error(e))?;
        let out = model
            .signature
            .outputs
            .first()
            .ok_or_else(|| model.signature_error("no output"))?;
        // a segmentation export: prototypes [1, M, H, W] as the second output
        let mask_channels = match model.signature.outputs.get(1).map(|o| o.shape.as_slice()) {
            Some([_, m, _, _]) if *m > 0 => *m as usize,
            _ => 0,
        };
        match out.shape.as_slice() {
            [_, c, _] if *c == -1 || *c as usize == 4 + names.len() + mask_channels => {}
            _ => {
                return Err(model
                    .signature_error(format!(
                        "output `{}` must be [1, 4+{}{}, N] for the {} classes in `names`",
                        out.name,
                        names.len(),
                        if mask_channels > 0 {
                            format!("+{mask_channels}")
                        } else {
                            String::new()
                        },
                        names.len()
                    ))
                    .into())
            }
        }
        let yoloe = model
            .metadata("description")
            .is_some_and(|d| d.to_ascii_lowercase().contains("yoloe"));
        Ok(ClosedVocabularyYolo {
            model,
            settings,
            input_name,
            input_size,
            input_layout,
            names,
            mask_channels,
            yoloe,
            active: Vec::new(),
        })
    }

    pub fn class_names(&self) -> &[String] {
        &self.names
    }
}

impl Detector for ClosedVocabularyYolo {
    fn backend(&self) -> &'static str {
        if self.yoloe {
            // its prompts were set at export: a closed vocabulary here
            "yoloe-closed-vocabulary"
        } else {
            "yolo-closed-vocabulary"
        }
    }

    fn set_prompts(&mut self, prompts: &[String]) -> Result<PromptReport, DetectorError> {
        if prompts.is_empty() {
            return Err(DetectorError::Prompt("no prompt given".into()));
        }
        let mut report = PromptReport::default();
        let mut active: Vec<(usize, String, String)> = Vec::new();
        for p in prompts {
            match resolve_prompt(p, &self.names) {
                Some(i) => {
                    report.matched.push((p.clone(), self.names[i].clone()));
                    // two prompts for one class: the first one names it
                    if !active.iter().any(|(c, _, _)| *c == i) {
                        active.push((i, p.clone(), self.names[i].clone()));
                    }
                }
                None => report.unmatched.push(p.clone()),
            }
        }
        self.active = active;
        Ok(report)
    }

    // `detect`: the trait's, through the letterbox below

    fn warm_up(&mut self) -> Result<(), DetectorError> {
        let name = self.model.name();
        let s = self.input_size;
        // the letterbox's grey, as a view's padding
        let grey = PreparedImage {
            pixels: match self.input_layout {
                InputLayout::ChwF32 => {
                    InputPixels::ChwF32(vec![f32::from(PAD_VALUE) / 255.0; 3 * s * s])
                }
                InputLayout::HwcU8 => InputPixels::HwcU8(vec![PAD_VALUE; 3 * s * s]),
            },
            letterbox: crate::perception::image::Letterbox {
                scale: 1.0,
                pad_left: 0.0,
                pad_top: 0.0,
                orig_width: s,
                orig_height: s,
            },
            side: s,
        };
        let run = |session: &mut ort::session::Session| -> Result<(), ort::Error> {
            let tensor = grey.into_tensor()?;
            session.run(ort::inputs![self.input_name.as_str() => tensor])?;
            Ok(())
        };
        run(&mut self.model.session).map_err(|e| {
            crate::perception::runtime::RuntimeError::Inference {
                model: name,
                reason: e.to_string(),
            }
            .into()
        })
    }

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
        let out_name = self.model.signature.outputs[0].name.clone();
        let letterbox = input.letterbox;
        let tensor = input.into_tensor().map_err(err)?;
        let outputs = self
            .model
            .session
            .run(ort::inputs![self.input_name.as_str() => tensor])
            .map_err(err)?;
        let (shape, data) = outputs[0].try_extract_tensor::<f32>().map_err(err)?;
        let dims: Vec<i64> = shape.to_vec();
        let (channels, anchors) = match dims.as_slice() {
            [1, c, n] if *c as usize == 4 + self.names.len() + self.mask_channels => {
                (*c as usize, *n as usize)
            }
            _ => {
                return Err(DetectorError::Output {
                    model: name.clone(),
                    output: out_name,
                    shape: dims,
                    expected: format!("[1, {}, N]", 4 + self.names.len() + self.mask_channels),
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
