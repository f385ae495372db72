//! [`OnnxDetector`]: the ONNX Runtime session around the YOLO decoder.

use std::sync::Mutex;

use ort::environment::Environment;
use ort::ep::{self, ExecutionProvider as _};
use ort::logging::LogLevel;
use ort::session::Session;
use ort::session::builder::SessionBuilder;
use ort::value::{Outlet, TensorElementType, TensorRef, ValueType};
use tracing::{info, warn};

use super::OnnxDetectorError;
use super::config::{ExecutionProvider, OnnxDetectorConfig};
use super::library::{LibrarySource, find_library};
use crate::detector::yolo::layout::{ElementType, TensorInfo, YoloHead, identify};
use crate::detector::yolo::letterbox::Letterbox;
use crate::detector::yolo::{DecodeSettings, OutputTensor, YoloDecoder};
use crate::detector::{Detection, Detector, DetectorFrameInfo};
use crate::frame::{FrameError, RgbView};

/// A pixel whose brightest channel reaches this is over-exposed (the colour detector's default).
const CLIP_LEVEL: u8 = 250;

/// The process's ONNX Runtime environment (one per process; the library is loaded once).
static ENVIRONMENT: Mutex<Option<Environment>> = Mutex::new(None);

/// Loads the library (once) and returns the environment.
fn environment() -> Result<Environment, OnnxDetectorError> {
    let mut guard = ENVIRONMENT
        .lock()
        .unwrap_or_else(|poisoned| poisoned.into_inner());
    if let Some(environment) = guard.as_ref() {
        return Ok(environment.clone());
    }
    let (path, source) =
        find_library().map_err(|tried| OnnxDetectorError::LibraryNotFound { tried })?;
    let load_error = |reason: String| OnnxDetectorError::LibraryLoad {
        path: path.clone(),
        reason,
    };
    let environment = ort::init_from(&path)
        .map_err(|error| load_error(error.to_string()))?
        .with_name("harvest")
        .build()
        .map_err(|error| load_error(error.to_string()))?;
    // ONNX Runtime's own messages (through `tracing`): warnings and errors only; its session
    // set-up chatter is not for an operator.
    environment.set_log_level(LogLevel::Warning);
    let found_by = match &source {
        LibrarySource::Environment => "ORT_DYLIB_PATH".to_string(),
        LibrarySource::PythonWheel { package_dir } => {
            format!("python3's onnxruntime package ({})", package_dir.display())
        }
    };
    info!(library = %path.display(), found_by, "ONNX Runtime loaded");
    *guard = Some(environment.clone());
    Ok(environment)
}

/// A YOLO detect or segment model run by ONNX Runtime.
pub struct OnnxDetector {
    session: Session,
    decoder: YoloDecoder,
    input_name: String,
    predictions_name: String,
    protos_name: Option<String>,
    input_size_px: u32,
    input: Vec<f32>,
    provider: ExecutionProvider,
}

impl std::fmt::Debug for OnnxDetector {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("OnnxDetector")
            .field("layout", self.decoder.layout())
            .field("provider", &self.provider)
            .finish_non_exhaustive()
    }
}

impl OnnxDetector {
    /// Loads ONNX Runtime and the model, registers the providers and checks the model's layout.
    pub fn new(config: &OnnxDetectorConfig) -> Result<Self, OnnxDetectorError> {
        config.validate()?;
        let environment = environment()?;
        let model_error = |reason: String| OnnxDetectorError::Model {
            path: config.model.clone(),
            reason,
        };
        let mut builder = Session::builder(&environment)
            .and_then(|builder| {
                builder
                    .with_log_level(LogLevel::Warning)
                    .map_err(Into::into)
            })
            .map_err(|error| model_error(error.to_string()))?;
        let provider = register_providers(&mut builder, config)?;
        if let Some(threads) = config.intra_threads {
            builder = builder
                .with_intra_threads(threads as usize)
                .map_err(|error| model_error(error.to_string()))?;
        }
        let session = builder
            .commit_from_file(&config.model)
            .map_err(|error| model_error(error.to_string()))?;
        let inputs: Vec<TensorInfo> = session.inputs().iter().map(tensor_info).collect();
        let outputs: Vec<TensorInfo> = session.outputs().iter().map(tensor_info).collect();
        let layout = identify(&inputs, &outputs, config.input_size)
            .and_then(|layout| layout.check_classes(&config.classes).map(|()| layout))
            .map_err(|layout| OnnxDetectorError::Layout {
                path: config.model.clone(),
                layout,
            })?;
        let protos_name = match layout.head {
            YoloHead::Detect => None,
            YoloHead::Segment { protos_output } => Some(outputs[protos_output].name.clone()),
        };
        info!(
            model = %config.model.display(),
            head = ?layout.head,
            classes = layout.classes,
            input_size = config.input_size,
            provider = provider.name(),
            "ONNX detector ready"
        );
        Ok(Self {
            input_name: inputs[0].name.clone(),
            predictions_name: outputs[layout.predictions_output].name.clone(),
            protos_name,
            input_size_px: config.input_size,
            decoder: YoloDecoder::new(
                layout,
                DecodeSettings {
                    apple_classes: config.classes.clone(),
                    score_threshold: config.score_threshold,
                    iou_threshold: config.iou_threshold,
                    max_detections: config.max_detections as usize,
                    clip_level: CLIP_LEVEL,
                },
            ),
            session,
            input: Vec::new(),
            provider,
        })
    }

    /// The execution provider the model runs on (the first of the configured ones that could be
    /// registered).
    pub fn provider(&self) -> ExecutionProvider {
        self.provider
    }

    /// The model's layout.
    pub fn layout(&self) -> &crate::detector::yolo::layout::YoloLayout {
        self.decoder.layout()
    }

    fn run(
        &mut self,
        rgb: &RgbView<'_>,
        detections: &mut Vec<Detection>,
    ) -> Result<DetectorFrameInfo, String> {
        let letterbox = Letterbox::new(rgb.width_px, rgb.height_px, self.input_size_px);
        let saturated_fraction = letterbox.fill_input(rgb, &mut self.input, CLIP_LEVEL);
        let side = self.input_size_px as usize;
        let tensor = TensorRef::from_array_view(([1usize, 3, side, side], self.input.as_slice()))
            .map_err(|error| error.to_string())?;
        let outputs = self
            .session
            .run(ort::inputs![self.input_name.as_str() => tensor])
            .map_err(|error| error.to_string())?;
        let extract = |name: &str| -> Result<(Vec<i64>, &[f32]), String> {
            let value = outputs
                .get(name)
                .ok_or_else(|| format!("no output {name}"))?;
            let (shape, data) = value
                .try_extract_tensor::<f32>()
                .map_err(|error| format!("output {name}: {error}"))?;
            Ok((shape.to_vec(), data))
        };
        let (predictions_shape, predictions) = extract(&self.predictions_name)?;
        let protos = match &self.protos_name {
            Some(name) => Some(extract(name)?),
            None => None,
        };
        let mut info = self
            .decoder
            .decode(
                OutputTensor {
                    shape: &predictions_shape,
                    data: predictions,
                },
                protos
                    .as_ref()
                    .map(|(shape, data)| OutputTensor { shape, data }),
                &letterbox,
                rgb,
                detections,
            )
            .map_err(|error| error.to_string())?;
        info.saturated_fraction = saturated_fraction;
        Ok(info)
    }
}

impl Detector for OnnxDetector {
    fn name(&self) -> &'static str {
        "onnx"
    }

    fn detect(
        &mut self,
        rgb: &RgbView<'_>,
        detections: &mut Vec<Detection>,
    ) -> Result<DetectorFrameInfo, FrameError> {
        detections.clear();
        rgb.validate()?;
        self.run(rgb, detections).map_err(|reason| {
            detections.clear();
            FrameError::DetectorFailed {
                detector: "onnx",
                reason,
            }
        })
    }
}

/// Name, element type and shape of a model input or output.
fn tensor_info(outlet: &Outlet) -> TensorInfo {
    let (element, shape) = match outlet.dtype() {
        ValueType::Tensor { ty, shape, .. } => (
            match ty {
                TensorElementType::Float32 => ElementType::Float32,
                TensorElementType::Float16 => ElementType::Other("f16"),
                TensorElementType::Uint8 => ElementType::Other("u8"),
                TensorElementType::Int64 => ElementType::Other("i64"),
                _ => ElementType::Other("non-f32"),
            },
            shape.to_vec(),
        ),
        _ => (ElementType::Other("non-tensor"), Vec::new()),
    };
    TensorInfo {
        name: outlet.name().to_string(),
        element,
        shape,
    }
}

/// Registers the configured providers in order and returns the first registered one. A GPU
/// provider this ONNX Runtime lacks (the CPU wheel) or that fails to register (no CUDA, cuDNN
/// or TensorRT libraries) is a warning, or with `require_gpu` an error when no GPU provider
/// registered at all.
fn register_providers(
    builder: &mut SessionBuilder,
    config: &OnnxDetectorConfig,
) -> Result<ExecutionProvider, OnnxDetectorError> {
    let mut first: Option<ExecutionProvider> = None;
    let mut gpu = false;
    let mut failures = Vec::new();
    for &provider in &config.providers {
        let result = match provider {
            ExecutionProvider::Cpu => ep::CPU::default()
                .register(builder)
                .map_err(|e| e.to_string()),
            ExecutionProvider::Cuda => {
                register_gpu(builder, ep::CUDA::default(), "CUDA 13 and cuDNN 9")
            }
            ExecutionProvider::Tensorrt => register_gpu(
                builder,
                ep::TensorRT::default(),
                "TensorRT 10, CUDA 13 and cuDNN 9",
            ),
        };
        match result {
            Ok(()) => {
                first.get_or_insert(provider);
                gpu |= provider.is_gpu();
            }
            Err(reason) => {
                if !config.require_gpu {
                    warn!(provider = provider.name(), %reason, "execution provider not available; trying the next");
                }
                failures.push(format!("{}: {reason}", provider.name()));
            }
        }
    }
    if config.require_gpu && !gpu {
        return Err(OnnxDetectorError::NoGpu {
            reasons: failures.join("; "),
        });
    }
    Ok(first.unwrap_or(ExecutionProvider::Cpu))
}

/// Registers one GPU provider when this ONNX Runtime has it.
fn register_gpu<P: ep::ExecutionProvider>(
    builder: &mut SessionBuilder,
    provider: P,
    needs: &str,
) -> Result<(), String> {
    match P::is_available() {
        Ok(true) => provider
            .register(builder)
            .map_err(|error| format!("{error} (needs {needs}; see docs/operating.md)")),
        Ok(false) => Err(format!(
            "this ONNX Runtime has no {} (the CPU wheel? install onnxruntime-gpu)",
            P::NAME
        )),
        Err(error) => Err(error.to_string()),
    }
}
