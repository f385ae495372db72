//! The schema of a payload, generated from its type: what a recording stores as MCAP schema
//! data so that another tool can decode the bytes without this code.
//!
//! A type says how the [`crate::codec`] writes it by implementing [`Describe`]: numbers and
//! arrays here, [`crate::FixedString`], [`crate::WireCode`] and [`crate::BoundedVec`] beside
//! their types, structs with `#[derive(Describe)]` (or `#[derive(Payload)]`, which includes it)
//! and enums with `#[derive(WireEnum)]`. The derive reads the field names, field types and doc
//! comments, so a payload is declared once and its schema cannot drift from it.
//!
//! [`schema_text`] renders the whole schema of a payload: type, version, encoding, the rules of
//! the encoding, then the message's fields and every struct and enum it contains, each defined
//! once, in a Rust-like notation:
//!
//! ```text
//! message ArmTarget {
//!   header: Header  # Sequence number, capture and publish stamps ...
//!   arm_id: u8  # The arm the target is for, 1 or 2.
//!   position_in_robot_m: [f64; 3]  # Apple centre in the robot frame, metres ...
//! }
//! struct Header { ... }
//! enum ArmPhase: u8 { 0 = Idle  # ... }
//! ```
//!
//! Everything after ` # ` on a line is the field's documentation; the rest is the layout
//! ([`layout_only`] strips the comments). Type notation: `u8`..`u64`, `i8`..`i64`, `f32`,
//! `f64`; `[T; N]` is N items with no count; `[T; u64 count <= N]` is a u64 count then the
//! items; `[T; meta.point_count <= N]` is as many items as an earlier field says, with no count;
//! `string <= N bytes` is a u64 byte count then UTF-8; a struct name is its fields in order; an
//! enum name is one `u8` code.

use crate::catalogue::{self, Channel, ChannelVisitor};
use crate::codec;
use crate::payload::Payload;

/// How the codec writes a value of a type (see the module docs).
pub trait Describe {
    /// The type's shape, with the names and documentation of its parts.
    fn shape() -> Shape;
}

/// How a value is laid out in the encoding.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Shape {
    /// A fixed-width little-endian number: `u8`..`u64`, `i8`..`i64`, `f32`, `f64` (IEEE-754).
    Number(&'static str),
    /// `len` items one after another, with no count (`[T; N]`).
    Array {
        /// The shape of each item.
        item: Box<Shape>,
        /// The number of items.
        len: usize,
    },
    /// A u64 count, then that many items (at most `max_len`).
    Sequence {
        /// The shape of each item.
        item: Box<Shape>,
        /// The most items a value holds.
        max_len: usize,
    },
    /// As many items as an earlier field of the same message says (at most `max_len`), with no
    /// count of their own.
    Counted {
        /// The shape of each item.
        item: Box<Shape>,
        /// The dotted path of the field holding the count, from the message (`meta.point_count`).
        count_field: &'static str,
        /// The most items a value holds.
        max_len: usize,
    },
    /// A u64 byte count, then UTF-8 (at most `max_bytes` bytes).
    Text {
        /// The most bytes a value holds.
        max_bytes: usize,
    },
    /// One `u8`: the code of an enum.
    Code(EnumShape),
    /// The fields of a struct in declaration order, with no padding.
    Struct(StructShape),
}

/// A struct: its fields in the order they are written.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct StructShape {
    /// The Rust name of the struct (`ArmState`).
    pub name: &'static str,
    /// The first paragraph of its documentation, on one line.
    pub doc: &'static str,
    /// The fields written, in order (a field the codec leaves out is not listed).
    pub fields: Vec<FieldShape>,
}

/// One field of a struct.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct FieldShape {
    /// The field's name.
    pub name: &'static str,
    /// The first paragraph of its documentation, on one line.
    pub doc: &'static str,
    /// How it is written.
    pub shape: Shape,
}

/// An enum carried as its `u8` code.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct EnumShape {
    /// The Rust name of the enum (`ArmPhase`).
    pub name: &'static str,
    /// The first paragraph of its documentation, on one line.
    pub doc: &'static str,
    /// Its values with their codes, in declaration order.
    pub variants: Vec<VariantShape>,
}

/// One value of an enum.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct VariantShape {
    /// The code on the wire.
    pub code: u8,
    /// The variant's name.
    pub name: &'static str,
    /// The first paragraph of its documentation, on one line.
    pub doc: &'static str,
}

macro_rules! describe_numbers {
    ($($ty:ty),* $(,)?) => {
        $(
            impl Describe for $ty {
                fn shape() -> Shape {
                    Shape::Number(stringify!($ty))
                }
            }
        )*
    };
}
describe_numbers!(u8, u16, u32, u64, i8, i16, i32, i64, f32, f64);

impl<T: Describe, const N: usize> Describe for [T; N] {
    fn shape() -> Shape {
        Shape::Array {
            item: Box::new(T::shape()),
            len: N,
        }
    }
}

/// The rules of [`codec::ENCODING`], for a reader of the schema without this code.
pub const ENCODING_RULES: &str = "little-endian; integers and floats fixed width (u8 u16 u32 \
u64 i8 i16 i32 i64, f32 f64 IEEE-754); a struct is its fields in order with no padding; [T; N] is \
N items with no count; [T; u64 count <= N] is a u64 count then the items; [T; FIELD <= N] is as \
many items as the earlier field FIELD of the message says, with no count; string <= N bytes is a \
u64 byte count then UTF-8; an enum is its u8 code";

/// The MCAP schema data of payload `T`: type, version, encoding, its rules, then the layout with
/// every nested struct and enum (see the module docs).
pub fn schema_text<T: Payload>() -> String {
    let mut text = format!(
        "harvest message schema\ntype: {}\nversion: {}\nencoding: {}\nrules: {ENCODING_RULES}\n\
layout:\n",
        T::TYPE_NAME,
        T::VERSION,
        codec::ENCODING,
    );
    render_layout(&T::shape(), &mut text);
    text
}

/// The schema text of the payload of catalogue channel `topic` (`None`: no such channel).
pub fn schema_of_topic(topic: &str) -> Option<String> {
    struct Find<'a> {
        topic: &'a str,
        text: Option<String>,
    }
    impl ChannelVisitor for Find<'_> {
        fn visit<T: Payload>(&mut self, channel: Channel<T>) {
            if channel.spec.topic == self.topic {
                self.text = Some(schema_text::<T>());
            }
        }
    }
    let mut find = Find { topic, text: None };
    catalogue::visit_all(&mut find);
    find.text
}

/// `text` without its documentation: each line up to its first ` # `, trailing space trimmed.
/// Two schemas whose layouts agree decode the same bytes the same way.
pub fn layout_only(text: &str) -> String {
    text.lines()
        .map(|line| line.split_once(" # ").map_or(line, |(layout, _)| layout))
        .map(str::trim_end)
        .collect::<Vec<_>>()
        .join("\n")
}

/// Writes the message (`shape`, a struct) and every struct and enum it contains, each once, in
/// the order they are first used.
fn render_layout(shape: &Shape, out: &mut String) {
    let mut written: Vec<Shape> = Vec::new();
    let mut pending: Vec<Shape> = vec![shape.clone()];
    let mut first = true;
    while !pending.is_empty() {
        let next = pending.remove(0);
        if written.contains(&next) {
            continue;
        }
        match &next {
            Shape::Struct(record) => {
                let keyword = if first { "message" } else { "struct" };
                line(out, &format!("{keyword} {} {{", record.name), record.doc);
                let mut nested = Vec::new();
                for field in &record.fields {
                    let ty = type_expression(&field.shape, &mut nested);
                    line(out, &format!("  {}: {ty}", field.name), field.doc);
                }
                out.push_str("}\n");
                // Depth-first: a struct's parts come right after it.
                pending.splice(0..0, nested);
            }
            Shape::Code(code) => {
                line(out, &format!("enum {}: u8 {{", code.name), code.doc);
                for variant in &code.variants {
                    line(
                        out,
                        &format!("  {} = {}", variant.code, variant.name),
                        variant.doc,
                    );
                }
                out.push_str("}\n");
            }
            // A message is a struct; anything else has no definition of its own.
            _ => {}
        }
        first = false;
        written.push(next);
    }
}

fn line(out: &mut String, layout: &str, doc: &str) {
    out.push_str(layout);
    if !doc.is_empty() {
        out.push_str("  # ");
        out.push_str(doc);
    }
    out.push('\n');
}

/// The notation of `shape` inside a field; the structs and enums it names are appended to
/// `nested` for definition.
fn type_expression(shape: &Shape, nested: &mut Vec<Shape>) -> String {
    match shape {
        Shape::Number(name) => (*name).to_owned(),
        Shape::Array { item, len } => format!("[{}; {len}]", type_expression(item, nested)),
        Shape::Sequence { item, max_len } => {
            format!(
                "[{}; u64 count <= {max_len}]",
                type_expression(item, nested)
            )
        }
        Shape::Counted {
            item,
            count_field,
            max_len,
        } => format!(
            "[{}; {count_field} <= {max_len}]",
            type_expression(item, nested)
        ),
        Shape::Text { max_bytes } => format!("string <= {max_bytes} bytes"),
        Shape::Code(code) => {
            nested.push(shape.clone());
            code.name.to_owned()
        }
        Shape::Struct(record) => {
            nested.push(shape.clone());
            record.name.to_owned()
        }
    }
}

/// Decodes the value of `shape` at the start of `bytes` by the schema alone, as a tool without
/// this code would: its JSON view (structs as objects, enums as their codes, arrays of more than
/// [`EXPANDED_ITEMS`] fixed-width items as `{"items": n, "bytes": b}`) and the bytes it spans.
/// The catalogue's tests check with it that each schema accounts for every byte of an encoded
/// message and reads the values serde wrote.
pub fn decode_json(shape: &Shape, bytes: &[u8]) -> Result<(serde_json::Value, usize), String> {
    let mut numbers = Vec::new();
    decode(shape, bytes, "", &mut numbers)
}

/// Longest array of fixed-width items [`decode_json`] lists item by item.
pub const EXPANDED_ITEMS: usize = 4096;

/// Reads one value; `numbers` collects the integers read, by dotted path, for
/// [`Shape::Counted`] fields.
fn decode(
    shape: &Shape,
    bytes: &[u8],
    path: &str,
    numbers: &mut Vec<(String, u64)>,
) -> Result<(serde_json::Value, usize), String> {
    use serde_json::Value;
    let take = |len: usize| {
        bytes
            .get(..len)
            .ok_or_else(|| format!("{path}: {len} bytes needed, {} left", bytes.len()))
    };
    match shape {
        Shape::Number(name) => {
            let width =
                number_width(name).ok_or_else(|| format!("{path}: unknown number {name}"))?;
            let mut raw = [0u8; 8];
            raw[..width].copy_from_slice(take(width)?);
            let bits = u64::from_le_bytes(raw);
            let value = match *name {
                "f32" => Value::from(f64::from(f32::from_bits(bits as u32))),
                "f64" => Value::from(f64::from_bits(bits)),
                "i8" => Value::from(bits as u8 as i8),
                "i16" => Value::from(bits as u16 as i16),
                "i32" => Value::from(bits as u32 as i32),
                "i64" => Value::from(bits as i64),
                _ => {
                    numbers.push((path.to_owned(), bits));
                    Value::from(bits)
                }
            };
            Ok((value, width))
        }
        Shape::Code(_) => Ok((Value::from(take(1)?[0]), 1)),
        Shape::Array { item, len } => items(item, *len, bytes, path, numbers),
        Shape::Sequence { item, max_len } => {
            let count = read_count(bytes, path, *max_len)?;
            let (value, used) = items(item, count, &bytes[8..], path, numbers)?;
            Ok((value, 8 + used))
        }
        Shape::Text { max_bytes } => {
            let count = read_count(bytes, path, *max_bytes)?;
            let text = std::str::from_utf8(&take(8 + count)?[8..])
                .map_err(|error| format!("{path}: not UTF-8: {error}"))?;
            Ok((Value::from(text), 8 + count))
        }
        Shape::Counted {
            item,
            count_field,
            max_len,
        } => {
            let count = numbers
                .iter()
                .rev()
                .find(|(name, _)| name == count_field)
                .map(|(_, value)| *value)
                .ok_or_else(|| format!("{path}: count field {count_field} not read before"))?;
            let count = usize::try_from(count)
                .ok()
                .filter(|count| count <= max_len)
                .ok_or_else(|| format!("{path}: count {count} over {max_len}"))?;
            items(item, count, bytes, path, numbers)
        }
        Shape::Struct(record) => {
            let mut object = serde_json::Map::new();
            let mut used = 0;
            for field in &record.fields {
                let field_path = if path.is_empty() {
                    field.name.to_owned()
                } else {
                    format!("{path}.{}", field.name)
                };
                let (value, len) = decode(&field.shape, &bytes[used..], &field_path, numbers)?;
                object.insert(field.name.to_owned(), value);
                used += len;
            }
            Ok((Value::Object(object), used))
        }
    }
}

fn items(
    item: &Shape,
    count: usize,
    bytes: &[u8],
    path: &str,
    numbers: &mut Vec<(String, u64)>,
) -> Result<(serde_json::Value, usize), String> {
    // Long runs of fixed-width items (pixels, points) are measured, not listed.
    if let Some(width) = fixed_width(item).filter(|_| count > EXPANDED_ITEMS) {
        let total = width * count;
        if bytes.len() < total {
            return Err(format!(
                "{path}: {total} bytes needed, {} left",
                bytes.len()
            ));
        }
        return Ok((serde_json::json!({ "items": count, "bytes": total }), total));
    }
    let mut values = Vec::with_capacity(count.min(EXPANDED_ITEMS));
    let mut used = 0;
    for index in 0..count {
        let item_path = format!("{path}[{index}]");
        let (value, len) = decode(item, &bytes[used..], &item_path, numbers)?;
        values.push(value);
        used += len;
    }
    Ok((serde_json::Value::Array(values), used))
}

fn read_count(bytes: &[u8], path: &str, max: usize) -> Result<usize, String> {
    let raw: [u8; 8] = bytes
        .get(..8)
        .and_then(|head| head.try_into().ok())
        .ok_or_else(|| format!("{path}: no u64 count"))?;
    let count = u64::from_le_bytes(raw);
    usize::try_from(count)
        .ok()
        .filter(|count| *count <= max)
        .ok_or_else(|| format!("{path}: count {count} over {max}"))
}

fn number_width(name: &str) -> Option<usize> {
    match name {
        "u8" | "i8" => Some(1),
        "u16" | "i16" => Some(2),
        "u32" | "i32" | "f32" => Some(4),
        "u64" | "i64" | "f64" => Some(8),
        _ => None,
    }
}

/// Encoded bytes of every value of `shape`, when that is fixed and no count depends on it.
fn fixed_width(shape: &Shape) -> Option<usize> {
    match shape {
        Shape::Number(name) => number_width(name),
        Shape::Code(_) => Some(1),
        Shape::Array { item, len } => fixed_width(item).map(|width| width * len),
        Shape::Struct(record) => record
            .fields
            .iter()
            .map(|field| fixed_width(&field.shape))
            .sum(),
        Shape::Sequence { .. } | Shape::Counted { .. } | Shape::Text { .. } => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn notation_of_the_shapes() {
        let mut nested = Vec::new();
        let array = <[[f64; 3]; 2]>::shape();
        assert_eq!(type_expression(&array, &mut nested), "[[f64; 3]; 2]");
        let sequence = Shape::Sequence {
            item: Box::new(Shape::Number("u32")),
            max_len: 4,
        };
        assert_eq!(
            type_expression(&sequence, &mut nested),
            "[u32; u64 count <= 4]"
        );
        assert_eq!(
            type_expression(&Shape::Text { max_bytes: 64 }, &mut nested),
            "string <= 64 bytes"
        );
        assert!(nested.is_empty());
    }

    #[test]
    fn layout_only_drops_the_documentation() {
        assert_eq!(
            layout_only("message A {  # An a.\n  x: u8  # The x # really.\n}\n"),
            "message A {\n  x: u8\n}"
        );
    }

    #[test]
    fn decoding_by_the_schema_follows_counts_and_rejects_short_input() {
        let shape = Shape::Struct(StructShape {
            name: "S",
            doc: "",
            fields: vec![
                FieldShape {
                    name: "n",
                    doc: "",
                    shape: Shape::Number("u32"),
                },
                FieldShape {
                    name: "text",
                    doc: "",
                    shape: Shape::Text { max_bytes: 8 },
                },
                FieldShape {
                    name: "items",
                    doc: "",
                    shape: Shape::Counted {
                        item: Box::new(Shape::Number("u16")),
                        count_field: "n",
                        max_len: 4,
                    },
                },
            ],
        });
        let mut bytes = 2u32.to_le_bytes().to_vec();
        bytes.extend_from_slice(&3u64.to_le_bytes());
        bytes.extend_from_slice(b"abc");
        bytes.extend_from_slice(&[1, 0, 2, 0]);
        assert_eq!(
            decode_json(&shape, &bytes),
            Ok((
                serde_json::json!({ "n": 2, "text": "abc", "items": [1, 2] }),
                bytes.len()
            ))
        );
        assert!(decode_json(&shape, &bytes[..bytes.len() - 1]).is_err());
        bytes[0] = 5;
        assert!(
            decode_json(&shape, &bytes).is_err(),
            "count over the maximum"
        );
    }
}
