//! Enums in payloads: a [`WireCode<E>`] holds the `u8` code of an enum `E` in shared memory.
//!
//! A Rust enum cannot sit in a payload: a publisher of another version, a bug or a hostile
//! process can leave any byte there, and an out-of-range discriminant is undefined behaviour.
//! A `WireCode<E>` is a byte (every bit pattern valid), written from an `E` with
//! [`WireCode::set`] and read back with [`WireCode::get`], which returns an [`UnknownCode`] for a
//! byte that is no code of `E`: the reader chooses what an unknown code means (skip the message,
//! fall back to the safe state, report it), and nothing panics. Code compares wire codes with
//! enum values (`state.phase == ArmPhase::Idle`), never with bare numbers.
//!
//! On the wire (the [`crate::codec`] encoding, JSON) a code is its `u8`, as before it was typed.

use iceoryx2::prelude::ZeroCopySend;
use serde::{Deserialize, Deserializer, Serialize, Serializer};
use std::marker::PhantomData;

/// An enum whose values travel as `u8` codes. Derive it with
/// [`derive(WireEnum)`](harvest_ipc_derive::WireEnum) on a `#[repr(u8)]` enum of unit
/// variants: the code is the discriminant.
pub trait WireEnum: Copy + Eq + std::fmt::Debug + 'static {
    /// The enum's name, for errors and logs.
    const NAME: &'static str;
    /// Every value, in declaration order.
    const ALL: &'static [Self];
    /// The value's code.
    fn code(self) -> u8;
    /// The value of `code`, `None` when no value has it.
    fn from_code(code: u8) -> Option<Self>;
}

/// A byte read from a payload that is no code of the expected enum.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[error("unknown {enum_name} code {code}")]
pub struct UnknownCode {
    /// The enum expected ([`WireEnum::NAME`]).
    pub enum_name: &'static str,
    /// The byte found.
    pub code: u8,
}

/// The `u8` code of an `E` as it lies in a payload (see the module docs).
#[repr(C)]
#[derive(crate::AnyBitPattern)]
pub struct WireCode<E: WireEnum> {
    code: u8,
    value: PhantomData<fn() -> E>,
}

impl<E: WireEnum> WireCode<E> {
    /// The code of `value`.
    pub fn new(value: E) -> Self {
        Self::from_raw(value.code())
    }

    /// A code from its raw byte, known or not (decoding, tests of unknown codes).
    pub const fn from_raw(code: u8) -> Self {
        Self {
            code,
            value: PhantomData,
        }
    }

    /// The raw byte.
    pub const fn raw(self) -> u8 {
        self.code
    }

    /// The value, or [`UnknownCode`] when the byte is no code of `E`.
    pub fn get(self) -> Result<E, UnknownCode> {
        E::from_code(self.code).ok_or(UnknownCode {
            enum_name: E::NAME,
            code: self.code,
        })
    }

    /// Stores `value`'s code.
    pub fn set(&mut self, value: E) {
        self.code = value.code();
    }
}

impl<E: WireEnum> From<E> for WireCode<E> {
    fn from(value: E) -> Self {
        Self::new(value)
    }
}

impl<E: WireEnum> PartialEq<E> for WireCode<E> {
    fn eq(&self, other: &E) -> bool {
        self.code == other.code()
    }
}

impl<E: WireEnum> Clone for WireCode<E> {
    fn clone(&self) -> Self {
        *self
    }
}

impl<E: WireEnum> Copy for WireCode<E> {}

impl<E: WireEnum> PartialEq for WireCode<E> {
    fn eq(&self, other: &Self) -> bool {
        self.code == other.code
    }
}

impl<E: WireEnum> Eq for WireCode<E> {}

impl<E: WireEnum> std::hash::Hash for WireCode<E> {
    fn hash<H: std::hash::Hasher>(&self, state: &mut H) {
        self.code.hash(state);
    }
}

/// Raw code 0 (what a zero-filled payload holds; not necessarily a code of `E`).
impl<E: WireEnum> Default for WireCode<E> {
    fn default() -> Self {
        Self::from_raw(0)
    }
}

impl<E: WireEnum> std::fmt::Debug for WireCode<E> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self.get() {
            Ok(value) => value.fmt(f),
            Err(unknown) => write!(f, "<{unknown}>"),
        }
    }
}

// SAFETY: `#[repr(C)]` around one `u8` (the marker is zero-sized and holds no `E`): no pointer,
// the same layout in every process.
unsafe impl<E: WireEnum> ZeroCopySend for WireCode<E> {}

impl<E: WireEnum> Serialize for WireCode<E> {
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        serializer.serialize_u8(self.code)
    }
}

/// Written as the enum's code (`#[derive(WireEnum)]` describes the enum).
impl<E: WireEnum + crate::schema::Describe> crate::schema::Describe for WireCode<E> {
    fn shape() -> crate::schema::Shape {
        E::shape()
    }
}

impl<'de, E: WireEnum> Deserialize<'de> for WireCode<E> {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        u8::deserialize(deserializer).map(Self::from_raw)
    }
}

// The marker must not make the code bigger than its byte.
const _: () = assert!(std::mem::size_of::<WireCode<crate::payloads::ArmPhase>>() == 1);

#[cfg(test)]
mod tests {
    use super::*;
    use crate::payloads::{ArmPhase, HarvestCause, HarvestEventKind};

    fn round_trips<E: WireEnum>() {
        for &value in E::ALL {
            let code = WireCode::new(value);
            assert_eq!(code.get(), Ok(value));
            assert_eq!(code, value);
        }
        for raw in 0..=u8::MAX {
            match WireCode::<E>::from_raw(raw).get() {
                Ok(value) => assert_eq!(value.code(), raw),
                Err(unknown) => {
                    assert_eq!(
                        unknown,
                        UnknownCode {
                            enum_name: E::NAME,
                            code: raw
                        }
                    );
                    assert!(E::ALL.iter().all(|value| value.code() != raw));
                }
            }
        }
    }

    #[test]
    fn every_code_round_trips_and_every_other_byte_is_unknown() {
        round_trips::<ArmPhase>();
        round_trips::<HarvestEventKind>();
        round_trips::<HarvestCause>();
    }

    #[test]
    fn an_unknown_code_names_the_enum_and_the_byte() {
        let code = WireCode::<ArmPhase>::from_raw(200);
        let error = code.get().expect_err("200 is no phase");
        assert_eq!(error.to_string(), "unknown ArmPhase code 200");
        assert_eq!(format!("{code:?}"), "<unknown ArmPhase code 200>");
        assert_ne!(code, ArmPhase::Idle);
    }

    #[test]
    fn set_and_serialize_as_the_byte() {
        let mut code = WireCode::<ArmPhase>::default();
        code.set(ArmPhase::Retract);
        assert_eq!(code.raw(), 3);
        let mut bytes = Vec::new();
        crate::codec::encode_into(&code, &mut bytes).expect("encode");
        assert_eq!(bytes, [3]);
        let back: WireCode<ArmPhase> = crate::codec::decode_exact(&[9]).expect("decode");
        assert!(back.get().is_err());
        assert_eq!(
            serde_json::to_value(code).expect("json"),
            serde_json::json!(3)
        );
    }
}
