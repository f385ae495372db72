//! For every catalogue channel, the names a payload is known by agree: the channel spec's type
//! name and version, the payload type's `TYPE_NAME`/`VERSION`, its iceoryx2 type name and the
//! MCAP schema name the recorder stores (`schema_name(TYPE_NAME, VERSION)`), and the codec
//! round-trips a value of the type. The schema texts themselves are compared whole in
//! `payload_schemas.rs`.

use harvest_ipc::catalogue::{ChannelVisitor, all_specs, visit_all};
use harvest_ipc::payload::{boxed_zeroed, schema_name};
use harvest_ipc::{Channel, Payload};
use iceoryx2::prelude::ZeroCopySend;
use std::collections::BTreeMap;

#[derive(Default)]
struct Agreement {
    /// TYPE_NAME -> (Rust type, schema name) of the first channel seen with it.
    types: BTreeMap<&'static str, (&'static str, String)>,
    channels: usize,
}

impl ChannelVisitor for Agreement {
    fn visit<T: Payload>(&mut self, channel: Channel<T>) {
        let spec = channel.spec;
        let topic = spec.topic;
        self.channels += 1;
        assert_eq!(spec.type_name, T::TYPE_NAME, "{topic}: spec type name");
        assert_eq!(spec.version, T::VERSION, "{topic}: spec version");

        let schema = schema_name(T::TYPE_NAME, T::VERSION);
        // SAFETY: reading the type name has no precondition; `unsafe` marks that implementing
        // it wrongly breaks iceoryx2's type check.
        let iceoryx2_name = unsafe { <T as ZeroCopySend>::type_name() };
        assert_eq!(
            iceoryx2_name, schema,
            "{topic}: #[type_name] must be TYPE_NAME.vVERSION (bump it with VERSION)"
        );

        let rust_type = std::any::type_name::<T>();
        let entry = self
            .types
            .entry(T::TYPE_NAME)
            .or_insert((rust_type, schema.clone()));
        assert_eq!(
            *entry,
            (rust_type, schema),
            "{topic}: TYPE_NAME {} is used by two payload types",
            T::TYPE_NAME
        );

        // What the recorder writes decodes into what was recorded.
        let mut value: Box<T> = boxed_zeroed();
        value.header_mut().msg_seq = 7;
        let mut bytes = Vec::new();
        value.encode(&mut bytes).expect("encode");
        let mut back: Box<T> = boxed_zeroed();
        T::decode_into(&bytes, &mut back).expect("decode");
        let mut again = Vec::new();
        back.encode(&mut again).expect("re-encode");
        assert!(bytes == again, "{topic}: the codec does not round-trip");
        assert_eq!(back.header().msg_seq, 7, "{topic}");
    }
}

#[test]
fn type_names_versions_and_schemas_agree_for_every_channel() {
    let mut agreement = Agreement::default();
    visit_all(&mut agreement);
    assert_eq!(agreement.channels, all_specs().len());
    assert!(agreement.types.contains_key("harvest.RgbdFrame"));
}
