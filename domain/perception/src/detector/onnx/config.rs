//! [`OnnxDetectorConfig`]: the `[detector]` table with `kind = "onnx"`.

use std::path::PathBuf;

use serde::{Deserialize, Serialize};
use thiserror::Error;

/// An ONNX Runtime execution provider, in the order of preference given in the config.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ExecutionProvider {
    /// NVIDIA TensorRT (the `onnxruntime-gpu` wheel with TensorRT 10 installed).
    Tensorrt,
    /// NVIDIA CUDA (the `onnxruntime-gpu` wheel, CUDA 13 and cuDNN 9).
    Cuda,
    /// The default CPU provider (always available).
    Cpu,
}

impl ExecutionProvider {
    pub fn name(self) -> &'static str {
        match self {
            Self::Tensorrt => "tensorrt",
            Self::Cuda => "cuda",
            Self::Cpu => "cpu",
        }
    }

    pub fn is_gpu(self) -> bool {
        !matches!(self, Self::Cpu)
    }
}

/// A learned detector: a YOLOv8/YOLO11 detect or segment model exported to ONNX, run by ONNX
/// Runtime (see [`crate::detector::onnx`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OnnxDetectorConfig {
    /// The `.onnx` file. A relative path is relative to the working directory.
    pub model: PathBuf,
    /// Side of the square input the image is letterboxed to, pixels (a multiple of 32; a model
    /// exported with a fixed size must be run at that size).
    #[serde(default = "default_input_size")]
    pub input_size: u32,
    /// Class ids of the model that are apples (a single-class apple model: `[0]`; COCO: `[47]`).
    #[serde(default = "default_classes")]
    pub classes: Vec<u32>,
    /// Minimum class score of a detection, in [0, 1].
    #[serde(default = "default_score_threshold")]
    pub score_threshold: f32,
    /// Class-wise NMS drops a box that overlaps a better one of its class by more than this IoU.
    #[serde(default = "default_iou_threshold")]
    pub iou_threshold: f32,
    /// At most this many detections per frame.
    #[serde(default = "default_max_detections")]
    pub max_detections: u32,
    /// Execution providers in order of preference, e.g. `["tensorrt", "cuda", "cpu"]`. A GPU
    /// provider that this ONNX Runtime or this machine lacks is skipped with a warning.
    #[serde(default = "default_providers")]
    pub providers: Vec<ExecutionProvider>,
    /// Refuse to start when no GPU provider of `providers` could be registered.
    #[serde(default)]
    pub require_gpu: bool,
    /// Threads ONNX Runtime runs one node on (CPU provider); default: its own (one per core).
    #[serde(default)]
    pub intra_threads: Option<u32>,
}

fn default_input_size() -> u32 {
    640
}
fn default_classes() -> Vec<u32> {
    vec![0]
}
fn default_score_threshold() -> f32 {
    0.25
}
fn default_iou_threshold() -> f32 {
    0.45
}
fn default_max_detections() -> u32 {
    100
}
fn default_providers() -> Vec<ExecutionProvider> {
    vec![ExecutionProvider::Cpu]
}

impl OnnxDetectorConfig {
    /// The defaults with `model`.
    pub fn with_model(model: PathBuf) -> Self {
        Self {
            model,
            input_size: default_input_size(),
            classes: default_classes(),
            score_threshold: default_score_threshold(),
            iou_threshold: default_iou_threshold(),
            max_detections: default_max_detections(),
            providers: default_providers(),
            require_gpu: false,
            intra_threads: None,
        }
    }

    /// Checks the values that need no model.
    pub fn validate(&self) -> Result<(), OnnxConfigError> {
        if !(32..=4096).contains(&self.input_size) || !self.input_size.is_multiple_of(32) {
            return Err(OnnxConfigError::InputSize {
                value: self.input_size,
            });
        }
        for (key, value) in [
            ("score_threshold", self.score_threshold),
            ("iou_threshold", self.iou_threshold),
        ] {
            if !(0.0..=1.0).contains(&value) {
                return Err(OnnxConfigError::OutOfRange { key, value });
            }
        }
        if self.classes.is_empty() {
            return Err(OnnxConfigError::Empty { key: "classes" });
        }
        if self.providers.is_empty() {
            return Err(OnnxConfigError::Empty { key: "providers" });
        }
        if self.max_detections == 0 {
            return Err(OnnxConfigError::Empty {
                key: "max_detections",
            });
        }
        if self.require_gpu && !self.providers.iter().any(|p| p.is_gpu()) {
            return Err(OnnxConfigError::RequireGpuWithoutGpu);
        }
        Ok(())
    }
}

/// An [`OnnxDetectorConfig`] value that cannot be used.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum OnnxConfigError {
    #[error("onnx detector: input_size = {value} is not a multiple of 32 in 32..=4096")]
    InputSize { value: u32 },
    #[error("onnx detector: {key} = {value} is outside 0..=1")]
    OutOfRange { key: &'static str, value: f32 },
    #[error("onnx detector: {key} is empty")]
    Empty { key: &'static str },
    #[error(
        "onnx detector: require_gpu = true but providers names no GPU provider (tensorrt, cuda)"
    )]
    RequireGpuWithoutGpu,
}
