//! JSON Schema for the JSON view of a payload, inferred from one message's `to_json` output
//! (every message of a type has the same shape), for exports read by Foxglove.

use serde_json::{Map, Value, json};

/// The JSON Schema describing values shaped like `value`, titled `title`.
pub fn infer_schema(title: &str, value: &Value) -> Value {
    let mut schema = infer(value);
    if let Value::Object(map) = &mut schema {
        map.insert("title".to_owned(), Value::String(title.to_owned()));
    }
    schema
}

fn infer(value: &Value) -> Value {
    match value {
        Value::Null => json!({}),
        Value::Bool(_) => json!({ "type": "boolean" }),
        Value::Number(number) if number.is_f64() => json!({ "type": "number" }),
        Value::Number(_) => json!({ "type": "integer" }),
        Value::String(_) => json!({ "type": "string" }),
        Value::Array(items) => {
            json!({ "type": "array", "items": items.first().map(infer).unwrap_or_else(|| json!({})) })
        }
        Value::Object(fields) => {
            let properties: Map<String, Value> = fields
                .iter()
                .map(|(key, field)| (key.clone(), infer(field)))
                .collect();
            json!({ "type": "object", "properties": properties })
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn infers_nested_shapes() {
        let value =
            json!({ "a": 1, "b": 1.5, "c": [ { "d": "x" } ], "e": [], "f": true, "g": null });
        let schema = infer_schema("T", &value);
        assert_eq!(schema["title"], "T");
        assert_eq!(schema["type"], "object");
        assert_eq!(schema["properties"]["a"]["type"], "integer");
        assert_eq!(schema["properties"]["b"]["type"], "number");
        assert_eq!(
            schema["properties"]["c"]["items"]["properties"]["d"]["type"],
            "string"
        );
        assert_eq!(schema["properties"]["e"]["items"], json!({}));
        assert_eq!(schema["properties"]["f"]["type"], "boolean");
        assert_eq!(schema["properties"]["g"], json!({}));
    }
}
