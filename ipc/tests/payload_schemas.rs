//! Every catalogue payload's schema, generated from its type, compared whole with the reviewed
//! copy in `ipc/tests/schemas/<schema name>.txt`, so that a change to a payload shows as a diff
//! of that file; and each schema decodes what the codec writes, byte for byte.
//!
//! After changing a payload (or its doc comments), write the new texts and review their diff:
//!
//! ```text
//! HARVEST_BLESS_SCHEMAS=1 cargo test --release -p harvest-ipc --test payload_schemas
//! git diff ipc/tests/schemas
//! ```
//!
//! Blessing never accepts a new layout under an old version: when the layout (the text without
//! its ` # ` comments) of `harvest.X.vN` differs from the reviewed one, raise the version in
//! `#[type_name("harvest.X.vN+1")]`; the old file then goes (readers of older recordings
//! recognise the old name).

use harvest_ipc::catalogue::{ChannelVisitor, visit_all};
use harvest_ipc::payload::{boxed_zeroed, schema_name};
use harvest_ipc::schema::{decode_json, layout_only, schema_text};
use harvest_ipc::{Channel, Payload};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

const BLESS: &str = "HARVEST_BLESS_SCHEMAS";

fn schemas_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/schemas")
}

/// Schema name -> generated text, for every payload type of the catalogue.
#[derive(Default)]
struct Generated(BTreeMap<String, String>);

impl ChannelVisitor for Generated {
    fn visit<T: Payload>(&mut self, _channel: Channel<T>) {
        self.0
            .insert(schema_name(T::TYPE_NAME, T::VERSION), schema_text::<T>());
    }
}

#[test]
fn every_schema_matches_its_reviewed_text() {
    let mut generated = Generated::default();
    visit_all(&mut generated);
    let bless = std::env::var_os(BLESS).is_some();
    let dir = schemas_dir();
    let mut problems = Vec::new();
    for (name, text) in &generated.0 {
        let path = dir.join(format!("{name}.txt"));
        match std::fs::read_to_string(&path) {
            Ok(reviewed) if reviewed == *text => {}
            Ok(reviewed) if layout_only(&reviewed) != layout_only(text) => problems.push(format!(
                "{name}: the layout changed under the same version; raise the version in \
#[type_name(..)] (blessing does not overwrite a layout)\n--- reviewed\n{reviewed}\n+++ generated\n{text}"
            )),
            Ok(_) if bless => {
                std::fs::write(&path, text).expect("write schema");
            }
            Ok(reviewed) => problems.push(format!(
                "{name}: the documentation in the schema changed; review and run with {BLESS}=1\n\
--- reviewed\n{reviewed}\n+++ generated\n{text}"
            )),
            Err(_) if bless => {
                std::fs::create_dir_all(&dir).expect("schema dir");
                std::fs::write(&path, text).expect("write schema");
            }
            Err(_) => problems.push(format!(
                "{name}: no reviewed schema at {}; run with {BLESS}=1 and review it\n{text}",
                path.display()
            )),
        }
    }
    for entry in std::fs::read_dir(&dir).expect("schema dir") {
        let path = entry.expect("entry").path();
        let name = path
            .file_name()
            .and_then(|name| name.to_str())
            .and_then(|name| name.strip_suffix(".txt"))
            .unwrap_or_default()
            .to_owned();
        if generated.0.contains_key(&name) {
            continue;
        }
        if bless {
            std::fs::remove_file(&path).expect("remove stale schema");
        } else {
            problems.push(format!(
                "{}: no catalogue payload has this schema any more; run with {BLESS}=1",
                path.display()
            ));
        }
    }
    assert!(problems.is_empty(), "{}", problems.join("\n\n"));
}

/// Fills `value` with bytes of a simple generator: every bit pattern is a valid payload.
fn fill<T: Payload>(value: &mut T, seed: u64) {
    let mut state = seed | 1;
    // SAFETY: `T: AnyBitPattern`: any bytes are a valid `T`; the slice covers exactly the value.
    let bytes = unsafe {
        std::slice::from_raw_parts_mut((value as *mut T).cast::<u8>(), std::mem::size_of::<T>())
    };
    for byte in bytes {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        // Mostly small values, so counts and lengths are often in range.
        *byte = if state.is_multiple_of(4) {
            (state >> 32) as u8
        } else {
            (state >> 40) as u8 % 4
        };
    }
}

/// Decodes what the codec wrote with the schema alone and checks that it spans every byte and
/// reads the values the payload's own decoder reads.
struct DecodeBySchema {
    checked: usize,
}

impl ChannelVisitor for DecodeBySchema {
    fn visit<T: Payload>(&mut self, channel: Channel<T>) {
        let topic = channel.spec.topic;
        for seed in [0, 1, 2, 0x9e37_79b9_7f4a_7c15] {
            let mut value: Box<T> = boxed_zeroed();
            if seed != 0 {
                fill(&mut *value, seed);
            }
            let mut bytes = Vec::new();
            value.encode(&mut bytes).expect("encode");
            let (by_schema, used) = decode_json(&T::shape(), &bytes)
                .unwrap_or_else(|error| panic!("{topic} (seed {seed}): {error}"));
            assert_eq!(used, bytes.len(), "{topic} (seed {seed}): bytes left over");

            let mut back: Box<T> = boxed_zeroed();
            T::decode_into(&bytes, &mut back).expect("decode");
            let by_codec = back.to_json();
            let (Some(by_schema), Some(by_codec)) = (by_schema.as_object(), by_codec.as_object())
            else {
                panic!("{topic}: a message decodes to an object");
            };
            // Serde payloads: every field. Hand-coded frames summarize their buffers in
            // `to_json`: the fields both show.
            let mut common = 0;
            for (key, value) in by_schema {
                if let Some(expected) = by_codec.get(key) {
                    assert_eq!(value, expected, "{topic} (seed {seed}): field {key}");
                    common += 1;
                }
            }
            assert!(
                by_codec.contains_key("header") && common >= 2,
                "{topic}: the schema names the fields the codec writes ({common} in common)"
            );
        }
        self.checked += 1;
    }
}

#[test]
fn every_schema_decodes_what_the_codec_writes() {
    let mut check = DecodeBySchema { checked: 0 };
    visit_all(&mut check);
    assert!(check.checked > 30);
}
