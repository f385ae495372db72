//! Any datagram on the Livox driver's command, discovery or data port, through the control
//! frame, command payload and point packet decoders, as the driver and the fake device read them.
#![no_main]

use harvest_hw::lidar::livox::command::{Broadcast, HeartbeatAck, HostCommand};
use harvest_hw::lidar::livox::frame::decode_frame;
use harvest_hw::lidar::livox::point_packet::decode_point_packet;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(frame) = decode_frame(data) {
        let _ = HostCommand::decode(frame.cmd_set, frame.cmd_id, frame.payload);
        let _ = Broadcast::decode(frame.payload).map(|b| b.code.as_string());
        let _ = HeartbeatAck::decode(frame.payload);
    }
    if let Ok(packet) = decode_point_packet(data) {
        let _ = packet.header.first_firing_ns();
        assert_eq!(
            packet.returns().count(),
            packet.header.data_type.firings() * packet.header.data_type.returns_per_firing()
        );
    }
});
