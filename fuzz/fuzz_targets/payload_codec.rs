//! Any bytes as a recorded message of any catalogue schema (the first byte picks the schema),
//! through the payload decoder `rec cat`, `rec export`, replay and the monitor use, then the
//! JSON view of what decoded.
#![no_main]

use harvest_recording::payload_codec::{SchemaMatch, json_decoder};
use harvest_recording::schema::catalogue_topics;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Some((&pick, bytes)) = data.split_first() else {
        return;
    };
    let topics = catalogue_topics();
    let topic = topics[usize::from(pick) % topics.len()];
    let SchemaMatch::Known(mut decoder) = json_decoder(&topic.schema_name()) else {
        panic!("{} has no decoder", topic.schema_name());
    };
    if let Ok(value) = decoder.to_json(bytes) {
        let _ = value.to_string();
    }
});
