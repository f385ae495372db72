//! The learned detector: a YOLOv8/YOLO11 detect or segment model exported to ONNX, run by ONNX
//! Runtime through `ort` (2.0 rc, `load-dynamic`: the shared library is loaded at start, see
//! [`library`]), decoded in pure Rust by [`crate::detector::yolo`].
//!
//! At start ([`OnnxDetector::new`]) the library is found and loaded, the execution providers are
//! registered in the configured order (a GPU provider that this ONNX Runtime or this machine lacks
//! is a warning, or an error with `require_gpu`), the model is loaded and its inputs and outputs
//! are matched against the known layouts (a model that fits none is refused, naming the shapes
//! it has and those expected). Per frame: letterbox, one run, decode, NMS, masks.
//!
//! The runtime part is behind this crate's `onnx` cargo feature (`ort` with
//! `default-features = false`); the configuration and the decoding are always built.

pub mod config;
#[cfg(feature = "onnx")]
mod detector;
pub mod library;

pub use config::{ExecutionProvider, OnnxConfigError, OnnxDetectorConfig};
#[cfg(feature = "onnx")]
pub use detector::OnnxDetector;

use std::path::PathBuf;

use thiserror::Error;

use crate::detector::yolo::layout::LayoutError;

/// Why the ONNX detector cannot start.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum OnnxDetectorError {
    /// A configuration value is invalid.
    #[error(transparent)]
    Config(#[from] OnnxConfigError),
    /// This build has no ONNX runtime (the `onnx` feature of harvest-perception is off).
    #[error("the onnx detector is not in this build (harvest-perception's `onnx` feature is off)")]
    NotBuilt,
    /// No ONNX Runtime library was found.
    #[error("ONNX Runtime library not found: {tried}; {hint}", hint = library::INSTALL_HINT)]
    LibraryNotFound { tried: String },
    /// The library was found but could not be loaded (wrong file, too old).
    #[error("ONNX Runtime library {path} cannot be used: {reason}; {hint}", hint = library::INSTALL_HINT)]
    LibraryLoad { path: PathBuf, reason: String },
    /// A requested GPU provider is missing and `require_gpu` is set.
    #[error("require_gpu: no GPU execution provider could be registered ({reasons})")]
    NoGpu { reasons: String },
    /// ONNX Runtime could not load the model file.
    #[error("model {path}: {reason}")]
    Model { path: PathBuf, reason: String },
    /// The model fits no known layout.
    #[error("model {path}: {layout}")]
    Layout { path: PathBuf, layout: LayoutError },
}
