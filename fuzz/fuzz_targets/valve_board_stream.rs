//! Any bytes on the valve board's serial line, through the line assembler and the frame, reply,
//! fault and request decoders, as the host driver and the fake board read them.
#![no_main]

use harvest_hw::valve_board::line_assembler::LineAssembler;
use harvest_hw::valve_board::protocol::{
    MAX_FRAME_LEN, decode_board_message, decode_frame, decode_request,
};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let mut assembler = LineAssembler::new();
    for &byte in data {
        let Some(Ok(line)) = assembler.push(byte) else {
            continue;
        };
        assert!(line.len() <= MAX_FRAME_LEN);
        assert!(line.iter().all(|b| (0x20..=0x7e).contains(b)));
        if let Ok(frame) = decode_frame(line) {
            let _ = decode_board_message(&frame).map_err(|error| error.to_string());
            let _ = decode_request(frame.body).map_err(|error| error.to_string());
        }
    }
    assert!(assembler.discarded_bytes() <= data.len() as u64);
});
