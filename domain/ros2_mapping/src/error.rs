//! Why a bag message cannot enter the stack: always naming the topic and, when it is about one,
//! the field.

use harvest_ros2::DecodeError;

/// A problem with one field of a message (the topic is added by the caller).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("field `{field}`: {problem}")]
pub struct FieldError {
    /// The field, as named in the message definition (`encoding`, `fields.intensity`, ...).
    pub field: String,
    pub problem: String,
}

impl FieldError {
    pub fn new(field: &str, problem: impl Into<String>) -> Self {
        Self {
            field: field.to_owned(),
            problem: problem.into(),
        }
    }
}

/// A bag message the stack cannot take.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum ImportError {
    /// A field holds what the stack does not support (an encoding, a size, a missing field).
    #[error("topic {topic} ({type_name}): {source}")]
    Field {
        topic: String,
        type_name: String,
        source: FieldError,
    },
    /// The message is not valid CDR of its type.
    #[error("topic {topic}: {source}")]
    Decode { topic: String, source: DecodeError },
    /// The topic's type is not one the map's role can take.
    #[error("topic {topic} is {found}, the map uses it as {role}, which takes {expected}")]
    Type {
        topic: String,
        found: String,
        role: &'static str,
        expected: &'static str,
    },
    /// The message encoding is not CDR.
    #[error("topic {topic}: message encoding {encoding:?}, not cdr (a ROS 2 bag's)")]
    Encoding { topic: String, encoding: String },
}
