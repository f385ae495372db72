//! The simulated ToF camera as a device: the simulator renders frames and delivers them on the
//! `hw/camera/rgbd` hardware channel, the way a real camera delivers them over USB/Ethernet;
//! this driver waits for each (event-driven) and transfers it into the caller's buffer (the
//! one copy a real driver makes from its DMA buffer).

use super::RgbdCamera;
use crate::error_kind::{DeviceError, ErrorKind};
use harvest_ipc::catalogue::HW_CAMERA_RGBD;
use harvest_ipc::error::IpcError;
use harvest_ipc::payloads::RgbdFrame;
use harvest_ipc::{Context, Subscriber};
use std::time::Duration;

/// Errors of the simulated camera link.
#[derive(Debug, thiserror::Error)]
pub enum SimCameraError {
    /// The hardware channel from the simulator failed (opening or receiving).
    #[error("simulated camera link: {0}")]
    Link(#[from] IpcError),
}

impl DeviceError for SimCameraError {
    fn kind(&self) -> ErrorKind {
        match self {
            Self::Link(_) => ErrorKind::Disconnected,
        }
    }
}

/// Driver of the simulated ToF camera: receives the frames the simulator renders on
/// `hw/camera/rgbd`.
pub struct SimRgbdCamera {
    frames: Subscriber<RgbdFrame>,
}

impl SimRgbdCamera {
    /// Subscribes to the simulator's frames.
    pub fn connect(context: &Context) -> Result<Self, SimCameraError> {
        let frames = context
            .subscriber_with_buffer(HW_CAMERA_RGBD, 2)
            .map_err(|error| SimCameraError::Link(error.into()))?;
        Ok(Self { frames })
    }
}

impl RgbdCamera for SimRgbdCamera {
    type Error = SimCameraError;

    fn capture_into(
        &mut self,
        frame: &mut RgbdFrame,
        timeout: Duration,
    ) -> Result<bool, Self::Error> {
        let receive = |frames: &Subscriber<RgbdFrame>| {
            frames
                .receive_latest()
                .map_err(|error| SimCameraError::Link(error.into()))
        };
        let mut latest = receive(&self.frames)?;
        if latest.is_none() {
            // An interrupted wait (a signal arrived) is a timeout: the caller checks for shutdown.
            if let Err(error) = self.frames.listener().timed_wait(|_| {}, timeout) {
                tracing::debug!(?error, "wait for device frame interrupted");
                return Ok(false);
            }
            latest = receive(&self.frames)?;
        }
        let Some(device_frame) = latest else {
            return Ok(false);
        };
        frame.header.capture_ns = device_frame.header.capture_ns;
        frame.meta = device_frame.meta;
        frame.rgb.copy_from_slice(&device_frame.rgb);
        frame.depth_mm.copy_from_slice(&device_frame.depth_mm);
        Ok(true)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::error_kind::lost_link;

    #[test]
    fn every_error_maps_to_its_kind() {
        let lost = SimCameraError::from(lost_link());
        assert_eq!(lost.kind(), ErrorKind::Disconnected);
        assert!(lost.to_string().contains("the simulator's node is gone"));
    }
}
