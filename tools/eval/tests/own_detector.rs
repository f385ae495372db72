//! harvest's own ONNX model (`models/apple_net_640.onnx`, trained by tools/detector_training/ on
//! the simulator's renders) in the perception evaluation, through the real ONNX Runtime (PyPI's
//! `onnxruntime` wheel, found as in production): on worlds it was not trained on (evaluation
//! seeds; training used seeds from 100000), it finds most apples that are at least half
//! visible, reports nothing on frames without apples, and its boxes localize within the 3D gate.
//! The full figures are `harvest eval perception --detector onnx --model ...`
//! (docs/evaluation.md); this test checks a small run with margins below them.

use std::path::Path;
use std::process::Command;

use harvest_eval::{EvalPerceptionArgs, run_eval_perception};
use harvest_perception::depth_source::DepthSource;
use harvest_perception::detector::DetectorKind;
use harvest_perception::estimator::EstimatorKind;

/// Makes sure python3 has `onnxruntime` (the runtime perception loads), installing it with pip
/// when missing, as `.ci/run` does.
fn ensure_onnxruntime() {
    let available = || {
        Command::new("python3")
            .args(["-c", "import onnxruntime"])
            .status()
            .map(|status| status.success())
            .unwrap_or(false)
    };
    if !available() {
        let _ = Command::new("python3")
            .args(["-m", "pip", "install", "--quiet", "onnxruntime"])
            .status();
    }
    assert!(
        available(),
        "python3 with `onnxruntime` is required (python3 -m pip install onnxruntime)"
    );
}

#[test]
fn the_committed_model_finds_apples_on_unseen_worlds() {
    ensure_onnxruntime();
    let model = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../models/apple_net_640.onnx");
    assert!(model.is_file(), "{} is missing", model.display());
    let args = EvalPerceptionArgs {
        scenario: vec!["default".to_owned()],
        frames: 4,
        empty_frames: Some(2),
        seed: 1,
        json: None,
        estimators: vec![EstimatorKind::SphereFit],
        depth_sources: vec![DepthSource::Tof],
        lidar_integration_s: 1.0,
        table_iii_trials: 0,
        detector: Some(DetectorKind::Onnx),
        model: Some(model),
    };
    let report = run_eval_perception(&args).expect("evaluation runs");
    assert_eq!(report.detector, "onnx");
    let detection = &report.scenarios[0].estimators[0].detection;
    let recall = detection.recall_half_visible.expect("apples half visible");
    let precision = detection.precision.expect("detections");
    assert!(recall >= MIN_RECALL, "recall (>= 50 % visible) {recall:.3}");
    assert!(precision >= MIN_PRECISION, "precision {precision:.3}");
    assert_eq!(detection.empty_frame_detections, 0);
}

/// Margins below the model's figures over 30 worlds (docs/evaluation.md).
const MIN_RECALL: f64 = 0.8;
const MIN_PRECISION: f64 = 0.85;
