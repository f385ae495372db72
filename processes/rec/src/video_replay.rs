//! Replay of the continuous record's camera: `camera/video` (H.264) and `camera/depth` are put
//! back together into `camera/rgbd` frames ([`CameraRebuild`]), decoded straight into a sample
//! loaned from the camera channel, so perception runs on a day's record as on the live camera.
//! Each video frame becomes one frame with the depth kept for it (or the newest before it, when
//! the recorder kept depth at a lower rate); its `capture_ns` is the recorded one.

use harvest_ipc::catalogue::CAMERA_RGBD;
use harvest_ipc::payloads::RgbdFrame;
use harvest_ipc::{Context, Publisher};
use harvest_recording::camera_record::{CameraRebuild, Rebuilt};
use harvest_recording::time_base::FileTimeBase;

/// What happened to one message of the camera's video or depth channel.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum CameraOutcome {
    /// A `camera/rgbd` frame was published.
    Published,
    /// A depth image was taken in (published with the next video frames).
    DepthTaken,
    /// A video frame gave no frame yet (no depth seen, or no IDR yet).
    Waiting(&'static str),
}

/// The camera channel's publisher and the decoder state of one replay pass.
pub struct CameraReplay {
    publisher: Publisher<RgbdFrame>,
    rebuild: CameraRebuild,
}

impl CameraReplay {
    pub fn open(context: &Context) -> Result<Self, String> {
        let publisher = context
            .publisher(CAMERA_RGBD)
            .map_err(|error| error.to_string())?;
        let rebuild = CameraRebuild::new().map_err(|error| error.to_string())?;
        Ok(Self { publisher, rebuild })
    }

    /// Starts a new pass (the decoder waits for the next IDR, old depth is forgotten).
    pub fn restart(&mut self) -> Result<(), String> {
        self.rebuild = CameraRebuild::new().map_err(|error| error.to_string())?;
        Ok(())
    }

    pub fn depth(&mut self, bytes: &[u8]) -> Result<CameraOutcome, String> {
        self.rebuild
            .depth(bytes)
            .map_err(|error| format!("undecodable depth: {error}"))?;
        Ok(CameraOutcome::DepthTaken)
    }

    /// Decodes a video message into a loaned frame and sends it.
    pub fn video(
        &mut self,
        bytes: &[u8],
        time_base: &FileTimeBase,
    ) -> Result<CameraOutcome, String> {
        let mut loan = self.publisher.loan().map_err(|error| error.to_string())?;
        let rebuilt = self
            .rebuild
            .video(bytes, |wall_ns| time_base.stack_ns(wall_ns), &mut loan)
            .map_err(|error| format!("undecodable video: {error}"))?;
        match rebuilt {
            Rebuilt::Frame => {
                self.publisher
                    .send(loan)
                    .map_err(|error| error.to_string())?;
                Ok(CameraOutcome::Published)
            }
            Rebuilt::NoDepthYet => Ok(CameraOutcome::Waiting("no depth image yet")),
            Rebuilt::NoPictureYet => Ok(CameraOutcome::Waiting("before the first IDR")),
        }
    }
}
