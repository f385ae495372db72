//! A camera opened through Aravis ([`Camera`]), its stream ([`Stream`]) and the buffers it fills
//! ([`Buffer`]). Aravis receives the stream on a thread of its own; the caller pops complete
//! buffers, reads them in place, and a buffer goes back to the stream when dropped.

use crate::error::AravisError;
use crate::library::Aravis;
use std::ffi::{CString, c_int, c_void};
use std::ptr::NonNull;
use std::time::Duration;

/// `ArvAcquisitionMode`: continuous.
const ACQUISITION_MODE_CONTINUOUS: c_int = 0;
/// `ArvAuto`: off (manual).
const AUTO_OFF: c_int = 0;

/// A camera (`ArvCamera`): GenICam features by name, stream creation, acquisition.
pub struct Camera {
    aravis: Aravis,
    camera: NonNull<c_void>,
}

// SAFETY: an ArvCamera has no thread affinity (Aravis serialises access to the device's
// control channel internally); `Camera` is not `Sync`, so one thread at a time calls it.
unsafe impl Send for Camera {}

impl std::fmt::Debug for Camera {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Camera").finish_non_exhaustive()
    }
}

fn c_string(what: &'static str, text: &str) -> Result<CString, AravisError> {
    CString::new(text).map_err(|_| AravisError::NulInString {
        what,
        text: text.to_owned(),
    })
}

impl Camera {
    /// Opens the camera `id` (a device id as Aravis lists it, a serial number, or the camera's
    /// IP address; None: the first camera found). The camera's control channel stays open (with
    /// Aravis's heartbeat) until the camera is dropped.
    pub fn open(aravis: &Aravis, id: Option<&str>) -> Result<Self, AravisError> {
        let id_c = id.map(|id| c_string("camera id", id)).transpose()?;
        let id_ptr = id_c.as_ref().map_or(std::ptr::null(), |id| id.as_ptr());
        let api = aravis.api();
        // SAFETY: `arv_camera_new(const char *name, GError **error)`; `id_ptr` is null or a
        // NUL-terminated string alive across the call.
        let camera =
            unsafe { aravis.checked("arv_camera_new", |error| (api.camera_new)(id_ptr, error)) }?;
        let camera = NonNull::new(camera).ok_or_else(|| AravisError::NoObject {
            call: "arv_camera_new",
            detail: format!("no camera {}", id.unwrap_or("(first found)")),
        })?;
        Ok(Self {
            aravis: aravis.clone(),
            camera,
        })
    }

    fn ptr(&self) -> *mut c_void {
        self.camera.as_ptr()
    }

    fn text(
        &self,
        what: &'static str,
        get: unsafe extern "C" fn(
            *mut c_void,
            *mut *mut crate::library::GError,
        ) -> *const std::ffi::c_char,
    ) -> Result<String, AravisError> {
        // SAFETY: `get` is one of the `const char *arv_camera_get_*(ArvCamera *, GError **)`
        // getters; the string belongs to the camera and is copied before the next call.
        unsafe {
            let text = self.aravis.checked(what, |error| get(self.ptr(), error))?;
            Ok(Aravis::string(text))
        }
    }

    /// The vendor's name (GenICam `DeviceVendorName`).
    pub fn vendor_name(&self) -> Result<String, AravisError> {
        self.text(
            "arv_camera_get_vendor_name",
            self.aravis.api().camera_get_vendor_name,
        )
    }

    /// The model's name (`DeviceModelName`).
    pub fn model_name(&self) -> Result<String, AravisError> {
        self.text(
            "arv_camera_get_model_name",
            self.aravis.api().camera_get_model_name,
        )
    }

    /// The device's id (`DeviceID`, often the serial number).
    pub fn device_id(&self) -> Result<String, AravisError> {
        self.text(
            "arv_camera_get_device_id",
            self.aravis.api().camera_get_device_id,
        )
    }

    /// Full sensor size, pixels (width, height).
    pub fn sensor_size(&self) -> Result<(u32, u32), AravisError> {
        let (mut width, mut height) = (0 as c_int, 0 as c_int);
        let api = self.aravis.api();
        // SAFETY: `arv_camera_get_sensor_size(ArvCamera *, gint *, gint *, GError **)` with
        // pointers to two live integers.
        unsafe {
            self.aravis.checked("arv_camera_get_sensor_size", |error| {
                (api.camera_get_sensor_size)(self.ptr(), &mut width, &mut height, error)
            })
        }?;
        Ok((width.max(0) as u32, height.max(0) as u32))
    }

    /// Sets the region of interest (offset and size, pixels).
    pub fn set_region(
        &mut self,
        x: u32,
        y: u32,
        width: u32,
        height: u32,
    ) -> Result<(), AravisError> {
        let as_int = |value: u32| c_int::try_from(value).unwrap_or(c_int::MAX);
        let api = self.aravis.api();
        // SAFETY: `arv_camera_set_region(ArvCamera *, gint x, gint y, gint w, gint h, GError **)`.
        unsafe {
            self.aravis.checked("arv_camera_set_region", |error| {
                (api.camera_set_region)(
                    self.ptr(),
                    as_int(x),
                    as_int(y),
                    as_int(width),
                    as_int(height),
                    error,
                )
            })
        }
    }

    /// The region of interest (x, y, width, height), pixels.
    pub fn region(&self) -> Result<(u32, u32, u32, u32), AravisError> {
        let mut region = [0 as c_int; 4];
        let [x, y, width, height] = &mut region;
        let api = self.aravis.api();
        // SAFETY: `arv_camera_get_region(ArvCamera *, gint *, gint *, gint *, gint *, GError **)`
        // with four distinct live integers.
        unsafe {
            self.aravis.checked("arv_camera_get_region", |error| {
                (api.camera_get_region)(self.ptr(), x, y, width, height, error)
            })
        }?;
        let [x, y, width, height] = region.map(|value| value.max(0) as u32);
        Ok((x, y, width, height))
    }

    /// Sets the pixel format (a GenICam PFNC code, see [`crate::pixel_format`]).
    pub fn set_pixel_format(&mut self, format: u32) -> Result<(), AravisError> {
        let api = self.aravis.api();
        // SAFETY: `arv_camera_set_pixel_format(ArvCamera *, ArvPixelFormat, GError **)`.
        unsafe {
            self.aravis.checked("arv_camera_set_pixel_format", |error| {
                (api.camera_set_pixel_format)(self.ptr(), format, error)
            })
        }
    }

    /// The pixel format (PFNC code).
    pub fn pixel_format(&self) -> Result<u32, AravisError> {
        let api = self.aravis.api();
        // SAFETY: `ArvPixelFormat arv_camera_get_pixel_format(ArvCamera *, GError **)`.
        unsafe {
            self.aravis.checked("arv_camera_get_pixel_format", |error| {
                (api.camera_get_pixel_format)(self.ptr(), error)
            })
        }
    }

    /// Sets the acquisition frame rate, frames per second.
    pub fn set_frame_rate(&mut self, rate_hz: f64) -> Result<(), AravisError> {
        let api = self.aravis.api();
        // SAFETY: `arv_camera_set_frame_rate(ArvCamera *, double, GError **)`.
        unsafe {
            self.aravis.checked("arv_camera_set_frame_rate", |error| {
                (api.camera_set_frame_rate)(self.ptr(), rate_hz, error)
            })
        }
    }

    /// The acquisition frame rate, frames per second.
    pub fn frame_rate(&self) -> Result<f64, AravisError> {
        let api = self.aravis.api();
        // SAFETY: `double arv_camera_get_frame_rate(ArvCamera *, GError **)`.
        unsafe {
            self.aravis.checked("arv_camera_get_frame_rate", |error| {
                (api.camera_get_frame_rate)(self.ptr(), error)
            })
        }
    }

    /// Sets a fixed exposure time, microseconds, turning automatic exposure off first where the
    /// camera has it.
    pub fn set_exposure_us(&mut self, exposure_us: f64) -> Result<(), AravisError> {
        let api = self.aravis.api();
        // SAFETY: `gboolean arv_camera_is_exposure_auto_available(ArvCamera *, GError **)`.
        let has_auto = unsafe {
            self.aravis
                .checked("arv_camera_is_exposure_auto_available", |error| {
                    (api.camera_is_exposure_auto_available)(self.ptr(), error)
                })
        }?;
        if has_auto != 0 {
            // SAFETY: `arv_camera_set_exposure_time_auto(ArvCamera *, ArvAuto, GError **)`.
            unsafe {
                self.aravis
                    .checked("arv_camera_set_exposure_time_auto", |error| {
                        (api.camera_set_exposure_time_auto)(self.ptr(), AUTO_OFF, error)
                    })
            }?;
        }
        // SAFETY: `arv_camera_set_exposure_time(ArvCamera *, double, GError **)`.
        unsafe {
            self.aravis
                .checked("arv_camera_set_exposure_time", |error| {
                    (api.camera_set_exposure_time)(self.ptr(), exposure_us, error)
                })
        }
    }

    /// The exposure time, microseconds.
    pub fn exposure_us(&self) -> Result<f64, AravisError> {
        let api = self.aravis.api();
        // SAFETY: `double arv_camera_get_exposure_time(ArvCamera *, GError **)`.
        unsafe {
            self.aravis
                .checked("arv_camera_get_exposure_time", |error| {
                    (api.camera_get_exposure_time)(self.ptr(), error)
                })
        }
    }

    /// Continuous acquisition (frames until stopped).
    pub fn set_continuous(&mut self) -> Result<(), AravisError> {
        let api = self.aravis.api();
        // SAFETY: `arv_camera_set_acquisition_mode(ArvCamera *, ArvAcquisitionMode, GError **)`.
        unsafe {
            self.aravis
                .checked("arv_camera_set_acquisition_mode", |error| {
                    (api.camera_set_acquisition_mode)(
                        self.ptr(),
                        ACQUISITION_MODE_CONTINUOUS,
                        error,
                    )
                })
        }
    }

    /// Bytes of one frame's payload at the current settings.
    pub fn payload_bytes(&self) -> Result<usize, AravisError> {
        let api = self.aravis.api();
        // SAFETY: `guint arv_camera_get_payload(ArvCamera *, GError **)`.
        let bytes = unsafe {
            self.aravis.checked("arv_camera_get_payload", |error| {
                (api.camera_get_payload)(self.ptr(), error)
            })
        }?;
        Ok(bytes as usize)
    }

    /// Whether the camera is a GigE Vision device.
    pub fn is_gige(&self) -> bool {
        let api = self.aravis.api();
        // SAFETY: `gboolean arv_camera_is_gv_device(ArvCamera *)` on a live camera.
        unsafe { (api.camera_is_gv_device)(self.ptr()) != 0 }
    }

    /// GigE Vision: finds the largest stream packet the link carries (the camera's test
    /// packets, where it has them) and sets it; returns the packet size, bytes.
    pub fn gige_auto_packet_size(&mut self) -> Result<u32, AravisError> {
        let api = self.aravis.api();
        // SAFETY: `guint arv_camera_gv_auto_packet_size(ArvCamera *, GError **)`.
        unsafe {
            self.aravis
                .checked("arv_camera_gv_auto_packet_size", |error| {
                    (api.camera_gv_auto_packet_size)(self.ptr(), error)
                })
        }
    }

    /// GigE Vision: sets the stream packet size, bytes (`GevSCPSPacketSize`).
    pub fn set_gige_packet_size(&mut self, bytes: u32) -> Result<(), AravisError> {
        let api = self.aravis.api();
        let bytes = c_int::try_from(bytes).unwrap_or(c_int::MAX);
        // SAFETY: `arv_camera_gv_set_packet_size(ArvCamera *, gint, GError **)`.
        unsafe {
            self.aravis
                .checked("arv_camera_gv_set_packet_size", |error| {
                    (api.camera_gv_set_packet_size)(self.ptr(), bytes, error)
                })
        }
    }

    /// GigE Vision: the stream packet size, bytes.
    pub fn gige_packet_size(&self) -> Result<u32, AravisError> {
        let api = self.aravis.api();
        // SAFETY: `guint arv_camera_gv_get_packet_size(ArvCamera *, GError **)`.
        unsafe {
            self.aravis
                .checked("arv_camera_gv_get_packet_size", |error| {
                    (api.camera_gv_get_packet_size)(self.ptr(), error)
                })
        }
    }

    /// Creates the camera's stream with `buffers` buffers of the current payload size queued
    /// for it to fill. Create it after the region and pixel format are set.
    pub fn create_stream(&mut self, buffers: usize) -> Result<Stream, AravisError> {
        let payload = self.payload_bytes()?;
        let api = self.aravis.api();
        // SAFETY: `ArvStream *arv_camera_create_stream(ArvCamera *, ArvStreamCallback,
        // void *user_data, GError **)` without a callback.
        let stream = unsafe {
            self.aravis.checked("arv_camera_create_stream", |error| {
                (api.camera_create_stream)(
                    self.ptr(),
                    std::ptr::null(),
                    std::ptr::null_mut(),
                    error,
                )
            })
        }?;
        let stream = NonNull::new(stream).ok_or_else(|| AravisError::NoObject {
            call: "arv_camera_create_stream",
            detail: "the camera offers no stream".to_owned(),
        })?;
        let stream = Stream {
            aravis: self.aravis.clone(),
            stream,
            is_gige: self.is_gige(),
            payload_bytes: payload,
        };
        for _ in 0..buffers.max(1) {
            // SAFETY: `ArvBuffer *arv_buffer_new_allocate(size_t)`; the new buffer's one
            // reference passes to the stream by `arv_stream_push_buffer`.
            unsafe {
                let buffer = (api.buffer_new_allocate)(payload);
                if buffer.is_null() {
                    return Err(AravisError::NoObject {
                        call: "arv_buffer_new_allocate",
                        detail: format!("{payload} bytes"),
                    });
                }
                (api.stream_push_buffer)(stream.stream.as_ptr(), buffer);
            }
        }
        Ok(stream)
    }

    /// Starts acquisition (the camera streams until stopped).
    pub fn start_acquisition(&mut self) -> Result<(), AravisError> {
        let api = self.aravis.api();
        // SAFETY: `arv_camera_start_acquisition(ArvCamera *, GError **)`.
        unsafe {
            self.aravis
                .checked("arv_camera_start_acquisition", |error| {
                    (api.camera_start_acquisition)(self.ptr(), error)
                })
        }
    }

    /// Stops acquisition.
    pub fn stop_acquisition(&mut self) -> Result<(), AravisError> {
        let api = self.aravis.api();
        // SAFETY: `arv_camera_stop_acquisition(ArvCamera *, GError **)`.
        unsafe {
            self.aravis.checked("arv_camera_stop_acquisition", |error| {
                (api.camera_stop_acquisition)(self.ptr(), error)
            })
        }
    }
}

impl Drop for Camera {
    fn drop(&mut self) {
        // SAFETY: the camera holds one reference from `arv_camera_new`, released once here.
        unsafe { (self.aravis.api().g_object_unref)(self.ptr()) }
    }
}

/// The stream's counters since it was created.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct StreamStatistics {
    /// Buffers filled completely.
    pub completed_buffers: u64,
    /// Buffers given back incomplete (missing packets, timeouts, size mismatches).
    pub failures: u64,
    /// Frames that found no free buffer (the caller held them too long).
    pub underruns: u64,
    /// GigE Vision: packets the camera sent again on the host's request.
    pub resent_packets: u64,
    /// GigE Vision: packets that never arrived, even after resend requests.
    pub missing_packets: u64,
}

/// A camera's stream (`ArvStream`): Aravis's receive thread fills the queued buffers.
pub struct Stream {
    aravis: Aravis,
    stream: NonNull<c_void>,
    is_gige: bool,
    payload_bytes: usize,
}

// SAFETY: ArvStream's queues are thread-safe (GAsyncQueue); `Stream` is not `Sync`, so one
// thread at a time pops and pushes.
unsafe impl Send for Stream {}

impl std::fmt::Debug for Stream {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Stream")
            .field("is_gige", &self.is_gige)
            .field("payload_bytes", &self.payload_bytes)
            .finish_non_exhaustive()
    }
}

impl Stream {
    /// Bytes of each buffer.
    pub fn payload_bytes(&self) -> usize {
        self.payload_bytes
    }

    /// Waits up to `timeout` for the next filled buffer (complete or failed: see
    /// [`Buffer::status`]); None on timeout. The buffer returns to the stream when dropped.
    pub fn pop(&mut self, timeout: Duration) -> Option<Buffer<'_>> {
        let timeout_us = u64::try_from(timeout.as_micros()).unwrap_or(u64::MAX);
        let api = self.aravis.api();
        // SAFETY: `ArvBuffer *arv_stream_timeout_pop_buffer(ArvStream *, guint64 timeout_us)`:
        // a popped buffer's reference is ours until pushed back.
        let buffer = unsafe { (api.stream_timeout_pop_buffer)(self.stream.as_ptr(), timeout_us) };
        NonNull::new(buffer).map(|buffer| Buffer {
            stream: self,
            buffer,
        })
    }

    /// The next filled buffer if one is waiting, without blocking.
    pub fn try_pop(&mut self) -> Option<Buffer<'_>> {
        let api = self.aravis.api();
        // SAFETY: `ArvBuffer *arv_stream_try_pop_buffer(ArvStream *)`, as [`Self::pop`].
        let buffer = unsafe { (api.stream_try_pop_buffer)(self.stream.as_ptr()) };
        NonNull::new(buffer).map(|buffer| Buffer {
            stream: self,
            buffer,
        })
    }

    /// The stream's counters.
    pub fn statistics(&self) -> StreamStatistics {
        let api = self.aravis.api();
        let mut stats = StreamStatistics::default();
        // SAFETY: `arv_stream_get_statistics(ArvStream *, guint64 *, guint64 *, guint64 *)`
        // and, for a GigE Vision stream (an ArvGvStream), `arv_gv_stream_get_statistics
        // (ArvGvStream *, guint64 *, guint64 *)`, with pointers to live counters.
        unsafe {
            (api.stream_get_statistics)(
                self.stream.as_ptr(),
                &mut stats.completed_buffers,
                &mut stats.failures,
                &mut stats.underruns,
            );
            if self.is_gige {
                (api.gv_stream_get_statistics)(
                    self.stream.as_ptr(),
                    &mut stats.resent_packets,
                    &mut stats.missing_packets,
                );
            }
        }
        stats
    }
}

impl Drop for Stream {
    fn drop(&mut self) {
        // SAFETY: the stream holds one reference from `arv_camera_create_stream`; releasing it
        // stops the receive thread and frees the buffers still queued.
        unsafe { (self.aravis.api().g_object_unref)(self.stream.as_ptr()) }
    }
}

/// `ArvBufferStatus`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BufferStatus {
    /// The buffer holds a complete frame.
    Success,
    /// Packets were missing (after resend requests).
    MissingPackets,
    /// The frame was not complete in time.
    Timeout,
    /// The frame did not fit the buffer.
    SizeMismatch,
    /// Any other status (cleared, wrong packet id, filling, aborted, unknown), with its code.
    Other(i32),
}

impl BufferStatus {
    fn from_code(code: c_int) -> Self {
        match code {
            0 => Self::Success,
            2 => Self::Timeout,
            3 => Self::MissingPackets,
            5 => Self::SizeMismatch,
            other => Self::Other(other),
        }
    }
}

/// A buffer popped from a [`Stream`]; pushed back to it when dropped.
pub struct Buffer<'s> {
    stream: &'s Stream,
    buffer: NonNull<c_void>,
}

impl std::fmt::Debug for Buffer<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Buffer")
            .field("status", &self.status())
            .field("frame_id", &self.frame_id())
            .finish_non_exhaustive()
    }
}

impl Buffer<'_> {
    fn ptr(&self) -> *mut c_void {
        self.buffer.as_ptr()
    }

    /// Whether the buffer holds a complete frame.
    pub fn status(&self) -> BufferStatus {
        // SAFETY: `ArvBufferStatus arv_buffer_get_status(ArvBuffer *)` on a buffer we hold.
        BufferStatus::from_code(unsafe { (self.stream.aravis.api().buffer_get_status)(self.ptr()) })
    }

    /// The received bytes.
    pub fn data(&self) -> &[u8] {
        let mut size = 0usize;
        // SAFETY: `const void *arv_buffer_get_data(ArvBuffer *, size_t *size)`: `size` bytes
        // from the returned pointer belong to the buffer, which Aravis's thread no longer
        // writes once popped; the slice lives no longer than this borrow of the buffer.
        unsafe {
            let data = (self.stream.aravis.api().buffer_get_data)(self.ptr(), &mut size);
            if data.is_null() || size == 0 {
                return &[];
            }
            std::slice::from_raw_parts(data.cast::<u8>(), size)
        }
    }

    /// The image's pixel format (PFNC code).
    pub fn pixel_format(&self) -> u32 {
        // SAFETY: `ArvPixelFormat arv_buffer_get_image_pixel_format(ArvBuffer *)`.
        unsafe { (self.stream.aravis.api().buffer_get_image_pixel_format)(self.ptr()) }
    }

    /// The image's width, pixels.
    pub fn width(&self) -> u32 {
        // SAFETY: `gint arv_buffer_get_image_width(ArvBuffer *)`.
        unsafe { (self.stream.aravis.api().buffer_get_image_width)(self.ptr()) }.max(0) as u32
    }

    /// The image's height, pixels.
    pub fn height(&self) -> u32 {
        // SAFETY: `gint arv_buffer_get_image_height(ArvBuffer *)`.
        unsafe { (self.stream.aravis.api().buffer_get_image_height)(self.ptr()) }.max(0) as u32
    }

    /// The camera's timestamp of the frame, nanoseconds of the device's clock (GigE Vision:
    /// the leader's tick count converted with the device's tick frequency).
    pub fn timestamp_ns(&self) -> u64 {
        // SAFETY: `guint64 arv_buffer_get_timestamp(ArvBuffer *)`.
        unsafe { (self.stream.aravis.api().buffer_get_timestamp)(self.ptr()) }
    }

    /// The host's wall-clock time (`CLOCK_REALTIME`, ns) when the frame's first packet arrived.
    pub fn system_timestamp_ns(&self) -> u64 {
        // SAFETY: `guint64 arv_buffer_get_system_timestamp(ArvBuffer *)`.
        unsafe { (self.stream.aravis.api().buffer_get_system_timestamp)(self.ptr()) }
    }

    /// The camera's frame (block) id.
    pub fn frame_id(&self) -> u64 {
        // SAFETY: `guint64 arv_buffer_get_frame_id(ArvBuffer *)`.
        unsafe { (self.stream.aravis.api().buffer_get_frame_id)(self.ptr()) }
    }
}

impl Drop for Buffer<'_> {
    fn drop(&mut self) {
        // SAFETY: the popped buffer's reference goes back to the stream it came from.
        unsafe {
            (self.stream.aravis.api().stream_push_buffer)(self.stream.stream.as_ptr(), self.ptr())
        }
    }
}
