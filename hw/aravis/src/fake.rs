//! Aravis's fake GigE Vision camera (`ArvGvFakeCamera`, what `arv-fake-gv-camera-0.8` runs),
//! hosted in-process: it answers GVCP on an interface's address (port 3956) and streams GVSP to
//! whoever opens it, from its own thread. [`FakeCamera::set_fill`] replaces its test pattern
//! with the caller's images (the library's `arv_fake_camera_set_fill_pattern`); for tests,
//! benchmarks and trying the driver without a camera, never onboard.

use crate::error::AravisError;
use crate::library::{Aravis, FillPattern};
use crate::pixel_format::bits_per_pixel;
use std::ffi::{CString, c_void};
use std::ptr::NonNull;

/// One image the fake is about to send, to be written by the fill function.
#[derive(Debug)]
pub struct FakeImage<'a> {
    /// The image's bytes (`width * height * bits_per_pixel / 8`), row-major, no padding.
    pub data: &'a mut [u8],
    /// Width, pixels.
    pub width: u32,
    /// Height, pixels.
    pub height: u32,
    /// The pixel format the camera is set to (PFNC code).
    pub pixel_format: u32,
    /// The frame's id (1-65535, wrapping).
    pub frame_id: u64,
    /// The frame's timestamp as the fake stamps it: the host's `CLOCK_REALTIME`, ns.
    pub timestamp_ns: u64,
    /// The exposure time register, microseconds.
    pub exposure_us: u32,
}

type FillFn = dyn FnMut(&mut FakeImage<'_>) + Send;

struct FillState {
    aravis: Aravis,
    fill: Box<FillFn>,
}

/// Called by the fake's thread for each frame, under the fake's fill-pattern lock.
unsafe extern "C" fn fill_trampoline(
    buffer: *mut c_void,
    data: *mut c_void,
    exposure_time_us: u32,
    _gain: u32,
    pixel_format: u32,
) {
    if buffer.is_null() || data.is_null() {
        return;
    }
    // SAFETY: `data` is the `FillState` registered with this trampoline; it outlives the fake
    // camera's thread (the thread is joined before the state is dropped) and only this thread
    // touches it while the fake runs.
    let state = unsafe { &mut *data.cast::<FillState>() };
    let api = state.aravis.api();
    // SAFETY: `buffer` is the ArvBuffer the fake is filling; the getters only read it. The
    // fake allocated it with the payload size of the current width, height and pixel format
    // (it refuses to fill a smaller buffer), so `width * height * bpp / 8` bytes from its
    // data pointer are the buffer's own; nothing else accesses them during the callback.
    let image = unsafe {
        let width = (api.buffer_get_image_width)(buffer).max(0) as u32;
        let height = (api.buffer_get_image_height)(buffer).max(0) as u32;
        let bytes = width as usize * height as usize * bits_per_pixel(pixel_format) as usize / 8;
        let pointer = (api.buffer_get_data)(buffer, std::ptr::null_mut());
        if pointer.is_null() || bytes == 0 {
            return;
        }
        FakeImage {
            data: std::slice::from_raw_parts_mut(pointer.cast::<u8>().cast_mut(), bytes),
            width,
            height,
            pixel_format,
            frame_id: (api.buffer_get_frame_id)(buffer),
            timestamp_ns: (api.buffer_get_timestamp)(buffer),
            exposure_us: exposure_time_us,
        }
    };
    let mut image = image;
    let fill = &mut state.fill;
    if std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| fill(&mut image))).is_err() {
        tracing::error!("the fake camera's fill function panicked; the frame goes out as is");
    }
}

/// A fake GigE Vision camera serving on an interface until dropped.
pub struct FakeCamera {
    aravis: Aravis,
    camera: NonNull<c_void>,
    fill: Option<Box<FillState>>,
}

// SAFETY: the fake camera's object is only touched through its thread-safe setters (the fill
// pattern under the fake's own mutex, GObject properties) and released once in `drop`.
unsafe impl Send for FakeCamera {}

impl std::fmt::Debug for FakeCamera {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("FakeCamera").finish_non_exhaustive()
    }
}

impl FakeCamera {
    /// Starts a fake camera with serial number `serial` on `interface` (an interface's name or
    /// address, e.g. `127.0.0.1`). Its device id is `Aravis-<serial>`; a driver reaches it by the
    /// interface's address.
    pub fn start(aravis: &Aravis, interface: &str, serial: &str) -> Result<Self, AravisError> {
        let interface_c = CString::new(interface).map_err(|_| AravisError::NulInString {
            what: "interface",
            text: interface.to_owned(),
        })?;
        let serial_c = CString::new(serial).map_err(|_| AravisError::NulInString {
            what: "serial number",
            text: serial.to_owned(),
        })?;
        let api = aravis.api();
        // SAFETY: `ArvGvFakeCamera *arv_gv_fake_camera_new(const char *interface, const char
        // *serial)` with two NUL-terminated strings alive across the call (the fake copies them).
        let camera = unsafe { (api.gv_fake_camera_new)(interface_c.as_ptr(), serial_c.as_ptr()) };
        let camera = NonNull::new(camera).ok_or_else(|| AravisError::NoObject {
            call: "arv_gv_fake_camera_new",
            detail: format!("a fake camera on {interface}"),
        })?;
        let fake = Self {
            aravis: aravis.clone(),
            camera,
            fill: None,
        };
        // SAFETY: `gboolean arv_gv_fake_camera_is_running(ArvGvFakeCamera *)` on a live fake.
        let running = unsafe { (api.gv_fake_camera_is_running)(fake.camera.as_ptr()) } != 0;
        if !running {
            return Err(AravisError::NoObject {
                call: "arv_gv_fake_camera_new",
                detail: format!(
                    "the fake camera did not start on {interface} (no such interface, or \
                     port 3956 taken by another camera)"
                ),
            });
        }
        Ok(fake)
    }

    /// Drops this fraction of the stream's packets (0-1), as `arv-fake-gv-camera -r` does.
    pub fn set_lost_packet_ratio(&mut self, ratio: f64) {
        let api = self.aravis.api();
        // SAFETY: `g_object_set(gpointer, const char *property, ..., NULL)` with the fake's
        // double property "gvsp-lost-ratio" and the NULL terminator.
        unsafe {
            (api.g_object_set)(
                self.camera.as_ptr(),
                c"gvsp-lost-ratio".as_ptr(),
                ratio,
                std::ptr::null::<c_void>(),
            )
        }
    }

    /// Makes `fill` write every frame from now on (called on the fake's thread at its frame
    /// rate; it should copy a prepared image rather than compute one).
    pub fn set_fill(&mut self, fill: impl FnMut(&mut FakeImage<'_>) + Send + 'static) {
        let mut state = Box::new(FillState {
            aravis: self.aravis.clone(),
            fill: Box::new(fill),
        });
        let data: *mut FillState = &mut *state;
        let api = self.aravis.api();
        // SAFETY: `ArvFakeCamera *arv_gv_fake_camera_get_fake_camera(ArvGvFakeCamera *)` is
        // owned by the gv fake; `arv_fake_camera_set_fill_pattern(ArvFakeCamera *, callback,
        // data)` swaps the callback under the fake's fill lock, so the previous state (dropped
        // below) is no longer in use once it returns. The new state lives in `self.fill` until
        // the fake's thread is joined in `drop`.
        unsafe {
            let fake = (api.gv_fake_camera_get_fake_camera)(self.camera.as_ptr());
            let trampoline: FillPattern = fill_trampoline;
            (api.fake_camera_set_fill_pattern)(fake, Some(trampoline), data.cast::<c_void>());
        }
        self.fill = Some(state);
    }
}

impl Drop for FakeCamera {
    fn drop(&mut self) {
        // SAFETY: the fake holds one reference from `arv_gv_fake_camera_new`; finalising it
        // stops and joins its thread, after which the fill state is dropped (field order).
        unsafe { (self.aravis.api().g_object_unref)(self.camera.as_ptr()) }
        drop(self.fill.take());
    }
}

/// Holds the host-wide lock on the loopback fake camera's GVCP port (3956 on 127.0.0.1): one
/// fake at a time may serve there, so tests and benchmarks in parallel processes take turns.
#[derive(Debug)]
pub struct LoopbackCameraLock {
    _file: std::fs::File,
}

impl LoopbackCameraLock {
    /// Blocks until no other holder on this host has the lock.
    pub fn acquire() -> std::io::Result<Self> {
        let path = std::env::temp_dir().join("harvest-gige-loopback-3956.lock");
        let file = std::fs::OpenOptions::new()
            .create(true)
            .truncate(false)
            .write(true)
            .open(path)?;
        file.lock()?;
        Ok(Self { _file: file })
    }
}
