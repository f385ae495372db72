//! How a catalogue channel is described in an MCAP file.
//!
//! - Schema name: `<TYPE_NAME>.v<VERSION>`, e.g. `harvest.RgbdFrame.v1`: a reader knows both the
//!   type and the layout version without decoding anything.
//! - Schema encoding and channel message encoding: [`harvest_ipc::codec::ENCODING`] (`bincode2-fixint-le`).
//! - Schema data: UTF-8 text generated from the payload type
//!   ([`harvest_ipc::schema::schema_text`]): type, version, encoding and its rules, then every
//!   field, nested struct and enum code with its documentation, so another tool can decode the
//!   bytes. Readers go by the schema name; the text is for people and other tools (recordings
//!   made before it was generated carry a hand-written text under the same names).
//! - Channel metadata: `type_name`, `version`, `layer`, `description`.

use harvest_ipc::catalogue::{self, ChannelSpec, Layer};
use harvest_ipc::{Channel, ChannelVisitor, Payload, schema};
use std::collections::BTreeMap;

/// A catalogue channel as the recording tools see it: its spec plus its payload's schema.
#[derive(Debug, Clone, Copy)]
pub struct TopicInfo {
    pub spec: ChannelSpec,
    /// [`harvest_ipc::schema::schema_text`] of the channel's payload type.
    pub schema_text: fn() -> String,
    /// Size of the payload type in memory, bytes.
    pub payload_bytes: usize,
}

impl TopicInfo {
    pub fn of<T: Payload>(channel: Channel<T>) -> Self {
        Self {
            spec: channel.spec,
            schema_text: schema::schema_text::<T>,
            payload_bytes: std::mem::size_of::<T>(),
        }
    }

    /// A bound on one encoded message of this channel: the fixed-size payload in memory plus
    /// room for the encoding's length prefixes.
    pub fn max_encoded_bytes(&self) -> usize {
        self.payload_bytes + 4096
    }

    /// The bound of [`Self::max_encoded_bytes`] over `topics` (0 for none): the largest
    /// message a recording of them can hold.
    pub fn largest_encoded_bytes(topics: &[TopicInfo]) -> usize {
        topics
            .iter()
            .map(TopicInfo::max_encoded_bytes)
            .max()
            .unwrap_or(0)
    }

    /// The MCAP schema name of this channel's payload.
    pub fn schema_name(&self) -> String {
        schema_name(self.spec.type_name, self.spec.version)
    }

    /// The MCAP schema data of this channel's payload (see the module docs).
    pub fn schema_data(&self) -> String {
        (self.schema_text)()
    }

    /// The MCAP channel metadata of this channel.
    pub fn channel_metadata(&self) -> BTreeMap<String, String> {
        BTreeMap::from([
            ("type_name".to_owned(), self.spec.type_name.to_owned()),
            ("version".to_owned(), self.spec.version.to_string()),
            ("layer".to_owned(), layer_name(self.spec.layer).to_owned()),
            ("description".to_owned(), self.spec.description.to_owned()),
        ])
    }
}

/// `harvest.RgbdFrame` version 1 -> `harvest.RgbdFrame.v1` (the convention is
/// [`harvest_ipc::payload::schema_name`], shared with the iceoryx2 type names).
pub fn schema_name(type_name: &str, version: u32) -> String {
    harvest_ipc::payload::schema_name(type_name, version)
}

/// `harvest.RgbdFrame.v1` -> (`harvest.RgbdFrame`, 1); `None` for a name of another form.
pub fn parse_schema_name(name: &str) -> Option<(&str, u32)> {
    let (type_name, version) = name.rsplit_once(".v")?;
    let version = version.parse().ok()?;
    (!type_name.is_empty()).then_some((type_name, version))
}

/// Lower-case layer name used on the command line and in channel metadata.
pub fn layer_name(layer: Layer) -> &'static str {
    match layer {
        Layer::Stack => "stack",
        Layer::Hardware => "hardware",
        Layer::Evaluation => "evaluation",
    }
}

/// Every catalogue channel, in catalogue order.
pub fn catalogue_topics() -> Vec<TopicInfo> {
    struct Collect(Vec<TopicInfo>);
    impl ChannelVisitor for Collect {
        fn visit<T: Payload>(&mut self, channel: Channel<T>) {
            self.0.push(TopicInfo::of(channel));
        }
    }
    let mut collect = Collect(Vec::new());
    catalogue::visit_all(&mut collect);
    collect.0
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn schema_names_round_trip() {
        assert_eq!(schema_name("harvest.RgbdFrame", 1), "harvest.RgbdFrame.v1");
        assert_eq!(
            parse_schema_name("harvest.RgbdFrame.v12"),
            Some(("harvest.RgbdFrame", 12))
        );
        assert_eq!(parse_schema_name("harvest.RgbdFrame"), None);
        assert_eq!(parse_schema_name(".v1"), None);
        assert_eq!(parse_schema_name("foxglove.RawImage"), None);
    }

    #[test]
    fn every_catalogue_channel_has_a_described_schema() {
        let topics = catalogue_topics();
        assert_eq!(topics.len(), catalogue::all_specs().len());
        for topic in &topics {
            let data = topic.schema_data();
            assert!(data.contains(harvest_ipc::codec::ENCODING));
            assert!(data.contains(&format!("type: {}\n", topic.spec.type_name)));
            let name = topic.schema_name();
            assert_eq!(
                parse_schema_name(&name),
                Some((topic.spec.type_name, topic.spec.version))
            );
        }
    }
}
