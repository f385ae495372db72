//! The Aravis 0.8 shared library, opened at run time, and the table of the C functions this
//! crate calls (signatures from Aravis 0.8.26's headers: `arvcamera.h`, `arvstream.h`,
//! `arvgvstream.h`, `arvbuffer.h`, `arvgvfakecamera.h`, `arvfakecamera.h`; GLib's `GError`,
//! `g_error_free`, `g_object_unref`, `g_object_set`).
//!
//! Every symbol is resolved once, when the library is opened: a library that lacks one is
//! refused with the symbol's name, never found missing in the middle of a capture. GLib and
//! GObject come with libaravis (its dependencies), so their symbols are looked up through the
//! same handle.

use crate::error::AravisError;
use std::ffi::{CStr, c_char, c_double, c_int, c_uint, c_void};
use std::sync::Arc;

/// The library's file name (Debian: package `libaravis-0.8-0`).
pub const LIBRARY: &str = "libaravis-0.8.so.0";

/// GLib's error record (`GError`: a quark, a code and a message); layout fixed by GLib's ABI.
#[repr(C)]
pub(crate) struct GError {
    pub domain: u32,
    pub code: c_int,
    pub message: *const c_char,
}

/// `ArvFakeCameraFillPattern`.
pub(crate) type FillPattern = unsafe extern "C" fn(
    buffer: *mut c_void,
    data: *mut c_void,
    exposure_time_us: u32,
    gain: u32,
    pixel_format: u32,
);

type Err = *mut *mut GError;

/// The C functions, resolved from one handle.
#[allow(clippy::type_complexity)]
pub(crate) struct Api {
    pub camera_new: unsafe extern "C" fn(*const c_char, Err) -> *mut c_void,
    pub camera_get_vendor_name: unsafe extern "C" fn(*mut c_void, Err) -> *const c_char,
    pub camera_get_model_name: unsafe extern "C" fn(*mut c_void, Err) -> *const c_char,
    pub camera_get_device_id: unsafe extern "C" fn(*mut c_void, Err) -> *const c_char,
    pub camera_get_sensor_size: unsafe extern "C" fn(*mut c_void, *mut c_int, *mut c_int, Err),
    pub camera_set_region: unsafe extern "C" fn(*mut c_void, c_int, c_int, c_int, c_int, Err),
    pub camera_get_region:
        unsafe extern "C" fn(*mut c_void, *mut c_int, *mut c_int, *mut c_int, *mut c_int, Err),
    pub camera_set_pixel_format: unsafe extern "C" fn(*mut c_void, u32, Err),
    pub camera_get_pixel_format: unsafe extern "C" fn(*mut c_void, Err) -> u32,
    pub camera_set_frame_rate: unsafe extern "C" fn(*mut c_void, c_double, Err),
    pub camera_get_frame_rate: unsafe extern "C" fn(*mut c_void, Err) -> c_double,
    pub camera_is_exposure_auto_available: unsafe extern "C" fn(*mut c_void, Err) -> c_int,
    pub camera_set_exposure_time_auto: unsafe extern "C" fn(*mut c_void, c_int, Err),
    pub camera_set_exposure_time: unsafe extern "C" fn(*mut c_void, c_double, Err),
    pub camera_get_exposure_time: unsafe extern "C" fn(*mut c_void, Err) -> c_double,
    pub camera_set_acquisition_mode: unsafe extern "C" fn(*mut c_void, c_int, Err),
    pub camera_get_payload: unsafe extern "C" fn(*mut c_void, Err) -> c_uint,
    pub camera_is_gv_device: unsafe extern "C" fn(*mut c_void) -> c_int,
    pub camera_gv_auto_packet_size: unsafe extern "C" fn(*mut c_void, Err) -> c_uint,
    pub camera_gv_set_packet_size: unsafe extern "C" fn(*mut c_void, c_int, Err),
    pub camera_gv_get_packet_size: unsafe extern "C" fn(*mut c_void, Err) -> c_uint,
    pub camera_create_stream:
        unsafe extern "C" fn(*mut c_void, *const c_void, *mut c_void, Err) -> *mut c_void,
    pub camera_start_acquisition: unsafe extern "C" fn(*mut c_void, Err),
    pub camera_stop_acquisition: unsafe extern "C" fn(*mut c_void, Err),
    pub stream_push_buffer: unsafe extern "C" fn(*mut c_void, *mut c_void),
    pub stream_timeout_pop_buffer: unsafe extern "C" fn(*mut c_void, u64) -> *mut c_void,
    pub stream_try_pop_buffer: unsafe extern "C" fn(*mut c_void) -> *mut c_void,
    pub stream_get_statistics: unsafe extern "C" fn(*mut c_void, *mut u64, *mut u64, *mut u64),
    pub gv_stream_get_statistics: unsafe extern "C" fn(*mut c_void, *mut u64, *mut u64),
    pub buffer_new_allocate: unsafe extern "C" fn(usize) -> *mut c_void,
    pub buffer_get_status: unsafe extern "C" fn(*mut c_void) -> c_int,
    pub buffer_get_data: unsafe extern "C" fn(*mut c_void, *mut usize) -> *const c_void,
    pub buffer_get_image_pixel_format: unsafe extern "C" fn(*mut c_void) -> u32,
    pub buffer_get_image_width: unsafe extern "C" fn(*mut c_void) -> c_int,
    pub buffer_get_image_height: unsafe extern "C" fn(*mut c_void) -> c_int,
    pub buffer_get_timestamp: unsafe extern "C" fn(*mut c_void) -> u64,
    pub buffer_get_system_timestamp: unsafe extern "C" fn(*mut c_void) -> u64,
    pub buffer_get_frame_id: unsafe extern "C" fn(*mut c_void) -> u64,
    pub gv_fake_camera_new: unsafe extern "C" fn(*const c_char, *const c_char) -> *mut c_void,
    pub gv_fake_camera_is_running: unsafe extern "C" fn(*mut c_void) -> c_int,
    pub gv_fake_camera_get_fake_camera: unsafe extern "C" fn(*mut c_void) -> *mut c_void,
    pub fake_camera_set_fill_pattern:
        unsafe extern "C" fn(*mut c_void, Option<FillPattern>, *mut c_void),
    pub g_object_unref: unsafe extern "C" fn(*mut c_void),
    pub g_object_set: unsafe extern "C" fn(*mut c_void, *const c_char, ...),
    pub g_error_free: unsafe extern "C" fn(*mut GError),
}

/// The opened library and its function table. Cheap to clone; the library stays loaded while
/// any clone, camera, stream or fake camera lives.
#[derive(Clone)]
pub struct Aravis {
    inner: Arc<Loaded>,
}

struct Loaded {
    api: Api,
    // Kept last so that the function pointers above never outlive the mapping.
    _library: libloading::Library,
}

impl std::fmt::Debug for Aravis {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Aravis").field("library", &LIBRARY).finish()
    }
}

/// Resolves one symbol as a function pointer of type `T`.
///
/// # Safety
/// `T` must be the C signature of `name` in the loaded library.
unsafe fn symbol<T: Copy>(
    library: &libloading::Library,
    name: &'static str,
) -> Result<T, AravisError> {
    let bytes = format!("{name}\0");
    // SAFETY: the caller guarantees `T` matches the symbol's C type; the pointer is copied out
    // and only used while `Loaded` keeps the library mapped.
    let found = unsafe { library.get::<T>(bytes.as_bytes()) };
    found
        .map(|symbol| *symbol)
        .map_err(|error| AravisError::MissingSymbol {
            library: LIBRARY,
            symbol: name,
            detail: error.to_string(),
        })
}

impl Aravis {
    /// Opens [`LIBRARY`] and resolves every function this crate uses. Fails with the library's
    /// name (and the package that provides it) when it is not installed.
    pub fn load() -> Result<Self, AravisError> {
        Self::load_named(LIBRARY)
    }

    /// [`Self::load`] from the library file `name` (a path, or a name the dynamic loader
    /// searches for), which must be an Aravis 0.8 build.
    pub fn load_named(name: &'static str) -> Result<Self, AravisError> {
        // SAFETY: loading libaravis runs its and GLib's initialisers, which have no
        // preconditions on the calling program (no other copy of Aravis is linked into
        // harvest).
        let library = unsafe { libloading::Library::new(name) }.map_err(|error| {
            AravisError::NotInstalled {
                library: name,
                detail: error.to_string(),
            }
        })?;
        // SAFETY: each type below is the function's C signature as declared in Aravis 0.8's
        // and GLib's headers (see the module docs); pointers are `void *` for the GObject types.
        let api = unsafe {
            Api {
                camera_new: symbol(&library, "arv_camera_new")?,
                camera_get_vendor_name: symbol(&library, "arv_camera_get_vendor_name")?,
                camera_get_model_name: symbol(&library, "arv_camera_get_model_name")?,
                camera_get_device_id: symbol(&library, "arv_camera_get_device_id")?,
                camera_get_sensor_size: symbol(&library, "arv_camera_get_sensor_size")?,
                camera_set_region: symbol(&library, "arv_camera_set_region")?,
                camera_get_region: symbol(&library, "arv_camera_get_region")?,
                camera_set_pixel_format: symbol(&library, "arv_camera_set_pixel_format")?,
                camera_get_pixel_format: symbol(&library, "arv_camera_get_pixel_format")?,
                camera_set_frame_rate: symbol(&library, "arv_camera_set_frame_rate")?,
                camera_get_frame_rate: symbol(&library, "arv_camera_get_frame_rate")?,
                camera_is_exposure_auto_available: symbol(
                    &library,
                    "arv_camera_is_exposure_auto_available",
                )?,
                camera_set_exposure_time_auto: symbol(
                    &library,
                    "arv_camera_set_exposure_time_auto",
                )?,
                camera_set_exposure_time: symbol(&library, "arv_camera_set_exposure_time")?,
                camera_get_exposure_time: symbol(&library, "arv_camera_get_exposure_time")?,
                camera_set_acquisition_mode: symbol(&library, "arv_camera_set_acquisition_mode")?,
                camera_get_payload: symbol(&library, "arv_camera_get_payload")?,
                camera_is_gv_device: symbol(&library, "arv_camera_is_gv_device")?,
                camera_gv_auto_packet_size: symbol(&library, "arv_camera_gv_auto_packet_size")?,
                camera_gv_set_packet_size: symbol(&library, "arv_camera_gv_set_packet_size")?,
                camera_gv_get_packet_size: symbol(&library, "arv_camera_gv_get_packet_size")?,
                camera_create_stream: symbol(&library, "arv_camera_create_stream")?,
                camera_start_acquisition: symbol(&library, "arv_camera_start_acquisition")?,
                camera_stop_acquisition: symbol(&library, "arv_camera_stop_acquisition")?,
                stream_push_buffer: symbol(&library, "arv_stream_push_buffer")?,
                stream_timeout_pop_buffer: symbol(&library, "arv_stream_timeout_pop_buffer")?,
                stream_try_pop_buffer: symbol(&library, "arv_stream_try_pop_buffer")?,
                stream_get_statistics: symbol(&library, "arv_stream_get_statistics")?,
                gv_stream_get_statistics: symbol(&library, "arv_gv_stream_get_statistics")?,
                buffer_new_allocate: symbol(&library, "arv_buffer_new_allocate")?,
                buffer_get_status: symbol(&library, "arv_buffer_get_status")?,
                buffer_get_data: symbol(&library, "arv_buffer_get_data")?,
                buffer_get_image_pixel_format: symbol(
                    &library,
                    "arv_buffer_get_image_pixel_format",
                )?,
                buffer_get_image_width: symbol(&library, "arv_buffer_get_image_width")?,
                buffer_get_image_height: symbol(&library, "arv_buffer_get_image_height")?,
                buffer_get_timestamp: symbol(&library, "arv_buffer_get_timestamp")?,
                buffer_get_system_timestamp: symbol(&library, "arv_buffer_get_system_timestamp")?,
                buffer_get_frame_id: symbol(&library, "arv_buffer_get_frame_id")?,
                gv_fake_camera_new: symbol(&library, "arv_gv_fake_camera_new")?,
                gv_fake_camera_is_running: symbol(&library, "arv_gv_fake_camera_is_running")?,
                gv_fake_camera_get_fake_camera: symbol(
                    &library,
                    "arv_gv_fake_camera_get_fake_camera",
                )?,
                fake_camera_set_fill_pattern: symbol(&library, "arv_fake_camera_set_fill_pattern")?,
                g_object_unref: symbol(&library, "g_object_unref")?,
                g_object_set: symbol(&library, "g_object_set")?,
                g_error_free: symbol(&library, "g_error_free")?,
            }
        };
        Ok(Self {
            inner: Arc::new(Loaded {
                api,
                _library: library,
            }),
        })
    }

    pub(crate) fn api(&self) -> &Api {
        &self.inner.api
    }

    /// Runs `call` with a fresh `GError *` slot and turns a set error into
    /// [`AravisError::Call`] naming `what`.
    ///
    /// # Safety
    /// `call` must be an Aravis call taking the slot as its `GError **` argument.
    pub(crate) unsafe fn checked<T>(
        &self,
        what: &'static str,
        call: impl FnOnce(*mut *mut GError) -> T,
    ) -> Result<T, AravisError> {
        let mut error: *mut GError = std::ptr::null_mut();
        let value = call(&mut error);
        if error.is_null() {
            return Ok(value);
        }
        // SAFETY: a non-null slot holds a GError the callee allocated; its message is a
        // NUL-terminated string (or null); we own the record and free it once, here.
        let (code, message) = unsafe {
            let record = &*error;
            let message = if record.message.is_null() {
                String::new()
            } else {
                CStr::from_ptr(record.message)
                    .to_string_lossy()
                    .into_owned()
            };
            let code = record.code;
            (self.api().g_error_free)(error);
            (code, message)
        };
        Err(AravisError::Call {
            call: what,
            code,
            message,
        })
    }

    /// Copies a C string the library owns (null: empty).
    ///
    /// # Safety
    /// `text` is null or a NUL-terminated string valid for the duration of the call.
    pub(crate) unsafe fn string(text: *const c_char) -> String {
        if text.is_null() {
            return String::new();
        }
        // SAFETY: per the contract above.
        unsafe { CStr::from_ptr(text) }
            .to_string_lossy()
            .into_owned()
    }
}
