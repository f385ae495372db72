//! Reading back what [`crate::state_encoding`] sends: each payload's JSON into the stack's
//! payload type. JSON has no NaN or infinity, so a non-finite float (a quantity not known, such
//! as the platform's position on a robot without one) was written as `null`; here a `null`
//! where a float is expected reads back as NaN, and everything else as plain JSON.

use serde::de::{self, DeserializeOwned, DeserializeSeed, IntoDeserializer, Visitor};
use serde_json::{Error, Value};

/// The payload in `bytes` (module docs).
pub fn payload_from_json<T: DeserializeOwned>(bytes: &[u8]) -> Result<T, Error> {
    let value: Value = serde_json::from_slice(bytes)?;
    T::deserialize(NullAsNan(value))
}

/// A JSON value whose `null`s read as NaN where a float is expected.
struct NullAsNan(Value);

struct Items(std::vec::IntoIter<Value>);

struct Fields {
    entries: serde_json::map::IntoIter,
    value: Option<Value>,
}

impl<'de> de::SeqAccess<'de> for Items {
    type Error = Error;

    fn next_element_seed<S: DeserializeSeed<'de>>(
        &mut self,
        seed: S,
    ) -> Result<Option<S::Value>, Error> {
        self.0
            .next()
            .map(|item| seed.deserialize(NullAsNan(item)))
            .transpose()
    }

    fn size_hint(&self) -> Option<usize> {
        Some(self.0.len())
    }
}

impl<'de> de::MapAccess<'de> for Fields {
    type Error = Error;

    fn next_key_seed<K: DeserializeSeed<'de>>(
        &mut self,
        seed: K,
    ) -> Result<Option<K::Value>, Error> {
        let Some((key, value)) = self.entries.next() else {
            return Ok(None);
        };
        self.value = Some(value);
        seed.deserialize(IntoDeserializer::<Error>::into_deserializer(key))
            .map(Some)
    }

    fn next_value_seed<S: DeserializeSeed<'de>>(&mut self, seed: S) -> Result<S::Value, Error> {
        let value = self
            .value
            .take()
            .ok_or_else(|| <Error as de::Error>::custom("a value without its key"))?;
        seed.deserialize(NullAsNan(value))
    }
}

impl<'de> de::Deserializer<'de> for NullAsNan {
    type Error = Error;

    fn deserialize_any<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, Error> {
        match self.0 {
            Value::Array(items) => visitor.visit_seq(Items(items.into_iter())),
            Value::Object(map) => visitor.visit_map(Fields {
                entries: map.into_iter(),
                value: None,
            }),
            other => de::Deserializer::deserialize_any(other, visitor),
        }
    }

    fn deserialize_f64<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, Error> {
        match self.0 {
            Value::Null => visitor.visit_f64(f64::NAN),
            other => de::Deserializer::deserialize_f64(other, visitor),
        }
    }

    fn deserialize_f32<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, Error> {
        match self.0 {
            Value::Null => visitor.visit_f32(f32::NAN),
            other => de::Deserializer::deserialize_f32(other, visitor),
        }
    }

    fn deserialize_option<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, Error> {
        match self.0 {
            Value::Null => visitor.visit_none(),
            other => visitor.visit_some(NullAsNan(other)),
        }
    }

    fn deserialize_newtype_struct<V: Visitor<'de>>(
        self,
        _name: &'static str,
        visitor: V,
    ) -> Result<V::Value, Error> {
        visitor.visit_newtype_struct(self)
    }

    fn deserialize_enum<V: Visitor<'de>>(
        self,
        name: &'static str,
        variants: &'static [&'static str],
        visitor: V,
    ) -> Result<V::Value, Error> {
        de::Deserializer::deserialize_enum(self.0, name, variants, visitor)
    }

    serde::forward_to_deserialize_any! {
        bool i8 i16 i32 i64 i128 u8 u16 u32 u64 u128 char str string bytes byte_buf unit
        unit_struct seq tuple tuple_struct map struct identifier ignored_any
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::state_encoding::json_bytes;
    use harvest_ipc::payloads::{OperatorModeState, VacuumState};

    #[test]
    fn a_float_written_as_null_reads_back_as_nan_and_the_rest_as_written() {
        let mut mode = OperatorModeState {
            platform_position_m: [f64::NAN, 0.25],
            last_change_reason: harvest_ipc::FixedString::new("started by test"),
            ..OperatorModeState::default()
        };
        mode.header.publish_ns = 42;
        let bytes = json_bytes(&mode);
        assert!(serde_json::from_slice::<OperatorModeState>(&bytes).is_err());
        let back: OperatorModeState = payload_from_json(&bytes).expect("mode");
        assert!(back.platform_position_m[0].is_nan());
        assert_eq!(back.platform_position_m[1], 0.25);
        assert_eq!(back.header.publish_ns, 42);
        assert_eq!(back.last_change_reason.as_str(), "started by test");
        let vacuum = VacuumState::default();
        assert_eq!(
            payload_from_json::<VacuumState>(&json_bytes(&vacuum)).expect("vacuum"),
            vacuum
        );
        assert!(payload_from_json::<VacuumState>(b"{\"header\": 1}").is_err());
    }
}
