//! Processing-time measurement on synthetic full-resolution frames (numbers are reported, never
//! asserted).

use std::time::Instant;

use harvest_ipc::camera_model::RigidTransform;

use crate::camera_setup::CameraSetup;
use crate::estimator::EstimatorKind;
use crate::pipeline::{Perception, PerceptionConfig, PerceptionSetupError};
use crate::synthetic::{SyntheticFrame, SyntheticScene};

/// Per-frame processing time of [`Perception::process_into`] on one thread.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ProcessingTimeReport {
    pub estimator: EstimatorKind,
    pub frames: usize,
    /// Apples placed in each synthetic scene.
    pub apples_in_scene: usize,
    /// Mean apples reported per frame.
    pub mean_apples_reported: f64,
    pub mean_ms: f64,
    /// Fastest frame: the least disturbed by other load on the machine.
    pub min_ms: f64,
    pub median_ms: f64,
    pub max_ms: f64,
    pub mean_detect_ms: f64,
    pub mean_register_ms: f64,
    pub mean_estimate_ms: f64,
}

/// Renders up to four synthetic TL460 scenes (1920x1080 colour, 640x480 depth) with
/// `apple_count` apples and times `frames` pipeline runs over them (after one warm-up run).
pub fn measure_processing_time(
    config: &PerceptionConfig,
    apple_count: usize,
    frames: usize,
    seed: u64,
) -> Result<ProcessingTimeReport, PerceptionSetupError> {
    let cameras = CameraSetup::tl460_simulated(RigidTransform::IDENTITY);
    let mut perception = Perception::new(config.clone(), cameras)?;
    let scenes: Vec<SyntheticFrame> = (0..frames.clamp(1, 4))
        .map(|k| SyntheticScene::orchard(&cameras, apple_count, seed + k as u64).render(&cameras))
        .collect();
    let mut apples = Vec::new();
    if let Some(first) = scenes.first() {
        perception.process_into(&first.rgb_view(), &first.depth_view(), &mut apples);
    }
    let mut times_ms = Vec::with_capacity(frames);
    let (mut detect, mut register, mut estimate, mut reported) = (0.0, 0.0, 0.0, 0.0);
    for k in 0..frames {
        let frame = &scenes[k % scenes.len()];
        let start = Instant::now();
        let stats = perception.process_into(&frame.rgb_view(), &frame.depth_view(), &mut apples);
        times_ms.push(start.elapsed().as_secs_f64() * 1e3);
        detect += stats.timings.detect_us as f64 * 1e-3;
        register += stats.timings.register_us as f64 * 1e-3;
        estimate += stats.timings.estimate_us as f64 * 1e-3;
        reported += apples.len() as f64;
    }
    let n = frames.max(1) as f64;
    let mut sorted = times_ms.clone();
    sorted.sort_by(f64::total_cmp);
    Ok(ProcessingTimeReport {
        estimator: config.estimator.kind,
        frames,
        apples_in_scene: apple_count,
        mean_apples_reported: reported / n,
        mean_ms: times_ms.iter().sum::<f64>() / n,
        min_ms: sorted.first().copied().unwrap_or(0.0),
        median_ms: sorted.get(sorted.len() / 2).copied().unwrap_or(0.0),
        max_ms: sorted.last().copied().unwrap_or(0.0),
        mean_detect_ms: detect / n,
        mean_register_ms: register / n,
        mean_estimate_ms: estimate / n,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Prints the per-frame time; run with
    /// `cargo test -p harvest-perception --release -- --ignored --nocapture report_processing_time`.
    #[test]
    #[ignore = "measurement, run in release"]
    fn report_processing_time() {
        for kind in EstimatorKind::ALL {
            let mut config = PerceptionConfig::default();
            config.estimator.kind = kind;
            let report = measure_processing_time(&config, 24, 40, 100).expect("valid config");
            println!("{report:?}");
        }
    }
}
