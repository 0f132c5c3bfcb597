//! The models directory and its manifest: which file plays which role,
//! its checksum, licence and I/O signature, and how to obtain it.
//!
//! A directory may carry its own `manifest.json`; otherwise the manifest
//! shipped with opennav (`models/manifest.json`) describes the expected
//! files. Within a role, entries are in order of preference.

use std::path::{Path, PathBuf};

use serde::Deserialize;
use sha2::{Digest, Sha256};
use thiserror::Error;

const EMBEDDED_MANIFEST: &str = include_str!("../../models/manifest.json");
pub const MANIFEST_FORMAT: &str = "opennav-models/1";

#[derive(Debug, Error)]
pub enum ModelStoreError {
    #[error("{path}: invalid model manifest: {reason}")]
    Manifest { path: String, reason: String },
    #[error("{path}: sha256 {got} does not match the manifest's {want}: wrong or corrupted file")]
    Checksum {
        path: String,
        got: String,
        want: String,
    },
    #[error("{path}: cannot read: {reason}")]
    Read { path: String, reason: String },
    #[error("no {role} model in {dir}: expected one of: {expected}")]
    Missing {
        role: String,
        dir: String,
        expected: String,
    },
}

#[derive(Debug, Clone, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct ManifestEntry {
    pub role: Role,
    pub file: String,
    pub sha256: Option<String>,
    pub licence: String,
    pub signature: String,
    pub obtain: String,
}

#[derive(Debug, Clone, Copy, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
pub enum Role {
    Detector,
    TextEncoder,
    TextEmbeddings,
    SamEncoder,
    SamDecoder,
    /// A detector's tokenizer (Grounding DINO's `tokenizer.json`).
    Tokenizer,
}

impl Role {
    pub fn name(self) -> &'static str {
        match self {
            Role::Detector => "detector",
            Role::TextEncoder => "text_encoder",
            Role::TextEmbeddings => "text_embeddings",
            Role::SamEncoder => "sam_encoder",
            Role::SamDecoder => "sam_decoder",
            Role::Tokenizer => "tokenizer",
        }
    }
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
struct Manifest {
    format: String,
    models: Vec<ManifestEntry>,
}

#[derive(Debug, Clone)]
pub struct ModelStore {
    dir: PathBuf,
    entries: Vec<ManifestEntry>,
}

pub fn sha256_file(path: &Path) -> Result<String, ModelStoreError> {
    let bytes = std::fs::read(path).map_err(|e| ModelStoreError::Read {
        path: path.display().to_string(),
        reason: e.to_string(),
    })?;
    let digest = Sha256::digest(&bytes);
    Ok(digest.iter().map(|b| format!("{b:02x}")).collect())
}

impl ModelStore {
    pub fn open(dir: &Path) -> Result<Self, ModelStoreError> {
        let own = dir.join("manifest.json");
        let (text, name) = if own.is_file() {
            let t = std::fs::read_to_string(&own).map_err(|e| ModelStoreError::Read {
                path: own.display().to_string(),
                reason: e.to_string(),
            })?;
            (t, own.display().to_string())
        } else {
            (
                EMBEDDED_MANIFEST.to_string(),
                "built-in models/manifest.json".to_string(),
            )
        };
        let m: Manifest = serde_json::from_str(&text).map_err(|e| ModelStoreError::Manifest {
            path: name.clone(),
            reason: e.to_string(),
        })?;
        if m.format != MANIFEST_FORMAT {
            return Err(ModelStoreError::Manifest {
                path: name,
                reason: format!("format `{}`, expected `{MANIFEST_FORMAT}`", m.format),
            });
        }
        Ok(ModelStore {
            dir: dir.to_path_buf(),
            entries: m.models,
        })
    }

    pub fn dir(&self) -> &Path {
        &self.dir
    }

    pub fn entries(&self) -> &[ManifestEntry] {
        &self.entries
    }

    /// The first present file of `role`, checksum-verified when the
    /// manifest gives one. None when no file of that role is there.
    pub fn find(&self, role: Role) -> Result<Option<PathBuf>, ModelStoreError> {
        for e in self.entries.iter().filter(|e| e.role == role) {
            let p = self.dir.join(&e.file);
            if p.is_file() {
                if let Some(want) = &e.sha256 {
                    let got = sha256_file(&p)?;
                    if !got.eq_ignore_ascii_case(want) {
                        return Err(ModelStoreError::Checksum {
                            path: p.display().to_string(),
                            got,
                            want: want.clone(),
                        });
                    }
                }
                return Ok(Some(p));
            }
        }
        Ok(None)
    }

    /// Like [`find`](Self::find), but a missing model is an error that
    /// names the files expected and how to obtain them.
    pub fn require(&self, role: Role) -> Result<PathBuf, ModelStoreError> {
        self.find(role)?.ok_or_else(|| self.missing(role))
    }

    pub fn missing(&self, role: Role) -> ModelStoreError {
        let expected: Vec<String> = self
            .entries
            .iter()
            .filter(|e| e.role == role)
            .map(|e| format!("{} ({})", e.file, e.obtain))
            .collect();
        ModelStoreError::Missing {
            role: role.name().into(),
            dir: self.dir.display().to_string(),
            expected: expected.join("; "),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn embedded_manifest_parses_and_missing_models_are_named() {
        let dir = tempfile::tempdir().unwrap();
        let store = ModelStore::open(dir.path()).unwrap();
        assert!(store.entries().iter().any(|e| e.role == Role::Detector));
        assert_eq!(store.find(Role::Detector).unwrap(), None);
        let e = store.require(Role::SamEncoder).unwrap_err().to_string();
        assert!(e.contains("mobile_sam_encoder.onnx"), "{e}");
    }

    #[test]
    fn checksum_mismatch_is_an_error() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("yolo11n_coco.onnx"), b"not a model").unwrap();
        let store = ModelStore::open(dir.path()).unwrap();
        let e = store.find(Role::Detector).unwrap_err().to_string();
        assert!(e.contains("does not match"), "{e}");
    }

    #[test]
    fn own_manifest_wins() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(
            dir.path().join("manifest.json"),
            r#"{"format":"opennav-models/1","models":[{"role":"detector","file":"d.onnx","sha256":null,"licence":"x","signature":"y","obtain":"z"}]}"#,
        )
        .unwrap();
        std::fs::write(dir.path().join("d.onnx"), b"x").unwrap();
        let store = ModelStore::open(dir.path()).unwrap();
        assert_eq!(
            store.find(Role::Detector).unwrap(),
            Some(dir.path().join("d.onnx"))
        );
        std::fs::write(dir.path().join("manifest.json"), "{").unwrap();
        assert!(ModelStore::open(dir.path()).is_err());
    }
}
