//! `builtin_interfaces`: time.

use crate::cdr::{CdrError, CdrReader, CdrWriter};
use crate::message::RosMessage;
use crate::type_description::{BaseType, Field, MessageType};

/// `builtin_interfaces/msg/Time`: seconds and nanoseconds (ROS time: Unix epoch for system
/// time, any clock's nanoseconds otherwise).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Time {
    pub sec: i32,
    pub nanosec: u32,
}

pub static TIME_TYPE: MessageType = MessageType {
    name: "builtin_interfaces/msg/Time",
    constants: &[],
    fields: &[
        Field::new("sec", BaseType::Int32),
        Field::new("nanosec", BaseType::Uint32),
    ],
};

impl Time {
    /// Nanoseconds since the clock's epoch; times past 2038 saturate at `i32::MAX` seconds.
    pub fn from_ns(ns: u64) -> Self {
        let sec = ns / 1_000_000_000;
        Self {
            sec: i32::try_from(sec).unwrap_or(i32::MAX),
            nanosec: (ns % 1_000_000_000) as u32,
        }
    }

    /// Nanoseconds since the epoch; negative times read as 0.
    pub fn to_ns(self) -> u64 {
        u64::try_from(self.sec).unwrap_or(0) * 1_000_000_000 + u64::from(self.nanosec)
    }
}

impl RosMessage for Time {
    const TYPE: &'static MessageType = &TIME_TYPE;

    fn write_fields(&self, w: &mut CdrWriter) {
        w.write_i32(self.sec);
        w.write_u32(self.nanosec);
    }

    fn read_fields(r: &mut CdrReader<'_>) -> Result<Self, CdrError> {
        Ok(Self {
            sec: r.read_i32()?,
            nanosec: r.read_u32()?,
        })
    }
}
