//! Decoding recorded messages back into catalogue payloads, found by their schema name.

use crate::scan::ScannedMessage;
use crate::schema::{TopicInfo, parse_schema_name, schema_name};
use harvest_ipc::codec::CodecError;
use harvest_ipc::{Channel, ChannelVisitor, Payload, catalogue};

/// A heap value of `T` with every byte zero, which the [`Payload`] contract makes a valid
/// value: large payloads (6.8 MB frames) are decoded into it without touching the stack.
pub fn zeroed_box<T: Payload>() -> Box<T> {
    harvest_ipc::payload::boxed_zeroed()
}

/// Decodes `message` into `into` if it was recorded with `channel`'s schema (this build's type
/// and version); false when the schema is another or the bytes do not decode.
pub fn decode_scanned_into<T: Payload>(
    channel: Channel<T>,
    message: &ScannedMessage<'_>,
    into: &mut T,
) -> bool {
    let expected = TopicInfo::of(channel).schema_name();
    let schema_ok = message
        .channel
        .schema
        .as_ref()
        .is_some_and(|schema| schema.name == expected);
    schema_ok && T::decode_into(message.data, into).is_ok()
}

/// The payload of `message` if it was recorded with `channel`'s schema and decodes (small
/// payloads; large ones go through [`decode_scanned_into`] and a [`zeroed_box`]).
pub fn decode_scanned<T: Payload + Default>(
    channel: Channel<T>,
    message: &ScannedMessage<'_>,
) -> Option<T> {
    let mut value = T::default();
    decode_scanned_into(channel, message, &mut value).then_some(value)
}

/// Decodes one payload type to its JSON view, reusing one heap value across messages.
pub trait JsonDecoder {
    fn type_name(&self) -> &'static str;
    fn to_json(&mut self, bytes: &[u8]) -> Result<serde_json::Value, CodecError>;
}

struct TypedJsonDecoder<T: Payload> {
    scratch: Box<T>,
}

impl<T: Payload> JsonDecoder for TypedJsonDecoder<T> {
    fn type_name(&self) -> &'static str {
        T::TYPE_NAME
    }

    fn to_json(&mut self, bytes: &[u8]) -> Result<serde_json::Value, CodecError> {
        T::decode_into(bytes, &mut self.scratch)?;
        Ok(self.scratch.to_json())
    }
}

/// How a recorded schema relates to this build's catalogue.
pub enum SchemaMatch<D> {
    /// Same type and version: decodable.
    Known(D),
    /// The type exists here with another layout version: not decodable by this build.
    OtherVersion {
        type_name: String,
        recorded: u32,
        current: u32,
    },
    /// Not a catalogue type (or not a harvest schema name at all).
    Unknown,
}

impl<D> SchemaMatch<D> {
    /// Why a message of this schema cannot be decoded (`None` when it can).
    pub fn problem(&self, schema: &str) -> Option<String> {
        match self {
            Self::Known(_) => None,
            Self::OtherVersion {
                type_name,
                recorded,
                current,
            } => Some(format!(
                "recorded with {type_name} v{recorded}, this build knows v{current} (recording from another software version)"
            )),
            Self::Unknown => Some(format!(
                "schema {schema:?} is not a payload type of this build"
            )),
        }
    }
}

/// A JSON decoder for messages of the recorded schema `schema` (e.g. `harvest.ArmState.v2`).
pub fn json_decoder(schema: &str) -> SchemaMatch<Box<dyn JsonDecoder>> {
    struct Find<'a> {
        schema: &'a str,
        found: Option<Box<dyn JsonDecoder>>,
        other_version: Option<(String, u32)>,
    }
    impl ChannelVisitor for Find<'_> {
        fn visit<T: Payload>(&mut self, _channel: Channel<T>) {
            if self.found.is_some() {
                return;
            }
            if schema_name(T::TYPE_NAME, T::VERSION) == self.schema {
                self.found = Some(Box::new(TypedJsonDecoder::<T> {
                    scratch: zeroed_box(),
                }));
            } else if parse_schema_name(self.schema).is_some_and(|(name, _)| name == T::TYPE_NAME) {
                self.other_version = Some((T::TYPE_NAME.to_owned(), T::VERSION));
            }
        }
    }
    let mut find = Find {
        schema,
        found: None,
        other_version: None,
    };
    catalogue::visit_all(&mut find);
    match (find.found, find.other_version, parse_schema_name(schema)) {
        (Some(decoder), _, _) => SchemaMatch::Known(decoder),
        (None, Some((type_name, current)), Some((_, recorded))) => SchemaMatch::OtherVersion {
            type_name,
            recorded,
            current,
        },
        _ => SchemaMatch::Unknown,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use harvest_ipc::payloads::{ArmState, RgbdFrame};

    #[test]
    fn zeroed_frames_live_on_the_heap() {
        let frame = zeroed_box::<RgbdFrame>();
        assert_eq!(frame.header.msg_seq, 0);
        assert!(frame.rgb.iter().all(|&byte| byte == 0));
    }

    #[test]
    fn decoders_by_schema_name() {
        let mut state = ArmState::default();
        state.header.msg_seq = 9;
        state.apple_id = 17;
        let mut bytes = Vec::new();
        state.encode(&mut bytes).expect("encode");
        let SchemaMatch::Known(mut decoder) = json_decoder("harvest.ArmState.v2") else {
            panic!("ArmState v2 must be known");
        };
        let json = decoder.to_json(&bytes).expect("decode");
        assert_eq!(json["apple_id"], 17);
        assert_eq!(json["header"]["msg_seq"], 9);
        assert!(decoder.to_json(&bytes[..bytes.len() - 1]).is_err());
        assert!(matches!(
            json_decoder("harvest.ArmState.v0"),
            SchemaMatch::OtherVersion {
                recorded: 0,
                current: 2,
                ..
            }
        ));
        assert!(matches!(
            json_decoder("foxglove.RawImage"),
            SchemaMatch::Unknown
        ));
        assert!(matches!(
            json_decoder("harvest.Nothing.v1"),
            SchemaMatch::Unknown
        ));
    }
}
