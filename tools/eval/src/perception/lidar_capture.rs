//! The LiDAR-fused depth of one evaluation frame: the simulated Mid-70 (the `harvest sim --lidar`
//! device, mounted on the ToF camera at the simulated unit's extrinsic) integrates one window of
//! returns against the frame's world, and perception's own [`FusedDepth`] projects them into the
//! frame's depth-image geometry (eq. 1-2), as the perception process does with `lidar/points`.
//!
//! The extrinsic given to the fusion is the device's true one: like the colour camera pose (see
//! [`super::run::CALIBRATION_SOURCE`]), calibration is measured elsewhere
//! (`harvest calibrate lidar-camera`).

use harvest_ipc::payload::boxed_zeroed;
use harvest_ipc::payloads::{PointCloud, RgbdFrameMeta};
use harvest_lidar::integration_window::window_returns;
use harvest_perception::depth_source::FusedDepth;
use harvest_sim::World;
use harvest_sim::lidar_device::{LidarDeviceConfig, LidarDeviceServer};

use crate::perception::error::EvalError;

/// The simulated LiDAR and the fused depth of the newest window.
pub struct LidarCapture {
    device: LidarDeviceServer,
    cloud: Box<PointCloud>,
    fused: FusedDepth,
    returns_per_window: usize,
}

impl LidarCapture {
    /// A LiDAR integrating `integration_s` per frame, with noise from `seed`.
    pub fn new(integration_s: f64, seed: u64) -> Result<Self, EvalError> {
        let config = LidarDeviceConfig {
            noise_seed: seed,
            ..LidarDeviceConfig::default()
        };
        let returns_per_window =
            window_returns(&config.spec, integration_s).ok_or_else(|| EvalError::BadArgument {
                argument: "--lidar-integration-s",
                value: integration_s.to_string(),
                reason: "must be positive and at most one cloud's capacity (1 s at 100k points/s)",
            })?;
        let device = LidarDeviceServer::new(config).map_err(|source| EvalError::Lidar {
            source: Box::new(source),
        })?;
        Ok(Self {
            device,
            cloud: boxed_zeroed(),
            fused: FusedDepth::new(config.camera_from_lidar),
            returns_per_window,
        })
    }

    /// Integrates one window against `world` and fuses it into the geometry of frames with
    /// `meta`; returns the fused depth image (millimetres, 0 = no point).
    pub fn capture(&mut self, world: &World, meta: &RgbdFrameMeta) -> Result<&[u16], EvalError> {
        self.cloud.clear();
        self.device
            .scan_into(world, self.returns_per_window, &mut self.cloud);
        self.fused
            .update(meta, self.cloud.valid_points())
            .map_err(|source| EvalError::Fusion {
                source: Box::new(source),
            })?;
        self.fused.depth_for(meta).ok_or_else(|| EvalError::Fusion {
            source: Box::new(harvest_lidar::FusionError::EmptyCloud),
        })
    }
}
