//! Perception re-run on a recording: each recorded `perception/apples` names the camera frame
//! it came from (`source_frame_seq`, `source_capture_ns`); that frame, read from the recording,
//! goes through this build's [`PerceptionTask`] under the runtime's [`Runner`] at the tick's
//! recorded time (publish stamp minus processing time), with the laser results that had been
//! published by then. What the task sends is compared with what was recorded: the detections
//! frame by frame, the scan requests in order.
//!
//! Needs the camera recorded raw (`harvest recorder --camera raw`, or a clip): H.264 video is
//! lossy, and a frame that is not the one perception saw gives other detections.

use std::collections::HashMap;
use std::path::PathBuf;
use std::time::Instant;

use harvest_ipc::Payload;
use harvest_ipc::catalogue::{
    CAMERA_RGBD, LASER_SCAN_REQUEST, LASER_SCAN_RESULT, PERCEPTION_APPLES,
};
use harvest_ipc::payloads::{AppleDetections, LaserScanRequest, LaserScanResult, RgbdFrame};
use harvest_node::{Inputs, Outputs, Runner, RunnerConfig};
use harvest_perception::task::PerceptionTask;
use harvest_recording::camera_record::VIDEO_TOPIC;
use harvest_recording::payload_codec::{decode_scanned, decode_scanned_into, zeroed_box};
use harvest_robot_model::ModeSource;

use crate::check::held_sample::AttachHeld;
use crate::check::json_diff::PUBLISHER_STAMPS;
use crate::check::recorded_inputs::{RecordedInputs, RerunOutputs};
use crate::check::report::{ChannelCheck, CheckError};
use crate::check::scan_recording::{scan, undecodable};

/// The detections' own measured field, besides the publisher's stamps: never compared.
const DETECTION_TIMING: &str = "processing_ns";

/// A recorded message with its log time.
struct Logged<T> {
    log_time_ns: u64,
    value: T,
}

/// What the first pass finds.
#[derive(Default)]
struct RecordedRun {
    detections: Vec<Logged<AppleDetections>>,
    scan_requests: Vec<Logged<LaserScanRequest>>,
    scan_results: Vec<LaserScanResult>,
    raw_frames: u64,
    video_frames: u64,
    first_log_time_ns: Option<u64>,
    last_log_time_ns: u64,
}

/// The perception part of `harvest replay --check`.
pub struct PerceptionCheck {
    pub detections: ChannelCheck,
    pub scan_requests: ChannelCheck,
    /// Recorded time covered, and the wall time the re-run took.
    pub recorded_span_ns: u64,
    pub rerun_wall_s: f64,
}

fn first_pass(files: &[PathBuf]) -> Result<RecordedRun, CheckError> {
    let mut run = RecordedRun::default();
    scan(files, |message| {
        let topic = message.channel.topic.as_str();
        let log_time_ns = message.log_time;
        run.first_log_time_ns.get_or_insert(log_time_ns);
        run.last_log_time_ns = run.last_log_time_ns.max(log_time_ns);
        if topic == PERCEPTION_APPLES.spec.topic {
            let value = decode_scanned(PERCEPTION_APPLES, message)
                .ok_or_else(|| undecodable(topic, log_time_ns))?;
            run.detections.push(Logged { log_time_ns, value });
        } else if topic == LASER_SCAN_REQUEST.spec.topic {
            let value = decode_scanned(LASER_SCAN_REQUEST, message)
                .ok_or_else(|| undecodable(topic, log_time_ns))?;
            run.scan_requests.push(Logged { log_time_ns, value });
        } else if topic == LASER_SCAN_RESULT.spec.topic {
            let value = decode_scanned(LASER_SCAN_RESULT, message)
                .ok_or_else(|| undecodable(topic, log_time_ns))?;
            run.scan_results.push(value);
        } else if topic == CAMERA_RGBD.spec.topic {
            run.raw_frames += 1;
        } else if topic == VIDEO_TOPIC {
            run.video_frames += 1;
        }
        Ok(())
    })?;
    // Results in the order perception could have received them.
    run.scan_results
        .sort_by_key(|result| result.header.publish_ns);
    Ok(run)
}

/// Compares one sent message with the recorded one; the first difference is kept.
fn compare<T: Payload>(
    check: &mut ChannelCheck,
    recorded: &Logged<T>,
    rerun: &T,
    ignored: &[&str],
    tolerance: Option<f64>,
    start_ns: u64,
) {
    check.compare_message(
        Some((recorded.log_time_ns, recorded.value.to_json())),
        Some(rerun.to_json()),
        ignored,
        tolerance,
        start_ns,
        start_ns,
    );
}

/// Re-runs `task` on the recording's frames and compares (module documentation).
pub fn check_perception(
    files: &[PathBuf],
    task: PerceptionTask,
    tolerance: Option<f64>,
) -> Result<PerceptionCheck, CheckError> {
    if task.fused_depth().is_some() {
        return Err(CheckError::Unsupported(
            "the lidar-fused depth source: the check re-runs perception with the ToF depth only"
                .to_owned(),
        ));
    }
    let recorded = first_pass(files)?;
    if recorded.detections.is_empty() {
        return Err(CheckError::NothingToCheck(
            "no perception/apples in the recording".to_owned(),
        ));
    }
    if recorded.raw_frames == 0 {
        return Err(CheckError::NothingToCheck(if recorded.video_frames > 0 {
            format!(
                "the camera is recorded as {VIDEO_TOPIC} (H.264, lossy), not the frames perception saw: record with `harvest recorder --camera raw`, or check a clip"
            )
        } else {
            "no camera/rgbd frames in the recording".to_owned()
        }));
    }
    let start_ns = recorded.first_log_time_ns.unwrap_or_default();
    // The recorded detection of each frame, by the frame's sequence number and capture stamp.
    let by_frame: HashMap<(u64, u64), usize> = recorded
        .detections
        .iter()
        .enumerate()
        .map(|(index, logged)| {
            (
                (
                    logged.value.source_frame_seq,
                    logged.value.source_capture_ns,
                ),
                index,
            )
        })
        .collect();

    let mut runner = Runner::new(
        task,
        (),
        RunnerConfig {
            max_read_failures: 1,
            mode_source: ModeSource::WithoutOperator,
        },
    );
    {
        let (inputs, outputs) = runner.slots_mut();
        let Ok(()) = Inputs::visit(inputs, &mut AttachHeld);
        let Ok(()) = Outputs::visit(outputs, &mut AttachHeld);
    }
    let mut frame = zeroed_box::<RgbdFrame>();
    let mut sent = RerunOutputs::default();
    let mut detections = ChannelCheck::new(PERCEPTION_APPLES.spec.topic);
    let mut results_fed = 0usize;
    let mut frames_rerun = 0u64;
    let started = Instant::now();
    scan(files, |message| {
        if message.channel.topic != CAMERA_RGBD.spec.topic {
            return Ok(());
        }
        if !decode_scanned_into(CAMERA_RGBD, message, &mut frame) {
            return Err(undecodable(CAMERA_RGBD.spec.topic, message.log_time));
        }
        let key = (frame.header.msg_seq, frame.header.capture_ns);
        let Some(&index) = by_frame.get(&key) else {
            return Ok(());
        };
        let logged = &recorded.detections[index];
        // The tick started when the frame was read: the detections' publish stamp less the
        // time perception spent on the frame.
        let tick_ns = logged
            .value
            .header
            .publish_ns
            .saturating_sub(logged.value.processing_ns);
        let fed_until = recorded.scan_results[results_fed..]
            .iter()
            .take_while(|result| result.header.publish_ns <= tick_ns)
            .count();
        let mut transport = RecordedInputs {
            frame: &mut frame,
            scan_results: &recorded.scan_results[results_fed..results_fed + fed_until],
            sent: &mut sent,
        };
        results_fed += fed_until;
        runner
            .tick(&mut transport, tick_ns)
            .map_err(|error| CheckError::Node(error.to_string()))?;
        frames_rerun += 1;
        let ignored = [PUBLISHER_STAMPS[0], PUBLISHER_STAMPS[1], DETECTION_TIMING];
        match sent.detections.pop() {
            Some(rerun) => compare(
                &mut detections,
                logged,
                &rerun,
                &ignored,
                tolerance,
                start_ns,
            ),
            None => {
                detections.compared += 1;
                detections.missing_in_rerun += 1;
            }
        }
        sent.detections.clear();
        Ok(())
    })?;
    let rerun_wall_s = started.elapsed().as_secs_f64();
    detections.not_rerun = recorded.detections.len() as u64 - frames_rerun;
    if detections.not_rerun > 0 {
        detections.not_rerun_reason =
            Some("their frame is not in the recording (recorded before the recorder started, or dropped)".to_owned());
    }

    let mut scan_requests = ChannelCheck::new(LASER_SCAN_REQUEST.spec.topic);
    for (recorded_request, rerun) in recorded.scan_requests.iter().zip(&sent.scan_requests) {
        compare(
            &mut scan_requests,
            recorded_request,
            rerun,
            &PUBLISHER_STAMPS,
            tolerance,
            start_ns,
        );
    }
    let (recorded_count, rerun_count) = (recorded.scan_requests.len(), sent.scan_requests.len());
    if recorded_count != rerun_count {
        scan_requests.count_mismatch = Some((recorded_count as u64, rerun_count as u64));
    }
    Ok(PerceptionCheck {
        detections,
        scan_requests,
        recorded_span_ns: recorded.last_log_time_ns.saturating_sub(start_ns),
        rerun_wall_s,
    })
}
