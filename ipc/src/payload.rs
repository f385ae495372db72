//! What every message type carried by the stack implements.

use crate::any_bit_pattern::AnyBitPattern;
use crate::codec::CodecError;
use crate::header::Header;
use crate::schema::Describe;
use iceoryx2::prelude::ZeroCopySend;

/// A message type of the channel catalogue.
///
/// The memory contract is [`AnyBitPattern`] (derived, so checked at compile time): `#[repr(C)]`
/// plain data without padding for which every bit pattern is a valid value (integers, floats,
/// arrays and structs of those; enums travel as [`crate::wire_code::WireCode`]s). The transport
/// relies on it to hand out loaned shared memory as `&mut Self` without first building a value:
/// the segment bytes are always initialized (zero-filled by the kernel when the segment is
/// created, earlier samples afterwards), so large frames are written in place and never built on
/// the stack or copied.
///
/// A payload is declared once, with `#[derive(Payload)]` beside iceoryx2's `ZeroCopySend` and
/// its `#[type_name("harvest.ArmState.v2")]`: the derive takes [`Self::TYPE_NAME`] and
/// [`Self::VERSION`] from that name, the schema from the fields ([`Describe`], rendered by
/// [`crate::schema::schema_text`]), and encodes through serde and the [`crate::codec`] unless
/// `#[payload(custom_codec)]` says the type implements [`CustomCodec`] (the large frames, which
/// copy their pixel and point buffers without serde).
pub trait Payload: AnyBitPattern + ZeroCopySend + Describe + std::fmt::Debug {
    /// Stable type name, e.g. `harvest.RgbdFrame`.
    const TYPE_NAME: &'static str;
    /// Layout version; bumped on any change of fields. With the type name it forms the iceoryx2
    /// type name (`#[type_name("harvest.RgbdFrame.v1")]`) and the MCAP schema name, both
    /// [`schema_name`]`(TYPE_NAME, VERSION)`, so a stale service of another version fails to
    /// open with a clear error.
    const VERSION: u32;

    /// The envelope every payload starts with.
    fn header(&self) -> &Header;
    /// The envelope, to stamp before sending.
    fn header_mut(&mut self) -> &mut Header;
    /// Appends the encoded message to `out`.
    fn encode(&self, out: &mut Vec<u8>) -> Result<(), CodecError>;
    /// Overwrites `dst` (possibly loaned shared memory) with the decoded message.
    fn decode_into(bytes: &[u8], dst: &mut Self) -> Result<(), CodecError>;
    /// A JSON view for humans and `harvest rec cat` (large buffers summarized).
    fn to_json(&self) -> serde_json::Value;
}

/// The encoding of a payload that does not go through serde as a whole (`#[payload(custom_codec)]`):
/// the multi-megabyte frames, whose buffers are copied without serde and decoded in place. It
/// must write what the type's [`Describe`] says (the catalogue's tests decode every payload by
/// its schema alone).
pub trait CustomCodec {
    /// Appends the encoded message to `out`.
    fn encode(&self, out: &mut Vec<u8>) -> Result<(), CodecError>;
    /// Overwrites `dst` with the decoded message.
    fn decode_into(bytes: &[u8], dst: &mut Self) -> Result<(), CodecError>;
    /// A JSON view for humans (large buffers summarized).
    fn to_json(&self) -> serde_json::Value;
}

/// The JSON view of a serde payload (what `#[derive(Payload)]` uses).
pub fn serde_json_of<T: serde::Serialize>(value: &T) -> serde_json::Value {
    serde_json::to_value(value)
        .unwrap_or_else(|error| serde_json::json!({ "error": error.to_string() }))
}

/// The name under which a payload type and version is known to iceoryx2 (its `#[type_name]`)
/// and in recordings (the MCAP schema name): `harvest.RgbdFrame` version 1 ->
/// `harvest.RgbdFrame.v1`.
pub fn schema_name(type_name: &str, version: u32) -> String {
    format!("{type_name}.v{version}")
}

/// A zero-filled `T` on the heap, for the few places that hold a payload outside shared memory
/// (tests, evaluation, decoding recordings): multi-megabyte payloads never live on the stack.
pub fn boxed_zeroed<T: AnyBitPattern>() -> Box<T> {
    let () = T::LAYOUT_CHECK;
    let layout = std::alloc::Layout::new::<T>();
    if layout.size() == 0 {
        // Every payload holds a header, so this does not happen in practice.
        // SAFETY: for a zero-sized T any non-null aligned pointer is a valid Box<T>.
        return unsafe { Box::from_raw(std::ptr::NonNull::<T>::dangling().as_ptr()) };
    }
    // SAFETY: the layout is not zero-sized; all-zero bytes are a valid `T` by the
    // `AnyBitPattern` contract; the pointer comes from the global allocator with `T`'s layout, as
    // `Box::from_raw` requires.
    unsafe {
        let pointer = std::alloc::alloc_zeroed(layout).cast::<T>();
        if pointer.is_null() {
            std::alloc::handle_alloc_error(layout);
        }
        Box::from_raw(pointer)
    }
}
