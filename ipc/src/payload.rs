//! What every message type carried by the stack implements.

use crate::codec::CodecError;
use crate::header::Header;
use iceoryx2::prelude::ZeroCopySend;

/// A message type of the channel catalogue.
///
/// # Safety
/// Implementors must be `#[repr(C)]` plain data for which **every bit pattern is a valid value**
/// (integers, floats, fixed arrays and structs of those; enums travel as integer codes). The
/// transport relies on this to hand out loaned shared memory as `&mut Self` without first
/// building a value: the segment bytes are always initialized (zero-filled by the kernel when the
/// segment is created, earlier samples afterwards), so large frames are written in place and
/// never built on the stack or copied.
pub unsafe trait Payload: ZeroCopySend + std::fmt::Debug + Sized + 'static {
    /// Stable type name, also the MCAP schema name, e.g. `harvest.RgbdFrame`.
    const TYPE_NAME: &'static str;
    /// Layout version; bumped on any change of fields. Part of the iceoryx2 type name, so a
    /// stale service of another version fails to open with a clear error.
    const VERSION: u32;
    /// Field-by-field description of the encoded form (see [`crate::codec`]), stored as MCAP
    /// schema data.
    const SCHEMA: &'static str;

    fn header(&self) -> &Header;
    fn header_mut(&mut self) -> &mut Header;
    /// Appends the encoded message to `out`.
    fn encode(&self, out: &mut Vec<u8>) -> Result<(), CodecError>;
    /// Overwrites `dst` (possibly loaned shared memory) with the decoded message.
    fn decode_into(bytes: &[u8], dst: &mut Self) -> Result<(), CodecError>;
    /// A JSON view for humans and `harvest rec cat` (large buffers summarized).
    fn to_json(&self) -> serde_json::Value;
}

/// Implements [`Payload`] for a small `Copy` type that derives serde: encode/decode through the
/// codec, JSON through serde_json.
#[macro_export]
macro_rules! serde_payload {
    ($ty:ty, $name:literal, $version:literal, $schema:expr) => {
        // SAFETY: the type is #[repr(C)] plain data made of integers, floats and arrays/structs
        // of those (checked by review of the type; enums travel as integer codes).
        unsafe impl $crate::payload::Payload for $ty {
            const TYPE_NAME: &'static str = $name;
            const VERSION: u32 = $version;
            const SCHEMA: &'static str = $schema;

            fn header(&self) -> &$crate::header::Header {
                &self.header
            }
            fn header_mut(&mut self) -> &mut $crate::header::Header {
                &mut self.header
            }
            fn encode(&self, out: &mut Vec<u8>) -> Result<(), $crate::codec::CodecError> {
                $crate::codec::encode_into(self, out)
            }
            fn decode_into(bytes: &[u8], dst: &mut Self) -> Result<(), $crate::codec::CodecError> {
                *dst = $crate::codec::decode_exact(bytes)?;
                Ok(())
            }
            fn to_json(&self) -> serde_json::Value {
                serde_json::to_value(self).unwrap_or_else(|error| {
                    serde_json::json!({ "error": error.to_string() })
                })
            }
        }
    };
}

/// A zero-filled `T` on the heap, for the few places that hold a payload outside shared memory
/// (tests, evaluation, decoding recordings): multi-megabyte payloads never live on the stack.
pub fn boxed_zeroed<T: Payload>() -> Box<T> {
    let layout = std::alloc::Layout::new::<T>();
    if layout.size() == 0 {
        // Every payload holds a header, so this does not happen in practice.
        // SAFETY: for a zero-sized T any non-null aligned pointer is a valid Box<T>.
        return unsafe { Box::from_raw(std::ptr::NonNull::<T>::dangling().as_ptr()) };
    }
    // SAFETY: the layout is not zero-sized; all-zero bytes are a valid `T` by the `Payload`
    // contract; the pointer comes from the global allocator with `T`'s layout, as
    // `Box::from_raw` requires.
    unsafe {
        let pointer = std::alloc::alloc_zeroed(layout).cast::<T>();
        if pointer.is_null() {
            std::alloc::handle_alloc_error(layout);
        }
        Box::from_raw(pointer)
    }
}
