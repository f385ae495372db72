//! The memory contract of every payload: any bit pattern is a valid value.
//!
//! The transport hands loaned shared memory out as `&mut T` without first building a `T`, and
//! subscribers read whatever bytes a publisher (possibly a buggy or hostile one) left there. Both
//! are sound only when every bit pattern of `size_of::<T>()` bytes is a valid `T`: integers,
//! floats, arrays of those and `#[repr(C)]` structs of those without padding. `bool`, `char`,
//! enums, references and pointers are not (a `u8` flag or a [`crate::wire_code::WireCode`]
//! carries them instead). [`crate::Payload`] requires this trait, and
//! [`derive(AnyBitPattern)`](harvest_ipc_derive::AnyBitPattern) proves it for a struct at compile
//! time, in the style of bytemuck's `AnyBitPattern` and zerocopy's `FromBytes`.
//!
//! The derive rejects a struct without `#[repr(C)]`:
//!
//! ```compile_fail
//! #[derive(harvest_ipc::AnyBitPattern)]
//! struct Unordered {
//!     stamp_ns: u64,
//!     count: u32,
//!     reserved: u32,
//! }
//! ```
//!
//! a field that is not any-bit-pattern (here a `bool`):
//!
//! ```compile_fail,E0277
//! #[repr(C)]
//! #[derive(harvest_ipc::AnyBitPattern)]
//! struct WithBool {
//!     engaged: bool,
//!     reserved: [u8; 7],
//! }
//! ```
//!
//! and padding between or after the fields:
//!
//! ```compile_fail,E0080
//! #[repr(C)]
//! #[derive(harvest_ipc::AnyBitPattern)]
//! struct Padded {
//!     engaged: u8,
//!     stamp_ns: u64,
//! }
//! ```
//!
//! while the same struct with its padding spelled out is accepted:
//!
//! ```
//! #[repr(C)]
//! #[derive(harvest_ipc::AnyBitPattern)]
//! struct Explicit {
//!     engaged: u8,
//!     _reserved: [u8; 7],
//!     stamp_ns: u64,
//! }
//! ```

use std::marker::PhantomData;

/// A type for which every bit pattern of `size_of::<Self>()` bytes is a valid value.
///
/// # Safety
/// Implementors must have no padding bytes, no invalid bit patterns (`bool`, `char`, enums,
/// references, `NonZero*`), and no pointers. Use `#[derive(AnyBitPattern)]`, which checks this,
/// rather than implementing it by hand.
#[diagnostic::on_unimplemented(
    message = "`{Self}` is not any-bit-pattern, so it cannot be part of a payload",
    label = "some bit patterns of `{Self}` are not valid values",
    note = "payload fields are integers, floats, arrays of those or `#[derive(AnyBitPattern)]` \
structs; carry a flag as `u8` and an enum as `WireCode<E>`"
)]
pub unsafe trait AnyBitPattern: Sized + 'static {
    /// Evaluating this constant fails to compile when the type has padding (set by the
    /// derive; a hand-written implementation has nothing to check).
    #[doc(hidden)]
    const LAYOUT_CHECK: () = ();
}

macro_rules! any_bit_pattern_primitives {
    ($($ty:ty),* $(,)?) => {
        // SAFETY: integers and IEEE-754 floats: every bit pattern is a value, no padding.
        $(unsafe impl AnyBitPattern for $ty {})*
    };
}

any_bit_pattern_primitives!(
    u8, u16, u32, u64, u128, usize, i8, i16, i32, i64, i128, isize, f32, f64
);

// SAFETY: an array of any-bit-pattern elements: elements are laid out without gaps (an element's
// size is a multiple of its alignment), so every bit pattern of the array is a value.
unsafe impl<T: AnyBitPattern, const N: usize> AnyBitPattern for [T; N] {
    const LAYOUT_CHECK: () = T::LAYOUT_CHECK;
}

// SAFETY: zero-sized; its one (empty) bit pattern is its value.
unsafe impl<T: ?Sized + 'static> AnyBitPattern for PhantomData<T> {}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::payload::boxed_zeroed;

    #[repr(C)]
    #[derive(Debug, crate::AnyBitPattern)]
    struct Generic<T: Copy, const N: usize> {
        count: u64,
        items: [T; N],
    }

    #[test]
    fn generic_structs_are_checked_per_instantiation() {
        // Both instantiations have no padding, so evaluating their checks compiles.
        let () = <Generic<u32, 2> as AnyBitPattern>::LAYOUT_CHECK;
        let () = <Generic<f64, 3> as AnyBitPattern>::LAYOUT_CHECK;
        assert_eq!(std::mem::size_of::<Generic<u32, 2>>(), 16);
    }

    #[test]
    fn every_payload_is_any_bit_pattern_of_its_declared_size() {
        use crate::catalogue::{ChannelVisitor, visit_all};
        use crate::{Channel, Payload};
        struct Check;
        impl ChannelVisitor for Check {
            fn visit<T: Payload>(&mut self, _channel: Channel<T>) {
                let () = <T as AnyBitPattern>::LAYOUT_CHECK;
                // A payload with all bits set is a value too: read its header through it.
                let mut value: Box<T> = boxed_zeroed();
                // SAFETY: `T: AnyBitPattern`, so every byte pattern, all-ones included, is a `T`.
                let bytes = unsafe {
                    std::slice::from_raw_parts_mut(
                        (&mut *value as *mut T).cast::<u8>(),
                        std::mem::size_of::<T>(),
                    )
                };
                bytes.fill(0xff);
                assert_eq!(value.header().msg_seq, u64::MAX);
            }
        }
        visit_all(&mut Check);
    }
}
