//! `harvest bench detector`: the latency of perception's detectors per frame, on one colour frame
//! of the simulator's camera (1920x1080), measured side by side in one run: each ONNX model given
//! (its letterbox, the ONNX Runtime run on the CPU provider, decoding and masks) and the colour
//! segmentation on the same frame.

use std::path::PathBuf;
use std::time::Instant;

use crate::scene_frame::{SceneFrame, SceneFrameError};
use harvest_perception::RgbView;
use harvest_perception::detector::color_segmentation::{
    ColorSegmentation, ColorSegmentationConfig,
};
use harvest_perception::detector::onnx::{OnnxDetector, OnnxDetectorConfig};
use harvest_perception::detector::{Detection, Detector};

/// Arguments of `harvest bench detector`.
#[derive(Debug, Clone, clap::Args)]
pub struct BenchDetectorArgs {
    /// ONNX models (YOLOv8/YOLO11 detect or segment exports), comma-separated.
    #[arg(long, value_delimiter = ',', required = true)]
    pub model: Vec<PathBuf>,
    /// Input size of each model, comma-separated (one value: all models).
    #[arg(long, value_delimiter = ',', default_value = "640")]
    pub input_size: Vec<u32>,
    /// Timed frames per detector (after 3 untimed warm-up frames).
    #[arg(long, default_value_t = 30)]
    pub frames: u32,
    /// ONNX Runtime's intra-op threads (default: its own, one per core).
    #[arg(long)]
    pub threads: Option<u32>,
    /// Scenario of the frame (preset or file).
    #[arg(long, default_value = "default")]
    pub scenario: String,
}

/// The latency of one detector.
#[derive(Debug, Clone, PartialEq)]
pub struct DetectorLatency {
    pub detector: String,
    pub median_ms: f64,
    pub p95_ms: f64,
    pub detections: usize,
}

/// Why the benchmark could not run.
#[derive(Debug, thiserror::Error)]
pub enum BenchDetectorError {
    #[error(transparent)]
    Scene(#[from] SceneFrameError),
    #[error("detector {name}: {reason}")]
    Detector { name: String, reason: String },
    #[error("--input-size: give one size or one per model")]
    InputSizes,
}

/// Runs the benchmark and prints the table.
pub fn run_bench_detector(
    args: &BenchDetectorArgs,
) -> Result<Vec<DetectorLatency>, BenchDetectorError> {
    let sizes: Vec<u32> = match args.input_size.as_slice() {
        [one] => vec![*one; args.model.len()],
        many if many.len() == args.model.len() => many.to_vec(),
        _ => return Err(BenchDetectorError::InputSizes),
    };
    let scene = SceneFrame::render(&args.scenario)?;
    let view = RgbView {
        width_px: scene.width_px as u32,
        height_px: scene.height_px as u32,
        data: &scene.rgb,
    };
    let mut detectors: Vec<(String, Box<dyn Detector>)> = Vec::new();
    for (model, size) in args.model.iter().zip(sizes) {
        let name = format!("onnx {} @ {size}", model.display());
        let config = OnnxDetectorConfig {
            input_size: size,
            intra_threads: args.threads,
            ..OnnxDetectorConfig::with_model(model.clone())
        };
        let detector = OnnxDetector::new(&config).map_err(|e| BenchDetectorError::Detector {
            name: name.clone(),
            reason: e.to_string(),
        })?;
        detectors.push((name, Box::new(detector)));
    }
    let colour = ColorSegmentation::new(ColorSegmentationConfig::default()).map_err(|e| {
        BenchDetectorError::Detector {
            name: "color_segmentation".to_string(),
            reason: e.to_string(),
        }
    })?;
    detectors.push(("color_segmentation".to_string(), Box::new(colour)));

    let mut results = Vec::new();
    let mut detections: Vec<Detection> = Vec::new();
    for (name, detector) in &mut detectors {
        let mut times_ms = Vec::with_capacity(args.frames as usize);
        for k in 0..args.frames + 3 {
            let start = Instant::now();
            detector
                .detect(&view, &mut detections)
                .map_err(|e| BenchDetectorError::Detector {
                    name: name.clone(),
                    reason: e.to_string(),
                })?;
            if k >= 3 {
                times_ms.push(start.elapsed().as_secs_f64() * 1e3);
            }
        }
        times_ms.sort_by(f64::total_cmp);
        let at = |q: f64| times_ms[((times_ms.len() - 1) as f64 * q).round() as usize];
        results.push(DetectorLatency {
            detector: name.clone(),
            median_ms: at(0.5),
            p95_ms: at(0.95),
            detections: detections.len(),
        });
    }
    println!(
        "Detector latency per {}x{} frame ({} timed frames each, scenario {}):",
        scene.width_px, scene.height_px, args.frames, args.scenario
    );
    println!(
        "{:<60} {:>10} {:>10} {:>10}",
        "detector", "median ms", "p95 ms", "detections"
    );
    for r in &results {
        println!(
            "{:<60} {:>10.1} {:>10.1} {:>10}",
            r.detector, r.median_ms, r.p95_ms, r.detections
        );
    }
    Ok(results)
}
