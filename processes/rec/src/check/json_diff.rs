//! The first difference between two JSON views of a message: the field's path
//! (`apples[2].position_in_camera_m[0]`) and both values.

use serde_json::Value;

/// Where two messages differ first (fields in the order their JSON view lists them).
#[derive(Debug, Clone, PartialEq)]
pub struct FieldDifference {
    /// The field's path from the message's root.
    pub field: String,
    pub recorded: Value,
    pub rerun: Value,
}

/// Header fields the publisher sets, not the node's decisions: never compared.
pub const PUBLISHER_STAMPS: [&str; 2] = ["header.msg_seq", "header.publish_ns"];

/// What stands for a whole message's path in a [`FieldDifference`].
const WHOLE_MESSAGE: &str = "(the message)";

impl FieldDifference {
    /// A difference of the whole message (one side missing).
    pub fn whole_message(recorded: Value, rerun: Value) -> Self {
        Self {
            field: WHOLE_MESSAGE.to_owned(),
            recorded,
            rerun,
        }
    }
}

/// The first field where `recorded` and `rerun` differ, leaving out the fields `ignored` names
/// (paths from the root, e.g. `header.publish_ns`). Numbers within `tolerance` (absolute) are
/// equal; `None` compares them exactly.
pub fn first_difference(
    recorded: &Value,
    rerun: &Value,
    ignored: &[&str],
    tolerance: Option<f64>,
) -> Option<FieldDifference> {
    let mut path = String::new();
    walk(recorded, rerun, &mut path, ignored, tolerance)
}

fn walk(
    recorded: &Value,
    rerun: &Value,
    path: &mut String,
    ignored: &[&str],
    tolerance: Option<f64>,
) -> Option<FieldDifference> {
    if ignored.contains(&path.as_str()) {
        return None;
    }
    let differs = |path: &str| FieldDifference {
        field: if path.is_empty() {
            WHOLE_MESSAGE.to_owned()
        } else {
            path.to_owned()
        },
        recorded: recorded.clone(),
        rerun: rerun.clone(),
    };
    match (recorded, rerun) {
        (Value::Object(left), Value::Object(right)) => {
            for (key, left_value) in left {
                let Some(right_value) = right.get(key) else {
                    return Some(differs(path));
                };
                let length = path.len();
                if !path.is_empty() {
                    path.push('.');
                }
                path.push_str(key);
                let found = walk(left_value, right_value, path, ignored, tolerance);
                path.truncate(length);
                if found.is_some() {
                    return found;
                }
            }
            right
                .keys()
                .any(|key| !left.contains_key(key))
                .then(|| differs(path))
        }
        (Value::Array(left), Value::Array(right)) => {
            for (index, (left_value, right_value)) in left.iter().zip(right).enumerate() {
                let length = path.len();
                path.push_str(&format!("[{index}]"));
                let found = walk(left_value, right_value, path, ignored, tolerance);
                path.truncate(length);
                if found.is_some() {
                    return found;
                }
            }
            if left.len() != right.len() {
                path.push_str(".len");
                let found = FieldDifference {
                    field: path.clone(),
                    recorded: Value::from(left.len()),
                    rerun: Value::from(right.len()),
                };
                return Some(found);
            }
            None
        }
        (Value::Number(left), Value::Number(right)) => {
            let equal = match (tolerance, left.as_f64(), right.as_f64()) {
                (Some(tolerance), Some(a), Some(b)) if left.is_f64() || right.is_f64() => {
                    (a - b).abs() <= tolerance
                }
                _ => left == right,
            };
            (!equal).then(|| differs(path))
        }
        _ => (recorded != rerun).then(|| differs(path)),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    #[test]
    fn the_first_differing_field_is_named_with_its_path() {
        let recorded = json!({"header": {"msg_seq": 1, "capture_ns": 5},
            "apples": [{"id": 1, "p": [0.5, 1.0]}, {"id": 2, "p": [0.25, 2.0]}]});
        let rerun = json!({"header": {"msg_seq": 9, "capture_ns": 5},
            "apples": [{"id": 1, "p": [0.5, 1.0]}, {"id": 2, "p": [0.25, 2.5]}]});
        let found =
            first_difference(&recorded, &rerun, &["header.msg_seq"], None).expect("a difference");
        assert_eq!(found.field, "apples[1].p[1]");
        assert_eq!(found.recorded, json!(2.0));
        assert_eq!(found.rerun, json!(2.5));
        assert_eq!(first_difference(&recorded, &recorded, &[], None), None);
    }

    #[test]
    fn ignored_fields_and_the_tolerance_hide_differences() {
        let recorded = json!({"header": {"msg_seq": 1}, "x": 1.0, "n": 3});
        let rerun = json!({"header": {"msg_seq": 2}, "x": 1.000_000_1, "n": 3});
        assert_eq!(
            first_difference(&recorded, &rerun, &["header.msg_seq"], Some(1e-6)),
            None
        );
        let exact = first_difference(&recorded, &rerun, &["header.msg_seq"], None)
            .expect("exact comparison sees the float");
        assert_eq!(exact.field, "x");
        // The tolerance is for floats: integers stay exact.
        let counts = json!({"n": 4});
        let found = first_difference(&json!({"n": 3}), &counts, &[], Some(10.0))
            .expect("integers compared exactly");
        assert_eq!(found.field, "n");
    }

    #[test]
    fn arrays_of_different_lengths_differ_in_their_length() {
        let found = first_difference(&json!({"a": [1, 2]}), &json!({"a": [1, 2, 3]}), &[], None)
            .expect("a difference");
        assert_eq!(found.field, "a.len");
        assert_eq!((found.recorded, found.rerun), (json!(2), json!(3)));
    }
}
