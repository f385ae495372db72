//! iceoryx2 failures reach callers as typed [`OpenChannelError`]/[`SendError`] variants, chosen
//! from iceoryx2's error enums. Real shared memory, a private domain per test.

use harvest_ipc::catalogue::{Channel, Qos};
use harvest_ipc::error::{Incompatibility, OpenChannelError, PortKind, SendError};
use harvest_ipc::payloads::{EmergencyStop, ProcessHealth};
use harvest_ipc::{Context, Payload, ScratchDomain};

#[test]
fn a_channel_of_another_payload_type_is_incompatible() {
    let domain = ScratchDomain::new("incompat");
    let context = Context::new(&domain, "incompatible-test").expect("context");
    let stops = Channel::<EmergencyStop>::ad_hoc("test/incompatible", Qos::SMALL);
    let _stop_publisher = context
        .publisher(stops)
        .expect("first type creates the service");

    let health = Channel::<ProcessHealth>::ad_hoc("test/incompatible", Qos::SMALL);
    let error = context
        .subscriber(health)
        .err()
        .expect("another type on the same topic");
    match &error {
        OpenChannelError::Incompatible {
            topic,
            type_name,
            version,
            domain: error_domain,
            mismatch,
        } => {
            assert_eq!(*topic, "test/incompatible");
            assert_eq!(*type_name, ProcessHealth::TYPE_NAME);
            assert_eq!(*version, ProcessHealth::VERSION);
            assert_eq!(error_domain, domain.name());
            assert_eq!(*mismatch, Incompatibility::PayloadType);
        }
        other => panic!("expected Incompatible, got {other:?}"),
    }
    let message = error.to_string();
    let expected_type = format!("{} v{}", ProcessHealth::TYPE_NAME, ProcessHealth::VERSION);
    for part in [
        "test/incompatible",
        expected_type.as_str(),
        "another payload type",
        domain.name(),
    ] {
        assert!(message.contains(part), "{part:?} missing from: {message}");
    }
}

#[test]
fn more_publishers_than_the_qos_allows_reach_the_port_limit() {
    let domain = ScratchDomain::new("publimit");
    let context = Context::new(&domain, "port-limit-test").expect("context");
    let qos = Qos {
        max_publishers: 2,
        ..Qos::SMALL
    };
    let channel = Channel::<EmergencyStop>::ad_hoc("test/port_limit", qos);
    let _first = context.publisher(channel).expect("first publisher");
    let _second = context.publisher(channel).expect("second publisher");
    let error = context
        .publisher(channel)
        .err()
        .expect("a third publisher exceeds max_publishers 2");
    match error {
        OpenChannelError::PortLimit { topic, port, limit } => {
            assert_eq!(topic, "test/port_limit");
            assert_eq!(port, PortKind::Publisher);
            assert_eq!(limit, 2);
        }
        other => panic!("expected PortLimit, got {other:?}"),
    }
}

#[test]
fn more_subscribers_than_the_qos_allows_reach_the_port_limit() {
    let domain = ScratchDomain::new("sublimit");
    let context = Context::new(&domain, "sub-limit-test").expect("context");
    let qos = Qos {
        max_subscribers: 1,
        ..Qos::SMALL
    };
    let channel = Channel::<EmergencyStop>::ad_hoc("test/sub_limit", qos);
    let _first = context.subscriber(channel).expect("first subscriber");
    match context.subscriber(channel).err() {
        Some(OpenChannelError::PortLimit { port, limit, .. }) => {
            assert_eq!((port, limit), (PortKind::Subscriber, 1));
        }
        other => panic!("expected PortLimit, got {other:?}"),
    }
}

#[test]
fn loaning_past_max_loans_exhausts_the_loans() {
    let domain = ScratchDomain::new("loans");
    let context = Context::new(&domain, "loan-test").expect("context");
    let channel = Channel::<EmergencyStop>::ad_hoc("test/loans", Qos::SMALL);
    let publisher = context.publisher(channel).expect("publisher");
    let held: Vec<_> = (0..Qos::SMALL.max_loans)
        .map(|_| publisher.loan().expect("within max_loans"))
        .collect();
    match publisher.loan().err() {
        Some(SendError::LoansExhausted { topic, max_loans }) => {
            assert_eq!(topic, "test/loans");
            assert_eq!(max_loans, Qos::SMALL.max_loans);
        }
        other => panic!("expected LoansExhausted, got {other:?}"),
    }
    drop(held);
    assert!(publisher.loan().is_ok());
}
