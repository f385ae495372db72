//! `vacuum/state` as plottable fields: Foxglove has no well-known schema for it, so it gets a
//! protobuf message of ours, `harvest.VacuumView`, with explicit field numbers (a recording
//! stays decodable when fields are added) and its descriptor stored with every channel.

use crate::stamps::TimeBase;
use foxglove::messages::{Log, Timestamp};
use foxglove::{Encode, Schema};
use harvest_ipc::WireCode;
use harvest_ipc::payloads::{ArmAttachment, VacuumState};
use prost::Message as _;
use prost_types::field_descriptor_proto::{Label, Type};
use prost_types::{DescriptorProto, FieldDescriptorProto, FileDescriptorProto, FileDescriptorSet};
use std::sync::OnceLock;

/// Schema name of [`VacuumView`].
pub const SCHEMA_NAME: &str = "harvest.VacuumView";

/// One `vacuum/state` sample, flattened for plots. Pressures are vacuum in mmH2O (positive =
/// below atmosphere); valves 1-2 serve arm 1, 3-4 arm 2; attachment codes 0 closed, 1 open to
/// atmosphere, 2 sealed (apple attached).
#[derive(Clone, PartialEq, prost::Message)]
pub struct VacuumView {
    #[prost(message, optional, tag = "1")]
    pub timestamp: Option<Timestamp>,
    #[prost(double, tag = "2")]
    pub pressure_arm1_mmh2o: f64,
    #[prost(double, tag = "3")]
    pub pressure_arm2_mmh2o: f64,
    #[prost(double, tag = "4")]
    pub pressure_source_mmh2o: f64,
    #[prost(uint32, tag = "5")]
    pub valve1_open: u32,
    #[prost(uint32, tag = "6")]
    pub valve2_open: u32,
    #[prost(uint32, tag = "7")]
    pub valve3_open: u32,
    #[prost(uint32, tag = "8")]
    pub valve4_open: u32,
    #[prost(uint32, tag = "9")]
    pub valves_in_transit: u32,
    #[prost(uint32, tag = "10")]
    pub arm1_attachment: u32,
    #[prost(uint32, tag = "11")]
    pub arm2_attachment: u32,
    #[prost(string, tag = "12")]
    pub arm1_attachment_name: String,
    #[prost(string, tag = "13")]
    pub arm2_attachment_name: String,
    #[prost(uint32, tag = "14")]
    pub policy: u32,
}

/// The fields of [`VacuumView`] as (number, name, type) for its descriptor.
const FIELDS: [(i32, &str, Type); 14] = [
    (1, "timestamp", Type::Message),
    (2, "pressure_arm1_mmh2o", Type::Double),
    (3, "pressure_arm2_mmh2o", Type::Double),
    (4, "pressure_source_mmh2o", Type::Double),
    (5, "valve1_open", Type::Uint32),
    (6, "valve2_open", Type::Uint32),
    (7, "valve3_open", Type::Uint32),
    (8, "valve4_open", Type::Uint32),
    (9, "valves_in_transit", Type::Uint32),
    (10, "arm1_attachment", Type::Uint32),
    (11, "arm2_attachment", Type::Uint32),
    (12, "arm1_attachment_name", Type::String),
    (13, "arm2_attachment_name", Type::String),
    (14, "policy", Type::Uint32),
];

const TIMESTAMP_PROTO: &str = "google/protobuf/timestamp.proto";

/// The serialized `FileDescriptorSet` of `harvest/vacuum_view.proto` and the timestamp file it
/// imports (taken from the SDK's own descriptors, so it is the same as theirs).
fn descriptor_set() -> &'static [u8] {
    static SET: OnceLock<Vec<u8>> = OnceLock::new();
    SET.get_or_init(|| {
        let timestamp_file = Log::get_schema()
            .and_then(|schema| FileDescriptorSet::decode(schema.data.as_ref()).ok())
            .and_then(|set| {
                set.file
                    .into_iter()
                    .find(|file| file.name() == TIMESTAMP_PROTO)
            });
        let fields = FIELDS
            .iter()
            .map(|&(number, name, kind)| FieldDescriptorProto {
                name: Some(name.to_owned()),
                number: Some(number),
                label: Some(Label::Optional as i32),
                r#type: Some(kind as i32),
                type_name: (kind == Type::Message).then(|| ".google.protobuf.Timestamp".to_owned()),
                json_name: Some(name.to_owned()),
                ..FieldDescriptorProto::default()
            })
            .collect();
        let file = FileDescriptorProto {
            name: Some("harvest/vacuum_view.proto".to_owned()),
            package: Some("harvest".to_owned()),
            dependency: vec![TIMESTAMP_PROTO.to_owned()],
            message_type: vec![DescriptorProto {
                name: Some("VacuumView".to_owned()),
                field: fields,
                ..DescriptorProto::default()
            }],
            syntax: Some("proto3".to_owned()),
            ..FileDescriptorProto::default()
        };
        let set = FileDescriptorSet {
            file: timestamp_file.into_iter().chain([file]).collect(),
        };
        set.encode_to_vec()
    })
}

impl Encode for VacuumView {
    type Error = prost::EncodeError;

    fn get_schema() -> Option<Schema> {
        Some(Schema::new(SCHEMA_NAME, "protobuf", descriptor_set()))
    }

    fn get_message_encoding() -> String {
        "protobuf".to_owned()
    }

    fn encode(&self, buf: &mut impl foxglove::bytes::BufMut) -> Result<(), Self::Error> {
        prost::Message::encode(self, buf)
    }

    fn encoded_len(&self) -> Option<usize> {
        Some(prost::Message::encoded_len(self))
    }
}

/// `closed`, `open`, `sealed` for an attachment code.
pub fn attachment_name(code: WireCode<ArmAttachment>) -> &'static str {
    match code.get() {
        Ok(ArmAttachment::Closed) => "closed",
        Ok(ArmAttachment::Open) => "open",
        Ok(ArmAttachment::Sealed) => "sealed",
        Err(_) => "unknown",
    }
}

/// The view of one `vacuum/state` sample.
pub fn vacuum_view(state: &VacuumState, time: &TimeBase) -> VacuumView {
    let valve = |index: usize| u32::from(state.valve_open[index]);
    VacuumView {
        timestamp: Some(time.timestamp(state.header.capture_ns)),
        pressure_arm1_mmh2o: f64::from(state.pressure_mmh2o[0]),
        pressure_arm2_mmh2o: f64::from(state.pressure_mmh2o[1]),
        pressure_source_mmh2o: f64::from(state.pressure_mmh2o[2]),
        valve1_open: valve(0),
        valve2_open: valve(1),
        valve3_open: valve(2),
        valve4_open: valve(3),
        valves_in_transit: state
            .valve_in_transit
            .iter()
            .map(|&moving| u32::from(moving != 0))
            .sum(),
        arm1_attachment: u32::from(state.arm_attachment[0].raw()),
        arm2_attachment: u32::from(state.arm_attachment[1].raw()),
        arm1_attachment_name: attachment_name(state.arm_attachment[0]).to_owned(),
        arm2_attachment_name: attachment_name(state.arm_attachment[1]).to_owned(),
        policy: u32::from(state.policy.raw()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use prost_types::DescriptorProto;

    /// The descriptor a reader decodes with agrees with the encoder's field numbers and types:
    /// decoding our bytes field by field with the descriptor alone gives the values back.
    #[test]
    fn descriptor_matches_the_encoded_fields() {
        let schema = VacuumView::get_schema().expect("schema");
        let set = FileDescriptorSet::decode(schema.data.as_ref()).expect("descriptor set");
        let names: Vec<&str> = set.file.iter().map(|file| file.name()).collect();
        assert_eq!(names, [TIMESTAMP_PROTO, "harvest/vacuum_view.proto"]);
        let message: &DescriptorProto = &set.file[1].message_type[0];
        assert_eq!(
            format!("{}.{}", set.file[1].package(), message.name()),
            SCHEMA_NAME
        );
        let mut state = VacuumState::default();
        state.header.capture_ns = 2_500_000_000;
        state.pressure_mmh2o = [310.5, 12.0, 400.0];
        state.valve_open = [1, 1, 0, 0];
        state.arm_attachment = [ArmAttachment::Sealed.into(), ArmAttachment::Closed.into()];
        let view = vacuum_view(&state, &TimeBase::MONOTONIC);
        let bytes = view.encode_to_vec();
        // Walk the wire format with the descriptor: every field number is declared with a
        // wire type that matches the descriptor's type.
        let mut rest = bytes.as_slice();
        let mut seen = Vec::new();
        while !rest.is_empty() {
            let key = prost::encoding::decode_varint(&mut rest).expect("key");
            let (number, wire_type) = ((key >> 3) as i32, key & 7);
            let field = message
                .field
                .iter()
                .find(|field| field.number() == number)
                .expect("field in descriptor");
            let expected_wire = match field.r#type() {
                Type::Double => 1,
                Type::Uint32 => 0,
                Type::Message | Type::String => 2,
                other => panic!("unexpected type {other:?}"),
            };
            assert_eq!(wire_type, expected_wire, "{}", field.name());
            match wire_type {
                0 => {
                    prost::encoding::decode_varint(&mut rest).expect("varint");
                }
                1 => {
                    let value = f64::from_le_bytes(rest[..8].try_into().expect("8 bytes"));
                    if field.name() == "pressure_arm1_mmh2o" {
                        assert_eq!(value, 310.5);
                    }
                    rest = &rest[8..];
                }
                _ => {
                    let length = prost::encoding::decode_varint(&mut rest).expect("length");
                    rest = &rest[length as usize..];
                }
            }
            seen.push(field.name().to_owned());
        }
        assert!(seen.contains(&"arm1_attachment_name".to_owned()));
        assert_eq!(VacuumView::decode(bytes.as_slice()).expect("decode"), view);
        assert_eq!(view.arm1_attachment_name, "sealed");
    }
}
