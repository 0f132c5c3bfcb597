//! Opens what the configuration asks for: ONNX Runtime, the detector and
//! the segmenter, from the models directory or explicit paths. (The
//! perception modules themselves take plain parameters, never `Settings`.)

use std::path::{Path, PathBuf};

use thiserror::Error;

use crate::config::{SegmenterChoice, Settings};
use crate::perception::detector::{
    open_detector, Detector, DetectorError, TextEmbedder, TextEmbeddingError,
};
use crate::perception::models::{ModelStore, ModelStoreError, Role};
use crate::perception::runtime::{init_runtime, resolve_library_path, Model, RuntimeError};
use crate::perception::segmenter::{DepthBoxSegmenter, SamSegmenter, Segmenter};
use crate::perception::tokenizer::ClipTokenizer;

#[derive(Debug, Error)]
pub enum SetupError {
    #[error(transparent)]
    Store(#[from] ModelStoreError),
    #[error(transparent)]
    Runtime(#[from] RuntimeError),
    #[error(transparent)]
    Detector(#[from] DetectorError),
    #[error(transparent)]
    Text(#[from] TextEmbeddingError),
}

/// What to open: the configured choices, with command-line overrides.
#[derive(Debug, Clone, Default)]
pub struct PerceptionChoice {
    /// Detector model file; None: from the models directory.
    pub detector: Option<PathBuf>,
    /// "auto", "depth", "sam", or a directory holding the SAM encoder and decoder.
    pub segmenter: Option<String>,
    /// Models directory; None: from config.
    pub models_dir: Option<PathBuf>,
}

/// Loads ONNX Runtime from the configured library path.
pub fn init_runtime_from(settings: &Settings) -> Result<(), RuntimeError> {
    init_runtime(&resolve_library_path(
        settings.onnxruntime_library().as_deref(),
    ))
}

fn text_embedder(
    store: &ModelStore,
    settings: &Settings,
) -> Result<Option<TextEmbedder>, SetupError> {
    if let Some(enc) = store.find(Role::TextEncoder)? {
        let model = Model::load(&enc, &settings.session_settings())?;
        let tok = ClipTokenizer::standard().map_err(TextEmbeddingError::from)?;
        return Ok(Some(TextEmbedder::from_encoder(model, tok)?));
    }
    if let Some(file) = store.find(Role::TextEmbeddings)? {
        return Ok(Some(TextEmbedder::from_file(&file)?));
    }
    Ok(None)
}

pub fn open_configured_detector(
    settings: &Settings,
    choice: &PerceptionChoice,
) -> Result<Box<dyn Detector>, SetupError> {
    init_runtime_from(settings)?;
    let dir = choice
        .models_dir
        .clone()
        .unwrap_or_else(|| settings.models.dir.clone());
    let store = ModelStore::open(&dir)?;
    let path = match (&choice.detector, settings.perception.detector.as_str()) {
        (Some(p), _) => p.clone(),
        (None, "auto") => store.require(Role::Detector)?,
        (None, p) => PathBuf::from(p),
    };
    let text = text_embedder(&store, settings)?;
    // a tokenizer the manifest lists is checked (its checksum) before use
    store.find(Role::Tokenizer)?;
    Ok(open_detector(&path, &settings.detector_settings(), text)?)
}

fn sam_from_dir(dir: &Path, settings: &Settings) -> Result<Option<SamSegmenter>, SetupError> {
    let store = ModelStore::open(dir)?;
    match (store.find(Role::SamEncoder)?, store.find(Role::SamDecoder)?) {
        (Some(e), Some(d)) => {
            let s = settings.session_settings();
            Ok(Some(SamSegmenter::new(
                Model::load(&e, &s)?,
                Model::load(&d, &s)?,
            )?))
        }
        _ => Ok(None),
    }
}

pub fn open_configured_segmenter(
    settings: &Settings,
    choice: &PerceptionChoice,
) -> Result<Box<dyn Segmenter>, SetupError> {
    let dir = choice
        .models_dir
        .clone()
        .unwrap_or_else(|| settings.models.dir.clone());
    let depth = || {
        Box::new(DepthBoxSegmenter::new(settings.depth_segmenter_settings())) as Box<dyn Segmenter>
    };
    let pick = choice
        .segmenter
        .clone()
        .unwrap_or_else(|| match settings.perception.segmenter {
            SegmenterChoice::Auto => "auto".into(),
            SegmenterChoice::Sam => "sam".into(),
            SegmenterChoice::Depth => "depth".into(),
        });
    match pick.as_str() {
        "depth" => Ok(depth()),
        "auto" => {
            init_runtime_from(settings)?;
            Ok(match sam_from_dir(&dir, settings)? {
                Some(s) => Box::new(s),
                None => {
                    tracing::info!(dir = %dir.display(), "no SAM encoder/decoder installed: depth-guided segmentation");
                    depth()
                }
            })
        }
        other => {
            init_runtime_from(settings)?;
            let sam_dir = if other == "sam" {
                dir
            } else {
                PathBuf::from(other)
            };
            match sam_from_dir(&sam_dir, settings)? {
                Some(s) => Ok(Box::new(s)),
                None => {
                    let store = ModelStore::open(&sam_dir)?;
                    let role = if store.find(Role::SamEncoder)?.is_none() {
                        Role::SamEncoder
                    } else {
                        Role::SamDecoder
                    };
                    Err(store.missing(role).into())
                }
            }
        }
    }
}
