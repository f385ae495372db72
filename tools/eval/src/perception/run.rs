//! The evaluation loop: render, process, match, record.

use std::time::Instant;

use crate::lidar::evaluation::{EvalLidarArgs, PAPER_TABLE_III_CM};
use harvest_ipc::payloads::AppleDetections;
use harvest_perception::PerceptionConfig;
use harvest_perception::calibration::{Calibration, CameraCalibration};
use harvest_perception::depth_source::DepthSource;
use harvest_perception::detector::{DetectorConfig, make_detector};
use harvest_perception::estimator::EstimatorKind;
use harvest_perception::node::PerceptionNode;
use harvest_sim::process::load_scenario;
use harvest_sim::{Scenario, World};
use nix::time::{ClockId, clock_gettime};
use tracing::{info, trace, warn};

use crate::perception::args::EvalPerceptionArgs;
use crate::perception::error::EvalError;
use crate::perception::frame::{FrameRenderer, zeroed_frame};
use crate::perception::lidar_capture::LidarCapture;
use crate::perception::matching::{
    FalsePositiveKind, MatchRule, Matching, OverlapTable, ReportedApple, TrueApple,
};
use crate::perception::records::{AppleOutcome, EstimatorRecords, FrameTiming};
use crate::perception::report::{PerceptionReport, ScenarioReport};
use crate::perception::tables::render_tables;
use crate::perception::truth::{FrameApple, TruthMeter, count_box_overlap};

/// Where perception's extrinsic calibration comes from in this evaluation.
pub const CALIBRATION_SOURCE: &str = "robot_from_camera = the simulator's true colour-sensor pose \
     (renderer robot_from_color), i.e. a perfect extrinsic calibration";

/// Runs the evaluation, prints the tables to stdout and writes the JSON report if asked.
pub fn run_eval_perception(args: &EvalPerceptionArgs) -> Result<PerceptionReport, EvalError> {
    let report = evaluate(args)?;
    print!("{}", render_tables(&report));
    if let Some(path) = &args.json {
        let text = serde_json::to_string_pretty(&report)?;
        std::fs::write(path, text + "\n").map_err(|source| EvalError::WriteJson {
            path: path.clone(),
            source,
        })?;
        info!(path = %path.display(), "wrote the JSON report");
    }
    Ok(report)
}

/// Runs the evaluation and returns the report (prints nothing).
pub fn evaluate(args: &EvalPerceptionArgs) -> Result<PerceptionReport, EvalError> {
    if args.frames == 0 {
        return Err(EvalError::BadArgument {
            argument: "--frames",
            value: "0".to_owned(),
            reason: "at least one frame is needed",
        });
    }
    let empty_frames = args.empty_frames.unwrap_or(args.frames);
    let span = u64::from(args.frames.max(empty_frames));
    if args.seed.checked_add(span).is_none() {
        return Err(EvalError::BadArgument {
            argument: "--seed",
            value: args.seed.to_string(),
            reason: "seed + frames overflows u64",
        });
    }
    let kinds = first_occurrences(&args.estimators);
    let depth_sources = first_occurrences(&args.depth_sources);
    if depth_sources.is_empty() {
        return Err(EvalError::BadArgument {
            argument: "--depth-sources",
            value: String::new(),
            reason: "name at least one depth source",
        });
    }
    let variants: Vec<(DepthSource, EstimatorKind)> = depth_sources
        .iter()
        .flat_map(|&source| kinds.iter().map(move |&kind| (source, kind)))
        .collect();
    if kinds.is_empty() {
        return Err(EvalError::BadArgument {
            argument: "--estimators",
            value: String::new(),
            reason: "name at least one estimator",
        });
    }
    if args.scenario.is_empty() {
        return Err(EvalError::BadArgument {
            argument: "--scenario",
            value: String::new(),
            reason: "name at least one scenario preset or file",
        });
    }
    let mut detector = DetectorConfig::default();
    detector
        .override_with(args.detector, args.model.as_deref())
        .map_err(EvalError::Detector)?;
    let rule = MatchRule::default();
    let mut scenarios = Vec::new();
    for name in &args.scenario {
        let scenario = load_scenario(name).map_err(|source| EvalError::Scenario {
            scenario: name.clone(),
            source: Box::new(source),
        })?;
        let run = ScenarioRun {
            name,
            scenario: &scenario,
            seed: args.seed,
            frames: args.frames,
            empty_frames,
            rule,
            lidar_integration_s: args.lidar_integration_s,
            detector: &detector,
        };
        scenarios.push(run.evaluate(&variants)?);
    }
    let repeatability =
        if depth_sources.contains(&DepthSource::LidarFused) && args.table_iii_trials > 0 {
            let table_args = EvalLidarArgs {
                trials: args.table_iii_trials,
                integration_s: args.lidar_integration_s,
                distances_m: PAPER_TABLE_III_CM.iter().map(|row| row.0).collect(),
                seed: args.seed,
                fusion_runs: FUSION_TIMING_RUNS,
            };
            let report = crate::lidar::evaluation::evaluate(&table_args).map_err(|source| {
                EvalError::TableIii {
                    source: Box::new(source),
                }
            })?;
            Some(report)
        } else {
            None
        };
    Ok(PerceptionReport {
        detector: detector.kind_name(),
        seed: args.seed,
        frames_per_scenario: args.frames,
        empty_frames_per_scenario: empty_frames,
        matching_rule: rule,
        lidar_integration_s: depth_sources
            .contains(&DepthSource::LidarFused)
            .then_some(args.lidar_integration_s),
        scenarios,
        repeatability,
    })
}

/// `values` without repeats, in the order of their first occurrence.
fn first_occurrences<T: Copy + PartialEq>(values: &[T]) -> Vec<T> {
    let mut unique = Vec::with_capacity(values.len());
    for value in values {
        if !unique.contains(value) {
            unique.push(*value);
        }
    }
    unique
}

/// The depth image a variant localizes from: the fused one for `lidar_fused`, else the frame's.
fn depth_for(source: DepthSource, fused_depth_mm: Option<&[u16]>) -> Option<&[u16]> {
    match source {
        DepthSource::Tof => None,
        DepthSource::LidarFused => fused_depth_mm,
    }
}

/// CPU time consumed by the calling thread, nanoseconds.
fn thread_cpu_ns() -> Result<i128, EvalError> {
    let now = clock_gettime(ClockId::CLOCK_THREAD_CPUTIME_ID).map_err(EvalError::CpuClock)?;
    Ok(i128::from(now.tv_sec()) * 1_000_000_000 + i128::from(now.tv_nsec()))
}

/// Runs of the fusion-time measurement printed with the Table-III comparison.
const FUSION_TIMING_RUNS: usize = 30;

/// The evaluation of one scenario.
struct ScenarioRun<'a> {
    name: &'a str,
    detector: &'a DetectorConfig,
    scenario: &'a Scenario,
    seed: u64,
    frames: u32,
    empty_frames: u32,
    rule: MatchRule,
    /// LiDAR window per frame of the `lidar_fused` depth source, seconds.
    lidar_integration_s: f64,
}

/// One perception node under evaluation: an estimator on a depth source, and what it did.
struct Variant {
    node: PerceptionNode,
    record: EstimatorRecords,
}

/// Per-frame scratch reused across frames and estimators.
#[derive(Default)]
struct Scratch {
    truth: Vec<FrameApple>,
    true_apples: Vec<TrueApple>,
    reported: Vec<ReportedApple>,
    overlap: OverlapTable,
    matching: Matching,
    matching_2d: Matching,
}

impl ScenarioRun<'_> {
    fn world(&self, scenario: &Scenario, seed: u64) -> Result<World, EvalError> {
        World::generate(scenario, seed).map_err(|source| EvalError::World {
            scenario: self.name.to_owned(),
            seed,
            source: Box::new(source),
        })
    }

    fn render_error(&self, source: harvest_sim::RenderError) -> EvalError {
        EvalError::Render {
            scenario: self.name.to_owned(),
            source: Box::new(source),
        }
    }

    fn evaluate(
        &self,
        variants: &[(DepthSource, EstimatorKind)],
    ) -> Result<ScenarioReport, EvalError> {
        let mut renderer =
            FrameRenderer::new(&self.scenario.camera).map_err(|e| self.render_error(e))?;
        let robot_from_color = renderer.robot_from_color();
        let calibration = Calibration {
            camera: CameraCalibration {
                robot_from_camera: robot_from_color,
            },
        };
        let meter = TruthMeter::new(renderer.color_intrinsics(), robot_from_color);
        let mut variants: Vec<Variant> = variants
            .iter()
            .map(|&(depth_source, kind)| {
                let mut config = PerceptionConfig::default();
                config.estimator.kind = kind;
                config.depth_source = depth_source;
                config.detector = self.detector.clone();
                // Built here so a model that cannot be loaded stops the evaluation at once.
                let detector = make_detector(&config.detector)
                    .map_err(|error| EvalError::Detector(error.to_string()))?;
                Ok(Variant {
                    node: PerceptionNode::with_detector(config, calibration, detector),
                    record: EstimatorRecords::new(kind, depth_source),
                })
            })
            .collect::<Result<_, EvalError>>()?;
        let mut lidar = if variants
            .iter()
            .any(|v| v.record.depth_source == DepthSource::LidarFused)
        {
            Some(LidarCapture::new(self.lidar_integration_s, self.seed)?)
        } else {
            None
        };
        let mut frame = zeroed_frame();
        let mut out = Box::<AppleDetections>::default();
        let mut labels = vec![0u32; meter.pixel_count()];
        let mut scratch = Scratch::default();
        let mut apples_generated = 0;
        info!(
            scenario = self.name,
            frames = self.frames,
            empty_frames = self.empty_frames,
            variants = variants.len(),
            "evaluating perception"
        );
        for i in 0..self.frames {
            let seed = self.seed + u64::from(i);
            let world = self.world(self.scenario, seed)?;
            apples_generated += world.apples().len();
            renderer
                .render(&world, u64::from(i), &mut frame)
                .map_err(|e| self.render_error(e))?;
            renderer
                .render_labels(&world, &mut labels)
                .map_err(|e| self.render_error(e))?;
            let fused_depth_mm = match lidar.as_mut() {
                Some(lidar) => Some(lidar.capture(&world, &frame.meta)?),
                None => None,
            };
            meter.measure(&world, &labels, &mut scratch.truth);
            scratch.true_apples.clear();
            scratch
                .true_apples
                .extend(scratch.truth.iter().map(|apple| TrueApple {
                    center_in_robot_m: apple.center_in_robot_m,
                    radius_m: apple.radius_m,
                    visible_px: apple.visible_px,
                }));
            let visible_apples = scratch.truth.iter().filter(|a| a.visible_px > 0).count();
            // Rotate the order so no variant always runs first on a freshly rendered frame.
            for k in 0..variants.len() {
                let e = (k + i as usize) % variants.len();
                let variant = &mut variants[e];
                let depth = depth_for(variant.record.depth_source, fused_depth_mm);
                if i == 0 {
                    // Warm-up: builds the pipeline for the frame's camera metadata.
                    self.process(variant, &frame, depth, &mut out)?;
                }
                let start_cpu_ns = thread_cpu_ns()?;
                let start = Instant::now();
                self.process(variant, &frame, depth, &mut out)?;
                let process_ms = start.elapsed().as_secs_f64() * 1e3;
                let process_cpu_ms = (thread_cpu_ns()? - start_cpu_ns) as f64 * 1e-6;
                let record = &mut variant.record;
                record.timings.push(FrameTiming {
                    process_ms,
                    process_cpu_ms,
                    visible_apples,
                });
                self.score(&out, &labels, meter.width_px(), &mut scratch, record);
                trace!(
                    frame = i,
                    estimator = record.kind.name(),
                    depth_source = record.depth_source.name(),
                    reported = out.apples.len(),
                    visible_apples,
                    process_ms,
                    process_cpu_ms,
                    "frame evaluated"
                );
            }
        }
        let mut empty = self.scenario.clone();
        empty.apples.count = 0;
        for i in 0..self.empty_frames {
            let world = self.world(&empty, self.seed + u64::from(i))?;
            renderer
                .render(&world, u64::from(self.frames) + u64::from(i), &mut frame)
                .map_err(|e| self.render_error(e))?;
            let fused_depth_mm = match lidar.as_mut() {
                Some(lidar) => Some(lidar.capture(&world, &frame.meta)?),
                None => None,
            };
            for variant in &mut variants {
                let depth = depth_for(variant.record.depth_source, fused_depth_mm);
                self.process(variant, &frame, depth, &mut out)?;
                let record = &mut variant.record;
                record.empty_frame_detections.push(out.apples.len());
                trace!(
                    frame = i,
                    estimator = record.kind.name(),
                    depth_source = record.depth_source.name(),
                    reported = out.apples.len(),
                    "frame without apples evaluated"
                );
            }
        }
        for variant in &variants {
            if variant.node.frames_rejected() > 0 {
                warn!(
                    estimator = variant.record.kind.name(),
                    depth_source = variant.record.depth_source.name(),
                    rejected = variant.node.frames_rejected(),
                    "perception rejected frames"
                );
            }
        }
        let records: Vec<EstimatorRecords> = variants.into_iter().map(|v| v.record).collect();
        Ok(ScenarioReport::from_records(
            &self.scenario.name,
            self.name,
            CALIBRATION_SOURCE,
            apples_generated,
            &records,
        ))
    }

    /// Runs `variant`'s node on `frame`, with `depth_mm` in place of the frame's depth when given.
    fn process(
        &self,
        variant: &mut Variant,
        frame: &harvest_ipc::payloads::RgbdFrame,
        depth_mm: Option<&[u16]>,
        out: &mut AppleDetections,
    ) -> Result<(), EvalError> {
        let kind = variant.record.kind;
        let stats = variant
            .node
            .process_with_depth(frame, depth_mm, out)
            .map_err(|source| EvalError::PerceptionSetup {
                scenario: self.name.to_owned(),
                estimator: kind.name(),
                source: Box::new(source),
            })?;
        if let Some(rejection) = stats.rejection {
            warn!(estimator = kind.name(), %rejection, "perception rejected a frame");
        }
        Ok(())
    }

    /// Matches the reported apples of one frame and records the outcome.
    fn score(
        &self,
        out: &AppleDetections,
        labels: &[u32],
        width_px: usize,
        scratch: &mut Scratch,
        record: &mut EstimatorRecords,
    ) {
        let apples = out.apples.as_slice();
        scratch.reported.clear();
        scratch
            .reported
            .extend(apples.iter().map(|a| ReportedApple {
                position_in_robot_m: a.position_in_robot_m,
                box_area_px: u64::from(a.box_px[2]) * u64::from(a.box_px[3]),
            }));
        scratch.overlap.reset(apples.len(), scratch.truth.len());
        for (d, apple) in apples.iter().enumerate() {
            count_box_overlap(labels, width_px, apple.box_px, scratch.overlap.row_mut(d));
        }
        self.rule.match_frame(
            &scratch.reported,
            &scratch.true_apples,
            &scratch.overlap,
            &mut scratch.matching,
        );
        self.rule.without_3d_gate().match_frame(
            &scratch.reported,
            &scratch.true_apples,
            &scratch.overlap,
            &mut scratch.matching_2d,
        );
        record.detections += apples.len();
        record.false_positives += scratch.matching.false_positives();
        for d in 0..apples.len() {
            match self.rule.false_positive_kind(
                d,
                &scratch.reported,
                &scratch.true_apples,
                &scratch.overlap,
                &scratch.matching,
            ) {
                Some(FalsePositiveKind::Duplicate) => record.false_positives_duplicate += 1,
                Some(FalsePositiveKind::Mislocalized) => record.false_positives_mislocalized += 1,
                Some(FalsePositiveKind::NoApple) | None => {}
            }
        }
        let matching = &scratch.matching;
        for (t, apple) in scratch.truth.iter().enumerate() {
            if apple.visible_px == 0 {
                continue;
            }
            let error_m = matching.detection_of_truth[t]
                .and_then(|d| matching.truth_of_detection[d])
                .map(|(_, error_m)| error_m);
            let found_2d = scratch.matching_2d.detection_of_truth[t].is_some();
            record
                .apples
                .push(AppleOutcome::new(apple, error_m, found_2d));
        }
    }
}
