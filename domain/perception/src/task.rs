//! Perception as a node of the runtime ([`PerceptionTask`]): [`PerceptionNode`] between its
//! channels, with the LiDAR-fused depth ([`FusedDepth`]) and the freshness of the frames it
//! works on ([`FreshnessTracker`]).
//!
//! Woken by each camera frame, it works on the newest one only (`camera/rgbd` is read as
//! [`LatestInPlace`]: every frame queued since the previous tick is taken and all but the
//! newest dropped), so a slow detector costs skipped frames, never a queue. The frame is read
//! in place in shared memory and the detections are written in place into a loaned
//! `perception/apples` sample ([`Loaned`]). Before the frame every `laser/scan_result` that
//! arrived is taken (never waited for); after it the scans the frame asked for go out on
//! `laser/scan_request`. With the LiDAR-fused depth source the newest `lidar/points` cloud
//! (read in place) is fused with the frame's geometry and the frame is localized from the
//! fused depth image.
//!
//! A colour-only frame (`RgbdFrameMeta::FLAG_COLOR_ONLY`: a camera without a depth sensor) is
//! localized from the fused depth only. Without the fused source there will never be depth for
//! it, and the task ends the run at the first one ([`PerceptionTaskError::NoDepthSource`]); with
//! it, frames that arrive before the first cloud is fused are refused (warned once, then at
//! DEBUG; the heartbeat is degraded while every frame is refused).

use harvest_ipc::catalogue::{
    CAMERA_RGBD, LASER_SCAN_REQUEST, LASER_SCAN_RESULT, LIDAR_POINTS, PERCEPTION_APPLES,
};
use harvest_ipc::payloads::{
    AppleDetections, LaserScanRequest, LaserScanResult, PointCloud, ProcessRunState, RgbdFrame,
    RgbdFrameMeta,
};
use harvest_node::ports::{Drain, Out};
use harvest_node::{
    InputVisitor, Inputs, LatestInPlace, Loaned, Node, NodeHealth, NodeTick, OutputVisitor, Outputs,
};

use crate::depth_source::FusedDepth;
use crate::frame_freshness::{FreshnessTotals, FreshnessTracker};
use crate::node::PerceptionNode;
use crate::pipeline::PerceptionSetupError;

/// Why perception ends its run.
#[derive(Debug, thiserror::Error)]
pub enum PerceptionTaskError {
    /// A colour-only frame arrived and the depth source is the frame's own (ToF): nothing will
    /// ever give it depth.
    #[error(
        "{0}; this process runs with the ToF depth source, so it stops (give it \
         --depth-source lidar-fused --lidar-extrinsic FILE and run a lidar process)"
    )]
    NoDepthSource(#[source] PerceptionSetupError),
}

/// The channels perception reads.
#[derive(Default)]
pub struct PerceptionInputs {
    frames: LatestInPlace<RgbdFrame>,
    /// Read only with the LiDAR-fused depth source.
    clouds: Option<LatestInPlace<PointCloud>>,
    scan_results: Drain<LaserScanResult>,
}

impl Inputs for PerceptionInputs {
    fn visit<V: InputVisitor>(&mut self, v: &mut V) -> Result<(), V::Error> {
        v.latest_in_place(CAMERA_RGBD, &mut self.frames)?;
        if let Some(clouds) = &mut self.clouds {
            v.latest_in_place(LIDAR_POINTS, clouds)?;
        }
        v.drain(LASER_SCAN_RESULT, &mut self.scan_results)
    }
}

/// The channels perception writes.
#[derive(Default)]
pub struct PerceptionOutputs {
    detections: Loaned<AppleDetections>,
    scan_requests: Out<LaserScanRequest>,
}

impl Outputs for PerceptionOutputs {
    fn visit<V: OutputVisitor>(&mut self, v: &mut V) -> Result<(), V::Error> {
        v.loaned(PERCEPTION_APPLES, &mut self.detections)?;
        v.output(LASER_SCAN_REQUEST, &mut self.scan_requests)
    }
}

/// [`PerceptionNode`] on the runtime (module documentation).
pub struct PerceptionTask {
    node: PerceptionNode,
    fused_depth: Option<FusedDepth>,
    freshness: FreshnessTracker,
    /// The geometry of the last frame, to fuse a cloud that arrives between frames.
    last_meta: Option<RgbdFrameMeta>,
    apples_published: u64,
    /// A colour-only frame has been refused for want of fused depth (warned once).
    warned_no_depth: bool,
}

impl PerceptionTask {
    /// `fused_depth`: the LiDAR-fused depth source (then `lidar/points` is read too).
    pub fn new(node: PerceptionNode, fused_depth: Option<FusedDepth>) -> Self {
        Self {
            node,
            fused_depth,
            freshness: FreshnessTracker::default(),
            last_meta: None,
            apples_published: 0,
            warned_no_depth: false,
        }
    }

    pub fn node(&self) -> &PerceptionNode {
        &self.node
    }

    pub fn fused_depth(&self) -> Option<&FusedDepth> {
        self.fused_depth.as_ref()
    }

    pub fn freshness(&self) -> &FreshnessTotals {
        self.freshness.totals()
    }

    /// Apples published so far.
    pub fn apples_published(&self) -> u64 {
        self.apples_published
    }

    fn fuse(&mut self, meta: &RgbdFrameMeta, cloud: &PointCloud) {
        let Some(fused) = self.fused_depth.as_mut() else {
            return;
        };
        match fused.update(meta, cloud.valid_points()) {
            Ok(stats) => {
                tracing::debug!(
                    cloud_seq = cloud.header.msg_seq,
                    ?stats,
                    "lidar cloud fused"
                )
            }
            Err(error) => tracing::warn!(
                cloud_seq = cloud.header.msg_seq,
                %error,
                "lidar cloud not fused; the previous fused depth stays in use"
            ),
        }
    }
}

impl Node for PerceptionTask {
    type Inputs = PerceptionInputs;
    type Outputs = PerceptionOutputs;
    type Devices = ();
    type Error = PerceptionTaskError;

    fn name(&self) -> &str {
        "perception"
    }

    fn inputs(&self) -> PerceptionInputs {
        PerceptionInputs {
            clouds: self.fused_depth.as_ref().map(|_| LatestInPlace::default()),
            ..PerceptionInputs::default()
        }
    }

    fn outputs(&self) -> PerceptionOutputs {
        PerceptionOutputs::default()
    }

    /// The camera frames up to the last one worked on (processed and skipped).
    fn progress(&self) -> Option<u64> {
        let totals = self.freshness.totals();
        Some(totals.frames + totals.skipped)
    }

    /// Degraded while every frame is rejected; the figure is the last frame's age.
    fn health(&mut self) -> Option<NodeHealth> {
        let rejected = self.node.frames_rejected();
        let state = if rejected > 0 && rejected == self.node.frames_processed() {
            ProcessRunState::Degraded
        } else {
            ProcessRunState::Running
        };
        Some(NodeHealth {
            state,
            detail: "frame_age_ns",
            value: self.freshness.totals().last.age_ns,
            device_error: None,
        })
    }

    fn step(
        &mut self,
        tick: &NodeTick,
        _readings: Option<&()>,
        inputs: &PerceptionInputs,
        _commands: &mut (),
        outputs: &mut PerceptionOutputs,
    ) -> Result<(), Self::Error> {
        for result in inputs.scan_results.items() {
            let outcome = self.node.handle_scan_result(result);
            tracing::debug!(
                request_seq = result.request_seq,
                apple_id = result.apple_id,
                ?outcome,
                "laser scan result"
            );
        }
        let cloud = inputs.clouds.as_ref().and_then(LatestInPlace::fresh);
        let Some(frame) = inputs.frames.fresh() else {
            // A cloud between frames is fused with the last frame's geometry.
            if let (Some(cloud), Some(meta)) = (cloud, self.last_meta) {
                self.fuse(&meta, cloud);
            }
            return Ok(());
        };
        if frame.meta.is_color_only() && self.fused_depth.is_none() {
            return Err(PerceptionTaskError::NoDepthSource(
                PerceptionSetupError::NoDepthSource {
                    frame_seq: frame.header.msg_seq,
                },
            ));
        }
        let fresh =
            self.freshness
                .start_frame(frame.header.msg_seq, frame.header.capture_ns, tick.now_ns);
        self.last_meta = Some(frame.meta);
        if let Some(cloud) = cloud {
            self.fuse(&frame.meta, cloud);
        }
        let Some(out) = outputs.detections.sample_mut() else {
            // No sample to lend: the transport reports why after the step.
            return Ok(());
        };
        let depth_override = self
            .fused_depth
            .as_mut()
            .and_then(|fused| fused.depth_for(&frame.meta));
        let result = self.node.process_with_depth(frame, depth_override, out);
        out.header.capture_ns = frame.header.capture_ns;
        let count = out.apples.len();
        outputs.detections.send();
        self.apples_published += count as u64;
        for request in self.node.scan_requests() {
            outputs.scan_requests.send(*request);
        }
        match result {
            Ok(stats) => tracing::trace!(
                frame_seq = frame.header.msg_seq,
                apples = count,
                frame_age_ns = fresh.age_ns,
                frames_skipped = fresh.skipped,
                detect_us = stats.timings.detect_us,
                total_us = stats.timings.total_us,
                "frame processed"
            ),
            Err(error @ PerceptionSetupError::NoDepthSource { .. }) => {
                if self.warned_no_depth {
                    tracing::debug!(%error, "frame refused: no fused depth yet");
                } else {
                    tracing::warn!(%error, "frame refused: no fused depth yet");
                    self.warned_no_depth = true;
                }
            }
            Err(error) => tracing::warn!(%error, "frame rejected: camera parameters unusable"),
        }
        Ok(())
    }
}
