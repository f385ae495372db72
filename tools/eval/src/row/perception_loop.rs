//! Detection sets of a row run: perception's own node on frames the simulator's ToF camera
//! renders from the world as it stands (robot moved by the trailer and the platform, apples
//! picked), or the ground truth through the camera's depth-noise model.
//!
//! Frames are rendered at a reduced rate, on the simulated clock (see [`FramePolicy`]); a set
//! reaches the stack a fixed simulated latency after its capture, so the figures do not depend
//! on how fast this machine renders.

use harvest_ipc::payloads::{AppleDetections, RgbdFrame};
use harvest_perception::PerceptionConfig;
use harvest_perception::calibration::{Calibration, CameraCalibration};
use harvest_perception::node::PerceptionNode;
use harvest_sim::World;
use rand::SeedableRng;
use rand::rngs::SmallRng;

use crate::harvest::HarvestEvalError;
use crate::harvest::detections::{DetectionModel, detect};
use crate::perception::frame::{FrameRenderer, zeroed_frame};

/// Decorrelates the model's detection noise from the world's random streams.
const MODEL_STREAM: u64 = 0x5eed_0000_0000_0017;

/// When a frame is rendered (all times simulated).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FramePolicy {
    /// While the arms harvest: at least this often, ns (keeps the targets younger than the
    /// arms' 2 s age limit and lets the vacuum supervisor refresh a waiting target).
    pub harvest_interval_ns: u64,
    /// While the stop cycle waits for a set (parking, settling): this often, ns.
    pub waiting_interval_ns: u64,
    /// Capture to delivery, ns.
    pub latency_ns: u64,
}

/// What the stop cycle is doing, as far as frames are concerned.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FrameNeed {
    /// The trailer or the platform moves: no frame.
    None,
    /// A set captured at or after this stamp is awaited.
    After(u64),
    /// The arms harvest.
    Harvesting,
}

enum Source {
    Perception {
        renderer: Box<FrameRenderer>,
        node: Box<PerceptionNode>,
        frame: Box<RgbdFrame>,
    },
    Model {
        model: DetectionModel,
        rng: SmallRng,
    },
}

/// Renders and processes frames on demand.
pub struct DetectionLoop {
    source: Source,
    policy: FramePolicy,
    seq: u64,
    last_capture_ns: Option<u64>,
    in_flight_until_ns: u64,
    frames: u64,
}

fn render_error(error: harvest_sim::RenderError) -> HarvestEvalError {
    HarvestEvalError::Device {
        device: "simulated camera",
        stamp_ns: 0,
        message: error.to_string(),
    }
}

impl DetectionLoop {
    /// Perception on rendered frames of `world`'s camera.
    pub fn perception(world: &World, policy: FramePolicy) -> Result<Self, HarvestEvalError> {
        let mut renderer =
            Box::new(FrameRenderer::new(&world.scenario().camera).map_err(render_error)?);
        let calibration = Calibration {
            camera: CameraCalibration {
                robot_from_camera: renderer.robot_from_color(),
            },
        };
        let node = Box::new(PerceptionNode::new(
            PerceptionConfig::default(),
            calibration,
        ));
        Ok(Self::with(
            Source::Perception {
                renderer,
                node,
                frame: zeroed_frame(),
            },
            policy,
        ))
    }

    /// The ground truth through the depth-noise model; `seed` seeds the noise.
    pub fn model(seed: u64, policy: FramePolicy) -> Self {
        Self::with(
            Source::Model {
                model: DetectionModel::default(),
                rng: SmallRng::seed_from_u64(seed ^ MODEL_STREAM),
            },
            policy,
        )
    }

    fn with(source: Source, policy: FramePolicy) -> Self {
        Self {
            source,
            policy,
            seq: 0,
            last_capture_ns: None,
            in_flight_until_ns: 0,
            frames: 0,
        }
    }

    /// Frames processed so far.
    pub fn frames(&self) -> u64 {
        self.frames
    }

    /// Whether a frame is due at `now_ns`: one set at a time (perception processes one frame
    /// at a time), and only when the cycle needs one. `attempt_ended_since` says an attempt
    /// ended after the last capture (the vacuum supervisor re-plans on the next set).
    pub fn due(&self, now_ns: u64, need: FrameNeed, attempt_ended_since: bool) -> bool {
        if now_ns < self.in_flight_until_ns {
            return false;
        }
        let since_last = |interval_ns: u64| {
            self.last_capture_ns
                .is_none_or(|last| now_ns.saturating_sub(last) >= interval_ns)
        };
        match need {
            FrameNeed::None => false,
            FrameNeed::After(stamp_ns) => {
                self.last_capture_ns.is_none_or(|last| last < stamp_ns)
                    || since_last(self.policy.waiting_interval_ns)
            }
            FrameNeed::Harvesting => {
                attempt_ended_since || since_last(self.policy.harvest_interval_ns)
            }
        }
    }

    /// The stamp of the last capture.
    pub fn last_capture_ns(&self) -> Option<u64> {
        self.last_capture_ns
    }

    /// Captures `world` at `now_ns`; returns the set and when it is delivered.
    pub fn capture(
        &mut self,
        world: &World,
        now_ns: u64,
    ) -> Result<(u64, Box<AppleDetections>), HarvestEvalError> {
        self.seq += 1;
        self.frames += 1;
        let mut set = Box::<AppleDetections>::default();
        match &mut self.source {
            Source::Perception {
                renderer,
                node,
                frame,
            } => {
                renderer
                    .render(world, self.seq, frame)
                    .map_err(render_error)?;
                frame.header.capture_ns = now_ns;
                frame.header.publish_ns = now_ns;
                let stats =
                    node.process(frame, &mut set)
                        .map_err(|error| HarvestEvalError::Device {
                            device: "perception",
                            stamp_ns: now_ns,
                            message: error.to_string(),
                        })?;
                if let Some(rejection) = stats.rejection {
                    tracing::warn!(%rejection, "perception rejected a frame");
                }
                set.source_capture_ns = now_ns;
                set.header.capture_ns = now_ns;
            }
            Source::Model { model, rng } => {
                *set = detect(world, now_ns, self.seq, model, rng);
            }
        }
        tracing::trace!(
            seq = self.seq,
            now_ns,
            apples = set.apples.len(),
            "detection set"
        );
        self.last_capture_ns = Some(now_ns);
        let deliver_ns = now_ns + self.policy.latency_ns;
        self.in_flight_until_ns = deliver_ns;
        Ok((deliver_ns, set))
    }
}
