//! ONNX Runtime: loading the shared library once, building sessions with the
//! configured execution provider, and reading a model's I/O signature.

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use ort::ep::ExecutionProvider;
use ort::session::Session;
use serde::{Deserialize, Serialize};
use thiserror::Error;

#[derive(Debug, Error)]
pub enum RuntimeError {
    #[error(
        "ONNX Runtime library not found at {path}: run scripts/fetch-onnxruntime.sh (or set \
         ORT_DYLIB_PATH / runtime.onnxruntime_library to libonnxruntime.so 1.31)"
    )]
    LibraryMissing { path: String },
    #[error("ONNX Runtime library {path} could not be loaded: {reason} (scripts/fetch-onnxruntime.sh fetches version 1.31.1)")]
    LibraryLoad { path: String, reason: String },
    #[error("ONNX Runtime was already initialised from {loaded}, not {requested}")]
    LibraryConflict { loaded: String, requested: String },
    #[error("model {path} not found: {hint}")]
    ModelMissing { path: String, hint: String },
    #[error("model {path}: {reason}")]
    Model { path: String, reason: String },
    #[error("model {path}: unexpected I/O signature: {reason}")]
    Signature { path: String, reason: String },
    #[error("inference with {model}: {reason}")]
    Inference { model: String, reason: String },
}

/// Where inference runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum ExecutionProviderKind {
    #[default]
    Cpu,
    Cuda,
    Tensorrt,
}

/// Session settings from config (`[runtime]`).
#[derive(Debug, Clone, PartialEq)]
pub struct SessionSettings {
    pub provider: ExecutionProviderKind,
    /// Threads inside one operator; 0 lets ONNX Runtime choose.
    pub intra_threads: usize,
    /// Threads across operators; 0 lets ONNX Runtime choose.
    pub inter_threads: usize,
}

impl Default for SessionSettings {
    fn default() -> Self {
        SessionSettings {
            provider: ExecutionProviderKind::Cpu,
            intra_threads: 0,
            inter_threads: 0,
        }
    }
}

static LOADED: OnceLock<(PathBuf, ort::environment::Environment)> = OnceLock::new();

/// The library path to use: `configured` if given, else `ORT_DYLIB_PATH`,
/// else `.onnxruntime/libonnxruntime.so` under the current directory.
pub fn resolve_library_path(configured: Option<&Path>) -> PathBuf {
    if let Some(p) = configured {
        return p.to_path_buf();
    }
    if let Some(p) = std::env::var_os("ORT_DYLIB_PATH").filter(|p| !p.is_empty()) {
        return PathBuf::from(p);
    }
    PathBuf::from(".onnxruntime/libonnxruntime.so")
}

/// Loads ONNX Runtime from `path` once per process. Later calls with the
/// same path are free; another path is an error.
pub fn init_runtime(path: &Path) -> Result<(), RuntimeError> {
    if let Some((loaded, _)) = LOADED.get() {
        return if loaded == path {
            Ok(())
        } else {
            Err(RuntimeError::LibraryConflict {
                loaded: loaded.display().to_string(),
                requested: path.display().to_string(),
            })
        };
    }
    if !path.exists() {
        return Err(RuntimeError::LibraryMissing {
            path: path.display().to_string(),
        });
    }
    let builder = ort::init_from(path).map_err(|e| RuntimeError::LibraryLoad {
        path: path.display().to_string(),
        reason: e.to_string(),
    })?;
    let env = builder
        .with_name("opennav")
        .build()
        .map_err(|e| RuntimeError::LibraryLoad {
            path: path.display().to_string(),
            reason: e.to_string(),
        })?;
    let _ = LOADED.set((path.to_path_buf(), env));
    Ok(())
}

/// An input or output of a model: name, element type and shape (−1 = dynamic).
#[derive(Debug, Clone, PartialEq)]
pub struct TensorSpec {
    pub name: String,
    pub dtype: String,
    pub shape: Vec<i64>,
}

impl std::fmt::Display for TensorSpec {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{} {} {:?}", self.name, self.dtype, self.shape)
    }
}

#[derive(Debug, Clone, PartialEq)]
pub struct Signature {
    pub inputs: Vec<TensorSpec>,
    pub outputs: Vec<TensorSpec>,
}

impl Signature {
    pub fn input(&self, name: &str) -> Option<&TensorSpec> {
        self.inputs.iter().find(|t| t.name == name)
    }
    pub fn output(&self, name: &str) -> Option<&TensorSpec> {
        self.outputs.iter().find(|t| t.name == name)
    }
}

impl std::fmt::Display for Signature {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let ins: Vec<String> = self.inputs.iter().map(|t| t.to_string()).collect();
        let outs: Vec<String> = self.outputs.iter().map(|t| t.to_string()).collect();
        write!(
            f,
            "inputs [{}] → outputs [{}]",
            ins.join(", "),
            outs.join(", ")
        )
    }
}

fn spec(name: &str, ty: &ort::value::ValueType) -> TensorSpec {
    TensorSpec {
        name: name.to_string(),
        dtype: ty
            .tensor_type()
            .map(|t| format!("{t:?}").to_lowercase())
            .unwrap_or_else(|| "non-tensor".into()),
        shape: ty.tensor_shape().map(|s| s.to_vec()).unwrap_or_default(),
    }
}

/// A loaded model with its path and signature.
pub struct Model {
    pub path: PathBuf,
    pub session: Session,
    pub signature: Signature,
}

impl std::fmt::Debug for Model {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Model")
            .field("path", &self.path)
            .field("signature", &self.signature)
            .finish()
    }
}

impl Model {
    /// Opens `path` with the given settings. The runtime must be initialised
    /// (see [`init_runtime`]).
    pub fn load(path: &Path, settings: &SessionSettings) -> Result<Model, RuntimeError> {
        let name = path.display().to_string();
        if !path.is_file() {
            return Err(RuntimeError::ModelMissing {
                path: name,
                hint: "see models/README.md for how to obtain it".into(),
            });
        }
        if LOADED.get().is_none() {
            init_runtime(&resolve_library_path(None))?;
        }
        let Some((_, env)) = LOADED.get() else {
            return Err(RuntimeError::LibraryMissing {
                path: resolve_library_path(None).display().to_string(),
            });
        };
        let err = |e: String| RuntimeError::Model {
            path: name.clone(),
            reason: e,
        };
        let mut builder = Session::builder(env).map_err(|e| err(e.to_string()))?;
        if settings.intra_threads > 0 {
            builder = builder
                .with_intra_threads(settings.intra_threads)
                .map_err(|e| err(e.to_string()))?;
        }
        if settings.inter_threads > 0 {
            builder = builder
                .with_inter_threads(settings.inter_threads)
                .map_err(|e| err(e.to_string()))?;
        }
        builder = register_provider(builder, settings.provider, &name)?;
        let session = builder
            .commit_from_file(path)
            .map_err(|e| err(e.to_string()))?;
        let signature = Signature {
            inputs: session
                .inputs()
                .iter()
                .map(|o| spec(o.name(), o.dtype()))
                .collect(),
            outputs: session
                .outputs()
                .iter()
                .map(|o| spec(o.name(), o.dtype()))
                .collect(),
        };
        Ok(Model {
            path: path.to_path_buf(),
            session,
            signature,
        })
    }

    /// A custom metadata value of the model (e.g. `names`).
    pub fn metadata(&self, key: &str) -> Option<String> {
        self.session.metadata().ok()?.custom(key)
    }

    pub fn name(&self) -> String {
        self.path.display().to_string()
    }

    pub fn inference_error(&self, e: impl std::fmt::Display) -> RuntimeError {
        RuntimeError::Inference {
            model: self.name(),
            reason: e.to_string(),
        }
    }

    pub fn signature_error(&self, reason: impl Into<String>) -> RuntimeError {
        RuntimeError::Signature {
            path: self.name(),
            reason: format!("{} (model has {})", reason.into(), self.signature),
        }
    }
}

/// Whether the loaded ONNX Runtime library can run on `kind` (the CPU
/// always; CUDA and TensorRT only with the GPU build, PyPI
/// `onnxruntime-gpu`). Call after [`init_runtime`].
pub fn provider_available(kind: ExecutionProviderKind) -> bool {
    match kind {
        ExecutionProviderKind::Cpu => true,
        ExecutionProviderKind::Cuda => ort::ep::CUDA::is_available().unwrap_or(false),
        ExecutionProviderKind::Tensorrt => ort::ep::TensorRT::is_available().unwrap_or(false),
    }
}

fn register_provider(
    builder: ort::session::builder::SessionBuilder,
    kind: ExecutionProviderKind,
    model: &str,
) -> Result<ort::session::builder::SessionBuilder, RuntimeError> {
    let dispatch = match kind {
        ExecutionProviderKind::Cpu => return Ok(builder),
        ExecutionProviderKind::Cuda => ort::ep::CUDA::default().build().error_on_failure(),
        ExecutionProviderKind::Tensorrt => ort::ep::TensorRT::default().build().error_on_failure(),
    };
    if !provider_available(kind) {
        tracing::warn!(
            provider = ?kind,
            model,
            "execution provider not available in this ONNX Runtime build (the GPU build is PyPI \
             `onnxruntime-gpu`); running on CPU"
        );
        return Ok(builder);
    }
    match builder.with_execution_providers([dispatch]) {
        Ok(b) => Ok(b),
        Err(e) => {
            tracing::warn!(provider = ?kind, model, error = %e, "execution provider failed to register; running on CPU");
            Ok(e.recover())
        }
    }
}
