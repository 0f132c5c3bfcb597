//! Text embeddings for the open-vocabulary detector: a CLIP text encoder
//! ONNX fed by our CLIP BPE tokenizer, or a precomputed embeddings file.
//! Embeddings are L2-normalised and cached per prompt, so the vocabulary can
//! change at run time without re-exporting anything.
//!
//! Embeddings file (JSON):
//! `{"format": "opennav-text-embeddings/1", "dim": 512,
//!   "embeddings": {"chair": [0.01, …], "person": […]}}`

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use ort::value::Tensor;
use serde::{Deserialize, Serialize};
use thiserror::Error;

use crate::perception::runtime::{Model, RuntimeError};
use crate::perception::tokenizer::{ClipTokenizer, TokenizerError, CONTEXT_LENGTH, END_OF_TEXT};

pub const EMBEDDINGS_FORMAT: &str = "opennav-text-embeddings/1";

#[derive(Debug, Error)]
pub enum TextEmbeddingError {
    #[error(transparent)]
    Runtime(#[from] RuntimeError),
    #[error(transparent)]
    Tokenizer(#[from] TokenizerError),
    #[error("{path}: {reason}")]
    File { path: String, reason: String },
    #[error("text encoder {model}: {reason}")]
    Encoder { model: String, reason: String },
}

#[derive(Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EmbeddingsFile {
    pub format: String,
    pub dim: usize,
    pub embeddings: HashMap<String, Vec<f32>>,
}

enum Source {
    Encoder {
        model: Box<Model>,
        tokenizer: Box<ClipTokenizer>,
        ids_name: String,
        ids_int32: bool,
        mask_name: Option<String>,
    },
    File {
        path: PathBuf,
        table: HashMap<String, Vec<f32>>,
    },
}

pub struct TextEmbedder {
    source: Source,
    dim: usize,
    cache: HashMap<String, Vec<f32>>,
}

impl std::fmt::Debug for TextEmbedder {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("TextEmbedder")
            .field("source", &self.describe())
            .field("dim", &self.dim)
            .finish()
    }
}

pub fn l2_normalised(v: &[f32]) -> Vec<f32> {
    let n = v.iter().map(|x| x * x).sum::<f32>().sqrt();
    if n > 0.0 {
        v.iter().map(|x| x / n).collect()
    } else {
        v.to_vec()
    }
}

impl TextEmbedder {
    /// A CLIP text encoder: input token ids `[K, 77]` (int64 or int32; an
    /// `attention_mask` input is fed too when present), output `[K, D]`.
    pub fn from_encoder(
        model: Model,
        tokenizer: ClipTokenizer,
    ) -> Result<Self, TextEmbeddingError> {
        let enc_err = |reason: String| TextEmbeddingError::Encoder {
            model: model.name(),
            reason: format!("{reason} (model has {})", model.signature),
        };
        let ids = model
            .signature
            .inputs
            .iter()
            .find(|t| t.name != "attention_mask")
            .ok_or_else(|| enc_err("no token-id input".into()))?;
        if ids.shape.len() != 2 || (ids.shape[1] != CONTEXT_LENGTH as i64 && ids.shape[1] != -1) {
            return Err(enc_err(format!(
                "token-id input `{}` must be [K, {CONTEXT_LENGTH}]",
                ids.name
            )));
        }
        let ids_int32 = match ids.dtype.as_str() {
            "int64" => false,
            "int32" => true,
            other => {
                return Err(enc_err(format!(
                    "token ids must be int64 or int32, not {other}"
                )))
            }
        };
        let out = model
            .signature
            .outputs
            .first()
            .ok_or_else(|| enc_err("no output".into()))?;
        let dim = match out.shape.as_slice() {
            [_, d] if *d > 0 => *d as usize,
            _ => return Err(enc_err(format!("output `{}` must be [K, D]", out.name))),
        };
        let ids_name = ids.name.clone();
        let mask_name = model
            .signature
            .input("attention_mask")
            .map(|t| t.name.clone());
        Ok(TextEmbedder {
            source: Source::Encoder {
                model: Box::new(model),
                tokenizer: Box::new(tokenizer),
                ids_name,
                ids_int32,
                mask_name,
            },
            dim,
            cache: HashMap::new(),
        })
    }

    /// A precomputed embeddings file (see the module docs).
    pub fn from_file(path: &Path) -> Result<Self, TextEmbeddingError> {
        let ferr = |reason: String| TextEmbeddingError::File {
            path: path.display().to_string(),
            reason,
        };
        let text = std::fs::read_to_string(path).map_err(|e| ferr(e.to_string()))?;
        let file: EmbeddingsFile = serde_json::from_str(&text).map_err(|e| ferr(e.to_string()))?;
        if file.format != EMBEDDINGS_FORMAT {
            return Err(ferr(format!(
                "format `{}`, expected `{EMBEDDINGS_FORMAT}`",
                file.format
            )));
        }
        let mut table = HashMap::new();
        for (k, v) in file.embeddings {
            if v.len() != file.dim {
                return Err(ferr(format!(
                    "embedding of `{k}` has {} values, `dim` says {}",
                    v.len(),
                    file.dim
                )));
            }
            if v.iter().any(|x| !x.is_finite()) {
                return Err(ferr(format!("embedding of `{k}` has a non-finite value")));
            }
            table.insert(k.to_lowercase(), l2_normalised(&v));
        }
        Ok(TextEmbedder {
            source: Source::File {
                path: path.to_path_buf(),
                table,
            },
            dim: file.dim,
            cache: HashMap::new(),
        })
    }

    pub fn dim(&self) -> usize {
        self.dim
    }

    pub fn describe(&self) -> String {
        match &self.source {
            Source::Encoder { model, .. } => format!("CLIP text encoder {}", model.name()),
            Source::File { path, .. } => format!("embeddings file {}", path.display()),
        }
    }

    /// Embeddings of `prompts` (L2-normalised, `dim` values each); None for
    /// a prompt an embeddings file does not hold. Encoded prompts are cached.
    pub fn embed(
        &mut self,
        prompts: &[String],
    ) -> Result<Vec<Option<Vec<f32>>>, TextEmbeddingError> {
        let missing: Vec<String> = prompts
            .iter()
            .map(|p| p.to_lowercase())
            .filter(|p| !self.cache.contains_key(p))
            .collect();
        if !missing.is_empty() {
            match &mut self.source {
                Source::File { table, .. } => {
                    for p in &missing {
                        if let Some(v) = table.get(p) {
                            self.cache.insert(p.clone(), v.clone());
                        }
                    }
                }
                Source::Encoder {
                    model,
                    tokenizer,
                    ids_name,
                    ids_int32,
                    mask_name,
                } => {
                    let rows: Vec<[i64; CONTEXT_LENGTH]> = missing
                        .iter()
                        .map(|p| tokenizer.tokenize_padded(p))
                        .collect();
                    let k = rows.len();
                    let flat: Vec<i64> = rows.iter().flatten().copied().collect();
                    let mask: Vec<i64> = rows
                        .iter()
                        .flat_map(|r| {
                            let end = r
                                .iter()
                                .position(|&t| t == END_OF_TEXT)
                                .unwrap_or(CONTEXT_LENGTH - 1);
                            (0..CONTEXT_LENGTH).map(move |i| i64::from(i <= end))
                        })
                        .collect();
                    let name = model.name();
                    let enc_err = |e: ort::Error| TextEmbeddingError::Encoder {
                        model: name.clone(),
                        reason: e.to_string(),
                    };
                    let shape = vec![k, CONTEXT_LENGTH];
                    let mut inputs: Vec<(String, ort::value::DynValue)> = Vec::new();
                    let to_value = |v: Vec<i64>| -> Result<ort::value::DynValue, ort::Error> {
                        if *ids_int32 {
                            let v32: Vec<i32> = v.iter().map(|&x| x as i32).collect();
                            Ok(Tensor::from_array((shape.clone(), v32))?.into_dyn())
                        } else {
                            Ok(Tensor::from_array((shape.clone(), v))?.into_dyn())
                        }
                    };
                    inputs.push((ids_name.clone(), to_value(flat).map_err(enc_err)?));
                    if let Some(m) = mask_name {
                        inputs.push((m.clone(), to_value(mask).map_err(enc_err)?));
                    }
                    let outputs = model.session.run(inputs).map_err(enc_err)?;
                    let (oshape, data) = outputs[0].try_extract_tensor::<f32>().map_err(enc_err)?;
                    if oshape.to_vec() != vec![k as i64, self.dim as i64] {
                        return Err(TextEmbeddingError::Encoder {
                            model: name.clone(),
                            reason: format!(
                                "output shape {:?}, expected [{k}, {}]",
                                oshape.to_vec(),
                                self.dim
                            ),
                        });
                    }
                    for (i, p) in missing.iter().enumerate() {
                        let row = &data[i * self.dim..(i + 1) * self.dim];
                        self.cache.insert(p.clone(), l2_normalised(row));
                    }
                }
            }
        }
        Ok(prompts
            .iter()
            .map(|p| self.cache.get(&p.to_lowercase()).cloned())
            .collect())
    }
}
