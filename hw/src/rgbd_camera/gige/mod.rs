//! A GigE Vision colour camera through Aravis ([`harvest_aravis`], loaded at run time) behind
//! [`RgbdCamera`]: `harvest camera --device gige`.
//!
//! Opening: the camera (by id, serial or address) gets a 1920x1080 region (centred unless the
//! config says where), the configured pixel format, frame rate and exposure, and a stream packet
//! size (configured, or negotiated); then a stream with a few buffers, and acquisition starts.
//! The camera's settings are read back and logged.
//!
//! Each capture pops the next filled buffer (Aravis reassembles the GVSP packets on its own
//! thread, asking for resends of missing ones where the camera supports it) and converts it in
//! one pass into the caller's frame, loaned shared memory ([`pixels`]): Mono8, Bayer (bilinear)
//! or RGB8 to RGB8. The frame is colour only ([`RgbdFrameMeta::FLAG_COLOR_ONLY`]): depth all 0,
//! the depth grid a 640x480 pinhole view through the colour camera ([`fused_depth_grid`]) onto
//! which perception lays the LiDAR's points, the registration the identity.
//!
//! Time: the frame's capture stamp is the camera's timestamp mapped to the stack's clock
//! ([`ClockMapping`]), paired with the host time the frame's first packet arrived (Aravis's
//! system timestamp, `CLOCK_REALTIME`, converted to `CLOCK_MONOTONIC` at that moment). A
//! camera without timestamps (0) is stamped with the arrival time.
//!
//! Health ([`CameraHealth`]): frames lost (given back incomplete by the stream, or missing from
//! the camera's frame-id sequence), packets resent on request and packets missing for good, and
//! frames that found no free buffer. An incomplete frame is counted and skipped, never published.

pub mod config;
pub mod pixels;

pub use config::GigeConfig;
pub use pixels::PixelFormat;

use super::{CameraHealth, RgbdCamera};
use crate::clock_mapping::ClockMapping;
use crate::error_kind::{DeviceError, ErrorKind};
use harvest_aravis::{Aravis, AravisError, BufferStatus, Camera, Stream};
use harvest_ipc::MonotonicClock;
use harvest_ipc::camera_model::{CameraIntrinsics, RigidTransform};
use harvest_ipc::payloads::rgbd_frame::{
    DEPTH_HEIGHT_PX, DEPTH_WIDTH_PX, RGB_HEIGHT_PX, RGB_WIDTH_PX,
};
use harvest_ipc::payloads::{RgbdFrame, RgbdFrameMeta};
use std::time::{Duration, Instant};

/// Errors of the GigE Vision camera.
#[derive(Debug, thiserror::Error)]
pub enum GigeError {
    /// Aravis is not installed, or too old.
    #[error("{0}")]
    Library(#[source] AravisError),
    /// The camera could not be opened or refused a setting; `what` names the step.
    #[error("GigE camera: {what}: {source}")]
    Camera {
        /// The step (opening, setting the region, ...).
        what: String,
        /// Aravis's error.
        source: AravisError,
    },
    /// The settings are unusable.
    #[error("GigE camera config: {0}")]
    Config(String),
    /// The camera cannot deliver the frames the stack carries.
    #[error("GigE camera: {0}")]
    Unsupported(String),
    /// A frame that does not fit its declared format and size.
    #[error("GigE camera frame {frame_id}: {detail}")]
    BadFrame {
        /// The camera's frame id.
        frame_id: u64,
        /// What did not fit.
        detail: String,
    },
}

impl DeviceError for GigeError {
    fn kind(&self) -> ErrorKind {
        match self {
            Self::Library(_) => ErrorKind::Other,
            Self::Camera { source, .. } => match source {
                AravisError::NoObject { .. } => ErrorKind::Disconnected,
                _ => ErrorKind::InvalidRequest,
            },
            Self::Config(_) | Self::Unsupported(_) => ErrorKind::InvalidRequest,
            Self::BadFrame { .. } => ErrorKind::Protocol,
        }
    }
}

fn step<T>(what: impl Into<String>, result: Result<T, AravisError>) -> Result<T, GigeError> {
    result.map_err(|source| GigeError::Camera {
        what: what.into(),
        source,
    })
}

/// The grid on which perception lays a depth image from another sensor for a colour-only
/// frame: the ToF depth image's 640x480 layout as a distortion-free pinhole looking through
/// `color` (same optical centre and field of view, pixels rescaled per axis).
pub fn fused_depth_grid(color: &CameraIntrinsics) -> CameraIntrinsics {
    let scale_x = DEPTH_WIDTH_PX as f64 / f64::from(color.width_px);
    let scale_y = DEPTH_HEIGHT_PX as f64 / f64::from(color.height_px);
    CameraIntrinsics {
        width_px: DEPTH_WIDTH_PX as u32,
        height_px: DEPTH_HEIGHT_PX as u32,
        fx_px: color.fx_px * scale_x,
        fy_px: color.fy_px * scale_y,
        // Pixel centres: continuous coordinate c maps to (c + 0.5) * scale - 0.5.
        cx_px: (color.cx_px + 0.5) * scale_x - 0.5,
        cy_px: (color.cy_px + 0.5) * scale_y - 0.5,
        distortion: [0.0; 5],
    }
}

/// The stack's `CLOCK_MONOTONIC` time of a `CLOCK_REALTIME` stamp, read side by side now.
fn realtime_to_monotonic_ns(realtime_ns: u64) -> u64 {
    use nix::time::{ClockId, clock_gettime};
    let read = |clock| {
        clock_gettime(clock)
            .map(|t| i128::from(t.tv_sec()) * 1_000_000_000 + i128::from(t.tv_nsec()))
            .unwrap_or(0)
    };
    let realtime_now = read(ClockId::CLOCK_REALTIME);
    let monotonic_now = read(ClockId::CLOCK_MONOTONIC);
    let monotonic = i128::from(realtime_ns) - realtime_now + monotonic_now;
    u64::try_from(monotonic.max(0)).unwrap_or(0)
}

/// Frames missing between two successive frame ids (16-bit ids that skip 0, as GigE Vision's
/// block ids do): 0 when the camera restarted its ids (a new acquisition: nothing known lost).
pub fn frames_missing_between(last: u64, frame_id: u64) -> u64 {
    if frame_id > last {
        frame_id - last - 1
    } else if last >= 0xff00 && frame_id < 0x0100 {
        // Wrapped: ids run 1..=65535.
        (0xffff - last) + frame_id.saturating_sub(1)
    } else {
        0
    }
}

/// A GigE Vision colour camera streaming 1920x1080 frames.
pub struct GigeCamera {
    // Declared before `camera`: the stream is released first.
    stream: Stream,
    camera: Camera,
    format: PixelFormat,
    meta: RgbdFrameMeta,
    clock: ClockMapping,
    last_stamp_ns: u64,
    last_frame_id: Option<u64>,
    health: CameraHealth,
}

impl std::fmt::Debug for GigeCamera {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("GigeCamera")
            .field("format", &self.format)
            .field("health", &self.health)
            .finish_non_exhaustive()
    }
}

impl GigeCamera {
    /// Loads Aravis and opens the camera of `config` (see the module docs); `camera_id`
    /// overrides the config's.
    pub fn open(config: &GigeConfig, camera_id: Option<&str>) -> Result<Self, GigeError> {
        let aravis = Aravis::load().map_err(GigeError::Library)?;
        Self::open_with(&aravis, config, camera_id)
    }

    /// [`Self::open`] with a loaded library.
    pub fn open_with(
        aravis: &Aravis,
        config: &GigeConfig,
        camera_id: Option<&str>,
    ) -> Result<Self, GigeError> {
        if let Some(problem) = config.problem() {
            return Err(GigeError::Config(problem));
        }
        let id = camera_id.or(config.camera_id.as_deref());
        let shown_id = id.unwrap_or("(the first camera found)");
        let mut camera = step(format!("opening {shown_id}"), Camera::open(aravis, id))?;
        if !camera.is_gige() {
            return Err(GigeError::Unsupported(format!(
                "{shown_id} is not a GigE Vision camera"
            )));
        }
        let (width, height) = (RGB_WIDTH_PX as u32, RGB_HEIGHT_PX as u32);
        let (sensor_width, sensor_height) = step("reading the sensor size", camera.sensor_size())?;
        if sensor_width < width || sensor_height < height {
            return Err(GigeError::Unsupported(format!(
                "the sensor is {sensor_width}x{sensor_height}, frames are {width}x{height}"
            )));
        }
        let [x, y] = config.region_offset_px.unwrap_or([
            ((sensor_width - width) / 2) & !1,
            ((sensor_height - height) / 2) & !1,
        ]);
        step(
            format!("setting the region {width}x{height} at ({x}, {y})"),
            camera.set_region(x, y, width, height),
        )?;
        let region = step("reading the region back", camera.region())?;
        if (region.2, region.3) != (width, height) {
            return Err(GigeError::Unsupported(format!(
                "asked for a {width}x{height} region, the camera set {}x{}",
                region.2, region.3
            )));
        }
        step(
            format!("setting the pixel format {:?}", config.pixel_format),
            camera.set_pixel_format(config.pixel_format.code()),
        )?;
        let format_code = step("reading the pixel format back", camera.pixel_format())?;
        if format_code != config.pixel_format.code() {
            return Err(GigeError::Unsupported(format!(
                "asked for {:?}, the camera set pixel format 0x{format_code:08x}",
                config.pixel_format
            )));
        }
        step("setting continuous acquisition", camera.set_continuous())?;
        step(
            format!("setting the frame rate {} Hz", config.frame_rate_hz),
            camera.set_frame_rate(config.frame_rate_hz),
        )?;
        if let Some(exposure_us) = config.exposure_us {
            step(
                format!("setting the exposure {exposure_us} us"),
                camera.set_exposure_us(exposure_us),
            )?;
        }
        match config.packet_size_bytes {
            Some(bytes) => step(
                format!("setting the packet size {bytes} B"),
                camera.set_gige_packet_size(bytes),
            )?,
            None => {
                step(
                    "negotiating the packet size",
                    camera.gige_auto_packet_size(),
                )?;
            }
        }
        let exposure_us = step("reading the exposure back", camera.exposure_us())?;
        let rate_hz = step("reading the frame rate back", camera.frame_rate())?;
        let packet_bytes = step("reading the packet size back", camera.gige_packet_size())?;
        let stream = step("creating the stream", camera.create_stream(config.buffers))?;
        let expected_payload =
            width as usize * height as usize * config.pixel_format.bytes_per_pixel();
        if stream.payload_bytes() < expected_payload {
            return Err(GigeError::Unsupported(format!(
                "the camera's payload is {} B, a {width}x{height} {:?} frame needs {expected_payload} B",
                stream.payload_bytes(),
                config.pixel_format
            )));
        }
        step("starting acquisition", camera.start_acquisition())?;
        tracing::info!(
            camera = shown_id,
            vendor = %camera.vendor_name().unwrap_or_default(),
            model = %camera.model_name().unwrap_or_default(),
            device_id = %camera.device_id().unwrap_or_default(),
            pixel_format = ?config.pixel_format,
            rate_hz,
            exposure_us,
            packet_bytes,
            region = ?region,
            "GigE camera streaming"
        );
        let meta = RgbdFrameMeta {
            rgb_intrinsics: config.intrinsics,
            depth_intrinsics: fused_depth_grid(&config.intrinsics),
            color_from_depth: RigidTransform::IDENTITY,
            exposure_us: exposure_us.round().clamp(0.0, f64::from(u32::MAX)) as u32,
            flags: RgbdFrameMeta::FLAG_COLOR_ONLY,
        };
        Ok(Self {
            stream,
            camera,
            format: config.pixel_format,
            meta,
            clock: ClockMapping::new(),
            last_stamp_ns: 0,
            last_frame_id: None,
            health: CameraHealth::default(),
        })
    }

    fn note_frame_id(&mut self, frame_id: u64) {
        if let Some(last) = self.last_frame_id {
            self.health.lost_frames += frames_missing_between(last, frame_id);
        }
        self.last_frame_id = Some(frame_id);
    }

    fn stamp(&mut self, device_ns: u64, arrival_realtime_ns: u64) -> u64 {
        let arrival_ns = if arrival_realtime_ns == 0 {
            MonotonicClock::read_ns()
        } else {
            realtime_to_monotonic_ns(arrival_realtime_ns)
        };
        let mapped = if device_ns == 0 {
            arrival_ns
        } else {
            self.clock.observe(device_ns, arrival_ns);
            self.clock.to_host_ns(device_ns).unwrap_or(arrival_ns)
        };
        // Stamps strictly increase even when the estimate steps down.
        let stamp = mapped.max(self.last_stamp_ns + 1);
        self.last_stamp_ns = stamp;
        stamp
    }
}

impl RgbdCamera for GigeCamera {
    type Error = GigeError;

    fn capture_into(
        &mut self,
        frame: &mut RgbdFrame,
        timeout: Duration,
    ) -> Result<bool, Self::Error> {
        let deadline = Instant::now() + timeout;
        loop {
            let left = deadline.saturating_duration_since(Instant::now());
            let Some(buffer) = self.stream.pop(left) else {
                return Ok(false);
            };
            let frame_id = buffer.frame_id();
            let status = buffer.status();
            if status != BufferStatus::Success {
                drop(buffer);
                self.note_frame_id(frame_id);
                self.health.lost_frames += 1;
                tracing::debug!(frame_id, ?status, "incomplete frame skipped");
                if Instant::now() >= deadline {
                    return Ok(false);
                }
                continue;
            }
            let format = PixelFormat::from_code(buffer.pixel_format());
            let size = (buffer.width() as usize, buffer.height() as usize);
            if format != Some(self.format) || size != (RGB_WIDTH_PX, RGB_HEIGHT_PX) {
                let detail = format!(
                    "pixel format 0x{:08x} {}x{}, expected {:?} {RGB_WIDTH_PX}x{RGB_HEIGHT_PX}",
                    buffer.pixel_format(),
                    size.0,
                    size.1,
                    self.format
                );
                return Err(GigeError::BadFrame { frame_id, detail });
            }
            let expected = RGB_WIDTH_PX * RGB_HEIGHT_PX * self.format.bytes_per_pixel();
            let data = buffer.data();
            let Some(image) = data.get(..expected) else {
                let detail = format!("{} bytes, expected {expected}", data.len());
                return Err(GigeError::BadFrame { frame_id, detail });
            };
            pixels::to_rgb(
                self.format,
                RGB_WIDTH_PX,
                RGB_HEIGHT_PX,
                image,
                &mut frame.rgb,
            )
            .map_err(|error| GigeError::BadFrame {
                frame_id,
                detail: error.to_string(),
            })?;
            let (device_ns, arrival_ns) = (buffer.timestamp_ns(), buffer.system_timestamp_ns());
            drop(buffer);
            self.note_frame_id(frame_id);
            frame.header.capture_ns = self.stamp(device_ns, arrival_ns);
            frame.meta = self.meta;
            frame.depth_mm.fill(0);
            self.health.frames += 1;
            tracing::trace!(frame_id, capture_ns = frame.header.capture_ns, "gige frame");
            return Ok(true);
        }
    }

    fn health(&self) -> CameraHealth {
        let stats = self.stream.statistics();
        CameraHealth {
            resent_packets: stats.resent_packets,
            missing_packets: stats.missing_packets,
            underruns: stats.underruns,
            ..self.health
        }
    }
}

impl Drop for GigeCamera {
    fn drop(&mut self) {
        if let Err(error) = self.camera.stop_acquisition() {
            tracing::warn!(%error, "stopping the GigE camera's acquisition");
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_depth_grid_sees_what_the_colour_camera_sees() {
        let color = CameraIntrinsics::tl460_rgb();
        let grid = fused_depth_grid(&color);
        assert_eq!((grid.width_px, grid.height_px), (640, 480));
        assert_eq!(grid.problem(), None);
        // The colour image's corners and centre fall on the grid's corners and centre.
        for (u, v) in [(-0.5, -0.5), (1919.5, 1079.5), (color.cx_px, color.cy_px)] {
            let x = (u - color.cx_px) / color.fx_px;
            let y = (v - color.cy_px) / color.fy_px;
            let (gu, gv) = (grid.fx_px * x + grid.cx_px, grid.fy_px * y + grid.cy_px);
            let expected = ((u + 0.5) / 3.0 - 0.5, (v + 0.5) * 480.0 / 1080.0 - 0.5);
            assert!((gu - expected.0).abs() < 1e-9 && (gv - expected.1).abs() < 1e-9);
        }
    }

    #[test]
    fn frame_id_gaps_count_lost_frames_across_the_wrap() {
        let lost = |ids: &[u64]| -> u64 {
            ids.windows(2)
                .map(|pair| frames_missing_between(pair[0], pair[1]))
                .sum()
        };
        assert_eq!(lost(&[1, 2, 3]), 0);
        assert_eq!(lost(&[1, 2, 5]), 2);
        assert_eq!(lost(&[65534, 65535, 1, 2]), 0);
        assert_eq!(lost(&[65534, 2]), 2);
        assert_eq!(lost(&[500, 1]), 0);
    }

    #[test]
    fn every_error_maps_to_its_kind() {
        let refused = GigeError::Camera {
            what: "setting".into(),
            source: AravisError::Call {
                call: "arv_camera_set_region",
                code: 1,
                message: "out of range".into(),
            },
        };
        assert_eq!(refused.kind(), ErrorKind::InvalidRequest);
        let gone = GigeError::Camera {
            what: "opening".into(),
            source: AravisError::NoObject {
                call: "arv_camera_new",
                detail: "x".into(),
            },
        };
        assert_eq!(gone.kind(), ErrorKind::Disconnected);
        let bad = GigeError::BadFrame {
            frame_id: 3,
            detail: "short".into(),
        };
        assert_eq!(bad.kind(), ErrorKind::Protocol);
    }
}
