//! The shared memory of the frame channel, measured where iceoryx2 puts it: a publisher of
//! `camera/rgbd`'s payload with today's QoS ([`Qos::FRAMES`]: 8 subscribers, buffer 3) holds no
//! more of `/dev/shm` than with the earlier one (4 subscribers, buffer 8), and both agree with
//! [`Qos::data_segment_samples`] x the payload size. Prints both sizes.

use harvest_ipc::catalogue::{CAMERA_RGBD, Channel, Qos};
use harvest_ipc::payloads::RgbdFrame;
use harvest_ipc::{Context, ScratchDomain};

/// Bytes of the largest `.data` file of `domain` in /dev/shm: the publisher's data segment (the
/// only large one in a domain with a single frame publisher).
fn largest_segment_bytes(domain: &ScratchDomain) -> u64 {
    let prefix = format!("hv_{}_", domain.name());
    std::fs::read_dir("/dev/shm")
        .expect("/dev/shm")
        .flatten()
        .filter(|entry| {
            let name = entry.file_name().to_string_lossy().into_owned();
            name.starts_with(&prefix) && name.ends_with(".data")
        })
        .map(|entry| entry.metadata().expect("metadata").len())
        .max()
        .unwrap_or(0)
}

fn segment_with(qos: Qos, tag: &str) -> u64 {
    let domain = ScratchDomain::new(tag);
    let context = Context::new(&domain, "segment-test").expect("context");
    let channel = Channel::<RgbdFrame>::ad_hoc("test/frames", qos);
    let publisher = context.publisher(channel).expect("publisher");
    let bytes = largest_segment_bytes(&domain);
    drop(publisher);
    bytes
}

#[test]
fn the_frame_channel_holds_no_more_shared_memory_than_with_four_readers() {
    let earlier = Qos {
        subscriber_max_buffer_size: 8,
        max_subscribers: 4,
        max_nodes: 8,
        ..Qos::FRAMES
    };
    let now = CAMERA_RGBD.spec.qos;
    assert!(now.max_subscribers >= 8);
    let frame = std::mem::size_of::<RgbdFrame>() as u64;
    let before = segment_with(earlier, "segold");
    let after = segment_with(now, "segnew");
    println!(
        "camera/rgbd data segment: before {before} B ({} subscribers x buffer {}: {} frames), \
         after {after} B ({} subscribers x buffer {}: {} frames), frame {frame} B",
        earlier.max_subscribers,
        earlier.subscriber_max_buffer_size,
        earlier.data_segment_samples(),
        now.max_subscribers,
        now.subscriber_max_buffer_size,
        now.data_segment_samples(),
    );
    assert!(after <= before, "before {before} B, after {after} B");
    for (qos, bytes) in [(earlier, before), (now, after)] {
        let expected = qos.data_segment_samples() as u64 * frame;
        // iceoryx2 adds a little management data (and alignment) to the samples.
        assert!(
            bytes >= expected && bytes < expected + frame / 10,
            "{bytes} B for {} samples of {frame} B",
            qos.data_segment_samples()
        );
    }
}
