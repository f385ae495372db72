//! `diagnostic_msgs`: the health of processes and devices, as `/diagnostics` carries it.

use super::std_msgs::{HEADER_TYPE, Header};
use crate::cdr::{CdrError, CdrReader, CdrWriter};
use crate::message::RosMessage;
use crate::type_description::{BaseType, Constant, Field, MessageType, STRING};

/// `diagnostic_msgs/msg/KeyValue`.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct KeyValue {
    pub key: String,
    pub value: String,
}

pub static KEY_VALUE_TYPE: MessageType = MessageType {
    name: "diagnostic_msgs/msg/KeyValue",
    constants: &[],
    fields: &[Field::new("key", STRING), Field::new("value", STRING)],
};

impl RosMessage for KeyValue {
    const TYPE: &'static MessageType = &KEY_VALUE_TYPE;

    fn write_fields(&self, w: &mut CdrWriter) {
        w.write_string(&self.key);
        w.write_string(&self.value);
    }

    fn read_fields(r: &mut CdrReader<'_>) -> Result<Self, CdrError> {
        Ok(Self {
            key: r.read_string()?,
            value: r.read_string()?,
        })
    }
}

/// `diagnostic_msgs/msg/DiagnosticStatus`: one component's level and message.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct DiagnosticStatus {
    /// [`Self::OK`], [`Self::WARN`], [`Self::ERROR`] or [`Self::STALE`].
    pub level: u8,
    pub name: String,
    pub message: String,
    pub hardware_id: String,
    pub values: Vec<KeyValue>,
}

impl DiagnosticStatus {
    pub const OK: u8 = 0;
    pub const WARN: u8 = 1;
    pub const ERROR: u8 = 2;
    pub const STALE: u8 = 3;
}

const fn level(name: &'static str, value: &'static str) -> Constant {
    Constant {
        name,
        base: BaseType::Byte,
        value,
    }
}

pub static DIAGNOSTIC_STATUS_TYPE: MessageType = MessageType {
    name: "diagnostic_msgs/msg/DiagnosticStatus",
    constants: &[
        level("OK", "0"),
        level("WARN", "1"),
        level("ERROR", "2"),
        level("STALE", "3"),
    ],
    fields: &[
        Field::new("level", BaseType::Byte),
        Field::new("name", STRING),
        Field::new("message", STRING),
        Field::new("hardware_id", STRING),
        Field::sequence("values", BaseType::Nested(&KEY_VALUE_TYPE)),
    ],
};

impl RosMessage for DiagnosticStatus {
    const TYPE: &'static MessageType = &DIAGNOSTIC_STATUS_TYPE;

    fn write_fields(&self, w: &mut CdrWriter) {
        w.write_u8(self.level);
        w.write_string(&self.name);
        w.write_string(&self.message);
        w.write_string(&self.hardware_id);
        w.write_sequence(&self.values, |w, value| value.write_fields(w));
    }

    fn read_fields(r: &mut CdrReader<'_>) -> Result<Self, CdrError> {
        Ok(Self {
            level: r.read_u8()?,
            name: r.read_string()?,
            message: r.read_string()?,
            hardware_id: r.read_string()?,
            values: r.read_sequence("KeyValue[]", 8, KeyValue::read_fields)?,
        })
    }
}

/// `diagnostic_msgs/msg/DiagnosticArray`.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct DiagnosticArray {
    pub header: Header,
    pub status: Vec<DiagnosticStatus>,
}

pub static DIAGNOSTIC_ARRAY_TYPE: MessageType = MessageType {
    name: "diagnostic_msgs/msg/DiagnosticArray",
    constants: &[],
    fields: &[
        Field::new("header", BaseType::Nested(&HEADER_TYPE)),
        Field::sequence("status", BaseType::Nested(&DIAGNOSTIC_STATUS_TYPE)),
    ],
};

impl RosMessage for DiagnosticArray {
    const TYPE: &'static MessageType = &DIAGNOSTIC_ARRAY_TYPE;

    fn write_fields(&self, w: &mut CdrWriter) {
        self.header.write_fields(w);
        w.write_sequence(&self.status, |w, status| status.write_fields(w));
    }

    fn read_fields(r: &mut CdrReader<'_>) -> Result<Self, CdrError> {
        Ok(Self {
            header: Header::read_fields(r)?,
            status: r.read_sequence("DiagnosticStatus[]", 17, DiagnosticStatus::read_fields)?,
        })
    }
}
