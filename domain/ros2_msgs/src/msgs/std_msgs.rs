//! `std_msgs`: the header every stamped message starts with, `Bool` and `String`.

use super::builtin_interfaces::{TIME_TYPE, Time};
use crate::cdr::{CdrError, CdrReader, CdrWriter};
use crate::message::RosMessage;
use crate::type_description::{BaseType, Field, MessageType, STRING};

/// `std_msgs/msg/Header`: the time of validity and the coordinate frame of the data.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Header {
    pub stamp: Time,
    pub frame_id: String,
}

pub static HEADER_TYPE: MessageType = MessageType {
    name: "std_msgs/msg/Header",
    constants: &[],
    fields: &[
        Field::new("stamp", BaseType::Nested(&TIME_TYPE)),
        Field::new("frame_id", STRING),
    ],
};

impl Header {
    pub fn new(stamp_ns: u64, frame_id: &str) -> Self {
        Self {
            stamp: Time::from_ns(stamp_ns),
            frame_id: frame_id.to_owned(),
        }
    }
}

impl RosMessage for Header {
    const TYPE: &'static MessageType = &HEADER_TYPE;

    fn write_fields(&self, w: &mut CdrWriter) {
        self.stamp.write_fields(w);
        w.write_string(&self.frame_id);
    }

    fn read_fields(r: &mut CdrReader<'_>) -> Result<Self, CdrError> {
        Ok(Self {
            stamp: Time::read_fields(r)?,
            frame_id: r.read_string()?,
        })
    }
}

/// `std_msgs/msg/Bool`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Bool {
    pub data: bool,
}

pub static BOOL_TYPE: MessageType = MessageType {
    name: "std_msgs/msg/Bool",
    constants: &[],
    fields: &[Field::new("data", BaseType::Bool)],
};

impl RosMessage for Bool {
    const TYPE: &'static MessageType = &BOOL_TYPE;

    fn write_fields(&self, w: &mut CdrWriter) {
        w.write_bool(self.data);
    }

    fn read_fields(r: &mut CdrReader<'_>) -> Result<Self, CdrError> {
        Ok(Self {
            data: r.read_bool()?,
        })
    }
}

/// `std_msgs/msg/String`.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct StringMessage {
    pub data: String,
}

pub static STRING_TYPE: MessageType = MessageType {
    name: "std_msgs/msg/String",
    constants: &[],
    fields: &[Field::new("data", STRING)],
};

impl RosMessage for StringMessage {
    const TYPE: &'static MessageType = &STRING_TYPE;

    fn write_fields(&self, w: &mut CdrWriter) {
        w.write_string(&self.data);
    }

    fn read_fields(r: &mut CdrReader<'_>) -> Result<Self, CdrError> {
        Ok(Self {
            data: r.read_string()?,
        })
    }
}
