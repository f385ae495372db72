//! The Livox control frame's checksums against an independent implementation: Python's
//! `crcmod` (installed here with pip when missing, as `.ci/run` does), configured from the
//! SDK's definitions (`FastCRCsw.cpp`: CRC-16/MCRF4XX from seed 0x4c49; CRC-32 with the register
//! started at `seed ^ 0xFFFFFFFF` for seed 0x564f580a, which is crcmod's `initCrc = seed` with
//! `xorOut = 0xFFFFFFFF`).

use harvest_hw::lidar::livox::command::{
    CMD_CONTROL_SAMPLE, CMD_HANDSHAKE, CMD_HEARTBEAT, Handshake, HeartbeatAck,
};
use harvest_hw::lidar::livox::frame::{Frame, PacketType, encode_frame};
use harvest_test_support::python::ensure_python;
use std::io::Write;
use std::net::Ipv4Addr;
use std::process::{Command, Stdio};

const SCRIPT: &str = r#"
import sys, crcmod
crc16 = crcmod.mkCrcFun(0x11021, initCrc=0x4c49, rev=True, xorOut=0)
crc32 = crcmod.mkCrcFun(0x104C11DB7, initCrc=0x564f580a, rev=True, xorOut=0xFFFFFFFF)
checked = 0
for line in sys.stdin:
    frame = bytes.fromhex(line.strip())
    if not frame:
        continue
    assert crc16(frame[:7]) == int.from_bytes(frame[7:9], "little"), line
    assert crc32(frame[:-4]) == int.from_bytes(frame[-4:], "little"), line
    checked += 1
print(checked)
"#;

#[test]
fn frame_checksums_match_crcmod() {
    ensure_python("crcmod", &["crcmod"]);
    let handshake = Handshake {
        host_ip: Ipv4Addr::new(192, 168, 1, 50),
        data_port: 56001,
        cmd_port: 55501,
        sensor_port: 56001,
    }
    .encode();
    let ack = HeartbeatAck {
        ret_code: 0,
        state: 1,
        feature: 0,
        status_code: 0x4000_2040,
    }
    .encode();
    let long: Vec<u8> = (0..1000u32).map(|k| (k * 37 % 251) as u8).collect();
    let cases: Vec<(PacketType, u16, u8, &[u8])> = vec![
        (PacketType::Ack, 1, CMD_HANDSHAKE, &handshake),
        (PacketType::Command, 2, CMD_HEARTBEAT, &[]),
        (PacketType::Ack, 2, CMD_HEARTBEAT, &ack),
        (PacketType::Command, 65535, CMD_CONTROL_SAMPLE, &[1]),
        (PacketType::Message, 300, 7, &long),
    ];
    let mut input = String::new();
    for (packet_type, seq, cmd_id, payload) in &cases {
        let mut out = Vec::new();
        encode_frame(
            &Frame {
                packet_type: *packet_type,
                seq: *seq,
                cmd_set: 0,
                cmd_id: *cmd_id,
                payload,
            },
            &mut out,
        )
        .expect("encode");
        for byte in &out {
            input.push_str(&format!("{byte:02x}"));
        }
        input.push('\n');
    }
    let mut child = Command::new("python3")
        .args(["-c", SCRIPT])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("python3");
    child
        .stdin
        .take()
        .expect("stdin")
        .write_all(input.as_bytes())
        .expect("write");
    let output = child.wait_with_output().expect("python3 output");
    assert!(
        output.status.success(),
        "crcmod disagrees:\n{}",
        String::from_utf8_lossy(&output.stderr)
    );
    assert_eq!(
        String::from_utf8_lossy(&output.stdout).trim(),
        cases.len().to_string()
    );
}
